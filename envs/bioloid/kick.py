"""A kick with a front leg, as goal positions: what the soccer envs' ``commands`` mode runs when a player kicks.

The report's robot walks and was to play soccer, but "has to [...] detect the ball [...] and try to kick it"
[bioloid-webots, VII]: it has no kick. This one is built on the report's leg kinematics (envs/bioloid/kinematics.py)
and the IK gait's ready posture (every sole at its ellipse's centre, under its hip). Lifting a front leg from
four-legged support leaves the centre of mass on the diagonal between the two other corners' feet, so the kick first
leans: the body moves back (every sole forward) and the back corner diagonal to the kicking leg, on the standing
front leg's side, lowers (that back leg's sole rises toward its hip), which tips the centre of mass onto the three
standing feet. Then the kicking sole lifts, strikes forward at the ball's height, comes back and sets down, and the
robot returns to the ready posture.

The shape's numbers were found on the model by a random search and CMA-ES over these keyframes (ball speed, its
direction and the body's drift, over ball places and seeds; a fall disqualifies), 2026-11-29. What the kick does,
measured on the model: ``python -m benchmarks.bioloid_kick`` (``benchmarks/results/bioloid_kick.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.bioloid import constants
from envs.bioloid.gait import IKGoals
from envs.bioloid.kinematics import Ellipse, LegGeometry

LEFT, RIGHT = 1.0, -1.0  # the kicking leg's side, as the sign of y in the robot's frame (+y is its left)


@dataclass(frozen=True)
class KickShape:
    """The kick's keyframes, for a kick with the right front leg (the left one's mirror it). Lengths in m in each
    leg's sagittal plane (x forward of its hip, z up from it), times in s.

    Attributes:
        lean_back: every standing sole's x moves forward by this (the body moves back).
        lean_corner: the back leg diagonal to the kicking one (the back-left for a right kick) shortens by
            this: its corner lowers and the body tips toward it.
        lift: the kicking sole's rise above the ready posture before the strike.
        reach: the kicking sole's x at the strike's end.
        strike_height: the kicking sole's z at the strike's end (the ready posture's sole is at the ellipse's
            centre, 0.14 m below the hip; a ball's centre is its radius above the ground).
        lean_time, lift_time, strike_time, return_time, set_time: the phases' lengths: leaning, lifting the sole,
            the strike, bringing it back above the ground, setting it down; the robot then returns to the ready
            posture over ``lean_time``.
    """

    lean_back: float = 0.046
    lean_corner: float = 0.054
    lift: float = 0.024
    reach: float = 0.096
    strike_height: float = -0.101
    lean_time: float = 0.39
    lift_time: float = 0.10
    strike_time: float = 0.08
    return_time: float = 0.25
    set_time: float = 0.20

    @property
    def duration(self) -> float:
        """From the first goal to the ready posture again, s."""
        return 2.0 * self.lean_time + self.lift_time + self.strike_time + self.return_time + self.set_time


KICK = KickShape()
# Where the ball's centre must lie in the robot's frame when a kick starts from the ready posture for the kick to send
# it straight (within 15 deg) at 2 m/s or more, without a fall (benchmarks/results/bioloid_kick.md): this far ahead of
# the body's centre, m, and this far to the kicking leg's side (the front soles' y is 0.092 m), within
# ``KICK_WIDTH``. Nearer than 0.14 m the shin lands on the ball and the robot can fall; at 0.16 m the foot only pushes
# it (0.5-0.7 m/s); 0.07 m aside or less, or 0.12 m or more, it goes off at 30 deg and more. In matches the scripted
# Bioloid kicking in this zone scored more than kicking in a wider one, whose kicks went off line (2026-11-29)
KICK_AHEAD = (0.14, 0.15)
KICK_SIDE = 0.10
KICK_WIDTH = 0.015


def _smooth(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


class Kick:
    """Goal counts of the kick, for a robot with knee wedge ``wedge`` (rad)."""

    def __init__(self, wedge: float = 0.0, shape: KickShape = KICK):
        self.shape = shape
        self.duration = shape.duration
        legs = [LegGeometry.of(leg, wedge) for leg in constants.LEGS]
        self._legs = LegGeometry.stack(legs)
        self._ready_z = np.array([Ellipse.seed_rules(g).k for g in legs])
        self._ready = IKGoals((0.0,) * len(constants.LEGS), 1.0, wedge).counts(np.zeros(1), np.zeros((1, 4)))[0][0]
        self._hips = np.array([constants.SERVO_INDEX[constants.HIP[leg]] for leg in constants.LEGS])
        self._knees = np.array([constants.SERVO_INDEX[constants.KNEE[leg]] for leg in constants.LEGS])
        front = np.array([leg.startswith("F") for leg in constants.LEGS])
        left = np.array([constants.LEG_SIDE[leg] == "left" for leg in constants.LEGS])
        # per side of the kick (index 0 a left kick, 1 a right kick): the kicking leg, and the corner that lowers
        self._kicker = np.array([front & left, front & ~left])
        self._corner = np.array([~front & ~left, ~front & left])
        s = shape
        self._times = np.cumsum([0.0, s.lean_time, s.lift_time, s.strike_time, s.return_time, s.set_time,
                                 s.lean_time])  # fmt: skip

    @property
    def ready(self) -> np.ndarray:
        """The ready posture's goal counts (16,), where the kick starts and ends."""
        return self._ready.copy()

    def counts(self, t: np.ndarray, side: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
        """Goal counts (n, 16) at times ``t`` (n,) since each kick started, for kicks with the leg on ``side`` (n,):
        :data:`LEFT` or :data:`RIGHT`; before 0 and after the kick's duration, the ready posture. ``start`` (n, 16):
        the goals each kick starts from (where a gait left the legs), blended into the kick's over its lean."""
        t = np.asarray(t, dtype=np.float64)
        right = np.asarray(side, dtype=np.float64) < 0.0
        s, k = self.shape, self._times
        lean = _smooth(t / s.lean_time) * (1.0 - _smooth((t - k[5]) / s.lean_time))  # in, then out at the end
        x = np.repeat((s.lean_back * lean)[:, None], 4, axis=1)
        z = np.repeat(self._ready_z[None, :], len(t), axis=0)
        corner = self._corner[right.astype(int)]
        z = z + np.where(corner, s.lean_corner * lean[:, None], 0.0)
        # the kicking sole: from the leaned stand up to the lift, out to the strike, back above the ground, down
        ready_z = self._ready_z[0]
        # the kicking sole's frames at the ends of the lean, the lift, the strike, the way back and the setting down
        frames_x = np.array([s.lean_back, 0.0, s.reach, s.lean_back, s.lean_back])
        frames_z = np.array([ready_z, ready_z + s.lift, s.strike_height, ready_z + 0.01, ready_z])
        phase = np.clip(np.searchsorted(k[1:6], t, side="right") - 1, 0, 3)  # 0 lift, 1 strike, 2 back, 3 set down
        u = _smooth((t - k[1 + phase]) / (k[2 + phase] - k[1 + phase]))
        moving = (t >= k[1]) & (t < k[5])  # outside, the kicking leg leans with the others
        kick_x = np.where(moving, frames_x[phase] + u * (frames_x[phase + 1] - frames_x[phase]), x[:, 0])
        kick_z = np.where(moving, frames_z[phase] + u * (frames_z[phase + 1] - frames_z[phase]), ready_z)
        kicker = self._kicker[right.astype(int)]
        x = np.where(kicker, kick_x[:, None], x)
        z = np.where(kicker, kick_z[:, None], z)
        hip, knee, _ = self._legs.inverse(x, z)
        goal = np.tile(self._ready, (len(t), 1))
        goal[:, self._hips] = constants.CENTER + hip / constants.RAD_PER_COUNT
        goal[:, self._knees] = constants.CENTER + knee / constants.RAD_PER_COUNT
        if start is not None:
            goal += (1.0 - _smooth(t / s.lean_time))[:, None] * (np.asarray(start) - self._ready)
        return goal
