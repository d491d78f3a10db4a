"""Does a hidden effect show in a robot's synthetic logs against the replay floor of the right model?

The replay floor (what replay in segments cannot match even with the right model: the unlogged body) depends on the
model replayed. Calibration starts from the nominal model and sees its floor; the held-out evaluation
(sysid/pipeline.py) measures against the floor of the calibrated model. Where the effect itself makes the body's
replay diverge more (a high foot friction, say), the two floors differ, and a log visible against the nominal floor
can sit at the floor of the right model: no calibration could then halve its excess. The generator (sysid/synth.py)
therefore asks for 3 noise levels against both. This tool shows how far the two floors part.

This prints, for an effect at given values, each seed and each of the generator's command draws, the nominal model's
error against both floors.

    python -m benchmarks.calibration_visibility --robot roach --effect foot_friction=1.39 --seeds 1013 --draws 4

``--effect`` takes NAME=VALUE (the first parameter) or NAME=p:v,p:v as ``python -m sysid.synth`` does. The seed of a
case's held-out log is its seed + ``sysid.cases.TEST_SEED_OFFSET``.

``--cases FILE`` instead takes every catalogued-effect case of a calibration matrix's results (its JSON) and measures
the first command draw of its training seed and of its held-out seed at the case's truth: where the two floors part,
a generator that measured visibility against the truth's floor would draw other truths or logs.

    python -m benchmarks.calibration_visibility --cases benchmarks/results/calibration_matrix_roach_motor_servo.json
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from benchmarks.common import Output, add_output_options, md_table, resolve_output
from envs.common.io import ToolParser
from sysid import synth
from sysid.robots import adapter as make_adapter
from sysid.robots import adapters


def measure(robot: str, effect: str, value: float | dict[str, float], seeds: Sequence[int], draws: int) -> dict:
    """The nominal model's error against the nominal floor and against the truth's, per seed and command draw."""
    adapter = make_adapter(robot)
    catalog = adapter.effects()
    if effect not in catalog:
        raise ValueError(f"robot {robot!r} has no effect {effect!r} (see python -m sysid.synth --list)")
    # given values are checked against the effect's names and ranges; nothing is drawn from the generator
    given = synth.effect_values(catalog[effect], value, np.random.default_rng(0))
    truth = {catalog[effect].key(k): v for k, v in given.items()}
    runs, seconds = synth.protocol(adapter)
    rows = []
    for seed in seeds:
        for draw in range(draws):
            start = time.perf_counter()
            # the robot's recording protocol, as the generator records a case
            log = [synth.noisy_log(adapter, truth, synth.excitation_commands(adapter, seconds, s, draw), s, robot)
                   for s in synth.run_seeds(seed, runs)]  # fmt: skip
            rows.append({"seed": seed, "draw": draw, "against_nominal_floor": synth.nominal_error(adapter, log),
                         "against_truth_floor": synth.nominal_error(adapter, log, floor_setting=truth),
                         "seconds": time.perf_counter() - start})  # fmt: skip
    return {"robot": robot, "effect": effect, "setting": truth, "rows": rows}


def matrix_cases(path: Path) -> list[dict]:
    """Each catalogued-effect case of a matrix's results, at its truth: the training seed's and the held-out seed's
    first command draw, against both floors, beside the case's recorded errors."""
    from sysid.cases import TEST_SEED_OFFSET

    rows = []
    for case in json.loads(path.read_text())["effects"]:
        ((name, values),) = case["injected"].items()
        seeds = [case["seed"], case["seed"] + TEST_SEED_OFFSET]
        train, held_out = measure(case["robot"], name, values, seeds, 1)["rows"]
        rows.append({"robot": case["robot"], "effect": name, "seed": case["seed"], "truth": values,
                     "train": train, "held_out": held_out, "case_nominal_error": case["nominal_error"],
                     "case_error_before": case["error_before"]})  # fmt: skip
    return rows


