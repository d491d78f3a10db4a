"""``python -m sysid.measure --robot ROBOT LOG ...``: what each log measures by itself, before any replay, beside
the nominal model's values (the robot's ``Adapter.measure_log``; the VelociRoACH's:
sysid/adapters/velociroach_measure.py).
Logs are whole files or windows ``FILE@START:END``; ``--out`` also writes the measurements as JSON, a new file.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

from sysid.measurement import Measurement, table


def main(argv: list[str] | None = None) -> int:
    from envs.common.io import ToolParser, parent_problem
    from sysid.cli import read_logs
    from sysid.logs import LogError
    from sysid.robots import adapter as make_adapter
    from sysid.robots import adapters

    parser = ToolParser(prog="python -m sysid.measure", description=__doc__)
    from sysid.problem import Adapter

    # the robots whose logs measure something by themselves (their adapter reads them: Adapter.measure_log)
    measurable = sorted(name for name, cls in adapters().items() if cls.measure_log is not Adapter.measure_log)
    parser.add_argument(
        "--robot",
        required=True,
        choices=measurable,
        help="the robot the logs are of (only these robots' logs hold measurements of their own)",
    )
    parser.add_argument("logs", nargs="+", metavar="LOG", help="logs, whole or FILE@START:END")
    parser.add_argument("--out", help="also write the measurements here as JSON (a new file)")
    parser.add_argument("--seed", type=int, default=0, help="the bootstrap's seed (default 0)")
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.error(f"--seed must be a whole number >= 0, got {args.seed}")
    if args.out is not None:
        if os.path.lexists(args.out):  # a dangling link too: never written through
            parser.error(f"--out {args.out}: already exists; choose another path or remove it first")
        problem = parent_problem(args.out)
        if problem:
            parser.error(f"--out {args.out}: {problem}")
    robot = make_adapter(args.robot)
    measurements: list[Measurement] = []
    for text in args.logs:
        try:
            (log,) = read_logs([Path(text)], robot.required(), None, tool="measure")
            measurements += robot.measure_log(log, seed=args.seed)
        except (LogError, ValueError) as exc:
            print(f"measure: error: {exc}", file=sys.stderr)
            return 2
    if not measurements:
        print(f"measure: the {args.robot}'s logs measure nothing by themselves here (its adapter has no measure_log)")
    else:
        print(table(measurements), end="")
    if args.out is not None:
        return _write_new(Path(args.out), json.dumps([asdict(m) for m in measurements], indent=1) + "\n")
    return 0


def _write_new(path: Path, text: str) -> int:
    """Write ``path`` whole, never over a file that appeared there meanwhile (kept under its own name then)."""
    from envs.common.io import atomic_write_new

    where, written = atomic_write_new(path, lambda tmp: tmp.write_text(text))
    if not written:
        print(f"measure: error: {path} appeared during the run and is left as it was; the measurements are in "
              f"{where}", file=sys.stderr)  # fmt: skip
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
