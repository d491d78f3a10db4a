"""The calibration loop: rank the effects the residual points to, fit the best, keep it only if it earns its place,
and stop when nothing helps.

1. Nuisance parameters (what the log does not hold, e.g. an unlogged servo goal) are fitted first, and with every
   candidate after.
2. **Rank** every catalog effect the robot's channels can observe by a score statistic of its parameters at the
   current model: how much of the residual their Jacobian can explain (the residual projected on the columns of
   ``J``, over the residual variance per effective sample; chi^2 with as many degrees of freedom as parameters when
   the effect is absent), or, where larger, what the best point of a small grid across its range explains (the
   only measure for non-smooth effects: delay, backlash, deadband). One batched rollout holds every column.
3. **Fit** the top candidates (those within half the best score) on the training segments and **keep** the best by
   BIC among those that earn their place: they lower the information criterion (BIC on the effective number of
   samples), their cross-validated held-out gain (each of ``FOLDS`` folds of segments, stratified by excitation,
   predicted by a fit on the others) beats a paired bootstrap interval over segments, and the data identify every
   parameter (a 95% interval narrower than half the parameter's range, the value off the range's ends).
   Otherwise record why, and try the next candidate. If no single effect earns its place, chains of two or three
   effects that may help only together are grown by the score statistic at each step's fit (``_chains``); a chain
   whose joint fit leaves members at nominal is tried again without them. Where fits are least squares, every
   candidate is fitted together with the effects already kept (stepwise with refitting: held, their values would hide
   part of it). A kept effect is refitted on every segment jointly with the effects kept before it (backfitting:
   their values had taken up part of its effect).
4. Effects of an alias group that already has a member are not offered again: the data cannot tell them apart. A
   group is per side or channel (:func:`group_of`): a member kept on one side leaves the other side's open.
5. Stop when nothing is kept or the training residual reaches the noise floor.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from envs.common.effects import Effect, Param
from sysid import diagnostics
from sysid.fit import FD_STEP, FitResult, evaluate, fit, fit_intervals, half_widths, rise_at, set_intervals
from sysid.problem import Problem, Setting, flatten, total_objective

MAX_EFFECTS = 4
Z95 = 1.96  # a 95% half-width in standard errors
TRIES_PER_ROUND = 3
NOISE_FLOOR = 1.05  # stop when the training error is this close to the noise floor (or within explained_below)
# A held-out error above this many noise levels is "unexplained": with the test logs' thousands of samples, the error
# of the true model sits within a few percent of 1 (tests/test_calibration.py checks the null case). Where the noise
# level holds a replay floor (sysid/problem.py), itself estimated from a few segments, the threshold widens by that
# estimate's uncertainty (``explained_below``).
UNEXPLAINED_ABOVE = 1.1
SCORE_GRID = 5  # grid points across the range of a non-smooth effect in the ranking
SCORE_GRID_PERIODIC = 12  # around the turn of a periodic parameter (Param.periodic): 30 degrees apart
SCORE_GRID_SMOOTH = 3  # and of a smooth one (which also has its Jacobian), unless it is a scale over decades
# (``Param.log``), whose grid is SCORE_GRID points spread geometrically: a linear grid over decades misses a basin
# below nominal
CHAIN_DEPTH = 3  # effects that help only together: chains of up to this many effects (the breadth of the search is
# the adapter's ``chain_search``: seeds, width, beam)
CONTENDERS = 0.5  # candidates scoring at least this share of the best are all fitted before one is kept
FOLDS = 3  # folds of the held-out test
MAX_DECISION_SEGMENTS = 12  # segments the loop decides on; kept effects are refitted on all
# the held-out test's margin for a channel made worse (``_held_out_test``): a rise of the channel's mean square by this
# many noise variances, which takes an RMS error of 1 (the noise floor) to 1.05, half the band within which the loop
# calls a residual explained (UNEXPLAINED_ABOVE)
CHANNEL_MARGIN = 0.1


@dataclass
class Choice:
    effect: Effect
    values: dict[str, float]
    bounds95: dict[str, tuple[float, float]]  # the 95% intervals, (low, high)
    score: float
    training_error: float
    together: list[str] = field(default_factory=list)  # effects kept in the same step (a pair)

    @property
    def ci95(self) -> dict[str, float]:
        """The intervals' half-widths (the larger side)."""
        return half_widths(self.values, self.bounds95)


@dataclass
class Outcome:
    setting: dict[str, float]
    nominal: dict[str, float]
    chosen: list[Choice] = field(default_factory=list)
    rejected: list[dict[str, str]] = field(default_factory=list)
    rounds: list[list[dict]] = field(default_factory=list)
    nuisance: dict[str, float] = field(default_factory=dict)
    training_errors: list[float] = field(default_factory=list)
    history: list[dict[str, float]] = field(default_factory=list)  # the setting before and after each kept effect
    mode: str = "select"  # "fit": the effects were named by the user (calibrate.py --fit), not selected
    diagnostics_before: dict = field(default_factory=dict)
    diagnostics_after: dict = field(default_factory=dict)
    started: list[str] = field(default_factory=list)  # the parameters a starting calibration held (not offered)


def _floor_band(problem: Problem) -> float:
    """The error within which a right model lies when the noise level holds a replay floor measured on few
    segments: 1 plus twice the relative standard error of the noise level (as a variance); 1 for sensor noise."""
    return math.sqrt(1.0 + 2.0 * problem.floor_uncertainty)


