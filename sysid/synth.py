"""Synthetic logs with hidden effects: telemetry from the model with effects nobody declares, under exciting commands
and sensor noise, to test calibration.

    python -m sysid.synth --robot motor --effect viscous_friction --seed 3 --out data.parquet
    python -m sysid.synth --robot servo --effect delay=0.02 --effect servo_gain=1.8 --seed 0 --out servo.parquet
    python -m sysid.synth --robot motor --effect disturbance=torque:0.3,frequency:4 --out disturbed.parquet
    python -m sysid.synth --list

An effect given without a value is drawn from its range with the seed, far enough from its nominal value that the
nominal model's error on the data is at least 3 (three times the noise floor), measured against the replay floor of
the true model (its catalogued part), as the held-out evaluation measures a calibrated model, and against the nominal
model's own, as calibration first sees the data (:func:`visibility`): pushed up to 90% of
the way to a bound, and where even that does not show, under other commands drawn from the same seed (up to three
draws). Given values are not moved; a case's held-out log of them (``synthesize(..., show=True)``, sysid/cases.py)
is, where the first commands do not show them, the one of three draws of the commands that shows them best. A robot
that records its cases as several short runs (``Adapter.runs``) has its effects drawn and shown on those runs
together (:func:`record`). The log holds the commands, the measured channels (with noise) and the noise levels; the
truth goes to a separate ``<out>.truth.json`` that calibration never reads. Out-of-catalog effects (a terrain bump,
a periodic disturbance) can be injected too. An effect may ask for its recording (``Effect.meta["record"]``, into
the log's record: the servo rig's load friction and gearbox efficiency are recorded on a loaded bench).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from envs.common.effects import Effect
from envs.common.io import ToolParser, parent_problem, write_json
from envs.common.telemetry import METADATA_KEY, write_telemetry
from sysid.logs import Log
from sysid.problem import Adapter, Problem, simulate
from sysid.robots import adapter as make_adapter
from sysid.robots import adapters

MIN_NOMINAL_ERROR = 3.0
# a drawn value goes at most this far from nominal toward a bound: a catalog range holds the plausible values, and a
# truth on its very bound cannot be told from one beyond it (calibration rejects fits that end on a bound)
MAX_REACH = 0.9
PUSHES = 4  # pushes of a drawn value toward MAX_REACH (60, 70, 80, 90% of the way) before the commands are redrawn
# draws of the commands (the first from the seed's generator, as the value; the others from (seed, 2, k)): how
# visible an effect is depends on what the commands excite, and the generator's job is commands that show it
EXCITATIONS = 3
SYNTHETIC_FORMAT = "skitter synthetic log"  # the metadata record's format: what --overwrite may replace
SECONDS = 10.0  # a synthetic log's length (about 10 s keeps each matrix case to minutes)
RUN_SEED_OFFSET = 1_000_000  # run k (from 0) of several runs: its commands and noise from seed + k x this
# sizes the command line accepts, checked before anything is simulated: a synthetic log is seconds long (SECONDS) and
# is simulated whole, several times over (the drawn effects' pushes, the commands' draws), every physics step's state
# kept; ten minutes of logs in all, or a hundred runs, is far past any recording protocol a robot declares
# (``Adapter.runs``) and still fits in memory
MAX_SECONDS = 600.0  # s, of all the runs together
MAX_RUNS = 100
MAX_SEED = 2**63 - 1  # numpy's seed sequences take any non-negative integer; run k's seed adds k x RUN_SEED_OFFSET


def synthesize(
    robot: str,
    injected: Mapping[str, float | Mapping[str, float] | None],
    seed: int,
    seconds: float = SECONDS,
    show: bool = False,
) -> tuple[Log, dict]:
    """A synthetic log of ``robot`` with effects ``name -> value`` (a number for the first parameter, a dict per
    parameter, or None: drawn). Returns the log and the truth. With ``show``, given values that the first commands
    do not show (error under 3) get the log of up to three draws of the commands that shows them best: a case's
    held-out log, whose commands should show its truth as the training log's do. See :func:`record`."""
    logs, truth = record(robot, injected, seed, seconds, show=show)
    return logs[0], truth


