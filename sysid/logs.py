"""Logs for calibration: every format read into one table (SI units, our channel names) with a record of its source.

Formats, recognized by their content:

- skitter telemetry (``.parquet``, envs/common/telemetry.py);
- the robots' own formats (:class:`LogFormats`, declared in sysid/adapters and given by ``sysid.robots.read_log``):
  the VelociRoACH's text telemetry (``%`` header lines, or the lab's older double-quoted ones;
  envs/velociroach/roach_csv.py);
- DYNAMIXEL Wizard exports (a ``DYNAMIXEL Graph`` header, then ``Time[ms]`` and the plotted items, e.g.
  ``Present Position`` in counts; ``Goal Position`` is the goal; also without the header, from ``Time[ms],
  Present Position``);
- the RHex-style gearmotor log (``time,pos,speed,power``: ms, encoder clicks, clicks/s, PWM of 255);
- a CSV whose columns are all our channels (:data:`CHANNEL_UNITS`: ``time,duty_FL,...,leg_angle_FL,...``), ``time``
  first, in SI units: read as it is, as a Parquet telemetry export would be;
- any other CSV or JSON with a column map (:class:`ColumnMap`): our channel -> the file's column, its unit and,
  for counts, how many counts make one unit. The map is for files in none of the formats above: one given with
  logs of those formats leaves them to their own readers. A mapped CSV may hold blank lines and ``#`` comments.

Sampling need not be regular: every channel keeps the file's time column. A malformed row (a repeated timestamp
among them) is dropped with a warning naming the file and its line; so is a row whose sample the robot could not
have produced (:func:`drop_impossible`: outside its channel's range, or apart from its neighbours by more than the
channel can move in the time between them, by the robot's ``channel_limits``); the log is refused (``LogError``:
one line naming the file, line and column) for a missing required column, time that does not increase, an unknown
unit or one of the wrong kind for its channel, a log too short, or more than 5% bad rows. Every message
names a row by its line in the file ("line 152"), the number an editor shows; in a Parquet or JSON log, which has
no lines, the number counts its rows (records) from 1.
"""

from __future__ import annotations

import csv
import json
import math
import warnings
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from envs.common.io import DuplicateKey, unique_keys
from envs.common.telemetry import MAX_REPEATED_ROWS, METADATA_KEY, SCHEMA_VERSION, ChannelLimit

MAX_BAD_FRACTION = 0.05
# fewer rows cannot be a log of motion; how long a log must be to replay is the robot's (Adapter.check_length: a
# segment to score, of the robot's segment length or, for a legged robot's short run, of a few strides)
MIN_ROWS = 20
# an impossible jump is judged against the median of the rows this far either side (the sample's own among them):
# up to this many corrupted rows in a row leave that median on good samples
NEIGHBOURS = 2

# unit -> factor to SI (the channel's SI unit is implied by the channel, CHANNEL_UNITS: s, rad, rad/s, V, N m, 1, ...)
UNITS: dict[str, float] = {
    "s": 1.0,
    "ms": 1e-3,
    "us": 1e-6,
    "min": 60.0,
    "rad": 1.0,
    "deg": math.pi / 180,
    "rev": 2 * math.pi,
    "rad/s": 1.0,
    "deg/s": math.pi / 180,
    "rpm": 2 * math.pi / 60,
    "rev/s": 2 * math.pi,
    "V": 1.0,
    "mV": 1e-3,
    "A": 1.0,
    "mA": 1e-3,
    "N m": 1.0,
    "mN m": 1e-3,
    "1": 1.0,
    "%": 0.01,
    "m": 1.0,
    "mm": 1e-3,
    "m/s": 1.0,
    "m/s^2": 1.0,
    "g": 9.81,
    "N": 1.0,
    "W": 1.0,
    "mW": 1e-3,
    "cycle": 1.0,
    "count": 1.0,  # a count channel keeps counts unless the map gives counts_per_unit
}
# unit -> the SI unit it converts to: its kind
UNIT_KINDS: dict[str, str] = {
    **dict.fromkeys(("s", "ms", "us", "min"), "s"),
    **dict.fromkeys(("rad", "deg", "rev"), "rad"),
    **dict.fromkeys(("rad/s", "deg/s", "rpm", "rev/s"), "rad/s"),
    **dict.fromkeys(("V", "mV"), "V"),
    **dict.fromkeys(("A", "mA"), "A"),
    **dict.fromkeys(("N m", "mN m"), "N m"),
    **dict.fromkeys(("1", "%"), "1"),
    **dict.fromkeys(("m", "mm"), "m"),
    "m/s": "m/s",
    **dict.fromkeys(("m/s^2", "g"), "m/s^2"),
    "N": "N",
    **dict.fromkeys(("W", "mW"), "W"),
    "cycle": "cycle",
    "count": "count",
}
KIND_NAMES = {"s": "a time", "rad": "an angle", "rad/s": "an angular speed", "V": "a voltage", "A": "a current",
              "N m": "a torque", "1": "a fraction", "m": "a length", "m/s": "a speed", "m/s^2": "an acceleration",
              "N": "a force", "W": "a power", "cycle": "a phase in cycles", "count": "a count"}  # fmt: skip
