"""Seeded terrains as MuJoCo height fields, for any robot: rough ground, a step, stairs and an obstacle course.

A :class:`Terrain` is a field of parallel lanes along +x, each starting on a level pad at x = 0 and ``lane_width``
apart in y. The roughness is a Gaussian random field (white noise through a Gaussian filter, ``scipy.ndimage``) scaled
to the RMS height asked for; the obstacles run across every lane at the same x, so that progress over them compares
between lanes and settings. The whole field is one height field in the compiled model: nothing writes the model
during an episode, a batch of simulations shares it, and a robot starts an episode at one of the lanes
(``terrain.starts()``), so that lane ``k`` of ``seed`` is the same ground for every robot setting.

Heights are in metres with the start pad at z = 0; the floor plane of the scene is lowered under the height field.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy import ndimage
from scipy.interpolate import RectBivariateSpline

OBSTACLES = ("none", "step", "stairs", "course")
GEOM = "terrain"


def _check(name: str, value: float, low: float, high: float) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (np.isfinite(x) and low <= x <= high):
        raise ValueError(f"{name} must be in [{low}, {high}], got {value!r}")
    return x


FLOOR_BELOW = 0.05  # m: the scene's floor plane lies this far under the height field's lowest point


@dataclass(frozen=True)
class Terrain:
    """A seeded field of lanes with rough ground and obstacles.

    Attributes:
        roughness: RMS height of the random ground, m (0: level).
        correlation: correlation length of the roughness (the Gaussian filter's sigma), m.
        obstacle: ``"none"``, ``"step"`` (one step up of ``step_height`` at ``obstacle_x``), ``"stairs"``
            (``stair_count`` steps up of ``step_height``, ``stair_run`` deep, from ``obstacle_x``) or ``"course"``
            (see :meth:`obstacle_profile`).
        step_height: height of the step or of each stair, m.
        obstacle_x: where the step or the stairs begin, m from the start.
        stair_count, stair_run: number of stairs and the depth of each, m.
        seed: the random field's seed.
        lanes, lane_width: number of lanes and their spacing, m.
        length: how far each lane runs from the start, m.
        behind: level ground behind the start, m.
        pad: level ground ahead of the start, m, before the roughness ramps in over another ``pad``.
        resolution: grid spacing, m.
    """

    roughness: float = 0.0
    correlation: float = 0.1
    obstacle: str = "none"
    step_height: float = 0.05
    obstacle_x: float = 2.0
    stair_count: int = 4
    stair_run: float = 0.3
    seed: int = 0
    lanes: int = 24
    lane_width: float = 1.5
    length: float = 10.0
    behind: float = 1.0
    pad: float = 0.4
    resolution: float = 0.04

    def __post_init__(self) -> None:
        _check("roughness", self.roughness, 0.0, 0.5)
        _check("correlation", self.correlation, 1e-3, 10.0)
        if self.obstacle not in OBSTACLES:
            raise ValueError(f"obstacle must be one of {OBSTACLES}, got {self.obstacle!r}")
        _check("step_height", self.step_height, 0.0, 1.0)
        _check("obstacle_x", self.obstacle_x, 0.0, self.length)
        _check("stair_run", self.stair_run, 1e-3, 10.0)
        _check("lane_width", self.lane_width, 0.1, 100.0)
        _check("length", self.length, 0.5, 1000.0)
        _check("behind", self.behind, 0.1, 100.0)
        _check("pad", self.pad, 0.0, 10.0)
        _check("resolution", self.resolution, 1e-3, 1.0)
        for name, least in (("stair_count", 1), ("lanes", 1), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < least:
                raise ValueError(f"{name} must be a whole number >= {least}, got {value!r}")

    # --- geometry ---------------------------------------------------------------------------------------------
    @property
    def width(self) -> float:
        return self.lanes * self.lane_width

    def grid(self) -> tuple[np.ndarray, np.ndarray]:
        """The x (ncol,) and y (nrow,) of the grid points, m."""
        ncol = round((self.length + self.behind) / self.resolution) + 1
        nrow = round(self.width / self.resolution) + 1
        return np.linspace(-self.behind, self.length, ncol), np.linspace(-self.width / 2, self.width / 2, nrow)

    def starts(self) -> np.ndarray:
        """Where each lane starts, (lanes, 2): x = 0, y at the lane's centre."""
        y = -self.width / 2 + (np.arange(self.lanes) + 0.5) * self.lane_width
        return np.column_stack([np.zeros(self.lanes), y])

    def lane_of(self, y: np.ndarray) -> np.ndarray:
        """The lane a y position lies in (clipped to the field)."""
        lane = np.floor((np.asarray(y) + self.width / 2) / self.lane_width).astype(int)
        return np.clip(lane, 0, self.lanes - 1)

    def obstacle_profile(self, x: np.ndarray) -> np.ndarray:
        """Height of the obstacles along x, m (the same across every lane).

        ``course``, in the spirit of the report's Figure 7 (an image only): from 1.0 m a 0.3 m long, 0.04 m tall
        bump (a cosine hill), at 1.8 m a step up of ``step_height``, at 2.6 m a log (0.06 m half-cylinder of radius
        0.06 m) on the plateau, at 3.4 m a step back down, from 4.0 m a 1:6 ramp up 0.1 m, 0.6 m level, a 1:6 ramp
        down, then from 6.0 m three 0.03 m ridges 0.5 m apart.
        """
        x = np.asarray(x, dtype=np.float64)
        h = np.zeros_like(x)
        if self.obstacle == "step":
            h = np.where(x >= self.obstacle_x, self.step_height, 0.0)
        elif self.obstacle == "stairs":
            steps = np.floor((x - self.obstacle_x) / self.stair_run) + 1
            h = self.step_height * np.clip(steps, 0, self.stair_count)
        elif self.obstacle == "course":
            bump = (x >= 1.0) & (x <= 1.3)
            h = h + np.where(bump, 0.02 * (1 - np.cos(2 * np.pi * (x - 1.0) / 0.3)), 0.0)
            plateau = (x >= 1.8) & (x < 3.4)
            h = h + np.where(plateau, self.step_height, 0.0)
            log = np.abs(x - 2.6) < 0.06
            h = h + np.where(log, np.sqrt(np.maximum(0.06**2 - (x - 2.6) ** 2, 0.0)), 0.0)
            ramp = np.clip((x - 4.0) / 0.6, 0, 1) - np.clip((x - 5.2) / 0.6, 0, 1)
            h = h + 0.1 * ramp
            for ridge in (6.0, 6.5, 7.0):
                h = h + np.where(np.abs(x - ridge) < 0.03, 0.03, 0.0)
        return h

    def obstacle_end(self) -> float:
        """x beyond which the robot has crossed the step or the stairs (inf for none; the course's last ridge)."""
        if self.obstacle == "step":
            return self.obstacle_x + 0.3
        if self.obstacle == "stairs":
            return self.obstacle_x + self.stair_count * self.stair_run
        if self.obstacle == "course":
            return 7.1
        return float("inf")

    def heights(self) -> np.ndarray:
        """The height field, (nrow, ncol) in m: row i at y[i], column j at x[j] (MuJoCo's order)."""
        x, y = self.grid()
        h = np.zeros((len(y), len(x)))
        if self.roughness > 0:
            rng = np.random.default_rng(self.seed)
            noise = ndimage.gaussian_filter(rng.standard_normal(h.shape), self.correlation / self.resolution,
                                            mode="wrap")  # fmt: skip
            noise *= self.roughness / noise.std()
            ramp = np.clip((x - self.pad) / max(self.pad, 1e-9), 0.0, 1.0) if self.pad > 0 else (x >= 0).astype(float)
            h = noise * ramp[None, :]
        return h + self.obstacle_profile(x)[None, :]

    def height_at(self, xy: np.ndarray) -> np.ndarray:
        """The ground's height under points (n, 2), m: the height field interpolated bilinearly between its grid
        points (MuJoCo collides with two triangles per cell: the two differ inside a cell by a fraction of its
        twist, tests/test_ground_rules.py); beyond the field, the floor plane under it."""
        cached = self.__dict__.get("_interpolator")  # built once (a frozen dataclass: set past its fields)
        if cached is None:
            x, y = self.grid()
            heights = self.heights()
            # degree-1 splines: bilinear, and a few microseconds a call (the single env asks at every step)
            spline = RectBivariateSpline(y, x, heights, kx=1, ky=1)
            cached = spline, (x[0], x[-1], y[0], y[-1]), float(heights.min()) - FLOOR_BELOW
            object.__setattr__(self, "_interpolator", cached)
        spline, (x0, x1, y0, y1), floor = cached
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy) == 1:  # one point (the single env): its test on floats
            ((px, py),) = xy.tolist()
            return spline.ev([py], [px]) if x0 <= px <= x1 and y0 <= py <= y1 else np.array([floor])
        px, py = xy[:, 0], xy[:, 1]
        inside = (px >= x0) & (px <= x1) & (py >= y0) & (py <= y1)
        return np.where(inside, spline.ev(np.clip(py, y0, y1), np.clip(px, x0, x1)), floor)

    def rms_roughness(self) -> float:
        """RMS of the random part of the ground where it is fully ramped in, m (what ``roughness`` asks for)."""
        x, _ = self.grid()
        full = x >= 2 * self.pad
        rough = self.heights() - self.obstacle_profile(x)[None, :]
        return float(np.sqrt(np.mean(np.square(rough[:, full]))))

    # --- the spec ---------------------------------------------------------------------------------------------
    def __call__(self, spec: mujoco.MjSpec) -> None:
        """Add the height field to a scene's spec (a spec edit) and lower a plane named ``floor`` beneath it."""
        heights = self.heights()
        low, high = float(heights.min()), float(heights.max())
        span = max(high - low, 1e-6)
        x, y = self.grid()
        spec.add_hfield(
            name=GEOM,
            size=[(x[-1] - x[0]) / 2, (y[-1] - y[0]) / 2, span, 0.1],
            nrow=len(y),
            ncol=len(x),
            userdata=((heights - low) / span).astype(np.float32).ravel().tolist(),
        )
        spec.worldbody.add_geom(
            name=GEOM,
            type=mujoco.mjtGeom.mjGEOM_HFIELD,
            hfieldname=GEOM,
            pos=[(x[-1] + x[0]) / 2, (y[-1] + y[0]) / 2, low],
            rgba=[0.55, 0.5, 0.42, 1.0],
            contype=1,
            conaffinity=1,
            condim=3,
        )
        floor = next((g for g in spec.geoms if g.name == "floor"), None)
        if floor is not None:
            floor.pos = [floor.pos[0], floor.pos[1], low - FLOOR_BELOW]
