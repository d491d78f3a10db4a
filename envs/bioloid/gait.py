"""The report's inverse-kinematics gait as goal positions [bioloid-webots, VI.A]: what the IK gait library
(agents/bioloid/ik.py) and the soccer envs' ``commands`` mode drive the Bioloid with.

Each foot follows the report's ellipse (eqs. 7-8) under its hip, at the gait's phase offset; the hip and knee servos
come from the leg's inverse kinematics (eqs. 3-6, envs/bioloid/kinematics.py). A stride factor per leg scales the
ellipse's x radius: 1 walks straight, 0 marks time. A turn in [-1, 1] swings each foot sideways in its stance
(:meth:`IKGoals.turning`): the Four-Legged League quadrupeds' way of turning (Hengst, Ibbotson, Pham, Sammut,
"Omnidirectional locomotion for quadruped robots", RoboCup 2001, LNAI 2377); the report's gait only walks straight.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from envs.bioloid import constants
from envs.bioloid.kinematics import Ellipse, LegGeometry

TROT = (0.0, 0.5, 0.5, 0.0)  # phase offsets, legs F_L, F_R, B_L, B_R: diagonal pairs together
TROT_FREQUENCY = 1.5  # Hz: the reference trot (the report's trot scored best at 1.5 Hz, Figure 30)
# rad of abduction swing either way at |turn| = 1 (the foot about 5 cm sideways at the sole, 0.16 m below the
# abduction axis; assets/bioloid/bioloid.xml): chosen on the soccer gait map, where larger swings turned no faster
TURN_ABDUCTION = 0.3
_FRONT = np.array([1.0 if leg.startswith("F") else -1.0 for leg in constants.LEGS])
_ABDUCTION = np.array([constants.SERVO_INDEX[constants.ABDUCTION[leg]] for leg in constants.LEGS])


class IKGoals:
    """Goal counts of the IK gait with phase offsets ``phases`` (LEGS order) at ``frequency`` Hz, for a robot with
    knee wedge ``wedge`` (rad)."""

    def __init__(self, phases: Sequence[float], frequency: float, wedge: float = 0.0):
        self.frequency = float(frequency)
        self.geometry = [LegGeometry.of(leg, wedge) for leg in constants.LEGS]
        self.ellipses = [Ellipse.seed_rules(g) for g in self.geometry]
        stand = np.array([constants.STAND_ANGLES[s] for s in constants.SERVOS])
        self.stand_counts = constants.CENTER + stand / constants.RAD_PER_COUNT
        self._hips = np.array([constants.SERVO_INDEX[constants.HIP[leg]] for leg in constants.LEGS])
        self._knees = np.array([constants.SERVO_INDEX[constants.KNEE[leg]] for leg in constants.LEGS])
        self._phases = np.asarray(phases, dtype=np.float64)
        # every leg in one numpy call (the same arithmetic as leg by leg)
        self._legs, self._ellipses = LegGeometry.stack(self.geometry), Ellipse.stack(self.ellipses)

    def lead_in(self, t: np.ndarray) -> np.ndarray:
        """Stride scale over the first cycle, from 0 to 1: the gait starts from the ready posture (every sole at the
        ellipse's centre) instead of jumping to its phases."""
        return np.minimum(1.0, self.frequency * t)

    def phase(self, t: np.ndarray) -> np.ndarray:
        """Each leg's phase on its ellipse (n, 4), rad, at clock times ``t`` (n,): the stance is where its sine is
        negative, from touch-down at pi to lift-off at 2 pi."""
        return 2.0 * np.pi * (self.frequency * t[:, None] + self._phases[None, :])

    def counts(self, t: np.ndarray, strides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Goal counts (n, 16) at clock times ``t`` (n,) with stride factors (n, 4), and where the knee limit held a
        leg back (n, 4)."""
        phase = self.phase(t)
        goal = np.tile(self.stand_counts, (len(t), 1))
        x, z = self._ellipses.point(phase, strides)
        hip, knee, limited = self._legs.inverse(x, z)
        goal[:, self._hips] = constants.CENTER + hip / constants.RAD_PER_COUNT
        goal[:, self._knees] = constants.CENTER + knee / constants.RAD_PER_COUNT
        return goal, limited

    def steered(self, t: np.ndarray, stride: np.ndarray, turn: np.ndarray | None = None) -> np.ndarray:
        """Goal counts (n, 16) at clock times ``t`` (n,), the lead-in applied: every leg at stride factor ``stride``
        (n,), turned by ``turn`` (n,; :meth:`turning`; None walks straight)."""
        lead = self.lead_in(t)
        goal, _ = self.counts(t, np.repeat((np.asarray(stride) * lead)[:, None], len(constants.LEGS), axis=1))
        if turn is not None:
            self.turning(goal, t, np.asarray(turn) * lead)
        return goal

    def turning(self, goal: np.ndarray, t: np.ndarray, turn: np.ndarray) -> None:
        """Turn the gait's goal counts ``goal`` (n, 16) at clock times ``t`` (n,) in place by ``turn`` (n,) in
        [-1, 1] (> 0 turns left): each sole swings sideways with its place along its stride, +1 at touch-down to -1
        at lift-off; turning left, a front foot steps from its left to its right in the stance (it pushes the body's
        front to the left) and a back foot the other way. An abduction of +0.1 rad moves a sole 1.6 cm to the
        robot's right on every leg."""
        along = -np.cos(self.phase(t))
        leftward = np.asarray(turn)[:, None] * TURN_ABDUCTION * _FRONT[None, :] * along
        goal[:, _ABDUCTION] -= leftward / constants.RAD_PER_COUNT
