"""The robot contract: what every robot (and every one-joint actuator bench rig) gives tasks, tools and policies.

A robot is built from its MJCF through ``mujoco.MjSpec``; its own configuration (action mode, firmware, options) and
any caller's edits (terrain, calibration effects) change the spec before it compiles. It owns its simulations (one,
or a batch), their reset, its actuators and firmware, its sensors and its telemetry; it knows nothing of rewards.
Everything it returns carries a leading simulation axis, so that a task computes observations, rewards and
termination for one simulation or many with the same code.

A control step::

    robot.command(command)        # (n, command size) in the action mode's physical units: fills the control block
    stable = robot.step()         # (n,) bool: the physics ran natively; False where a simulation went unstable
    readings = robot.read(rngs)   # named arrays (n, ...): senses, pose, power, time, ...

Every robot's telemetry channels include ``time``, ``pos_x``/``_y``/``_z``, ``quat_w``/``_x``/``_y``/``_z`` (its root
body) and ``power``; the plots of evaluate.py rely on them.

The readings every robot gives (tasks rely on them): ``time`` (n,), ``position`` (n, 3) of its root body in the world,
``quaternion`` (n, 4) (w, x, y, z), ``velocity`` (n, 3) of the root in its own frame, ``power`` (n,) the mean
electrical power drawn over the step (W), ``senses`` (n, size) what the robot senses of itself, laid out by
:attr:`Robot.sense_structure`. ``robot.telemetry(readings)`` gives the telemetry channels (n, channels) in the order
of :attr:`Robot.telemetry_channels`, computed only when asked (recording costs nothing when it is off).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import mujoco
import numpy as np

from envs.common.batch import BatchSimulation
from envs.common.calibration import Calibration, CalibrationError, read_calibration
from envs.common.effects import Effect, Param
from envs.common.mujoco_utils import sensor_slices, spec_hash
from envs.common.parameters import ParameterMap, SpecEdit
from envs.common.simulation import Simulation
from envs.common.telemetry import ChannelLimit

# (num_sims, nthread) for robots built inside `batched_robots`: how an env class's own constructor builds the robot of
# its batched env (envs/common/vector.py) without a second copy of its arguments
_BATCH: ContextVar[tuple[int, int | None] | None] = ContextVar("skitter_batch", default=None)


@contextmanager
def batched_robots(num_sims: int, nthread: int | None = None) -> Iterator[None]:
    """Robots built inside this block (with ``num_sims`` left unset) run ``num_sims`` simulations on a
    ``mujoco.batch.Batch`` of ``nthread`` threads."""
    token = _BATCH.set((int(num_sims), nthread))
    try:
        yield
    finally:
        _BATCH.reset(token)


# the shared scene (envs/common/match.py) that robots built inside `hosted_robots` run on, as its players
_HOST: ContextVar[Any] = ContextVar("skitter_host", default=None)


@contextmanager
def hosted_robots(scene: Any) -> Iterator[None]:
    """Robots built inside this block are the players of ``scene`` (a :class:`envs.common.match.SharedScene`): one
    robot object for its ``num_sims`` players, whose simulation is the scene's view of them."""
    token = _HOST.set(scene)
    try:
        yield
    finally:
        _HOST.reset(token)


