"""Measurements a log holds by itself, before any replay: the record each robot's adapter returns
(``Adapter.measure_log``), their intervals and their table; ``python -m sysid.measure --robot ROBOT LOG ...`` prints
them.

Intervals are 95% circular block bootstrap intervals (``arch``): blocks of the log's rows, so that the residuals
within a block (a stride, say) keep their dependence.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

REPS = 400  # bootstrap replications


@dataclass(frozen=True)
class Measurement:
    """One quantity read off a log: its value, 95% interval, and the nominal model's value with its source."""

    log: str
    quantity: str
    side: str  # "left", "right" or "" (the robot)
    value: float
    low: float
    high: float
    unit: str
    nominal: float | None
    source: str  # where the nominal value comes from
    note: str = ""

    @property
    def ratio(self) -> float | None:
        """The measured value over the nominal one."""
        return None if not self.nominal else self.value / self.nominal


def lstsq(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(x, y, rcond=None)[0]


def bootstrap(fn: Callable[..., np.ndarray], block: int, *arrays: np.ndarray, seed: int = 0) -> np.ndarray:
    """95% percentile intervals (2, k) of ``fn``'s k estimates under a circular block bootstrap of the rows."""
    from arch.bootstrap import CircularBlockBootstrap
    from threadpoolctl import threadpool_limits

    bs = CircularBlockBootstrap(max(block, 1), *arrays, seed=seed)
    # one BLAS thread: each replicate's fit is small (thousands of rows, a dozen columns), and OpenBLAS's threads for
    # it made a log's measurements four times slower on a host whose other core is busy (24.7 s against 6.4 s for
    # `python -m sysid.measure --robot roach` on the two 2015 logs, beside a training job, 2026-12-04)
    with warnings.catch_warnings(), threadpool_limits(limits=1, user_api="blas"):
        warnings.simplefilter("ignore")  # arch warns when a replicate's regression is rank-deficient; its NaN drops
        return bs.conf_int(fn, reps=REPS, method="percentile")


def table(measurements: Sequence[Measurement]) -> str:
    """A markdown table of measurements."""
    lines = ["| log | quantity | side | measured (95%) | nominal | measured / nominal | nominal's source |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for m in measurements:
        nominal = "-" if m.nominal is None else f"{m.nominal:.4g}"
        ratio = "-" if m.ratio is None else f"{m.ratio:.2f}"
        lines.append(f"| {m.log} | {m.quantity} | {m.side or '-'} | {m.value:.4g} [{m.low:.4g}, {m.high:.4g}] "
                     f"{m.unit} | {nominal} | {ratio} | {m.source} |")  # fmt: skip
    return "\n".join(lines) + "\n"


# --- the conditions of training and held-out logs -----------------------------------------------------------------
@dataclass(frozen=True)
class ConditionCheck:
    """One held-out log's measurement of a condition quantity (a log's load, its ground) against the training logs'
    measurements of it: ``outside`` where its interval overlaps none of theirs and lies beyond all of them."""

    quantity: str
    side: str
    unit: str
    training: tuple[Measurement, ...]
    held_out: Measurement

    @property
    def outside(self) -> bool:
        low, high = min(m.low for m in self.training), max(m.high for m in self.training)
        return self.held_out.high < low or self.held_out.low > high

    @property
    def direction(self) -> str:
        """Where the held-out log lies against the training logs, ``above`` or ``below`` (meaningful where
        :attr:`outside`)."""
        return "above" if self.held_out.low > max(m.high for m in self.training) else "below"


def compare_conditions(train: Sequence[Measurement], test: Sequence[Measurement],
                       quantities: Sequence[str]) -> list[ConditionCheck]:  # fmt: skip
    """Each held-out log's measurement of each condition quantity (and side) against the training logs' of it; only
    quantities measured on at least one training log and the held-out log."""
    checks = []
    for q in quantities:
        for m in test:
            if m.quantity != q:
                continue
            training = tuple(t for t in train if t.quantity == q and t.side == m.side)
            if training:
                checks.append(ConditionCheck(q, m.side, m.unit, training, m))
    return checks


def conditions_table(checks: Sequence[ConditionCheck]) -> str:
    """A markdown table of :func:`compare_conditions`' checks and a sentence naming those outside."""

    def shown(m: Measurement) -> str:
        return f"{m.value:.3g} [{m.low:.3g}, {m.high:.3g}]"

    lines = ["| quantity | side | training logs (95%) | held-out log | held-out (95%) | |", "|---|---|---|---|---|---|"]
    for c in checks:
        training = "; ".join(shown(m) for m in c.training)
        verdict = f"**outside, {c.direction}**" if c.outside else "within"
        lines.append(f"| {c.quantity} ({c.unit}) | {c.side or '-'} | {training} | {c.held_out.log} | "
                     f"{shown(c.held_out)} | {verdict} |")  # fmt: skip
    outside = [c for c in checks if c.outside]
    if outside:
        named = "; ".join(f"{c.quantity} {c.side} on {c.held_out.log} ({shown(c.held_out)}, {c.direction})"
                          for c in outside)  # fmt: skip
        lines += ["", f"Held-out logs ran under conditions no training log holds: {named}. What the training logs "
                  "asked of the model was asked under other conditions, and need not carry over to them."]  # fmt: skip
    else:
        lines += ["", "Every held-out log ran under conditions within the training logs'."]
    return "\n".join(lines) + "\n"


# --- measurements as a calibration ------------------------------------------------------------------------------
@dataclass(frozen=True)
class EffectReading:
    """One log's measurement read as a catalog effect's parameter (``Adapter.effect_readings``): the value a
    calibration file would hold, its 95% interval, and the parameter's value in the nominal model."""

    log: str
    effect: str
    param: str
    value: float
    low: float
    high: float
    nominal: float
    quantity: str  # the measurement it is read from


@dataclass(frozen=True)
class MeasuredEffect:
    """An effect's parameter measured on one log or pooled over several (:func:`pool`): the readings it comes from
    and their combined value and 95% interval."""

    readings: tuple[EffectReading, ...]
    value: float
    low: float
    high: float

    @property
    def effect(self) -> str:
        return self.readings[0].effect

    @property
    def param(self) -> str:
        return self.readings[0].param

    @property
    def nominal(self) -> float:
        return self.readings[0].nominal

    @property
    def logs(self) -> tuple[str, ...]:
        return tuple(r.log for r in self.readings)

    @property
    def logs_disagree(self) -> bool:
        """Two logs' intervals do not overlap: the logs measure different robots or conditions."""
        return any(
            a.high < b.low or b.high < a.low for i, a in enumerate(self.readings) for b in self.readings[i + 1 :]
        )

    @property
    def significant(self) -> bool:
        """The interval excludes the nominal value: the measurement says the nominal model is wrong."""
        return not self.low <= self.nominal <= self.high


def pool(readings: Sequence[EffectReading]) -> list[MeasuredEffect]:
    """Each effect parameter's readings combined, in the order first read: one log's as it is; several logs' by
    their inverse-variance weighted mean, each log's standard error taken from its interval's width (the pooled
    interval assumes the logs measure one value, which ``logs_disagree`` questions)."""
    from sysid.select import Z95

    groups: dict[tuple[str, str], list[EffectReading]] = {}
    for r in readings:
        groups.setdefault((r.effect, r.param), []).append(r)
    out = []
    for group in groups.values():
        if len(group) == 1:
            (r,) = group
            out.append(MeasuredEffect((r,), r.value, r.low, r.high))
            continue
        weights = np.array([(2 * Z95 / max(r.high - r.low, 1e-12)) ** 2 for r in group])  # 1 / standard error^2
        value = float(np.sum(weights * [r.value for r in group]) / weights.sum())
        half = Z95 / float(np.sqrt(weights.sum()))
        out.append(MeasuredEffect(tuple(group), value, value - half, value + half))
    return out
