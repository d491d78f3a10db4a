"""One synthetic calibration case, judged as issue 7 asks: training logs with hidden effects (drawn by the generator
when no value is given) and held-out logs of the same truth under other commands (one 10 s log each, or the robot's
protocol of several shorter runs: ``Adapter.runs``); calibrate on the one, judge on the other. Shared by the tests
(one fast case per robot) and ``benchmarks/calibration_matrix.py`` (every effect, coverage over seeds)."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from sysid import synth
from sysid.logs import Log
from sysid.pipeline import Result, relative_excess, run
from sysid.robots import adapter as make_adapter

TEST_SEED_OFFSET = 1000  # the test log's commands and noise come from seed + this


@dataclass
class Case:
    """What a case found, against the truth; the verdicts follow issue 7's criteria."""

    robot: str
    injected: dict[str, dict[str, float]]
    seed: int
    nominal_error: float
    result: Result = field(repr=False)
    seconds: float
    first: str | None  # the first effect chosen
    first_in_alias_group: bool  # the first pick is in the (single) injected effect's alias group
    recovered: bool  # each parameter within max(2 x half-width, 5% of its range) (same effect picked)
    covered: dict[str, bool]  # per parameter: the 95% interval holds the truth (same effect picked)
    values: dict[str, tuple[float, float, float]]  # parameter -> (truth, estimate, half-width: the larger side)
    intervals: dict[str, tuple[float, float]]  # parameter -> the 95% interval (low, high)
    excess_ratio: float  # held-out excess over the noise floor, after / before

    @property
    def halved(self) -> bool:
        return self.excess_ratio <= 0.5

    def row(self) -> dict[str, Any]:
        return {
            "robot": self.robot, "injected": self.injected, "seed": self.seed, "nominal_error": self.nominal_error,
            "chosen": [c.effect.name for c in self.result.outcome.chosen], "first": self.first,
            "first_in_alias_group": self.first_in_alias_group, "recovered": self.recovered, "covered": self.covered,
            "values": {k: list(v) for k, v in self.values.items()},
            "intervals": {k: list(v) for k, v in self.intervals.items()}, "error_before": self.result.before.error,
            "error_after": self.result.after.error, "excess_ratio": self.excess_ratio, "halved": self.halved,
            "unexplained": self.result.unexplained, "threshold": self.result.threshold, "seconds": self.seconds,
            # why each refused effect was refused: which cases a change to a test can move, read without a rerun
            "rejected": [dict(r) for r in self.result.outcome.rejected],
        }  # fmt: skip


def pair(
    robot: str, effects: Mapping[str, float | Mapping[str, float] | None], seed: int
) -> tuple[list[Log], list[Log], dict]:
    """A case's logs: the training logs with hidden effects (drawn when None) and the held-out logs of the same truth
    under other commands (seed + TEST_SEED_OFFSET), chosen to show it as the training logs' do. The robot's
    recording protocol (``Adapter.runs``) says how many runs of how many seconds each (by default one log of
    ``synth.SECONDS``); the truth is drawn on the training runs, where calibration will look for it. Returns both
    lists and the truth."""
    runs, seconds = synth.protocol(make_adapter(robot))
    train, truth = synth.record(robot, effects, seed, seconds, runs)
    test, _ = synth.record(robot, truth["effects"], seed + TEST_SEED_OFFSET, seconds, runs, show=True)
    if runs > 1:
        train, test = ([dataclasses.replace(log, path=f"synthetic {name} run {k + 1}") for k, log in enumerate(logs)]
                       for name, logs in (("training", train), ("held-out", test)))  # fmt: skip
    return train, test, truth


def run_case(
    robot: str,
    effects: Mapping[str, float | Mapping[str, float] | None],
    seed: int,
    say: Callable[[str], None] = lambda s: None,
) -> Case:
    """Synthesize the pair of logs, calibrate, and judge the result."""
    start = time.perf_counter()
    adapter = make_adapter(robot)
    train, test, truth = pair(robot, effects, seed)
    result = run(adapter, train, test, say=say)
    chosen = result.outcome.chosen
    first = chosen[0] if chosen else None
    catalog = adapter.effects()
    in_group, recovered, covered, values, intervals = False, False, {}, {}, {}
    if len(truth["effects"]) == 1 and first is not None:
        (name, true_values), = truth["effects"].items()  # fmt: skip
        injected = catalog[name]
        in_group = first.effect.alias == injected.alias
        if first.effect.name == name:
            recovered = True
            for p in injected.params:
                key = injected.key(p.name)
                true, got, half = true_values[p.name], first.values[key], first.ci95[key]
                low, high = first.bounds95[key]
                values[p.name], intervals[p.name] = (true, got, half), (low, high)
                covered[p.name] = low <= true <= high
                recovered &= abs(got - true) <= max(2 * half, 0.05 * p.span)
    return Case(robot, truth["effects"], seed, truth["nominal_error"], result, time.perf_counter() - start,
                first.effect.name if first else None, in_group, recovered, covered, values, intervals,
                relative_excess(result.before.error, result.after.error))  # fmt: skip
