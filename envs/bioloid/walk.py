"""BioloidWalk: walk the Bioloid quadruped forward on flat ground."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.actuators.servo import ServoConstants
from envs.bioloid.robot import GOAL, Bioloid
from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, WalkTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point

ENERGY_COST_WEIGHT = 0.01  # per W: the 16 servos draw a few watts standing and walking (docs/bioloid.md)


class BioloidWalkEnv(SkitterEnv):
    """Walk a 1.76 kg Bioloid quadruped [bioloid-webots] forward (+x) on flat ground.

    The robot (``assets/bioloid/``, documented in docs/bioloid.md): a CM-5 body, a pelvis on a roll servo, four legs
    of three AX-12 servos each (hip pitch, abduction, knee) on crutch feet, a two-servo neck and a head: 16 servos,
    each the shared AX-12 model (envs/actuators/servo.py: its compliance slope as gain, its stall torque and speed
    from its motor and a 10 V supply). Physics at 500 Hz, control at 50 Hz.

    ## Action Space
    ``Box(-1, 1, (16,))``; out-of-range actions are clipped to [-1, 1]; NaN or infinite actions raise
    ``ValueError``. Each entry is one servo's goal position, mapped linearly from [-1, 1] onto its allowed range in
    counts (``env.unwrapped.robot.mode``; 0..1023 over 300 deg, 512 = 0 rad; the knees from straight to 90 deg of
    bend, 512..819), held over the 20 ms control step. Order: PELVIS, F_L_1, F_L_2, F_L_3, F_R_1, F_R_2, F_R_3,
    B_L_1, B_L_2, B_L_3, B_R_1, B_R_2, B_R_3, N_1, N_2, HEAD (1 hip pitch, 2 abduction, 3 knee).
    ``robot.mode.to_action(counts)`` builds an action from counts. The robot stands with servo 2 at 819 (left legs)
    and 205 (right legs).

    ## Observation Space
    What the robot senses, in SI units (``Box(-inf, inf)``, float64), laid out by name in
    ``env.unwrapped.observation_structure``:

    | name | size | observation | unit |
    |---|---|---|---|
    | ``leg_cos``, ``leg_sin`` | 16 + 16 | cos, sin of each servo's present position (a whole count, as it reports) | |
    | ``servo_speed`` | 16 | each servo's output speed | rad/s |
    | ``servo_load`` | 16 | each servo's present load, signed, of 1023 (its torque over its stall torque) | count |
    | ``gyro`` | 3 | gyro, body frame, with noise and a bias per episode (an IMU on the CM-5, assumed) | rad/s |
    | ``accel`` | 3 | accelerometer, body frame, with noise | m/s^2 |
    | ``battery`` | 1 | the servos' supply | V |
    | ``heading_error`` | 2 | sin, cos of (integrated-gyro heading - commanded heading, +x) | |
    | ``body_velocity``, ``body_quaternion`` | 3 + 4 | privileged only: body velocity (body frame), pose | m/s, 1 |

    Size 73, 7 more with ``privileged_obs``. The body's world pose is in ``info``.

    ## Rewards
    ``reward = forward + energy + upright``, each weighted, each in ``info["reward_<term>"]``:

    - ``forward``: ``forward_reward_weight * v_x / 0.30 m``, world-x speed over the step in body lengths per second;
    - ``energy``: ``-energy_cost_weight * P``, P the servos' battery power (W, mean over the step);
    - ``upright``: ``upright_reward_weight * u``, u the world-z component of the body's z axis.

    ## Starting State
    The gaits' ready posture: legs down (servo 2 at +-90 deg), knees bent so that every sole is at the centre of the
    seed's IK ellipse [bioloid-webots, eqs. 7-8], neck up, level with its lowest sole on the ground; servo angles
    perturbed by ``U(-1, 1) * 0.2 * reset_noise_scale`` rad (the goals hold the perturbed posture), body angular
    velocity by ``N(0, reset_noise_scale / 2)`` rad/s and linear velocity by ``N(0, reset_noise_scale / 20)`` m/s. With
    ``randomize``, the named physical parameters (``env.unwrapped.robot.parameters``) are drawn at every reset.

    ## Episode End
    - terminated also (``info["fallen"]``) when anything but its feet (each leg's shank below the knee, crutch and sole;
      not the knee servo, which ik-trot sets down in 12% of its steps) has touched the ground, or its body's origin has
      been outside its height band (0.083 to 0.281 m above the ground under it), for longer than ``grace_time`` (1.5 s)
      in a leaky count: a step that breaks the rule adds its duration, one that keeps it takes a quarter of that away
      (``info["contact_time"]``, ``info["band_time"]``; see envs/common/locomotion.py). Off with
      ``terminate_when_unhealthy=False``;
    - terminated when the body tilts more than ``max_tilt`` (rad) from upright (``info["fallen"]``), or when the
      simulation goes numerically unstable (``info["sim_unstable"]``: MuJoCo has reset the state; the last good
      step's observation and info are returned, with reward 0);
    - truncated after ``episode_seconds`` of simulated time (10 s: 500 steps at 50 Hz, 250 at 25 Hz), whatever the
      control rate.

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
    ``gymnasium.make("skitter/BioloidWalk-v2", **kwargs)``: ``action_mode`` (``"goal"``), ``control_freq`` (Hz,
    default 50), ``privileged_obs``, ``forward_reward_weight`` (1.0), ``energy_cost_weight`` (0.01 per W),
    ``upright_reward_weight`` (1.0), ``max_tilt`` (1.0 rad), ``reset_noise_scale`` (0.1), ``knee_wedge`` (False:
    the 18 deg "aibo style" wedges of [bioloid-webots, IV.A] when True), ``servo`` (an
    ``envs.actuators.servo.ServoConstants``:
    supply, compliance slope, torque limit; default AX-12 at 10 V), ``battery_voltage`` (V, shorthand for the
    servos' supply), ``sensor_noise`` (True), ``randomize`` (parameter name -> (low, high)), ``calibration`` (a
    calibration file from ``calibrate.py --robot bioloid``, docs/calibration.md), ``episode_seconds`` (the time
    limit, s; default 10, None for none), ``telemetry``, ``render_mode``, ``width``, ``height``.
    The ground rules: ``terminate_when_unhealthy`` (True), ``height_band`` ((low, high) m, default the robot's),
    ``grace_time`` (1.5 s).

    ## Version History
    - v2: the episode also ends when anything but the feet touches the ground, or the body leaves its height
      band, for more than ``grace_time`` (a leaky count); ``info`` and the evaluation report the fraction of
      steps with a non-foot ground contact and the mean body height (v1 ended only on a tilt, and a learner
      could win it crawling).
    - v1: the knees stop at straight: their joint limits and the servos' allowed range cover 0 to 90 deg of bend
      only, as the robot's postures and IK have them (v0 let them bend 90 deg backward too, which an optimized CPG
      exploited).
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: str = GOAL,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        upright_reward_weight: float = 1.0,
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


make_env = entry_point(BioloidWalkEnv)
make_batched = vector_entry_point(BioloidWalkEnv)
