"""PettingZoo's own tests on every soccer match: each robot, each team size (1 to 3 a side, 4 for the Bioloid), in
both action modes (the robot's own and ``commands``).

For every configuration it runs ``parallel_api_test``, ``api_test`` (AEC), ``parallel_seed_test``, ``seed_test``,
``max_cycles_test`` and ``render_test`` (``pettingzoo.test``) and records which passed, with the first error of any
that failed. ``make test`` runs them on a three-a-side Bioloid match; this runs the whole matrix.

Run: ``python -m benchmarks.soccer_api`` (about 2 minutes).
"""

from __future__ import annotations

import argparse
import functools
import time
import traceback
import types

from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test, seed_test

from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser
from envs.soccer import match
from envs.soccer.steering import COMMANDS

CONFIGURATIONS: dict[str, list[str]] = {"soccer_api": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
CYCLES = 100  # steps of each test (PettingZoo's defaults are 500-1000: a minute a test on the roach's 2 kHz physics)
TESTS = ("parallel_api_test", "api_test", "parallel_seed_test", "seed_test", "max_cycles_test", "render_test")


MODES = ("own", COMMANDS)  # the robot's own action mode (its first), and the commands mode


def matrix() -> list[tuple[str, int, str]]:
    """(robot, players a side, action mode) of every configuration the suite promises."""
    sizes = {"roach": 3, "xjus": 3, "bioloid": 4}
    return [(robot, k, mode) for robot, most in sizes.items() for k in range(1, most + 1) for mode in MODES]


def battery(robot: str, k: int, mode: str, cycles: int) -> dict[str, str | None]:
    """Each test's error (None: passed)."""
    action_mode = None if mode == "own" else mode
    parallel = functools.partial(match.parallel_env, robot=robot, players_per_team=k, action_mode=action_mode)
    aec = functools.partial(match.env, robot=robot, players_per_team=k, action_mode=action_mode)
    runs = {
        "parallel_api_test": lambda: parallel_api_test(parallel(), num_cycles=cycles),
        "api_test": lambda: api_test(aec(), num_cycles=cycles),
        "parallel_seed_test": lambda: parallel_seed_test(parallel, num_cycles=cycles),
        "seed_test": lambda: seed_test(aec, num_cycles=cycles),
        "max_cycles_test": lambda: max_cycles_test(types.SimpleNamespace(parallel_env=parallel, env=aec)),
        "render_test": lambda: render_test(functools.partial(aec, render_mode="rgb_array")),
    }
    errors: dict[str, str | None] = {}
    for name in TESTS:
        try:
            runs[name]()
            errors[name] = None
        except Exception:  # a failed test is a result to report, not a reason to stop the matrix
            errors[name] = traceback.format_exc(limit=3).strip().splitlines()[-1]
    return errors


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--cycles", type=int, default=CYCLES, help="steps of each test")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.cycles < 1:
        parser.error(f"--cycles must be at least 1, got {args.cycles}")
    output = resolve_output(parser, args, "soccer_api", CONFIGURATIONS)
    rows = []
    for robot, k, mode in matrix():
        started = time.perf_counter()
        errors = battery(robot, k, mode, args.cycles)
        rows.append({"robot": robot, "players_per_team": k, "action_mode": mode, "errors": errors,
                     "seconds": time.perf_counter() - started})  # fmt: skip
    failed = [(r["robot"], r["players_per_team"], r["action_mode"], t)
              for r in rows for t, e in r["errors"].items() if e]  # fmt: skip
    table = md_table(
        ["robot", "a side", "action mode", *TESTS, "seconds"],
        [[r["robot"], r["players_per_team"], r["action_mode"],
          *("passed" if r["errors"][t] is None else "FAILED" for t in TESTS), f"{r['seconds']:.1f}"] for r in rows],
    )  # fmt: skip
    verdict = f"{len(rows) * len(TESTS) - len(failed)} of {len(rows) * len(TESTS)} passed" + (
        "" if not failed else "; failed: " + "; ".join(f"{r} {k} a side, {m} mode: {t}" for r, k, m, t in failed)
    )
    md = (
        "# PettingZoo's tests on every soccer match\n\n"
        f"Each test with {args.cycles} cycles where it takes a number, in each action mode (own: the robot's "
        "first).\n\n" + table + f"\n{verdict}.\n"
    )
    output.save({"rows": rows, "cycles": args.cycles, "passed": not failed}, md)


if __name__ == "__main__":
    main()