def record(
    robot: str,
    injected: Mapping[str, float | Mapping[str, float] | None],
    seed: int,
    seconds: float = SECONDS,
    runs: int = 1,
    show: bool = False,
) -> tuple[list[Log], dict]:
    """``runs`` synthetic logs of ``seconds`` each, every one from rest (a robot's recording protocol,
    ``Adapter.runs``; one log by default), with effects as :func:`synthesize` takes them. How visible the effects
    are is measured on all the runs together, as calibration will see them, and against two replay floors, the
    smaller error counting (:func:`visibility`): the true model's catalogued part's, the best model a calibration
    can reach, whose floor the held-out evaluation measures against (sysid/pipeline.py), so that an effect the
    right model's own replay floor would swallow is not called visible; and the nominal model's, which calibration
    starts from (an out-of-catalog effect is measured against the nominal model's floor alone: no calibration can
    reach it). Run k's commands and noise come from seed + k x RUN_SEED_OFFSET (run 0's from the seed's generator,
    before the drawn values); redrawn commands are redrawn for every run. Returns the logs and the truth."""
    adapter = make_adapter(robot)
    check_effects(adapter, injected)
    effects = adapter.effects()  # the catalog's and the out-of-catalog ones the generator alone injects
    rng = np.random.default_rng(seed)
    first = adapter.excite(seconds, rng)  # draw 0 (``excitation``): the first numbers of the seed's generator
    seeds = run_seeds(seed, runs)
    commands = [first] + [excitation_commands(adapter, seconds, s, 0) for s in seeds[1:]]
    setting: dict[str, float] = {}
    truth: dict[str, dict[str, float]] = {}
    for name, value in injected.items():
        effect = effects[name]
        values = effect_values(effect, value, rng)
        setting.update({effect.key(k): v for k, v in values.items()})
        truth[name] = values
    drawn = [n for n, v in injected.items() if v is None]
    best: tuple[float, list[Log] | None] = (float("-inf"), None)  # given values: the logs that show them best so far
    first_draw = (dict(setting), {k: dict(v) for k, v in truth.items()})

    def logs_of(setting: Mapping[str, float]) -> list[Log]:
        return [noisy_log(adapter, setting, c, s, robot) for c, s in zip(commands, seeds, strict=True)]

    in_catalog = set(adapter.catalog_nominal())

    def reachable(setting: Mapping[str, float]) -> dict[str, float]:
        """The catalog's part of a setting: the best model a calibration can reach, whose replay floor the held-out
        evaluation measures against (an out-of-catalog effect stays in the residual, above the catalog's floor)."""
        return {k: v for k, v in setting.items() if k in in_catalog}

    for excitation in range(EXCITATIONS):
        if excitation:  # the commands did not show the drawn effects: other commands, from the same seed
            commands = [excitation_commands(adapter, seconds, s, excitation) for s in seeds]
            setting, truth = dict(first_draw[0]), {k: dict(v) for k, v in first_draw[1].items()}
            # commands the nominal model cannot replay on its own data (a legged robot's body diverging) would pass
            # the test on that alone: redrawn commands are kept only if, without the effects, the nominal model's
            # error stays under the threshold
            if nominal_error(adapter, logs_of({})) >= MIN_NOMINAL_ERROR:
                error = float("nan")
                continue
        for attempt in range(PUSHES + 1):
            logs = logs_of(setting)
            error = visibility(adapter, logs, reachable(setting))
            if error >= MIN_NOMINAL_ERROR or not drawn or attempt == PUSHES:
                break
            for name in drawn:  # push the drawn values further from nominal
                effect = effects[name]
                truth[name] = effect_values(effect, None, rng, push=min(MAX_REACH, 0.5 + 0.1 * (attempt + 1)))
                setting.update({effect.key(k): v for k, v in truth[name].items()})
        if not drawn and error > best[0]:
            best = (error, logs)
        if error >= MIN_NOMINAL_ERROR or not injected or (not drawn and not show):
            break
    else:
        if drawn:
            raise NotShown(
                f"{', '.join(drawn)} (seed {seed}): even far from nominal, under {EXCITATIONS} draws of the commands, "
                f"the nominal model's error is {error:.2f} < {MIN_NOMINAL_ERROR} against the true or the nominal "
                "model's replay floor: these channels barely see it"
            )
        error, logs = best  # given values (a case's held-out logs): the commands that showed them best
    return logs, {"robot": robot, "seed": seed, "effects": truth, "nominal_error": error, "setting": setting}


