"""Replaying logs in the model: segments, batched rollouts of candidate settings, residuals on the noise scale.

A log is cut into segments of about a second (multiple shooting): each starts from the measured joint state, so one
early divergence does not dominate the error. A *setting* is a flat dict of effect parameters (``effect.param``);
the robot's adapter turns a setting into a model (spec edits or field writes), controls (delay, deadband, supply),
and predicted channels (sensor bias and gain). Every (setting, segment) pair is one row of a single
``mujoco.rollout`` call on the machine's cores: candidate settings of a fit, of a finite-difference Jacobian, or of
a grid run together.

Residuals are measured minus predicted, divided by each channel's noise level (so 1 is the noise floor).

A segment's measured start is itself noisy (an encoder's noise, a speed from differences), and an error in it grows
along the segment. So the start is refined, not trusted: the adapter names the start's uncertain coordinates and
their standard deviations, the prediction's sensitivity to each is measured at an *anchor* setting (one batched
rollout, a perturbed start per row), and every residual is the least-squares remainder after the best correction
of the start, with the correction itself as residual rows against its prior (in units of its standard deviation).
The correction is linear in the residual (variable projection), so it costs no rollout per candidate; with its
prior rows counted, the expected cost of the true model is still one per data sample.
"""

from __future__ import annotations

import itertools
import math
import re
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import mujoco
import numpy as np
import pandas as pd
from mujoco import rollout

from envs.common.batch import default_threads
from envs.common.effects import Effect, Param, Setting
from envs.common.robot import Robot
from envs.common.telemetry import ChannelLimit
from sysid.logs import Log, LogError, white_noise

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS
SENSITIVITY_CACHE = 768  # segments' start sensitivities kept (anchors x segments) before the cache starts over
MODEL_CACHE = 2048  # compiled models kept per adapter (settings x segment keys) before the cache starts over
CTRL_SPEC = mujoco.mjtState.mjSTATE_CTRL.value
LEAD_SECONDS = 0.25  # s of the log kept before each segment: the commands a delayed actuator still acts on
TIME_TOLERANCE = 1e-9  # s: sample and physics times that differ by rounding alone are the same time
UNSTABLE_RESIDUAL = 1e3  # noise levels: the residual of a sample a numerically unstable rollout did not reach
DECISION_BURN_IN = 1  # segments replayed before each run of decision segments (Problem.decisions)
FLOOR_TWINS = 3  # noisy readings of the model's twin of a log whose replay measures the replay floor


@dataclass
class Segment:
    """A piece of a log replayed from its measured start.

    Attributes:
        log: the log's path; index: the segment's number in it; t0: its start time in the log, s.
        source: the log's place in its problem's logs (set by Problem; two logs may share a path).
        steps: physics step (from the segment's start) of each sample; samples: the samples' rows in the log.
        measured: the compared channels at the samples, (samples, channels).
        data: the log's columns over the segment (commands, start values), as arrays.
    """

    log: str
    index: int
    t0: float
    steps: np.ndarray
    samples: np.ndarray
    measured: np.ndarray
    data: dict[str, np.ndarray] = field(default_factory=dict)
    sigma: dict[str, float] = field(default_factory=dict)  # the channels' noise levels (set by Problem)
    lead: dict[str, np.ndarray] = field(default_factory=dict)  # the log's rows just before t0 (for delays)
    carry_steps: int = 0  # physics steps to the next segment's start, if it follows on directly
    n_steps: int = 0  # physics steps rolled out (the same for every segment of a problem)
    cache: dict = field(default_factory=dict, repr=False)  # what an adapter derives once per segment
    source: int = 0

    def command_at(self, column: str, physics_times: np.ndarray, delay: float = 0.0) -> np.ndarray:
        """The log's ``column`` held (zero-order) from each sample to the next, at physics times (s from t0),
        ``delay`` seconds late: before the segment's first sample, the log's samples before it (``lead``)."""
        lead = self.lead.get("time", np.zeros(0))
        t = np.concatenate([lead, self.data["time"]]) - self.t0 - TIME_TOLERANCE  # a sample acts from its step
        values = np.concatenate([self.lead.get(column, np.zeros(0)), self.data[column]])
        index = np.searchsorted(t, physics_times - delay, side="right") - 1
        return values[np.clip(index, 0, len(values) - 1)]