# our channels' SI units, as the robots declare them (their telemetry_channels and calibration adapters; tested to
# agree): a channel is one of these names, or one followed by "_<joint, leg or side>" (leg_angle_left, goal_F_L_1)
CHANNEL_UNITS: dict[str, str] = {
    "time": "s",
    "period": "s",
    **dict.fromkeys(("angle", "leg_angle", "leg_angle_cmd", "sweep", "spine"), "rad"),
    **dict.fromkeys(("speed", "leg_speed", "gyro"), "rad/s"),
    **dict.fromkeys(("bemf", "vbatt"), "V"),
    "current": "A",
    "torque": "N m",
    **dict.fromkeys(("duty", "quat"), "1"),
    **dict.fromkeys(("pos", "deflection"), "m"),
    "accel": "m/s^2",
    **dict.fromkeys(("grf", "touch"), "N"),
    **dict.fromkeys(("power", "servo_power"), "W"),
    "clock_phase": "cycle",
    **dict.fromkeys(("goal", "present_position", "load"), "count"),
}


def channel_unit(channel: str) -> str | None:
    """The SI unit of our channel ``channel`` (:data:`CHANNEL_UNITS`, the longest name it is or starts with followed
    by ``_``), or None for a channel skitter does not know."""
    stem = _stem(channel)
    return None if stem is None else CHANNEL_UNITS[stem]


def _stem(channel: str) -> str | None:
    """The longest :data:`CHANNEL_UNITS` name that ``channel`` is or starts with followed by ``_``, or None."""
    for n in range(channel.count("_") + 1):
        stem = channel.rsplit("_", n)[0]
        if stem in CHANNEL_UNITS:
            return stem
    return None


def channel_suffixes(channels: Iterable[str]) -> frozenset[str]:
    """The joints, legs, sides and axes that ``channels`` name after a :data:`CHANNEL_UNITS` name (``FL``, ``left``,
    ``B_L_1``)."""
    suffixes = set()
    for name in channels:
        stem = _stem(name)
        if stem is not None and name != stem:
            suffixes.add(name[len(stem) + 1 :])
    return frozenset(suffixes)


def is_our_channel(name: str, suffixes: Collection[str] = frozenset()) -> bool:
    """Whether ``name`` is a channel of ours exactly: a :data:`CHANNEL_UNITS` name, alone or followed by one of
    ``suffixes``, a joint, leg, side or axis that a robot declares (``leg_angle_FL``, ``sweep_left``; not
    ``angle_deg``)."""
    stem = _stem(name)
    return stem is not None and (name == stem or name[len(stem) + 1 :] in suffixes)


class LogError(ValueError):
    """A log that cannot be used; the message names the file, line and column."""


@dataclass
class Log:
    """One log: a table with a ``time`` column (s, increasing) and channels in SI units, and its record."""

    path: str
    df: pd.DataFrame
    meta: dict[str, Any] = field(default_factory=dict)
    # a window's earlier rows of the same file (``between``): what came before it, for a twin simulated from the
    # file's start (sysid/problem.py: the replay floor of a window that starts mid-run)
    history: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def time(self) -> np.ndarray:
        return self.df["time"].to_numpy()

    @property
    def duration(self) -> float:
        t = self.time
        return float(t[-1] - t[0]) if len(t) else 0.0

    def between(self, start: float, end: float) -> Log:
        """The samples with ``start <= time < end``; the earlier ones become its ``history``. A measured log's
        window keeps the whole file's white-noise estimate per channel (``file_white``): a sensor's noise is the
        file's, and a window where a channel rests (a held speed reading, second differences all zero) cannot show
        it."""
        t = self.time
        before = self.df[t < start]
        history = pd.concat([self.history, before], ignore_index=True) if self.history is not None else before
        meta = dict(self.meta)
        if "noise_sigma" not in meta and "file_white" not in meta:
            numeric = [c for c in self.df.columns if c != "time" and pd.api.types.is_numeric_dtype(self.df[c])]
            meta["file_white"] = {c: white_noise(self.df[c].to_numpy(dtype=float)) for c in numeric}
        return Log(self.path, self.df[(t >= start) & (t < end)].reset_index(drop=True), meta,
                   history.reset_index(drop=True) if len(history) else None)  # fmt: skip


def white_noise(x: np.ndarray) -> float:
    """A robust estimate of white noise on a channel, from its second differences (their median absolute deviation
    as a standard deviation, over the sqrt(6) a second difference multiplies white noise by); 0 where most second
    differences are zero (a resting or held reading)."""
    d2 = np.diff(x, 2)
    return float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6)) if len(d2) else 0.0


