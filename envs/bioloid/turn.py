"""BioloidTurn: follow a commanded yaw rate."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.actuators.servo import ServoConstants
from envs.bioloid.gait import TROT_FREQUENCY
from envs.bioloid.robot import OFFSET, Bioloid
from envs.bioloid.walk import ENERGY_COST_WEIGHT
from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, TurnTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point

# rad/s: commands from U(-0.3, 0.3), within the steered trot's reach (0.40 rad/s at its largest turn: the soccer gait
# map, benchmarks/results/gait_maps.md)
YAW_RATE_RANGE = 0.3
# s: the yaw rate tracked is the mean over one cycle of the reference trot, whose body sways within it
TRACKING_WINDOW = 1.0 / TROT_FREQUENCY
# rad/s: with 0.2 (v2) and one step's rate, a robot that stood still out-scored the steered trot; with a cycle's mean
# and 0.05, standing still scores a fifth of what the steered trot does (docs/bioloid.md)
TRACKING_SIGMA = 0.05
# per step, times the world-z component of the body's z axis: BioloidWalk's weight. Without it (v3) a fall cost nothing
# while every step before the robot stood cost more energy than it earned, and PPO learned to fall sooner
# (docs/bioloid.md); with it a step upright pays more than a flailing step's energy (about 0.5 under random actions)
UPRIGHT_REWARD_WEIGHT = 1.0


class BioloidTurnEnv(SkitterEnv):
    """Make a Bioloid quadruped turn at a commanded yaw rate on its stepping legs.

    Robot, starting state, episode end, info and the shared observations are those of
    :class:`envs.bioloid.walk.BioloidWalkEnv`; this docstring lists what differs.

    ## Action Space
    ``Box(-1, 1, (16,))`` in the ``offset`` mode by default: each entry is one servo's goal, its angle in the ready
    posture plus 0.5 rad times the action (``envs.bioloid.robot.OFFSET_SCALE``, in counts, clipped to the servo's
    allowed range), so that an action of 0 stands; every IK gait's goals lie within 0.39 rad of the ready posture.
    ``action_mode="goal"`` maps [-1, 1] onto each servo's whole range, as BioloidWalk.

    ## Command
    A yaw rate ``r`` (rad/s, positive counter-clockwise seen from above), drawn per episode from
    ``U(-yaw_rate_range, yaw_rate_range)`` (default 0.3 rad/s), or set with ``reset(options={"yaw_rate": r})``. The
    commanded heading turns at ``r`` from the heading at reset. The reference gait (``ik-trot`` on this env;
    agents/bioloid/ik.py) trots in place and turns by swinging each foot sideways in its stance.

    ## Observation Space
    As BioloidWalk, ``heading_error`` taken against the turning commanded heading, and the commanded yaw rate
    (``yaw_rate_command``, rad/s) after it: size 74, 7 more with ``privileged_obs``.

    ## Rewards
    ``reward = tracking + speed + energy + upright``, each in ``info["reward_<term>"]``:

    - ``tracking``: ``tracking_reward_weight * exp(-(w - r)^2 / tracking_sigma^2)``, w the mean yaw rate over the
      last ``tracking_window`` (one cycle of the 1.5 Hz trot; since the reset within the first);
    - ``speed``: ``speed_reward_weight * v / 0.30 m``, v the speed along the body's heading in body lengths/s;
    - ``energy``: ``-energy_cost_weight * P`` as in BioloidWalk;
    - ``upright``: ``upright_reward_weight * u`` as in BioloidWalk, u the world-z component of the body's z axis.

    ## Arguments
    As BioloidWalk, less ``forward_reward_weight``; ``action_mode`` ``"offset"`` (default) or ``"goal"``; plus
    ``yaw_rate_range``
    (0.3 rad/s), ``tracking_reward_weight`` (1.0), ``tracking_sigma`` (0.05 rad/s), ``tracking_window``
    (0.667 s), ``speed_reward_weight`` (0.1).

    ## Version History
    - v5: the action is an offset from the ready posture (``action_mode="offset"``; v4's ``goal`` mode remains as an
      option). In the ``goal`` mode an action of 0 puts the legs out sideways, a fresh policy sprawls and falls
      within about 2 s, and PPO's row on v4 fell in every evaluation episode after 7M steps; under random offsets
      the robot stays up for the whole episode (docs/bioloid.md).
    - v4: pays for staying upright (``upright_reward_weight`` 1.0, as BioloidWalk). On v3 a fall cost nothing and
      every step before the robot stood cost more energy than it earned: PPO learned to end its episodes sooner
      and every evaluation episode of its row was a fall.
    - v3: the yaw rate tracked is the mean over ``tracking_window`` (one trot cycle) within 0.05 rad/s, commands
      within 0.3 rad/s, and the reference trot turns by its feet's sideways swing. On v2 standing still out-scored
      the steered trot (411 against 10): one step's yaw rate is the trot's sway, and the stride-scaling steering
      turned the wrong way.
    - v2: as BioloidWalk-v2 (the episode ends on a non-foot ground contact or a body out of its height band).
    - v1: as BioloidWalk-v1 (the knees stop at straight).
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: str = OFFSET,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        yaw_rate_range: float = YAW_RATE_RANGE,
        tracking_reward_weight: float = 1.0,
        tracking_sigma: float = TRACKING_SIGMA,
        speed_reward_weight: float = 0.1,
        tracking_window: float = TRACKING_WINDOW,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        upright_reward_weight: float = UPRIGHT_REWARD_WEIGHT,
        max_tilt: float = 1.0,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        knee_wedge: bool = False,
        servo: ServoConstants | None = None,
        battery_voltage: float | None = None,
        sensor_noise: bool = True,
        randomize: Mapping[str, Sequence[float]] | None = None,
        calibration: str | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        robot = Bioloid(
            action_mode,
            control_freq,
            knee_wedge,
            servo,
            battery_voltage,
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
            upright_reward_weight=upright_reward_weight,
        )
        super().__init__(robot, task, reset_noise_scale, randomize, telemetry, render_mode, width, height)


make_env = entry_point(BioloidTurnEnv)
make_batched = vector_entry_point(BioloidTurnEnv)
