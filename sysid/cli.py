"""Close the loop with measured data: replay logs in the model, trace the residual to the effects the model lacks,
add them, and report the error before and after on held-out logs: the code of the ``calibrate.py`` command.

    python calibrate.py --robot motor --train steps_a.csv --test steps_b.csv --out results/motor
    python calibrate.py --robot roach --train run.txt@0:6 --test run.txt@6: --out results/roach \
        [--calibration earlier/calibration.json] [--columns map.json]

A log may be given whole (``FILE``) or as a window of its own time in seconds (``FILE@START:END``, either end open);
windows of one file must not overlap between training and test.

Reads the project's telemetry (Parquet) and the real formats (VelociRoACH text telemetry, DYNAMIXEL Wizard exports,
the gearmotor CSV), or any CSV/JSON through a column map (``--columns``, see sysid/logs.py). Writes DIR/report.json,
DIR/report.md, DIR/residual_before.png, DIR/residual_after.png and DIR/calibration.json (the calibrated model, for
``gym.make(id, calibration=PATH)`` and ``evaluate.py --calibration PATH``) as one unit. Every input is checked before
anything is written; a bad one stops the run with one line naming the file, row and column, and exit code 2.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import tempfile
import time
import warnings
from collections.abc import Mapping
from pathlib import Path

from envs.common.calibration import CalibrationError, read_calibration
from envs.common.io import (
    ToolParser,
    foreign_unless,
    publish_folder,
    published_exit_code,
    replace_problem,
    results_folder_problem,
    run_interruptibly,
    unpublished_exit_code,
    write_json,
    write_text,
)
from envs.common.telemetry import ChannelLimit
from sysid.logs import ColumnMap, Log, LogError, check_log
from sysid.robots import adapter as make_adapter
from sysid.robots import adapters, read_log


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ToolParser(prog="calibrate.py", description=__doc__)
    p.add_argument("--robot", required=True, choices=sorted(adapters()), help="the robot (or bench rig) of the logs")
    p.add_argument("--train", required=True, nargs="+", type=Path, help="logs to calibrate on (FILE or FILE@START:END)")
    p.add_argument("--test", required=True, nargs="+", type=Path, help="held-out logs the errors are measured on")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--calibration", type=Path, help="start from an earlier calibration.json of the same robot")
    p.add_argument("--columns", type=Path,
                   help="a JSON file: the column map for logs of a format skitter has no reader for")  # fmt: skip
    p.add_argument("--fit", nargs="+", metavar="EFFECT", help="fit these catalog effects, without selecting")
    p.add_argument("--threads", type=int, help="rollout threads (default: the machine's cores)")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results of an earlier run in --out (a folder holding other files is refused)",
    )
    p.add_argument("--quiet", action="store_true", help="print only the result")
    args = p.parse_args(argv)
    if args.threads is not None and args.threads < 1:
        p.error(f"--threads must be at least 1, got {args.threads}")
    problem = results_folder_problem(args.out, args.overwrite, "calibrate.py", foreign_unless(RESULTS))
    problem = problem or replace_problem(args.out)
    if problem:
        p.error(problem)
    args.out_existed = args.out.exists()  # publishing checks again: a folder that appeared meanwhile is not replaced
    return args


RESULTS = ("calibration.json", "report.json", "report.md", "residual_after.png", "residual_before.png")


_WARNED: set[str] = set()
WINDOW = re.compile(r"^(?P<path>.+)@(?P<start>[0-9.eE+-]*):(?P<end>[0-9.eE+-]*)$")


def split_spec(spec: Path) -> tuple[Path, float | None, float | None]:
    """``FILE`` or ``FILE@START:END`` (a window of the log, seconds of its own time; either end may be left out)."""
    text = str(spec)
    m = WINDOW.match(text)
    if spec.exists():
        return spec, None, None
    if m is None:
        path, at, window = text.rpartition("@")
        if at and Path(path).is_file():  # a file with a window that is not one
            raise LogError(f"{text}: the window {'@' + window!r} is not @START:END in seconds")
        return spec, None, None
    try:
        start = float(m["start"]) if m["start"] else None
        end = float(m["end"]) if m["end"] else None
    except ValueError:
        raise LogError(f"{text}: the window {text[len(m['path']) :]!r} is not @START:END in seconds") from None
    if start is not None and end is not None and end <= start:
        raise LogError(f"{text}: the window ends ({end:g} s) before it starts ({start:g} s)")
    return Path(m["path"]), start, end


def read_logs(
    specs: list[Path],
    required: tuple[str, ...],
    column_map: ColumnMap | None,
    limits: Mapping[str, ChannelLimit] | None = None,
    tool: str = "calibrate.py",
) -> list[Log]:
    logs = []
    for spec in specs:
        path, start, end = split_spec(spec)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            log = read_log(path, required, column_map, limits)
        for message in dict.fromkeys(str(w.message) for w in caught):  # once each, in order
            if message not in _WARNED:
                _WARNED.add(message)
                print(f"{tool}: warning: {message}", file=sys.stderr)
        if start is not None or end is not None:
            t = log.time
            if (start is not None and start > t[-1]) or (end is not None and end < t[0]):
                raise LogError(f"{spec}: the window lies outside the log, which runs from {t[0]:.3g} s to "
                               f"{t[-1]:.3g} s")  # fmt: skip
            if start is not None and start < min(0.0, t[0]):  # a typo, not a window that begins with the log
                raise LogError(f"{spec}: the window starts at {start:g} s, before the log, which runs from "
                               f"{t[0]:.3g} s to {t[-1]:.3g} s")  # fmt: skip
            if end is not None and end > t[-1] + 1.0:  # a typo too, not a window that ends with the log
                rest = f"{path}@{'' if start is None else f'{start:g}'}:"
                raise LogError(f"{spec}: the window ends at {end:g} s, past the log's end at {t[-1]:.3g} s; give "
                               f"{rest} for the rest of the log")  # fmt: skip
            log = log.between(t[0] if start is None else start, t[-1] + 1.0 if end is None else end)
            log.path = str(spec)
            log = check_log(log, required)
        logs.append(log)
    return logs


def check_disjoint(
    train: list[Path], test: list[Path], train_flag: str = "--train", train_name: str = "training log"
) -> None:
    """No test data may be training data, and no stretch of a file may be given twice to one of them (it would count
    twice): the same file only in windows that do not overlap (of a file that does not exist, that it does not
    exist). ``train_flag`` and ``train_name`` say where the training logs were given and what they are
    (``sysid.measure``: its measured logs)."""
    for flag, specs in ((train_flag, train), ("--test", test)):
        for i, a in enumerate(specs):
            for b in specs[i + 1 :]:
                if _overlap(a, b):
                    raise LogError(f"{b} overlaps {a}, both given to {flag}: each stretch of a log counts once")
    for a in train:
        for b in test:
            if _overlap(a, b):
                raise LogError(f"{b} overlaps the {train_name} {a}: the test logs must be data the fit does not see")


def _overlap(a: Path, b: Path) -> bool:
    """Whether two log specs (a file, with or without a window) share data."""
    pa, sa, ea = split_spec(a)
    pb, sb, eb = split_spec(b)
    if pa.resolve() != pb.resolve():
        return False
    lo = max(-math.inf if sa is None else sa, -math.inf if sb is None else sb)
    hi = min(math.inf if ea is None else ea, math.inf if eb is None else eb)
    if lo < hi and not pa.is_file():
        raise LogError(f"{pa}: no such file")
    return lo < hi


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    return run_interruptibly("calibrate.py", args.out, lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    say = (lambda s: None) if args.quiet else (lambda s: print(s, flush=True))
    adapter = make_adapter(args.robot)
    try:
        column_map = ColumnMap.load(args.columns) if args.columns else None
        if column_map is not None:
            reads = adapter.reads()
            unread = [name for name in column_map.columns if name not in reads]
            if unread:  # a misspelt channel would leave its column unread: a logged goal fitted, say
                print(f"calibrate.py: warning: {args.columns}: the {args.robot}'s calibration reads no channel named "
                      f"{', '.join(map(repr, unread))}; those columns are ignored (it reads "
                      f"{', '.join(sorted(reads - {'episode'}))})", file=sys.stderr)  # fmt: skip
        limits = adapter.channel_limits()  # a sample the robot could not produce is dropped, with a warning
        # each window is found in its log before the windows are compared: a window past its log is that error
        train = read_logs(args.train, adapter.required(), column_map, limits)
        check_disjoint(args.train, [])
        test = read_logs(args.test, adapter.required(), column_map, limits)
        check_disjoint(args.train, args.test)
        start = None
        if args.calibration is not None:
            start = read_calibration(args.calibration, adapter.robot)
            start.check(adapter.known_effects())
        for log in [*train, *test]:  # a telemetry file names the robot it was recorded on
            declared = log.meta.get("robot")
            if isinstance(declared, str) and declared not in (args.robot, adapter.robot):
                print(f"calibrate.py: warning: {log.path}: its metadata says it was recorded on the {declared!r}; "
                      f"calibrating the {args.robot!r} on it", file=sys.stderr)  # fmt: skip
        adapter.check_logs([*train, *test])
        adapter.check_length([*train, *test])
        known = adapter.known_effects()
        for name in args.fit or ():
            if name not in known:
                raise LogError(f"--fit {name!r}: {args.robot} has no such effect (known: {', '.join(known)})")
        repeated = sorted({name for name in args.fit or () if args.fit.count(name) > 1})
        if repeated:
            raise LogError(f"--fit names {', '.join(repeated)} more than once: give each effect once")
    except (LogError, CalibrationError) as exc:
        print(f"calibrate.py: error: {exc}", file=sys.stderr)
        return 2
    from sysid.pipeline import run
    from sysid.report import baseline, calibration_dict, plot_residuals, report_dict, report_markdown

    try:
        result = run(adapter, train, test, start.setting if start else None, say=say, nthread=args.threads,
                     effects=args.fit, warn=lambda s: print(f"calibrate.py: {s}", file=sys.stderr))  # fmt: skip
    except ValueError as exc:  # e.g. logs too short to cut into segments
        print(f"calibrate.py: error: {exc}", file=sys.stderr)
        return 2
    report = report_dict(result, time.perf_counter() - started, str(args.calibration) if start else None)
    out: Path = args.out
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{out.name}.", dir=out.parent) as tmp:
        staging = Path(tmp) / "calibration"
        staging.mkdir()
        write_json(staging / "report.json", report)
        write_text(staging / "report.md", report_markdown(report))
        write_json(staging / "calibration.json", calibration_dict(result, report, _base(start)))
        plot_residuals(result, staging / "residual_before.png", "before")
        plot_residuals(result, staging / "residual_after.png", "after")
        try:
            where = publish_folder(staging, out, args.out_existed, foreign_unless(RESULTS))
        except OSError as exc:  # checked before the run, yet the file system may change in minutes
            return unpublished_exit_code("calibrate.py", staging, out, exc)
    chosen = ", ".join(c["name"] for c in report["chosen"]) or "nothing"
    print(
        f"{args.robot}: held-out error {report['error_before']:.3g} -> {report['error_after']:.3g} (1 is the noise "
        f"floor); kept {chosen}; {'unexplained' if report['unexplained'] else 'explained'}. Results in {where}/"
    )
    if report["worse_on_test"]:
        after, before = report["error_after"], report["error_before"]
        print(f"calibrate.py: warning: the calibrated model's held-out error ({after:.3g}) is above that of the "
              f"{baseline(report)} ({before:.3g}); see {where}/report.md", file=sys.stderr)  # fmt: skip
    return published_exit_code("calibrate.py", out, where)


def _base(start) -> dict | None:
    if start is None:
        return None
    return {name: {p: {"value": v} for p, v in params.items()} for name, params in start.effects.items()}
