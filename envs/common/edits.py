"""``MjSpec`` edits that several robots' calibration effects share, by names the robot gives: a body's mass and
centre of mass, actuators' delay, a bump across the floor and a disturbance torque at a site (synthetic data only),
and the deepest contact of a state (for starting a segment out of the ground)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import mujoco

from envs.common.parameters import SpecEdit


def scale_mass(spec: mujoco.MjSpec, bodies: Iterable[str], scale: float, shift_x: float = 0.0,
               shifted: str | None = None) -> None:  # fmt: skip
    """Scale the mass and inertia of ``bodies`` by ``scale`` (their compiled values, made explicit) and move the
    centre of mass of ``shifted`` (default: the first of them) by ``shift_x`` along its x axis."""
    bodies = list(bodies)
    if scale == 1.0 and shift_x == 0.0:
        return
    nominal = spec.compile()
    shifted = bodies[0] if shifted is None else shifted
    for name in bodies:
        i = nominal.body(name).id
        body = spec.body(name)
        body.explicitinertial = True
        body.mass = float(nominal.body_mass[i]) * scale
        body.inertia = nominal.body_inertia[i] * scale
        body.ipos = nominal.body_ipos[i] + ([shift_x, 0.0, 0.0] if name == shifted else 0.0)
        body.iquat = nominal.body_iquat[i]


def delay_actuators(seconds: float, names: Sequence[str]) -> SpecEdit:
    """Spec edit: the inputs of actuators ``names`` delayed by ``seconds`` (MuJoCo's actuator delay: a history of the
    inputs, held between samples), as a replay shifts the logged commands."""

    def edit(spec: mujoco.MjSpec) -> None:
        steps = math.ceil(seconds / spec.option.timestep - 1e-9)
        for name in names:
            a = spec.actuator(name)
            a.delay, a.nsample, a.interp = float(seconds), steps + 2, 0

    return edit


def add_bump(height: float, x: float, width: float, count: int = 1, centre: float = 0.0) -> SpecEdit:
    """Spec edit (synthetic data only): bumps of the floor across the robot's path, each a capsule of radius
    ``height`` and half-length ``width`` lying along y. With ``count`` 1, one at ``x`` ahead of the start; with
    more, ``count`` on each side of ``centre`` (the start, or the middle of the robot's feet), ``x`` apart, so that
    a robot walking either way for the length of a log keeps crossing them (one bump is crossed once, within a
    second or two of a 10 s log, and its transient averages away)."""

    def edit(spec: mujoco.MjSpec) -> None:
        where = [x] if count == 1 else [centre + sign * k * x for k in range(1, count + 1) for sign in (1, -1)]
        for i, at in enumerate(where):
            g = spec.worldbody.add_geom(name=f"bump{i}" if i else "bump", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                                        size=[height, width, 0], pos=[at, 0, 0],
                                        quat=[0.7071068, 0.7071068, 0, 0])  # fmt: skip
            g.rgba = [0.6, 0.5, 0.4, 1]

    return edit


def add_site_disturbance(site: str, axis: int) -> SpecEdit:
    """Spec edit (synthetic data only): an actuator ``disturbance`` applying a torque about the site's ``axis`` (0 x
    roll, 1 y pitch, 2 z yaw, in the site's frame), unbounded: a torque from outside the model. At a site, not
    through a body transmission, which would act through the body's contacts, as an adhesion actuator does."""

    def edit(spec: mujoco.MjSpec) -> None:
        a = spec.add_actuator(name="disturbance", target=site, trntype=mujoco.mjtTrn.mjTRN_SITE)
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        gear = [0.0] * 6
        gear[3 + axis] = 1.0
        a.gear = gear

    return edit


def deepest_contact(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The most negative contact distance (the deepest penetration, m; 0 without contacts) at the data's qpos."""
    mujoco.mj_fwdPosition(model, data)
    return float(min(data.contact.dist[: data.ncon], default=0.0)) if data.ncon else 0.0
