"""The VelociRoACH's text telemetry as a calibration log (``sysid.robots.read_log`` finds it through
``LOG_READERS``)."""

from __future__ import annotations

import warnings
from pathlib import Path

from envs.velociroach.roach_csv import read_roach_csv
from sysid.logs import Log, LogError, LogReader, drop_bad_rows


def _matches(head: str) -> bool:
    # ``%`` header lines, or the lab's older dialect with each header line in double quotes, the first one
    # ``"Data file recorded ..."`` without its ``%``
    unquoted = head.lstrip('"').lstrip()
    return unquoted.startswith("%") or unquoted.lower().startswith("data file recorded")


def _read(path: Path) -> Log:
    with warnings.catch_warnings():  # the skipped rows are reported below, one by one, not as a count
        warnings.filterwarnings("ignore", message=r".*: skipped \d+ malformed rows")
        try:
            df, meta = read_roach_csv(path, skip_bad_rows=True)
        except ValueError as exc:
            raise LogError(str(exc)) from None
    skipped = meta.get("skipped_rows", [])
    drop_bad_rows(path, [(s["line"], s["reason"].split(": ", 1)[-1]) for s in skipped], len(df) + len(skipped))
    return Log(str(path), df, meta)


READER = LogReader("VelociRoACH text telemetry", _matches, _read)
LOG_READERS = [READER]
