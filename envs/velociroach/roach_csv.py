"""The real VelociRoACH's telemetry text format (ImageProc 2.5 board, the lab's ``Experiment.py``), read and written.

A file holds ``%`` header lines (date, stride frequency, lead in/out, deltas, phase, motor gains, ``% Columns:`` and a
line naming the columns separated by ``|``), then one comma-separated row of integers per sample::

    %  Data file recorded 2015/2/28  16:7:3
    %  Stride Frequency         = [2, 2]
    ...
    % Columns:
    % time | Right Leg Pos | Left Leg Pos | Commanded Right Leg Pos | ... | RBEMF | LBEMF | VBatt
    1002,2965052,4377936,2967408,4376432,3800,-616,105,-104,-21,-100,100,3951,8,7,831

:func:`read_roach_csv` turns such a file into our telemetry table (SI units, our column names, see docs/telemetry.md)
and a metadata record; :func:`write_roach_csv` writes a table in our schema back to the real format. The two formats
share the columns of :data:`REAL_COLUMNS`; what each lacks, and the assumptions of the conversion (duty full scale
3900 counts, the board's axes equal to ours, g = 9.81 m/s^2), are in docs/telemetry.md.
"""

from __future__ import annotations

import datetime
import json
import math
import re
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from envs.common.io import atomic_write, refuse_overwrite
from envs.common.telemetry import MAX_REPEATED_ROWS, SCHEMA_VERSION
from envs.velociroach.robot import TELEMETRY_COLUMNS

# --- units of the real format (the lab's scaling script; docs/telemetry.md) ------------------------------------
COUNTS_PER_REV = 65536  # leg position counts per leg revolution (cumulative)
DUTY_FULL_SCALE = 3900  # PWM duty counts at 100 % (the README says "about 3900"; we take 3900)
GYRO_LSB_PER_DPS = 16.384  # MPU6000 at +-2000 deg/s
ACCEL_LSB_PER_G = 4096.0  # MPU6000 at +-8 g
STANDARD_GRAVITY = 9.81  # m/s^2 per g
BEMF_VOLTS_PER_LSB = 3.3 / 1024 / (15 / 47)
VBATT_VOLTS_PER_LSB = (3.7 / 2.7) * 3.3 / 1023
TIME_SECONDS_PER_LSB = 1e-6  # the time column is in microseconds

_LEG = 2.0 * math.pi / COUNTS_PER_REV
_GYRO = math.pi / 180.0 / GYRO_LSB_PER_DPS
_ACCEL = STANDARD_GRAVITY / ACCEL_LSB_PER_G


@dataclass(frozen=True)
class RealColumn:
    """One column of the real format: its label, our column, SI units per count, and other spellings of the label."""

    label: str
    name: str
    scale: float
    aliases: tuple[str, ...] = ()


# The firmware writes these 16 columns in this order; files may add more after them (e.g. shell sensors S1..S8).
# Labels are spelled as the lab's Experiment.py writes them ("GryoY", "GryoZ"); files also spell them "GyroY", "GyroZ".
REAL_COLUMNS: tuple[RealColumn, ...] = (
    RealColumn("time", "time", TIME_SECONDS_PER_LSB),
    RealColumn("Right Leg Pos", "leg_angle_right", _LEG),
    RealColumn("Left Leg Pos", "leg_angle_left", _LEG),
    RealColumn("Commanded Right Leg Pos", "leg_angle_cmd_right", _LEG),
    RealColumn("Commanded Left Leg Pos", "leg_angle_cmd_left", _LEG),
    RealColumn("DCR", "duty_right", 1.0 / DUTY_FULL_SCALE),
    RealColumn("DCL", "duty_left", 1.0 / DUTY_FULL_SCALE),
    RealColumn("GyroX", "gyro_x", _GYRO, ("GryoX",)),
    RealColumn("GryoY", "gyro_y", _GYRO, ("GyroY",)),
    RealColumn("GryoZ", "gyro_z", _GYRO, ("GyroZ",)),
    RealColumn("AX", "accel_x", _ACCEL),
    RealColumn("AY", "accel_y", _ACCEL),
    RealColumn("AZ", "accel_z", _ACCEL),
    RealColumn("RBEMF", "bemf_right", BEMF_VOLTS_PER_LSB),
    RealColumn("LBEMF", "bemf_left", BEMF_VOLTS_PER_LSB),
    RealColumn("VBatt", "vbatt", VBATT_VOLTS_PER_LSB),
)
SHARED_COLUMNS: tuple[str, ...] = tuple(c.name for c in REAL_COLUMNS)  # our names of the columns both formats hold
QUANTISATION: dict[str, float] = {c.name: c.scale for c in REAL_COLUMNS}  # SI value of one count, per our column
EXTRA_COLUMN_UNIT = "count"  # unit recorded for columns kept raw (S1..S8: uncalibrated shell-sensor ADC counts)
# header lines this module writes itself: what it wrote as 0, and where the data came from (JSON)
ZERO_FILLED_KEY = "Not in the source (written as 0)"
PROVENANCE_KEY = "Written by skitter (envs/velociroach/roach_csv.py):"
_PROVENANCE_FIELDS = ("robot", "source", "model_hash", "controller", "rate_hz")

