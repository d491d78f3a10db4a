"""The alternating tripod gait of the VelociRoACH ([roach-sim] and the lab's firmware) as reference policies.

A leg clock per side runs at stride frequency f; the right clock trails the left by a phase (pi runs straight,
other offsets turn). In gait mode the clock and its PID are the robot's firmware, so the policy only sends
(f, f, phase). In duty mode the policy is the firmware: it runs the clock and the firmware's PID per side on the
measured leg angle at the control rate (its 1 kHz) and outputs the duty cycle, the same voltage-mode law the gait
mode's motors run.

Both follow Stable-Baselines3's ``predict(observation, state, episode_start, deterministic) -> (action, state)``,
batched or not. They read their inputs by name from the env's observation layout, and the policy's clock lives in
``state``, so it depends only on its observations and its own clock.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs.common.robot import ActionMode
from envs.common.task import ObservationLayout
from envs.velociroach import constants
from envs.velociroach.robot import DUTY, FIRMWARE_PID, wrap_angle

TURN_TABLE = Path(__file__).resolve().parent / "turn_table.json"
WALK_FREQUENCY = 45.0  # Hz: the real robot's top stride [roach-sim, Table 1]


@dataclass(frozen=True)
class TripodContext:
    """What the tripod knows of the env it drives: the observation layout, the action mode and the control period."""

    layout: ObservationLayout
    mode: ActionMode
    control_dt: float

    @classmethod
    def from_env(cls, env) -> TripodContext:
        base = env.unwrapped
        robot = base.robot
        if robot.name != "velociroach":
            raise ValueError(f"the tripod drives a VelociRoACH, not a {robot.name}")
        return cls(base.task.layout, robot.mode, robot.control_dt)


class TripodGait:
    """Alternating tripod at a fixed stride frequency and left/right phase.

    Args:
        context: the env's layout and control period (:meth:`TripodContext.from_env`).
        frequency: stride frequency, Hz.
        phase: how far the right legs trail the left, rad (pi: alternating tripod, straight).
    """

    def __init__(self, context: TripodContext, frequency: float = 20.0, phase: float = constants.STRAIGHT_PHASE):
        if not 0 <= frequency <= constants.MAX_COMMAND_FREQUENCY:
            raise ValueError(f"frequency must be in [0, {constants.MAX_COMMAND_FREQUENCY:g}] Hz, got {frequency}")
        self.context = context
        self.frequency = float(frequency)
        self.phase = float(phase)

    def __repr__(self) -> str:
        return f"TripodGait(f={self.frequency:g} Hz, phase={np.degrees(self.phase):.0f} deg)"

    def phase_for(self, obs: np.ndarray) -> np.ndarray:
        """The phase to run for each observation in a batch (fixed here; the turning gait overrides it)."""
        return np.full(obs.shape[0], self.phase)

    def predict(
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        obs = np.asarray(observation, dtype=np.float64)
        single = obs.ndim == 1
        obs = np.atleast_2d(obs)
        phase = self.phase_for(obs)
        if self.context.mode.name == DUTY:
            action, new_state = self._duty(obs, phase, state, episode_start)
        else:
            f = np.full(len(obs), self.frequency)
            action, new_state = self.context.mode.to_action(np.column_stack([f, f, phase])), None
        action = action.astype(np.float32)
        return (action[0], None if new_state is None else new_state[0]) if single else (action, new_state)

    def _duty(self, obs, phase, state, episode_start):
        """One firmware tick: advance the clocks, PID on the leg angles, duty out.

        State per env: [clock_L, clock_R, integral_L, integral_R].
        """
        layout, n = self.context.layout, len(obs)
        measured = np.arctan2(layout.get(obs, "leg_sin"), layout.get(obs, "leg_cos"))
        if state is None:
            state = np.zeros((n, 4))
            fresh = np.ones(n, dtype=bool)
        else:
            state = np.atleast_2d(np.array(state, dtype=np.float64))
            fresh = np.zeros(n, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool)
            fresh = np.atleast_1d(fresh)
        if fresh.any():
            state[fresh, 0] = measured[fresh, 0]
            state[fresh, 1] = measured[fresh, 0] - phase[fresh]
            state[fresh, 2:] = 0.0
        dt = self.context.control_dt
        omega = 2.0 * np.pi * self.frequency
        # the right clock moves toward its phase at most PHASE_SLEW, as the firmware does
        lag = wrap_angle(state[:, 0] - state[:, 1] - phase)
        correction = np.clip(lag, -constants.PHASE_SLEW * dt, constants.PHASE_SLEW * dt)
        state[:, 0] += omega * dt
        state[:, 1] += omega * dt + correction
        error = wrap_angle(state[:, :2] - measured)
        pid = FIRMWARE_PID
        state[:, 2:] += pid.ki * error * dt
        if pid.integral_limit > 0:  # 0: unbounded, as the firmware's
            np.clip(state[:, 2:], -pid.integral_limit, pid.integral_limit, out=state[:, 2:])
        clock_rate = np.column_stack([np.full(n, omega), omega + correction / dt])
        duty = pid.kp * error + state[:, 2:] + pid.kd * (clock_rate - layout.get(obs, "leg_velocity")) + pid.feedforward
        return np.clip(duty, -1.0, 1.0), state


class TripodTurn(TripodGait):
    """The tripod that turns: it maps a commanded yaw rate to a left/right phase.

    The map is the yaw rate measured against phase in this simulation (the curve of [roach-sim, figures 16 and 17]),
    written by ``benchmarks/turn_table.py`` to ``agents/velociroach/turn_table.json``; the policy inverts its
    monotonic part and clips commands beyond it.
    """

    def __init__(self, context: TripodContext, table: str | Path = TURN_TABLE):
        if "yaw_rate_command" not in context.layout:
            raise ValueError("the turning tripod needs an env with a yaw-rate command (skitter/RoachTurn-*)")
        data = json.loads(Path(table).read_text())
        super().__init__(context, frequency=float(data["frequency_hz"]))
        phase = np.radians(np.asarray(data["monotonic"]["phase_deg"], dtype=float))
        rate = np.asarray(data["monotonic"]["yaw_rate"], dtype=float)
        order = np.argsort(rate)
        self._rates, self._phases = rate[order], phase[order]

    def __repr__(self) -> str:
        return f"TripodTurn(f={self.frequency:g} Hz, yaw rate {self._rates[0]:.2f}..{self._rates[-1]:.2f} rad/s)"

    def phase_for(self, obs: np.ndarray) -> np.ndarray:
        command = self.context.layout.get(obs, "yaw_rate_command")[:, 0]
        return np.interp(command, self._rates, self._phases)


def tripod_for(env, arg: str = "") -> TripodGait:
    """``tripod`` (straight at 45 Hz, or the turning table where the task commands a yaw rate) or ``tripod:F``."""
    context = TripodContext.from_env(env)
    if arg:
        try:
            frequency = float(arg)
        except ValueError:
            raise ValueError(f"policy 'tripod:{arg}': frequency {arg!r} is not a number") from None
        return TripodGait(context, frequency=frequency)
    if "yaw_rate_command" in context.layout:
        return TripodTurn(context)
    return TripodGait(context, frequency=WALK_FREQUENCY)