class Adapter(ABC):
    """How calibration replays one robot's logs. Each robot (and bench rig) provides one in its folder.

    Class attributes:
        name: the robot's name for ``calibrate.py --robot``.
        channels: the compared channels, name -> unit.
        commands: the columns a log must hold to be replayed (besides ``channels`` and ``time``).
        optional: the columns it reads where a log holds them (a servo's goal, which is fitted where it is not).
        context: the log columns the residual diagnostics relate the residual to (``velocity``, ``command``,
            ``load``, ``supply``, ``phase``), each one column or a dict channel -> column (sysid/diagnostics.py).
    """

    name: str
    robot: str = ""  # the robot's name in calibration files (default: ``name``)
    channels: Mapping[str, str]
    commands: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()
    segment_seconds: float = 1.0
    context: Mapping[str, str | Mapping[str, str]] = {}  # log columns for the diagnostics
    carry_over: bool = True  # a segment starts from the previous one's end, its measured coordinates overwritten
    replay_floor: bool = False  # add what replay cannot match on the model's own data to the noise (see Problem)
    fd_step: float = 1e-3  # finite-difference step, a fraction of each parameter's range (larger for chaotic models)
    rough_cost: bool = False  # the cost is rough at small scales (contacts): fit derivative-free (sysid/fit.py)
    # the fits' objective: least squares (None) or, where a segment's replay can part from the log for good (a leg
    # that stalls in one and runs on in the other: contacts), the soft-L1 loss with this scale in noise levels, so
    # that such a segment weighs as a few samples far out rather than as its squared error (see Residual.objective)
    loss_scale: float | None = None
    # the fits' objective where segments diverge for good by different amounts: each segment's residual variance its
    # own, at least the noise level's (a profile likelihood; see Residual.objective). Decisions (the information
    # criterion, the held-out gain) then read the same likelihood, since it is one
    segment_variance: bool = False
    # stepwise selection with refitting (sysid/select.py): each candidate fitted with the effects already kept, the
    # ranking's score test taking them as refitted, and the backward step. None: where fits are least squares
    # (not ``rough_cost``); a robot whose derivative-free fits are cheap enough to fit every candidate jointly with
    # the kept effects says True
    stepwise: bool | None = None
    # the breadth of the search for effects that help only together (sysid/select.py: seeds, width, beam); a robot
    # whose every fit costs seconds of rollouts narrows it
    chain_search: tuple[int, int, int] = (3, 3, 2)
    # the fewest points of the ranking's grid across an effect's range (None: sysid/select.py's SCORE_GRID and
    # SCORE_GRID_SMOOTH); a robot whose cost has basins narrower than those grids' spacing raises it
    score_grid: int | None = None
    # a controller that closes the loop at its own rate (a PD run by the robot's code once per control step): the
    # physics steps between its updates (0: none, every control is known before the rollout; see :meth:`feedback`)
    feedback_steps: int = 0
    # physics steps by which a log's reading is older than its time stamp (see :meth:`sample_steps`)
    sample_lag: int = 0
    # the first segment of a log (or of a window of one) starts from a guessed body state, since the log does not
    # hold it: with ``burn_in`` it is replayed only to carry its end over, and its residual is not counted
    burn_in: bool = False
    # the measurements of :meth:`measure_log` that describe what a log ran under (the load on the legs, the ground),
    # not the robot: a held-out log whose interval lies outside every training log's ran under conditions the
    # training did not hold, and the report names it (sysid.measurement.compare_conditions)
    condition_quantities: tuple[str, ...] = ()
    # a log too short for segments of ``segment_seconds`` is cut into shorter ones, each of at least this many of
    # its strides (:meth:`stride_seconds`), so that a short run still holds a burn-in and a scored segment; 0: never
    min_segment_strides: float = 0.0
    # how a synthetic case records its training and its held-out logs (sysid/cases.py): None, the generator's own
    # log of the case (one run of ``synth.SECONDS``); or (runs, seconds), this many runs, each from rest, of this many
    # seconds. A robot whose unlogged body, carried from segment to segment, parts from the log within seconds even
    # in the true model's replay (the xJüs: a stumble in one replay and not in the next) records several short runs,
    # each replayed from a body at rest, as a user should log it
    runs: tuple[int, float] | None = None

    nominal_robot: Robot  # the robot as the replay runs it, with no effect (set by the adapter): build's base

    def __init__(self) -> None:
        self._models: dict[tuple, mujoco.MjModel] = {}
        self.robot = self.robot or self.name

    # --- what the robot offers ------------------------------------------------------------------------------------
    @abstractmethod
    def effects(self) -> dict[str, Effect]:
        """The catalog effects this robot can apply and its channels can observe, by name."""

    def catalog(self) -> dict[str, Effect]:
        """The effects calibration may choose (the generator's out-of-catalog ones left out), by name."""
        return {k: e for k, e in self.effects().items() if e.catalogued}

    def catalog_nominal(self) -> dict[str, float]:
        """Every catalog parameter at its nominal value, flat (``effect.param`` -> value): the nominal model."""
        return {k: v for e in self.catalog().values() for k, v in e.nominal().items()}

    def nuisance(self, logs: Sequence[Log]) -> dict[str, Param]:
        """Parameters fitted with every candidate but never reported as effects (e.g. an unlogged servo goal)."""
        return {}

    def required(self) -> tuple[str, ...]:
        return (*self.commands, *self.channels)

    def reads(self) -> frozenset[str]:
        """Every log column the calibration of this robot reads: ``time``, the required ones, the optional ones and
        those its residual diagnostics relate the residual to (``context``)."""
        context = [c for v in self.context.values() for c in ([v] if isinstance(v, str) else v.values())]
        return frozenset(("time", "episode", *self.required(), *self.optional, *context))

    def known_effects(self) -> dict[str, dict[str, Param]]:
        """effect -> parameter -> its catalog entry (unit and range), of the catalog effects (for checking
        calibration files)."""
        return {n: {p.name: p for p in e.params} for n, e in self.catalog().items()}

    def channel_limits(self) -> dict[str, ChannelLimit]:
        """What the robot's hardware can read on each channel (range, fastest change): a log's sample beyond them is
        dropped as malformed when the log is read (``sysid.logs.drop_impossible``). The robot's own declaration."""
        return dict(self.nominal_robot.channel_limits)

    def check_logs(self, logs: Sequence[Log]) -> None:  # noqa: B027 (optional hook)
        """Robot-specific checks of logs before anything runs (raise ``LogError`` naming file, row and column)."""

    @property
    @abstractmethod
    def physics_dt(self) -> float: ...

    # --- replay ---------------------------------------------------------------------------------------------------
    def stride_seconds(self, log: Log) -> float | None:
        """The period of the log's stride, for a robot whose segments may shrink to a number of strides
        (``min_segment_strides``); None where the log has none (default)."""
        return None

    def segment_length(self, log: Log) -> float:
        """The length of the log's segments: ``segment_seconds``, or for a log too short to hold its burn-in and
        one scored segment of that length, as long as the log allows but at least ``min_segment_strides`` strides."""
        needed = 2 if self.burn_in else 1
        stride = self.stride_seconds(log) if self.min_segment_strides > 0 else None
        if stride is None or log.duration >= needed * self.segment_seconds:
            return self.segment_seconds
        # a hair over the share, so that the last segment holds the log's last sample
        return max(log.duration / needed * (1 + 1e-9), self.min_segment_strides * stride)

    def shortest_log(self, log: Log) -> tuple[float, str]:
        """The shortest log of this kind the replay can use (s), and why: one segment to score, after the
        burn-in segment where the robot has one."""
        needed = 2 if self.burn_in else 1
        stride = self.stride_seconds(log) if self.min_segment_strides > 0 else None
        what = "a burn-in segment and a scored one" if self.burn_in else "one segment"
        if stride is None:
            return needed * self.segment_seconds, f"{what} of {self.segment_seconds:g} s"
        shortest = needed * self.min_segment_strides * stride
        strides = f"{self.min_segment_strides:g} stride" + ("" if self.min_segment_strides == 1 else "s")
        return shortest, f"{what}, each of {strides} of {stride:.3g} s"

    def check_length(self, logs: Sequence[Log]) -> None:
        """Each log holds a segment to score (LogError naming the log, its length and the shortest usable)."""
        for log in logs:
            scored = len(self.segments(log)) - (1 if self.burn_in else 0)
            if scored < 1:
                shortest, why = self.shortest_log(log)
                if log.duration >= shortest:  # long enough, but its samples lie too far apart for a segment
                    step = float(np.median(np.diff(log.time)))
                    raise LogError(
                        f"{log.path}: its samples lie {step:.3g} s apart, so a {self.segment_length(log):.3g} s "
                        f"segment holds fewer than 3 of them ({log.duration:.3g} s in all): is its time column in "
                        "the unit the file or its column map says?"
                    )
                raise LogError(f"{log.path}: {log.duration:.3g} s is too short to replay; the shortest usable log is "
                               f"{shortest:.3g} s ({why})")  # fmt: skip

    def segments(self, log: Log) -> list[Segment]:
        """Cut a log into segments of about :meth:`segment_length` (a shorter tail, under half a segment, is left
        out). A segment starts at its first sample; ``carry_steps`` is the number of physics steps to the next
        segment's start when that follows on directly (0 otherwise)."""
        t = log.time
        h = self.physics_dt
        columns = {
            c: log.df[c].to_numpy(dtype=float) for c in log.df.columns if np.issubdtype(log.df[c].dtype, np.number)
        }
        length = self.segment_length(log)
        edges = np.arange(t[0], t[-1] - 0.5 * length + 1e-12, length)
        out: list[Segment] = []
        for index, start in enumerate(edges):
            rows = np.flatnonzero((t >= start) & (t < start + length))
            if len(rows) < 3:
                continue
            t0 = float(t[rows[0]])
            steps = np.round((t[rows] - t0) / h).astype(int)
            measured = np.column_stack([columns[c][rows] for c in self.channels])
            data = {c: v[rows] for c, v in columns.items()}
            before = np.flatnonzero((t >= t0 - LEAD_SECONDS) & (t < t0))
            lead = {c: v[before] for c, v in columns.items()}
            out.append(Segment(log.path, index, t0, steps, rows, measured, data, lead=lead))
        for seg, following in itertools.pairwise(out):
            if following.index == seg.index + 1:
                seg.carry_steps = round((following.t0 - seg.t0) / h)
        for seg in out:
            seg.n_steps = max(int(seg.steps[-1]) + 1, seg.carry_steps)
        return out

    @staticmethod
    def acting(values: np.ndarray) -> np.ndarray:
        """A logged command as it acts from each sample on, for telemetry that stamps a row with the command of the
        control step that *ended* at its time (envs/common/env.py records after stepping): row k + 1's, the last
        row's held."""
        return np.append(values[1:], values[-1:]) if len(values) > 1 else values

    @staticmethod
    def attach(log: Log, segments: Sequence[Segment], columns: Mapping[str, np.ndarray]) -> None:
        """Add per-sample arrays of a log (one value per row) to its segments' data and to their lead-in samples."""
        t = log.time
        for seg in segments:
            lead = np.searchsorted(t, seg.lead.get("time", np.zeros(0)))
            for column, values in columns.items():
                seg.data[column] = values[seg.samples]
                seg.lead[column] = values[lead]

    def physics_times(self, segment: Segment) -> np.ndarray:
        """The time of every physics step of a segment's rollout, s from its start."""
        return np.arange(segment.n_steps) * self.physics_dt

    def structure(self, setting: Setting) -> tuple:
        """The part of a setting that changes the model's sizes (a joint or actuator added): rows of one batched
        rollout share it. The catalog's structural effects: backlash's play (its gap, 0 when absent), a terrain
        bump (its height) and a disturbance actuator (present or not)."""
        gap = round(float(setting.get("backlash.gap", 0.0)), 6)
        return (gap if gap > 1e-6 else 0.0, round(float(setting.get("terrain_bump.height", 0.0)), 6),
                setting.get("disturbance.torque", 0.0) > 0)  # fmt: skip

    def structural_edits(
        self,
        setting: Setting,
        backlash: Callable[[float], Callable[[mujoco.MjSpec], None]] | None = None,
        bump: Callable[[float], Callable[[mujoco.MjSpec], None]] | None = None,
        disturbance: Callable[[mujoco.MjSpec], None] | None = None,
    ) -> list[Callable[[mujoco.MjSpec], None]]:
        """The spec edits of a setting's structural effects (:meth:`structure`), from the robot's own makers of
        each: ``backlash(gap)``, ``bump(height)`` and the ``disturbance`` edit (the first three entries of
        :meth:`structure`, which an adapter extends with structure its own edits add)."""
        gap, height, disturbed = Adapter.structure(self, setting)
        return [*([backlash(gap)] if gap and backlash else []), *([bump(height)] if height and bump else []),
                *([disturbance] if disturbed and disturbance else [])]  # fmt: skip

    @abstractmethod
    def spec_edits(self, setting: Setting) -> list[Callable[[mujoco.MjSpec], None]]:
        """A setting's effects as ``MjSpec`` edits, applied to the nominal spec before it compiles (nothing writes
        a compiled model: what runs is what the spec says, and ``mujoco.rollout`` replays it from ``ctrl``)."""

    def build(self, edits: Sequence[Callable[[mujoco.MjSpec], None]]) -> mujoco.MjModel:
        """The robot's model compiled with ``edits`` after its own configuration: a copy of the nominal robot's spec
        (``nominal_robot``, which the adapter builds once) with the edits, compiled (``Robot.compile_with``), byte for
        byte the model of a robot built with them, without building one."""
        return self.nominal_robot.compile_with(edits)

    @abstractmethod
    def initial_state(
        self, model: mujoco.MjModel, data: mujoco.MjData, segment: Segment, setting: Setting, carried: bool = False
    ) -> None:
        """Put ``data`` at the segment's measured start: ``data`` is fresh from ``mj_resetData`` or, ``carried``,
        holds the previous segment's end state; write the coordinates the log measures (and, fresh, estimates of
        the others)."""

    @abstractmethod
    def controls(self, model: mujoco.MjModel, segment: Segment, setting: Setting) -> np.ndarray:
        """The control of every physics step of the segment, (segment.n_steps, nu)."""

    @abstractmethod
    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        """Predicted channels at the segment's samples from the sensor data at their physics steps."""

    def feedback(  # noqa: B027 (optional hook: no update by default)
        self, ctrl: np.ndarray, sensordata: np.ndarray, rows: Sequence[tuple[Setting, Segment]], step: int
    ) -> None:
        """With ``feedback_steps``: the controller's update for the next ``feedback_steps`` physics steps of every
        row, written into ``ctrl`` (rows, steps, nu; it holds :meth:`controls`' values) from ``sensordata`` (rows,
        nsensordata), the sensors as the robot reads them at the update (computed at the physics step before it),
        ``step`` the update's physics step from the segment's start. Vectorized over the rows: Python runs once per
        control step of all the rollouts together, never per physics step. Default: no update (the controls
        computed before the rollout stand), as for an adapter with ``feedback_steps = 0``, which is never asked."""

    def sample_steps(self, steps: np.ndarray, n_steps: int) -> np.ndarray:
        """The physics step whose sensor data a sample reports, for samples at ``steps`` from a rollout's start: the
        step itself (its sensors, computed at its start, are the state at the sample's time), or ``sample_lag``
        steps before it for a robot whose telemetry stamps a reading taken that much earlier."""
        return np.clip(steps - self.sample_lag, 0, n_steps - 1)

    def initial_uncertainty(
        self, model: mujoco.MjModel, segment: Segment, setting: Setting
    ) -> list[tuple[str, int, float]]:
        """The uncertain coordinates of a segment's start: (``"qpos"`` or ``"qvel"``, address, standard deviation)."""
        return []

    def segment_edits(self, segment: Segment, setting: Setting) -> tuple[tuple, list[Callable[[mujoco.MjSpec], None]]]:
        """What a segment's model holds beyond the setting's (a controller's gains for the segment's battery
        voltage), as a key (segments with equal keys share a model) and spec edits; default nothing."""
        return (), []

    def acts_on(self, effect: Effect, channel: str) -> bool:
        """Whether a catalog effect acts on a compared channel (a report's trace of what remains asks only those).
        Default: an effect on no target acts on every channel; one with a target, on the channel it names and on
        those its target ends or starts (``left``: ``duty_left``; ``current``: ``current_FL``)."""
        t = effect.target
        return not t or channel == t or channel.endswith("_" + t) or channel.startswith(t + "_")

    def measure_log(self, log: Log, seed: int = 0) -> list:
        """What the log measures by itself, before any replay (``sysid.measurement.Measurement`` records beside the
        nominal model's values: ``python -m sysid.measure``, and a section of every calibration report); ValueError
        naming the log where it holds too little. Default: nothing."""
        return []

    def effect_readings(self, measurements: Sequence) -> list:
        """The measurements of :meth:`measure_log` that read a catalog effect's parameter directly
        (``sysid.measurement.EffectReading`` records: ``python -m sysid.measure --calibration-out`` writes them as a
        calibration). Default: none."""
        return []

    def report_extra(self, result) -> dict:
        """Robot-specific additions to the report: ``{"sections": {title: markdown}, ...}`` (e.g. channels
        compared as distributions)."""
        return {}

    def model_for(self, setting: Setting, segment: Segment | None = None) -> mujoco.MjModel:
        """The compiled model of a setting (of one segment, with :meth:`segment_edits`); compiled once per distinct
        setting and segment key (a compile takes milliseconds, a segment's rollout far longer)."""
        extra_key, extra = self.segment_edits(segment, setting) if segment is not None else ((), [])
        key = (tuple(sorted((k, round(float(v), 12)) for k, v in setting.items())), extra_key)
        model = self._models.get(key)
        if model is None:
            if len(self._models) >= MODEL_CACHE:
                self._models.clear()
            model = self._models[key] = self.build([*self.spec_edits(setting), *extra])
        return model

    # --- synthetic data (sysid/synth.py) -----------------------------------------------------------------------------
    def excite(self, seconds: float, rng: np.random.Generator):
        """A command table (``time``, the commands, the channels' start values) that excites the robot."""
        raise NotImplementedError(f"{self.name} has no excitation for synthetic logs")

    def synth_noise(self) -> dict[str, float]:
        """The sensor noise (standard deviation per channel) of synthetic logs."""
        raise NotImplementedError

    def synth_meta(self) -> dict:
        """What a synthetic log's record holds besides the noise (a firmware's gains, for example)."""
        return {}

    def measure(self, channel: str, values: np.ndarray) -> np.ndarray:
        """What the sensor reports of a noisy value (rounding to counts, for example)."""
        return values

    def recorded_noise(self, noise: dict[str, float]) -> dict[str, float]:
        """The noise level a synthetic log records per channel (its sensor noise, and rounding)."""
        return dict(noise)

    # --- noise ------------------------------------------------------------------------------------------------------
    def noise(self, log: Log) -> dict[str, float]:
        """Each channel's noise level: the log's own record if it has one (synthetic data), else the larger of its
        quantisation step / sqrt(12) and a robust estimate of white noise from second differences
        (:func:`~sysid.logs.white_noise`). Where most second differences are zero (a motor at rest, a held reading)
        a window takes its whole file's estimate; failing that, a channel whose step the reader does not know takes
        the smallest step between its values as its quantisation. A channel that never changes (a servo held
        still) shows no noise of its own: it takes the median level of the log's other channels in its unit (the
        same kind of sensor), and with none, it is refused, naming the log and channel (its errors would be divided
        by nothing)."""
        recorded = log.meta.get("noise_sigma") or {}
        quantisation = log.meta.get("quantisation") or {}
        out: dict[str, float] = {}
        still = []
        for c in self.channels:
            if c in recorded:
                out[c] = float(recorded[c])
                continue
            x = log.df[c].to_numpy(dtype=float)
            white = white_noise(x)
            if white <= 0.0:  # at rest or held in this window: the whole file's, if this is a window of one
                white = float((log.meta.get("file_white") or {}).get(c, 0.0))
            q = float(quantisation.get(c, 0.0)) / math.sqrt(12)
            if white <= 0.0 and q <= 0.0:
                steps = np.abs(np.diff(x))
                steps = steps[steps > 1e-9 * max(float(np.max(np.abs(x))), 1e-300)] if len(x) else steps
                if not len(steps):
                    still.append(c)
                    continue
                q = float(np.min(steps)) / math.sqrt(12)
            out[c] = max(white, q)
        for c in still:
            unit = self.channels[c]
            kin = [v for k, v in out.items() if self.channels.get(k) == unit]
            if not kin:
                x = log.df[c].to_numpy(dtype=float)
                raise LogError(
                    f"{log.path}: channel {c!r} reads {x[0] if len(x) else float('nan'):g} throughout: its noise "
                    "level cannot be measured, so no error on it can be; give a stretch of the log where it moves"
                )
            out[c] = float(np.median(kin))
        return {c: out[c] for c in self.channels}