def explained_below(problem: Problem) -> float:
    """The held-out error below which a model explains a problem's logs: 1.1, or the replay floor's band
    (:func:`_floor_band`) where that is larger."""
    return max(UNEXPLAINED_ABOVE, _floor_band(problem))


def at_floor(problem: Problem, error: float) -> bool:
    """The loop's stopping rule: the training error is within NOISE_FLOOR of the noise level, or, where the noise
    level holds a replay floor, within that floor's own uncertainty (the band in which the error of a right model
    lies, as :func:`explained_below` says on held-out logs). Inside that band a fit has nothing left to explain
    and can only lower the floor itself: on noise-only logs of a legged robot, an effect that damps the body's
    carried motion replays a few percent closer."""
    return error <= max(NOISE_FLOOR, _floor_band(problem))


def decision_segments(problem: Problem) -> list[int]:
    """The segments the loop decides on (ranking, fits, held-out tests): all of them up to MAX_DECISION_SEGMENTS,
    else that many spread evenly over the segments sorted by excitation (variance of the measured channels over
    the noise), so quiet and lively stretches are both represented. Kept effects are refitted on every segment."""
    scored = problem.scored
    n = len(scored)
    if n <= MAX_DECISION_SEGMENTS:
        return list(scored)
    order = _by_excitation(problem, scored)
    picks = np.unique(np.round(np.linspace(0, n - 1, MAX_DECISION_SEGMENTS)).astype(int))
    return sorted(order[k] for k in picks)


def _by_excitation(problem: Problem, index) -> list[int]:
    excitation = {i: float(np.sum(np.var(problem.segments[i].measured, axis=0) / problem._sigma**2)) for i in index}
    return sorted(index, key=lambda i: (excitation[i], i))


def split(problem: Problem, index: Sequence[int]) -> list[list[int]]:
    """Held-out folds of the segments ``index``, stratified by excitation: sorted by how much their measured
    channels move, the segments are dealt out in turn to FOLDS folds, so every fold holds quiet and lively ones.
    Every fold is held out in turn (cross-validation), so every segment's gain is measured once."""
    order = _by_excitation(problem, list(index))
    n = len(order)
    folds = [sorted(order[k] for k in range(start, n, FOLDS)) for start in (1, 2, 0)]
    return [f for f in folds if f]


def nominal_setting(effects: Mapping[str, Effect], start: Mapping[str, float] | None = None) -> dict[str, float]:
    setting = {}
    for e in effects.values():
        setting.update(e.nominal())
    setting.update(start or {})
    return setting


def _params(effect: Effect) -> dict[str, Param]:
    return {effect.key(p.name): p for p in effect.params}


def _chosen_params(choices: Sequence[Choice]) -> dict[str, Param]:
    """The parameters of kept effects, flat."""
    return {k: p for c in choices for k, p in _params(c.effect).items()}


def _fd_probe(problem: Problem, current: Setting, key: str, p: Param) -> tuple[dict[str, float], float]:
    """A finite-difference probe of one smooth parameter at ``current`` (toward the middle of its range): the
    setting and the step."""
    fd = max(FD_STEP * 10, problem.adapter.fd_step)
    step = (fd if (current[key] - p.low) / p.span < 0.5 else -fd) * p.span
    return {**current, key: current[key] + step}, step


def _bounds(result: FitResult, effect: Effect) -> dict[str, tuple[float, float]]:
    """An effect's 95% intervals from a fit (NaN where the fit has none)."""
    return {k: result.bounds95.get(k, (math.nan, math.nan)) for k in _params(effect)}