class NotShown(ValueError):
    """Drawn effects that no draw of the commands shows: the nominal model's error on the logs stays under
    :data:`MIN_NOMINAL_ERROR` (how visible an effect is depends on the commands, drawn from the seed)."""


def check_effects(adapter: Adapter, injected: Mapping[str, float | Mapping[str, float] | None]) -> None:
    """``ValueError`` naming the first effect that ``adapter``'s robot does not have, or a given value outside its
    parameter's range: what :func:`record` refuses, checked without simulating anything."""
    effects = adapter.effects()
    rng = np.random.default_rng(0)  # (given values draw nothing)
    for name, value in injected.items():
        if name not in effects:
            raise ValueError(f"robot {adapter.name!r} has no effect {name!r} (see --list)")
        if value is not None:
            effect_values(effects[name], value, rng)


def protocol(adapter: Adapter) -> tuple[int, float]:
    """How a robot's synthetic cases are recorded: (runs, seconds each); one log of SECONDS unless the adapter
    declares runs from rest (``Adapter.runs``)."""
    return adapter.runs or (1, SECONDS)


def run_seeds(seed: int, runs: int) -> list[int]:
    """The seeds of a recording's runs: run k's commands and noise come from seed + k x RUN_SEED_OFFSET."""
    return [seed + RUN_SEED_OFFSET * k for k in range(runs)]


def excitation_commands(adapter: Adapter, seconds: float, seed: int, draw: int) -> pd.DataFrame:
    """The commands of the generator's draw ``draw`` (0 to EXCITATIONS - 1) for ``seed``."""
    return adapter.excite(seconds, np.random.default_rng(seed if draw == 0 else [seed, 2, draw]))


def noisy_log(adapter: Adapter, setting: Mapping[str, float], commands: pd.DataFrame, seed: int, robot: str) -> Log:
    """The model with ``setting`` run under ``commands``, read with the adapter's sensor noise drawn from ``seed``;
    recorded as :func:`recording` says."""
    meta = recording(adapter, setting)
    clean = simulate(adapter, setting, commands, meta)
    return _log(adapter, commands, clean, adapter.synth_noise(), rng_noise(seed), robot, meta)


def recording(adapter: Adapter, setting: Mapping[str, float]) -> dict:
    """What a synthetic log's record holds besides its noise: the adapter's own (``synth_meta``), and what an effect
    of ``setting`` asks of the recording (``Effect.meta["record"]``: the servo rig's load friction and gearbox
    efficiency need load torque to show, and are recorded on a loaded bench, the load declared in the record)."""
    meta = dict(adapter.synth_meta())
    for effect in adapter.effects().values():
        if any(effect.key(p.name) in setting for p in effect.params):
            meta.update(effect.meta.get("record", {}))
    return meta


def rng_noise(seed: int) -> np.random.Generator:
    return np.random.default_rng([seed, 1])