def setting_key(setting: Setting) -> tuple:
    """A setting as a cache key: its values by name."""
    return tuple(sorted(setting.items()))


def _missing(keys: Sequence[tuple], settings: Sequence[Setting], cache: Mapping) -> dict[tuple, Setting]:
    """The settings whose keys the cache lacks, each once, in the order first asked for."""
    out: dict[tuple, Setting] = {}
    for key, setting in zip(keys, settings, strict=True):
        if key not in cache:
            out.setdefault(key, setting)
    return out


MODEL_SIZE_FIELDS = tuple(name for name in dir(mujoco.MjModel) if re.fullmatch(r"n[a-zA-Z0-9_]+", name))


def model_sizes(model: mujoco.MjModel) -> tuple[int, ...]:
    """Every size of a model (``nq``, ``ntendon``, ``nconmax``...): models alike in all of them can share MjData."""
    return tuple(v for v in (getattr(model, name) for name in MODEL_SIZE_FIELDS) if isinstance(v, int))


def run_rollout(
    runner: rollout.Rollout,
    adapter: Adapter,
    models: Sequence[mujoco.MjModel],
    datas: Sequence[mujoco.MjData],
    state: np.ndarray,
    control: np.ndarray,
    rows: Sequence[tuple[Setting, Segment]],
    start_sensordata: np.ndarray,
    keep_states: bool = False,
) -> tuple[np.ndarray | None, np.ndarray]:
    """Roll out rows (each a model, a start state, the controls of every physics step) natively: in one call when
    every control is known beforehand, or, for an adapter whose controller closes the loop at its own rate
    (``feedback_steps``), in chunks of that many physics steps, the controller's update between them computed for
    every row at once (:meth:`Adapter.feedback`) from the sensors the chunk before left. Returns the states after
    every physics step (``keep_states``) and the sensor data of every physics step, (rows, steps, ...)."""
    n, steps = control.shape[:2]
    m0 = models[0]
    # NaN where a rollout went numerically unstable: MuJoCo warns, resets and stops that row, leaving the rest unset
    sensordata = np.full((n, steps, m0.nsensordata), np.nan)
    states = np.full((n, steps, state.shape[1]), np.nan) if keep_states or adapter.feedback_steps else None
    if not adapter.feedback_steps:
        runner.rollout(models, datas, state, control, control_spec=CTRL_SPEC, initial_warmstart=np.zeros((n, m0.nv)),
                       sensordata=sensordata, state=states)  # fmt: skip
        return states, sensordata
    k = adapter.feedback_steps
    models = list(models)
    current = np.ascontiguousarray(state, dtype=np.float64)
    sensors = start_sensordata
    warmstart = np.zeros((n, m0.nv))
    for begin in range(0, steps, k):
        end = min(begin + k, steps)
        width = end - begin
        chunk = np.ascontiguousarray(control[:, begin:end])
        adapter.feedback(chunk, sensors, rows, begin)
        control[:, begin:end] = chunk
        # contiguous outputs of the chunk's own (rollout would copy strided views); checks skipped: shapes are ours
        out_states = np.full((n, width, state.shape[1]), np.nan)
        out_sensors = np.full((n, width, m0.nsensordata), np.nan)
        runner.rollout(models, datas, current, chunk, control_spec=CTRL_SPEC, skip_checks=True, nstep=width,
                       initial_warmstart=warmstart, state=out_states, sensordata=out_sensors)  # fmt: skip
        states[:, begin:end], sensordata[:, begin:end] = out_states, out_sensors
        current, sensors = np.ascontiguousarray(out_states[:, -1]), out_sensors[:, -1]
    return states, sensordata


