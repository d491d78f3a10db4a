"""RoachTurn: follow a commanded yaw rate."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, TurnTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point
from envs.velociroach.robot import GAIT, VelociRoach

YAW_RATE_RANGE = 0.8  # rad/s: commands are drawn from U(-0.8, 0.8), within the turning tripod's reach at 10 Hz
# the task's weights, measured against what they reward (docs/velociroach.md, "RoachTurn's reward"): the yaw rate is
# tracked over half a second (the body's yaw over one 20 ms step is mostly the bound of its stride), within 0.3 rad/s,
# and speed pays a tenth of v2's 0.1 per body length a second, at which running straight at 45 Hz out-returned the
# turning tripod 2.7 times
TRACKING_WINDOW = 0.5  # s
TRACKING_SIGMA = 0.3  # rad/s
SPEED_REWARD_WEIGHT = 0.01  # per body length a second


class RoachTurnEnv(SkitterEnv):
    """Make a VelociRoACH turn at a commanded yaw rate while it runs.

    Robot, actions, starting state, episode end, info and the shared observations are those of
    :class:`envs.velociroach.walk.RoachWalkEnv`; this docstring lists what differs.

    ## Command
    A yaw rate ``r`` (rad/s, positive counter-clockwise seen from above), drawn per episode from
    ``U(-yaw_rate_range, yaw_rate_range)`` (default 0.8 rad/s, within what the tripod reaches by phase alone,
    ``benchmarks/results/turn_table.md``), or set with ``reset(options={"yaw_rate": r})``. The commanded heading
    turns at ``r`` from the heading at reset. The real robot turns by the phase offset between its sides ([roach-sim];
    Haldane and Fearing, ICRA 2014); so does this model, once its feet slip (docs/velociroach.md).

    ## Observation Space
    As RoachWalk, ``heading_error`` taken against the turning commanded heading, and the commanded yaw rate
    (``yaw_rate_command``, rad/s) after it: size 22 in gait mode, 18 in duty mode, 7 more with ``privileged_obs``.

    ## Rewards
    ``reward = tracking + speed + energy``, each in ``info["reward_<term>"]``:

    - ``tracking``: ``tracking_reward_weight * exp(-(w - r)^2 / tracking_sigma^2)``, w the mean yaw rate over the
      last ``tracking_window`` (since the reset within the first);
    - ``speed``: ``speed_reward_weight * v / 0.1 m``, v the speed along the body's heading in body lengths/s;
    - ``energy``: ``-energy_cost_weight * P`` as in RoachWalk.

    ## Arguments
    As RoachWalk, less ``forward_reward_weight`` and ``upright_reward_weight``, plus ``yaw_rate_range`` (0.8 rad/s),
    ``tracking_reward_weight`` (1.0), ``tracking_sigma`` (0.3 rad/s), ``tracking_window`` (0.5 s),
    ``speed_reward_weight`` (0.01).

    ## Version History
    - v5: (duty mode v4) as RoachWalk-v4 (the battery sags under its load).
    - v4: (gait mode; duty mode stays v3) as RoachWalk-v3 (the real firmware's voltage-mode PID and gains).
    - v3: tracking of the mean yaw rate over ``tracking_window`` (0.5 s) within 0.3 rad/s, and a speed weight of 0.01
      (v2: the rate over each 20 ms step within 0.5 rad/s, and 0.1). Under v2 the tripod run straight at 45 Hz,
      ignoring the command, returned 1699 against the turning tripod's 625 (seeds 1000-1007): a learner won the turn
      by not turning.
    - v2: as RoachWalk-v2 (the episode ends on a non-foot ground contact or a body out of its height band).
    - v1: as RoachWalk-v1 (heading error in the observation, IMU noise, 0-45 Hz strides, replayable controls).
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        yaw_rate_range: float = YAW_RATE_RANGE,
        tracking_reward_weight: float = 1.0,
        tracking_sigma: float = TRACKING_SIGMA,
        speed_reward_weight: float = SPEED_REWARD_WEIGHT,
        energy_cost_weight: float = 0.1,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        battery_voltage: float | None = None,
        battery_resistance: float | None = None,
        sensor_noise: bool = True,
        randomize: Mapping[str, Sequence[float]] | None = None,
        calibration: str | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        tracking_window: float = TRACKING_WINDOW,
    ):
        robot = VelociRoach(
            action_mode,
            control_freq,
            battery_voltage,
            battery_resistance,
            ImuNoise() if check_flag("sensor_noise", sensor_noise) else None,
            calibration=calibration,
        )
        task = TurnTask(
            robot,
            privileged_obs,
            yaw_rate_range,
            tracking_reward_weight,
            tracking_sigma,
            speed_reward_weight,
            energy_cost_weight,
            max_tilt,
            terminate_when_unhealthy=terminate_when_unhealthy,
            height_band=height_band,
            grace_time=grace_time,
            tracking_window=tracking_window,
        )
        super().__init__(robot, task, reset_noise_scale, randomize, telemetry, render_mode, width, height)


make_env = entry_point(RoachTurnEnv)
make_batched = vector_entry_point(RoachTurnEnv)
