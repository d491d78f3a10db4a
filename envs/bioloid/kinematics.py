"""A Bioloid leg in its sagittal plane: forward and inverse kinematics of hip pitch (servo 1) and knee (servo 3).

With servo 2 holding a leg straight down (the standing posture), servo 1 and the knee both turn the leg about the
body's +y axis; positive angles swing the foot backward (assets/bioloid/bioloid.xml). In the plane through the hip
pitch axis (x forward, z up), the thigh runs from the pitch axis to the knee (0.0145 m to the abduction axis, 0.083 m
on to the knee: L1 = 0.0975 m) and the shank from the knee to the sole (0.085 m; the back crutches 0.0145 m behind the
knee line: their shank is the vector (-0.0145, -0.085) turned with the knee). An optional wedge turns every shank by a
fixed angle about its knee [bioloid-webots, IV.A].

Inverse kinematics as [bioloid-webots, eqs. 3-6] solve it (the law of cosines for the knee, then the hip), with the
knee bent forward-of-the-foot (a positive knee angle, as the report's model bends it) and never past ``KNEE_LIMIT`` (eq.
3's angle clipped: the report's Figure 27 shows the servo value flat at that limit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.bioloid import constants


@dataclass(frozen=True)
class LegGeometry:
    """One leg's sagittal geometry.

    Attributes:
        thigh: hip pitch axis to knee, m.
        shank: knee to sole along the leg, m.
        offset: the sole's offset along x of the shank frame (back legs: -0.0145 m), m.
        wedge: the shank's fixed turn about the knee, rad (0 without the wedge).
    """

    thigh: float = constants.ABDUCTION_DROP + constants.THIGH
    shank: float = constants.SHANK
    offset: float = 0.0
    wedge: float = 0.0

    @classmethod
    def of(cls, leg: str, wedge: float = 0.0) -> LegGeometry:
        return cls(offset=-constants.BACK_CRUTCH_OFFSET if leg.startswith("B") else 0.0, wedge=wedge)

    @classmethod
    def stack(cls, legs: list[LegGeometry]) -> LegGeometry:
        """Several legs as one geometry of arrays (one entry per leg), whose kinematics take (..., legs) arrays: the
        same arithmetic, one numpy call for every leg instead of one per leg."""
        return cls(*(np.array([getattr(g, f) for g in legs]) for f in ("thigh", "shank", "offset", "wedge")))

    @property
    def shank_length(self) -> float | np.ndarray:
        """Knee to sole, straight, m."""
        return np.hypot(self.shank, self.offset)[()]

    @property
    def shank_angle(self) -> float | np.ndarray:
        """The angle by which the offset sole sits behind the shank's axis, rad (0 for the front legs)."""
        return np.arctan2(-self.offset, self.shank)[()]

    def forward(self, hip: np.ndarray, knee: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sole position (x, z) relative to the hip pitch axis from servo angles (rad)."""
        ls, psi = self.shank_length, hip + knee + self.wedge + self.shank_angle
        x = -self.thigh * np.sin(hip) - ls * np.sin(psi)
        z = -self.thigh * np.cos(hip) - ls * np.cos(psi)
        return x, z

    def inverse(self, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Servo angles (hip, knee), rad, that put the sole at (x, z), and where the knee limit held it back.

        Eq. 3 (law of cosines) gives the bend between thigh and shank, eq. 4 the hip angle; a target out of reach is
        approached along its direction; the knee servo is clipped to [-KNEE_EXTENSION, KNEE_LIMIT]."""
        l1, ls = self.thigh, self.shank_length
        x, z = np.asarray(x, dtype=np.float64), np.asarray(z, dtype=np.float64)
        r2 = x * x + z * z
        cos_bend = np.clip((r2 - l1 * l1 - ls * ls) / (2.0 * l1 * ls), -1.0, 1.0)
        bend = np.arccos(cos_bend)  # >= 0: the foot behind the thigh's line, as the report's Figure 27 bends it
        knee = bend - self.wedge - self.shank_angle
        limited = knee > constants.KNEE_LIMIT + 1e-9  # the ellipse's top reaches the limit exactly
        knee = np.clip(knee, -constants.KNEE_EXTENSION, constants.KNEE_LIMIT)
        bend = knee + self.wedge + self.shank_angle
        hip = np.arctan2(-x, -z) - np.arctan2(ls * np.sin(bend), l1 + ls * np.cos(bend))
        return hip, knee, limited


@dataclass(frozen=True)
class Ellipse:
    """The report's foot trajectory (eqs. 7-8) with its rules of thumb [bioloid-webots, VI.A.2]: centre (h, k) =
    (0, -(L1 + L2/2)), x radius a = 0.95 L1/2 and, corrected for the knee limit, y radius b = -k - sqrt(L1^2 + L2^2),
    so that the top of the ellipse is where the knee is bent 90 deg. L1 and L2 are this model's thigh and shank."""

    h: float
    k: float
    a: float
    b: float

    @classmethod
    def seed_rules(cls, geometry: LegGeometry) -> Ellipse:
        l1, l2 = geometry.thigh, geometry.shank_length
        k = -(l1 + l2 / 2.0)
        return cls(h=0.0, k=k, a=0.95 * l1 / 2.0, b=-k - float(np.hypot(l1, l2)))

    @classmethod
    def stack(cls, ellipses: list[Ellipse]) -> Ellipse:
        """Several legs' ellipses as one of arrays (one entry per leg): :meth:`point` then takes (..., legs)."""
        return cls(*(np.array([getattr(e, f) for e in ellipses]) for f in ("h", "k", "a", "b")))

    def point(self, phase: np.ndarray, stride: np.ndarray | float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """The sole's target at ``phase`` (rad): x = h - a s cos(phase), z = k + b sin(phase), ``s`` the stride
        scale. The lower half (sin < 0) is the stance, where the foot moves backward (for s > 0) and the body
        forward; touch-down at phase pi, lift-off at 0."""
        return self.h - self.a * stride * np.cos(phase), self.k + self.b * np.sin(phase)