def calibrate(
    problem: Problem,
    start: Mapping[str, float] | None = None,
    say: Callable[[str], None] = print,
) -> Outcome:
    """Run the loop on a problem's segments (the training logs)."""
    adapter = problem.adapter
    effects = adapter.catalog()
    nuisance = adapter.nuisance(problem.logs)
    fitting = decision_segments(problem)
    folds = split(problem, fitting)
    # the ranking, fits and held-out tests read the decision segments, replayed as Problem.decisions says; kept
    # effects are refitted, and errors measured, on every segment
    whole, problem = problem, problem.decisions(fitting)
    on_all = len(fitting) == len(whole.scored)  # the decisions see every segment: no refit, the same residuals
    current = nominal_setting(effects, start)
    nominal = dict(current)
    if nuisance:  # what the log does not hold is fitted on every segment that shows it
        current = fit(whole, current, nuisance).values
        nominal.update({k: current[k] for k in nuisance})
    outcome = Outcome(setting=current, nominal=nominal, nuisance={k: current[k] for k in nuisance},
                      started=sorted(start or {}))  # fmt: skip
    outcome.history.append(dict(current))
    everything = evaluate(whole, current)
    before = everything if on_all else evaluate(problem, current, fitting)
    outcome.diagnostics_before = diagnostics.diagnose(whole, everything.residuals, adapter.context)
    outcome.training_errors.append(everything.error)
    say(f"nominal model: error {everything.error:.2f} on the training logs")
    offered = {k: e for k, e in effects.items() if not any(key in (start or {}) for key in e.nominal())}
    used_groups: set[tuple[str, str]] = set()
    # candidates fitted with the kept effects, and the backward step (below; ``Adapter.stepwise``)
    stepwise = adapter.stepwise if adapter.stepwise is not None else not adapter.rough_cost
    for _ in range(MAX_EFFECTS):
        if at_floor(problem, outcome.training_errors[-1]):
            say("the residual is at the noise floor: stop")
            break
        candidates = {k: e for k, e in offered.items() if not aliased(e, used_groups)}
        if not candidates:
            break
        # the effects kept so far are fitted again with every candidate (stepwise with refitting): held at values
        # that took up part of the candidate's effect, they would hide it (a delay fitted first, without the torque
        # constant also at work, comes out short and leaves the torque constant too little to explain); with the
        # nuisance parameters, they are what the candidate is fitted beside, and what the ranking takes as
        # refitted. Where fits are derivative-free (``rough_cost``: contacts), a joint fit of every candidate costs
        # several times a single one: unless the robot asks for it (``Adapter.stepwise``), the kept effects are
        # held (the backfit after a keep still refits them)
        beside = {**(_chosen_params(outcome.chosen) if stepwise else {}), **nuisance}
        ranking = score(problem, current, candidates, fitting, beside if stepwise else None)
        outcome.rounds.append(ranking)
        say("ranking: " + ", ".join(f"{r['effect']} {r['score']:.1f}" for r in ranking[:5]))
        # the close contenders (a score within CONTENDERS of the best) are all fitted and the best by BIC is kept;
        # if none earns its place, the next ones are tried in turn; if no single effect does, chains of effects
        # that may help only together (_chains)
        significant = [e for e in ranking if e["p_value"] <= 0.05]
        top = significant[0]["score"] if significant else 0.0
        first = [e for e in significant[:TRIES_PER_ROUND] if e["score"] >= CONTENDERS * top]
        later = significant[len(first) : TRIES_PER_ROUND]
        failed: dict[str, str] = {}
        singles: list[tuple[float, Effect, dict, FitResult]] = []

        def attempt(group_effects: list[Effect], start_values: Mapping[str, float], current=current, before=before,
                    beside=beside):  # fmt: skip
            """Fit and test effects together: (verdict, fit, BIC change); the verdict is None if they earn their
            place."""
            verdict, trial, bic = _fit_candidate(problem, current, group_effects, beside, fitting, before,
                                                 start_values)  # fmt: skip
            if verdict is None:
                verdict = _identified(problem, group_effects, beside, fitting, trial) or _held_out_test(
                    problem, current, group_effects, beside, fitting, folds, trial
                )
            _record(group_effects, verdict)
            return verdict, trial, bic

        def _record(group_effects: list[Effect], verdict: str | None, failed=failed) -> None:
            label = " + ".join(e.name for e in group_effects)
            if verdict is not None:
                failed.setdefault(label, verdict)
                say(f"rejected {label}: {verdict}")

        chosen_group = None
        for stage in (first, later):
            # every candidate of the stage is fitted; those that pass the fit's own tests (range, identifiability,
            # information criterion) face the held-out test in order of their BIC, until one passes
            passing = []
            for entry in stage:
                effect = candidates[entry["effect"]]
                verdict, trial, bic = _fit_candidate(problem, current, [effect], beside, fitting, before,
                                                     entry["start"])  # fmt: skip
                if entry.get("measured") is not None and trial.objective > entry["measured"][1]:
                    # the local fit from nominal ended above a point the ranking measured: it stalled (a cost
                    # so curved that its steps fail, the pwm decay's); it is fitted again from that point, and the
                    # better of the two fits stands
                    again = {**entry, "start": entry["measured"][0]}
                    retry = _fit_candidate(problem, current, [effect], beside, fitting, before, again["start"])
                    if retry[1].objective < trial.objective:
                        entry, (verdict, trial, bic) = again, retry
                singles.append((trial.cost, effect, entry, trial))
                if verdict is None:
                    passing.append((bic, [effect], [entry], trial))
                else:
                    _record([effect], verdict)
            passing.sort(key=lambda x: x[0])
            for k, (bic, group_effects, entries, trial) in enumerate(passing):
                verdict = _identified(problem, group_effects, beside, fitting, trial) or _held_out_test(
                    problem, current, group_effects, beside, fitting, folds, trial
                )
                if verdict is None:
                    chosen_group = (bic, group_effects, entries, trial)
                    for _, others, _, _ in passing[k + 1 :]:
                        say(f"{others[0].name} also fits, less well than {group_effects[0].name} by BIC")
                    break
                _record(group_effects, verdict)
            if chosen_group is not None:
                break
        if chosen_group is None and singles:
            chosen_group = _chains(problem, current, candidates, singles, fitting, used_groups, attempt, say)
        if chosen_group is not None:
            _, group_effects, entries, trial = chosen_group
            label = " + ".join(e.name for e in group_effects)
            params = {k: p for e in group_effects for k, p in _params(e).items()}
            # the effects kept before were fitted without this one, and their values took up some of its part (a
            # servo's gain fitted before its delay was known comes out low): they are refitted with it, jointly
            # (backfitting), so that a later round does not keep a third effect to mend the bias of the first
            earlier = _chosen_params(outcome.chosen)
            if on_all and not earlier:  # the fit already saw every segment
                refit = trial
            else:
                refit = fit(whole, current, {**earlier, **params, **nuisance}, None, start=trial.values, local="fine")
            current = refit.values
            for choice in outcome.chosen:  # their values and intervals as the joint fit has them
                choice.values = {k: current[k] for k in _params(choice.effect)}
                choice.bounds95 = _bounds(refit, choice.effect)
            outcome.training_errors.append(refit.error)
            floor_moved = adapter.replay_floor and refit.error > NOISE_FLOOR
            compared = refit  # the joint fit as the backward step compares it: under the floor of the loop's next turn
            if floor_moved:  # the loop goes on: from this model's floor
                problem.set_floor(current)  # the whole problem's, which a decision problem adopts
                compared = evaluate(whole, current)
                outcome.training_errors[-1] = compared.error
            before = refit if on_all and not floor_moved else evaluate(problem, current, fitting)
            for effect, entry in zip(group_effects, entries, strict=True):
                outcome.chosen.append(
                    Choice(effect, {k: current[k] for k in _params(effect)}, _bounds(refit, effect), entry["score"],
                           outcome.training_errors[-1], together=[e.name for e in group_effects if e is not effect])
                )  # fmt: skip
                outcome.history.append(dict(current))
                used_groups.add(group_of(effect))
                offered.pop(effect.name)
                failed.pop(effect.name, None)
            say(f"kept {label}: error {outcome.training_errors[-1]:.2f} on the training logs")
            if stepwise and _drop_idle(whole, outcome, len(group_effects), nuisance, compared, say):
                current = outcome.setting
                used_groups.intersection_update(group_of(c.effect) for c in outcome.chosen)
                before = evaluate(problem, current, fitting)
        for label, verdict in failed.items():
            if " + " not in label:
                outcome.rejected.append({"name": label, "reason": verdict})
                offered.pop(label, None)
            elif chosen_group is None:
                outcome.rejected.append({"name": label, "reason": "together: " + verdict})
        kept = chosen_group is not None
        if not kept:
            break
    for k in nuisance:
        outcome.nuisance[k] = current[k]
    outcome.setting = current
    outcome.diagnostics_after = diagnostics.diagnose(whole, whole.residuals([current])[0], adapter.context)
    return outcome