@dataclass(frozen=True)
class ColumnMap:
    """How to read a log of unknown format: our channel -> (the file's column, its unit, counts per unit).

    Written as JSON: ``{"time": {"column": "t_ms", "unit": "ms"}, "angle": {"column": "enc", "unit": "rev",
    "counts_per_unit": 3592}}``. A unit must be of the channel's kind (:func:`channel_unit`): an angle in rad, deg
    or rev, a current in A or mA, ...; a map giving ``"A"`` for ``angle`` is refused, naming the file, channel and
    unit. Without a ``unit``, the column is in the channel's SI unit. Channels skitter does not know are not checked.
    """

    columns: Mapping[str, Mapping[str, Any]]

    @classmethod
    def load(cls, path: str | Path) -> ColumnMap:
        path = Path(path)
        try:
            data = json.loads(path.read_text(encoding="utf-8-sig"), object_pairs_hook=unique_keys)
        except DuplicateKey as exc:
            raise LogError(f"{path}: entry {exc.args[0]!r} is given twice (each channel's column once)") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise LogError(f"{path}: not a readable JSON column map ({exc})") from None
        if not isinstance(data, dict) or "time" not in data:
            raise LogError(f"{path}: a column map is a JSON object with at least a 'time' entry")
        for name, entry in data.items():
            unknown = sorted(set(entry) - {"column", "unit", "counts_per_unit"}) if isinstance(entry, dict) else []
            if unknown:
                raise LogError(f"{path}: entry {name!r}: unknown key {unknown[0]!r} (known: column, unit, "
                               "counts_per_unit)")  # fmt: skip
            if not isinstance(entry, dict) or "column" not in entry:
                raise LogError(f"{path}: entry {name!r} needs a 'column' (and a 'unit')")
            si = channel_unit(name)
            unit = entry.get("unit", si or "1")  # none given: the column is in the channel's SI unit already
            if not isinstance(unit, str) or unit not in UNITS:
                raise LogError(f"{path}: entry {name!r}: unknown unit {unit!r} (known: {', '.join(UNITS)})")
            if si is not None and UNIT_KINDS[unit] != si:
                fitting = ", ".join(u for u, kind in UNIT_KINDS.items() if kind == si)
                hint = " with counts_per_unit for a column of counts" if unit == "count" else ""
                raise LogError(
                    f"{path}: entry {name!r}: unit {unit!r} is {KIND_NAMES[UNIT_KINDS[unit]]}, but channel {name!r} "
                    f"is {KIND_NAMES[si]} ({si}); give one of {fitting}{hint}"
                )
            if not isinstance(entry["column"], str):
                raise LogError(f"{path}: entry {name!r}: 'column' {entry['column']!r} is not a column name")
            counts = entry.get("counts_per_unit", 1.0)
            if (
                isinstance(counts, bool)
                or not isinstance(counts, int | float)
                or not math.isfinite(counts)
                or counts <= 0
            ):
                raise LogError(f"{path}: entry {name!r}: 'counts_per_unit' {counts!r} is not a positive number")
            data[name] = {"column": entry["column"], "unit": unit, "counts_per_unit": float(counts)}  # defaults filled
        return cls(data)


def read_log(
    path: str | Path,
    required: Sequence[str],
    column_map: ColumnMap | None,
    formats: LogFormats,
    limits: Mapping[str, ChannelLimit] | None = None,
) -> Log:
    """Read one log in any known format (the shared ones and ``formats``, the robots'; or, if it is in none, with
    ``column_map``), check it, and drop malformed rows with a warning: among them, with ``limits`` (the robot's
    ``channel_limits``), rows whose required channel reads what the robot could not have produced
    (:func:`drop_impossible`). ``sysid.robots.read_log`` calls it with every robot's formats."""
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: {'a directory, not a log file' if path.is_dir() else 'no such file'}")
    native = _native_reader(path, formats)
    if native is not None:
        log = native(path)
        if column_map is not None:  # a map meant for another file, or for this one by a user who thinks it is used
            warnings.warn(f"{path}: read as {log.meta.get('format', 'a format skitter knows')}; the column map "
                          "(--columns) is not used for it", stacklevel=2)  # fmt: skip
    elif column_map is not None:
        log = _read_mapped(path, column_map, required)
    else:
        head = _head(path)
        lacking = _lacking_columns(head)
        if lacking:
            raise LogError(f"{path}: line 1 {lacking}")
        raise LogError(
            f"{path}: unknown log format (first line {head[:60]!r}{_not_ours(head, formats.suffixes)}); give a column "
            "map (--columns), or name the columns by skitter's channels (time first, SI units)"
        )
    return check_log(log, required, limits)


GEARMOTOR_COLUMNS = ("time", "pos", "speed", "power")
# formats known by their first line, the names of their columns: a first line that names some of them, first column
# first, is such a log lacking a column (named in the error), not an unknown format
COLUMNS_LINES: dict[str, tuple[str, ...]] = {"gearmotor CSV": GEARMOTOR_COLUMNS}


def _lacking_columns(head: str) -> str | None:
    """What a first line that is a known format's columns line with some missing lacks (the gearmotor CSV's
    ``time,pos,speed,power`` without its power, say), or None."""
    names = [n.strip().lower() for n in head.split(",")]
    for fmt, columns in COLUMNS_LINES.items():
        if len(names) >= 2 and names[0] == columns[0] and set(names) < set(columns):
            missing = [c for c in columns if c not in names]
            return (f"names the {fmt}'s columns {', '.join(names)} but lacks column {missing[0]!r} (the format is "
                    f"{','.join(columns)})")  # fmt: skip
    return None


