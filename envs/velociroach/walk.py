"""RoachWalk: run the VelociRoACH forward."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, WalkTask
from envs.common.robot import check_flag
from envs.common.vector import vector_entry_point
from envs.velociroach.robot import GAIT, VelociRoach


class RoachWalkEnv(SkitterEnv):
    """Run a 10 cm, 30 g VelociRoACH hexapod forward (+x) on flat ground.

    The robot (``assets/velociroach/``, documented in docs/velociroach.md): a chassis on six compliant C-legs, moved
    by two DC motors with back-EMF, one per side, through a linkage that keeps the front and back legs of a side in
    phase and the middle leg half a cycle apart. Physics at 2 kHz.

    ## Action Space
    ``Box(-1, 1)``; out-of-range actions are clipped to [-1, 1]; NaN or infinite actions raise ``ValueError``. Each
    entry maps linearly from [-1, 1] onto its physical range (``env.unwrapped.robot.mode``):

    - ``action_mode="gait"`` (default, 50 Hz), shape (3,): the robot's firmware runs a leg clock per side and a PID
      that tracks it at every physics step, as the real firmware accepts commands:

      | index | command | range |
      |---|---|---|
      | 0 | left stride frequency | 0 to 45 Hz (the real robot's range, [roach-sim, Table 1]) |
      | 1 | right stride frequency | 0 to 45 Hz |
      | 2 | how far the right clock trails the left | 0 to 2 pi rad (0 action: pi, the alternating tripod) |

      The firmware moves its phase toward the command at up to 5 cycles/s. ``robot.mode.to_action([f_l, f_r, phase])``
      builds an action from physical values.
    - ``action_mode="duty"`` (default 1 kHz), shape (2,): PWM duty cycle of the left and right motor in [-1, 1], as
      the motor driver sees it (terminal voltage = duty x battery voltage).

    ## Observation Space
    What the real robot senses, in SI units (``Box(-inf, inf)``, float64), laid out by name in
    ``env.unwrapped.observation_structure``:

    | name | size | observation | unit |
    |---|---|---|---|
    | ``leg_cos``, ``leg_sin`` | 2 + 2 | cos, sin of the left, right leg (crank) angle | |
    | ``leg_velocity`` | 2 | left, right leg angular velocity (encoders) | rad/s |
    | ``gyro`` | 3 | gyro, body frame, with the MPU-6000's noise and a bias drawn per episode | rad/s |
    | ``accel`` | 3 | accelerometer, body frame (+9.81 up at rest), with noise | m/s^2 |
    | ``back_emf`` | 2 | left, right motor back-EMF | V |
    | ``battery`` | 1 | battery voltage | V |
    | ``clock_cos``, ``clock_sin`` | 2 + 2 | gait mode only: the firmware's leg clocks | |
    | ``heading_error`` | 2 | sin, cos of (heading estimate - commanded heading); see below | |
    | ``body_velocity``, ``body_quaternion`` | 3 + 4 | privileged only: body velocity (body frame), pose | m/s, 1 |

    Size 21 in gait mode, 17 in duty mode, 7 more with ``privileged_obs``. The heading estimate is what the firmware
    integrates from its z gyro since the reset; the commanded heading is +x (the heading at reset). It drifts as the
    real robot's would: its gyro bias (0.5 deg/s per axis, 1 sigma) integrates to a few degrees over an episode. The
    body's world pose is in ``info``, never in the observation unless privileged.

    ## Rewards
    ``reward = forward + energy + upright``, each term weighted, each in ``info["reward_<term>"]``:

    - ``forward``: ``forward_reward_weight * v_x / 0.1 m``, the world-x speed over the step in body lengths per second;
    - ``energy``: ``-energy_cost_weight * P``, P the mean electrical power the motors drew over the step (W;
      braking energy is not returned to the battery);
    - ``upright``: ``upright_reward_weight * u``, u the world-z component of the body's z axis (1 upright).

    ## Starting State
    Tripod A (front-left, back-left, middle-right legs) at the bottom of its stroke, the right crank half a cycle
    behind the left; crank angle and phase perturbed by ``U(-reset_noise_scale, reset_noise_scale)`` rad, body angular
    velocity by ``N(0, reset_noise_scale)`` rad/s and linear velocity by ``N(0, reset_noise_scale / 10)`` m/s. With
    ``randomize``, the named physical parameters (``env.unwrapped.robot.parameters``) are drawn at every reset.

    ## Episode End
    - terminated also (``info["fallen"]``) when anything but its feet (its six C-legs) has touched the ground, or its
      body's origin has been outside its height band (0.0084 to 0.0312 m above the ground under it), for longer than
      ``grace_time`` (1.5 s) in a leaky count: a step that breaks the rule adds its duration, one that keeps it takes a
      quarter of that away (``info["contact_time"]``, ``info["band_time"]``; see envs/common/locomotion.py). Off with
      ``terminate_when_unhealthy=False``;
    - terminated when the body tilts more than ``max_tilt`` (rad) from upright (``info["fallen"]``), or when the
      simulation goes numerically unstable (``info["sim_unstable"]``: MuJoCo has reset the state; the last good
      step's observation and info are returned, with reward 0);
    - truncated after ``episode_seconds`` of simulated time (10 s: 500 steps in gait mode, 10000 in duty mode),
      whatever the control rate.

    ## Info
    ``x_position``, ``y_position``, ``z_position``, ``quaternion``, ``x_velocity``, ``y_velocity``, ``speed`` (along
    the heading), ``yaw``, ``yaw_rate``, ``up_z``, ``power`` (W), ``heading_error``, ``time``, ``fallen``,
    ``sim_unstable``, the reward terms, and the episode's running sums ``distance`` (along the heading, m),
    ``energy`` (J), ``progress_x`` (m), ``elapsed`` (s), ``yaw_travel`` (rad, unwrapped) and
    ``yaw_travel_warmup`` (its value at 1 s, where rate metrics start).
    The ground rules' values: ``body_height`` (m above the ground), ``non_foot_touch`` (1 if anything but the
    feet touched the ground in the step), their leaky counts ``contact_time`` and ``band_time`` (s), and the
    sums ``contact_steps``, ``height_sum``, ``steps`` behind the episode metrics ``non_foot_contact`` (fraction
    of steps) and ``body_height`` (mean, m).

    ## Arguments
    ``gymnasium.make("skitter/RoachWalk-v4", **kwargs)``: ``action_mode``, ``control_freq`` (Hz; default 50 in gait
    mode, 1000 in duty mode), ``privileged_obs``, ``forward_reward_weight`` (1.0), ``energy_cost_weight`` (0.1 per W),
    ``upright_reward_weight`` (1.0), ``max_tilt`` (1.4 rad), ``reset_noise_scale`` (0.1), ``battery_voltage`` (V,
    the battery's open-circuit voltage, default the model's 3.7), ``battery_resistance`` (ohm, its internal
    resistance, default the model's 0.2; 0 for an ideal source), ``sensor_noise`` (True: the IMU's noise and
    bias), ``randomize`` (parameter name -> (low, high)), ``calibration`` (a calibration file from ``calibrate.py
    --robot roach``: the model with its effects, docs/calibration.md), ``episode_seconds`` (the time limit, s;
    default 10, None for none), ``telemetry`` (record telemetry, see docs/telemetry.md), ``render_mode``
    (``"human"``, ``"rgb_array"``), ``width``, ``height``.
    The ground rules: ``terminate_when_unhealthy`` (True), ``height_band`` ((low, high) m, default the robot's),
    ``grace_time`` (1.5 s).

    ## Version History
    - v4: (duty mode v3) the battery sags under its load: a cell with an internal resistance of 0.2 ohm (measured
      on the real logs, 0.11-0.34 ohm), holding over each control step the voltage it sags to under the power the
      motors drew over the step before; the ``battery`` sense reads it and the firmware's duty multiplies it (v3: an
      ideal 3.7 V source). ``battery_voltage`` is the open-circuit voltage; ``battery_resistance`` is new.
    - v3: (gait mode; duty mode stays v2) the firmware's PID is the real one, a voltage-mode PWM law with the lab's
      gains (Kp 1800, Ki 200, Kd 100 in its units; no back-EMF compensation), where v2 ran a current-mode PID with
      stiffer gains of our own; the legs now lag the clock (about 4 deg at 15 Hz and 12 at 45 Hz, against 1.3 and
      2.7), as the real robot's do.
    - v2: the episode also ends when anything but the feet touches the ground, or the body leaves its height
      band, for more than ``grace_time`` (a leaky count); ``info`` and the evaluation report the fraction of
      steps with a non-foot ground contact and the mean body height (v1 ended only on a tilt, and a learner
      could win it crawling).
    - v1: the heading error from the integrated gyro joins the observation, with the gyro's noise and bias; the
      stride frequencies are bounded to the real robot's 0-45 Hz (v0: -50 to 50 Hz); the firmware's clock is given to
      the motor controller at every physics step through ``ctrl`` (v0 rewrote the model's slew limit at every step),
      so any episode replays exactly from its controls.
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = 0.1,
        upright_reward_weight: float = 1.0,
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
    ):
        robot = VelociRoach(
            action_mode,
            control_freq,
            battery_voltage,
            battery_resistance,
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


make_env = entry_point(RoachWalkEnv)
make_batched = vector_entry_point(RoachWalkEnv)
