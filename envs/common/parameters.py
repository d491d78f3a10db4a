"""Named physical parameters of a robot: one map from a name to the model fields (and controller settings) it sets.

Calibration fits these parameters and domain randomization samples them. Each parameter writes compiled-model fields
that change no model structure (masses, frictions, stiffnesses, damping, actuator constants), so setting one on a
compiled ``MjModel`` is what editing the ``MjSpec`` and recompiling would give, without the recompile; a batch of
simulations sets them per simulation through ``mujoco.batch.Batch.expand``. ``mj_setConst`` runs afterwards, so
that derived constants (subtree masses, ...) follow.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import mujoco
import numpy as np


@dataclass(frozen=True)
class FieldRef:
    """Entries of one ``MjModel`` field that a parameter sets.

    ``how="set"``: each entry becomes the value itself; ``"scale"``: nominal x value / parameter nominal (e.g. a mass
    that scales the inertia too); ``"inverse"``: nominal x parameter nominal / value (e.g. a controller's torque gain
    when the motor's resistance grows).
    """

    field: str
    index: tuple  # numpy index into the field, e.g. (body_id,) or (ids, slot)
    how: Literal["set", "scale", "inverse"] = "set"
    most: float | None = None  # the largest value an entry may take, whatever the built model (e.g. for stability)
    why: str = ""  # why it may take no more, for the message that refuses a range reaching past ``most``


@dataclass(frozen=True)
class Parameter:
    """A named physical parameter with its unit, nominal value, plausible range and where it lives in the model.

    ``attribute``: a per-simulation array of the robot's controller that the parameter also sets (for example the
    battery voltage that turns a duty cycle into volts).
    """

    name: str
    unit: str
    nominal: float
    low: float
    high: float
    description: str
    fields: tuple[FieldRef, ...] = ()
    attribute: str | None = None
    setconst: bool = False  # the fields feed mj_setConst (masses, inertias)

    def __post_init__(self) -> None:
        # a value on a bound that arithmetic moved by a rounding error (0.2 / 0.8 * 0.8) is on the bound
        tol = 1e-9 * max(abs(self.low), abs(self.high), 1e-300)
        if self.low - tol <= self.nominal < self.low or self.high < self.nominal <= self.high + tol:
            object.__setattr__(self, "nominal", min(max(self.nominal, self.low), self.high))
        if not (self.low <= self.nominal <= self.high):
            raise ValueError(f"parameter {self.name}: nominal {self.nominal} outside [{self.low}, {self.high}]")


@dataclass
class ParameterMap:
    """A robot's parameters by name, with the nominal model's field values to scale from."""

    parameters: dict[str, Parameter] = field(default_factory=dict)
    _nominal_fields: dict[str, np.ndarray] = field(default_factory=dict)
    # entries no product of their parameters can give (a sum of terms, say): each is called with ``target`` and every
    # parameter's value after the fields are set, and writes its entries from them
    derived: list[Callable[[Callable[[str], np.ndarray], Mapping[str, float]], None]] = field(default_factory=list)

    def add(self, parameter: Parameter) -> None:
        if parameter.name in self.parameters:
            raise ValueError(f"parameter {parameter.name!r} defined twice")
        self.parameters[parameter.name] = parameter

    def __contains__(self, name: str) -> bool:
        return name in self.parameters

    def __getitem__(self, name: str) -> Parameter:
        return self.parameters[name]

    def __iter__(self):
        return iter(self.parameters.values())

    def names(self) -> list[str]:
        return list(self.parameters)

    def remember_nominal(self, model: mujoco.MjModel) -> None:
        """Keep the compiled nominal values of every field a parameter touches (scaling starts from them)."""
        for p in self:
            for ref in p.fields:
                if ref.field not in self._nominal_fields:
                    self._nominal_fields[ref.field] = np.array(getattr(model, ref.field), copy=True)

    def field_values(self, name: str, value: float) -> dict[str, np.ndarray]:
        """What parameter ``name`` at ``value`` writes into each of its fields (from the built model's values)."""
        p = self.parameters[name]
        out = {}
        for ref in p.fields:
            built = np.asarray(self._nominal_fields[ref.field][ref.index], dtype=float)
            if ref.how == "set":
                out[ref.field] = np.full_like(built, value)
            elif ref.how == "scale":
                out[ref.field] = built * (value / p.nominal)
            else:
                out[ref.field] = built * (p.nominal / value)
        return out

    def check_range(self, name: str, low: float, high: float, where: str) -> None:
        """Refuse a range of parameter ``name`` that takes one of its fields past that field's ``most``: a scale
        applies to the model as built, whose own value may already be near the bound."""
        p = self.parameters[name]
        for ref in p.fields:
            if ref.most is None:
                continue
            reached = max(float(np.max(self.field_values(name, x)[ref.field], initial=-np.inf)) for x in (low, high))
            if reached > ref.most:
                built = float(np.max(self._nominal_fields[ref.field][ref.index]))
                given = f"{low:g}" if low == high else f"({low:g}, {high:g})"
                raise ValueError(
                    f"{where}[{name!r}] = {given} takes {ref.field} from {built:g} as built to "
                    f"{reached:g}, above its bound {ref.most:g} ({ref.why or 'the most it may be'})"
                )

    def apply(self, target: Callable[[str], np.ndarray], values: Mapping[str, float]) -> bool:
        """Set parameters for one simulation, whose writable field arrays ``target(field)`` gives (the model's own
        field, or one simulation's row of a batch's); parameters not named return to nominal. Returns whether
        ``mj_setConst`` must follow (masses changed).

        Fields shared by several parameters compose: each starts from its nominal value, a ``set`` writes, and
        ``scale`` and ``inverse`` multiply (the battery voltage and the motor resistance both act on a PID's gains).
        Then the :attr:`derived` entries are written from the values.
        """
        for name, nominal in self._nominal_fields.items():
            target(name)[...] = nominal
        setconst = False
        for p in self:
            value = float(values.get(p.name, p.nominal))
            for ref in p.fields:
                array = target(ref.field)
                if ref.how == "set":
                    array[ref.index] = value
                elif ref.how == "scale":
                    array[ref.index] = array[ref.index] * (value / p.nominal)
                else:
                    array[ref.index] = array[ref.index] * (p.nominal / value)
            setconst |= p.setconst
        if self.derived:
            every = {p.name: float(values.get(p.name, p.nominal)) for p in self}
            for derive in self.derived:
                derive(target, every)
        return setconst

    def describe(self) -> list[dict[str, Any]]:
        return [
            {
                "name": p.name,
                "unit": p.unit,
                "nominal": p.nominal,
                "low": p.low,
                "high": p.high,
                "description": p.description,
            }
            for p in self
        ]


Ranges = Mapping[str, Sequence[float]]


def check_randomize(randomize: Ranges | None, parameters: ParameterMap, where: str = "randomize") -> dict:
    """Validate ``randomize`` (parameter name -> (low, high)) against the robot's parameters; return it as floats.

    Each range must be finite, ordered and within the parameter's plausible range, and keep the fields it writes
    within their bounds (``FieldRef.most``) from the model as built.
    """
    if randomize is None:
        return {}
    if not isinstance(randomize, Mapping):
        raise ValueError(f"{where} must map parameter names to (low, high) ranges, got {randomize!r}")
    out = {}
    for name, bounds in randomize.items():
        if name not in parameters:
            known = ", ".join(parameters.names())
            raise ValueError(f"{where}: unknown parameter {name!r} (this robot's parameters: {known})")
        try:
            if isinstance(bounds, str | bytes) or any(isinstance(b, str | bytes | bool | np.bool_) for b in bounds):
                raise TypeError  # float() would read "34" as two bounds and "0.02" or True as numbers
            low, high = (float(b) for b in bounds)
        except (TypeError, ValueError):
            raise ValueError(f"{where}[{name!r}] must be a (low, high) pair of numbers, got {bounds!r}") from None
        p = parameters[name]
        if not (math.isfinite(low) and math.isfinite(high)) or low > high:
            raise ValueError(f"{where}[{name!r}] = ({low}, {high}): expected finite low <= high")
        if low < p.low or high > p.high:
            raise ValueError(
                f"{where}[{name!r}] = ({low}, {high}) leaves the parameter's range [{p.low}, {p.high}] {p.unit}"
            )
        parameters.check_range(name, low, high, where)
        out[name] = (low, high)
    return out


def sample(ranges: Mapping[str, tuple[float, float]], rng: np.random.Generator) -> dict[str, float]:
    """One draw of every randomized parameter, uniform in its range, in a fixed order (same seed, same draw)."""
    return {name: float(rng.uniform(low, high)) for name, (low, high) in sorted(ranges.items())}


SpecEdit = Callable[[mujoco.MjSpec], None]
