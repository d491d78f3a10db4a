"""XjusWalk: walk the xJüs forward on flat ground."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, WalkTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point
from envs.xjus.robot import COMPLIANT, GAIT, SpineSetting, Xjus

ENERGY_COST_WEIGHT = 0.002  # per W: the walk at T = 0.5 s draws about 170 W, a cost of a third of its forward reward


class XjusWalkEnv(SkitterEnv):
    """Walk a 4.5 kg, 0.53 m xJüs hexapod forward (+x) on flat ground.

    The robot (``assets/xjus/``, documented in docs/xjus.md): three chassis segments joined by two passive spine
    joints (pitch and roll, 19.4 N m/rad by default, the report's design stiffness), six 7 in semicircular spring-steel
    legs with a radial spring each (29.2 N gives 7.6 mm, the report's FEA), each turned by the report's gearmotor
    (``tau = eta N Kt (d Vs - Ks w) / (Ra + d^2 Ramp)``, Table 1). Physics at 500 Hz, control at 125 Hz.

    ## Action Space
    ``Box(-1, 1)``; out-of-range actions are clipped to [-1, 1]; NaN or infinite actions raise ``ValueError``. Each
    entry maps linearly from [-1, 1] onto its physical range (``env.unwrapped.robot.mode``):

    - ``action_mode="gait"`` (default), shape (3,): the robot's Buehler clock and PD [xjus-report, sections 2.4-2.5] run
      at the control rate (at least 120 Hz) and drive the legs in an alternating tripod:

      | index | command | range |
      |---|---|---|
      | 0 | clock period T | 0.5 to 1.5 s (0 action: 1 s) |
      | 1 | ground sweep angle, left legs | 0 to 90 deg |
      | 2 | ground sweep angle, right legs | 0 to 90 deg |

      Equal sweeps walk straight; the side with the larger sweep sweeps the ground faster, so the robot turns away
      from it. ``robot.mode.to_action([T, sweep_left, sweep_right])`` builds an action from physical values.
    - ``action_mode="duty"``, shape (6,): the duty factor ``d`` of each leg's motor (FL, ML, BL, FR, MR, BR) in
      [-1, 1], held over the control step, as the report's simulation took it.

    ## Observation Space
    What the robot senses, in SI units (``Box(-inf, inf)``, float64), laid out by name in
    ``env.unwrapped.observation_structure``:

    | name | size | observation | unit |
    |---|---|---|---|
    | ``leg_cos``, ``leg_sin`` | 6 + 6 | cos, sin of each hip angle (encoders), legs FL, ML, BL, FR, MR, BR | |
    | ``leg_velocity`` | 6 | hip angular velocities | rad/s |
    | ``gyro`` | 3 | gyro, body frame, MPU-6000 noise and a bias drawn per episode | rad/s |
    | ``accel`` | 3 | accelerometer, body frame, with noise | m/s^2 |
    | ``motor_current`` | 6 | each motor's current (the EPOS2 drivers measure it) | A |
    | ``battery`` | 1 | supply voltage | V |
    | ``clock_cos``, ``clock_sin`` | 1 + 1 | gait mode only: the Buehler clock's phase | |
    | ``heading_error`` | 2 | sin, cos of (integrated-gyro heading - commanded heading, +x) | |
    | ``body_velocity``, ``body_quaternion`` | 3 + 4 | privileged only: body velocity (body frame), pose | m/s, 1 |

    Size 35 in gait mode, 33 in duty mode, 7 more with ``privileged_obs``. The body's world pose is in ``info``.

    ## Rewards
    ``reward = forward + energy + upright``, each weighted, each in ``info["reward_<term>"]``:

    - ``forward``: ``forward_reward_weight * v_x / 0.53 m``, world-x speed over the step in body lengths per second;
    - ``energy``: ``-energy_cost_weight * P``, ``P = sum over legs of max(d Vs i, 0)``, the battery power of the
      seed's motor model (W, mean over the step's physics steps; braking returns nothing);
    - ``upright``: ``upright_reward_weight * u``, u the world-z component of the middle segment's z axis.

    The cost of transport reported by evaluate.py is energy / (m g distance); the report's motor constants cap the
    motor's efficiency at ``eta N Kt / Ks = 0.37``, so it is at least 1 / 0.37 of the mechanical one.

    ## Starting State
    Tripod A (front-left, back-left, middle-right legs) standing with its legs pointing down, tripod B pointing up,
    the clock in the middle of tripod A's stance; leg angles perturbed by ``U(-reset_noise_scale,
    reset_noise_scale)`` rad, body angular velocity by ``N(0, reset_noise_scale)`` rad/s and linear velocity by
    ``N(0, reset_noise_scale / 10)`` m/s. With ``randomize``, the named physical parameters
    (``env.unwrapped.robot.parameters``) are drawn at every reset.

    ## Episode End
    - terminated also (``info["fallen"]``) when anything but its feet (its six legs) has touched the ground, or its
      body's origin has been outside its height band (0.103 to 0.364 m above the ground under it), for longer than
      ``grace_time`` (1.5 s) in a leaky count: a step that breaks the rule adds its duration, one that keeps it takes a
      quarter of that away (``info["contact_time"]``, ``info["band_time"]``; see envs/common/locomotion.py). Off with
      ``terminate_when_unhealthy=False``;
    - terminated when the middle segment tilts more than ``max_tilt`` (rad) from upright (``info["fallen"]``), or
      when the simulation goes numerically unstable (``info["sim_unstable"]``: MuJoCo has reset the state; the last
      good step's observation and info are returned, with reward 0);
    - truncated after ``episode_seconds`` of simulated time (10 s: 1250 steps at 125 Hz, 2500 at 250 Hz), whatever
      the control rate.

    ## Info
    As RoachWalk: ``x_position``, ``y_position``, ``z_position``, ``quaternion``, ``x_velocity``, ``y_velocity``,
    ``speed``, ``yaw``, ``yaw_rate``, ``up_z``, ``power`` (W), ``heading_error``, ``time``, ``fallen``,
    ``sim_unstable``, the reward terms and the running sums ``distance``, ``energy`` (J), ``progress_x``,
    ``elapsed``, ``yaw_travel``, ``yaw_travel_warmup``.
    The ground rules' values: ``body_height`` (m above the ground), ``non_foot_touch`` (1 if anything but the
    feet touched the ground in the step), their leaky counts ``contact_time`` and ``band_time`` (s), and the
    sums ``contact_steps``, ``height_sum``, ``steps`` behind the episode metrics ``non_foot_contact`` (fraction
    of steps) and ``body_height`` (mean, m).

    ## Arguments
    ``gymnasium.make("skitter/XjusWalk-v1", **kwargs)``: ``action_mode``, ``control_freq`` (Hz, default 125; gait
    mode at least 120), ``privileged_obs``, ``forward_reward_weight`` (1.0), ``energy_cost_weight`` (0.002 per W),
    ``upright_reward_weight`` (1.0), ``max_tilt`` (1.4 rad), ``reset_noise_scale`` (0.1), ``spine``
    (``"compliant"`` or ``"rigid"``), ``spine_stiffness`` (N m/rad, one value or per ``front_pitch``,
    ``front_roll``, ``rear_pitch``, ``rear_roll``; default 19.4), ``spine_damping`` (N m s/rad, default 0.1),
    ``battery_voltage`` (V, default 22.2), ``current_limit`` (A per motor, default none; the report gives 1.08 A
    continuous), ``sensor_noise`` (True), ``randomize`` (parameter name -> (low, high)), ``calibration`` (a
    calibration file from ``calibrate.py --robot xjus``, docs/calibration.md), ``episode_seconds`` (the time limit,
    s; default 10, None for none), ``telemetry``, ``render_mode``, ``width``, ``height``.
    The ground rules: ``terminate_when_unhealthy`` (True), ``height_band`` ((low, high) m, default the robot's),
    ``grace_time`` (1.5 s).

    ## Version History
    - v1: the episode also ends when anything but the feet touches the ground, or the body leaves its height
      band, for more than ``grace_time`` (a leaky count); ``info`` and the evaluation report the fraction of
      steps with a non-foot ground contact and the mean body height (v0 ended only on a tilt, and a learner
      could win it crawling).
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        upright_reward_weight: float = 1.0,
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
        task = WalkTask(
            robot,
            privileged_obs,
            forward_reward_weight,
            energy_cost_weight,
            upright_reward_weight,
            max_tilt,
            terminate_when_unhealthy=terminate_when_unhealthy,
            height_band=height_band,
            grace_time=grace_time,
        )
        super().__init__(robot, task, reset_noise_scale, randomize, telemetry, render_mode, width, height)


make_env = entry_point(XjusWalkEnv)
make_batched = vector_entry_point(XjusWalkEnv)
