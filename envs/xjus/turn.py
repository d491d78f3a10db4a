"""XjusTurn: follow a commanded yaw rate."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, TurnTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point
from envs.xjus.robot import COMPLIANT, GAIT, SpineSetting, Xjus
from envs.xjus.walk import ENERGY_COST_WEIGHT

YAW_RATE_RANGE = 0.4  # rad/s: commands from U(-0.4, 0.4), within the differential sweep's reach at T = 0.5 s
# the yaw rate is tracked over one stride of the Buehler clock's period T = 0.5 s [xjus-report]: the body swings from
# side to side within a stride, by more than the commands' range over one 8 ms control step
TRACKING_WINDOW = 0.5  # s
TRACKING_SIGMA = 0.15  # rad/s: a 0.4 rad/s command range; with 0.3, a robot that does not turn scored 0.6 of the best


class XjusTurnEnv(SkitterEnv):
    """Make an xJüs turn at a commanded yaw rate while it walks.

    Robot, actions, starting state, episode end, info and the shared observations are those of
    :class:`envs.xjus.walk.XjusWalkEnv`; this docstring lists what differs.

    ## Command
    A yaw rate ``r`` (rad/s, positive counter-clockwise seen from above), drawn per episode from
    ``U(-yaw_rate_range, yaw_rate_range)`` (default 0.4 rad/s: the differential sweep reaches about +-0.5 rad/s at
    T = 0.5 s, docs/xjus.md), or set with ``reset(options={"yaw_rate": r})``. The commanded heading turns at ``r``
    from the heading at reset. The robot turns by a different ground sweep angle on each side at a common clock
    period (gait mode ``sweep_left``, ``sweep_right``), which keeps the tripods intact.

    ## Observation Space
    As XjusWalk, ``heading_error`` taken against the turning commanded heading, and the commanded yaw rate
    (``yaw_rate_command``, rad/s) after it: size 36 in gait mode, 34 in duty mode, 7 more with ``privileged_obs``.

    ## Rewards
    ``reward = tracking + speed + energy``, each in ``info["reward_<term>"]``:

    - ``tracking``: ``tracking_reward_weight * exp(-(w - r)^2 / tracking_sigma^2)``, w the mean yaw rate over the
      last ``tracking_window`` (0.5 s, one stride at the Buehler clock's T; since the reset within the first);
    - ``speed``: ``speed_reward_weight * v / 0.53 m``, v the speed along the body's heading in body lengths/s;
    - ``energy``: ``-energy_cost_weight * P`` as in XjusWalk (costs of transport: the motor's efficiency is capped at
      0.37 by the report's constants).

    ## Arguments
    As XjusWalk, less ``forward_reward_weight`` and ``upright_reward_weight``, plus ``yaw_rate_range`` (0.4 rad/s),
    ``tracking_reward_weight`` (1.0), ``tracking_sigma`` (0.15 rad/s), ``tracking_window`` (0.5 s),
    ``speed_reward_weight`` (0.1).

    ## Version History
    - v2: the yaw rate tracked is the mean over ``tracking_window`` (one stride) and ``tracking_sigma`` is 0.15 rad/s
      (was the rate over each 8 ms step, and 0.3): v1's tracking scored the body's sway within a stride, so that the
      Buehler clock, which turns at the commanded rate to 0.03 rad/s, returned less than random gait commands (268
      against 376 over seeds 1000-1019).
    - v1: as XjusWalk-v1 (the episode ends on a non-foot ground contact or a body out of its height band).
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
        speed_reward_weight: float = 0.1,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        spine: str = COMPLIANT,
        spine_stiffness: SpineSetting = None,
        spine_damping: SpineSetting = None,
        battery_voltage: float | None = None,
        current_limit: float | None = None,
        sensor_noise: bool = True,
        randomize: Mapping[str, Sequence[float]] | None = None,
        calibration: str | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        tracking_window: float = TRACKING_WINDOW,
    ):
        robot = Xjus(
            action_mode,
            control_freq,
            spine,
            spine_stiffness,
            spine_damping,
            battery_voltage,
            current_limit,
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


make_env = entry_point(XjusTurnEnv)
make_batched = vector_entry_point(XjusTurnEnv)
