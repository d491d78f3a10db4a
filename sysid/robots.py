"""What the calibration adapters declare (sysid/adapters): each module there names its adapters (``ADAPTERS``, robot
name -> adapter class) and, for a log format of the robot's own, its readers (``LOG_READERS``). The shared tools find
a robot's parts here without naming it; a robot joins by adding a module to sysid/adapters.

The log readers and the channel names the robots declare reach :func:`sysid.logs.read_log` as arguments
(:func:`formats`), so that reading a log never reaches up to the robots; :func:`read_log` reads with all of them."""

from __future__ import annotations

import functools
import importlib
import pkgutil
from collections.abc import Mapping, Sequence
from pathlib import Path

import sysid.adapters
from envs.common.telemetry import ChannelLimit
from sysid import logs
from sysid.logs import ColumnMap, Log, LogFormats, LogReader, channel_suffixes
from sysid.problem import Adapter


def declared(name: str) -> list:
    """What every module of sysid/adapters declares under ``name``, a dict's items merged or a list's entries
    joined, in the modules' name order."""
    found: list = []
    for module in pkgutil.iter_modules(sysid.adapters.__path__):
        value = getattr(importlib.import_module(f"sysid.adapters.{module.name}"), name, None)
        if value:
            found += list(value.items()) if isinstance(value, dict) else list(value)
    return found


def adapters() -> dict[str, type[Adapter]]:
    """Robot name -> its adapter class."""
    return dict(declared("ADAPTERS"))


def adapter(name: str) -> Adapter:
    known = adapters()
    if name not in known:
        raise ValueError(f"no calibration adapter for robot {name!r}; known: {', '.join(sorted(known))}")
    return known[name]()


def log_readers() -> list[LogReader]:
    """The robots' own log formats."""
    return declared("LOG_READERS")


@functools.lru_cache(maxsize=1)
def formats() -> LogFormats:
    """What the robots add to the shared log formats: their readers, and the joints, legs, sides and axes that their
    adapters' channels name (``FL``, ``left``, ``B_L_1``: what may follow a channel's name in a CSV read without a
    column map)."""
    names: set[str] = set()
    for cls in adapters().values():  # class attributes: no robot is built for this
        names.update(cls.commands, cls.channels)
    return LogFormats(readers=tuple(log_readers()), suffixes=channel_suffixes(names))


def read_log(
    path: str | Path,
    required: Sequence[str] = (),
    column_map: ColumnMap | None = None,
    limits: Mapping[str, ChannelLimit] | None = None,
) -> Log:
    """:func:`sysid.logs.read_log` with every robot's log formats and channels (:func:`formats`); ``limits`` (a
    robot's ``channel_limits``) drop the rows it could not have produced."""
    return logs.read_log(path, required, column_map, formats(), limits)