def _native_reader(path: Path, formats: LogFormats) -> Callable[[Path], Log] | None:
    """The reader of a format skitter knows, recognized by the file's content (a column map is for the others)."""
    if path.suffix == ".parquet":
        return _read_parquet
    head = _head(path)
    if head.startswith("DYNAMIXEL") or head.replace(" ", "").lower().startswith("time[ms],present"):
        return _read_dynamixel
    for reader in formats.readers:
        if reader.matches(head):
            return reader.read
    if head.replace(" ", "").lower().startswith(",".join(GEARMOTOR_COLUMNS)):
        return _read_gearmotor
    if path.suffix.lower() != ".json" and not _lacking_columns(head) and _our_channels(head, formats.suffixes):
        return _read_skitter_csv
    return None


def _not_ours(head: str, suffixes: Collection[str]) -> str:
    """For a first line that begins with ``time``: which of its names keeps it from being read by our channels."""
    names = [n.strip() for n in head.split(",")]
    if names[0] != "time":
        return ""
    seen: set[str] = set()
    for name in names[1:]:
        if name in seen:
            return f": column {name!r} appears twice"
        if name and not is_our_channel(name, suffixes):
            return f": {name!r} is not one of skitter's channels"
        seen.add(name)
    return ""


def _our_channels(head: str, suffixes: Collection[str]) -> bool:
    """Whether a CSV's first line names only our channels (:data:`CHANNEL_UNITS`), ``time`` first, each once."""
    names = [n.strip() for n in head.split(",")]
    names = names[:-1] if len(names) > 2 and names[-1] == "" else names  # a trailing comma
    return (
        len(names) >= 2
        and names[0] == "time"
        and len(set(names)) == len(names)
        and all(is_our_channel(name, suffixes) for name in names)
    )


@dataclass(frozen=True)
class LogReader:
    """A robot's own log format, declared beside its adapter (``LOG_READERS`` in sysid/adapters): whether
    a file's first non-empty line is its, and how to read it (raising :class:`LogError`; malformed rows through
    :func:`drop_bad_rows`)."""

    name: str
    matches: Callable[[str], bool]
    read: Callable[[Path], Log]


@dataclass(frozen=True)
class LogFormats:
    """What the robots add to the shared formats (``sysid.robots.formats``): their own readers, and the joints,
    legs, sides and axes their channels name (what may follow a channel's name in a CSV read without a column
    map)."""

    readers: tuple[LogReader, ...] = ()
    suffixes: frozenset[str] = frozenset()


def check_log(log: Log, required: Sequence[str], limits: Mapping[str, ChannelLimit] | None = None) -> Log:
    """Required columns present, time increasing, long enough; a row whose time or required value is not a finite
    number (NaN, inf, in any reader's format) is malformed: dropped with a warning, as every reader drops a row it
    cannot parse (more than 5% such rows refuse the log); so is a row whose required value the robot could not have
    produced, by ``limits`` (:func:`drop_impossible`)."""
    missing = [c for c in ("time", *required) if c not in log.df.columns]
    if missing:
        raise LogError(
            f"{log.path}: column {missing[0]!r} is missing (needed: {', '.join(required)}; "
            f"the file has: {', '.join(map(str, log.df.columns))})"
        )
    for column in ("time", *required):
        values = log.df[column]
        if not (pd.api.types.is_numeric_dtype(values) or pd.api.types.is_bool_dtype(values)):
            raise LogError(f"{log.path}: column {column!r} holds text, not numbers (row 1: "
                           f"{values.iloc[0] if len(values) else ''!r})")  # fmt: skip
    rows = len(log.df)
    log = _drop_non_finite(log, ("time", *required))
    log = _drop_time_glitches(log)
    t = log.time
    backwards = np.flatnonzero(np.diff(t) <= 0)
    if len(backwards):
        row = int(backwards[0]) + 1
        where = f"{log.path}: row at line {_row_label(log, row)}, column 'time': {t[row]:.6g} s"
        if t[row] == t[row - 1]:
            raise LogError(f"{where}, the same as the row at line {_row_label(log, row - 1)}: a repeated timestamp")
        raise LogError(f"{where} does not increase (previous {t[row - 1]:.6g} s): time runs backwards")
    if limits:
        log = drop_impossible(log, {c: limits[c] for c in required if c in limits})
        t = log.time
    dropped = rows - len(t)
    if dropped > MAX_BAD_FRACTION * rows:  # each kind of bad row is within bounds, but not all of them together
        raise LogError(f"{log.path}: {dropped} of {rows} rows are malformed (more than {MAX_BAD_FRACTION:.0%}), "
                       "counting every kind dropped above")  # fmt: skip
    if len(t) < MIN_ROWS or not log.duration > 0:
        raise LogError(f"{log.path}: too short: {len(t)} row{'' if len(t) == 1 else 's'} over {log.duration:.3g} s "
                       f"(at least {MIN_ROWS} rows)")  # fmt: skip
    return log


