"""``MjSpec`` edits that several robots' calibration effects share, by names the robot gives: a body's mass and
centre of mass, actuators' delay, a bump across the floor and a disturbance torque at a site (synthetic data only),
and the deepest contact of a state (for starting a segment out of the ground)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import mujoco
import numpy as np

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


def add_periodic_torque(spec: mujoco.MjSpec, joint: str, harmonics: Mapping[int, tuple[float, float]],
                        radius: float = 0.004) -> None:  # fmt: skip
    """A torque on hinge ``joint`` that depends on where it is: sum over ``harmonics`` {h: (s, c)} of s sin(h q) + c
    cos(h q) N m at its reading q, in MuJoCo's own passive forces (no Python per step). Harmonic h is a tendon spring
    of zero rest length between a site ``radius`` off the axis on a body turning h times as fast as the joint and a
    site as far off the axis on the joint's parent: its energy k L^2 / 2, with L^2 = 2 r^2 (1 - cos(h (q - ref) -
    a)), turns the body with the torque -k r^2 sin(h (q - ref) - a), h times that at the joint. The first harmonic's
    site rides on the joint's own body; a higher one's on a light body of its own (1 mg, 1e-10 kg m^2) that a joint
    equality turns h times as fast, as the model's linkage ties its joints (its joint ``<joint>_h<h>``: a reset puts
    it where the equality holds it, as it does a linkage joint's)."""
    hinge = spec.joint(joint)
    body = hinge.parent
    parent = body.parent
    axis = np.asarray(hinge.axis, dtype=float) / np.linalg.norm(hinge.axis)
    u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)  # where u turns to at a quarter turn
    for h, (s, c) in sorted(harmonics.items()):
        amplitude = math.hypot(s, c)
        if amplitude == 0.0:
            continue
        # -sin(h (q - ref) - a) = sin(h q + b), with s = A cos b, c = A sin b
        a = math.pi - math.atan2(c, s) - h * hinge.ref
        turning = body
        if h != 1:
            turning = parent.add_body(name=f"{joint}_h{h}", pos=body.pos, quat=body.quat, mass=1e-6,
                                      inertia=[1e-10, 1e-10, 1e-10], explicitinertial=True)  # fmt: skip
            turning.add_joint(name=f"{joint}_h{h}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=hinge.axis,
                              pos=hinge.pos)  # fmt: skip
            spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT, name1=f"{joint}_h{h}", name2=joint,
                              data=[0.0, float(h), 0.0, 0.0, 0.0] + [0.0] * 7, solref=[0.002, 1.0],
                              solimp=[0.9999, 0.9999, 0.001, 0.5, 2.0])  # fmt: skip
        on = turning.add_site(name=f"{joint}_h{h}_spring", pos=np.asarray(hinge.pos) + radius * u)
        fixed = np.asarray(hinge.pos) + radius * (math.cos(a) * u + math.sin(a) * w)  # in the body's frame at rest
        where = np.zeros(3)
        mujoco.mju_rotVecQuat(where, fixed, np.asarray(body.quat, dtype=float))
        anchor = parent.add_site(name=f"{joint}_h{h}_anchor", pos=np.asarray(body.pos) + where)
        tendon = spec.add_tendon(name=f"{joint}_h{h}", stiffness=amplitude / (h * radius**2), springlength=[0.0, 0.0])
        tendon.wrap_site(on.name)
        tendon.wrap_site(anchor.name)


def deepest_contact(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """The most negative contact distance (the deepest penetration, m; 0 without contacts) at the data's qpos."""
    mujoco.mj_fwdPosition(model, data)
    return float(min(data.contact.dist[: data.ncon], default=0.0)) if data.ncon else 0.0