@dataclass
class Residual:
    """One segment's residual under one setting: ``data`` (samples, channels) is measured minus predicted over the
    noise, after the start's correction ``prior`` (one entry per uncertain coordinate, in its standard deviations)."""

    data: np.ndarray
    prior: np.ndarray
    loss_scale: float | None = None  # the adapter's (see Adapter.loss_scale)
    segment_variance: bool = False  # the adapter's (see Adapter.segment_variance)

    def flat(self) -> np.ndarray:
        return np.concatenate([self.data.ravel(), self.prior])

    def flat_objective(self) -> np.ndarray:
        """Residuals whose sum of squares is :attr:`objective` (each sample's sign times the root of its loss), for
        least-squares solvers: :meth:`flat` without a loss scale."""
        if self.segment_variance:
            squares = float(np.sum(self.data * self.data))
            scale = math.sqrt(self._segment_loss / squares) if squares > 0 else 1.0
            return np.concatenate([(self.data * scale).ravel(), self.prior])
        if self.loss_scale is None:
            return self.flat()
        return np.concatenate([(np.sign(self.data) * np.sqrt(self._loss)).ravel(), self.prior])

    @cached_property
    def cost(self) -> float:
        """Sum of squares: what the errors (RMS over the noise) are computed from."""
        return float(np.sum(self.data * self.data) + self.prior @ self.prior)

    @cached_property
    def objective(self) -> float:
        """What a fit minimizes: the cost, or, with a loss scale c, the soft-L1 loss 2 c^2 (sqrt(1 + (r/c)^2) - 1)
        summed over the samples (scipy's ``soft_l1``: r^2 within the noise, 2 c |r| far out; convex, so it keeps
        least squares' optimum where the model is right and the residual is noise), plus the prior's squares.

        With ``segment_variance``, the segment's residual is taken as Gaussian with a variance of its own, at least
        the noise level's (1): its -2 log-likelihood, that variance profiled out, is n c for a mean square c <= 1 (least
        squares) and n (1 + log c) above (each sample at the variance c), plus the prior's squares. A segment whose
        replay parted from the log for good (the body carried into a stumble the log's robot did not take) then
        weighs by the log of its error, not the error itself: a true model's few chaotic segments do not outweigh
        what the others show."""
        if self.segment_variance:
            return float(self._segment_loss + self.prior @ self.prior)
        if self.loss_scale is None:
            return self.cost
        return float(np.sum(self._loss) + self.prior @ self.prior)

    @cached_property
    def _segment_loss(self) -> float:
        n = self.data.size
        c = float(np.sum(self.data * self.data)) / max(n, 1)
        return n * c if c <= 1.0 else n * (1.0 + math.log(c))

    @cached_property
    def _loss(self) -> np.ndarray:
        """Each sample's soft-L1 loss (written out: scipy keeps its losses private to ``least_squares``)."""
        c = self.loss_scale
        return 2.0 * c * c * (np.sqrt(1.0 + (self.data / c) ** 2) - 1.0)


def flatten(residuals: Sequence[Residual]) -> np.ndarray:
    return np.concatenate([r.flat() for r in residuals])