def effect_values(
    effect: Effect, value: float | Mapping[str, float] | None, rng: np.random.Generator, push: float = 0.0
) -> dict[str, float]:
    """Values of an effect's parameters: given (a number for the first parameter, the rest nominal; or a value per
    parameter), else drawn away from nominal: between 35% and 90% of the way from nominal to a bound (the farther
    bound, three times in four), at least ``push`` of the way; a shape parameter (``Param.shape``) anywhere in its
    range."""
    if value is not None:
        given = dict(value) if isinstance(value, Mapping) else {effect.params[0].name: float(value)}
        names = [p.name for p in effect.params]
        for name in given:
            if name not in names:
                raise ValueError(f"{effect.name} has no parameter {name!r} (it has {', '.join(names)})")
        out = {}
        for p in effect.params:
            v = float(given.get(p.name, p.nominal))
            if not p.low <= v <= p.high:
                raise ValueError(f"{effect.name}.{p.name}={v:g}: outside its range [{p.low:g}, {p.high:g}] {p.unit}")
            out[p.name] = v
        return out
    out = {}
    for p in effect.params:
        if p.shape:  # how the effect looks, not how strong it is: anywhere in its range, redrawn with each push
            out[p.name] = float(rng.uniform(p.low, p.high))
            continue
        up, down = p.high - p.nominal, p.nominal - p.low
        direction = 1.0 if (up >= down if rng.random() < 0.75 else up < down) and up > 0 else -1.0
        if (down if direction < 0 else up) <= 0:  # no room that way (nominal on a bound): the other way
            direction = -direction
        reach = up if direction > 0 else down
        fraction = max(push, rng.uniform(0.35, MAX_REACH)) if push else rng.uniform(0.35, MAX_REACH)
        out[p.name] = float(p.nominal + direction * fraction * reach)
    return out


def _log(
    adapter: Adapter, commands: pd.DataFrame, clean: np.ndarray, noise: Mapping[str, float], rng, robot, record: Mapping
) -> Log:
    df = commands.copy()
    for i, c in enumerate(adapter.channels):
        df[c] = adapter.measure(c, clean[:, i] + rng.normal(0.0, noise[c], len(df)))
    meta = {"robot": robot, "format": SYNTHETIC_FORMAT, "noise_sigma": adapter.recorded_noise(noise),
            "units": {"time": "s", **dict(adapter.channels)}, **record}  # fmt: skip
    return Log("synthetic", df, meta)


def visibility(adapter: Adapter, logs: Sequence[Log], reachable: Mapping[str, float]) -> float:
    """How visible a truth is on its logs: the nominal model's error against the replay floor of the true model's
    catalogued part ``reachable`` (how the held-out evaluation will judge a calibrated model) and against the nominal
    model's own floor (how calibration, starting from the nominal model, first sees it), the smaller of the two. An
    effect has to show against both: one visible to the judge only is one the loop cannot find, and one visible to
    the loop only is one no fit can halve."""
    error = nominal_error(adapter, logs)
    if reachable and adapter.replay_floor:  # (without a replay floor, the two are the sensor noise alike)
        error = min(error, nominal_error(adapter, logs, floor_setting=reachable))
    return error


def nominal_error(
    adapter: Adapter, log: Log | Sequence[Log], floor_setting: Mapping[str, float] | None = None
) -> float:
    """The nominal model's error on a log or on several together (nuisance parameters fitted first), against the
    replay floor of the nominal model, or of ``floor_setting`` (the held-out evaluation measures against the
    calibrated model's floor: sysid/pipeline.py)."""
    from sysid.fit import fit

    logs = [log] if isinstance(log, Log) else list(log)
    problem = Problem(adapter, logs, floor_setting=floor_setting)
    setting = adapter.catalog_nominal()
    nuisance = adapter.nuisance(logs)
    if nuisance:
        setting = fit(problem, setting, nuisance).values
    return problem.error(problem.residuals([setting])[0])


