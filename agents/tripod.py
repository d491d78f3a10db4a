"""The alternating tripod gait of the VelociRoACH (seed 000 and the lab's firmware) as reference policies.

A leg clock per side runs at stride frequency f; the right clock trails the left by a phase (pi runs straight,
other offsets turn). In gait mode the clock and its PID are the robot's firmware, so the policy only sends
(f, f, phase). In duty mode the policy is the firmware: it runs the clock and a PID per side on the measured leg
angle at the control rate and outputs the duty cycle, with a back-EMF feed-forward.

Both follow Stable-Baselines3's ``predict(observation, state, episode_start, deterministic) -> (action, state)``,
batched or not. The policy's clock lives in ``state``, so it depends only on its observations and its own clock.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs.velociroach import constants as C
from envs.velociroach.robot import wrap_angle

TURN_TABLE = Path(__file__).resolve().parent / "data" / "roach_turn_table.json"


@dataclass(frozen=True)
class RoachObsLayout:
    """What the tripod knows of the robot it drives: where to find things in its observation, its control period, and
    (for the duty-mode firmware's feed-forward) the back-EMF per unit leg speed, Ke x gear, V s/rad."""

    action_mode: str
    control_dt: float
    back_emf_per_leg_rate: float
    battery_index: int = 14
    command_index: int | None = None  # the yaw-rate command of RoachTurn

    @classmethod
    def from_env(cls, env) -> RoachObsLayout:
        base = env.unwrapped
        size = 15 + (4 if base.action_mode == "gait" else 0)
        command = size if base._command_size() else None
        robot = base.robot
        return cls(base.action_mode, base.dt, float(robot.motor_constant[0] * robot.gear), command_index=command)


class TripodGait:
    """Alternating tripod at a fixed stride frequency and left/right phase.

    Args:
        layout: observation layout and control period of the env it drives.
        frequency: stride frequency, Hz.
        phase: how far the right legs trail the left, rad (pi: alternating tripod, straight).
    """

    def __init__(self, layout: RoachObsLayout, frequency: float = 20.0, phase: float = C.STRAIGHT_PHASE):
        if not 0 <= frequency <= C.MAX_COMMAND_FREQUENCY:
            raise ValueError(f"frequency must be in [0, {C.MAX_COMMAND_FREQUENCY}] Hz, got {frequency}")
        self.layout = layout
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
        if self.layout.action_mode == "gait":
            f = self.frequency / C.MAX_COMMAND_FREQUENCY
            action = np.column_stack([np.full(len(obs), f), np.full(len(obs), f), phase / np.pi - 1.0])
            new_state = None
        else:
            action, new_state = self._duty(obs, phase, state, episode_start)
        action = action.astype(np.float32)
        return (action[0], None if new_state is None else new_state[0]) if single else (action, new_state)

    def _duty(self, obs, phase, state, episode_start):
        """One firmware tick: advance the clocks, PID on the leg angles, duty out.

        State per env: [clock_L, clock_R, integral_L, integral_R].
        """
        n = len(obs)
        measured = np.arctan2(obs[:, 2:4], obs[:, 0:2])
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
        dt = self.layout.control_dt
        omega = 2.0 * np.pi * self.frequency
        # the right clock moves toward its phase at most PHASE_SLEW, as the firmware does
        lag = wrap_angle(state[:, 0] - state[:, 1] - phase)
        correction = np.clip(lag, -C.PHASE_SLEW * dt, C.PHASE_SLEW * dt)
        state[:, 0] += omega * dt
        state[:, 1] += omega * dt + correction
        error = wrap_angle(state[:, :2] - measured)
        state[:, 2:] = np.clip(state[:, 2:] + C.PID_KI * error * dt, -C.PID_INTEGRAL_LIMIT, C.PID_INTEGRAL_LIMIT)
        clock_rate = np.column_stack([np.full(n, omega), omega + correction / dt])
        vbatt = obs[:, self.layout.battery_index : self.layout.battery_index + 1]
        feedforward = self.layout.back_emf_per_leg_rate * clock_rate / vbatt
        duty = C.PID_KP * error + state[:, 2:] + C.PID_KD * (clock_rate - obs[:, 4:6]) + feedforward
        return np.clip(duty, -1.0, 1.0), state


class TripodTurn(TripodGait):
    """The tripod that turns: it maps RoachTurn's commanded yaw rate to a left/right phase.

    The map is the yaw rate measured against phase in this simulation (the curve of seed 000 figures 16 and 17),
    written by ``benchmarks/turn_table.py`` to ``agents/data/roach_turn_table.json``; the policy inverts its monotonic
    part and clips commands beyond it.
    """

    def __init__(self, layout: RoachObsLayout, table: str | Path = TURN_TABLE):
        if layout.command_index is None:
            raise ValueError("TripodTurn needs an env with a yaw-rate command (skitter/RoachTurn-*)")
        data = json.loads(Path(table).read_text())
        super().__init__(layout, frequency=float(data["frequency_hz"]))
        phase = np.radians(np.asarray(data["monotonic"]["phase_deg"], dtype=float))
        rate = np.asarray(data["monotonic"]["yaw_rate"], dtype=float)
        order = np.argsort(rate)
        self._rates, self._phases = rate[order], phase[order]

    def __repr__(self) -> str:
        return f"TripodTurn(f={self.frequency:g} Hz, yaw rate {self._rates[0]:.2f}..{self._rates[-1]:.2f} rad/s)"

    def phase_for(self, obs: np.ndarray) -> np.ndarray:
        command = obs[:, self.layout.command_index]
        return np.interp(command, self._rates, self._phases)