def flatten_objective(residuals: Sequence[Residual]) -> np.ndarray:
    return np.concatenate([r.flat_objective() for r in residuals])


def total_cost(residuals: Sequence[Residual]) -> float:
    return float(sum(r.cost for r in residuals))


def total_objective(residuals: Sequence[Residual]) -> float:
    return float(sum(r.objective for r in residuals))


def data_size(residuals: Sequence[Residual]) -> int:
    return int(sum(r.data.size for r in residuals))


class Problem:
    """The logs of one robot, cut into segments, replayed under candidate settings.

    Args:
        adapter: the robot's adapter.
        logs: the logs (already read and checked).
        nthread: rollout threads (default: the machine's cores).
        floor_setting: the setting the replay floor is measured at (default nominal; adapters with
            ``replay_floor``).
    """

    def __init__(
        self,
        adapter: Adapter,
        logs: Sequence[Log],
        nthread: int | None = None,
        floor_setting: Mapping[str, float] | None = None,
    ):
        self.adapter = adapter
        self.logs = list(logs)
        self.segments: list[Segment] = []
        self._by_log: list[list[int]] = []  # each log's segments, as indices into ``segments``
        for source, log in enumerate(self.logs):
            cut = adapter.segments(log)
            for seg in cut:
                seg.source = source
            self._by_log.append(list(range(len(self.segments), len(self.segments) + len(cut))))
            self.segments += cut
        # the segments whose residuals count: all, or, where the body's state is carried over and a log's first
        # segment must guess it (``burn_in``), all but the first of each run of consecutive segments
        self.scored = [i for i, seg in enumerate(self.segments)
                       if not adapter.burn_in or (i and seg.index == self.segments[i - 1].index + 1
                                                  and seg.source == self.segments[i - 1].source)]  # fmt: skip
        if not self.scored:
            raise ValueError("no segment to replay: the logs are too short")
        self.nthread = nthread or default_threads()
        self._runner = rollout.Rollout(nthread=self.nthread)
        self.n_steps = max(seg.n_steps for seg in self.segments)
        for seg in self.segments:
            seg.n_steps = self.n_steps
        self._sensitivity: dict[tuple, np.ndarray] = {}  # (anchor, segment) -> its start's sensitivity
        self._carry: dict[tuple, tuple[dict, dict, dict]] = {}  # a setting's run over every segment
        self._datas: dict[tuple, list[mujoco.MjData]] = {}
        self._objectives: dict[tuple, float] = {}  # anchored objectives per segment already measured (objectives)
        self.rollouts = 0  # rows rolled out so far (segments x settings), for reports
        noise = [adapter.noise(log) for log in self.logs]
        self.sensor_sigma = {c: float(np.median([n[c] for n in noise])) for c in adapter.channels}
        self.set_floor(floor_setting)

    def set_floor(self, setting: Mapping[str, float] | None = None) -> None:
        """Measure the replay floor at ``setting`` (default nominal; adapters with ``replay_floor``) and make the
        noise levels the hypotenuse of it and the sensor noise. How far a legged robot's replay diverges depends on
        its dynamics, so the floor is measured at the model whose error is measured: the nominal model to start,
        each calibrated one after (sysid/select.py, sysid/pipeline.py)."""
        adapter = self.adapter
        self.replay_sigma = self._replay_floor(setting) if adapter.replay_floor else {}
        self.sigma = {c: float(np.hypot(s, self.replay_sigma.get(c, 0.0))) for c, s in self.sensor_sigma.items()}
        self._sigma = np.array([self.sigma[c] for c in adapter.channels])
        for seg in self.segments:
            seg.sigma = dict(self.sigma)
        self._sensitivity.clear()  # in units of the noise levels

    @property
    def channels(self) -> list[str]:
        return list(self.adapter.channels)

    def _replay_floor(self, setting: Mapping[str, float] | None) -> dict[str, float]:
        """What replay cannot match even with the right model, per channel: the log's commands run through the
        model without a break (``simulate``), giving a twin of the log whose channels the model itself made,
        read FLOOR_TWINS times with the log's sensor noise; each reading replayed in segments as the real log is
        (each segment from its own noisy measured state); the RMS of the difference from the twin's clean channels
        over all of them. It comes
        from what the log does not hold (a legged robot's body state, which its contacts make sensitive) and from
        the noise of the measured starts, and is added to the sensor noise as the floor errors are measured
        against. The twin, not the log, is replayed, so that what the model lacks stays in the residual and out of
        the floor."""
        adapter = self.adapter
        setting = {**adapter.catalog_nominal(), **(setting or {})}
        self._sigma = np.ones(len(adapter.channels))
        real, by_log = self.segments, self._by_log
        # every reading of every log's twin is a log of its own, appended to the segments, and all of them replay
        # in one chain, each step batched over them (one chain at a time leaves every rollout thread but one idle);
        # the logs themselves ride along at the same setting on the threads the twins leave idle, and their run is
        # kept as _runs keeps a setting's (the loop evaluates the nominal model first; the held-out error, the
        # calibrated model the test logs' floor is measured at)
        readings = []  # (clean channels, the reading's scored segments: (the log's, the twin's) indices)
        segments, chains = list(real), list(by_log)
        for source, log in enumerate(self.logs):
            if log.history is not None:  # a window of a file: its twin runs from the file's start, as it did
                full = pd.concat([log.history, log.df], ignore_index=True)
                clean = simulate(adapter, setting, full, log.meta)[len(log.history) :]
            else:
                clean = simulate(adapter, setting, log.df, log.meta)
            index = by_log[source]
            scored = [i for i in index if i in self.scored]
            for seed in range(FLOOR_TWINS):  # several readings of the twin: one log's divergences are few
                twin = log.df.copy()
                noise = np.random.default_rng(seed)  # the twin is measured as the log is, with its sensors' noise
                for j, c in enumerate(adapter.channels):
                    twin[c] = adapter.measure(c, clean[:, j] + noise.normal(0.0, self.sensor_sigma[c], len(clean)))
                twin_segments = adapter.segments(Log(log.path, twin, log.meta))
                if len(twin_segments) != len(index):
                    raise RuntimeError(f"{log.path}: the twin log cut into other segments than the log")
                at = {i: len(segments) + k for k, i in enumerate(index)}
                for seg in twin_segments:
                    seg.n_steps, seg.source = self.n_steps, source
                segments += twin_segments
                chains.append([at[i] for i in index])
                readings.append((clean, [(i, at[i]) for i in scored]))
        try:
            self.segments, self._by_log = segments, chains
            self._carry.clear()
            twins = [t for _, pairs in readings for _, t in pairs]
            predictions, starts, carried = self._chain([setting], self.scored + twins, with_carry=True)
        finally:
            self.segments, self._by_log = real, by_log
            self._sensitivity.clear()
            self._carry.clear()
        self._keep_runs([setting_key(setting)], predictions, starts, carried, range(len(real)))
        squares = np.zeros(len(adapter.channels))
        count = 0
        per_segment = []  # each segment's mean square difference per channel
        for clean, pairs in readings:
            for i, t in pairs:
                d = clean[real[i].samples] - predictions[(0, t)]
                d = d[np.isfinite(d).all(axis=1)]  # a replay gone unstable measures nothing
                squares += np.sum(d * d, axis=0)
                count += len(d)
                if len(d):
                    per_segment.append(np.mean(d * d, axis=0))
        self._floor_segments = np.array(per_segment)
        return {c: float(np.sqrt(squares[j] / max(count, 1))) for j, c in enumerate(adapter.channels)}

    @property
    def floor_uncertainty(self) -> float:
        """The relative standard error of the noise variance the errors are measured against, averaged over the
        channels: zero for sensor noise alone (thousands of samples pin it down), the segment-to-segment spread of
        the replay floor otherwise (a legged robot's replay diverges in some segments and not in others, so one
        log's floor is an uncertain estimate). The error of a right model lies within about twice this of 1."""
        per = getattr(self, "_floor_segments", None)
        if per is None or len(per) < 2:
            return 0.0
        se = np.std(per, axis=0, ddof=1) / math.sqrt(len(per))
        return float(np.mean(se / self._sigma**2))

    def _index(self, segments: Sequence[int] | None) -> list[int]:
        return list(self.scored) if segments is None else list(segments)

    def predict(
        self, settings: Sequence[Setting], segments: Sequence[int] | None = None, anchor: Setting | None = None
    ) -> list[list[np.ndarray]]:
        """Predicted channels for every setting and segment: ``out[k][s]`` is (samples, channels).

        With ``anchor`` (inside a fit), what a segment carries over from the one before is taken from the anchor's
        own run, so that every segment of every setting runs in one batched rollout; settings whose model structure
        differs from the anchor's, and calls without an anchor, run the segments of each log in order."""
        index = self._index(segments)
        if anchor is None or not self.adapter.carry_over:
            predictions, _, _ = self._runs(settings)
            return [[predictions[k][i] for i in index] for k in range(len(settings))]
        key = self.adapter.structure(anchor)
        same = [k for k, s in enumerate(settings) if self.adapter.structure(s) == key]
        other = [k for k in range(len(settings)) if self.adapter.structure(settings[k]) != key]
        predictions: dict = {}
        if same:
            carry = self._carried(anchor)
            subset = [settings[k] for k in same]
            models = [self.adapter.model_for(s) for s in subset]
            rows = [(j, i, ("carry", carry[i]) if carry.get(i) is not None else None)
                    for j in range(len(subset)) for i in index]  # fmt: skip
            pred, _, _ = self._run(subset, models, rows)
            predictions.update({(same[j], i): v for (j, i), v in pred.items()})
        if other:
            pred, _ = self._chain([settings[k] for k in other], index)
            predictions.update({(other[j], i): v for (j, i), v in pred.items()})
        return [[predictions[(k, i)] for i in index] for k in range(len(settings))]

    def _carried(self, anchor: Setting) -> dict[int, np.ndarray | None]:
        """The state each segment carries over from the one before, in the anchor's run over every segment."""
        return self._runs([anchor])[2][0]

    def _runs(self, settings: Sequence[Setting]) -> tuple[list[dict], list[dict], list[dict]]:
        """Each setting's run over every segment in order (:meth:`_chain`): its predictions, start states and
        carried states per segment. Runs are cached per setting: a setting is evaluated, its start's sensitivity
        measured and its carried states used as a fit's anchor from one run."""
        keys = [setting_key(s) for s in settings]
        missing = _missing(keys, settings, self._carry)
        if missing:
            predictions, starts, carried = self._chain(list(missing.values()), self._index(None), with_carry=True)
            if len(self._carry) + len(missing) > 64:  # keep what this call asks for (a cached anchor among them)
                wanted = {key: self._carry[key] for key in keys if key in self._carry}
                self._carry.clear()
                self._carry.update(wanted)
            self._keep_runs(list(missing), predictions, starts, carried, range(len(self.segments)))
        runs = [self._carry[key] for key in keys]
        return [r[0] for r in runs], [r[1] for r in runs], [r[2] for r in runs]

    def _keep_runs(self, keys: Sequence[tuple], predictions: dict, starts: dict, carried: dict, segments) -> None:
        """Keep each setting's run (settings numbered as ``keys``, as :meth:`_chain` numbers them) over those of
        ``segments`` it reached, for :meth:`_runs`."""
        segments = set(segments)
        for j, key in enumerate(keys):
            index = [i for (k, i) in predictions if k == j and i in segments]
            self._carry[key] = ({i: predictions[(j, i)] for i in index}, {i: starts[(j, i)] for i in index},
                                {i: carried[(j, i)] for i in index})  # fmt: skip

    def _chain(self, settings: Sequence[Setting], index: Sequence[int], with_carry: bool = False):
        """Roll out every setting over the segments of ``index``: the predictions and start states per (setting,
        segment). Each segment starts from its measured state; with ``carry_over`` the rest of the state (what
        the log does not hold) is the previous segment's end, so the segments of a log run in order (each step
        batched over the settings), from the log's first segment up to the last one asked for. ``with_carry`` adds
        the state each (setting, segment) carried over (None for a log's first segment)."""
        adapter = self.adapter
        wanted = set(index)
        models = [adapter.model_for(s) for s in settings]
        if not adapter.carry_over:
            rows = [(k, i, None) for k in range(len(settings)) for i in index]
            predictions, starts, _ = self._run(settings, models, rows)
            return (predictions, starts, {key: None for key in predictions}) if with_carry else (predictions, starts)
        chains = []
        for log_segments in self._by_log:
            needed = [j for j, i in enumerate(log_segments) if i in wanted]
            if needed:
                chains.append(log_segments[: needed[-1] + 1])
        predictions: dict[tuple[int, int], np.ndarray] = {}
        starts: dict[tuple[int, int], np.ndarray] = {}
        ends: dict[tuple[int, int], np.ndarray] = {}
        carried: dict[tuple[int, int], np.ndarray | None] = {}
        for j in range(max((len(c) for c in chains), default=0)):
            rows = []
            for chain in chains:
                if j >= len(chain):
                    continue
                i = chain[j]
                previous = chain[j - 1] if j else None
                contiguous = previous is not None and self.segments[i].index == self.segments[previous].index + 1
                for k in range(len(settings)):
                    carried[(k, i)] = ends[(k, previous)] if contiguous else None
                    rows.append((k, i, ("carry", ends[(k, previous)]) if contiguous else None))
            pred, start, end = self._run(settings, models, rows, keep_end=True)
            predictions.update(pred)
            starts.update(start)
            ends = end
        return (predictions, starts, carried) if with_carry else (predictions, starts)

    def _run(self, settings, models, rows, keep_end: bool = False):
        """Roll out rows (setting number, segment number, how to start): the start is the measured state
        (None), the measured state over a carried one (``("carry", state)``), or a given state perturbed
        (``("perturb", state, [(kind, address, delta), ...])``). Rows whose settings share a model structure run
        in one batched rollout. Returns predictions, start states and (``keep_end``) end states per row key."""
        groups: dict[tuple, list[int]] = {}
        for r, (k, _, _) in enumerate(rows):
            groups.setdefault(self.adapter.structure(settings[k]), []).append(r)
        predictions, starts, ends = {}, {}, {}
        for members in groups.values():
            self._rollout(settings, models, [rows[r] for r in members], predictions, starts, ends, keep_end)
        return predictions, starts, ends

    def _rollout(self, settings, models, rows, predictions, starts, ends, keep_end) -> None:
        adapter = self.adapter
        m0 = models[rows[0][0]]
        nstate = mujoco.mj_stateSize(m0, STATE_SPEC)
        n = len(rows)
        state = np.empty((n, nstate))
        control = np.empty((n, self.n_steps, m0.nu))
        start_sensordata = np.empty((n, m0.nsensordata))
        data = mujoco.MjData(m0)
        controls: dict[tuple[int, int], np.ndarray] = {}
        row_models = []
        for row, (k, i, how) in enumerate(rows):
            setting, seg = settings[k], self.segments[i]
            model = adapter.model_for(setting, seg)
            row_models.append(model)
            mujoco.mj_resetData(model, data)
            if how is not None and not np.isfinite(how[1]).all():  # the segment before went unstable: start afresh
                how = None
            if how is not None and how[0] == "perturb":
                mujoco.mj_setState(model, data, how[1], STATE_SPEC)
                for kind, address, delta in how[2]:
                    getattr(data, kind)[address] += delta
            else:
                if how is not None:
                    mujoco.mj_setState(model, data, how[1], STATE_SPEC)
                    data.time = 0.0
                adapter.initial_state(model, data, seg, setting, carried=how is not None)
            mujoco.mj_forward(model, data)
            mujoco.mj_getState(model, data, state[row], STATE_SPEC)
            start_sensordata[row] = data.sensordata
            if (k, i) not in controls:
                controls[(k, i)] = adapter.controls(model, seg, setting)
            control[row] = controls[(k, i)]
        size = model_sizes(m0)  # every size its data is allocated by: a spring adds a tendon and no joint
        if size not in self._datas:
            self._datas[size] = [mujoco.MjData(m0) for _ in range(self.nthread)]
        datas = self._datas[size]
        contexts = [(settings[k], self.segments[i]) for k, i, _ in rows]
        trajectory, sensordata = run_rollout(self._runner, adapter, row_models, datas, state, control, contexts,
                                             start_sensordata, keep_states=keep_end)  # fmt: skip
        self.rollouts += n
        for row, (k, i, how) in enumerate(rows):
            seg = self.segments[i]
            key = (k, i) if how is None or how[0] != "perturb" else (k, i, id(how))
            # a sample at step k is the state after k physics steps: the sensors computed at the start of step k
            predictions[key] = adapter.observe(sensordata[row, adapter.sample_steps(seg.steps, self.n_steps)], seg,
                                               settings[k])  # fmt: skip
            starts[key] = state[row].copy()
            if keep_end and seg.carry_steps:
                ends[key] = trajectory[row, seg.carry_steps - 1].copy()

    # --- the start's correction -------------------------------------------------------------------------------------
    def sensitivity(self, anchor: Setting, segments: Sequence[int] | None = None) -> list[np.ndarray]:
        """Per segment, the change of the normalized prediction per standard deviation of each uncertain start
        coordinate, at ``anchor``: (samples x channels, k)."""
        asked = self._index(segments)
        anchor_key = setting_key(anchor)  # kept per segment: each one's columns are its own rows' (one run each)
        index = [i for i in asked if (anchor_key, i) not in self._sensitivity]
        if not index:
            return [self._sensitivity[(anchor_key, i)] for i in asked]
        model = self.adapter.model_for(anchor)
        coords = {i: self.adapter.initial_uncertainty(model, self.segments[i], anchor) for i in index}
        if any(coords.values()):
            runs = self._runs([anchor])
            base, starts = {(0, i): runs[0][0][i] for i in index}, {(0, i): runs[1][0][i] for i in index}
        else:
            base, starts = {}, {}
        rows = []
        for i in index:
            rows.extend((0, i, ("perturb", starts[(0, i)], [c])) for c in coords[i])
        perturbed, _, _ = self._run([anchor], [model], rows) if rows else ({}, {}, {})
        out = []
        for i in index:
            columns = [
                ((perturbed[(0, i, id(how))] - base[(0, i)]) / self._sigma).ravel() for _, j, how in rows if j == i
            ]
            out.append(
                np.column_stack(columns) if columns else np.zeros((len(self.segments[i].steps) * len(self._sigma), 0))
            )
        known = {i: self._sensitivity[(anchor_key, i)] for i in asked if (anchor_key, i) in self._sensitivity}
        known.update(zip(index, out, strict=True))
        if len(self._sensitivity) + len(index) > SENSITIVITY_CACHE:
            self._sensitivity.clear()
        self._sensitivity.update({(anchor_key, i): known[i] for i in index})
        return [known[i] for i in asked]

    def residuals(
        self, settings: Sequence[Setting], segments: Sequence[int] | None = None, anchor: Setting | None = None
    ) -> list[list[Residual]]:
        """Residuals per setting and segment, the start corrected with sensitivities at ``anchor`` (default: at
        each setting itself, exact but one rollout per uncertain coordinate more)."""
        index = self._index(segments)
        predictions = self.predict(settings, index, anchor)
        out = []
        for k, per in enumerate(predictions):
            sens = self.sensitivity(anchor if anchor is not None else settings[k], index)
            row = []
            for i, p, a in zip(index, per, sens, strict=True):
                r = (self.segments[i].measured - p) / self._sigma
                # a setting whose rollout went unstable predicts nothing: a large, finite residual (optimizers
                # steer away from it; least squares stays defined)
                r = np.where(np.isfinite(r), r, UNSTABLE_RESIDUAL)
                if a.shape[1]:
                    delta = np.linalg.solve(a.T @ a + np.eye(a.shape[1]), a.T @ r.ravel())
                    r = r - (a @ delta).reshape(r.shape)
                else:
                    delta = np.zeros(0)
                row.append(Residual(r, delta, self.adapter.loss_scale, self.adapter.segment_variance))
            out.append(row)
        return out

    def objectives(self, settings: Sequence[Setting], segments: Sequence[int] | None, anchor: Setting) -> list[float]:
        """The objective of each setting (``total_objective`` of its residuals), the start's correction and the
        carried state anchored at ``anchor``. Kept per segment: under an anchor a segment's residual depends on the
        setting and that segment alone (its carried state comes from the anchor's run, its rollout from its own row
        of the batch), so a setting asked for again under the same anchor and noise levels is rolled out only on
        the segments not yet measured: a grid shrinking around its best point asks for that point again, points
        clipped to a range's end coincide, and the held-out test's folds, each refitted from the same start on two
        thirds of the segments, share most of their points. The sum runs in the segments' order, as
        ``total_objective`` sums, so the numbers are those of a rollout of every setting asked for."""
        index = self._index(segments)
        head = (self._sigma.tobytes(), setting_key(anchor))
        keys = [setting_key(s) for s in settings]
        gaps: dict[tuple[int, ...], dict[tuple, Setting]] = {}  # settings grouped by the segments they lack
        measured = {}
        for key, setting in dict(zip(keys, settings, strict=True)).items():  # each setting once
            lacking = []
            for i in index:
                if (head, i, key) in self._objectives:
                    measured[(head, i, key)] = self._objectives[(head, i, key)]
                else:
                    lacking.append(i)
            if lacking:
                gaps.setdefault(tuple(lacking), {})[key] = setting
        for lacking, group in gaps.items():
            ran = self.residuals(list(group.values()), lacking, anchor=anchor)
            for key, per in zip(group, ran, strict=True):
                measured.update({(head, i, key): r.objective for i, r in zip(lacking, per, strict=True)})
        if len(self._objectives) + len(measured) > 1_000_000:
            self._objectives.clear()
        self._objectives.update(measured)
        return [float(sum(measured[(head, i, key)] for i in index)) for key in keys]

    def error(self, residuals: Sequence[Residual]) -> float:
        """RMS of the normalized residual (the start's correction counted against its prior) per data sample and
        channel: 1 is the noise floor."""
        n = data_size(residuals)
        return math.sqrt(total_cost(residuals) / n) if n else float("nan")

    def error_outside(self, residuals: Sequence[Residual], log: str, start: float, end: float) -> float:
        """:meth:`error` with every channel's samples of ``log`` between ``start`` and ``end`` (the log's own time,
        s) left out: what the error is without one moment of one log (a stall the diagnostics found)."""
        kept = []
        for i, res in zip(self.scored, residuals, strict=True):
            segment = self.segments[i]
            if segment.log == log:
                time = np.asarray(segment.data["time"])
                res = replace(res, data=res.data[(time < start) | (time > end)])
            kept.append(res)
        return self.error(kept)

    def log_errors(self, residuals: Sequence[Residual]) -> dict[str, float]:
        """:meth:`error` per log (its path), of the residuals of the scored segments in order."""
        by_log: dict[str, list[Residual]] = {}
        for i, res in zip(self.scored, residuals, strict=True):
            by_log.setdefault(self.segments[i].log, []).append(res)
        return {log: self.error(rs) for log, rs in by_log.items()}

    def channel_errors(self, residuals: Sequence[Residual]) -> dict[str, float]:
        r = np.concatenate([x.data for x in residuals])
        return {c: float(np.sqrt(np.mean(r[:, i] ** 2))) for i, c in enumerate(self.channels)}

    def segment_costs(self, residuals: Sequence[Residual]) -> np.ndarray:
        """Cost per data sample of each segment (for paired bootstraps over segments): the sum of squares, or, with
        ``segment_variance``, the likelihood the fits minimize (``Residual.objective``)."""
        if self.adapter.segment_variance:
            return np.array([r.objective / max(r.data.size, 1) for r in residuals])
        return np.array([r.cost / max(r.data.size, 1) for r in residuals])

    def effective_samples(self, residuals: Sequence[Residual]) -> float:
        """The residual's samples, discounted for their autocorrelation (residuals at 1 kHz are far from
        independent): n / tau per segment and channel, tau the integrated autocorrelation time
        (:func:`_autocorrelation_time`)."""
        total = 0.0
        for res in residuals:
            r = res.data
            for c in range(r.shape[1]):
                total += len(r) / _autocorrelation_time(r[:, c])
        return max(total, 1.0)

    def decisions(self, index: Sequence[int]) -> Problem:
        """The problem the loop decides on when it decides on the segments ``index`` only
        (sysid/select.py ``decision_segments``): itself, or, where the body's state is carried from segment to
        segment and a log's first segment burns it in (``burn_in``), a :class:`DecisionProblem` in which each run
        of consecutive decision segments is burnt in by the one segment before it, as a log's first segment is.
        Carried from the log's start instead, every decision replay would run the log up to its last decision
        segment, in order, so that deciding on a few segments of a long log cost as much as on all of them."""
        index = sorted(index)
        unknown = sorted(set(index) - set(self.scored))
        if unknown:
            raise ValueError(f"decision segments {unknown} are not scored segments of this problem")
        if not (self.adapter.carry_over and self.adapter.burn_in) or index == sorted(self.scored):
            return self
        return DecisionProblem(self, index)