def _drop_non_finite(log: Log, columns: Sequence[str]) -> Log:
    """The log without its rows whose ``columns`` are not all finite numbers (each warned of, naming its line and
    column; refused above 5%)."""
    values = log.df[list(columns)].to_numpy(dtype=float)
    finite = np.isfinite(values)
    bad = np.flatnonzero(~finite.all(axis=1))
    if not len(bad):
        return log
    first = np.argmin(finite, axis=1)  # each row's first column that is not finite
    unparsed = log.meta.get("unparsed", {})  # column -> {file line: the text that is not a number, as the file has it}
    lines = []
    for k in bad:
        line, column = int(_row_label(log, int(k))), columns[first[k]]
        text = unparsed.get(column, {}).get(str(line))
        shown = repr(text) if text is not None else str(float(values[k, first[k]]))
        lines.append((line, f"column {column!r}: {shown} is not a finite number"))
    drop_bad_rows(Path(log.path), lines, len(values))
    return _keep_rows(log, np.flatnonzero(finite.all(axis=1)))


def drop_impossible(log: Log, limits: Mapping[str, ChannelLimit]) -> Log:
    """The log without its rows whose value in a channel of ``limits`` the robot could not have produced (each
    warned of, naming its line, column, value and the limit; refused above 5%, as malformed rows are):

    - outside the channel's range (``low``, ``high``);
    - farther from the median of its neighbourhood (the rows :data:`NEIGHBOURS` either side, its own among them)
      than the channel can move over that neighbourhood's time span at ``max_rate``, plus the reading's own
      resolution (the reader's quantisation) and eight times its white noise (:func:`white_noise`): a corrupted
      field (an angle of 1e3 rad among readings near 1), not a fast motion, which moves the whole neighbourhood.

    The limits come from the robot's hardware (``Robot.channel_limits``: its actuators' constants); a channel
    without one, or a value that is not finite (:func:`check_log` drops those), is not judged here."""
    t = log.time
    n = len(t)
    reasons: dict[int, str] = {}
    lo = np.clip(np.arange(n) - NEIGHBOURS, 0, n - 1)
    hi = np.clip(np.arange(n) + NEIGHBOURS, 0, n - 1)
    span = t[hi] - t[lo] if n else t
    for column, limit in limits.items():
        if column not in log.df.columns:
            continue
        x = log.df[column].to_numpy(dtype=float)
        finite = np.isfinite(x)
        outside = finite & ((x < limit.low) | (x > limit.high))
        for k in np.flatnonzero(outside):
            reasons.setdefault(
                int(k),
                f"column {column!r}: {x[k]:.6g} is outside what the channel can read, [{limit.low:g}, {limit.high:g}] "
                f"({limit.source})",
            )
        if not math.isfinite(limit.max_rate) or n < 3:
            continue
        good = np.where(finite & ~outside, x, np.nan)
        middle = pd.Series(good).rolling(2 * NEIGHBOURS + 1, center=True, min_periods=1).median().to_numpy()
        quantum = float((log.meta.get("quantisation") or {}).get(column, 0.0))
        slack = limit.max_rate * span + quantum + 8.0 * white_noise(good[np.isfinite(good)])
        jumps = np.isfinite(good) & (np.abs(good - middle) > slack)
        for k in np.flatnonzero(jumps):
            reasons.setdefault(
                int(k),
                f"column {column!r}: {x[k]:.6g} is {abs(x[k] - middle[k]):.3g} from its neighbours' median "
                f"{middle[k]:.6g}, more than the channel can move in {span[k]:.3g} s at {limit.max_rate:.3g} per s "
                f"({limit.source})",
            )
    if not reasons:
        return log
    bad = sorted(reasons)
    lines = [(int(_row_label(log, k)), f"a sample the robot could not produce: {reasons[k]}") for k in bad]
    drop_bad_rows(Path(log.path), lines, n)
    return _keep_rows(log, np.setdiff1d(np.arange(n), bad))


def _keep_rows(log: Log, keep: np.ndarray) -> Log:
    """The log's rows ``keep`` (indices), their file line numbers with them."""
    meta = dict(log.meta)
    if meta.get("file_rows") is not None:
        meta["file_rows"] = [meta["file_rows"][k] for k in keep]
    return Log(log.path, log.df.iloc[keep].reset_index(drop=True), meta, log.history)