def listing() -> str:
    """Every effect the generator can inject, per robot: parameters and ranges, alias group, and whether the
    calibration catalog holds it."""
    lines = [
        "effect | robot | parameters (unit, nominal, range) | alias group | in the catalog | channels see it",
        "---|---|---|---|---|---",
    ]
    for robot in sorted(adapters()):
        for name, e in make_adapter(robot).effects().items():
            params = "; ".join(f"{p.name} ({p.unit}, {p.nominal:g}, [{p.low:g}, {p.high:g}])" for p in e.params)
            seen = "yes" if e.observable else f"barely: {e.weak}"
            lines.append(f"{name} | {robot} | {params} | {e.alias} | {'yes' if e.catalogued else 'no'} | {seen}")
    return "\n".join(lines)


def parse_effect(text: str) -> tuple[str, float | dict[str, float] | None]:
    """``NAME``, ``NAME=VALUE`` (the first parameter) or ``NAME=param:value,param:value``."""
    name, _, value = text.partition("=")
    if not value:
        return name, None
    try:
        if ":" in value:
            return name, {k.strip(): float(v) for k, v in (part.split(":", 1) for part in value.split(","))}
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--effect {text!r}: {value!r} is not a number or param:number,...") from None


def main(argv: Sequence[str] | None = None) -> int:
    parser = ToolParser(prog="python -m sysid.synth", description=__doc__)
    parser.add_argument("--robot", choices=sorted(adapters()))
    parser.add_argument(
        "--effect", action="append", default=[], type=parse_effect, help="NAME, NAME=VALUE or NAME=p:v,p:v"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=SECONDS, help="each run's length")
    parser.add_argument("--runs", type=int, default=1, help="runs from rest, each a log of its own (a robot's "
                        "recording protocol: the xJüs's cases record --runs 6 --seconds 2); the effects are drawn to "
                        "show on all of them together")  # fmt: skip
    parser.add_argument("--out", type=Path, help="the log, FILE.parquet (with --runs K: FILE.run1.parquet ... "
                        "FILE.runK.parquet); the truth goes to FILE.parquet.truth.json")  # fmt: skip
    parser.add_argument("--overwrite", action="store_true", help="replace an earlier log and its truth at --out")
    parser.add_argument("--list", action="store_true", help="list every effect that can be injected")
    args = parser.parse_args(argv)
    if args.list:
        try:
            print(listing(), flush=True)
        except BrokenPipeError:  # the reader stopped early (``--list | head -1``)
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # nor fail again on the exit's flush
            return 1
        return 0
    if args.robot is None or args.out is None:
        parser.error("--robot and --out are required (or --list)")
    names = [name for name, _ in args.effect]
    twice = sorted({name for name in names if names.count(name) > 1})
    if twice:
        parser.error(f"--effect {twice[0]!r} is given twice")
    if not 0 <= args.seed <= MAX_SEED - RUN_SEED_OFFSET * MAX_RUNS:
        parser.error(f"--seed must be in [0, {MAX_SEED - RUN_SEED_OFFSET * MAX_RUNS}] (numpy seeds are "
                     f"non-negative), got {args.seed}")  # fmt: skip
    if not 1 <= args.runs <= MAX_RUNS:
        parser.error(f"--runs must be in [1, {MAX_RUNS}], got {args.runs}")
    adapter = make_adapter(args.robot)
    shortest = adapter.segment_seconds * (2 if adapter.burn_in else 1)  # one segment to replay, after the burn-in
    if not shortest <= args.seconds <= MAX_SECONDS / args.runs:
        parser.error(f"--seconds must be a finite number in [{shortest:g}, {MAX_SECONDS / args.runs:g}] for "
                     f"{args.robot}{f' with --runs {args.runs}' if args.runs > 1 else ''} (at most {MAX_SECONDS:g} s "
                     f"of logs in all), got {args.seconds:g}")  # fmt: skip
    try:  # the effects' names and given values, before the long part (simulating and measuring how they show)
        check_effects(adapter, dict(args.effect))
    except ValueError as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return 2
    out: Path = args.out
    if not out.name:  # '', '.', '/': no file name to give the log (nor its truth beside it)
        parser.error(f"--out {str(out)!r}: give the log's file name, FILE.parquet")
    truth_path = out.with_name(out.name + ".truth.json")
    paths = run_paths(out, args.runs)
    try:
        _check_out(out, [*paths, truth_path], args.overwrite)
        logs, truth = record(args.robot, dict(args.effect), args.seed, args.seconds, args.runs)
    except NotShown as exc:  # a drawn value the commands of this seed do not show: another seed's commands may
        print(f"{parser.prog}: error: {exc}; try another --seed, or give the value (--effect NAME=VALUE)",
              file=sys.stderr)  # fmt: skip
        return 2
    except (ValueError, FileExistsError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)  # as the parser's own errors begin
        return 2
    # the logs and their truth as one unit: all written in full beside them, then renamed into place
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f".{out.name}.", dir=out.parent) as tmp:
        staged = Path(tmp)
        for path, log in zip(paths, logs, strict=True):
            write_telemetry(staged / path.name, log.df, log.meta)
        write_json(staged / truth_path.name, truth)
        os.replace(staged / truth_path.name, truth_path)
        for path in paths:
            os.replace(staged / path.name, path)
    for path, log in zip(paths, logs, strict=True):
        print(f"{path}: {len(log.df)} samples over {log.duration:.1f} s")
    together = f" on the {args.runs} runs together" if args.runs > 1 else ""
    print(f"nominal model's error {truth['nominal_error']:.2f}{together}")
    return 0


