"""XjusRough: walk the xJüs over seeded rough ground, a step, stairs or an obstacle course."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME, WalkTask
from envs.common.robot import Robot, check_flag, check_number
from envs.common.terrain import Terrain
from envs.common.vector import vector_entry_point
from envs.xjus.robot import COMPLIANT, GAIT, SpineSetting, Xjus
from envs.xjus.walk import ENERGY_COST_WEIGHT

FLIPPED = np.pi / 2  # rad: the middle segment's z axis at or past horizontal


class RoughTask(WalkTask):
    """Walk along +x over a terrain; the episode ends when the robot flips. Reports the lane and, at the end, whether
    it crossed the obstacle."""

    name = "rough"
    metrics: ClassVar[dict[str, str]] = {
        **WalkTask.metrics,
        "progress": "how far along +x the robot got, m",
        "obstacle_cleared": "1 if it got past the step, the stairs or the course's last obstacle (none: not reported)",
    }
    binary_metrics: ClassVar[tuple[str, ...]] = ("obstacle_cleared",)

    def __init__(
        self,
        robot: Robot,
        terrain: Terrain,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        upright_reward_weight: float = 1.0,
        max_tilt: float = FLIPPED,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.terrain = terrain
        super().__init__(
            robot,
            privileged_obs,
            forward_reward_weight,
            energy_cost_weight,
            upright_reward_weight,
            max_tilt,
            terminate_when_unhealthy,
            height_band,
            grace_time,
            terrain.height_at if ground_height is None else ground_height,
        )

    def info(self, readings: dict[str, np.ndarray], state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {**state, "lane": self.robot.start_index.astype(np.float64)}

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        metrics = {**super().episode_metrics(info), "progress": float(info["progress_x"])}
        end = self.terrain.obstacle_end()
        metrics["obstacle_cleared"] = float(info["progress_x"] >= end) if np.isfinite(end) else float("nan")
        return metrics


class XjusRoughEnv(SkitterEnv):
    """Walk an xJüs forward over a seeded rough terrain, optionally with a step, stairs or an obstacle course.

    Robot, actions, observations, starting state and info are those of :class:`envs.xjus.walk.XjusWalkEnv`; this
    docstring lists what differs. The robot is blind, as RHex and the report's robot are: it senses only itself.

    ## Terrain
    A height field (``envs/common/terrain.py``) of 24 parallel lanes, 1.5 m apart, each running 10 m along +x from a
    level start pad; every reset starts the robot at the start of a lane drawn from the episode's random generator,
    or at ``reset(options={"start": k})``. The ground is a Gaussian random field of RMS height ``roughness`` (m,
    correlation length 0.1 m, ramping in over 0.4-0.8 m), the same for every setting of the robot with the same
    ``terrain_seed``. ``obstacle`` adds, across every lane: ``"step"``, a step up of ``step_height`` at x = 2 m;
    ``"stairs"``, four stairs of ``step_height``, 0.3 m deep, from x = 2 m; ``"course"``, an obstacle course in the
    spirit of the report's Figure 7 (a bump, a step up of ``step_height``, a log, a step down, a ramp up and down, three
    ridges; :meth:`envs.common.terrain.Terrain.obstacle_profile`).

    ## Rewards
    As XjusWalk: ``reward = forward + energy + upright`` (progress along +x; the cost of transport's motor efficiency
    is capped at 0.37 by the report's constants).

    ## Episode End
    - terminated also (``info["fallen"]``) when anything but its feet (its six legs) has touched the ground, or its
      body's origin has been outside its height band (0.103 to 0.364 m above the ground under it), for longer than
      ``grace_time`` (1.5 s), the ground's height taken from the terrain under the body, in a leaky count: a step that
      breaks the rule adds its duration, one that keeps it takes a quarter of that away (``info["contact_time"]``,
      ``info["band_time"]``; see envs/common/locomotion.py). Off with ``terminate_when_unhealthy=False``;
    - terminated when the robot flips (the middle segment tilts ``max_tilt`` from upright, default pi/2) or the
      simulation goes unstable (as XjusWalk); truncated after ``episode_seconds`` of simulated time (10 s) at any
      control rate.

    ## Info
    As XjusWalk, and ``lane`` (the start's index). Episode metrics add ``progress`` (m along +x) and
    ``obstacle_cleared`` (1 if the robot got past the step, the stairs or the course).

    ## Arguments
    As XjusWalk (``max_tilt`` default pi/2), plus ``roughness`` (RMS height, m, 0 to 0.1, default 0.02),
    ``obstacle`` (``"none"``, ``"step"``, ``"stairs"``, ``"course"``), ``step_height`` (m, 0 to 0.15, default 0.05)
    and ``terrain_seed`` (the random ground's seed, default 0).

    ## Version History
    - v1: as XjusWalk-v1 (the episode ends on a non-foot ground contact or a body out of its height band).
    - v0: first release.
    """

    def __init__(
        self,
        roughness: float = 0.02,
        obstacle: str = "none",
        step_height: float = 0.05,
        terrain_seed: int = 0,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = ENERGY_COST_WEIGHT,
        upright_reward_weight: float = 1.0,
        max_tilt: float = FLIPPED,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        spine: str = COMPLIANT,
        spine_stiffness: SpineSetting = None,
        spine_damping: SpineSetting = None,
        battery_voltage: float | None = None,
        current_limit: float | None = None,
        sensor_noise: bool = True,
        randomize: Mapping[str, Sequence[float]] | None = None,
        calibration: str | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        if isinstance(terrain_seed, bool) or not isinstance(terrain_seed, int | np.integer) or terrain_seed < 0:
            raise ValueError(f"terrain_seed must be a whole number >= 0, got {terrain_seed!r}")  # named as passed
        terrain = Terrain(
            roughness=check_number("roughness", roughness, 0.0, 0.1),
            obstacle=obstacle,
            step_height=check_number("step_height", step_height, 0.0, 0.15),
            seed=terrain_seed,
        )
        robot = Xjus(
            action_mode,
            control_freq,
            spine,
            spine_stiffness,
            spine_damping,
            battery_voltage,
            current_limit,
            ImuNoise() if check_flag("sensor_noise", sensor_noise) else None,
            starts=terrain.starts(),
            spec_edits=[terrain],
            calibration=calibration,
        )
        task = RoughTask(
            robot,
            terrain,
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


make_env = entry_point(XjusRoughEnv)
make_batched = vector_entry_point(XjusRoughEnv)