@dataclass(frozen=True)
class ActionMode:
    """One way to command a robot: named command entries with their physical bounds.

    A normalized action ``a`` in [-1, 1] maps to ``low + (a + 1) / 2 * (high - low)`` per entry.
    """

    name: str
    commands: tuple[str, ...]  # names of the command entries, e.g. ("freq_left", "freq_right", "phase")
    units: tuple[str, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    control_freq: float  # default control rate, Hz
    description: str = ""

    def __post_init__(self) -> None:
        n = len(self.commands)
        if not (len(self.units) == len(self.low) == len(self.high) == n):
            raise ValueError(f"action mode {self.name}: commands, units and bounds differ in length")
        object.__setattr__(self, "_low", np.asarray(self.low, dtype=np.float64))
        object.__setattr__(self, "_span", np.asarray(self.high) - np.asarray(self.low))
        object.__setattr__(self, "_half_span", 0.5 * (np.asarray(self.high) - self._low))

    @property
    def size(self) -> int:
        return len(self.commands)

    def to_command(self, action: np.ndarray) -> np.ndarray:
        """Physical commands from normalized actions (..., size), clipped to [-1, 1] first."""
        return self._low + (np.minimum(np.maximum(action, -1.0), 1.0) + 1.0) * self._half_span

    def to_action(self, command: np.ndarray) -> np.ndarray:
        """Normalized actions from physical commands (the inverse of :meth:`to_command` inside the bounds)."""
        return (2.0 * (np.asarray(command, dtype=np.float64) - self._low) / self._span - 1.0).astype(np.float32)


@dataclass(frozen=True)
class Facts:
    """A robot's physical facts as the model has them, for metrics and checks."""

    mass: float  # kg, everything the robot carries
    length: float  # m, the body length: speeds are also reported in lengths per second
    sides: tuple[str, ...] = ()  # e.g. ("left", "right"); channels named per side end in _<side>
    legs: tuple[str, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PlotGroup:
    """Telemetry channels plotted together (same unit): what evaluate.py draws for a robot.

    With ``minus``, each channel is plotted less its partner (a tracking error: measured minus commanded).
    """

    title: str
    unit: str
    channels: tuple[str, ...]
    scale: float = 1.0  # plotted value = channel x scale (e.g. 1e3 for mN m)
    minus: tuple[str, ...] = ()


GROUND_SENSOR = "ground_contact_"  # prefix of the contact sensors add_ground_contact_sensors adds


def add_ground_contact_sensors(spec: mujoco.MjSpec, root_body: str, feet: Sequence[str]) -> list[str]:
    """Add to ``spec`` contact sensors (MuJoCo's ``contact``, ``data="found"``: the number of contacts) between the
    world body (the floor, a terrain) and every colliding part of the robot under ``root_body`` that is not a foot:
    one per body, or, on a body that carries a foot geom, one per other colliding geom. ``feet`` names bodies (all
    their geoms) and geoms. The sensors' names, in body order; ValueError if a foot is neither a body nor a geom of
    the robot, or a geom beside a foot geom has no name. Everything of the world body counts as ground: a scene
    with walls or goals that a robot may touch without breaking a rule puts them in a body of their own."""
    root = spec.body(root_body)
    if root is None:
        raise ValueError(f"the model has no body {root_body!r}")
    bodies = [root, *root.find_all(mujoco.mjtObj.mjOBJ_BODY)]
    known = {b.name for b in bodies} | {g.name for b in bodies for g in b.geoms}
    unknown = sorted(set(feet) - known)
    if unknown:
        raise ValueError(f"feet {unknown} are neither bodies nor geoms of the robot under {root_body!r}")
    names = []

    def add(name: str, objtype: mujoco.mjtObj, objname: str) -> None:
        spec.add_sensor(
            name=GROUND_SENSOR + name,
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=objtype,
            objname=objname,
            reftype=mujoco.mjtObj.mjOBJ_BODY,
            refname=spec.worldbody.name,
            intprm=[1, 0, 1],  # data "found", no reduction, one match (MuJoCo's contact sensor)
        )
        names.append(GROUND_SENSOR + name)

    for body in bodies:
        colliding = [g for g in body.geoms if g.contype or g.conaffinity]
        if body.name in feet or not colliding:
            continue
        if not any(g.name in feet for g in colliding):
            add(body.name, mujoco.mjtObj.mjOBJ_BODY, body.name)
            continue
        for geom in colliding:
            if geom.name in feet:
                continue
            if not geom.name:
                raise ValueError(f"body {body.name!r} carries a foot geom and an unnamed colliding geom: name it")
            add(geom.name, mujoco.mjtObj.mjOBJ_GEOM, geom.name)
    return names


def standing_band(standing_height: float, belly_clearance: float) -> tuple[float, float]:
    """The height band of a legged robot's root body from its standing pose (its own model): from halfway between
    standing and lying on its belly (``standing_height - belly_clearance / 2``) to twice its standing height.

    ``standing_height`` is the root body's origin above level ground in the robot's ready posture, and
    ``belly_clearance`` how far the lowest point of the root body's geoms is above the ground then. Below the band the
    body has sunk more than half its clearance, as a robot crawling on its knees or belly does; above it, the robot
    has leapt clear of the ground by more than its own standing height, which no gait of these robots does."""
    check_number("standing_height", standing_height, 0, strict=True)
    check_number("belly_clearance", belly_clearance, 0, standing_height, strict=True)
    return standing_height - 0.5 * belly_clearance, 2.0 * standing_height


def check_number(name: str, value: Any, low: float | None = None, high: float | None = None, strict: bool = False):
    """``value`` as a finite float within bounds; ValueError naming the argument and value otherwise (a string or a
    bool too: ``float`` would read ``"1.08"`` and ``True`` as numbers)."""
    if isinstance(value, str | bytes | bool | np.bool_):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if low is not None and (x <= low if strict else x < low):
        raise ValueError(f"{name} must be {'>' if strict else '>='} {low}, got {value!r}")
    if high is not None and x > high:
        raise ValueError(f"{name} must be <= {high}, got {value!r}")
    return x


def check_flag(name: str, value: Any) -> bool:
    """``value`` as a bool: True or False (numpy's too) only; a string such as ``"false"`` would read as true, so it
    is refused with a ValueError naming the argument and value."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise ValueError(f"{name} must be True or False, got {value!r}")


class Robot(ABC):
    """Base of every robot and bench rig. Subclasses set the class attributes and fill in the abstract methods.

    Args:
        action_mode: one of :attr:`action_modes`.
        control_freq: control steps per second (default: the action mode's); a whole number of physics steps each.
        spec_edits: functions applied to the ``MjSpec`` after the robot's own configuration, before it compiles
            (terrain, calibration effects, a bench clamp).
        num_sims: number of simulations stepped together; None: one, or what an enclosing :func:`batched_robots`
            says.
        nthread: threads of the batch (default: the machine's cores).
        batched: run on ``mujoco.batch.Batch`` even for one simulation (default: when ``num_sims > 1``).
        calibration: a calibration file written by ``calibrate.py`` (or a read :class:`Calibration`): its effects
            are added to the nominal spec before it compiles (:meth:`calibration_edits`); the nominal model files are
            not touched.
    """

    name: ClassVar[str]
    action_modes: ClassVar[Mapping[str, ActionMode]]
    root_body: ClassVar[str]
    # the bodies (all their geoms) and geoms that may touch the ground when the robot walks (None: no feet, and
    # :meth:`non_foot_contact` is always False, as for a bench rig); every other colliding body of the robot gets a
    # contact sensor against the ground (the world body's geoms: the floor, a terrain)
    feet: ClassVar[tuple[str, ...] | None] = None
    # (low, high): the band of heights of the root body's origin above the ground under it, m, that the robot holds
    # when it stands or walks (see :func:`standing_band`); None: no band
    height_band: ClassVar[tuple[float, float] | None] = None

    def action_mode_of(self, name: str) -> ActionMode:
        """The action mode ``name`` of :attr:`action_modes` for this robot; a robot whose mode depends on how it is
        built (set before ``Robot.__init__``) overrides this."""
        return self.action_modes[name]

    def __init__(
        self,
        action_mode: str,
        control_freq: float | None = None,
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
        calibration: str | Path | Calibration | None = None,
    ):
        self.calibration = None if calibration is None else self.load_calibration(calibration)
        host = _HOST.get()
        context = _BATCH.get()
        if host is not None:  # a scene's players: their count and batching are the scene's
            num_sims, batched, context = host.num_sims, host.batched, None
        if num_sims is None:
            num_sims, nthread = context if context is not None else (1, nthread)
            batched = context is not None if batched is None else batched
        if isinstance(num_sims, bool) or not isinstance(num_sims, int | np.integer) or num_sims < 1:
            raise ValueError(f"num_sims must be a whole number >= 1, got {num_sims!r}")
        self.batched = num_sims > 1 if batched is None else bool(batched)
        self.nthread = nthread
        if action_mode not in self.action_modes:
            raise ValueError(f"action_mode must be one of {sorted(self.action_modes)}, got {action_mode!r}")
        self.mode = self.action_mode_of(action_mode)
        self.action_mode = action_mode
        freq = (
            self.mode.control_freq
            if control_freq is None
            else check_number("control_freq", control_freq, 0, strict=True)
        )
        spec = mujoco.MjSpec.from_file(str(self.xml_path()))
        timestep = spec.option.timestep
        self.n_substeps = max(1, round(1.0 / (freq * timestep)))
        if abs(self.n_substeps * timestep - 1.0 / freq) > 1e-9 * max(1.0, 1.0 / freq):
            raise ValueError(
                f"control_freq={freq} Hz is not a whole number of {timestep} s physics steps per control step"
            )
        self.control_dt = self.n_substeps * timestep
        self.num_sims = int(num_sims)
        self.configure(spec)
        if self.calibration is not None:
            for edit in self.calibration_edits(self.calibration):
                edit(spec)
        for edit in spec_edits:
            edit(spec)
        player_spec = spec.copy() if host is not None else None  # a scene adds each player's own ground sensors
        ground_sensors = add_ground_contact_sensors(spec, self.root_body, self.feet) if self.feet is not None else []
        # the spec as it compiles, kept uncompiled: the base of compile_with and the source of model_hash (writing
        # the MJCF out to hash it takes longer than compiling it, so only a record that asks for the hash pays)
        self._spec: mujoco.MjSpec | None = spec.copy()
        self._model_hash: str | None = None
        self.model = spec.compile()
        self.sensors: dict[str, slice] = sensor_slices(
            self.model, [self.model.sensor(i).name for i in range(self.model.nsensor)]
        )
        # the contact sensors, added together, hold one value ("found") each in one run of sensordata
        starts = [self.sensors[name].start for name in ground_sensors]
        self._ground_sensors = slice(starts[0], starts[-1] + 1) if starts else None
        if starts and starts != list(range(starts[0], starts[-1] + 1)):
            raise RuntimeError(f"{self.name}: the ground contact sensors are not one run of sensordata")
        self.hosted = host is not None
        self.sim = host.host(self, player_spec) if host is not None else self.make_simulation()
        self.setup()
        self.parameters = self.build_parameters(self.model)
        self.parameters.remember_nominal(self.model)

    @property
    def model_hash(self) -> str:
        """A short content hash of the robot's spec as it compiled (a calibration's effects are in the spec: its own
        hash)."""
        if self._model_hash is None:
            self._model_hash = spec_hash(self._spec)
        return self._model_hash

    def compile_with(self, edits: Sequence[SpecEdit]) -> mujoco.MjModel:
        """The robot's model with ``edits`` applied after everything the robot was built with (its configuration,
        calibration and spec edits), compiled from a copy of its spec: the model a robot built with those edits
        added would hold, without building one. The robot itself is not changed."""
        if self._spec is None:
            raise RuntimeError(f"{self.name}: an unpickled robot does not keep its spec; build the robot anew")
        spec = self._spec.copy()
        for edit in edits:
            edit(spec)
        return spec.compile()

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_model_hash"] = self.model_hash  # an MjSpec does not pickle: the hash travels, the spec does not
        state["_spec"] = None
        return state

    # --- building (subclasses) ------------------------------------------------------------------------------------
    @classmethod
    @abstractmethod
    def xml_path(cls) -> Path:
        """The robot's scene MJCF."""

    @abstractmethod
    def configure(self, spec: mujoco.MjSpec) -> None:
        """Edit the nominal spec for this instance (action mode, firmware, options) before it compiles."""

    @abstractmethod
    def setup(self) -> None:
        """Look up addresses in the compiled model and allocate per-simulation controller state."""

    # --- calibration (subclasses that take calibration files) ---------------------------------------------------
    def calibration_effects(self) -> Mapping[str, Effect]:
        """The catalog effects a calibration file may hold for this robot, by name."""
        raise CalibrationError(f"robot {self.name!r} takes no calibration files")

    def calibration_params(self) -> dict[str, dict[str, Param]]:
        """Effect -> parameter -> its catalog entry (unit and range) of what a calibration file may hold."""
        return {name: {p.name: p for p in e.params} for name, e in self.calibration_effects().items()}

    def load_calibration(self, calibration: str | Path | Calibration) -> Calibration:
        """Read and check a calibration file against this robot's effects (one-line errors naming file and field)."""
        if not isinstance(calibration, str | Path | Calibration):
            raise CalibrationError(f"calibration must be the path of a calibration file, got {calibration!r}")
        cal = calibration if isinstance(calibration, Calibration) else read_calibration(calibration, self.name)
        if cal.robot != self.name:
            raise CalibrationError(f"{cal.path}: field 'robot': the file calibrates {cal.robot!r}, not {self.name!r}")
        cal.check(self.calibration_params())
        return cal

    def calibration_edits(self, calibration: Calibration) -> Sequence[SpecEdit]:
        """A calibration's effects as spec edits, applied after :meth:`configure` and before callers' edits (every
        effect lands in the spec: nothing writes the compiled model)."""
        raise CalibrationError(f"robot {self.name!r} takes no calibration files")

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        """The robot's named physical parameters (see envs/common/parameters.py)."""
        return ParameterMap()

    def make_simulation(self) -> Simulation | BatchSimulation:
        if self.batched:
            return BatchSimulation(self.model, self.n_substeps, self.num_sims, self.nthread)
        if self.num_sims != 1:
            raise ValueError(f"one MjData runs one simulation, not {self.num_sims}: pass batched=True")
        return Simulation(self.model, self.n_substeps)

    # --- the contract ------------------------------------------------------------------------------------------
    @property
    def data(self) -> mujoco.MjData:
        """The ``MjData`` of simulation 0 (the single env's, live)."""
        return self.sim.get_data(0)

    @property
    @abstractmethod
    def facts(self) -> Facts: ...

    @property
    @abstractmethod
    def sense_structure(self) -> dict[str, int]:
        """What ``readings["senses"]`` holds, in order: name -> size."""

    @property
    @abstractmethod
    def telemetry_channels(self) -> dict[str, str]:
        """Telemetry channel name -> unit, in the order of :meth:`telemetry`'s columns."""

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        """What the hardware can read on telemetry channels (their range, their fastest change), from the actuators'
        constants: a real log's sample outside them is dropped as malformed (sysid/logs.py). None declared: {}."""
        return {}

    @property
    def plot_groups(self) -> tuple[PlotGroup, ...]:
        """Channel groups evaluate.py plots for this robot (beside the trajectory and body angles)."""
        return ()

    @abstractmethod
    def reset(
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float, options: Mapping | None
    ) -> None:
        """Reset simulations ``ids`` to the robot's starting pose, perturbed by ``noise`` (see each robot)."""

    @abstractmethod
    def command(self, command: np.ndarray) -> None:
        """Fill the next control block from physical commands (num_sims, mode size) of the current action mode."""

    def step(self, ids: np.ndarray | None = None) -> np.ndarray:
        """Run the control blocks natively (of simulations ``ids``, default all); (num_sims,) bool, False where a
        simulation went unstable (True for those not stepped)."""
        return self.sim.step() if ids is None else self.sim.step(ids)

    @abstractmethod
    def read(self, rngs: Sequence[np.random.Generator], stepped: bool | np.ndarray = True) -> dict[str, np.ndarray]:
        """The readings after the last step (see the module docstring); sensor noise drawn from ``rngs``, one
        generator per simulation. ``stepped``: False (or False per simulation) right after a reset, with no step to
        integrate or draw power over."""

    @abstractmethod
    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        """Telemetry channels (num_sims, channels) after the step that gave ``readings``; the channels the robot
        reads from its sensors are read from ``sensordata`` (num_sims, nsensordata) where given (default: the last
        physics step's)."""

    def physics_telemetry(self, readings: dict[str, np.ndarray]) -> np.ndarray:
        """Telemetry at every physics step of the last control step, (num_sims, n_substeps, channels): what the robot
        reads from its sensors at that physics step (leg angles, motor speeds and torques, contact forces), with the
        physics step's time, and its other channels (clock, commands, battery, IMU, pose, power) at their control-step
        values. The last physics step's row is :meth:`telemetry`'s. A loop over the physics steps of one control step,
        for recording only (``telemetry="physics"``), never in stepping."""
        sub = self.sim.substep_sensordata
        steps = sub.shape[1]
        rows = np.stack([self.telemetry(readings, sub[:, j]) for j in range(steps)], axis=1)
        time = list(self.telemetry_channels).index("time")
        back = float(self.model.opt.timestep) * np.arange(steps - 1, -1, -1)
        rows[:, :, time] = readings["time"][:, None] - back[None, :]
        return rows

    def non_foot_contact(self) -> np.ndarray:
        """(num_sims,) bool: whether anything of the robot but its :attr:`feet` touched the ground in any physics step
        of the last control step (after a reset: in the reset state). Read from contact sensors that MuJoCo
        evaluates at every physics step, so a touch between control steps counts."""
        if self._ground_sensors is None:
            return np.zeros(self.num_sims, dtype=bool)
        return self.sim.substep_sensordata[:, :, self._ground_sensors].max(axis=(1, 2)) > 0.0

    def non_foot_contact_of(self, sim: int) -> bool:
        """:meth:`non_foot_contact` of one simulation, as a bool (the single env's step asks for it)."""
        if self._ground_sensors is None:
            return False
        return bool(self.sim.substep_sensordata[sim, :, self._ground_sensors].max() > 0.0)

    def sensor(self, name: str, sensordata: np.ndarray | None = None) -> np.ndarray:
        """Values of the named sensor in every simulation, (num_sims, dim)."""
        sd = self.sim.sensordata if sensordata is None else sensordata
        return sd[..., self.sensors[name]]

    def set_parameters(self, ids: np.ndarray, values: Mapping[str, float]) -> None:
        """Set named physical parameters for simulations ``ids``; parameters not named return to nominal."""
        if self.hosted:
            raise ValueError(f"{self.name}: robots on a shared scene take no per-robot physical parameters")
        unknown = set(values) - set(self.parameters.names())
        if unknown:
            raise ValueError(f"{self.name}: unknown parameters {sorted(unknown)}; known: {self.parameters.names()}")
        for name, value in values.items():
            self.parameters.check_range(name, float(value), float(value), f"{self.name} parameters")
        if self.batched:
            for i in ids:
                self.parameters.apply(lambda name, i=i: self.sim.expand(name)[i], values)
            if any(p.setconst for p in self.parameters):
                self.sim.set_const(np.asarray(ids))
        elif self.parameters.apply(lambda name: getattr(self.model, name), values):
            mujoco.mj_setConst(self.model, self.sim.data)
        for p in self.parameters:
            if p.attribute is not None:
                getattr(self, p.attribute)[ids] = float(values.get(p.name, p.nominal))
        self.parameters_changed(np.asarray(ids))

    def parameters_changed(self, ids: np.ndarray) -> None:  # noqa: B027 (an optional hook)
        """Refresh what the robot keeps from model fields (motor constants...) for simulations ``ids``."""

    def field(self, name: str) -> np.ndarray:
        """A model field's values in every simulation, (num_sims, ...): per-simulation ones where a batch holds them."""
        if self.batched:
            values = self.sim.batch.expanded(name)
            if values is not None:
                return values
        return np.broadcast_to(getattr(self.model, name), (self.num_sims, *getattr(self.model, name).shape))

    def metadata(self) -> dict[str, Any]:
        """The robot's part of a telemetry or results record."""
        return {
            "robot": self.name,
            "model_hash": self.model_hash,
            "calibration": None if self.calibration is None else self.calibration.path,
            "action_mode": self.action_mode,
            "control_dt": self.control_dt,
            "physics_dt": float(self.model.opt.timestep),
        }