def _drop_idle(
    problem: Problem, outcome: Outcome, new: int, nuisance: Mapping[str, Param], refit: FitResult, say
) -> bool:
    """The backward step of stepwise selection: an effect kept before the ``new`` last ones may have stood in for
    what they do (a supply voltage kept first, in place of the back-EMF constant kept later). Each is taken out in
    turn and the rest refitted on every segment; the one whose absence costs least is dropped if the model without
    it is no worse by the information criterion. It goes to ``rejected``, its step out of the history (each step
    is then the final model with the effects kept after it at nominal), and its alias group is free again. Returns
    whether one was dropped; ``outcome.setting`` then holds the refit. The criterion is a candidate's
    (:func:`_bic_change`), read from the model with the effect to the model without it."""
    n_eff = refit.n_eff
    best = None
    for c in outcome.chosen[:-new]:
        nominal = {k: p.nominal for k, p in _params(c.effect).items()}
        rest = {**_chosen_params([o for o in outcome.chosen if o is not c]), **nuisance}
        again = fit(problem, {**refit.values, **nominal}, rest, None, start=refit.values, local="fine",
                    intervals=False)  # fmt: skip
        bic = _bic_change(problem, again, refit, -len(nominal))
        if best is None or bic < best[0]:
            best = (bic, c, again, nominal, rest)
    if best is None or best[0] > 0:
        return False
    bic, idle, again, nominal, rest = best
    set_intervals(again, fit_intervals(problem, again, rest, None))
    later = ", ".join(c.effect.name for c in outcome.chosen[-new:])
    shown = ", ".join(f"{k} {refit.values[k]:.4g}" for k in nominal)
    outcome.rejected.append({"name": idle.effect.name, "reason": (
        f"kept, then dropped once {later} was kept: the model without it ({shown} in the joint fit), refitted, "
        f"is no worse by the information criterion (BIC change {bic:+.1f} on {n_eff:.0f} effective samples)"
    )})  # fmt: skip
    outcome.chosen = [c for c in outcome.chosen if c is not idle]
    # the history: after each kept effect, the final model with the effects kept after it at nominal (the path's
    # own settings held the dropped effect); the effects of this step share the final model
    this_step = len(outcome.chosen) - new
    after = [outcome.chosen[i + 1 :] if i < this_step else [] for i in range(len(outcome.chosen))]
    outcome.history = [outcome.history[0]] + [
        {**again.values, **{k: p.nominal for k, p in _chosen_params(tail).items()}} for tail in after
    ]
    for choice in outcome.chosen:
        choice.values = {k: again.values[k] for k in _params(choice.effect)}
        choice.bounds95 = _bounds(again, choice.effect)
        choice.together = [name for name in choice.together if name != idle.effect.name]
    for choice in outcome.chosen[-new:]:
        choice.training_error = again.error
    outcome.training_errors[-1] = again.error
    outcome.setting = dict(again.values)
    say(f"dropped {idle.effect.name}: {later} {'explain' if new > 1 else 'explains'} what it did; error "
        f"{again.error:.2f} on the training logs")  # fmt: skip
    return True


