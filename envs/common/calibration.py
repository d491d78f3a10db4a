"""Calibration files: the effects ``calibrate.py`` found for a robot, applied by the robot when an env is made with
``calibration=PATH``. The nominal model is never modified; a calibrated robot is the nominal one plus these effects.

A file is JSON::

    {"format": "skitter calibration", "version": 1, "robot": "velociroach",
     "effects": {"viscous_friction_left": {"damping": {"value": 2.1e-5, "ci95": 3e-7, "unit": "N m s/rad"}}},
     "provenance": {"train": [...], "test": [...], "error_before": 41.2, "error_after": 3.1, ...}}

Values may also be written bare (``{"damping": 2.1e-5}``).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from envs.common.io import DuplicateKey, nearest, not_a_file, unique_keys

FORMAT = "skitter calibration"
VERSION = 1
# the robot's name in a calibration file is the robot's own (``velociroach``); ``calibrate.py --robot`` takes the
# short one, and a file written by hand with it means the same robot
ROBOT_ALIASES = {"roach": "velociroach"}
# a catalog parameter in the unit of whatever channel it acts on (a sensor's offset) has no unit to check against
ANY_UNIT = "channel unit"

if TYPE_CHECKING:
    from envs.common.effects import Param


class CalibrationError(ValueError):
    """A calibration file that cannot be used; the message names the file, field and value."""


@dataclass(frozen=True)
class Calibration:
    """A robot's calibrated effects: ``effects[name][param]`` is the value."""

    robot: str
    effects: Mapping[str, Mapping[str, float]]
    path: str = ""
    provenance: Mapping[str, Any] = field(default_factory=dict)
    units: Mapping[str, Mapping[str, str]] = field(default_factory=dict)  # as the file states them, where it does

    @property
    def setting(self) -> dict[str, float]:
        """The effects as one flat dict, ``effect.param -> value``."""
        return {f"{e}.{p}": float(v) for e, params in self.effects.items() for p, v in params.items()}

    def check(self, known: Mapping[str, Mapping[str, Param]]) -> None:
        """Refuse effects or parameters the robot does not know, values outside their range, or a value stated in
        another unit than the catalog's; ``known`` is effect -> parameter -> catalog parameter."""
        for name, params in self.effects.items():
            if name not in known:
                raise CalibrationError(
                    f"{self.path}: field 'effects.{name}': robot {self.robot!r} has no effect {name!r} "
                    f"(known: {', '.join(sorted(known))})"
                )
            for param, value in params.items():
                if param not in known[name]:
                    raise CalibrationError(
                        f"{self.path}: field 'effects.{name}.{param}': {name} has no parameter {param!r} "
                        f"(it has {', '.join(known[name])})"
                    )
                spec = known[name][param]
                stated = self.units.get(name, {}).get(param)
                if stated is not None and spec.unit != ANY_UNIT and _unit_key(stated) != _unit_key(spec.unit):
                    raise CalibrationError(
                        f"{self.path}: field 'effects.{name}.{param}.unit': {stated!r} is not the unit skitter "
                        f"reads {name}.{param} in ({spec.unit!r}): write the value in {spec.unit}"
                    )
                if not spec.low <= value <= spec.high:
                    raise CalibrationError(
                        f"{self.path}: field 'effects.{name}.{param}': {value:g} is outside its range "
                        f"[{spec.low:g}, {spec.high:g}]"
                    )


DIMENSIONLESS = ("", "1", "-", "none", "dimensionless", "unitless")  # a ratio's unit, however it is written


def _unit_key(unit: str) -> str:
    """A unit's spelling, blind to spacing and the product's sign (``N m s/rad``, ``N·m·s/rad``, ``N*m*s/rad``)
    and to how a ratio's is written."""
    key = "".join(unit.replace("\u00b7", " ").replace("*", " ").split())
    return "1" if key.lower() in DIMENSIONLESS else key


FIELDS = ("format", "version", "robot", "effects", "provenance")  # as calibration_record writes a file
# a parameter's entry, as calibrate.py and sysid.measure write it: what is read (value, unit) and what describes it
ENTRY_FIELDS = ("value", "unit", "ci95", "interval95", "nominal", "range")


