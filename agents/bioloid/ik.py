"""The report's inverse-kinematics gait library for the Bioloid quadruped [bioloid-webots, VI.A].

Each foot follows the report's ellipse (eqs. 7-8, with its rules of thumb and the knee-limit correction of the y
radius) under its hip; the hip and knee servos come from the leg's inverse kinematics (eqs. 3-6), the knee never
bent past 90 deg (envs/bioloid/kinematics.py). The four legs run the same ellipse with the phase offsets of a gait
(``GAITS``): trot, walk, gallop, canter, pace, bound and pronk, at any stride frequency. The lower half of the
ellipse is the stance (the foot moves backward), so every gait's commanded duty factor is 0.5; docs/bioloid.md
sets the phases and duty factors beside the gait literature's.

Steering, on a turning task: the trot marks time (``STEER_STRIDE``, its feet stepping in place) and swings each foot
sideways in its stance (``IKGoals.turning``, the Four-Legged League's turn, as the soccer envs' ``commands`` mode
steers). The turn follows the commanded yaw rate (a feed-forward) plus a proportional correction on the observed
heading error. The report's Webots model steered by scaling one side's stride instead; on this model that turned less
than the full trot drifts from episode to episode (up to +-0.17 rad/s), and often the wrong way (docs/bioloid.md).

Names in the policy registry (agents/bioloid/__init__.py): ``ik-<gait>`` (at 1.5 Hz, the trot's reference) and
``ik-<gait>:<Hz>``. Every policy follows Stable-Baselines3's ``predict(observation, state, episode_start,
deterministic) -> (action, state)``, batched or not; its state is its own clock (seconds since the episode began),
which it also keeps itself, so that a caller that does not pass the state back gets the same walk.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.bioloid import constants
from envs.bioloid.gait import TROT, TROT_FREQUENCY, IKGoals
from envs.common.robot import ActionMode
from envs.common.task import ObservationLayout


@dataclass(frozen=True)
class Gait:
    """A gait: each leg's phase offset (fraction of a cycle, legs in ``LEGS`` order F_L, F_R, B_L, B_R) and the duty
    factor animals use for it (Hildebrand 1965; Alexander 1984; docs/bioloid.md); ours is 0.5 by the ellipse."""

    name: str
    phases: tuple[float, float, float, float]
    literature_duty: str


# Phase offsets: the report's Figure 29 (after Alexander [30]) as its author's Webots controller tabulates them
# (gait_phase_shift, legs FL, FR, BR, BL), here reordered to F_L, F_R, B_L, B_R.
GAITS: dict[str, Gait] = {
    g.name: g
    for g in (
        Gait("trot", TROT, "about 0.5"),
        Gait("walk", (0.0, 0.5, 0.75, 0.25), "above 0.5"),
        Gait("gallop", (0.0, 0.1, 0.5, 0.6), "below 0.5"),
        Gait("canter", (0.0, 0.3, 0.7, 0.0), "below 0.5"),
        Gait("pace", (0.0, 0.5, 0.0, 0.5), "about 0.5"),
        Gait("bound", (0.0, 0.0, 0.5, 0.5), "below 0.5"),
        Gait("pronk", (0.0, 0.0, 0.0, 0.0), "below 0.5"),
    )
}
DEFAULT_FREQUENCY = TROT_FREQUENCY  # Hz: the reference trot (the report's trot scored 11.06 at 1.5 Hz, Figure 30)
FREQUENCY_RANGE = (0.05, 5.0)  # Hz accepted by name: beyond 5 Hz the AX-12 cannot follow a 0.1 m stride
# Steering on BioloidTurn, chosen on it (seeds 1000-1019, docs/bioloid.md): the stride it turns at (0: the trot
# marks time, its feet stepping in place; longer strides drift more and track worse), the turn per rad/s of wanted
# yaw rate (2 of 1.5 and 2), the wanted yaw rate per rad of heading error, and the largest turn (past it the soccer
# gait map's turn rate falls: 0.40 rad/s at 0.75, 0.30 at 1, marking time)
STEER_STRIDE = 0.0
TURN_PER_RATE = 2.0
HEADING_GAIN = 1.0
TURN_LIMIT = 0.75


def touchdown_fraction(gait: Gait) -> np.ndarray:
    """When in the cycle each leg's foot comes down (fraction of a cycle from the clock's zero), LEGS order: the
    ellipse's phase pi (front of the stance)."""
    return np.mod(0.5 - np.asarray(gait.phases), 1.0)


def stance(gait: Gait, t: np.ndarray, frequency: float) -> np.ndarray:
    """Whether each leg is commanded in stance at times ``t`` (s): (len(t), 4) bool."""
    phase = 2.0 * np.pi * (frequency * np.asarray(t)[:, None] + np.asarray(gait.phases)[None, :])
    return np.sin(phase) < 0.0