def fit_chosen(
    problem: Problem,
    names: Sequence[str],
    start: Mapping[str, float] | None = None,
    say: Callable[[str], None] = print,
) -> Outcome:
    """Fit the named effects together, without selection (``calibrate.py --fit``): for effects the user already
    chose, as ``mujoco.sysid`` does, with the same intervals and report."""
    adapter = problem.adapter
    effects = adapter.catalog()
    unknown = [n for n in names if n not in effects]
    if unknown:
        raise ValueError(f"--fit {unknown[0]!r}: {adapter.name} has no such effect (known: {', '.join(effects)})")
    nuisance = adapter.nuisance(problem.logs)
    current = nominal_setting(effects, start)
    current.update({k: p.nominal for k, p in nuisance.items() if k not in current})
    if nuisance:
        current = fit(problem, current, nuisance).values
    outcome = Outcome(setting=current, nominal=dict(current), nuisance={k: current[k] for k in nuisance}, mode="fit",
                      started=sorted(start or {}))  # fmt: skip
    outcome.history.append(dict(current))
    before = evaluate(problem, current)
    outcome.training_errors.append(before.error)
    outcome.diagnostics_before = diagnostics.diagnose(problem, before.residuals, adapter.context)
    params = {k: p for n in names for k, p in _params(effects[n]).items()}
    result = fit(problem, current, {**params, **nuisance})
    current = result.values
    outcome.training_errors.append(result.error)
    for n in names:
        e = effects[n]
        outcome.chosen.append(Choice(e, {k: current[k] for k in _params(e)}, _bounds(result, e), float("nan"),
                                     result.error, together=[m for m in names if m != n]))  # fmt: skip
        outcome.history.append(dict(current))
    say(f"fitted {', '.join(names)}: error {before.error:.2f} -> {result.error:.2f} on the training logs")
    outcome.setting = current
    outcome.nuisance = {k: current[k] for k in nuisance}
    outcome.diagnostics_after = diagnostics.diagnose(problem, result.residuals, adapter.context)
    return outcome


def score_grid(effect: Effect, points: int | None = None) -> list[dict[str, float]]:
    """The ranking's grid points across an effect's range (a diagonal for several parameters): SCORE_GRID of them
    for a non-smooth effect or a scale over decades (spread geometrically: ``Param.log``), SCORE_GRID_SMOOTH for
    another smooth one (which has its Jacobian too), SCORE_GRID_PERIODIC around the turn of a periodic one (its two
    ends one point, counted once); at least ``points`` (a robot's ``Adapter.score_grid``)."""
    n = SCORE_GRID if not effect.smooth or any(p.log for p in effect.params) else SCORE_GRID_SMOOTH
    periodic = any(p.periodic for p in effect.params)
    n = max(n, points or 0, SCORE_GRID_PERIODIC if periodic else 0)
    return [{effect.key(p.name): float(p.low * (p.high / p.low) ** f if p.log else p.low + f * p.span)
             for p in effect.params} for f in np.linspace(0.0, 1.0, n, endpoint=not periodic)]  # fmt: skip


def score(
    problem: Problem,
    current: Setting,
    candidates: Mapping[str, Effect],
    segments,
    beside: Mapping[str, Param] | None = None,
) -> list[dict]:
    """Each candidate's score statistic at ``current``, highest first.

    For an effect's parameters the statistic is the residual sum of squares their Jacobian can explain (the
    residual projected on its columns) over the residual variance per effective sample: chi^2 with as many degrees
    of freedom as parameters when the effect is absent. A linearization at the nominal value misjudges large
    effects (and says nothing of non-smooth ones), so each effect is also tried on a small grid across its range
    (a diagonal for several parameters); the statistic is the larger of the two reductions. Every Jacobian column
    and grid point runs in one batched rollout. Each entry keeps its best grid point, where its fit starts.

    ``beside``: smooth parameters fitted with every candidate (the effects kept so far, the nuisance). The statistic
    is then the score test's with them refitted: the candidate's columns are taken orthogonal to theirs before the
    residual is projected, so that a candidate whose direction the kept effects' columns nearly share (a back-EMF
    constant beside a supply voltage kept first) is measured by what it adds, not hidden by what they took.
    """
    base = evaluate(problem, current, segments)
    r0 = flatten(base.residuals)
    s2 = base.cost / base.n_eff  # residual variance per effective sample
    probes, owners = [], []
    for name, e in candidates.items():
        for p in e.params:
            if p.smooth:
                probe, step = _fd_probe(problem, current, e.key(p.name), p)
                probes.append(probe)
                owners.append((name, "fd", step))
        for point in score_grid(e, problem.adapter.score_grid):
            if all(np.isclose(v, current[k]) for k, v in point.items()):
                continue
            probes.append({**current, **point})
            owners.append((name, "grid", point))
    for key, p in (beside or {}).items():
        if p.smooth and p.span > 0:
            probe, step = _fd_probe(problem, current, key, p)
            probes.append(probe)
            owners.append((None, "held", step))
    # a carried effect's grid points run with their own carried state (Effect.carried): its action through the
    # body shows only so; the rest, anchored at ``current``, in one batched rollout
    own = [k for k, (name, kind, _) in enumerate(owners) if kind == "grid" and candidates[name].carried]
    anchored = [k for k in range(len(owners)) if k not in set(own)]
    columns: list = [None] * len(owners)
    for rows, anchor in ((anchored, current), (own, None)):
        if rows:
            ran = problem.residuals([probes[k] for k in rows], segments, anchor=anchor)
            for k, col in zip(rows, ran, strict=True):
                columns[k] = col
    by_effect: dict[str, dict] = {n: {"jac": [], "grid": []} for n in candidates}
    held = []
    for (name, kind, arg), col in zip(owners, columns, strict=True):
        r = flatten(col)
        if kind == "held":
            held.append((r - r0) / arg)
        elif kind == "fd":
            by_effect[name]["jac"].append((r - r0) / arg)
        else:
            by_effect[name]["grid"].append((float(r @ r), arg, total_objective(col)))
    out = []
    for name, e in candidates.items():
        parts = by_effect[name]
        explained, start, measured = 0.0, {}, None
        if parts["jac"]:
            jac = np.column_stack(parts["jac"])
            if held:  # the part of each column the parameters fitted beside it cannot make
                other = np.column_stack(held)
                jac = jac - other @ np.linalg.lstsq(other, jac, rcond=None)[0]
            coef, *_ = np.linalg.lstsq(jac, r0, rcond=None)
            fitted = jac @ coef
            explained = float(fitted @ fitted)
        if parts["grid"]:
            cost, point, objective = min(parts["grid"], key=lambda x: x[0])
            if base.cost - cost > explained or not parts["jac"]:
                explained, start = base.cost - cost, point
            elif cost < base.cost:  # the fit starts at nominal (the Jacobian promises more), this point is measured
                measured = (point, objective)
        stat = max(explained, 0.0) / max(s2, 1e-300)
        out.append({"effect": name, "alias_group": e.alias, "score": stat,
                    "p_value": float(stats.chi2.sf(stat, len(e.params))),
                    "explained_fraction": max(explained, 0.0) / max(base.cost, 1e-300), "start": start,
                    "measured": measured})  # fmt: skip
    out.sort(key=lambda d: -d["score"])
    return out