def _drop_time_glitches(log: Log) -> Log:
    """Drop as malformed rows, with a warning: single rows whose time is out of order with both neighbours (a
    corrupted field, as in the AX-12A file's ``71`` between 4239 and 4288 ms), and a short stretch that goes back in
    time and rejoins the log within :data:`MAX_REPEATED_ROWS` rows (an exporter that sent a few samples again after
    a broken row, as DYNAMIXEL Wizard exports do: ``2496, 5, 2480, 2496, 2512`` ms). A log whose time itself goes
    back (the rows after a point stay earlier than the rows before it) is left for the caller to refuse."""
    t = log.time
    bad: list[int] = []
    reasons: dict[int, str] = {}
    i, last = 1, 0  # the row under test, the last row kept
    while i < len(t):
        if t[i] > t[last]:
            last, i = i, i + 1
            continue
        rejoin = next((j for j in range(i + 1, min(i + 1 + MAX_REPEATED_ROWS, len(t))) if t[j] > t[last]), None)
        if rejoin != i + 1 and last == i - 1 and i >= 2 and i + 1 < len(t) and t[i - 2] < t[i] < t[i + 1]:
            bad.append(i - 1)  # not row i but row i-1 is the odd one: it jumped ahead
            reasons[i - 1] = f"time {t[i - 1]:.6g} s out of order with its neighbours"
            last, i = i, i + 1
            continue
        if rejoin is None:
            if i + 1 < len(t):
                break  # the log's time itself runs backwards
            rejoin = len(t)  # the last row is the odd one
        for k in range(i, rejoin):
            bad.append(k)
            if t[k] == t[last]:
                reasons[k] = (
                    f"time {t[k]:.6g} s, the same as the row at line {_row_label(log, last)} (a repeated timestamp)"
                )
            elif rejoin == i + 1:
                reasons[k] = f"time {t[k]:.6g} s out of order with its neighbours"
            else:
                reasons[k] = f"time {t[k]:.6g} s goes back from {t[last]:.6g} s (a repeated or broken sample)"
        last, i = rejoin, rejoin + 1
    if not bad:
        return log
    lines = [(int(_row_label(log, k)), reasons[k]) for k in bad]
    drop_bad_rows(Path(log.path), lines, len(t))
    return _keep_rows(log, np.setdiff1d(np.arange(len(t)), bad))


def _row_label(log: Log, index: int) -> str:
    rows = log.meta.get("file_rows")
    return str(rows[index]) if rows is not None and index < len(rows) else str(index + 1)


def _head(path: Path) -> str:
    with path.open("rb") as fh:
        for raw in fh:
            line = raw.decode("utf-8-sig", errors="replace").strip()
            if line:
                return line
    raise LogError(f"{path}: empty file")


def drop_bad_rows(path: Path, bad: list[tuple[int, str]], total: int) -> None:
    """Warn about dropped rows; refuse the log if more than 5% were bad."""
    if not bad:
        return
    if len(bad) > MAX_BAD_FRACTION * total:
        line, reason = bad[0]
        raise LogError(
            f"{path}: {len(bad)} of {total} rows are malformed (more than {MAX_BAD_FRACTION:.0%}); "
            f"the first, at line {line}: {reason}"
        )
    for line, reason in bad:
        warnings.warn(f"{path}: dropped malformed row at line {line}: {reason}", stacklevel=3)


# --- the formats ----------------------------------------------------------------------------------------------------
def _read_parquet(path: Path) -> Log:
    from envs.common.telemetry import read_telemetry

    try:
        df, meta = read_telemetry(path)
    except ValueError as exc:
        raise LogError(str(exc)) from None
    _check_parquet_meta(path, meta)
    df, unparsed = _numeric_columns(df)
    if unparsed:
        meta = {**meta, "unparsed": unparsed}
    if "episode" in df.columns and df["episode"].nunique() > 1:
        first = int(df["episode"].iloc[0])
        warnings.warn(f"{path}: holds {df['episode'].nunique()} episodes; using episode {first}", stacklevel=3)
        df = df[df["episode"] == first].reset_index(drop=True)
    return Log(str(path), df, {**meta, "format": "skitter telemetry"})


# the fields of a telemetry file's record that the calibration reads, each a channel -> number map, and whether
# 0 is a value it may hold (a noise level of 0 would divide an error by nothing)
_PER_CHANNEL_FIELDS = {"noise_sigma": False, "quantisation": True, "file_white": True}


def _check_parquet_meta(path: Path, meta: Mapping[str, Any]) -> None:
    """The fields of a telemetry file's record that the calibration uses, checked: its schema, the units of the
    channels it names (skitter's SI units, as it writes them) and the per-channel numbers."""
    where = f"{path}: metadata '{METADATA_KEY.decode()}'"
    version = meta.get("schema_version", SCHEMA_VERSION)
    if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= SCHEMA_VERSION:
        raise LogError(f"{where} field 'schema_version' = {version!r}: this skitter reads telemetry of schema "
                       f"1 to {SCHEMA_VERSION}")  # fmt: skip
    units = meta.get("units", {})
    if not isinstance(units, Mapping):
        raise LogError(f"{where} field 'units' = {units!r}: expected a channel -> unit object")
    for channel, unit in units.items():
        si = channel_unit(str(channel))
        if si is not None and unit != si:
            raise LogError(f"{where} field 'units.{channel}' = {unit!r}: skitter telemetry holds {channel!r} in "
                           f"{si!r}")  # fmt: skip
    for name, zero_allowed in _PER_CHANNEL_FIELDS.items():
        values = meta.get(name)
        if values is None:
            continue
        if not isinstance(values, Mapping):
            raise LogError(f"{where} field {name!r} = {values!r}: expected a channel -> number object")
        for channel, value in values.items():
            number = value if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
            if not (math.isfinite(number) and (number > 0 or (zero_allowed and number == 0))):
                need = "a finite number, 0 or more" if zero_allowed else "a positive finite number"
                raise LogError(f"{where} field '{name}.{channel}' = {value!r}: must be {need}")


