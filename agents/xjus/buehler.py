"""The report's controller as reference policies for xJüs: stand, walk and turn [xjus-report, sections 2.4 and 2.5].

Three stages: the Buehler clock's target per leg (the Fourier series, M = 10, tripods half a cycle apart), PD
feedback on the leg angle giving a desired torque and, through the report's motor model inverted, the voltage Vpd and
duty d = Vpd / Vs; then the motor model itself, in the simulation (envs/xjus/controller.py has the stages). In the
env's ``gait`` action mode the robot runs the first two stages itself and the policy only sends the clock's period
and sweep angles; in ``duty`` mode the policy runs them on its observations and its own clock and sends the duty.

Routines (the report's keyboard commands):

- ``stand``: every leg to pointing down and held there (duty mode only: the gait mode's clock always runs);
- ``walk``: the alternating tripod at period T (default 0.5 s) and ground sweep 60 deg on both sides;
- ``turn``: the same tripod with a different sweep per side: the side with the larger sweep sweeps the ground faster
  and the robot turns away from it. The sweep difference is a feed-forward from the commanded yaw rate plus a
  proportional correction on the observed heading error (the integrated gyro against the commanded heading).

All follow Stable-Baselines3's ``predict(observation, state, episode_start, deterministic) -> (action, state)``,
batched or not, and read their inputs by name from the env's observation layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.common.robot import ActionMode
from envs.common.task import ObservationLayout
from envs.xjus import constants
from envs.xjus.controller import Gait, MotorArrays, pd_torque, stand_targets, wrap_angle
from envs.xjus.robot import DUTY, GAIT

WALK_PERIOD = 0.5  # s: RHex-like speed (measured 0.6 m/s on flat ground, docs/xjus.md)
TURN_PERIOD = 0.5  # s: the differential sweep turns most at the faster clock (docs/xjus.md)
TURN_GAIN = 0.45  # rad/s of yaw rate per rad of sweep difference at T = 0.5 s (measured, docs/xjus.md)
HEADING_GAIN = 1.0  # rad of sweep difference per rad of heading error (1.5 overshot: docs/xjus.md)
MAX_SWEEP_DIFFERENCE = np.radians(60.0)  # keeps both sweeps within 30 to 90 deg around 60 deg
ROUTINES = ("stand", "walk", "turn")


@dataclass(frozen=True)
class XjusContext:
    """What the controller knows of the env it drives: the observation layout, the action mode, the control period,
    the legs' inertia about the hips and the motors' nominal constants (the supply voltage it reads)."""

    layout: ObservationLayout
    mode: ActionMode
    control_dt: float
    hip_inertia: np.ndarray
    motor_resistance: float
    amplifier_resistance: float
    torque_per_amp: float
    speed_constant: float

    @classmethod
    def from_env(cls, env) -> XjusContext:
        base = env.unwrapped
        robot = base.robot
        if robot.name != "xjus":
            raise ValueError(f"the Buehler-clock controller drives an xJüs, not a {robot.name}")
        c = robot.constants
        return cls(base.task.layout, robot.mode, robot.control_dt, robot.hip_inertia.copy(), c.motor_resistance,
                   c.amplifier_resistance, c.torque_per_amp, c.speed_constant)  # fmt: skip

    def motors(self, supply: np.ndarray) -> MotorArrays:
        n = len(supply)
        return MotorArrays(supply, np.full(n, self.motor_resistance), np.full(n, self.amplifier_resistance),
                           np.full(n, self.torque_per_amp), np.full(n, self.speed_constant))  # fmt: skip


class BuehlerController:
    """One routine of the report's controller.

    Args:
        context: the env's layout and constants (:meth:`XjusContext.from_env`).
        routine: ``"stand"``, ``"walk"`` or ``"turn"``.
        period: the clock's period T, s.
        sweep: the ground sweep angle theta_g, rad (walking; turning centres its two sweeps on it).
    """

    def __init__(self, context: XjusContext, routine: str = "walk", period: float = WALK_PERIOD,
                 sweep: float = constants.WALK_SWEEP):  # fmt: skip
        if routine not in ROUTINES:
            raise ValueError(f"routine must be one of {ROUTINES}, got {routine!r}")
        if not constants.PERIOD_RANGE[0] <= period <= constants.PERIOD_RANGE[1]:
            raise ValueError(
                f"period must be in [{constants.PERIOD_RANGE[0]}, {constants.PERIOD_RANGE[1]}] s, got {period!r}"
            )
        if not constants.SWEEP_RANGE[0] <= sweep <= constants.SWEEP_RANGE[1]:
            raise ValueError(f"sweep must be in [0, pi/2] rad, got {sweep!r}")
        if routine == "stand" and context.mode.name == GAIT:
            raise ValueError("the stand routine needs action_mode='duty': the gait mode's clock always runs")
        if routine == "turn" and "yaw_rate_command" not in context.layout:
            raise ValueError("the turn routine needs an env with a yaw-rate command (skitter/XjusTurn-v2)")
        self.context, self.routine = context, routine
        self.period, self.sweep = float(period), float(sweep)
        self.gait = Gait.tripod()
        # the gait mode's walk sends the same action at every step: computed once (float32), copied out per call
        self._constant: np.ndarray | None = None

    def __repr__(self) -> str:
        return f"BuehlerController({self.routine}, T={self.period:g} s, sweep={np.degrees(self.sweep):.0f} deg)"

    def sweeps(self, obs: np.ndarray) -> np.ndarray:
        """Ground sweep of the left and right legs per observation, (n, 2), rad."""
        n = len(obs)
        if self.routine != "turn":
            return np.full((n, 2), self.sweep)
        layout = self.context.layout
        command = layout.get(obs, "yaw_rate_command")[:, 0]
        s, c = layout.get(obs, "heading_error").T
        difference = command / TURN_GAIN - HEADING_GAIN * np.arctan2(s, c)
        half = 0.5 * np.clip(difference, -MAX_SWEEP_DIFFERENCE, MAX_SWEEP_DIFFERENCE)
        return np.clip(np.column_stack([self.sweep - half, self.sweep + half]), *constants.SWEEP_RANGE)

    def predict(
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        if self.routine == "walk" and self.context.mode.name == GAIT:
            return self._walk_action(observation)
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs = np.atleast_2d(obs)
        sweeps = self.sweeps(obs)
        if self.context.mode.name == DUTY:
            action, new_state = self._duty(obs, sweeps, state, episode_start)
        else:
            period = np.full((len(obs), 1), self.period)
            action, new_state = self.context.mode.to_action(np.column_stack([period, sweeps])), None
        action = action.astype(np.float32)
        return (action[0], None if new_state is None else new_state[0]) if single else (action, new_state)

    def _walk_action(self, observation: np.ndarray) -> tuple[np.ndarray, None]:
        """The gait mode's walk: the clock's period and one sweep on both sides, whatever the observation (its
        shape only: one action per observation), the same action every step."""
        if self._constant is None:
            command = np.array([[self.period, self.sweep, self.sweep]])
            self._constant = self.context.mode.to_action(command)[0]
        shape = np.shape(observation)
        if len(shape) == 1:
            return self._constant.copy(), None
        return np.tile(self._constant, (shape[0] if shape else 1, 1)), None

    def _duty(self, obs, sweeps, state, episode_start):
        """One logic step: the clock's targets, the PD, the motor model inverted; state per env: the clock phase
        (cycles since tripod A began its stance; 0.25 at the env's starting pose)."""
        n = len(obs)
        layout, ctx = self.context.layout, self.context
        if state is None:
            phase, fresh = np.zeros(n), np.ones(n, dtype=bool)
        else:
            phase = np.array(np.atleast_1d(state), dtype=np.float64).reshape(n)
            fresh = np.zeros(n, dtype=bool) if episode_start is None else np.atleast_1d(np.asarray(episode_start, bool))
        phase[fresh] = 0.25
        angle = np.arctan2(layout.get(obs, "leg_sin"), layout.get(obs, "leg_cos"))
        speed = layout.get(obs, "leg_velocity")
        period = np.full(n, self.period)
        if self.routine == "stand":
            target, rate, accel = stand_targets(n, len(constants.LEGS))
        else:
            target, rate, accel = self.gait.targets(phase, period, sweeps)
        torque = pd_torque(
            wrap_angle(target - angle), rate - speed, accel, ctx.hip_inertia, constants.PD_KP, constants.PD_KD
        )
        duty = ctx.motors(layout.get(obs, "battery")[:, 0]).duty_for_torque(torque, speed)
        if self.routine != "stand":
            phase = np.mod(phase + ctx.control_dt / period, 1.0)
        return duty, phase


def buehler_for(env, arg: str = "") -> BuehlerController:
    """``buehler`` (walk at T = 0.5 s; turn where the task commands a yaw rate), ``buehler:stand``,
    ``buehler:walk``, ``buehler:turn`` or ``buehler:T`` (walk at period T, s)."""
    context = XjusContext.from_env(env)
    if arg in ROUTINES:
        return BuehlerController(context, arg, TURN_PERIOD if arg == "turn" else WALK_PERIOD)
    if arg:
        try:
            period = float(arg)
        except ValueError:
            raise ValueError(
                f"policy 'buehler:{arg}': give a routine ({', '.join(ROUTINES)}) or a period in s"
            ) from None
        return BuehlerController(context, "walk", period)
    if "yaw_rate_command" in context.layout:
        return BuehlerController(context, "turn", TURN_PERIOD)
    return BuehlerController(context, "walk", WALK_PERIOD)