def _chains(problem: Problem, current: Setting, candidates, singles, fitting, used_groups, attempt, say):
    """Effects that help only together: when no single effect earns its place, a beam search over chains, from the
    singles that fitted best (``seeds`` of them, the adapter's ``chain_search``). Each chain grows by each of the
    ``width`` candidates the score statistic ranks highest at its fitted values (what the residual still points to
    once the chain is in); each grown chain is fitted jointly and tested by the same rules as a single effect; the
    ``beam`` best of each length (by training cost) grow on, up to CHAIN_DEPTH effects. The first chain that earns
    its place is returned as (BIC change, effects, ranking entries, fit)."""
    seeds, width, beam = problem.adapter.chain_search
    tried: set[frozenset[str]] = set()  # a joint fit is of a set of effects: one met in another order is not refitted

    def first_time(effects: Sequence[Effect]) -> bool:
        """Whether this set of effects is met for the first time (it is then marked as tried)."""
        key = frozenset(e.name for e in effects)
        new = key not in tried
        tried.add(key)
        return new

    for _, seed, seed_entry, seed_trial in sorted(singles, key=lambda x: x[0])[:seeds]:
        frontier = [([seed], [seed_entry], seed_trial)]
        for _length in range(2, CHAIN_DEPTH + 1):
            grown = []
            for chain, entries, trial in frontier:
                groups = {group_of(e) for e in chain} | used_groups
                rest = {k: e for k, e in candidates.items() if not aliased(e, groups)}
                if not rest:
                    continue
                ranking = [e for e in score(problem, trial.values, rest, fitting) if e["p_value"] <= 0.05]
                for entry in ranking[:width]:
                    effects, chain_entries = [*chain, candidates[entry["effect"]]], [*entries, entry]
                    if not first_time(effects):
                        continue
                    say(f"trying together: {' + '.join(e.name for e in effects)}")
                    verdict, fitted, bic = attempt(effects, {**trial.values, **entry["start"]})
                    if verdict is None:
                        return bic, effects, chain_entries, fitted
                    # a chain whose joint fit leaves some of its members at nominal (their intervals hold it) says
                    # the others may be at work without them: the chain without them is fitted from there (the
                    # seed of a chain is only the single that fitted best, and may be the member the data reject)
                    idle = _unidentified(effects, fitted) if verdict.startswith("not told from nominal") else []
                    kept = [(e, en) for e, en in zip(effects, chain_entries, strict=True) if e not in idle]
                    if idle and len(kept) >= 2 and first_time([e for e, _ in kept]):
                        pruned = [e for e, _ in kept]
                        say(f"trying together: {' + '.join(e.name for e in pruned)} (without "
                            f"{', '.join(e.name for e in idle)}, which the joint fit left at nominal)")  # fmt: skip
                        verdict, refitted, bic = attempt(pruned, fitted.values)
                        if verdict is None:
                            return bic, pruned, [en for _, en in kept], refitted
                    grown.append((effects, chain_entries, fitted))
            frontier = sorted(grown, key=lambda x: x[2].cost)[:beam]
            if not frontier:
                break
    return None


def group_of(effect: Effect) -> tuple[str, str]:
    """An effect's alias group and its target: effects of one group alias each other on one side or channel, and
    an effect on no side (a supply) aliases its group's members on every side, but the left motor's torque constant
    does not stand for the right one's."""
    return effect.alias, effect.target


def aliased(effect: Effect, used: set[tuple[str, str]]) -> bool:
    """Whether a kept effect has found ``effect``'s group already: one of its group on its target, or on none; for
    an effect on no target, one of its group on any."""
    if not effect.target:
        return any(group == effect.alias for group, _ in used)
    return (effect.alias, effect.target) in used or (effect.alias, "") in used


