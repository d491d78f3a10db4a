"""Telemetry: one table schema for simulated and real robots, stored as Parquet with a JSON metadata record.

A table has one row per sample and one column per channel, in SI units, plus an ``episode`` column. The metadata
record (robot, model hash, controller, rate, units, source) travels inside the Parquet file under the key
``skitter``. See docs/telemetry.md.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from envs.common.io import atomic_write, json_default, refuse_overwrite

SCHEMA_VERSION = 1
METADATA_KEY = b"skitter"
# A log's rows whose time stays at or before the last kept row's: up to this many, a repeated or broken stretch the
# log rejoins (dropped as malformed rows); more, and the log's clock went back (the log is refused). Every reader's
# rule: sysid.logs for the formats it reads, each robot's own reader (envs/velociroach/roach_csv.py)
MAX_REPEATED_ROWS = 16


@dataclass(frozen=True)
class ChannelLimit:
    """What a channel's hardware can read: its range and the fastest it can change, in the channel's unit (and that
    unit per second), with where the bounds come from. A log's sample outside them is one the robot could not have
    produced (a corrupted field): the log readers drop its row with a warning (sysid/logs.py). A robot declares its
    channels' limits (``Robot.channel_limits``) from its actuators' constants, never from example logs."""

    low: float = -math.inf
    high: float = math.inf
    max_rate: float = math.inf
    source: str = ""

    def __post_init__(self) -> None:
        if not (self.low < self.high and self.max_rate > 0):  # false for NaN too
            raise ValueError(f"a channel limit needs low < high and a positive max_rate, got {self}")


class TelemetryRecorder:
    """Collects telemetry rows at the control rate, episode by episode.

    Args:
        meta: the metadata record (robot, model hash, controller, rate...).
        units: column name -> unit, in the order of the columns of ``robot.telemetry()`` (its
            ``telemetry_channels``).
    """

    def __init__(self, meta: dict[str, Any], units: dict[str, str]):
        self.meta = {**meta, "units": dict(units), "schema_version": SCHEMA_VERSION}
        self.columns = list(units)
        self._rows: list[np.ndarray] = []
        self._episodes: list[int] = []
        self._episode = -1

    def start_episode(self) -> None:
        self._episode += 1

    def record(self, row: np.ndarray) -> None:
        if self._episode < 0:
            raise RuntimeError("TelemetryRecorder.record() before start_episode()")
        row = np.array(row, dtype=np.float64)
        if row.shape != (len(self.columns),):
            raise ValueError(f"telemetry row has shape {row.shape}, expected ({len(self.columns)},)")
        self._rows.append(row)
        self._episodes.append(self._episode)

    def __len__(self) -> int:
        return len(self._rows)

    def frame(self) -> pd.DataFrame:
        data = np.vstack(self._rows) if self._rows else np.zeros((0, len(self.columns)))
        df = pd.DataFrame(data, columns=self.columns)
        df.insert(0, "episode", np.asarray(self._episodes, dtype=np.int64))
        return df

    def save(self, path: str | Path, overwrite: bool = False, **extra_meta: Any) -> Path:
        return write_telemetry(path, self.frame(), {**self.meta, **extra_meta}, overwrite=overwrite)

    def clear(self) -> None:
        self._rows.clear()
        self._episodes.clear()
        self._episode = -1


def write_telemetry(path: str | Path, df: pd.DataFrame, meta: dict[str, Any], overwrite: bool = False) -> Path:
    """Write a telemetry table and its metadata record to one Parquet file, atomically. An existing file is kept
    (``FileExistsError``) unless ``overwrite``."""
    if not overwrite:
        refuse_overwrite(path, "telemetry file")
    missing = [c for c in meta.get("units", {}) if c not in df.columns]
    if missing:
        raise ValueError(f"telemetry for {path} lacks columns {missing} named in its units")
    table = pa.Table.from_pandas(df, preserve_index=False)
    record = json.dumps({**meta, "schema_version": SCHEMA_VERSION}, default=json_default).encode()
    table = table.replace_schema_metadata({**(table.schema.metadata or {}), METADATA_KEY: record})
    return atomic_write(path, lambda p: pq.write_table(table, p))


def read_telemetry(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a telemetry Parquet file written by :func:`write_telemetry`: (table, metadata record)."""
    path = Path(path)
    try:
        table = pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as exc:
        raise ValueError(f"{path}: not a readable Parquet telemetry file ({exc})") from exc
    raw = (table.schema.metadata or {}).get(METADATA_KEY)
    if raw is None:
        raise ValueError(f"{path}: Parquet file has no '{METADATA_KEY.decode()}' metadata record")
    try:
        record = json.loads(raw)
    except ValueError as exc:  # json's error, or bytes that are not text
        raise ValueError(f"{path}: its '{METADATA_KEY.decode()}' metadata record is not JSON ({exc})") from None
    if not isinstance(record, dict):
        raise ValueError(f"{path}: its '{METADATA_KEY.decode()}' metadata record is a JSON {type(record).__name__}, "
                         "not an object of named fields")  # fmt: skip
    return table.to_pandas(), record