def read_calibration(path: str | Path, robot: str | None = None) -> Calibration:
    """Read and check a calibration file (for ``robot`` if given)."""
    path = Path(path)
    if not path.is_file():
        raise CalibrationError(f"{path}: {not_a_file(path, 'calibration file')}")
    try:
        data = json.loads(path.read_text(encoding="utf-8-sig"), object_pairs_hook=unique_keys)
    except DuplicateKey as exc:
        raise CalibrationError(f"{path}: field {exc.args[0]!r} is given twice: give each field once") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationError(f"{path}: not a readable JSON calibration file ({exc})") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: a calibration file is a JSON object, not {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise CalibrationError(f"{path}: field 'format': {data.get('format')!r} is not {FORMAT!r}")
    if data.get("version") != VERSION:
        given = data.get("version")
        kind = " (a string, not a number)" if isinstance(given, str) else ""
        raise CalibrationError(f"{path}: field 'version': {given!r}{kind}; this skitter reads version {VERSION}")
    unknown = [key for key in data if key not in FIELDS]
    if unknown:
        near = nearest(unknown[0], FIELDS)
        raise CalibrationError(f"{path}: unknown field {unknown[0]!r}" + (f" (did you mean {near!r}?)" if near else "")
                               + f"; a calibration file has {', '.join(map(repr, FIELDS))}")  # fmt: skip
    name = data.get("robot")
    if not isinstance(name, str):
        raise CalibrationError(f"{path}: field 'robot': {name!r} is not a robot name")
    name = ROBOT_ALIASES.get(name, name)
    if robot is not None and name != robot:
        raise CalibrationError(f"{path}: field 'robot': the file calibrates {name!r}, not {robot!r}")
    raw = data.get("effects")
    if "effects" not in data:
        raise CalibrationError(f"{path}: no field 'effects' (an object of effects, each an object of parameters)")
    if not isinstance(raw, dict):
        raise CalibrationError(f"{path}: field 'effects': {raw!r} is not an object of effects")
    effects: dict[str, dict[str, float]] = {}
    units: dict[str, dict[str, str]] = {}
    for effect, params in raw.items():
        if not isinstance(params, dict) or not params:
            raise CalibrationError(f"{path}: field 'effects.{effect}': {params!r} is not an object of parameters")
        effects[effect] = {}
        for param, entry in params.items():
            if isinstance(entry, dict) and "value" not in entry:
                raise CalibrationError(f"{path}: field 'effects.{effect}.{param}': no 'value' (an entry is a number, "
                                       "or an object with one under 'value')")  # fmt: skip
            value = entry.get("value") if isinstance(entry, dict) else entry
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise CalibrationError(f"{path}: field 'effects.{effect}.{param}': {value!r} is not a finite number")
            effects[effect][param] = float(value)
            stray = [key for key in entry if key not in ENTRY_FIELDS] if isinstance(entry, dict) else []
            if stray:
                near = nearest(str(stray[0]), ENTRY_FIELDS)
                raise CalibrationError(f"{path}: field 'effects.{effect}.{param}': unknown field {stray[0]!r}"
                                       + (f" (did you mean {near!r}?)" if near else "")
                                       + f"; an entry has {', '.join(map(repr, ENTRY_FIELDS))}")  # fmt: skip
            unit = entry.get("unit") if isinstance(entry, dict) else None
            if unit is not None and not isinstance(unit, str):
                raise CalibrationError(f"{path}: field 'effects.{effect}.{param}.unit': {unit!r} is not a unit's name")
            if unit is not None:
                units.setdefault(effect, {})[param] = unit
    return Calibration(name, effects, str(path), data.get("provenance") or {}, units)


def calibration_record(
    robot: str, effects: Mapping[str, Mapping[str, Mapping[str, Any]]], provenance: Mapping[str, Any]
) -> dict[str, Any]:
    """The JSON object of a calibration file."""
    return {"format": FORMAT, "version": VERSION, "robot": robot, "effects": effects, "provenance": provenance}
