"""``python -m sysid.measure --robot ROBOT LOG ...``: what each log measures by itself, before any replay, beside
the nominal model's values (the robot's ``Adapter.measure_log``; the VelociRoACH's:
sysid/adapters/velociroach_measure.py).
Logs are whole files or windows ``FILE@START:END``; ``--out`` also writes the measurements as JSON, a new file.

``--calibration-out FILE`` writes a calibration file (``gym.make(id, calibration=FILE)``, ``calibrate.py
--calibration FILE``) from the measurements alone: the robot's measurements that read a catalog effect's parameter
directly (``Adapter.effect_readings``; the roach's back-EMF reading's scale, duty coupling and zero per side),
pooled over the logs by inverse variance. A parameter is written only where its interval excludes the nominal
value, the logs agree (their intervals overlap) and the value lies in the effect's range; each decision is printed.
With ``--test LOG ...`` (logs not measured) it also replays the test logs in the nominal and the measured model
and reports both held-out errors, as ``calibrate.py`` does, and writes them into the file's provenance.
"""

from __future__ import annotations

import json
import os
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from sysid.measurement import MeasuredEffect, Measurement, pool, table


def main(argv: list[str] | None = None) -> int:
    from envs.common.io import ToolParser, parent_problem
    from sysid.cli import check_disjoint, read_logs
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
    parser.add_argument(
        "--calibration-out",
        metavar="FILE",
        help="also write a calibration file (a new file) of the effects the measurements read directly",
    )
    parser.add_argument(
        "--test",
        nargs="+",
        metavar="LOG",
        default=[],
        help="with --calibration-out: held-out logs (not among those measured) on which the nominal and the "
        "measured model are replayed and their errors reported",
    )
    parser.add_argument("--threads", type=int, help="rollout threads for --test (default: the machine's cores)")
    args = parser.parse_args(argv)
    if args.seed < 0:
        parser.error(f"--seed must be a whole number >= 0, got {args.seed}")
    if args.threads is not None and args.threads < 1:
        parser.error(f"--threads must be at least 1, got {args.threads}")
    if args.test and args.calibration_out is None:
        parser.error("--test replays the measured model: give --calibration-out FILE too")
    for flag, path in (("--out", args.out), ("--calibration-out", args.calibration_out)):
        if path is None:
            continue
        if os.path.lexists(path):  # a dangling link too: never written through
            parser.error(f"{flag} {path}: already exists; choose another path or remove it first")
        problem = parent_problem(path)
        if problem:
            parser.error(f"{flag} {path}: {problem}")
    if args.out is not None and args.calibration_out is not None and _same_file(args.out, args.calibration_out):
        parser.error(f"--out {args.out} and --calibration-out {args.calibration_out} are one file: give two files")
    robot = make_adapter(args.robot)
    measurements: list[Measurement] = []
    test = []
    try:
        check_disjoint(
            [Path(t) for t in args.logs], [Path(t) for t in args.test or []], "the measured logs", "measured log"
        )
        logs = [read_logs([Path(text)], robot.required(), None, tool="measure")[0] for text in args.logs]
        if args.test:
            test = read_logs([Path(t) for t in args.test], robot.required(), None, robot.channel_limits(), "measure")
            robot.check_logs(test)
            robot.check_length(test)
        for log in logs:
            measurements += robot.measure_log(log, seed=args.seed)
    except (LogError, ValueError) as exc:
        print(f"python -m sysid.measure: error: {exc}", file=sys.stderr)
        return 2
    if not measurements:
        print(f"measure: the {args.robot}'s logs measure nothing by themselves here (its adapter has no measure_log)")
    else:
        print(table(measurements), end="")
    code = 0
    if args.out is not None:
        code = _write_new(Path(args.out), json.dumps([asdict(m) for m in measurements], indent=1) + "\n")
    if args.calibration_out is not None:
        code = max(code, _write_calibration(robot, measurements, test, args))
    return code


