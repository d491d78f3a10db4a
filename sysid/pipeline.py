"""The whole loop on files' worth of logs: calibrate on the training logs, then measure the held-out error of the
nominal model and of each effect kept, on test logs the fit never saw (``calibrate.py`` writes it out)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from envs.common.effects import Effect
from sysid import diagnostics
from sysid.diagnostics import MECHANISMS
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
    _diagnostics: dict | None = field(default=None, repr=False, compare=False)

    @property
    def threshold(self) -> float:
        """The held-out error above which the residual is unexplained (:func:`explained_below`)."""
        return explained_below(self.test_problem)

    @property
    def unexplained(self) -> bool:
        return bool(self.after.error > self.threshold)

    def where(self) -> str:
        """A sentence saying where the remaining residual lies, and (unexplained) what it points to."""
        after = self.after
        worst = max(after.per_channel, key=after.per_channel.get)
        found = diagnostics.summarize(self.diagnostics_after())
        if not self.unexplained:
            return (f"The held-out residual is at the noise floor ({after.error:.2f} noise levels); nothing "
                    "remains to explain.")  # fmt: skip
        text = (f"The held-out residual stays above the noise floor ({after.error:.2f} noise levels), most on "
                f"{worst} ({after.per_channel[worst]:.2f})")  # fmt: skip
        if found:
            text += "; " + "; ".join(found)
        if not self.outcome.chosen:
            text += ". No catalog effect explains it"
        else:
            kept = ", ".join(c.effect.name for c in self.outcome.chosen)
            text += (f". The effects kept ({kept}) take the held-out error from {self.before.error:.2f} to "
                     f"{after.error:.2f} but do not explain it")  # fmt: skip
        traced = self.trace()
        return text + (". " + traced["why"] if traced else ": what remains lies outside the catalog") + "."

    def diagnostics_after(self) -> dict[str, dict]:
        """The diagnostics of the held-out residual after calibration (sysid/diagnostics.py)."""
        if self._diagnostics is None:
            self._diagnostics = diagnostics.diagnose(self.test_problem, self.after.residuals, self.adapter.context)
        return self._diagnostics

    def trace(self) -> dict | None:
        """What the strongest finding on the held-out residual after calibration points to, and what became of
        each catalog effect of that kind (:func:`trace`); None where nothing stands out."""
        return trace(self.adapter, self.outcome, diagnostics.findings(self.diagnostics_after()))


def _relevant(effect: Effect, channel: str, channels: Sequence[str]) -> bool:
    """Whether an effect acts on a channel: it has no target, the target is the channel or its suffix (``left`` of
    ``duty_left``), or its target names no channel's suffix at all (a joint group), so that it may act on any."""
    t = effect.target
    if not t or channel == t or channel.endswith("_" + t):
        return True
    return not any(c == t or c.endswith("_" + t) for c in channels)


def _fate(effect: Effect, outcome: Outcome, start: Mapping[str, float]) -> tuple[str, str]:
    """What became of one catalog effect in a calibration: (kind, words). Kinds: kept, start, refused, aliased,
    ranked, unranked."""
    for choice in outcome.chosen:
        if choice.effect.name == effect.name:
            values = ", ".join(f"{k.split('.', 1)[1]} {v:.3g}" for k, v in choice.values.items()
                               if k in effect.nominal())  # fmt: skip
            return "kept", f"kept ({values})"
    if any(k in start for k in effect.nominal()):
        return "start", "held at the calibration the run started from"
    reasons = [r["reason"] for r in outcome.rejected if r["name"] == effect.name]
    reasons = reasons or [r["reason"] for r in outcome.rejected if effect.name in r["name"].split(" + ")]
    if reasons:
        return "refused", f"refused: {reasons[0]}"
    ranked = [entry for round_ in outcome.rounds for entry in round_ if entry["effect"] == effect.name]
    taken = [c.effect.name for c in outcome.chosen if c.effect.alias == effect.alias
             and (not effect.target or c.effect.target in ("", effect.target))]  # fmt: skip
    if ranked and len(ranked) < len(outcome.rounds) and taken:
        return "aliased", f"not offered once {taken[0]} was kept (its alias group, {effect.alias})"
    if ranked:
        share = ranked[-1]["explained_fraction"]
        text = f"ranked, not tried: it explains {share:.1%} of the training residual at best"
        return "ranked", text + (f"; barely seen on this robot ({effect.weak})" if effect.weak else "")
    if outcome.mode == "fit":
        return "unranked", "not tried: the run fitted only the effects it was given (--fit)"
    return "unranked", "not ranked"


def trace(adapter: Adapter, outcome: Outcome, found: Sequence[diagnostics.Finding]) -> dict | None:
    """The mechanism the strongest finding points to (:data:`sysid.diagnostics.MECHANISMS`), every catalog effect of
    that kind on the finding's channel with what became of it in ``outcome``, the kinds of effect the robot's
    catalog lacks, and a sentence on why none of them explains what remains."""
    from envs.common.effects import TEMPLATES, base_name

    strongest = next((f for f in found if MECHANISMS.get(f.key, ("", ()))[1] or f.key == "sides"), None)
    if strongest is None:
        return None
    mechanism, kinds = MECHANISMS[strongest.key]
    catalog = adapter.catalog()
    channels = list(adapter.channels)
    catalog_nominal = adapter.catalog_nominal()  # a calibration the run started from moves the outcome's nominal
    start = {k: v for k, v in outcome.nominal.items() if k in catalog_nominal and v != catalog_nominal[k]}
    if strongest.key == "sides":  # a per-side effect: every effect with a side
        effects = [e for e in catalog.values() if e.target]
    else:
        effects = [e for e in catalog.values() if base_name(e) in kinds and _relevant(e, strongest.channel, channels)]
    fates = {e.name: _fate(e, outcome, start) for e in effects}
    have = {base_name(e) for e in catalog.values()}
    missing = [k for k in kinds if k in TEMPLATES and k not in have]
    counts = {kind: [n for n, (k, _) in fates.items() if k == kind] for kind in
              ("kept", "start", "refused", "aliased", "ranked", "unranked")}  # fmt: skip
    parts = []
    if counts["kept"]:
        parts.append(f"{', '.join(counts['kept'])} kept, and a residual of this kind remains")
    if counts["refused"]:
        parts.append(f"{', '.join(counts['refused'])} refused (the report gives each one's reason)")
    if counts["ranked"]:
        parts.append(f"{', '.join(counts['ranked'])} ranked too low to try")
    if counts["aliased"]:
        parts.append(f"{', '.join(counts['aliased'])} taken by an effect kept in its alias group")
    if counts["start"]:
        parts.append(f"{', '.join(counts['start'])} held at the calibration the run started from")
    if counts["unranked"]:
        parts.append(f"{', '.join(counts['unranked'])} not tried")
    why = f"It points to {mechanism} ({strongest.text})"
    if effects:
        why += ": of the catalog's effects of that kind, " + "; ".join(parts)
    else:
        why += ": this robot's catalog has no effect of that kind"
    if missing:
        why += f"; not in this robot's catalog: {', '.join(missing)}"
    return {"channel": strongest.channel, "finding": strongest.key, "text": strongest.text, "mechanism": mechanism,
            "effects": {n: {"fate": k, "words": w} for n, (k, w) in fates.items()}, "missing": missing,
            "why": why}  # fmt: skip


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
