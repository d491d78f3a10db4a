"""One synthetic calibration case, judged by the calibration matrix's criteria: training logs with hidden effects
(drawn by the generator when no value is given) and held-out logs of the same truth under other commands (one 10 s log
each, or the robot's protocol of several shorter runs: ``Adapter.runs``); calibrate on the one, judge on the other.
Shared by the tests (one fast case per robot) and ``benchmarks/calibration_matrix.py`` (every effect, coverage over
seeds)."""

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
    """What a case found, against the truth; the verdicts follow the calibration matrix's criteria."""

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
    # every injected effect (several at once, ``found``): the effect kept from its alias group (None: none), and,
    # where that is the effect itself, whether each parameter is recovered and covered as above
    found: dict[str, dict[str, Any]] = field(default_factory=dict)
    spurious: list[str] = field(default_factory=list)  # effects kept from no injected effect's alias group

    @property
    def halved(self) -> bool:
        return self.excess_ratio <= 0.5

    @property
    def all_found(self) -> bool:
        """Every injected effect's alias group has an effect kept, and nothing else is kept."""
        return all(f["chosen"] is not None for f in self.found.values()) and not self.spurious

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
            "found": self.found, "spurious": self.spurious, "all_found": self.all_found,
        }  # fmt: skip


def pair(
    robot: str, effects: Mapping[str, float | Mapping[str, float] | None], seed: int, seconds: float | None = None
) -> tuple[list[Log], list[Log], dict]:
    """A case's logs: the training logs with hidden effects (drawn when None) and the held-out logs of the same truth
    under other commands (seed + TEST_SEED_OFFSET), chosen to show it as the training logs' do. The robot's
    recording protocol (``Adapter.runs``) says how many runs of how many seconds each (by default one log of
    ``synth.SECONDS``; ``seconds`` shortens a run); the truth is drawn on the training runs, where calibration will
    look for it. Returns both lists and the truth."""
    runs, protocol_seconds = synth.protocol(make_adapter(robot))
    seconds = protocol_seconds if seconds is None else seconds
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
    found = {}
    for name, true_values in truth["effects"].items():
        injected = catalog[name]
        kept = next((c for c in chosen if c.effect.alias == injected.alias), None)
        judged = _judge(kept, name, injected, true_values)
        found[name] = {"chosen": kept.effect.name if kept else None, **judged}
        if len(truth["effects"]) == 1 and first is not None:
            in_group = first.effect.alias == injected.alias
            if first.effect.name == name:
                recovered, covered = judged["recovered"], judged["covered"]
                values, intervals = judged["values"], judged["intervals"]
    groups = {catalog[name].alias for name in truth["effects"]}
    spurious = [c.effect.name for c in chosen if c.effect.alias not in groups]
    return Case(robot, truth["effects"], seed, truth["nominal_error"], result, time.perf_counter() - start,
                first.effect.name if first else None, in_group, recovered, covered, values, intervals,
                relative_excess(result.before.error, result.after.error), found, spurious)  # fmt: skip


def _judge(kept, name: str, injected, true_values: Mapping[str, float]) -> dict[str, Any]:
    """An injected effect against the choice kept from its alias group: if that is the effect itself, whether each
    parameter is recovered (within max(2 x half-width, 5% of its range)) and covered by its 95% interval."""
    out: dict[str, Any] = {"recovered": False, "covered": {}, "values": {}, "intervals": {}}
    if kept is None or kept.effect.name != name:
        return out
    recovered = True
    for p in injected.params:
        key = injected.key(p.name)
        true, got, half = true_values[p.name], kept.values[key], kept.ci95[key]
        low, high = kept.bounds95[key]
        out["values"][p.name], out["intervals"][p.name] = (true, got, half), (low, high)
        out["covered"][p.name] = bool(low <= true <= high)
        recovered &= bool(abs(got - true) <= max(2 * half, 0.05 * p.span))
    out["recovered"] = recovered
    return out
