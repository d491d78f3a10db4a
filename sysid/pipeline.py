"""The whole loop on files' worth of logs: calibrate on the training logs, then measure the held-out error of the
nominal model and of each effect kept, on test logs the fit never saw (``calibrate.py`` writes it out)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sysid import diagnostics
from sysid.fit import evaluate, fit
from sysid.logs import Log
from sysid.problem import Adapter, Problem, Residual
from sysid.select import Outcome, calibrate, explained_below, fit_chosen


@dataclass
class HeldOut:
    """The error of a setting on the test logs (their own nuisance parameters fitted with the model held)."""

    error: float
    per_channel: dict[str, float]
    residuals: list[Residual] = field(repr=False, default_factory=list)
    per_log: dict[str, float] = field(default_factory=dict)


@dataclass
class Result:
    adapter: Adapter
    train: list[Log]
    test: list[Log]
    outcome: Outcome
    before: HeldOut
    after: HeldOut
    steps: list[HeldOut]  # after each kept effect, in order
    test_problem: Problem = field(repr=False)
    train_problem: Problem = field(repr=False)

    @property
    def threshold(self) -> float:
        """The held-out error above which the residual is unexplained (:func:`explained_below`)."""
        return explained_below(self.test_problem)

    @property
    def unexplained(self) -> bool:
        return bool(self.after.error > self.threshold)

    def where(self) -> str:
        """A sentence saying where the remaining residual lies."""
        after = self.after
        worst = max(after.per_channel, key=after.per_channel.get)
        found = diagnostics.summarize(diagnostics.diagnose(self.test_problem, after.residuals, self.adapter.context))
        if not self.unexplained:
            return (f"The held-out residual is at the noise floor ({after.error:.2f} noise levels); nothing "
                    "remains to explain.")  # fmt: skip
        text = (f"The held-out residual stays above the noise floor ({after.error:.2f} noise levels), most on "
                f"{worst} ({after.per_channel[worst]:.2f})")  # fmt: skip
        if found:
            text += "; " + "; ".join(found)
        if not self.outcome.chosen:
            text += ". No catalog effect explains it."
        else:
            kept = ", ".join(c.effect.name for c in self.outcome.chosen)
            text += (f". The effects kept ({kept}) take the held-out error from {self.before.error:.2f} to "
                     f"{after.error:.2f} but do not explain it: no catalog effect brings it to the noise floor, so "
                     "what remains lies outside the catalog or in effects these logs cannot tell apart, and what was "
                     "kept may stand in for it")  # fmt: skip
        return text


def held_out(problem: Problem, setting: Mapping[str, float]) -> HeldOut:
    """The error of ``setting`` on a problem's logs, their nuisance parameters (an unlogged goal) fitted first."""
    nuisance = problem.adapter.nuisance(problem.logs)
    setting = dict(setting)
    if nuisance:
        for k, p in nuisance.items():
            setting.setdefault(k, p.nominal)
        setting = fit(problem, setting, nuisance).values
    result = evaluate(problem, setting)
    return HeldOut(
        result.error, problem.channel_errors(result.residuals), result.residuals, problem.log_errors(result.residuals)
    )


def run(
    adapter: Adapter,
    train: Sequence[Log],
    test: Sequence[Log],
    start: Mapping[str, float] | None = None,
    say: Callable[[str], None] = print,
    nthread: int | None = None,
    effects: Sequence[str] | None = None,
) -> Result:
    """Calibrate ``adapter``'s robot on ``train`` and measure the held-out error on ``test``; with ``effects``,
    fit those effects without selection."""
    train_problem = Problem(adapter, train, nthread)
    if effects:
        outcome = fit_chosen(train_problem, effects, start, say=say)
    else:
        outcome = calibrate(train_problem, start, say=say)
    # the held-out logs' noise levels hold the replay floor of the calibrated model (Problem.set_floor): the best
    # description of the robot says how closely a right model can replay these logs; before and after are both
    # measured against it
    test_problem = Problem(adapter, test, nthread, floor_setting=outcome.setting)
    if not adapter.nuisance(test):  # every setting's replay of the test logs in one batch, kept for held_out
        test_problem.predict(outcome.history)
    steps = [held_out(test_problem, s) for s in outcome.history]
    say(
        "held-out error: "
        + " -> ".join(f"{h.error:.2f}" for h in steps)
        + (f" (after {', '.join(c.effect.name for c in outcome.chosen)})" if outcome.chosen else " (nothing kept)")
    )
    return Result(adapter, list(train), list(test), outcome, steps[0], steps[-1], steps[1:], test_problem,
                  train_problem)  # fmt: skip


def relative_excess(before: float, after: float) -> float:
    """How much of the error's excess over the noise floor remains: (after - 1) / (before - 1)."""
    return float((after - 1.0) / (before - 1.0)) if before > 1.0 else float(np.nan)