def _numeric_columns(df: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, dict[str, str]]]:
    """A telemetry table whose columns of text (an exporter's numbers written as strings, an "N/A") are numbers:
    each cell that does not parse is NaN, and kept as the file has it (column -> {row: text}) for the warning that
    drops its row. A column none of whose cells parse is left as text; refused if a channel needs it."""
    unparsed: dict[str, dict[str, str]] = {}
    for column in df.columns:
        if pd.api.types.is_numeric_dtype(df[column]) or pd.api.types.is_bool_dtype(df[column]):
            continue
        numbers = pd.to_numeric(df[column], errors="coerce")
        failed = np.flatnonzero((numbers.isna() & df[column].notna()).to_numpy())
        if len(failed) == len(df):
            continue
        texts = df[column].to_numpy()
        unparsed[str(column)] = {str(i + 1): str(texts[i]) for i in failed}
        df = df.assign(**{column: numbers.astype(float)})
    return df, unparsed


# a plotted item's column -> our channel, where the adapters expect another name than the item's own
DYNAMIXEL_ITEMS = {"goal_position": "goal"}


def _fields(line: str, expected: int) -> list[str]:
    """A CSV line's fields, stripped; one trailing empty field (a trailing comma) is not a field."""
    return _without_trailing_comma([f.strip() for f in line.split(",")], expected)


def _without_trailing_comma(fields: list[str], expected: int) -> list[str]:
    return fields[:-1] if len(fields) == expected + 1 and fields[-1] == "" else fields


def _read_dynamixel(path: Path) -> Log:
    """A DYNAMIXEL Wizard graph export: header lines until one starting ``Time``, then ``time, item, ...`` rows."""
    lines = path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    header_at = next((i for i, line in enumerate(lines) if line.strip().lower().startswith("time")), None)
    if header_at is None:
        raise LogError(f"{path}: a DYNAMIXEL export without a 'Time[ms], ...' column line")
    names = [c.strip() for c in lines[header_at].split(",")]
    time_unit = "ms" if "[ms]" in names[0].lower() else "s"
    rows, file_rows, bad = [], [], []
    for number, line in enumerate(lines[header_at + 1 :], start=header_at + 2):
        if not line.strip():
            continue
        fields = _fields(line, len(names))
        try:
            if len(fields) != len(names):
                raise ValueError(f"{len(fields)} fields, expected {len(names)}")
            if empty := [names[k] for k, f in enumerate(fields) if f == ""]:
                raise ValueError(f"field {empty[0]!r} is empty")
            rows.append([float(f) for f in fields])
            file_rows.append(number)
        except ValueError as exc:
            bad.append((number, f"{line.strip()!r} ({exc})"))
    drop_bad_rows(path, bad, len(rows) + len(bad))
    data = np.asarray(rows, dtype=float).reshape(-1, len(names))
    df = pd.DataFrame({"time": data[:, 0] * UNITS[time_unit]})
    for i, name in enumerate(names[1:], start=1):
        key = name.lower().replace(" ", "_")
        key = DYNAMIXEL_ITEMS.get(key, key)
        df[key] = data[:, i]  # counts, as the servo reports them
    model = lines[1].split(",")[0].strip() if header_at > 1 and lines[0].startswith("DYNAMIXEL") else None
    meta = {"format": "DYNAMIXEL Wizard export", "model": model,
            "columns": names, "file_rows": file_rows, "units": {"present_position": "count"}}  # fmt: skip
    return Log(str(path), df, meta)


GEARMOTOR_CLICKS_PER_REV = 3592  # shared/data/real/README.md


def _read_gearmotor(path: Path) -> Log:
    """``time`` ms, ``pos`` encoder clicks (3592 per output revolution), ``speed`` clicks/s, ``power`` PWM of 255."""
    lines = path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    rows, file_rows, bad = [], [], []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = _fields(line, 4)
        try:
            if len(fields) != 4:
                raise ValueError(f"{len(fields)} fields, expected 4")
            rows.append([float(f) for f in fields])
            file_rows.append(number)
        except ValueError as exc:
            bad.append((number, f"{line.strip()!r} ({exc})"))
    drop_bad_rows(path, bad, len(rows) + len(bad))
    data = np.asarray(rows, dtype=float).reshape(-1, 4)
    per_click = 2 * math.pi / GEARMOTOR_CLICKS_PER_REV
    df = pd.DataFrame(
        {
            "time": data[:, 0] * 1e-3,
            "angle": data[:, 1] * per_click,
            "speed": data[:, 2] * per_click,
            "duty": data[:, 3] / 255.0,
        }
    )
    meta = {"format": "gearmotor CSV (time ms, pos clicks, speed clicks/s, power PWM/255)", "file_rows": file_rows,
            "quantisation": {"angle": per_click, "speed": per_click, "duty": 1 / 255.0}}  # fmt: skip
    return Log(str(path), df, meta)