class IKGait:
    """One gait of the report's IK library at one frequency, for a Bioloid env.

    Args:
        layout: the env's observation layout (a turning task's ``yaw_rate_command`` and ``heading_error``).
        mode: the env's action mode (goal positions in counts, normalized).
        control_dt: the control step, s.
        gait: one of ``GAITS``.
        frequency: stride frequency, Hz.
        wedge: the robot's knee wedge, rad (0 for the report's design).
        steer: follow a turning task's yaw-rate command (default: when the env commands one).
    """

    def __init__(self, layout: ObservationLayout, mode: ActionMode, control_dt: float, gait: str = "trot",
                 frequency: float = DEFAULT_FREQUENCY, wedge: float = 0.0, steer: bool | None = None):  # fmt: skip
        if gait not in GAITS:
            raise ValueError(f"gait must be one of {sorted(GAITS)}, got {gait!r}")
        low, high = FREQUENCY_RANGE
        if not (isinstance(frequency, int | float) and low <= frequency <= high):
            raise ValueError(f"frequency must be in [{low}, {high}] Hz, got {frequency!r}")
        self.layout, self.mode, self.control_dt = layout, mode, control_dt
        self.gait, self.frequency = GAITS[gait], float(frequency)
        self.steer = "yaw_rate_command" in layout if steer is None else bool(steer)
        if self.steer and "yaw_rate_command" not in layout:
            raise ValueError("steering needs an env with a yaw-rate command (skitter/BioloidTurn)")
        self.goals = IKGoals(self.gait.phases, self.frequency, wedge)
        self._clock: np.ndarray | None = None  # the clock after the last call, per row

    def __repr__(self) -> str:
        return f"IKGait({self.gait.name}, {self.frequency:g} Hz{', steering' if self.steer else ''})"

    def turn(self, obs: np.ndarray) -> np.ndarray:
        """The turn (n,) in [-TURN_LIMIT, TURN_LIMIT], > 0 left, on a turning task: the commanded yaw rate less a
        correction on the heading error, scaled to the sideways swing of ``IKGoals.turning``."""
        command = self.layout.get(obs, "yaw_rate_command")[:, 0]
        s, c = self.layout.get(obs, "heading_error").T
        return np.clip(TURN_PER_RATE * (command - HEADING_GAIN * np.arctan2(s, c)), -TURN_LIMIT, TURN_LIMIT)

    def lead_in(self, t: np.ndarray) -> np.ndarray:
        """Stride scale over the first cycle, from 0 to 1 (see :meth:`envs.bioloid.gait.IKGoals.lead_in`)."""
        return self.goals.lead_in(t)

    def counts(self, t: np.ndarray, strides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Goal counts (n, 16) at clock times ``t`` (n,) with stride factors (n, 4), and where the knee limit held a
        leg back (n, 4) (envs/bioloid/gait.py)."""
        return self.goals.counts(t, strides)

    def predict(
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The goal positions at the gait's clock; ``state`` is the clock (s) per row. Without it, the clock this
        policy kept from its last call runs on (a new policy, or a new number of rows, starts at 0): rows whose
        ``episode_start`` is set start again at 0 either way, and :meth:`reset` starts every row again."""
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
        single = np.asarray(observation).ndim == 1
        n = len(obs)
        if state is not None:
            t = np.array(np.atleast_1d(state), dtype=np.float64).reshape(n)
        elif self._clock is not None and len(self._clock) == n:
            t = self._clock.copy()
        else:
            t = np.zeros(n)
        if episode_start is not None:
            t[np.atleast_1d(np.asarray(episode_start, dtype=bool))] = 0.0
        if self.steer:
            goal = self.goals.steered(t, np.full(n, STEER_STRIDE), self.turn(obs))
        else:
            goal = self.goals.steered(t, np.ones(n))
        action = self.mode.to_action(goal).astype(np.float32)
        t = t + self.control_dt
        self._clock = t
        return (action[0], t[:1].copy()) if single else (action, t.copy())

    def reset(self) -> None:
        """Start the clock this policy keeps again at 0 (a new episode for a caller that passes no state)."""
        self._clock = None


def ik_for(env, gait: str, arg: str = "") -> IKGait:
    """``ik-<gait>`` (1.5 Hz) or ``ik-<gait>:<Hz>`` for a Bioloid env; steers on a turning task."""
    base = env.unwrapped
    robot = base.robot
    if robot.name != "bioloid":
        raise ValueError(f"the IK gait library drives a Bioloid, not a {robot.name}")
    frequency = DEFAULT_FREQUENCY
    if arg:
        try:
            frequency = float(arg)
        except ValueError:
            raise ValueError(f"policy 'ik-{gait}:{arg}': give the stride frequency in Hz after the colon") from None
    return IKGait(base.task.layout, robot.mode, robot.control_dt, gait, frequency, robot.wedge)


class IKRollouts:
    """The gait library as a controller of agents.optimize's evaluator: row i runs ``gaits[i]`` at
    ``frequencies[i]`` Hz from its own clock (as ``IKGait.predict``, lead-in included); no free parameters."""

    dimension = 0

    def __init__(self, robot, gaits: list[str], frequencies: list[float]):
        if len(gaits) != len(frequencies):
            raise ValueError("one frequency per gait")
        self.rows = [IKGait(ObservationLayout({}), robot.mode, robot.control_dt, g, f, robot.wedge, steer=False)
                     for g, f in zip(gaits, frequencies, strict=True)]  # fmt: skip
        self.control_dt = robot.control_dt
        self.t = np.zeros(len(self.rows))

    def start(self, parameters: np.ndarray) -> None:
        self.t = np.zeros(len(self.rows))

    def commands(self) -> np.ndarray:
        goals = np.empty((len(self.rows), len(constants.SERVOS)))
        for i, gait in enumerate(self.rows):
            t = self.t[i : i + 1]
            goals[i] = gait.counts(t, np.ones((1, 4)) * gait.lead_in(t)[:, None])[0][0]
        self.t = self.t + self.control_dt
        return goals

    def policy_record(self, parameters: np.ndarray) -> dict:
        return {}