class DecisionProblem(Problem):
    """A problem's decision segments (:meth:`Problem.decisions`), each run of consecutive ones replayed from the
    segment before it (replayed, carried over, not counted: the burn-in a log's first segment gets) rather than
    from its log's start. A decision replay costs two segments per decision segment at most, however long the
    logs, and the runs are independent, so they go out in one batch on every rollout thread. The segments, noise
    levels and replay floor are the whole problem's, read through from it; its own :meth:`set_floor` measures the
    floor there and clears the view's sensitivities (in noise units): a view serves one ``calibrate`` call, which
    moves the floor only through it. Kept effects are refitted on the whole problem.

    The burn-in costs a little accuracy: a body started mid-walk from the adapter's guess (the roach's: at home, at
    rest) settles within a segment or two, so the true model's error on the decision segments reads slightly above
    its error carried from the log's start (a second burn-in segment does no better)."""

    def __init__(self, whole: Problem, index: Sequence[int]):
        self.whole = whole
        self.adapter, self.logs, self.segments = whole.adapter, whole.logs, whole.segments
        self.nthread, self._runner, self._datas = whole.nthread, whole._runner, whole._datas
        self.n_steps = whole.n_steps
        self.scored = sorted(index)
        self._deciding = frozenset(self.scored)
        self._by_log = []  # runs of consecutive decision segments, each after its burn-in segments
        segs = self.segments
        for i in self.scored:
            run = self._by_log[-1] if self._by_log else None
            if run is not None and i - run[-1] - 1 < DECISION_BURN_IN:  # nearer than a burn-in: carry on to it
                run.extend(range(run[-1] + 1, i + 1))
                continue
            first = i
            while (i - first < DECISION_BURN_IN and first > 0 and segs[first - 1].source == segs[i].source
                   and segs[first - 1].index == segs[first].index - 1):  # fmt: skip
                first -= 1
            self._by_log.append(list(range(first, i + 1)))
        self._sensitivity = {}
        self._carry = {}
        self._objectives = {}

    # the whole problem's noise levels and replay floor
    sensor_sigma = property(lambda self: self.whole.sensor_sigma)
    replay_sigma = property(lambda self: self.whole.replay_sigma)
    sigma = property(lambda self: self.whole.sigma)
    _sigma = property(lambda self: self.whole._sigma)
    _floor_segments = property(lambda self: getattr(self.whole, "_floor_segments", None))

    def set_floor(self, setting: Mapping[str, float] | None = None) -> None:
        """The whole problem's replay floor, measured at ``setting`` over every segment (see Problem.set_floor)."""
        self.whole.set_floor(setting)
        self._sensitivity.clear()  # in units of the noise levels; the runs themselves (``_carry``) do not change

    def _index(self, segments: Sequence[int] | None) -> list[int]:
        index = super()._index(segments)
        outside = sorted(set(index) - self._deciding)
        if outside:  # their carried state would be guessed anew, or missing: not a decision problem's to replay
            raise ValueError(f"segments {outside} are not decision segments of this problem (those: {self.scored})")
        return index

    @property
    def rollouts(self) -> int:  # counted with the whole problem's, for reports
        return self.whole.rollouts

    @rollouts.setter
    def rollouts(self, value: int) -> None:
        self.whole.rollouts = value