_KEY_VALUE = re.compile(r"^(?P<key>[^=]*?)\s*=\s*(?P<value>.*?)\s*$")
_DATE = re.compile(r"^data file recorded\s+(?P<date>.*?)\s*$", re.IGNORECASE)
_DATE_FIELDS = re.compile(r"^(\d{4})/(\d{1,2})/(\d{1,2})\s+(\d{1,2}):(\d{1,2}):(\d{1,2})$")
_INT = re.compile(r"^[+-]?\d+$")


def _norm(label: str) -> str:
    return " ".join(label.split()).casefold()


def _expected_labels(column: RealColumn) -> set[str]:
    return {_norm(column.label), *(_norm(a) for a in column.aliases)}


# --- reading ----------------------------------------------------------------------------------------------------
def read_roach_csv(path: str | Path, skip_bad_rows: bool = False) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a VelociRoACH telemetry text file: (table in our schema and SI units, metadata record).

    Rows are kept as they are: samples the radio download lost are simply absent (no resampling, no filling), and
    ``time`` comes from the file's time column. Columns after the 16 standard ones (e.g. the shell sensors S1..S8)
    are kept raw, as integers, under their own names.

    Header lines start with ``%``, or (the lab's older scripts) are wrapped in double quotes: ``"% ... "``, the
    first one ``"Data file recorded ..."`` without the ``%``, the closing quote sometimes missing. That dialect gives
    the stride frequency per side (``Right Stride Frequency = 6.0``, ``Left ...``; read as ``[right, left]``) and the
    phase as ``Phase (Fractional) = 32768.0``. A data row may end in one empty field (a trailing comma).

    A measured leg position that jumps more than half a revolution between two rows (faster than
    :data:`MAX_LEG_REV_PER_S`) is a glitch, not a leg: the row is malformed. A column of the IMU stuck at a limit of
    its 16-bit range on every row (a saturated or unplugged sensor) and a duty beyond the full scale are warned of.

    A malformed file raises ``ValueError`` naming the file, the line and the offending field or value. A malformed
    data row (a field that is not an integer, the wrong number of fields, time not increasing) raises as well, unless
    ``skip_bad_rows`` is true: then the row is left out, a warning is issued, and the record's ``skipped_rows`` lists
    every such row's line number and reason. Nothing is ever dropped silently.

    Files written by :func:`write_roach_csv` are read like any other; the record then also holds ``zero_filled``
    (our columns the writer had no data for and wrote as 0) and, from the provenance line, ``written_from``,
    ``model_hash`` and ``controller``.
    """
    path = Path(path)
    lines = _read_lines(path)
    header: list[tuple[int, str, str]] = []  # (line number, text after '%', the raw line)
    data: list[tuple[int, str]] = []
    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith('"'):  # the dialect of the lab's older scripts: header lines in double quotes
            stripped = stripped[1:-1] if stripped.endswith('"') and len(stripped) > 2 else stripped[1:]
            stripped = stripped.strip()
            if not stripped.startswith("%"):  # its first line, "Data file recorded ...", has no '%'
                stripped = "%" + stripped
        if stripped.startswith("%"):
            header.append((number, stripped[1:].strip(), line.rstrip("\r\n")))
        else:
            data.append((number, stripped))
    if not data:
        raise ValueError(f"{path}: no data rows (only {len(header)} '%' header lines)")

    meta, columns, columns_line = _parse_header(path, header, first_data_line=data[0][0])
    n_fields = len(columns)
    rows: list[list[int]] = []
    skipped: list[dict[str, Any]] = []
    previous: tuple[list[int], int] | None = None  # (the last kept row, its line number)
    behind: list[int] = []  # the lines since the last kept row whose time did not pass it
    for number, line in data:
        if number < columns_line:
            problem = f"{path}, line {number}: data row before the columns line (line {columns_line})"
        else:
            values, problem = _parse_row(path, number, line, columns)
            if values is not None and previous is not None:
                problem = _out_of_sequence(path, number, columns, values, *previous)
                if values[0] <= previous[0][0]:
                    behind.append(number)
        if problem is not None:
            if not skip_bad_rows:
                raise ValueError(problem)
            if len(behind) > MAX_REPEATED_ROWS:  # not a glitch the log rejoins: its clock went back
                raise ValueError(
                    f"{path}, line {behind[0]}, field 1 (time): time runs backwards (this row and the "
                    f"{len(behind) - 1} after it stay at or before line {previous[1]}'s {previous[0][0]} us)"
                )
            skipped.append({"line": number, "reason": problem})
            continue
        rows.append(values)
        previous = (values, number)
        behind = []
    if skipped:
        warnings.warn(f"{path}: skipped {len(skipped)} malformed rows (see the record's 'skipped_rows')", stacklevel=2)
    if not rows:
        raise ValueError(
            f"{path}: no valid data rows ({len(skipped)} malformed rows skipped; the first: {skipped[0]['reason']})"
        )

    raw = np.asarray(rows, dtype=np.int64).reshape(len(rows), n_fields)
    df = _to_table(raw, columns)
    meta.update(_data_summary(raw))
    _warn_implausible(path, raw)
    meta["skipped_rows"] = skipped
    meta["source"] = str(path)
    meta["units"] = {c: _unit(c) for c in df.columns if c != "episode"}
    return df, meta


def _read_lines(path: Path) -> list[str]:
    if not path.exists():
        raise ValueError(f"{path}: no such file")
    if not path.is_file():
        raise ValueError(f"{path}: not a file")
    lines = path.read_bytes().splitlines()
    out = []
    for number, line in enumerate(lines, start=1):
        try:
            out.append(line.decode("utf-8-sig" if number == 1 else "utf-8"))  # a leading BOM (Excel) is not text
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}, line {number}: not text ({exc.reason} at byte {exc.start})") from None
    return out


def _parse_header(
    path: Path, header: list[tuple[int, str, str]], first_data_line: int
) -> tuple[dict[str, Any], list[str], int]:
    """The metadata record from the header lines, the column labels, and the line number of the columns line."""
    meta: dict[str, Any] = {
        "robot": "velociroach",
        "source": str(path),
        "format": "ImageProc 2.5 VelociRoACH telemetry text (Experiment.py)",
        "controller": "gait mode (firmware leg clock and PID)",
        "date": None,
        "date_iso": None,
        "stride_frequency_hz": None,
        "phase_counts": None,
        "phase_rad": None,
        "motor_gains": None,
        "zero_filled": [],
    }
    other: list[str] = []
    columns: list[str] | None = None
    columns_line = 0
    per_side: dict[str, float] = {}
    for number, text, raw_line in header:
        key_value = _KEY_VALUE.match(text)
        key = _norm(key_value["key"]) if key_value else ""
        value = key_value["value"] if key_value else ""
        if date := _DATE.match(text):
            meta["date"] = date["date"]
            meta["date_iso"] = _iso_date(date["date"])
        elif key == "stride frequency":
            meta["stride_frequency_hz"] = _number_list(path, number, "Stride Frequency", value, float) or None
        elif key in ("right stride frequency", "left stride frequency"):  # the older dialect: one per side
            if value:
                try:
                    per_side[key.split()[0]] = float(value)
                except ValueError:
                    raise ValueError(f"{path}, line {number}: {text.split('=')[0].strip()} {value!r} is not a "
                                     "number") from None  # fmt: skip
        elif key in ("phase", "phase (fractional)"):
            if value:
                counts = _integral(value)
                if counts is None:
                    raise ValueError(f"{path}, line {number}: Phase {value!r} is not an integer (counts of 65536)")
                meta["phase_counts"] = counts
                meta["phase_rad"] = 2.0 * math.pi * counts / COUNTS_PER_REV
        elif key == "motor gains":
            meta["motor_gains"] = _number_list(path, number, "Motor Gains", value, int) or None
        elif key == _norm(ZERO_FILLED_KEY):
            by_label = {_norm(x): c.name for c in REAL_COLUMNS for x in (c.label, *c.aliases)}
            meta["zero_filled"] = [by_label[_norm(x)] for x in value.split(",") if _norm(x) in by_label]
            other.append(raw_line)
        elif _norm(text).startswith(_norm(PROVENANCE_KEY)):
            other.append(raw_line)
            meta.update(_provenance(text))
        elif _norm(text) == "columns:":
            continue
        elif "|" in text and columns is None:
            columns = [c.strip() for c in text.split("|")]
            columns_line = number
        else:
            other.append(raw_line)
            if _norm(text).endswith(".py"):
                meta["controller"] = f"gait mode (firmware leg clock and PID, {text.strip()})"
    if per_side and meta["stride_frequency_hz"] is None:
        meta["stride_frequency_hz"] = [
            int(f) if f.is_integer() else f for f in (per_side.get("right"), per_side.get("left")) if f is not None
        ]
    if columns is None:
        raise ValueError(
            f"{path}, line {first_data_line}: data begins but the header has no columns line "
            f"('% {' | '.join(c.label for c in REAL_COLUMNS)}')"
        )
    _check_columns(path, columns_line, columns)
    meta["columns"] = columns
    meta["header_other"] = other
    return meta, columns, columns_line


def _provenance(text: str) -> dict[str, Any]:
    """The fields of our own provenance line (written by :func:`write_roach_csv`); nothing if it does not parse."""
    try:
        record = json.loads(text.split(":", 1)[1])
    except (IndexError, ValueError):
        return {}
    if not isinstance(record, dict):
        return {}
    out: dict[str, Any] = {"written_from": record}
    for key in ("model_hash", "controller"):
        if isinstance(record.get(key), str):
            out[key] = record[key]
    return out


def _iso_date(text: str) -> str | None:
    m = _DATE_FIELDS.match(" ".join(text.split()))
    if m is None:
        return None
    try:
        return datetime.datetime(*(int(g) for g in m.groups())).isoformat()
    except ValueError:
        return None


def _integral(value: str) -> int | None:
    """``32768`` or ``32768.0`` as an int; None if not a whole number."""
    if _INT.match(value):
        return int(value)
    try:
        number = float(value)
    except ValueError:
        return None
    return int(number) if math.isfinite(number) and number.is_integer() else None


def _number_list(path: Path, number: int, what: str, value: str, kind: type) -> list[Any]:
    text = value.strip()
    if not text:
        return []
    if not (text.startswith("[") and text.endswith("]")):
        raise ValueError(f"{path}, line {number}: {what} {value!r} is not a list like [2, 2]")
    out = []
    for item in text[1:-1].split(","):
        item = item.strip()
        try:
            out.append(kind(item))
        except ValueError:
            wanted = "an integer" if kind is int else "a number"
            raise ValueError(f"{path}, line {number}: {what} holds {item!r}, not {wanted}") from None
    if kind is float:
        out = [int(x) if float(x).is_integer() else x for x in out]
    return out


def _check_columns(path: Path, number: int, columns: list[str]) -> None:
    where = f"{path}, line {number}"
    for i, column in enumerate(REAL_COLUMNS):
        if i >= len(columns):
            missing = [c.label for c in REAL_COLUMNS[i:]]
            raise ValueError(f"{where}: the columns line lacks the required columns {missing}")
        if _norm(columns[i]) not in _expected_labels(column):
            raise ValueError(
                f"{where}: column {i + 1} is {columns[i]!r}, expected {column.label!r} "
                f"(the firmware writes {' | '.join(c.label for c in REAL_COLUMNS)}, then any extra columns)"
            )
    ours = set(TELEMETRY_COLUMNS) | set(SHARED_COLUMNS) | {"episode"}
    seen: set[str] = set()
    for i, name in enumerate(columns[len(REAL_COLUMNS) :], start=len(REAL_COLUMNS) + 1):
        if not name:
            raise ValueError(f"{where}: column {i} has no name")
        if name in ours or _norm(name) in {_norm(x) for c in REAL_COLUMNS for x in (c.label, *c.aliases)}:
            raise ValueError(f"{where}: extra column {i} {name!r} clashes with a standard or schema column")
        if name in seen:
            raise ValueError(f"{where}: column {i} {name!r} appears twice")
        seen.add(name)


MAX_LEG_REV_PER_S = 100.0  # a leg turning faster is a glitch: over twice the real robot's fastest strides (45 Hz)
_LEG_COLUMNS = (1, 2)  # the measured leg positions' fields (Right Leg Pos, Left Leg Pos)
_IMU_COLUMNS = range(7, 13)  # GyroX .. AZ: signed 16-bit readings


def _out_of_sequence(
    path: Path, number: int, columns: list[str], values: list[int], last: list[int], last_line: int
) -> str | None:
    """Why a row cannot follow the last kept one (time not increasing, a leg that jumps), or None."""
    if values[0] <= last[0]:
        return (
            f"{path}, line {number}, field 1 (time): {values[0]} us does not increase "
            f"(previous row, line {last_line}: {last[0]} us)"
        )
    limit = COUNTS_PER_REV * max(0.5, MAX_LEG_REV_PER_S * (values[0] - last[0]) * TIME_SECONDS_PER_LSB)
    for i in _LEG_COLUMNS:
        if abs(values[i] - last[i]) > limit:
            return (
                f"{path}, line {number}, field {i + 1} ({columns[i]}): {values[i]} counts jumps "
                f"{(values[i] - last[i]) / COUNTS_PER_REV:+.3g} revolutions from line {last_line} in "
                f"{(values[0] - last[0]) * TIME_SECONDS_PER_LSB * 1e3:.3g} ms (faster than {MAX_LEG_REV_PER_S:g} rev/s)"
            )
    return None


def _warn_implausible(path: Path, raw: np.ndarray) -> None:
    """Warn of what reads but cannot be right: an IMU column stuck at a limit of its range on every row, a duty
    beyond the full scale (:data:`DUTY_FULL_SCALE`)."""
    for i in _IMU_COLUMNS:
        column = raw[:, i]
        if len(column) > 1 and column.min() == column.max() and int(column[0]) in (-32768, 32767):
            warnings.warn(
                f"{path}: column {REAL_COLUMNS[i].label} reads {int(column[0])} (a limit of its 16-bit range) on "
                "every row: the sensor is saturated or not connected",
                stacklevel=3,
            )
    level = int(np.abs(raw[:, [5, 6]]).max(initial=0))
    if level > DUTY_FULL_SCALE:
        warnings.warn(
            f"{path}: columns DCR/DCL reach {level} counts, beyond the duty full scale of {DUTY_FULL_SCALE} counts "
            "this reader assumes (the lab's scaling script): duty above 1 cannot be replayed faithfully",
            stacklevel=3,
        )


def _parse_row(path: Path, number: int, line: str, columns: list[str]) -> tuple[list[int] | None, str | None]:
    fields = line.split(",")
    if len(fields) == len(columns) + 1 and not fields[-1].strip():  # a trailing comma
        fields = fields[:-1]
    if len(fields) != len(columns):
        return None, (
            f"{path}, line {number}: {len(fields)} fields, expected {len(columns)} (one per column of the header)"
        )
    values = []
    for i, field in enumerate(fields):
        field = field.strip()
        if not _INT.match(field):
            return None, f"{path}, line {number}, field {i + 1} ({columns[i]}): {field!r} is not an integer"
        values.append(int(field))
    return values, None


def _to_table(raw: np.ndarray, columns: list[str]) -> pd.DataFrame:
    shared = {c.name: raw[:, i] * c.scale for i, c in enumerate(REAL_COLUMNS)}
    order = [c for c in TELEMETRY_COLUMNS if c in shared] + [c for c in SHARED_COLUMNS if c not in TELEMETRY_COLUMNS]
    df = pd.DataFrame({c: shared[c].astype(np.float64) for c in order})
    for i, name in enumerate(columns[len(REAL_COLUMNS) :], start=len(REAL_COLUMNS)):
        df[name] = raw[:, i].astype(np.int64)
    df.insert(0, "episode", np.zeros(len(df), dtype=np.int64))
    return df


def _unit(column: str) -> str:
    if column in TELEMETRY_COLUMNS:
        return TELEMETRY_COLUMNS[column]
    return EXTRA_COLUMN_UNIT


def _data_summary(raw: np.ndarray) -> dict[str, Any]:
    """Sampling (rate, missing samples, gaps) and duty saturation, from the raw counts."""
    t = raw[:, 0]
    out: dict[str, Any] = {"rows": len(raw)}
    if len(t) > 1:
        dt = np.diff(t)
        median = float(np.median(dt))
        out["rate_hz"] = round(1.0 / (median * TIME_SECONDS_PER_LSB), 3)
        out["median_dt_s"] = median * TIME_SECONDS_PER_LSB
        out["max_gap_s"] = float(dt.max()) * TIME_SECONDS_PER_LSB
        out["missing_samples"] = max(round(float(t[-1] - t[0]) / median) + 1 - len(t), 0)
    else:
        out.update(rate_hz=None, median_dt_s=None, max_gap_s=None, missing_samples=0)
    out["duration_s"] = float(t[-1] - t[0]) * TIME_SECONDS_PER_LSB
    # the firmware clips its PID output symmetrically: a clipped channel piles up at +-limit, an unclipped one
    # touches its extreme once or twice
    i_right = [c.name for c in REAL_COLUMNS].index("duty_right")
    duty = np.abs(raw[:, [i_right, i_right + 1]])
    level = int(duty.max())
    at_level = {side: int((duty[:, k] == level).sum()) for k, side in enumerate(("right", "left"))}
    clipped = level > 0 and sum(at_level.values()) >= 3
    out["duty_full_scale_counts"] = DUTY_FULL_SCALE
    out["duty_clip_counts"] = level if clipped else None
    out["duty_clip"] = level / DUTY_FULL_SCALE if clipped else None
    out["duty_clipped_samples"] = {"left": at_level["left"], "right": at_level["right"]} if clipped else None
    out["quantisation"] = dict(QUANTISATION)
    out["column_map"] = {c.label: c.name for c in REAL_COLUMNS}
    out["schema_version"] = SCHEMA_VERSION
    return out


# --- writing ----------------------------------------------------------------------------------------------------
def write_roach_csv(
    df: pd.DataFrame, path: str | Path, meta: Mapping[str, Any] | None = None, overwrite: bool = False
) -> Path:
    """Write one episode of a telemetry table in our schema to the real robot's text format, atomically.

    The 16 columns the formats share are converted to the real format's integer counts (rounded to the nearest
    count). A shared column that the table lacks, and every NaN in one (the commanded leg angles in duty mode), is
    written as 0, and a ``%  Not in the source (written as 0) = ...`` header line names those columns (read back,
    they are 0 and the record's ``zero_filled`` names them). Columns of our schema that the real format lacks (pose,
    ground forces, torque, power) are not written. A ``%  Written by skitter ...`` line records, as JSON, the robot,
    source, model hash, controller and rate of ``meta``; the reader takes the model hash and controller back.
    Columns beyond the 16 that ``meta["columns"]`` names (e.g. S1..S8 of a file read by :func:`read_roach_csv`) are
    written raw when the table has them, so a real file survives read -> write with only that line added.

    The header carries the stride frequency, phase and motor gains when ``meta`` knows them
    (``stride_frequency_hz``, ``phase_counts`` or ``phase_rad``, ``motor_gains``), empty values otherwise.

    Raises ``FileExistsError`` if ``path`` exists and ``overwrite`` is false, ``ValueError`` for a table that cannot
    be written (several episodes, no ``time`` column, infinite values, time not increasing once in microseconds).
    """
    path = Path(path)
    if not overwrite:
        refuse_overwrite(path, "telemetry file")
    meta = dict(meta or {})
    if "episode" in df.columns and df["episode"].nunique() > 1:
        episodes = sorted(int(e) for e in df["episode"].unique())
        raise ValueError(
            f"cannot write {path}: the table holds episodes {episodes}, and the real format holds one run; "
            "write one at a time (df[df.episode == k])"
        )
    if "time" not in df.columns:
        raise ValueError(f"cannot write {path}: the table has no 'time' column")
    if len(df) == 0:
        raise ValueError(f"cannot write {path}: the table has no rows")

    labels = _column_labels(meta)
    counts: list[np.ndarray] = []
    zeroed: list[str] = []
    for column, label in zip(REAL_COLUMNS, labels, strict=False):
        if column.name not in df.columns:
            counts.append(np.zeros(len(df), dtype=np.int64))
            zeroed.append(label)
            continue
        values = df[column.name].to_numpy(dtype=np.float64)
        nan = np.isnan(values)
        if np.isinf(values).any():
            row = int(np.flatnonzero(np.isinf(values))[0])
            raise ValueError(f"cannot write {path}: column {column.name!r} is infinite at row {row}")
        if column.name == "time" and nan.any():
            raise ValueError(f"cannot write {path}: time is NaN at row {int(np.flatnonzero(nan)[0])}")
        if nan.any() or column.name in (meta.get("zero_filled") or []):
            zeroed.append(label)
        counts.append(np.rint(np.where(nan, 0.0, values) / column.scale).astype(np.int64))
    if (np.diff(counts[0]) <= 0).any():
        row = int(np.flatnonzero(np.diff(counts[0]) <= 0)[0]) + 1
        raise ValueError(f"cannot write {path}: time does not increase at row {row} (in whole microseconds)")

    extras = [name for name in labels[len(REAL_COLUMNS) :] if name in df.columns]
    for name in extras:
        values = df[name].to_numpy(dtype=np.float64)
        if not np.isfinite(values).all() or (values != np.rint(values)).any():
            raise ValueError(f"cannot write {path}: extra column {name!r} must hold integers (raw counts)")
        counts.append(values.astype(np.int64))
    table = np.column_stack(counts)
    text = _header(meta, labels[: len(REAL_COLUMNS)] + extras, zeroed) + _rows(table)
    return atomic_write(path, lambda p: p.write_text(text))


def _column_labels(meta: Mapping[str, Any]) -> list[str]:
    """The column labels to write: those of the source file when it was a real file, else the lab's spelling."""
    columns = meta.get("columns")
    if isinstance(columns, list) and len(columns) >= len(REAL_COLUMNS):
        if all(_norm(str(x)) in _expected_labels(c) for x, c in zip(columns, REAL_COLUMNS, strict=False)):
            return [str(x) for x in columns]
    return [c.label for c in REAL_COLUMNS]