def measured_effects(robot: Any, measurements: list[Measurement]) -> tuple[dict[str, dict], list[MeasuredEffect]]:
    """The calibration's effects (``effect -> param -> {value, ci95, unit}``) from the measurements that read a
    catalog effect directly, and every pooled reading; each decision is printed, a disagreement as a warning."""
    known = {name: {p.name: p for p in effect.params} for name, effect in robot.catalog().items()}
    pooled = pool(robot.effect_readings(measurements))
    effects: dict[str, dict] = {}
    for m in pooled:
        name = f"{m.effect}.{m.param}"
        where = f"{m.value:.4g} [{m.low:.4g}, {m.high:.4g}] from {', '.join(m.logs)}"
        param = known.get(m.effect, {}).get(m.param)
        if m.logs_disagree:
            each = "; ".join(f"{r.value:.4g} [{r.low:.4g}, {r.high:.4g}] from {r.log}" for r in m.readings)
            print(f"measure: warning: {name}: the logs' intervals do not overlap ({each}): they measure different "
                  "robots or conditions; not written (measure them one at a time)", file=sys.stderr)  # fmt: skip
        elif not m.significant:
            print(f"{name}: {where}; its interval holds the nominal {m.nominal:g}: left nominal")
        elif param is None or not param.low <= m.value <= param.high:
            span = "" if param is None else f" [{param.low:g}, {param.high:g}]"
            print(f"{name}: {where}; outside the effect's range{span}: not written (the catalog's range, or the "
                  "model's form, is wrong for this robot)")  # fmt: skip
        else:
            print(f"{name}: {where}; nominal {m.nominal:g}: written")
            effects.setdefault(m.effect, {})[m.param] = {"value": m.value, "ci95": [m.low, m.high],
                                                         "unit": param.unit}  # fmt: skip
    return effects, pooled


def held_out_errors(robot: Any, test: list, setting: dict[str, float], threads: int | None) -> tuple[Any, Any]:
    """The held-out error (``sysid.pipeline.HeldOut``) of the nominal and of the measured model on ``test``, in
    noise levels, each log's nuisance parameters fitted first, against the replay floor of the measured model (as
    ``calibrate.py`` measures it)."""
    from sysid.pipeline import held_out
    from sysid.problem import Problem

    problem = Problem(robot, test, threads, floor_setting=setting)
    return held_out(problem, {}), held_out(problem, setting)


def _write_calibration(robot: Any, measurements: list[Measurement], test: list, args: Any) -> int:
    from envs.common.calibration import calibration_record

    effects, pooled = measured_effects(robot, measurements)
    provenance: dict[str, Any] = {
        "tool": "python -m sysid.measure",
        "logs": list(args.logs),
        "seed": args.seed,
        "measured": [
            {
                "effect": m.effect,
                "param": m.param,
                "value": m.value,
                "ci95": [m.low, m.high],
                "logs_disagree": m.logs_disagree,
                "readings": [asdict(r) for r in m.readings],
            }
            for m in pooled
        ],
    }
    if test:
        setting = {f"{e}.{p}": v["value"] for e, params in effects.items() for p, v in params.items()}
        before, after = held_out_errors(robot, test, setting, args.threads)
        print(f"held-out error (noise levels): nominal {before.error:.3g}, measured {after.error:.3g}")
        for log, error in before.per_log.items():
            print(f"  {log}: {error:.3g} -> {after.per_log.get(log, float('nan')):.3g}")
        provenance |= {"test": list(args.test), "error_nominal": before.error, "error_measured": after.error,
                       "per_log": {log: [e, after.per_log.get(log)] for log, e in before.per_log.items()}}  # fmt: skip
    if not effects:
        print("measure: no effect measured away from nominal; the calibration file holds none")
    record = calibration_record(robot.robot, effects, provenance)
    return _write_new(Path(args.calibration_out), json.dumps(record, indent=1) + "\n")


def _write_new(path: Path, text: str) -> int:
    """Write ``path`` whole, never over a file that appeared there meanwhile (kept under its own name then)."""
    from envs.common.io import atomic_write_new

    where, written = atomic_write_new(path, lambda tmp: tmp.write_text(text))
    if not written:
        print(f"python -m sysid.measure: error: {path} appeared during the run and is left as it was; the "
              f"measurements are in {where}", file=sys.stderr)  # fmt: skip
        return 1
    return 0


def _same_file(a: str, b: str) -> bool:
    """Whether two output paths name one file (``x.json`` and ``./x.json``, or through a link to the folder)."""
    return Path(a).resolve() == Path(b).resolve()


if __name__ == "__main__":
    sys.exit(main())
