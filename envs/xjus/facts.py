"""Measurements of the xJüs model's physical facts, for the tests and docs/xjus.md.

Each function measures the compiled model (in simulation where the fact is dynamic), so that the checks follow the
model files rather than restate them.
"""

from __future__ import annotations

import mujoco
import numpy as np

from envs.xjus import constants
from envs.xjus.robot import DUTY, RIGID, Xjus

RNG = [np.random.default_rng(0)]
ONE = np.array([0])
UPRIGHT = np.array([1.0, 0.0, 0.0, 0.0])
HIPS_VERTICAL = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # rolled 90 deg: hip axes point up


def body_length(robot: Xjus) -> float:
    """Fore-aft extent (m) of the three segments' boxes at the reset pose."""
    robot.reset(ONE, RNG)
    m, d = robot.model, robot.data
    xs = []
    for name in constants.SEGMENTS:
        g = m.geom(name).id
        half = m.geom_size[g, 0]
        xs += [d.geom_xpos[g, 0] - half, d.geom_xpos[g, 0] + half]
    return float(max(xs) - min(xs))


def clamp(height: float = 0.6, quat: np.ndarray = UPRIGHT, lock_hips: bool = False):
    """A spec edit: the middle segment fixed in the air (no free joint), turned by ``quat``; hips locked at zero."""

    def edit(spec: mujoco.MjSpec) -> None:
        spec.delete(spec.joint(constants.ROOT_JOINT))
        body = spec.body(constants.ROOT_BODY)
        body.pos = [0.0, 0.0, height]
        body.quat = list(quat)
        if lock_hips:
            for leg in constants.LEGS:
                joint = spec.joint(constants.HIP_JOINTS[leg])
                joint.range = [-1e-6, 1e-6]
                joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE

    return edit


def hold(robot: Xjus, duty: float, seconds: float) -> None:
    for _ in range(max(1, round(seconds / robot.control_dt))):
        robot.command(np.full((1, len(constants.LEGS)), duty))
        robot.step()


def leg_load_test(load: float = constants.LEG_TEST_LOAD) -> dict[str, np.ndarray]:
    """Static load test of every leg, as the report's FEA loads one (section 3.3): the chassis fixed in the air, the
    hips locked with the legs pointing down, ``load`` (N) pushed up at each toe along the leg; returns the toe's
    deflection (m, loaded minus unloaded, so that the leg's own weight cancels) and the spring's."""
    robot = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[clamp(lock_hips=True)])
    robot.reset(ONE, RNG, options={"leg_angles": np.zeros(len(constants.LEGS))})
    m, d = robot.model, robot.data
    tips = [m.site(f"{leg}_tip").id for leg in constants.LEGS]
    bodies = [m.body(f"{leg}_leg").id for leg in constants.LEGS]

    def settle() -> tuple[np.ndarray, np.ndarray]:
        hold(robot, 0.0, 1.0)
        mujoco.mj_forward(m, d)
        return d.site_xpos[tips, 2].copy(), robot.sim.sensordata[0, robot._i_deflection].copy()

    free_z, free_spring = settle()
    for tip, body in zip(tips, bodies, strict=True):
        force = np.array([0.0, 0.0, load])
        arm = d.site_xpos[tip] - d.xipos[body]
        d.xfrc_applied[body] = np.concatenate([force, np.cross(arm, force)])
    loaded_z, loaded_spring = settle()
    d.xfrc_applied[:] = 0.0
    return {"toe": loaded_z - free_z, "spring": free_spring - loaded_spring}


def motor_bench(duty: float = 1.0) -> dict[str, np.ndarray]:
    """Each leg's motor in the assembled robot, chassis fixed with the hip axes vertical (gravity does no work on the
    legs): the torque on the locked hips, N m, and the steady speed of the free legs, rad/s, at ``duty``."""
    blocked = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[clamp(quat=HIPS_VERTICAL, lock_hips=True)])
    blocked.reset(ONE, RNG, options={"leg_angles": np.zeros(len(constants.LEGS))})
    hold(blocked, duty, 0.2)
    free = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[clamp(quat=HIPS_VERTICAL)])
    free.reset(ONE, RNG, options={"leg_angles": np.zeros(len(constants.LEGS))})
    hold(free, duty, 2.0)
    return {"stall_torque": blocked.hip_torques()[0].copy(), "no_load_speed": free.leg_speeds()[0].copy()}
