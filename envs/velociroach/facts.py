"""Measurements of the VelociRoACH model's physical facts, for the tests and docs/velociroach.md.

Each function measures the compiled model (in simulation where the fact is dynamic), so that the checks follow the
model files rather than restate them.
"""

from __future__ import annotations

import mujoco
import numpy as np

from envs.velociroach import constants
from envs.velociroach.robot import VelociRoach

GRAVITY = 9.81


RNG = [np.random.default_rng(0)]
ONE = np.array([0])


def overall_length(robot: VelociRoach) -> float:
    """Fore-aft extent (m) of the robot's geoms at the home pose, legs included."""
    robot.reset(ONE, RNG)
    m, d = robot.model, robot.data
    root = m.body(constants.ROOT_BODY).id
    xs = []
    for g in range(m.ngeom):
        if m.body_rootid[m.geom_bodyid[g]] != root:
            continue
        aabb = m.geom_aabb[g]  # centre (3) and half sizes (3) in the geom frame
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * aabb[3:]
        world = d.geom_xpos[g] + (corners + aabb[:3]) @ d.geom_xmat[g].reshape(3, 3).T
        xs.extend(world[:, 0])
    return float(max(xs) - min(xs))


def hold(robot: VelociRoach, seconds: float, load: float = 0.0) -> tuple[float, int]:
    """Hold the cranks still (firmware clock stopped) under an extra downward load (N) on the body; return the mean
    centre-of-mass height over the last fifth of the time and the number of legs touching the ground."""
    d = robot.data
    body = robot.model.body(constants.ROOT_BODY).id
    d.xfrc_applied[body] = [0, 0, -load, 0, 0, 0]
    steps = max(1, round(seconds / robot.control_dt))
    heights = []
    for i in range(steps):
        robot.command(np.array([[0.0, 0.0, robot.phase[0]]]))
        robot.step()
        if i >= 0.8 * steps:
            heights.append(robot.com_position()[2])
    legs = int((robot.ground_reaction_forces()[0, :, 2] > 1e-3).sum())
    d.xfrc_applied[body] = 0
    return float(np.mean(heights)), legs


def standing_com_height(robot: VelociRoach | None = None) -> float:
    """Centre-of-mass height (m) standing on tripod A at the bottom of its stroke, motors holding."""
    robot = robot or VelociRoach("gait", control_freq=100.0)
    robot.reset(ONE, RNG)
    return hold(robot, 1.0)[0]


def relative_leg_stiffness(loads: tuple[float, ...] = (0.0, 0.05, 0.1, 0.15)) -> dict[str, float]:
    """Static load test: press the standing robot down with growing loads and fit height against load.

    Relative stiffness per leg, k_rel = k L / (m g) [roach-sim], with k = (load / compression) / legs in stance,
    L = the 0.015 m centre-of-mass height of the source and m the robot's mass. The floor contact's own compliance is
    part of what the test measures, as it would be on a real robot.
    """
    robot = VelociRoach("gait", control_freq=100.0)
    robot.reset(ONE, RNG)
    hold(robot, 1.0)
    heights, legs = [], []
    for load in loads:
        h, n = hold(robot, 0.5, load)
        heights.append(h)
        legs.append(n)
    slope = np.polyfit(np.asarray(loads), np.asarray(heights), 1)[0]  # m per N, negative
    k_total = -1.0 / slope
    n = legs[0]
    k_leg = k_total / n
    weight = robot.facts.mass * GRAVITY
    return {
        "k_total": float(k_total),
        "legs_in_stance": n,
        "k_leg": float(k_leg),
        "k_rel": float(k_leg * constants.COM_HEIGHT / weight),
        "max_relative_compression": float((heights[0] - heights[-1]) / constants.COM_HEIGHT),
    }


def reflected_leg_inertia(robot: VelociRoach) -> float:
    """Inertia one leg adds to its crank through the linkage, m a^2 (kg m^2), a the fore-aft sweep amplitude."""
    m = robot.model
    leg = m.body("FL_leg").id
    return float(m.body_subtreemass[leg] * robot.sweep_amplitude**2)


def motor_bench(duty: float = 1.0, seconds: float = 1.0) -> dict[str, float]:
    """The left motor and its linkage with the body clamped to the world and legs in the air: stall torque at the
    crank (at rest) and free-running stride frequency at ``duty``."""

    def clamp(spec: mujoco.MjSpec) -> None:
        spec.delete(spec.joint(constants.ROOT_JOINT))
        spec.body(constants.ROOT_BODY).pos[2] = 0.5

    robot = VelociRoach("duty", control_freq=1000.0, spec_edits=[clamp])
    robot.reset(ONE, RNG)
    command = np.array([[duty, 0.0]])
    robot.command(command)
    robot.data.ctrl[:] = robot.sim.ctrl[0, 0]
    mujoco.mj_forward(robot.model, robot.data)  # at rest: the stall torque
    stall = float(robot.crank_torques()[0, 0])
    speeds = []
    for i in range(round(seconds / robot.control_dt)):
        robot.command(command)
        robot.step()
        if i >= round(0.5 * seconds / robot.control_dt):
            speeds.append(robot.leg_velocities()[0, 0])
    return {"stall_torque": stall, "free_stride_hz": float(np.mean(speeds) / (2 * np.pi))}