def run_paths(out: Path, runs: int) -> list[Path]:
    """Where the logs go: ``out`` itself, or, for several runs, FILE.run1.parquet ... beside it."""
    return [out] if runs == 1 else [out.with_name(f"{out.stem}.run{k + 1}{out.suffix}") for k in range(runs)]


def _check_out(out: Path, paths: Sequence[Path], overwrite: bool) -> None:
    """Refuse (``ValueError``, ``FileExistsError``) an --out the logs and their truth cannot be written to, before
    anything is synthesized."""
    for path in paths:
        if path.is_dir():
            raise ValueError(f"--out {out}: {path} is a directory")
    if out.suffix != ".parquet":
        raise ValueError(f"--out {out}: the log is written as Parquet; give a path ending in .parquet")
    problem = parent_problem(out)
    if problem:
        raise ValueError(f"--out {out}: {problem}")
    existing = [str(path) for path in paths if path.exists()]
    if existing and not overwrite:
        raise FileExistsError(
            f"--out {out}: {_listed(existing)} already exist{'s' * (len(existing) == 1)}; choose another path "
            "or pass --overwrite"
        )
    foreign = [name for name in existing if not _written_by_synth(Path(name))]
    if foreign:  # --overwrite replaces an earlier synthetic log and its truth, never a user's file
        raise FileExistsError(
            f"--out {out}: {_listed(foreign)} {'is' if len(foreign) == 1 else 'are'} not a synthetic log or truth "
            "this tool wrote; --overwrite replaces only those: choose another path"
        )


def _written_by_synth(path: Path) -> bool:
    """Whether ``path`` is a log (its Parquet metadata record says so) or a truth file this tool wrote."""
    try:
        if path.suffix == ".parquet":
            record = (pq.read_schema(path).metadata or {}).get(METADATA_KEY)
            return record is not None and json.loads(record).get("format") == SYNTHETIC_FORMAT
        truth = json.loads(path.read_text(encoding="utf-8"))
        return isinstance(truth, dict) and {"robot", "effects", "setting", "nominal_error"} <= set(truth)
    except (OSError, ValueError, AttributeError, pa.ArrowException):
        return False


def _listed(names: Sequence[str]) -> str:
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


if __name__ == "__main__":
    sys.exit(main())