def _read_skitter_csv(path: Path) -> Log:
    """A CSV whose columns are all our channels, ``time`` first, in their SI units (as skitter's telemetry has them):
    read as it is. A field that is not a number is NaN, as a blank is in a Parquet log; :func:`check_log` drops a row
    whose time or required channel is not finite, naming that column."""
    names, rows, bad = _csv_rows(path)
    drop_bad_rows(path, bad, len(rows) + len(bad))
    unparsed: dict[str, dict[str, str]] = {}
    data = np.asarray([[_number_or_nan(f, unparsed, number, name) for f, name in zip(fields, names, strict=True)]
                       for number, fields in rows], dtype=float)  # fmt: skip
    df = pd.DataFrame(data.reshape(-1, len(names)), columns=names)
    meta = {"format": "skitter CSV (our channel names, SI units)", "file_rows": [number for number, _ in rows],
            "unparsed": unparsed}  # fmt: skip
    return Log(str(path), df, meta)


def _read_mapped(path: Path, column_map: ColumnMap, required: Sequence[str] = ()) -> Log:
    """A CSV or JSON log through a column map. A row whose time or required channel is not a finite number is
    malformed; another mapped channel that is not a number is NaN there (as a blank in a Parquet log)."""
    names, rows, bad = _json_rows(path) if path.suffix.lower() == ".json" else _csv_rows(path)
    columns: dict[str, int] = {}
    for name, entry in column_map.columns.items():
        column = entry["column"]
        if column not in names:
            raise LogError(
                f"{path}: the column map's column {column!r} (for {name!r}) is missing; the file has {names}"
            )
        columns[name] = names.index(column)
    total = len(rows) + len(bad)
    values, file_rows = [], []
    strict = {"time", *required}
    for number, fields in rows:
        try:
            values.append(
                [_number(fields[k], names[k]) if name in strict else _number_or_nan(fields[k])
                 for name, k in columns.items()]
            )  # fmt: skip
            file_rows.append(number)
        except ValueError as exc:
            bad.append((number, str(exc)))
    drop_bad_rows(path, sorted(bad), total)
    data = np.asarray(values, dtype=float).reshape(-1, len(columns))
    scales = [UNITS[e["unit"]] / e["counts_per_unit"] for e in column_map.columns.values()]  # as load filled them
    df = pd.DataFrame(data * np.asarray(scales), columns=list(columns))
    meta = {"format": "mapped " + path.suffix.lstrip("."), "column_map": dict(column_map.columns),
            "file_rows": file_rows}  # fmt: skip
    return Log(str(path), df, meta)


def _number_or_nan(value: Any, unparsed: dict | None = None, line: int = 0, column: str = "") -> float:
    """``value`` as a number, else NaN (its text kept in ``unparsed[column][str(line)]``, string keys so that the log's
    meta stays JSON, for the warning that drops its row)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        if unparsed is not None:
            unparsed.setdefault(column, {})[str(line)] = value
        return math.nan


def _number(value: Any, column: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number):
        raise ValueError(f"column {column!r}: {value!r} is not a finite number")
    return number


def _csv_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]], list[tuple[int, str]]]:
    """A CSV's column names (its first line that is not blank or a comment), its data rows with their line numbers
    in the file, and its malformed rows (a field too many or too few); blank lines and ``#`` comments are skipped."""
    try:
        with path.open(newline="", encoding="utf-8-sig", errors="replace") as fh:
            reader = csv.reader((line.partition("#")[0] for line in fh), skipinitialspace=True)
            lines = [
                (reader.line_num, [f.strip() for f in row]) for row in reader if len(row) > 1 or "".join(row).strip()
            ]
    except (OSError, csv.Error) as exc:
        raise LogError(f"{path}: not readable as CSV ({exc})") from None
    if not lines:
        raise LogError(f"{path}: no column line (a CSV read with a column map starts with its column names)")
    names = lines[0][1]
    rows, bad = [], []
    for number, row in lines[1:]:
        fields = _without_trailing_comma(row, len(names))
        if len(fields) == len(names):
            rows.append((number, fields))
        else:
            bad.append((number, f"{len(fields)} fields, expected {len(names)}"))
    return names, rows, bad


def _json_rows(path: Path) -> tuple[list[Any], list[tuple[int, list[Any]]], list[tuple[int, str]]]:
    """A JSON table's column names and its records, numbered from 1 (no record is malformed as a whole)."""
    try:
        raw = pd.read_json(path, encoding="utf-8-sig")
    except (ValueError, OSError) as exc:
        raise LogError(f"{path}: not readable as JSON ({exc})") from None
    return list(raw.columns), [(i + 1, list(row)) for i, row in enumerate(raw.itertuples(index=False))], []
