"""Is an optimized CPG gait physical, or does it exploit the simulator? The checks behind docs/bioloid.md's verdict on
the seed-scale PSO runs' best policies (experiments 5 and 6).

A CPG runs open loop (no observation enters its oscillators), so its rollout is a fixed sequence of servo goals: the
controls are recorded once through the optimizer's own evaluator (the rollout that was scored) and then

- **replayed one physics step at a time** on the same model (the replay ends in the scored state exactly), measuring
  what an exploit would show: foot slip while a foot carries load (slip speed of the contact point, force-weighted),
  time with no ground contact, the share of the ground force carried by parts other than the crutches, peak ground
  reaction, body height and tilt, joint limits, parts passing through each other, and each servo's speed against
  its no-load speed with the torque it gives then (a servo faster than its no-load speed must be braking: driven by
  the load, not by its motor) and the most its driving torque exceeds the torque-speed line of the AX-12 model;
- **replayed on altered models**, the same controls: a smaller physics step, another integrator, elliptic friction
  cones, softer and stiffer contacts, other friction, friction in the servos' gear trains (the AX-12's is not
  published: 0.1 and 0.2 N m, 6% and 12% of its stall torque, are probes), parts other than the crutches not
  touching the ground, and the robot's parts colliding with each other (the
  model lets them pass through each other). A numerical exploit (energy from penetration, solver artefacts) would not
  survive the first five; a gait that rests on one modelling assumption collapses when that one changes.

And the robot alone, dropped 5 cm in its ready posture: how far it rebounds (elastic contacts would give energy
back).

Run: ``python -m benchmarks.bioloid_cpg_check <policy.json> [...]`` (about ten seconds per policy); the CPG
experiments' summary (``benchmarks/bioloid_cpg_experiments.py``) runs it on each run's best policy.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from agents.optimize.problem import Evaluator, parse_config
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.actuators.servo import SPEED_PER_VOLT, TORQUE_PER_VOLT
from envs.bioloid import constants
from envs.common.io import ToolParser, atomic_write

STANCE_FORCE = 1.0  # N: a foot carrying at least this is in stance (a twentieth of the robot's weight, 17.3 N)
SELF_DEPTH = 0.002  # m: parts overlapping deeper than this pass through each other (the shapes are approximate)
LEG_SERVOS = tuple(s for s in constants.SERVOS if s[:3] in constants.LEGS)
Edit = Callable[[mujoco.MjModel], None]


def record_controls(policy_path: str | Path) -> dict[str, Any]:
    """The scored rollout of a policy file written by agents.optimize: its model, start state and per-physics-step
    controls, recorded through the optimizer's evaluator (one simulation, no reset noise)."""
    record = json.loads(Path(policy_path).read_text())
    config = parse_config({**record["run"]["config"], "coupling": record["coupling"]}, str(policy_path))
    evaluator = Evaluator(config, 1, nthread=1)
    robot, controller = evaluator.robot, evaluator.controller
    robot.reset(np.arange(1), [np.random.default_rng(0)], 0.0, None)
    controller.start(np.asarray(record["parameters"], dtype=np.float64)[None])
    state = np.empty(mujoco.mj_stateSize(robot.model, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(robot.model, robot.sim.get_data(0), state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    blocks = []
    for _ in range(evaluator.steps):
        robot.command(controller.commands())
        blocks.append(robot.sim.ctrl[0].copy())
        robot.step()
    end = robot.sim.get_data(0)
    x0 = float(_start(robot.model, state).xpos[robot.model.body(constants.ROOT_BODY).id][0])
    return {"model": robot.model, "state": state, "x0": x0, "ctrl": np.concatenate(blocks),
            "qpos_end": end.qpos.copy(), "max_tilt": config.max_tilt, "record": record}  # fmt: skip


def _start(model: mujoco.MjModel, state: np.ndarray) -> mujoco.MjData:
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(model, data)
    return data


def _geom_classes(model: mujoco.MjModel) -> dict[int, str]:
    """Each robot geom's class for the ground-force shares: crutch (foot sphere and shaft), knee case, other."""
    feet = {model.geom(constants.FOOT_GEOM[leg]).id for leg in constants.LEGS} | {
        model.geom(constants.CRUTCH_GEOM[leg]).id for leg in constants.LEGS
    }
    knees = {model.geom(f"{leg}_3_case").id for leg in constants.LEGS}
    return {g: "crutch" if g in feet else "knee case" if g in knees else "other"
            for g in range(model.ngeom) if model.geom_bodyid[g] != 0}  # fmt: skip


def gait_statistics(rollout: dict[str, Any]) -> dict[str, Any]:
    """The rollout replayed one physics step at a time: slip, contacts, servo speeds and torques (module docstring)."""
    m, ctrl = rollout["model"], rollout["ctrl"]
    d = _start(m, rollout["state"])
    dt, floor, body = m.opt.timestep, m.geom(constants.FLOOR_GEOM).id, m.body(constants.ROOT_BODY).id
    classes = _geom_classes(m)
    leg_geom = {m.geom(constants.FOOT_GEOM[leg]).id: i for i, leg in enumerate(constants.LEGS)}
    leg_geom.update({m.geom(constants.CRUTCH_GEOM[leg]).id: i for i, leg in enumerate(constants.LEGS)})
    servos = [constants.SERVO_INDEX[s] for s in LEG_SERVOS]
    actuators = np.array([m.actuator(f"{s}_servo").id for s in constants.SERVOS])[servos]
    dofs = np.array([m.jnt_dofadr[m.joint(s).id] for s in constants.SERVOS])[servos]
    qadr = np.array([m.jnt_qposadr[m.joint(s).id] for s in constants.SERVOS])[servos]
    low, high = m.jnt_range[[m.joint(s).id for s in LEG_SERVOS]].T
    gear = m.actuator_gear[actuators, 0]
    stall, no_load = TORQUE_PER_VOLT * constants.BATTERY_VOLTAGE, SPEED_PER_VOLT * constants.BATTERY_VOLTAGE
    weight = float(m.body_subtreemass[body]) * float(np.linalg.norm(m.opt.gravity))
    f6, vel6 = np.zeros(6), np.zeros(6)
    probe = copy.deepcopy(m)  # the same bodies with self-collision, to measure how far parts pass through each other
    _self_collision(probe)
    probe_data = mujoco.MjData(probe)
    self_depth, self_pairs, self_samples, self_deep = 0.0, {}, 0, 0
    force_by_class = {"crutch": 0.0, "knee case": 0.0, "other": 0.0}
    touching: dict[str, int] = {}
    slip_work, stance_force, slip_distance = np.zeros(4), np.zeros(4), np.zeros(4)
    airborne = over_no_load = braking_over = samples = 0
    over_per_servo = np.zeros(len(servos))
    drive_excess = max_violation = max_torque = 0.0
    ground, heights, ups = [], [], []
    for i in range(len(ctrl)):
        d.ctrl[:] = ctrl[i]
        w_before = d.qvel[dofs].copy()
        mujoco.mj_step(m, d)  # forces below are those of this step: computed at the state before its integration
        torque = d.actuator_force[actuators] * gear
        max_torque = max(max_torque, float(np.abs(torque).max()))
        over = np.abs(w_before) > no_load
        over_no_load += int(over.sum())
        over_per_servo += over
        braking_over += int((over & (torque * w_before < 0)).sum())
        driving = torque * w_before > 0
        if driving.any():
            line = stall * (1.0 - np.abs(w_before[driving]) / no_load)
            drive_excess = max(drive_excess, float((np.abs(torque[driving]) - line).max()))
        samples += len(servos)
        q = d.qpos[qadr]
        max_violation = max(max_violation, float(np.maximum(q - high, low - q).max()))
        total, leg_force, leg_slip = 0.0, np.zeros(4), np.zeros(4)
        for ci in range(d.ncon):
            c = d.contact[ci]
            if floor not in (c.geom1, c.geom2) or c.efc_address < 0:
                continue
            mujoco.mj_contactForce(m, d, ci, f6)
            if f6[0] <= 0.0:
                continue
            other = c.geom2 if c.geom1 == floor else c.geom1
            total += f6[0]
            force_by_class[classes[other]] += f6[0] * dt
            touching[m.geom(other).name] = touching.get(m.geom(other).name, 0) + 1
            if other in leg_geom:
                j = leg_geom[other]
                mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, other, vel6, 0)
                v = vel6[3:] + np.cross(vel6[:3], c.pos - d.geom_xpos[other])  # the contact point's velocity
                n = c.frame[:3]
                speed = float(np.linalg.norm(v - n * (v @ n)))
                leg_force[j] += f6[0]
                leg_slip[j] = max(leg_slip[j], speed)
        stance = leg_force >= STANCE_FORCE
        slip_work += np.where(stance, leg_slip * leg_force, 0.0)
        stance_force += np.where(stance, leg_force, 0.0)
        slip_distance += np.where(leg_force > 0, leg_slip * dt, 0.0)
        airborne += total == 0.0
        if i % 10 == 0:
            probe_data.qpos[:] = d.qpos
            mujoco.mj_kinematics(probe, probe_data)
            mujoco.mj_collision(probe, probe_data)
            worst = 0.0
            for c in probe_data.contact[: probe_data.ncon]:
                if probe.geom_bodyid[c.geom1] != 0 and probe.geom_bodyid[c.geom2] != 0 and c.dist < -SELF_DEPTH:
                    pair = " / ".join(sorted((probe.geom(c.geom1).name, probe.geom(c.geom2).name)))
                    self_pairs[pair] = self_pairs.get(pair, 0) + 1
                    worst = min(worst, c.dist)
            self_samples += 1
            self_deep += worst < 0.0
            self_depth = max(self_depth, -worst)
        ground.append(total)
        heights.append(d.xpos[body][2])
        ups.append(d.xmat[body][8])
    if not np.array_equal(d.qpos, rollout["qpos_end"]):
        raise RuntimeError("the step-by-step replay left the scored rollout")
    ground_total = sum(force_by_class.values())
    ground, ups = np.array(ground), np.array(ups)
    progress = float(d.xpos[body][0] - rollout["x0"])
    return {
        "progress_x": progress,
        "speed": progress / (len(ctrl) * dt),
        "airborne_fraction": airborne / len(ctrl),
        "ground_force_share": {k: v / ground_total for k, v in force_by_class.items()},
        "touching_fraction": {k: v / len(ctrl) for k, v in sorted(touching.items(), key=lambda kv: -kv[1])},
        "stance_slip_speed": dict(
            zip(constants.LEGS, (slip_work / np.maximum(stance_force, 1e-12)).tolist(), strict=True)
        ),
        "slip_distance": dict(zip(constants.LEGS, slip_distance.tolist(), strict=True)),
        "ground_reaction_bw": {"p99": float(np.percentile(ground, 99) / weight), "max": float(ground.max() / weight)},
        "body_height": {"min": float(min(heights)), "max": float(max(heights))},
        "max_tilt_deg": float(np.degrees(np.arccos(np.clip(ups.min(), -1, 1)))),
        "leg_servo_over_no_load": over_no_load / samples,
        "over_no_load_by_servo": dict(zip(LEG_SERVOS, (over_per_servo / len(ctrl)).tolist(), strict=True)),
        "braking_when_over_no_load": braking_over / max(over_no_load, 1),
        "max_driving_torque_over_the_line": drive_excess,
        "max_torque_over_stall": max_torque / stall,
        "no_load_speed": no_load,
        "stall_torque": stall,
        "max_joint_limit_violation_deg": math.degrees(max(max_violation, 0.0)),
        "self_penetration_fraction": self_deep / self_samples,
        "self_penetration_max": self_depth,
        "self_penetrating_pairs": {k: v / self_samples for k, v in sorted(self_pairs.items(), key=lambda kv: -kv[1])},
    }


def drop_rebound(height: float = 0.05, seconds: float = 1.0) -> dict[str, float]:
    """The robot dropped level from ``height`` (m) in its ready posture, its servos holding it: how far the body sinks
    below where it comes to rest and how far it rebounds above it after the first impact (m). Elastic contacts (energy
    from penetration) would rebound a good part of the drop."""
    import gymnasium as gym

    import envs  # noqa: F401

    env = gym.make("skitter/BioloidWalk-v2", reset_noise_scale=0.0, sensor_noise=False)
    env.reset(seed=0)
    robot = env.unwrapped.robot
    data = robot.sim.get_data(0)
    data.qpos[2] += height
    mujoco.mj_forward(robot.model, data)
    z = []
    for _ in range(round(seconds / robot.control_dt)):
        robot.command(robot.ready_counts[None])
        robot.step()
        z.append(float(robot.sim.get_data(0).qpos[2]))
    z = np.array(z)
    rest, lowest = z[-1], int(np.argmin(z))
    return {"height": height, "sink_below_rest": float(rest - z[lowest]),
            "rebound_above_rest": float(max(z[lowest:].max() - rest, 0.0))}  # fmt: skip


def _robot_geoms(m: mujoco.MjModel) -> list[int]:
    return [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0]


def _geoms(field: str, column: int, value: float, which: str = "all") -> Edit:
    def edit(m: mujoco.MjModel) -> None:
        classes = _geom_classes(m)
        for g in _robot_geoms(m):
            if which == "all" or (which == "not crutch") == (classes[g] != "crutch"):
                getattr(m, field)[g, column] = value

    return edit


def _gear_friction(torque: float) -> Edit:
    def edit(m: mujoco.MjModel) -> None:
        for s in constants.SERVOS:
            m.dof_frictionloss[m.jnt_dofadr[m.joint(s).id]] = torque

    return edit


def _only_crutches_touch(m: mujoco.MjModel) -> None:
    classes = _geom_classes(m)
    for g in _robot_geoms(m):
        if classes[g] != "crutch":
            m.geom_contype[g] = m.geom_conaffinity[g] = 0


def _self_collision(m: mujoco.MjModel) -> None:
    """The robot's parts collide with each other too (the model: only with the ground); bodies joined by a joint
    still do not (MuJoCo's parent filter)."""
    for g in _robot_geoms(m):
        m.geom_contype[g] = m.geom_conaffinity[g] = 1
    m.body_contype[1:] = m.body_conaffinity[1:] = 1  # the broad phase's per-body masks


def _elliptic(m: mujoco.MjModel) -> None:
    m.opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC


def _implicit(m: mujoco.MjModel) -> None:
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT


# (name, what it tests, physics steps per recorded step, model edit). v0 also replayed a knee stopped at 45 deg
# backward; v1's knees stop at straight in the model itself (envs/bioloid/constants.py).
VARIANTS: tuple[tuple[str, str, int, Edit | None], ...] = (
    ("nominal", "the scored rollout", 1, None),
    ("physics step 0.5 ms", "numerics", 4, None),
    ("implicit integrator", "numerics", 1, _implicit),
    ("elliptic friction cones", "numerics", 1, _elliptic),
    ("contact time constant 10 ms", "contact softness", 1, _geoms("geom_solref", 0, 0.010)),
    ("contact time constant 2 ms, step 0.5 ms", "contact softness", 4, _geoms("geom_solref", 0, 0.002)),
    ("robot friction 0.5", "friction", 1, _geoms("geom_friction", 0, 0.5)),
    ("robot friction 1.0", "friction", 1, _geoms("geom_friction", 0, 1.0)),
    ("cases and brackets friction 0.3", "friction", 1, _geoms("geom_friction", 0, 0.3, "not crutch")),
    ("gear-train friction 0.1 N m per servo", "servo back-driving", 1, _gear_friction(0.1)),
    ("gear-train friction 0.2 N m per servo", "servo back-driving", 1, _gear_friction(0.2)),
    ("only the crutches touch the ground", "walking on other parts", 1, _only_crutches_touch),
    ("parts collide with each other", "legs passing through each other", 1, _self_collision),
)


def replay(rollout: dict[str, Any], substeps: int = 1, edit: Edit | None = None) -> dict[str, Any]:
    """The recorded controls on a copy of the model (``edit`` applied, the physics step divided by ``substeps``):
    +x progress, when the body first tilted past the run's limit, the share of the ground force not on the crutches."""
    m = copy.deepcopy(rollout["model"])
    if edit is not None:
        edit(m)
    m.opt.timestep = rollout["model"].opt.timestep / substeps
    d = _start(m, rollout["state"])
    body, floor = m.body(constants.ROOT_BODY).id, m.geom(constants.FLOOR_GEOM).id
    classes = _geom_classes(m)
    min_up = math.cos(rollout["max_tilt"])
    ctrl = rollout["ctrl"]
    per_block = 10  # recorded steps per control step: contacts sampled once per control step
    f6 = np.zeros(6)
    crutch = other = 0.0
    fall_time = None
    for k in range(0, len(ctrl), per_block):
        for row in ctrl[k : k + per_block]:
            d.ctrl[:] = row
            mujoco.mj_step(m, d, nstep=substeps)
        for ci in range(d.ncon):
            c = d.contact[ci]
            if floor in (c.geom1, c.geom2) and c.efc_address >= 0:
                mujoco.mj_contactForce(m, d, ci, f6)
                g = c.geom2 if c.geom1 == floor else c.geom1
                if classes[g] == "crutch":
                    crutch += max(f6[0], 0.0)
                else:
                    other += max(f6[0], 0.0)
        if fall_time is None and d.xmat[body][8] < min_up:
            fall_time = float(d.time)
    return {"progress_x": float(d.xpos[body][0] - rollout["x0"]), "fall_time": fall_time,
            "not_crutch_share": other / max(crutch + other, 1e-12)}  # fmt: skip


def contact_sheet(rollout: dict[str, Any], path: Path, start: float = 20.0, frames: int = 10,
                  seconds: float = 1.0) -> bool:  # fmt: skip
    """Frames of the rollout seen from the side, ``frames`` over ``seconds`` from ``start`` s, tiled into a png.
    False where this machine cannot render (no OpenGL)."""
    try:
        from PIL import Image, ImageDraw

        m = rollout["model"]
        renderer = mujoco.Renderer(m, 180, 240)
    except Exception:  # any missing GL backend
        return False
    d = _start(m, rollout["state"])
    camera = mujoco.MjvCamera()
    camera.type, camera.distance, camera.elevation, camera.azimuth = mujoco.mjtCamera.mjCAMERA_FREE, 0.6, -5.0, 90.0
    body, dt = m.body(constants.ROOT_BODY).id, m.opt.timestep
    wanted = {round((start + k * seconds / frames) / dt) for k in range(frames)}
    images = []
    for i, row in enumerate(rollout["ctrl"]):
        d.ctrl[:] = row
        mujoco.mj_step(m, d)
        if i + 1 in wanted:
            camera.lookat[:] = [d.xpos[body][0], d.xpos[body][1], 0.08]
            renderer.update_scene(d, camera)
            image = Image.fromarray(renderer.render())
            ImageDraw.Draw(image).text((4, 4), f"t = {d.time:.1f} s", fill=(0, 0, 0))
            images.append(image)
    renderer.close()
    columns = 5
    sheet = Image.new("RGB", (240 * columns, 180 * math.ceil(len(images) / columns)), "white")
    for k, image in enumerate(images):
        sheet.paste(image, ((k % columns) * 240, (k // columns) * 180))
    atomic_write(path, lambda p: sheet.save(p, format="PNG"))
    return True


def check(policy_path: str | Path, frames_path: Path | None = None) -> dict[str, Any]:
    """Every check of the module docstring on one policy file."""
    rollout = record_controls(policy_path)
    stats = gait_statistics(rollout)
    variants = []
    for name, tests, substeps, edit in VARIANTS:
        variants.append({"variant": name, "tests": tests, **replay(rollout, substeps, edit)})
    rendered = frames_path is not None and contact_sheet(rollout, frames_path)
    return {"policy": str(policy_path), "statistics": stats, "variants": variants,
            "frames": str(frames_path) if rendered else None}  # fmt: skip


def markdown(result: dict[str, Any], title: str) -> str:
    """A check's statistics and variant table as markdown."""
    s = result["statistics"]
    share, height, reaction = s["ground_force_share"], s["body_height"], s["ground_reaction_bw"]
    over = s["over_no_load_by_servo"]
    top = max(over, key=over.get)
    touching = ", ".join(f"{k} {v:.2f}" for k, v in list(s["touching_fraction"].items())[:6])
    slip = ", ".join(f"{k} {v:.2f}" for k, v in s["stance_slip_speed"].items())
    distance = ", ".join(f"{k} {v:.2f}" for k, v in s["slip_distance"].items())
    lines = [
        f"- +x progress {s['progress_x']:.2f} m ({s['speed']:.2f} m/s); no ground contact "
        f"{s['airborne_fraction']:.0%} of the time; body tilted up to {s['max_tilt_deg']:.0f} deg, its height "
        f"{height['min'] * 100:.1f} to {height['max'] * 100:.1f} cm",
        f"- ground force carried by the crutches {share['crutch']:.0%}, the knee servos' cases "
        f"{share['knee case']:.0%}, other parts {share['other']:.0%}; touching the ground (fraction of the time): "
        + touching,
        f"- foot slip speed in stance (force-weighted, m/s): {slip}; slip distance over the rollout (m): {distance}",
        f"- ground reaction: 99th percentile {reaction['p99']:.1f}, peak {reaction['max']:.0f} body weights (one "
        "2 ms step)",
        f"- leg servos faster than the no-load speed ({s['no_load_speed']:.2f} rad/s at 10 V) "
        f"{s['leg_servo_over_no_load']:.1%} of the time (most: {top}, {over[top]:.0%}), braking then "
        f"{s['braking_when_over_no_load']:.0%} of it (driven by the load); torque up to "
        f"{s['max_torque_over_stall']:.1f}x the stall torque; driving torque over the torque-speed line "
        f"at most {s['max_driving_torque_over_the_line']:.3f} N m (stall {s['stall_torque']:.2f} N m); joint limits "
        f"exceeded by at most {s['max_joint_limit_violation_deg']:.2f} deg",
        f"- parts passing through each other (deeper than {SELF_DEPTH * 1000:.0f} mm; the model lets them): "
        f"{s['self_penetration_fraction']:.0%} of the time, up to {s['self_penetration_max'] * 1000:.0f} mm"
        + ("" if not s["self_penetrating_pairs"] else " (" + ", ".join(list(s["self_penetrating_pairs"])[:3]) + ")"),
    ]
    header = ["the same controls on", "tests", "+x progress (m)", "tilted past the limit at", "force not on crutches"]
    rows = [
        [v["variant"], v["tests"], f"{v['progress_x']:+.2f}",
         "never" if v["fall_time"] is None else f"{v['fall_time']:.1f} s", f"{v['not_crutch_share']:.0%}"]
        for v in result["variants"]
    ]  # fmt: skip
    frames = ""
    if result["frames"]:
        frames = f"\nFrames (one second from t = 20 s, side view): `{Path(result['frames']).name}`\n"
    return f"### {title}\n\n" + "\n".join(lines) + "\n\n" + md_table(header, rows) + frames


CONFIGURATIONS: dict[str, list[str]] = {}
"""None kept in benchmarks/results/: the checks of the optimized gaits are in bioloid_cpg_experiments' results."""
FILES = ("{name}.json", "{name}.md", "{name}_[0-9]*.png")


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("policies", nargs="+", help="policy files written by agents.optimize (best.json)")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_cpg_check", CONFIGURATIONS, files=FILES)
    output.folder.mkdir(parents=True, exist_ok=True)
    results, parts = [], []
    for k, path in enumerate(args.policies):
        result = check(path, output.path(f"_{k}.png"))
        results.append(result)
        parts.append(markdown(result, str(path)))
    drop = drop_rebound()
    contacts = (f"The robot dropped {drop['height'] * 100:.0f} cm in its ready posture sinks "
                f"{drop['sink_below_rest'] * 1000:.1f} mm below where it comes to rest and rebounds "
                f"{drop['rebound_above_rest'] * 1000:.1f} mm above it.\n\n")  # fmt: skip
    output.save({"checks": results, "drop": drop}, "# Is the optimized CPG gait physical?\n\n" + contacts
         + "\n".join(parts))  # fmt: skip


if __name__ == "__main__":
    main()
