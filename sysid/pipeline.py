"""The whole loop on files' worth of logs: calibrate on the training logs, then measure the held-out error of the
nominal model and of each effect kept, on test logs the fit never saw (``calibrate.py`` writes it out)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from envs.common.effects import Effect, base_name
from sysid import diagnostics
from sysid.diagnostics import BODY_KINDS, MECHANISMS
from sysid.fit import evaluate, fit
from sysid.logs import Log
from sysid.problem import Adapter, Problem, Residual
from sysid.select import Outcome, calibrate, explained_below, fit_chosen

# what a stall in a training log is, and what to do about it: the console's warning and the report's line
STALL_SIGN = "the drive at its limit, the joint not moving its way: held or blocked"
STALL_ADVICE = (
    "no effect acting throughout a run makes one, so the fit is pulled toward it; windows of the log that leave it "
    "out (FILE@START:END) fit without it"
)


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
    train_stall: dict | None = None  # a stall in the training logs (training_stall), found before the fit

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
        if not self.unexplained:
            return (f"The held-out residual is at the noise floor ({after.error:.2f} noise levels); nothing "
                    "remains to explain.")  # fmt: skip
        found = diagnostics.findings(self.diagnostics_after())
        # a stall is an event, not a property: named even where stronger findings come first
        stall = _first_stall(found)
        listed = found[:3] + ([stall] if stall is not None and stall not in found[:3] else [])
        text = (f"The held-out residual stays above the noise floor ({after.error:.2f} noise levels), most on "
                f"{worst} ({after.per_channel[worst]:.2f})")  # fmt: skip
        if listed:
            text += "; " + "; ".join(f.text for f in listed)
        if not self.outcome.chosen:
            text += ". No catalog effect explains it"
        else:
            kept = ", ".join(c.effect.name for c in self.outcome.chosen)
            text += (f". The effects kept ({kept}) take the held-out error from {self.before.error:.2f} to "
                     f"{after.error:.2f} but do not explain it")  # fmt: skip
        text += ": what remains lies outside the catalog or in effects these logs cannot tell apart" + (
            ", and what was kept may stand in for it" if self.outcome.chosen else ""
        )
        traced = trace(self.adapter, self.outcome, found)
        if traced:
            text += f". The strongest finding, on {traced['channel']}, points to " + traced["why"]
        if stall is not None and (traced is None or traced["finding"] != "stall"):
            text += f". The stall found on {stall.channel} is {MECHANISMS['stall'][0]}"
        return text + "."

    def without_stall(self) -> dict[str, Any] | None:
        """The held-out error before and after calibration with the span of the stall found after it left out (every
        channel's samples of that log between the stall's start and end): how much of what remains the stall holds.
        None where no stall is found."""
        stall = _stall(self.diagnostics_after())
        if stall is None:
            return None
        log, start, end = stall["log"], stall["start"], stall["end"]
        before, after = (
            self.test_problem.error_outside(h.residuals, log, start, end) for h in (self.before, self.after)
        )
        return {**stall, "before": before, "after": after}

    def diagnostics_after(self) -> dict[str, dict]:
        """The diagnostics of the held-out residual after calibration (sysid/diagnostics.py)."""
        if self._diagnostics is None:
            self._diagnostics = diagnostics.diagnose(self.test_problem, self.after.residuals, self.adapter.context)
        return self._diagnostics

    def trace(self) -> dict | None:
        """What the strongest finding on the held-out residual after calibration points to, and what became of
        each catalog effect of that kind (:func:`trace`); None where nothing stands out."""
        return trace(self.adapter, self.outcome, diagnostics.findings(self.diagnostics_after()))


def _first_stall(found: Sequence[diagnostics.Finding]) -> diagnostics.Finding | None:
    """The strongest stall among findings (strongest first), or None."""
    return next((f for f in found if f.key == "stall"), None)


def _stall(diagnosed: Mapping[str, dict]) -> dict[str, Any] | None:
    """The stall among diagnostics' findings (the strongest, if several channels show one): its channel, log, start
    and end (s, the log's own time) and share of the channel's squared residual; None where there is none."""
    stall = _first_stall(diagnostics.findings(diagnosed))
    if stall is None:
        return None
    entry = diagnosed[stall.channel]
    return {"channel": stall.channel, "log": entry["event_log"], "start": entry["event_start"],
            "end": entry["event_end"], "share": entry["event_share"]}  # fmt: skip


def training_stall(problem: Problem, start: Mapping[str, float] | None = None) -> dict[str, Any] | None:
    """A stall in the training logs, found by the diagnostics in the residual of the model the run starts from (the
    drive at its limit while the joint does not move its way: the robot held or blocked by something outside it).
    No effect acting throughout a run makes one, so a fit on a log that holds one is pulled toward it; a window that
    leaves it out (``FILE@START:END``) fits without it. None where none is found."""
    setting, _ = _with_nuisance(problem, start or {})
    return _stall(diagnostics.diagnose(problem, evaluate(problem, setting).residuals, problem.adapter.context))


def _fate(effect: Effect, outcome: Outcome) -> tuple[str, str]:
    """What became of one catalog effect in a calibration: (kind, words). Kinds: kept, start, refused, refused
    together (only in a chain with others), aliased, ranked (not kept), unranked."""
    for choice in outcome.chosen:
        if choice.effect.name == effect.name:
            values = ", ".join(f"{k.split('.', 1)[1]} {v:.3g}" for k, v in choice.values.items()
                               if k in effect.nominal())  # fmt: skip
            return "kept", f"kept ({values})"
    if any(k in outcome.started for k in effect.nominal()):
        return "start", "held at the calibration the run started from (not offered again)"
    alone = [r["reason"] for r in outcome.rejected if r["name"] == effect.name]
    if alone:
        return "refused", f"refused: {alone[0]}"
    chains = [r for r in outcome.rejected if effect.name in r["name"].split(" + ")]
    if chains:
        others = " + ".join(n for n in chains[0]["name"].split(" + ") if n != effect.name)
        reason = chains[0]["reason"].removeprefix("together: ")
        return "together", f"refused in a chain with {others}: {reason}"
    ranked = [(entry, len(round_), round_.index(entry)) for round_ in outcome.rounds for entry in round_
              if entry["effect"] == effect.name]  # fmt: skip
    taken = [c.effect.name for c in outcome.chosen if c.effect.alias == effect.alias
             and (not effect.target or c.effect.target in ("", effect.target))]  # fmt: skip
    if ranked and len(ranked) < len(outcome.rounds) and taken:
        return "aliased", f"not offered once {taken[0]} was kept (its alias group, {effect.alias})"
    if ranked:
        entry, of, place = ranked[-1]
        share, p = entry["explained_fraction"], entry["p_value"]
        text = (f"not kept: ranked {place + 1} of {of} in the last ranking it was in, where it explains "
                f"{share:.1%} of the training residual at best (p {p:.2g})")  # fmt: skip
        return "ranked", text + (f"; barely seen on this robot ({effect.weak})" if effect.weak else "")
    if outcome.mode == "fit":
        return "unranked", "not tried: the run fitted only the effects it was given (--fit)"
    return "unranked", "never ranked (the training residual was at its noise floor from the start)"


def trace(adapter: Adapter, outcome: Outcome, found: Sequence[diagnostics.Finding]) -> dict | None:
    """The mechanism the strongest finding points to (:data:`sysid.diagnostics.MECHANISMS`), every catalog effect of
    that kind acting on the finding's channel (:meth:`Adapter.acts_on`) with what became of it in ``outcome``, the
    kinds of effect the robot declares out of its catalog or lacks, and a sentence on what became of them."""
    strongest = next((f for f in found if MECHANISMS.get(f.key, ("", ()))[1] or f.key == "sides"), None)
    if strongest is None:
        return None
    mechanism, kinds = MECHANISMS[strongest.key]
    catalog = adapter.catalog()
    if strongest.key == "sides":  # a per-side effect: every effect on the finding's side
        effects = [e for e in catalog.values() if e.target and adapter.acts_on(e, strongest.channel)]
    else:
        effects = [e for e in catalog.values() if base_name(e) in kinds and adapter.acts_on(e, strongest.channel)]
    fates = {e.name: _fate(e, outcome) for e in effects}
    declared = {base_name(e): e for e in adapter.effects().values()}
    held_out = [k for k in kinds if k in declared and not declared[k].catalogued]
    # a robot with no effect on a body (a bench rig) is not asked for the body's kinds
    body = any(base_name(e) in BODY_KINDS for e in catalog.values())
    lacking = [k for k in kinds if k not in declared and (body or k not in BODY_KINDS)]
    named = {kind: [n for n, (k, _) in fates.items() if k == kind] for kind in
             ("kept", "start", "refused", "together", "aliased", "ranked", "unranked")}  # fmt: skip
    words = {"kept": "kept, and a residual of this kind remains", "start": "held at the starting calibration",
             "refused": "refused", "together": "refused in a chain only", "aliased": "not offered once an effect "
             "of its alias group was kept", "ranked": "ranked but not kept", "unranked": "not tried"}  # fmt: skip
    parts = [f"{', '.join(names)} {words[kind]}" for kind, names in named.items() if names]
    why = mechanism
    if effects:
        why += ": of the catalog's effects of that kind, " + "; ".join(parts)
    else:
        why += ": this robot's catalog has no effect of that kind"
    if held_out:
        why += f"; declared but kept out of the catalog: {', '.join(held_out)}"
    if lacking:
        why += f"; not declared for this robot: {', '.join(lacking)}"
    return {"channel": strongest.channel, "finding": strongest.key, "text": strongest.text, "mechanism": mechanism,
            "effects": {n: {"fate": k, "words": w} for n, (k, w) in fates.items()}, "out_of_catalog": held_out,
            "missing": lacking, "why": why}  # fmt: skip


def _with_nuisance(problem: Problem, setting: Mapping[str, float]) -> tuple[dict[str, float], dict]:
    """``setting`` with the nominal value of each nuisance parameter of the problem's logs (an unlogged goal) it
    does not give, and those parameters."""
    nuisance = problem.adapter.nuisance(problem.logs)
    setting = dict(setting)
    for k, p in nuisance.items():
        setting.setdefault(k, p.nominal)
    return setting, nuisance


def held_out(problem: Problem, setting: Mapping[str, float]) -> HeldOut:
    """The error of ``setting`` on a problem's logs, their nuisance parameters (an unlogged goal) fitted first."""
    setting, nuisance = _with_nuisance(problem, setting)
    if nuisance:
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
    warn: Callable[[str], None] | None = None,
) -> Result:
    """Calibrate ``adapter``'s robot on ``train`` and measure the held-out error on ``test``; with ``effects``,
    fit those effects without selection. ``warn`` (default ``say``) takes what the user must see even when the
    progress is not shown (a stall in a training log)."""
    train_problem = Problem(adapter, train, nthread)
    stall = training_stall(train_problem, start)
    if stall is not None:
        (warn or say)(
            f"warning: {stall['log']} holds a stall on {stall['channel']} between {stall['start']:.2f} and "
            f"{stall['end']:.2f} s ({STALL_SIGN}); {STALL_ADVICE}"
        )
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
                  train_problem, train_stall=stall)  # fmt: skip


def relative_excess(before: float, after: float) -> float:
    """How much of the error's excess over the noise floor remains: (after - 1) / (before - 1)."""
    return float((after - 1.0) / (before - 1.0)) if before > 1.0 else float(np.nan)