def _autocorrelation_time(x: np.ndarray) -> float:
    """The integrated autocorrelation time of a series, tau = 1 + 2 sum_k rho_k, by Geyer's initial monotone sequence
    (the sums of adjacent pairs of autocorrelations, taken while positive and made non-increasing), as effective
    sample sizes of MCMC chains are estimated: it counts correlation beyond the first lag, which an AR(1) reading
    (n (1 - rho) / (1 + rho)) misses when residuals wander smoothly. At least 1, at most n."""
    n = len(x)
    x = x - x.mean()
    denom = float(x @ x)
    if n < 4 or denom <= 0:
        return 1.0
    size = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(x, size)
    rho = np.fft.irfft(f * np.conj(f), size)[:n] / denom
    pairs = rho[: 2 * (n // 2)].reshape(-1, 2).sum(axis=1)  # Gamma_m = rho_2m + rho_2m+1
    positive = np.flatnonzero(pairs <= 0)
    pairs = pairs[: positive[0]] if len(positive) else pairs
    if not len(pairs):
        return 1.0
    pairs = np.minimum.accumulate(pairs)
    return float(min(max(-1.0 + 2.0 * pairs.sum(), 1.0), n))


def simulate(
    adapter: Adapter,
    setting: Mapping[str, float],
    commands: pd.DataFrame,
    meta: Mapping | None = None,
    observe: Callable[[np.ndarray, Segment, Setting], np.ndarray] | None = None,
) -> np.ndarray:
    """The adapter's channels (without noise) at the command table's sample times: the adapter's own segments of the
    table, run one after another, each from the full state the previous one ended in (nothing re-measured), so the
    robot is simulated without a break; only what the adapter makes per segment (a controller's gains for the
    segment's battery voltage) changes at the segment boundaries. Rows past the last segment stay zero.

    ``meta`` is the log's record (default the synthetic logs'); ``observe`` reads other columns off the sensor data
    (default the adapter's channels), e.g. body rates to compare as distributions."""
    log = Log("synthetic", commands, dict(adapter.synth_meta() if meta is None else meta))
    segments = adapter.segments(log)
    h = adapter.physics_dt
    observe = observe or adapter.observe
    out = None
    state = None
    runner = rollout.Rollout(nthread=0)
    for k, segment in enumerate(segments):
        following = segments[k + 1] if k + 1 < len(segments) else None
        end = following.t0 if following is not None else float(commands["time"].iloc[-1]) + h
        segment.n_steps = max(int(segment.steps[-1]) + 1, round((end - segment.t0) / h))
        model = adapter.model_for(setting, segment)
        d = mujoco.MjData(model)
        if state is None:
            adapter.initial_state(model, d, segment, setting)
            mujoco.mj_forward(model, d)
            state = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
            mujoco.mj_getState(model, d, state, STATE_SPEC)
        state[0] = 0.0  # time from the segment's start
        mujoco.mj_setState(model, d, state, STATE_SPEC)
        mujoco.mj_forward(model, d)
        control = adapter.controls(model, segment, setting)
        states, sensordata = run_rollout(runner, adapter, [model], [d], state[None].copy(), control[None],
                                         [(setting, segment)], d.sensordata[None].copy(), keep_states=True)  # fmt: skip
        columns = observe(sensordata[0, adapter.sample_steps(segment.steps, len(control))], segment, setting)
        if out is None:
            out = np.zeros((len(commands), columns.shape[1]))
        out[segment.samples] = columns
        state = states[0, round((end - segment.t0) / h) - 1].copy()
    return out if out is not None else np.zeros((len(commands), len(adapter.channels)))
