"""RoachWalk: run the VelociRoACH forward."""

from __future__ import annotations

from envs.velociroach import constants as C
from envs.velociroach.base import RoachEnv
from envs.velociroach.robot import ActionMode


class RoachWalkEnv(RoachEnv):
    """Run a 10 cm, 30 g VelociRoACH hexapod forward (+x) on flat ground.

    The robot (``assets/velociroach/``, documented in docs/velociroach.md): a chassis on six compliant C-legs, moved
    by two DC motors with back-EMF, one per side, through a linkage that keeps the front and back legs of a side in
    phase and the middle leg half a cycle apart. Physics at 2 kHz.

    ## Action Space
    ``Box(-1, 1)``; out-of-range actions are clipped to [-1, 1]; NaN or infinite actions raise ``ValueError``.

    - ``action_mode="gait"`` (default, 50 Hz), shape (3,): the robot's firmware runs a leg clock per side and a PID
      that tracks it at every physics step, as the real firmware accepts commands:

      | index | command | mapping |
      |---|---|---|
      | 0 | left stride frequency | ``50 Hz * a`` (negative runs the legs backward) |
      | 1 | right stride frequency | ``50 Hz * a`` |
      | 2 | left/right phase: how far the right clock trails the left | ``pi * (1 + a)`` rad; 0 = pi = tripod |

      The firmware moves its phase toward the command at up to 5 cycles/s. ``RoachEnv.gait_action(f_l, f_r, phase)``
      builds an action from physical values.
    - ``action_mode="duty"`` (default 1 kHz), shape (2,): PWM duty cycle of the left and right motor, as the motor
      driver sees it (terminal voltage = duty x battery voltage).

    ## Observation Space
    What the real robot senses, in SI units (``Box(-inf, inf)``, float64):

    | slice | size | observation | unit |
    |---|---|---|---|
    | 0:2 | 2 | cos of left, right leg (crank) angle | |
    | 2:4 | 2 | sin of left, right leg angle | |
    | 4:6 | 2 | left, right leg angular velocity (encoders) | rad/s |
    | 6:9 | 3 | gyro, body frame | rad/s |
    | 9:12 | 3 | accelerometer, body frame (+9.81 up at rest) | m/s^2 |
    | 12:14 | 2 | left, right motor back-EMF | V |
    | 14 | 1 | battery voltage | V |
    | 15:19 | 4 | gait mode only: cos, sin of the firmware's commanded leg angles | |
    | last | 7 | ``privileged_obs=True`` only: body linear velocity (body frame) and orientation quaternion | m/s, 1 |

    The privileged observations are ones the real robot does not sense; they are off by default.

    The body's world pose is in ``info``, never in the observation unless privileged.

    ## Rewards
    ``reward = forward + energy + upright``, each term weighted, each in ``info["reward_<term>"]``:

    - ``forward``: ``forward_reward_weight * v_x / 0.1 m``, the world-x speed over the step in body lengths per second;
    - ``energy``: ``-energy_cost_weight * P``, P the mean electrical power the motors drew over the step (W;
      braking energy is not returned to the battery);
    - ``upright``: ``upright_reward_weight * u``, u the world-z component of the body's z axis (1 upright).

    ## Starting State
    Tripod A (front-left, back-left, middle-right legs) at the bottom of its stroke, the right crank half a cycle
    behind the left; crank angle and phase perturbed by ``U(-reset_noise_scale, reset_noise_scale)`` rad, body angular
    velocity by ``N(0, reset_noise_scale)`` rad/s and linear velocity by ``N(0, reset_noise_scale / 10)`` m/s.

    ## Episode End
    - terminated when the body tilts more than ``max_tilt`` (rad) from upright (``info["fallen"]``), or when the
      simulation goes numerically unstable (``info["sim_unstable"]``; the last finite observation is returned with
      reward 0, and ``info`` holds only ``sim_unstable``, ``fallen`` and ``time``: MuJoCo has reset the state, so
      there is no velocity or power to report);
    - truncated at the registration's time limit: 10 s (500 steps in gait mode, 10000 in duty mode).

    ## Info
    ``x_position``, ``y_position``, ``z_position``, ``quaternion``, ``x_velocity``, ``y_velocity``, ``yaw``,
    ``yaw_rate``, ``up_z``, ``power`` (W), ``time``, ``fallen``, ``sim_unstable`` and the reward terms.

    ## Arguments
    ``gymnasium.make("skitter/RoachWalk-v0", **kwargs)``: ``action_mode``, ``control_freq`` (Hz; default 50 in gait
    mode, 1000 in duty mode), ``privileged_obs``, ``forward_reward_weight`` (1.0), ``energy_cost_weight`` (0.1 per W),
    ``upright_reward_weight`` (1.0), ``max_tilt`` (1.4 rad), ``reset_noise_scale`` (0.1), ``battery_voltage`` (V,
    default the model's 3.7), ``telemetry`` (record telemetry, see docs/telemetry.md), ``render_mode``
    (``"human"``, ``"rgb_array"``), ``width``, ``height``.

    ## Version History
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: ActionMode = "gait",
        control_freq: float | None = None,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = 0.1,
        upright_reward_weight: float = 1.0,
        max_tilt: float = 1.4,
        reset_noise_scale: float = 0.1,
        battery_voltage: float | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        self.forward_reward_weight = forward_reward_weight
        self.upright_reward_weight = upright_reward_weight
        super().__init__(
            action_mode=action_mode,
            control_freq=control_freq,
            privileged_obs=privileged_obs,
            energy_cost_weight=energy_cost_weight,
            max_tilt=max_tilt,
            reset_noise_scale=reset_noise_scale,
            battery_voltage=battery_voltage,
            telemetry=telemetry,
            render_mode=render_mode,
            width=width,
            height=height,
        )

    def _reward_terms(self, state: dict[str, float]) -> dict[str, float]:
        return {
            "forward": self.forward_reward_weight * state["x_velocity"] / C.LENGTH,
            "energy": -self.energy_cost_weight * state["power"],
            "upright": self.upright_reward_weight * state["up_z"],
        }