def _fit_candidate(
    problem: Problem,
    current: Setting,
    effects: Sequence[Effect],
    nuisance: Mapping[str, Param],
    fitting,
    before: FitResult,
    start: Mapping[str, float],
) -> tuple[str | None, FitResult, float]:
    """Fit effects together on the fitting segments, without intervals yet: (None if the fit passes its first
    tests, else the reason; the fit; the BIC change). The tests: no parameter at the end of its range, and a lower
    information criterion (BIC on the effective samples)."""
    params = {k: p for e in effects for k, p in _params(e).items()}
    trial = fit(problem, current, {**params, **nuisance}, fitting, start=start, intervals=False)
    for k, p in params.items():
        value = trial.values[k]
        at_end = not p.periodic and min(value - p.low, p.high - value) < 0.01 * p.span  # a turn has no end
        if p.span > 0 and at_end and not np.isclose(value, p.nominal):
            asked = _asked_for(problem, current, params, nuisance, fitting, trial, k) if len(effects) == 1 else ""
            return (
                f"{k} pushes against the end of its range ({value:.3g} {p.unit}, range [{p.low:g}, {p.high:g}])"
                f"{asked}: something else is at work",
                trial,
                0.0,
            )
    n_eff = before.n_eff
    bic = _bic_change(problem, trial, before, len(params))
    if bic >= 0:
        return (
            f"no better by the information criterion (BIC change {bic:+.1f} on {n_eff:.0f} effective samples)",
            trial,
            bic,
        )
    return None, trial, bic


def _bic_change(problem: Problem, trial: FitResult, before: FitResult, added: int) -> float:
    """The information criterion's change from ``before`` to ``trial``, which has ``added`` more parameters
    (negative: fewer), on ``before``'s effective samples."""
    n_eff = before.n_eff
    if problem.adapter.segment_variance:  # -2 log-likelihood itself (each segment's variance profiled out), its
        # samples discounted to the effective ones
        fit_term = (trial.objective - before.objective) * n_eff / max(before.n, 1)
    else:  # one variance for all, profiled out
        fit_term = n_eff * math.log(max(trial.cost, 1e-300) / max(before.cost, 1e-300))
    return fit_term + added * math.log(n_eff)


def _asked_for(
    problem: Problem,
    current: Setting,
    params: Mapping[str, Param],
    nuisance: Mapping[str, Param],
    fitting,
    trial: FitResult,
    key: str,
) -> str:
    """What the data ask of a parameter that a fit pushed to an end of its range: the fit again with that end moved
    out by the range's span, for this question only; the model keeps its range, widened only with a physical reason
    written beside it. A range that starts at 0 is not moved below it; one that starts above 0 (a scale, a mass)
    stays above it, its low end moved out by the range's ratio instead (a scale's [0.5, 2] to [0.125, 2]): a scale
    of 0 is no model (a body without mass does not compile). Where the wider range's model still cannot be built,
    the report says so rather than the run ending."""
    p = params[key]
    value = trial.values[key]
    if abs(p.high - value) <= abs(value - p.low):
        low, high = p.low, p.high + p.span
    elif p.low > 0:
        low, high = p.low * p.low / p.high, p.high
    else:
        low, high = (0.0 if p.low == 0 else p.low - p.span), p.high
    if np.isclose(low, p.low) and np.isclose(high, p.high):
        return ""
    wide = replace(p, low=low, high=high)
    try:
        again = fit(problem, current, {**params, key: wide, **nuisance}, fitting, start=trial.values, intervals=False)
    except ValueError as exc:  # MuJoCo refuses a model of the wider range (its compiler's errors are ValueErrors)
        return f"; over [{low:.3g}, {high:.3g}] the model cannot be built ({str(exc).splitlines()[0]})"
    asked = again.values[key]
    still = ", again at that end" if min(asked - low, high - asked) < 0.01 * wide.span else ""
    return f"; over [{low:.3g}, {high:.3g}] the data ask for {asked:.3g}{still}"


def _identified(
    problem: Problem, effects: Sequence[Effect], nuisance: Mapping[str, Param], fitting, trial: FitResult
) -> str | None:
    """The fit's 95% intervals (computed now, for the candidate about to be tested; (low, high), one-sided where the
    cost is flat on one side), and whether the data identify every parameter: an interval no wider than the
    parameter's range, and the estimate more than one standard error from an end of the range other than nominal,
    the standard error read on the interval's other side (1.96 of them from the estimate to that side's end): how
    tightly the data hold the estimate from within. Closer, the estimate sits at the end: the data would take it
    further, something else is at work (the roach's 2 Hz log needs this test: docs/real-logs.md, "VelociRoACH 2
    Hz"). A cost flat from the estimate out to the end (a friction above which the leg stalls anyway) is no such
    push: the estimate is a lower bound and the interval says so. Nor is an end that the interval reaches only by
    its shape (a rough cost's parabola is symmetric): where the cost at the end itself rises above the estimate's by
    more than the interval's threshold (:func:`sysid.fit.rise_at`), the data hold the estimate inside, and the
    interval is cut at the end (tests/test_calibration.py,
    test_an_estimate_near_the_end_is_refused_only_where_the_cost_does_not_rise_there). And whether each effect is
    there at all: at least one of its parameters' intervals leaves out the nominal value (a
    Wald test at 5%, read on the side toward nominal; an estimate the interval cannot tell from nominal is no
    evidence of the effect). None if so, else the reason."""
    params = {k: p for e in effects for k, p in _params(e).items()}
    set_intervals(trial, fit_intervals(problem, trial, {**params, **nuisance}, fitting))
    nowhere = (-math.inf, math.inf)
    for k, p in params.items():
        low, high = trial.bounds95.get(k, nowhere)
        if not (np.isfinite(low) and np.isfinite(high)) or high - low > p.span:
            return (f"the data cannot identify {k}: 95% interval [{low:.3g}, {high:.3g}] {p.unit} over a range of "
                    f"{p.span:.3g}")  # fmt: skip
    for k, p in params.items():  # the fit's own end-of-range test, read through the interval
        value, (low, high) = trial.values[k], trial.bounds95.get(k, nowhere)
        for bound, inner in ((p.low, high - value), (p.high, value - low)):
            if not np.isclose(bound, p.nominal) and abs(value - bound) < inner / Z95:
                if rise_at(problem, trial, k, p, bound, len(params), fitting) > 1.0:
                    # the cost at the end itself lies beyond the interval's threshold: a rough cost's parabola
                    # (symmetric) put the end inside the interval, the profile read there does not; the data
                    # hold the estimate inside the range, and its interval ends at the range's end
                    low, high = max(low, p.low), min(high, p.high)
                    trial.bounds95[k] = (low, high)
                    continue
                return (
                    f"{k} {value:.3g} [{low:.3g}, {high:.3g}] {p.unit}: within one standard error of the "
                    f"end of its range ({bound:g}), the data would take it further: something else is at work"
                )
    idle = _unidentified(effects, trial)
    if not idle:
        return None
    own = _params(idle[0])
    shown = ", ".join(f"{k} {trial.values[k]:.3g} [{trial.bounds95[k][0]:.3g}, {trial.bounds95[k][1]:.3g}] (nominal "
                      f"{p.nominal:.3g})" for k, p in own.items())  # fmt: skip
    return f"not told from nominal: {shown}"


