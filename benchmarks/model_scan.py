"""Why the VelociRoACH model's assumed constants are what they are: each alternative, measured.

The sources leave some constants open (foot lift, track width, leg mass and damping, floor friction, integrator).
For each, this scan changes one from the nominal model and runs the tripod: falls over 4 perturbed starts at 10,
20, 30, 35 and 45 Hz, speed at 45 Hz, and the turning rate at 10 Hz with the right legs trailing by 140 and 220 deg
(the sign of the offset should set the sign of the turn). The model files cite this scan.

Run: ``python -m benchmarks.model_scan``.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import mujoco
import numpy as np

from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, at_least_one, positive_number
from envs.common.locomotion import quat_up, quat_yaw
from envs.velociroach import constants
from envs.velociroach.robot import VelociRoach

LEGS = [f"{leg}_leg" for leg in constants.LEGS]


def set_lift(b: float) -> Callable[[mujoco.MjSpec], None]:
    """Foot ellipse with lift half-amplitude b (the two cranks' radii are (a + b) / 2 and (a - b) / 2)."""

    def edit(spec: mujoco.MjSpec) -> None:
        a = spec.numeric(constants.NUMERIC_SWEEP).data[0]
        r1, r2 = (a + b) / 2, (a - b) / 2
        for side in constants.SIDES:
            for kind, up in (("fb", -1), ("m", 1)):
                spec.body(f"link_{side}_{kind}").pos[2] = up * r1
                spec.body(f"carrier_{side}_{kind}").pos[2] = -up * r2
        spec.numeric(constants.NUMERIC_LIFT).data = [b]

    return edit


def set_track(half: float) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        for side, sign in (("left", 1), ("right", -1)):
            for name in (f"crank_{side}", f"crank_{side}_m"):
                spec.body(name).pos[1] = sign * half

    return edit


def set_leg_mass(grams: float) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        delta = 0.0
        for leg in LEGS:
            for g in spec.body(leg).geoms:
                delta += grams * 1e-3 / 4 - g.mass
                g.mass = grams * 1e-3 / 4
        spec.geom(constants.CHASSIS_GEOM).mass -= delta  # keep 30 g

    return edit


def set_leg_damping(value: float) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        for leg in constants.LEGS:
            spec.joint(f"{leg}_spring").damping[0] = value

    return edit


def set_friction(mu: float) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        spec.geom(constants.FLOOR_GEOM).friction[0] = mu
        for leg in LEGS:
            for g in spec.body(leg).geoms:
                g.friction[0] = mu

    return edit


def set_integrator(integrator: mujoco.mjtIntegrator) -> Callable[[mujoco.MjSpec], None]:
    def edit(spec: mujoco.MjSpec) -> None:
        spec.option.integrator = integrator

    return edit


VARIANTS: dict[str, Callable[[mujoco.MjSpec], None] | None] = {
    "nominal": None,
    "lift 4 mm (nominal 1.5)": set_lift(0.004),
    "lift 1 mm": set_lift(0.001),
    "track 35 mm (nominal 40)": set_track(0.0175),
    "legs 0.4 g (nominal 0.133)": set_leg_mass(0.4),
    "leg damping 0.3 N s/m (nominal 0.7)": set_leg_damping(0.3),
    "leg damping 1.5 N s/m": set_leg_damping(1.5),
    "friction 0.8 (nominal 0.4)": set_friction(0.8),
    "implicitfast integrator (nominal discrete)": set_integrator(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
}


def run(robot: VelociRoach, freq: float, phase: float, seed: int, seconds: float) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    robot.reset(np.array([0]), [rng], 0.0, {"crank_left": 0.0, "phase": phase})
    robot.set_body_velocity(rng.normal(0, 0.01, 3), rng.normal(0, 0.5, 3))
    yaws, fell = [], False
    start = None
    command = np.array([[freq, freq, phase]])
    while robot.data.time < seconds:
        robot.command(command)
        if not robot.step()[0]:
            return {"fell": 1.0, "speed": np.nan, "yaw_rate": np.nan}
        readings = robot.read([rng])
        pos, quat = readings["position"], readings["quaternion"]
        fell |= bool(quat_up(quat)[0] < 0.2)
        if robot.data.time > 1.0:
            if start is None:
                start = (robot.data.time, pos[0, 0], pos[0, 1])
            yaws.append(quat_yaw(quat)[0])
    duration = robot.data.time - start[0]
    return {
        "fell": float(fell),
        "speed": float(np.hypot(pos[0, 0] - start[1], pos[0, 1] - start[2]) / duration),
        "yaw_rate": float(np.degrees((np.unwrap(yaws)[-1] - yaws[0]) / duration)),
    }


CONFIGURATIONS: dict[str, list[str]] = {"model_scan": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--seeds", type=at_least_one, default=4)
    parser.add_argument("--seconds", type=positive_number, default=4.0)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "model_scan", CONFIGURATIONS)
    rows, out = [], {}
    for name, edit in VARIANTS.items():
        robot = VelociRoach("gait", spec_edits=[edit] if edit else [])
        falls, speed45 = 0, []
        for f in (10.0, 20.0, 30.0, 35.0, 45.0):
            for seed in range(args.seeds):
                r = run(robot, f, np.pi, seed, args.seconds)
                falls += int(r["fell"])
                if f == 45.0:
                    speed45.append(r["speed"])
        left = np.mean([run(robot, 10.0, np.radians(140), s, args.seconds)["yaw_rate"] for s in range(3)])
        right = np.mean([run(robot, 10.0, np.radians(220), s, args.seconds)["yaw_rate"] for s in range(3)])
        turns = "yes" if left > 0 > right else "no"
        out[name] = {"falls": falls, "runs": 5 * args.seeds, "speed45": speed45, "yaw140": left, "yaw220": right}
        rows.append(
            [name, f"{falls}/{5 * args.seeds}", round(float(np.nanmean(speed45)), 2), round(left), round(right), turns]
        )
        print(rows[-1], flush=True)
    header = ["variant", "falls (10-45 Hz)", "speed at 45 Hz (m/s)", "yaw 140 deg (deg/s)", "yaw 220 deg", "turns?"]
    text = (
        "# Model scan: the tripod on variants of the VelociRoACH model\n\n"
        f"Falls over {args.seeds} perturbed starts x 5 frequencies (10, 20, 30, 35, 45 Hz), {args.seconds:g} s each; "
        "turning at 10 Hz, 3 seeds: 'turns' means 140 deg turns left and 220 deg turns right.\n\n"
        + md_table(header, rows)
    )
    output.save({"variants": out}, text)


if __name__ == "__main__":
    main()