def _format_number(x: Any) -> str:
    x = float(x)
    return str(int(x)) if x.is_integer() else repr(x)


def _header(meta: Mapping[str, Any], labels: list[str], zeroed: list[str]) -> str:
    date = meta.get("date") or _lab_date(time.localtime())
    freq = meta.get("stride_frequency_hz")
    freq_text = "[" + ", ".join(_format_number(f) for f in freq) + "]" if freq else ""
    phase = meta.get("phase_counts")
    if phase is None and meta.get("phase_rad") is not None:
        phase = round(float(meta["phase_rad"]) / (2.0 * math.pi) * COUNTS_PER_REV)
    gains = meta.get("motor_gains")
    ours = (_norm(ZERO_FILLED_KEY), _norm(PROVENANCE_KEY))
    other = [line for line in meta.get("header_other") or [] if not _norm(line.lstrip("%")).startswith(ours)]
    if not other:
        other = ["%  Lead In /Lead Out        = "]
    # the lab's order: key = value lines (lead in/out, deltas) before the phase, bare lines (Experiment.py) after it
    lines = [f"%  Data file recorded {date}", f"%  Stride Frequency         = {freq_text}"]
    lines += [line for line in other if "=" in line]
    lines.append(f"%  Phase                    = {'' if phase is None else int(phase)}")
    lines += [line for line in other if "=" not in line]
    lines.append("%  Motor Gains    = " + ("[" + ", ".join(str(int(g)) for g in gains) + "]" if gains else ""))
    provenance = {key: meta[key] for key in _PROVENANCE_FIELDS if meta.get(key) is not None}
    lines.append(f"%  {PROVENANCE_KEY} {json.dumps(provenance)}")
    if zeroed:
        lines.append(f"%  {ZERO_FILLED_KEY} = {', '.join(zeroed)}")
    lines += ["% Columns: ", "% " + " | ".join(labels)]
    return "\n".join(lines) + "\n"


def _lab_date(t: time.struct_time) -> str:
    """The date as the lab's Experiment.py writes it: ``2015/2/28  16:7:3``."""
    return f"{t.tm_year}/{t.tm_mon}/{t.tm_mday}  {t.tm_hour}:{t.tm_min}:{t.tm_sec}"


def _rows(table: np.ndarray) -> str:
    return "".join(",".join(map(str, row)) + "\n" for row in table.tolist())