def _unidentified(effects: Sequence[Effect], trial: FitResult) -> list[Effect]:
    """The effects of a fit that its 95% intervals cannot tell from nominal (every parameter's interval holds its
    nominal value): no evidence that they are there. Empty where the fit has no intervals yet."""
    out = []
    for e in effects:
        own = _params(e)
        if all(k in trial.bounds95 and trial.bounds95[k][0] <= p.nominal <= trial.bounds95[k][1]
               for k, p in own.items()):  # fmt: skip
            out.append(e)
    return out


def _held_out_test(
    problem: Problem,
    current: Setting,
    effects: Sequence[Effect],
    nuisance: Mapping[str, Param],
    fitting,
    folds: Sequence[Sequence[int]],
    trial: FitResult,
) -> str | None:
    """The held-out gain, cross-validated: each fold's segments are predicted by a fit on the others (started at
    the full fit, searched locally, no intervals), and the paired gains of every segment are bootstrapped. None if
    the interval's lower end is above zero and no channel is made worse, else the reason.

    A channel made worse: the paired bootstrap interval of one channel's gain per segment (its mean square, in noise
    variances) lies wholly below -CHANNEL_MARGIN (at 95% over all the channels together, Bonferroni): a one-sided
    test against a margin, so that a loss too small to show in any reported error is no trade, however consistent
    (a sensor bias whose refitted start moves another channel by a hundredth of the noise on every segment). An
    effect the model truly lacks brings each channel's expected error down or leaves it (the true model minimizes
    every channel's); one that trades a channel for another stands in for something else (a right-side friction
    taking up a push on the body, which the left side's channels then show)."""
    params = {k: p for e in effects for k, p in _params(e).items()}
    gains, channel_gains = [], []
    for fold in folds:
        rest = [i for i in (fitting if fitting is not None else problem.scored) if i not in fold]
        fitted = (
            fit(problem, current, {**params, **nuisance}, rest, start=trial.values, local=True, intervals=False)
            if rest
            else trial
        )
        old_residuals = problem.residuals([current], fold)[0]
        new_residuals = problem.residuals([fitted.values], fold)[0]
        gains.append(problem.segment_costs(old_residuals) - problem.segment_costs(new_residuals))
        channel_gains += [np.mean(a.data**2, axis=0) - np.mean(b.data**2, axis=0)
                          for a, b in zip(old_residuals, new_residuals, strict=True)]  # fmt: skip
    gain = np.concatenate(gains)
    if len(gain) < 2:
        ok = gain.sum() > 0
        low = float(gain.mean()) if len(gain) else 0.0
    else:
        low = _bootstrap_interval(gain, 0.95)[0]
        ok = low > 0
    if not ok:
        return (
            f"no held-out gain: the paired bootstrap interval of its cross-validated gain per segment reaches {low:.3g}"
        )
    per_channel = np.array(channel_gains)
    if len(per_channel) >= 2:
        level = 1.0 - 0.05 / per_channel.shape[1]
        for j, channel in enumerate(problem.channels):
            low_j, high_j = _bootstrap_interval(per_channel[:, j], level)
            if high_j < -CHANNEL_MARGIN:
                return (
                    f"it makes {channel} worse on held-out segments (paired bootstrap interval of that channel's "
                    f"gain per segment [{low_j:.3g}, {high_j:.3g}] in squared noise levels, at {level:.1%}, wholly "
                    f"below the margin -{CHANNEL_MARGIN:g}): it trades one channel for another, standing in for "
                    "something else"
                )
    return None


def _bootstrap_interval(values: np.ndarray, level: float) -> tuple[float, float]:
    """The percentile bootstrap interval of a mean at ``level`` (scipy, seeded: same data, same verdict)."""
    res = stats.bootstrap((values,), np.mean, confidence_level=level, method="percentile",
                          random_state=np.random.default_rng(0))  # fmt: skip
    return float(res.confidence_interval.low), float(res.confidence_interval.high)
