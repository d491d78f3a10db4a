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

    bs = CircularBlockBootstrap(max(block, 1), *arrays, seed=seed)
    with warnings.catch_warnings():
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
