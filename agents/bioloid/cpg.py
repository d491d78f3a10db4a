"""The report's central pattern generator for the Bioloid quadruped [bioloid-webots, VI.B]: coupled nonlinear
oscillators.

Each oscillating servo has an oscillator of the report's eq. 14 (Mojon's normalized coupling)::

    tau v_i' = -alpha (x_i^2 + v_i^2 - E_i) / E_i v_i - x_i + sum_j (a_ij x_j + b_ij v_j) / (x_i^2 + v_i^2)
    tau x_i' = v_i

with tau = 1 / (2 pi f) (f = 1 Hz, the report's baseline; a coupling file may free one shared frequency in [1, 2] Hz
for some oscillators, as the report's experiment 2 did). Its servo's goal is ``stand + sign (x0_i + A x_i)``: the
standing posture, the oscillator's offset x0 (the report's Figure 40) and its state in units of A = 45 deg, so that the
seed's amplitude sqrt(E) in (0, 1] spans up to 45 deg; ``sign`` mirrors the right abduction servos, so that
parameters shared by a left-right pair move the pair symmetrically.

**Coupling file** (JSON; ``agents/bioloid/cpg_configs/``)::

    {
      "name": "experiment 5",
      "source": "[bioloid-webots, VI.B.3.e] (CPG Model 4)",
      "frequency": 1.0,                   # Hz, every oscillator's (tau = 1 / (2 pi f))
      "alpha": 0.7,                       # convergence rate to the limit cycle
      "oscillators": {                    # the oscillating servos; each listens to one other (its connection)
        "F_L_1": {"input": "B_L_1", "bidir": true},   # bidir: the input also gets this one's weights, negated
        "F_L_3": {"input": "F_L_1"},
        ...
      },
      "shared": [["F_L_1", "F_R_1"], ...],             # groups that share all four parameters (symmetric pairs)
      "fixed": {"F_L_2": 819, ...},                    # servos held at a count (others hold the standing posture)
      "free_frequency": [],                            # oscillators sharing one free frequency in [1, 2] Hz
      "ranges": {"offset": 1.0472, "amplitude": [0.05, 1.0], "coupling": 0.7, "frequency": [1.0, 2.0]}
    }

**Parameters** (the report's mapping, VI.B.3): an optimizer's vector in [0, 1]^n, n = 4 per parameter group (the
oscillators not sharing are groups of one) plus 1 with a free frequency. Per group, in the order of the groups'
first oscillators in the file: offset x0 in [-offset, +offset] rad around the standing posture, amplitude sqrt(E) in
the amplitude range, and the weights a and b of the group's connections in [-coupling, coupling] (the report: [-0.7,
0.7]); then the frequency. The report's experiments 1-6 have 64, 33, 32, 24, 16 and 24 parameters; the files here
reproduce those counts (tests/test_bioloid_cpg.py).

Integration: semi-implicit Euler at 2.5 ms (400 steps per 1 Hz cycle), the limit cycle's pull taken implicitly where
it damps (it grows as (x^2 + v^2) / E and is stiff for small amplitudes), vectorized over simulations (rows) and
oscillators, each row computed on its own (no reduction across rows), so that a row's trajectory does not depend on
the batch it is in. The normalization x_i^2 + v_i^2 of the coupling is taken no smaller than E / 4 (eq. 14 is
singular at the origin; assumed).
Oscillators start at x = 0, v = sqrt(E) (on their own limit cycles, in phase): the same parameters give the same
gait.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from envs.bioloid import constants
from envs.bioloid.robot import GOAL
from envs.common.io import not_a_file

CONFIGS = Path(__file__).resolve().parent / "cpg_configs"
DEFAULT_CONFIG = "experiment5"  # the policy ``cpg`` without a file: experiment 5's model at the middle of its box
AMPLITUDE_SCALE = math.radians(45.0)  # rad per unit of oscillator state (assumed: the report gives no unit)
SUBSTEP = 0.0025  # s, the integration step
DEFAULT_RANGES = {"offset": math.radians(60.0), "amplitude": [0.05, 1.0], "coupling": 0.7, "frequency": [1.0, 2.0]}
FLOOR = 0.25  # x E: the coupling's normalization x^2 + v^2 taken no smaller (eq. 14 is singular at the origin)
MIRRORED = {"F_R_2", "B_R_2"}  # right abduction servos: a shared motion is mirrored
FIELDS = {"name", "source", "frequency", "alpha", "oscillators", "shared", "fixed", "free_frequency", "ranges"}


class CouplingError(ValueError):
    """A coupling or policy file that cannot be used; the message names the file and the field."""


@dataclass(frozen=True)
class Coupling:
    """A coupling configuration, checked (:func:`read_coupling`)."""

    name: str
    oscillators: tuple[str, ...]
    inputs: tuple[int, ...]  # per oscillator, the index of the one it listens to
    bidir: tuple[bool, ...]
    groups: tuple[int, ...]  # per oscillator, its parameter group
    fixed: Mapping[str, float]  # servo -> count
    free_frequency: tuple[int, ...]  # oscillators with the free frequency
    frequency: float = 1.0
    alpha: float = 0.7
    ranges: Mapping[str, Any] = field(default_factory=lambda: dict(DEFAULT_RANGES))
    source: str = ""
    path: str = "<inline>"

    @property
    def n_groups(self) -> int:
        return max(self.groups) + 1

    @property
    def dimension(self) -> int:
        """Number of free parameters (the optimizer's search space, [0, 1]^n)."""
        return 4 * self.n_groups + (1 if self.free_frequency else 0)

    def to_dict(self) -> dict[str, Any]:
        """The file's content (what :func:`read_coupling` reads back)."""
        groups: dict[int, list[str]] = {}
        for name, g in zip(self.oscillators, self.groups, strict=True):
            groups.setdefault(g, []).append(name)
        return {
            "name": self.name,
            "source": self.source,
            "frequency": self.frequency,
            "alpha": self.alpha,
            "oscillators": {
                name: {"input": self.oscillators[j], **({"bidir": True} if b else {})}
                for name, j, b in zip(self.oscillators, self.inputs, self.bidir, strict=True)
            },
            "shared": [names for names in groups.values() if len(names) > 1],
            "fixed": dict(self.fixed),
            "free_frequency": [self.oscillators[i] for i in self.free_frequency],
            "ranges": dict(self.ranges),
        }


def _number(where: str, value: Any, low: float | None = None, high: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CouplingError(f"{where} must be a finite number, got {value!r}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise CouplingError(f"{where} must be in [{low}, {high}], got {value!r}")
    return float(value)


def parse_coupling(raw: Any, path: str = "<inline>") -> Coupling:
    """Check a coupling configuration (the JSON's content); :class:`CouplingError` names the file and field."""
    if not isinstance(raw, Mapping):
        raise CouplingError(f"{path}: a coupling file holds a JSON object, got {type(raw).__name__}")
    unknown = set(raw) - FIELDS
    if unknown:
        raise CouplingError(f"{path}: unknown field(s) {sorted(unknown)}; known: {sorted(FIELDS)}")
    oscillators = raw.get("oscillators")
    if not isinstance(oscillators, Mapping) or not oscillators:
        raise CouplingError(
            f"{path}: field 'oscillators' must map servo names to their connection, got {oscillators!r}"
        )
    names = tuple(oscillators)
    for name in names:
        if name not in constants.SERVO_INDEX:
            raise CouplingError(
                f"{path}: field 'oscillators': {name!r} is not a servo; servos: {', '.join(constants.SERVOS)}"
            )
    inputs, bidir = [], []
    for name, spec in oscillators.items():
        where = f"{path}: field 'oscillators.{name}'"
        if not isinstance(spec, Mapping) or set(spec) - {"input", "bidir"}:
            raise CouplingError(f"{where} must be {{'input': <oscillator>, 'bidir': true|false}}, got {spec!r}")
        source = spec.get("input")
        if source not in oscillators or source == name:
            raise CouplingError(f"{where}.input must name another oscillator of the file, got {source!r}")
        flag = spec.get("bidir", False)
        if not isinstance(flag, bool):
            raise CouplingError(f"{where}.bidir must be true or false, got {flag!r}")
        inputs.append(names.index(source))
        bidir.append(flag)
    groups = list(range(len(names)))
    shared = raw.get("shared", [])
    if not isinstance(shared, list):
        raise CouplingError(f"{path}: field 'shared' must be a list of lists of oscillators, got {shared!r}")
    seen: set[str] = set()
    for k, group in enumerate(shared):
        if not isinstance(group, list) or len(group) < 2 or any(g not in oscillators for g in group):
            raise CouplingError(f"{path}: field 'shared[{k}]' must list two or more oscillators, got {group!r}")
        if seen & set(group):
            raise CouplingError(f"{path}: field 'shared[{k}]': {sorted(seen & set(group))} already share a group")
        seen |= set(group)
        first = names.index(group[0])
        for g in group[1:]:
            groups[names.index(g)] = groups[first]
    order = {g: i for i, g in enumerate(dict.fromkeys(groups))}  # groups numbered by their first oscillator
    groups = [order[g] for g in groups]
    fixed = raw.get("fixed", {})
    if not isinstance(fixed, Mapping):
        raise CouplingError(f"{path}: field 'fixed' must map servos to counts, got {fixed!r}")
    for servo, count in fixed.items():
        if servo not in constants.SERVO_INDEX:
            raise CouplingError(f"{path}: field 'fixed': {servo!r} is not a servo")
        if servo in oscillators:
            raise CouplingError(f"{path}: field 'fixed': {servo!r} also has an oscillator")
        low, high = constants.SERVO_RANGE[servo]
        _number(f"{path}: field 'fixed.{servo}'", count, low, high)
    free = raw.get("free_frequency", [])
    if not isinstance(free, list) or any(f not in oscillators for f in free):
        raise CouplingError(f"{path}: field 'free_frequency' must list oscillators of the file, got {free!r}")
    ranges = dict(DEFAULT_RANGES)
    given = raw.get("ranges", {})
    if not isinstance(given, Mapping) or set(given) - set(DEFAULT_RANGES):
        raise CouplingError(f"{path}: field 'ranges' may set {sorted(DEFAULT_RANGES)}, got {given!r}")
    ranges.update(given)
    _number(f"{path}: field 'ranges.offset'", ranges["offset"], 0.0, math.pi)
    _number(f"{path}: field 'ranges.coupling'", ranges["coupling"], 0.0, 10.0)
    for key, low, high in (("amplitude", 1e-3, 2.0), ("frequency", 0.05, 10.0)):
        pair = ranges[key]
        if not (isinstance(pair, list | tuple) and len(pair) == 2):
            raise CouplingError(f"{path}: field 'ranges.{key}' must be [low, high], got {pair!r}")
        a, b = (_number(f"{path}: field 'ranges.{key}'", v, low, high) for v in pair)
        if a > b:
            raise CouplingError(f"{path}: field 'ranges.{key}' must have low <= high, got {pair!r}")
    name = raw.get("name", Path(path).stem)
    if not isinstance(name, str):
        raise CouplingError(f"{path}: field 'name' must be a string, got {name!r}")
    return Coupling(
        name=name,
        oscillators=names,
        inputs=tuple(inputs),
        bidir=tuple(bidir),
        groups=tuple(groups),
        fixed={k: float(v) for k, v in fixed.items()},
        free_frequency=tuple(names.index(f) for f in free),
        frequency=_number(f"{path}: field 'frequency'", raw.get("frequency", 1.0), 0.05, 10.0),
        alpha=_number(f"{path}: field 'alpha'", raw.get("alpha", 0.7), 0.0, 100.0),
        ranges=ranges,
        source=str(raw.get("source", "")),
        path=path,
    )


def _load_json(path: str | Path) -> Any:
    p = Path(path)
    if not p.is_file():
        raise CouplingError(f"{p}: {not_a_file(p)}")
    try:
        return json.loads(p.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise CouplingError(f"{p}: not valid JSON ({error})") from None


def read_coupling(path: str | Path) -> Coupling:
    """A coupling file, by path or by name in ``cpg_configs`` (``experiment5``)."""
    p = Path(path)
    if not p.suffix and not p.exists():
        p = CONFIGS / f"{path}.json"
    return parse_coupling(_load_json(p), str(p))


@dataclass(frozen=True)
class PolicyFile:
    """A CPG policy: its coupling and its parameters in [0, 1]^n."""

    coupling: Coupling
    parameters: np.ndarray
    record: Mapping[str, Any]


# what a policy file holds: :meth:`CPGRollouts.policy_record`'s fields and what agents.optimize adds to its best.json
POLICY_FILE_FIELDS = {"policy", "robot", "coupling", "parameters", "score", "objective", "metrics", "iteration", "run"}


def _shown(value: Any) -> str:
    """A value for a message, cut to 60 characters."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def read_policy_file(path: str | Path) -> PolicyFile:
    """A coupling file (parameters at the middle of the box, 0.5) or a policy file written by agents.optimize."""
    raw = _load_json(path)
    if isinstance(raw, Mapping) and "parameters" in raw:
        if raw.get("policy") != "cpg":
            raise CouplingError(f"{path}: field 'policy' must be 'cpg', got {raw.get('policy')!r}")
        unknown = sorted(set(raw) - POLICY_FILE_FIELDS)
        if unknown:
            raise CouplingError(
                f"{path}: unknown field {unknown[0]!r} (a policy file holds {sorted(POLICY_FILE_FIELDS)})"
            )
        if raw.get("robot", "bioloid") != "bioloid":
            raise CouplingError(f"{path}: field 'robot' must be 'bioloid' (the CPG drives its servos), got "
                                f"{raw['robot']!r}")  # fmt: skip
        coupling = parse_coupling(raw.get("coupling"), f"{path} (coupling)")
        values = raw["parameters"]
        if not isinstance(values, list) or len(values) != coupling.dimension:
            raise CouplingError(f"{path}: field 'parameters' must be a list of {coupling.dimension} numbers in [0, 1] "
                                f"(coupling {coupling.name!r}), got {_shown(values)}")  # fmt: skip
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, int | float) or not (math.isfinite(v) and 0 <= v <= 1):
                raise CouplingError(f"{path}: field 'parameters' item {i} must be a number in [0, 1], got {v!r}")
        return PolicyFile(coupling, np.asarray(values, dtype=np.float64), raw)
    coupling = parse_coupling(raw, str(path))
    return PolicyFile(coupling, np.full(coupling.dimension, 0.5), {})


class CPG:
    """The oscillators of a coupling for many simulations at once, with their parameters.

    Args:
        coupling: the coupling configuration.
        parameters: (n, dimension) in [0, 1] (clipped), one row per simulation.
    """

    def __init__(self, coupling: Coupling, parameters: np.ndarray):
        p = np.clip(np.atleast_2d(np.asarray(parameters, dtype=np.float64)), 0.0, 1.0)
        if p.shape[1] != coupling.dimension:
            raise ValueError(f"coupling {coupling.name!r} takes {coupling.dimension} parameters, got {p.shape[1]}")
        self.coupling = c = coupling
        n, k = len(p), len(c.oscillators)
        r = c.ranges
        g = np.asarray(c.groups)
        per_group = p[:, : 4 * c.n_groups].reshape(n, c.n_groups, 4)[:, g, :]  # (n, k, 4)
        self.offset = (2.0 * per_group[:, :, 0] - 1.0) * r["offset"]
        lo, hi = r["amplitude"]
        self.amplitude = lo + per_group[:, :, 1] * (hi - lo)  # sqrt(E)
        self.energy = self.amplitude**2
        w = r["coupling"]
        a, b = (2.0 * per_group[:, :, 2] - 1.0) * w, (2.0 * per_group[:, :, 3] - 1.0) * w
        # coupling matrices A[i, j], B[i, j]: what oscillator i takes from j (its input; the reverse for bidir)
        self.A, self.B = np.zeros((n, k, k)), np.zeros((n, k, k))
        for i, (j, both) in enumerate(zip(c.inputs, c.bidir, strict=True)):
            self.A[:, i, j] += a[:, i]
            self.B[:, i, j] += b[:, i]
            if both:
                self.A[:, j, i] -= a[:, i]
                self.B[:, j, i] -= b[:, i]
        frequency = np.full((n, k), c.frequency)
        if c.free_frequency:
            f_lo, f_hi = r["frequency"]
            frequency[:, list(c.free_frequency)] = (f_lo + p[:, -1] * (f_hi - f_lo))[:, None]
        self.rate = 2.0 * np.pi * frequency  # 1 / tau
        stand = np.array([constants.STAND_ANGLES[s] for s in constants.SERVOS])
        self.base_counts = constants.CENTER + stand / constants.RAD_PER_COUNT
        for servo, count in c.fixed.items():
            self.base_counts[constants.SERVO_INDEX[servo]] = count
        self.columns = np.array([constants.SERVO_INDEX[s] for s in c.oscillators])
        self.sign = np.array([-1.0 if s in MIRRORED else 1.0 for s in c.oscillators])
        self._floor = FLOOR * self.energy
        self.reset()

    def reset(self, rows: np.ndarray | None = None) -> None:
        """Oscillators of ``rows`` (default all) back to x = 0, v = sqrt(E)."""
        if rows is None:
            self.x, self.v = np.zeros_like(self.amplitude), self.amplitude.copy()
            self.time = np.zeros(len(self.amplitude))
        else:
            self.x[rows], self.v[rows], self.time[rows] = 0.0, self.amplitude[rows], 0.0

    def advance(self, seconds: float) -> None:
        """Integrate every row over ``seconds`` in steps of at most 2.5 ms (semi-implicit Euler, below)."""
        steps = max(1, math.ceil(seconds / SUBSTEP - 1e-9))
        hr = (seconds / steps) * self.rate  # h / tau
        alpha, energy, floor = self.coupling.alpha, self.energy, self._floor
        x, v = self.x, self.v
        for _ in range(steps):
            r2 = x * x + v * v
            drive = (self.A * x[:, None, :]).sum(axis=2) + (self.B * v[:, None, :]).sum(axis=2)
            force = drive / np.maximum(r2, floor) - x
            damping = alpha * (r2 - energy) / energy
            # the limit cycle's pull implicitly where it damps (it grows as r^2 / E: stiff for small amplitudes),
            # explicitly where it pumps (at most alpha)
            v = (v + hr * (force - np.minimum(damping, 0.0) * v)) / (1.0 + hr * np.maximum(damping, 0.0))
            x = x + hr * v
        self.x, self.v = x, v
        self.time = self.time + seconds

    def goals(self) -> np.ndarray:
        """Goal counts (n, 16) of the oscillators' present state, clipped to the servos' allowed ranges."""
        goal = np.tile(self.base_counts, (len(self.x), 1))
        angle = self.sign * (self.offset + AMPLITUDE_SCALE * self.x)
        goal[:, self.columns] += angle / constants.RAD_PER_COUNT
        return np.clip(goal, constants.RANGE_LOW, constants.RANGE_HIGH)


class CPGController:
    """A CPG as a policy for Bioloid envs: ``predict`` integrates its oscillators over each control step; its state is
    the oscillators' (x, v) and their time, per env (the oscillators run open loop: no observation enters them).

    Args:
        mode: the env's action mode; control_dt: its control step, s.
        policy: the coupling and parameters (:func:`read_policy_file`).
    """

    def __init__(self, mode, control_dt: float, policy: PolicyFile):
        self.mode, self.control_dt, self.policy = mode, control_dt, policy
        self._k = len(policy.coupling.oscillators)

    def __repr__(self) -> str:
        return f"CPGController({self.policy.coupling.name}, {self.policy.coupling.dimension} parameters)"

    def predict(
        self,
        observation: np.ndarray,
        state: np.ndarray | None = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, np.ndarray]:
        obs = np.asarray(observation)
        single = obs.ndim == 1
        n = 1 if single else len(obs)
        cpg = CPG(self.policy.coupling, np.tile(self.policy.parameters, (n, 1)))
        if state is not None:
            s = np.asarray(state, dtype=np.float64).reshape(n, 2 * self._k + 1)
            cpg.x, cpg.v, cpg.time = s[:, : self._k].copy(), s[:, self._k : 2 * self._k].copy(), s[:, -1].copy()
            if episode_start is not None:
                cpg.reset(np.flatnonzero(np.atleast_1d(np.asarray(episode_start, dtype=bool))))
        action = self.mode.to_action(cpg.goals()).astype(np.float32)
        cpg.advance(self.control_dt)
        new_state = np.concatenate([cpg.x, cpg.v, cpg.time[:, None]], axis=1)
        return (action[0], new_state[0]) if single else (action, new_state)


def cpg_for(env, arg: str = "") -> CPGController:
    """``cpg`` (experiment 5's coupling at mid parameters) or ``cpg:<coupling or policy file>``."""
    robot = env.unwrapped.robot
    if robot.name != "bioloid":
        raise ValueError(f"the CPG drives a Bioloid, not a {robot.name}")
    if robot.action_mode != GOAL:
        raise ValueError(
            f"the CPG needs the servos' whole range (its offsets and amplitudes reach up to 105 deg from the standing "
            f"posture), which the {robot.action_mode!r} action mode does not give: make the env with action_mode="
            f"{GOAL!r}"
        )
    source = arg or str(CONFIGS / f"{DEFAULT_CONFIG}.json")
    p = Path(source)
    if not p.suffix and not p.exists():
        p = CONFIGS / f"{source}.json"
    return CPGController(robot.mode, robot.control_dt, read_policy_file(p))


class CPGRollouts:
    """The CPG as an optimizer's controller (agents/optimize): one parameter vector per simulation.

    Args:
        coupling: the coupling configuration.
        control_dt: the robot's control step, s.
    """

    def __init__(self, coupling: Coupling, control_dt: float):
        self.coupling, self.control_dt = coupling, control_dt
        self.dimension = coupling.dimension
        self._cpg: CPG | None = None

    def start(self, parameters: np.ndarray) -> None:
        self._cpg = CPG(self.coupling, parameters)

    def commands(self) -> np.ndarray:
        """The goals at the oscillators' present state; then the oscillators advance one control step."""
        goals = self._cpg.goals()
        self._cpg.advance(self.control_dt)
        return goals

    def policy_record(self, parameters: np.ndarray) -> dict[str, Any]:
        return {"policy": "cpg", "robot": "bioloid", "coupling": self.coupling.to_dict(),
                "parameters": np.asarray(parameters, dtype=np.float64).tolist()}  # fmt: skip


def optimizer_controller(fields: Mapping[str, Any], robot) -> CPGRollouts:
    """Builder named in ``CONTROLLERS``: a run configuration's ``coupling`` (a name in ``cpg_configs``, a path, or
    the configuration itself) for a Bioloid robot."""
    unknown = set(fields) - {"coupling"}
    if unknown:
        raise ValueError(f"the cpg controller takes the field 'coupling' only, got also {sorted(unknown)}")
    source = fields.get("coupling", DEFAULT_CONFIG)
    if isinstance(source, Mapping):
        coupling = parse_coupling(source, "field 'coupling'")
    elif isinstance(source, str):
        coupling = read_coupling(source)
    else:
        raise ValueError(f"field 'coupling' must name a coupling file or hold one, got {source!r}")
    return CPGRollouts(coupling, robot.control_dt)