def _main_cases(parser: argparse.ArgumentParser, path: Path, output: Output) -> None:
    try:
        rows = matrix_cases(path)
    except (OSError, ValueError, KeyError, TypeError) as e:
        parser.error(f"--cases {path}: not a calibration matrix's results ({type(e).__name__}: {e})")
    table = md_table(
        ["robot", "effect", "seed", "training draw 0: nominal floor", "truth's floor", "held-out draw 0: nominal floor",
         "truth's floor", "case: training error", "case: held-out before"],
        [[r["robot"], r["effect"], r["seed"], round(r["train"]["against_nominal_floor"], 2),
          round(r["train"]["against_truth_floor"], 2), round(r["held_out"]["against_nominal_floor"], 2),
          round(r["held_out"]["against_truth_floor"], 2), round(r["case_nominal_error"], 2),
          round(r["case_error_before"], 2)] for r in rows],
    )  # fmt: skip
    text = (
        f"# Visibility of each case of `{path.name}` against both replay floors\n\n"
        "The first command draw of each case's training seed and held-out seed, at the case's truth. The case's own "
        "training log may come from a later draw or push (its training error, recorded by the generator against the "
        "nominal floor in earlier versions and the truth's since, is beside); its held-out error before calibration is "
        "measured against the calibrated model's floor.\n\n" + table
    )
    output.save({"matrix": str(path), "cases": rows}, text)


CONFIGURATIONS: dict[str, list[str]] = {
    "calibration_visibility_roach_foot_friction": ["--robot", "roach", "--effect", "foot_friction=1.39", "--seeds",
                                                   "13", "1013", "--draws", "3"],
    "calibration_visibility_roach_foot_friction_far": ["--robot", "roach", "--effect", "foot_friction=1.5", "--seeds",
                                                       "0", "1", "2", "--draws", "1"],
}  # fmt: skip
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--robot", choices=sorted(adapters()))
    parser.add_argument("--effect", type=synth.parse_effect, help="NAME=VALUE or NAME=p:v,p:v")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--draws", type=int, default=synth.EXCITATIONS, help="command draws per seed")
    parser.add_argument("--cases", type=Path, help="a calibration matrix's results (JSON): measure each effect case")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "calibration_visibility", CONFIGURATIONS)
    if args.cases is not None:
        if args.robot or args.effect:
            parser.error("--cases measures the matrix's own cases: give it without --robot and --effect")
        _main_cases(parser, args.cases, output)
        return
    if not args.robot or not args.effect:
        parser.error("give --robot and --effect, or --cases")
    name, value = args.effect
    if value is None:
        parser.error("--effect needs a value: NAME=VALUE or NAME=p:v,p:v")
    if args.draws < 1:
        parser.error(f"--draws must be at least 1, got {args.draws}")
    try:
        result = measure(args.robot, name, value, args.seeds, args.draws)
    except ValueError as e:
        parser.error(str(e))
    rows = result["rows"]
    table = md_table(
        ["seed", "command draw", "error against the nominal model's floor", "against the truth's floor", "s"],
        [[r["seed"], r["draw"], round(r["against_nominal_floor"], 3), round(r["against_truth_floor"], 3),
          round(r["seconds"])] for r in rows],
    )  # fmt: skip
    medians = [float(np.median([r[k] for r in rows])) for k in ("against_nominal_floor", "against_truth_floor")]
    text = (
        f"# Visibility of {name} on the {args.robot}\n\n"
        f"Setting {result['setting']}. The generator calls an effect visible at an error of "
        f"{synth.MIN_NOMINAL_ERROR:g} against both floors (earlier versions: the truth's alone, before that the "
        "nominal's); "
        "the held-out evaluation measures against the calibrated model's.\n\n"
        + table
        + f"\nMedian: {medians[0]:.2f} against the nominal floor, {medians[1]:.2f} against the truth's.\n"
    )
    output.save({**result, "median_against_nominal_floor": medians[0], "median_against_truth_floor": medians[1]},
         text)  # fmt: skip


if __name__ == "__main__":
    main()
