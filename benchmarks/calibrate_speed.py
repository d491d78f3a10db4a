"""Wall time of the whole calibration loop on 60 s of 1 kHz VelociRoACH telemetry (goal: under
5 minutes on 2 cores).

A synthetic log (sysid.synth: the firmware's clocks at 1 kHz with a hidden effect drawn by the seed) is written as
Parquet; ``calibrate.py --robot roach --train LOG@0:45 --test LOG@45:`` runs on it, as a user would run it. Beside
the wall time, the time of one replay of the whole log through the model (every segment, the nominal setting) gives
the loop's cost in replays, a number that does not depend on the machine's load.

Run: ``python -m benchmarks.calibrate_speed [--seconds 60] [--effect coulomb_friction_right] [--seed 0]``.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, non_negative, positive_number
from envs.common.telemetry import write_telemetry
from sysid import cli as calibrate_cli
from sysid import synth
from sysid.problem import Problem
from sysid.robots import adapter as make_adapter

GOAL_MINUTES = 5.0


CONFIGURATIONS: dict[str, list[str]] = {"calibrate_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--seconds", type=positive_number, default=60.0)
    parser.add_argument("--effect", default="coulomb_friction_right")
    parser.add_argument("--seed", type=non_negative, default=0)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    p = make_parser()
    args = p.parse_args(argv)
    output = resolve_output(p, args, "calibrate_speed", CONFIGURATIONS)
    adapter = make_adapter("roach")
    t0 = time.perf_counter()
    log, truth = synth.synthesize("roach", {args.effect: None}, args.seed, seconds=args.seconds)
    synth_seconds = time.perf_counter() - t0
    problem = Problem(adapter, [log])
    setting = adapter.catalog_nominal()
    problem.residuals([setting])  # models compiled, as the loop's first replay compiles them
    problem._carry.clear()  # but no run of this setting kept: a replay of the log from scratch
    problem._sensitivity.clear()
    t0 = time.perf_counter()
    problem.residuals([setting])
    replay = time.perf_counter() - t0
    split = round(0.75 * args.seconds, 3)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "roach.parquet"
        write_telemetry(path, log.df, log.meta)
        argv_cal = ["--robot", "roach", "--train", f"{path}@0:{split}", "--test", f"{path}@{split}:",
                    "--out", str(Path(tmp) / "out"), "--quiet"]  # fmt: skip
        t0 = time.perf_counter()
        code = calibrate_cli.main(argv_cal)
        wall = time.perf_counter() - t0
        report = json.loads((Path(tmp) / "out" / "report.json").read_text()) if code == 0 else {}
    minutes = wall / 60
    verdict = "met" if code == 0 and minutes < GOAL_MINUTES else "MISSED"
    chosen = ", ".join(c["name"] for c in report.get("chosen", [])) or "none"
    md = (
        f"# calibrate.py on {args.seconds:g} s of 1 kHz VelociRoACH telemetry\n\n"
        f"{os.cpu_count()} cores. Hidden effect {args.effect} = {truth['effects'][args.effect]} (seed {args.seed}); "
        f"train 0-{split:g} s, test {split:g}-{args.seconds:g} s.\n\n"
        + md_table(
            ["whole loop (min)", "goal (min)", "goal", "one replay of the log (s)", "loop in replays", "chosen",
             "held-out error before", "after", "exit code"],
            [[minutes, GOAL_MINUTES, verdict, replay, wall / replay, chosen, report.get("error_before", float("nan")),
              report.get("error_after", float("nan")), code]],
        )
        + f"\n(generating the log took {synth_seconds:.0f} s, not counted)\n"
    )  # fmt: skip
    output.save({"seconds_of_log": args.seconds, "effect": args.effect, "truth": truth["effects"],
                             "wall_seconds": wall, "goal_minutes": GOAL_MINUTES, "verdict": verdict,
                             "replay_seconds": replay, "exit_code": code, "report": report}, md)  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
