"""Fitting an effect's parameters: least squares through ``mujoco.sysid`` for smooth ones, a grid refined by CMA-ES
(``cma``) for non-smooth ones, with 95% intervals sized by the residual's effective number of samples.

Parameters are fitted in normalized coordinates (0 at the low bound, 1 at the high one), so that one finite-
difference step suits a friction of 0.01 N m and a rotor inertia of 1e-8 kg m^2 alike. The residual function is
vectorized: the columns of a finite-difference Jacobian are candidate settings of one batched rollout.
"""

from __future__ import annotations

import contextlib
import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from envs.common.effects import Param
from sysid.problem import (
    Problem,
    Residual,
    Setting,
    data_size,
    flatten_objective,
    total_cost,
    total_objective,
)

FD_STEP = 1e-3  # finite-difference step in normalized coordinates (an adapter may ask for more: ``fd_step``)
GRID_POINTS = 9
CMA_EVALS = 120  # cost evaluations of a derivative-free fit (the second, re-anchored pass gets half)
XTOL = 1e-6  # stop when a step moves the parameters by less than this (relative, in normalized coordinates)
ALTERNATIONS = 4  # turns of a fit of non-smooth and smooth parameters together (grid, then least squares)
ALTERNATION_GAIN = 0.01  # another turn only while the last lowered the cost by more than this share
PROFILE_GAIN = 1e-4  # a step of the profile walk (_profile_walk) must lower the cost by this share of itself
PROFILE_FITS = 24  # and the walk stops after this many least-squares fits
MU_FACTOR = 10**0.5  # the regularizer's growth after a failed step (mujoco.minimize's default 10^0.1 takes many)


@dataclass
class FitResult:
    """Fitted values (every parameter of the fit, nuisance included), their 95% intervals, and the cost.

    ``bounds95`` holds each interval as (low, high): a profile likelihood can be one-sided (a friction above which
    the leg stalls anyway is "at least" a value); ``ci95`` is their half-widths, the larger side
    (:func:`half_widths`)."""

    values: dict[str, float]
    cost: float  # sum of squared normalized residuals (the start's corrections included)
    n: int  # data samples x channels
    n_eff: float
    residuals: list[Residual] = field(repr=False, default_factory=list)
    bounds95: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def ci95(self) -> dict[str, float]:
        return half_widths(self.values, self.bounds95)

    @property
    def error(self) -> float:
        return math.sqrt(self.cost / max(self.n, 1))

    @property
    def objective(self) -> float:
        """What the fit minimized (the cost, or its robust loss: ``Residual.objective``)."""
        return total_objective(self.residuals) if self.residuals else self.cost


def evaluate(problem: Problem, setting: Setting, segments: Sequence[int] | None = None) -> FitResult:
    """The cost of one setting (no fitting), the start's correction anchored at the setting itself."""
    residuals = problem.residuals([setting], segments)[0]
    return FitResult(dict(setting), total_cost(residuals), data_size(residuals),
                     problem.effective_samples(residuals), residuals)  # fmt: skip


def costs(problem: Problem, settings: Sequence[Setting], segments, anchor: Setting | None) -> list[float]:
    """The objective of each setting (its cost, or the robust loss of ``Adapter.loss_scale``), the start's
    correction and the carried state anchored at ``anchor`` (one batched rollout), or, None, each at its own
    (each log's segments in order). Anchored, a setting measured before is not rolled out again
    (:meth:`Problem.objectives`)."""
    if anchor is not None:
        return problem.objectives(settings, segments, anchor)
    return [total_objective(r) for r in problem.residuals(settings, segments, anchor=anchor)]


def fit(
    problem: Problem,
    base: Setting,
    params: Mapping[str, Param],
    segments: Sequence[int] | None = None,
    start: Mapping[str, float] | None = None,
    max_iter: int = 25,
    local: bool | str = False,
    intervals: bool = True,
) -> FitResult:
    """Fit ``params`` (flat name -> Param) from ``base``: non-smooth ones by grid and CMA-ES, then smooth ones by
    least squares at the best grid point; where there are both, in turn while a turn lowers the cost by more than
    ALTERNATION_GAIN (at most ALTERNATIONS turns). Where the cost is rough (``Adapter.rough_cost``), all of them
    without derivatives.

    ``local``: ``start`` is near the optimum (a refit on part of the data): non-smooth and derivative-free searches
    stay near it; ``"fine"``: very near (a refit on all the data of a fit on part of it), a window of a sixteenth
    of the range. ``intervals=False`` skips the 95% intervals (``ci95`` is then empty)."""
    start = dict(start or {})
    smooth = {k: p for k, p in params.items() if p.smooth}
    rough = {k: p for k, p in params.items() if not p.smooth}
    setting = {**base, **{k: start.get(k, base.get(k, p.nominal)) for k, p in params.items()}}
    if problem.adapter.rough_cost:
        result = _derivative_free(problem, setting, dict(params), segments, local)
    else:
        result = None
        for _ in range(ALTERNATIONS if rough and smooth else 1):
            # non-smooth parameters on a grid with the smooth ones held, then the smooth ones by least squares at
            # the grid's best point; where both kinds are fitted, in turn until the cost stops falling (a servo's
            # supply and backlash, each fitted with the other held at a value the other had pushed it to)
            if rough:
                setting = _grid_search(problem, setting, rough, smooth, segments, local or result is not None)
            step = (
                _least_squares(problem, setting, smooth, segments, max_iter)
                if smooth
                else evaluate(problem, setting, segments)
            )
            if result is not None and step.objective >= (1.0 - ALTERNATION_GAIN) * result.objective:
                result = step if step.objective < result.objective else result
                break
            result, setting = step, dict(step.values)
        if len(rough) == 1 and smooth:
            result = _profile_walk(problem, result, rough, smooth, segments, max_iter)
    if intervals:
        set_intervals(result, fit_intervals(problem, result, params, segments))
    return result


def _profile_walk(
    problem: Problem,
    result: FitResult,
    rough: Mapping[str, Param],
    smooth: Mapping[str, Param],
    segments: Sequence[int] | None,
    max_iter: int,
) -> FitResult:
    """Turns of grid and least squares move along the axes; where the non-smooth parameter and the smooth ones lie
    along one narrow valley (a motor's delay and its torque constant: a longer delay wants a stronger drive), they
    stall short of its floor. The profile cost (the smooth ones fitted at each value of the non-smooth one) has no
    such valley: walk it from the fit, a step of the parameter's resolution at a time in the direction that lowers
    it, the step doubling while it does, then halving back to the resolution (a line search on the profile). A
    move must lower the cost by PROFILE_GAIN of itself (no creeping along a flat profile on the fits' own
    tolerance), and the walk stops after PROFILE_FITS fits."""
    ((k, p),) = rough.items()
    best = result
    fits = 0

    def at(value: float) -> FitResult | None:
        nonlocal fits
        if not p.low <= value <= p.high or fits >= PROFILE_FITS:
            return None
        fits += 1
        return _least_squares(problem, {**best.values, k: float(value)}, smooth, segments, max_iter)

    improved = True
    while improved:  # both ways until neither moves (a walk that overshot comes back)
        improved = False
        for direction in (1.0, -1.0):
            step = p.resolution
            moved = False
            while step >= p.resolution and fits < PROFILE_FITS:
                trial = at(best.values[k] + direction * step)
                if trial is not None and trial.objective < best.objective * (1.0 - PROFILE_GAIN):
                    best, moved = trial, True
                    step *= 2.0
                elif moved or step > p.resolution:
                    step /= 2.0
                else:
                    break
            improved = improved or moved
    return best


def half_widths(values: Mapping[str, float], bounds: Mapping[str, tuple[float, float]]) -> dict[str, float]:
    """The half-width of each interval: the larger distance from the value to an end."""
    return {k: float(max(values[k] - low, high - values[k])) for k, (low, high) in bounds.items()}


def set_intervals(result: FitResult, bounds: Mapping[str, tuple[float, float]]) -> None:
    """Store 95% intervals (low, high) on a fit (``ci95``, the half-widths, follow from them)."""
    result.bounds95 = {k: (float(low), float(high)) for k, (low, high) in bounds.items()}


def fit_intervals(
    problem: Problem, result: FitResult, params: Mapping[str, Param], segments: Sequence[int] | None = None
) -> dict[str, tuple[float, float]]:
    """95% intervals (low, high) of a fit's parameters ``params`` at its values: where the cost is rough
    (contacts), from a parabola over the profile, widened on a side where the cost stays within the threshold
    further out (:func:`_smoothed_profile`); else, smooth parameters from the Jacobian at the optimum or the profile
    likelihood, whichever is wider on each side (:func:`_jacobian_intervals`), non-smooth ones from the profile
    (:func:`_profile_intervals`)."""
    best = result.values
    if problem.adapter.rough_cost:
        return _smoothed_profile(problem, best, params, segments, result)
    smooth = {k: p for k, p in params.items() if p.smooth}
    rough = {k: p for k, p in params.items() if not p.smooth}
    out = _jacobian_intervals(problem, result, smooth, segments) if smooth else {}
    if rough:
        out.update(_profile_intervals(problem, best, rough, segments, result))
    return out


def _to_unit(p: Param, x: float) -> float:
    return (x - p.low) / p.span if p.span > 0 else 0.0


def _from_unit(p: Param, u: float) -> float:
    return p.low + u * p.span


def _least_squares(
    problem: Problem,
    setting: dict[str, float],
    params: Mapping[str, Param],
    segments: Sequence[int] | None,
    max_iter: int,
) -> FitResult:
    from mujoco import sysid

    names = list(params)
    fd = max(FD_STEP, problem.adapter.fd_step)
    u0 = np.clip([_to_unit(params[k], setting[k]) for k in names], 2e-3, 1 - 2e-3)  # off the bounds: can stall

    def settings_of(u: np.ndarray) -> list[dict[str, float]]:
        u = u.reshape(len(names), -1)
        return [{**setting, **{k: _from_unit(params[k], float(u[i, j])) for i, k in enumerate(names)}}
                for j in range(u.shape[1])]  # fmt: skip

    def optimize(u_start: np.ndarray, anchor: Setting, iterations: int) -> np.ndarray:
        def residual_fn(x: np.ndarray, _params=None):
            columns = problem.residuals(settings_of(np.asarray(x, dtype=float)), segments, anchor=anchor)
            flat = np.column_stack([flatten_objective(c) for c in columns])
            return [flat if np.ndim(x) == 2 else flat[:, 0]], None, None

        pdict = sysid.ParameterDict({k: sysid.Parameter(k, u_start[i], 0.0, 1.0) for i, k in enumerate(names)})
        # sysid.optimize's own ``verbose`` shadows the backend's, which then prints every iteration: silence it
        with contextlib.redirect_stdout(io.StringIO()):
            fitted, _ = sysid.optimize(pdict, residual_fn, optimizer="mujoco", verbose=False, max_iters=iterations,
                                       eps=fd, xtol=XTOL, mu_factor=MU_FACTOR)  # fmt: skip
        return np.clip(fitted.as_vector(), 0.0, 1.0)

    # the start's correction and what segments carry over are taken from an anchor: the starting point, then, if
    # that changed the cost at the optimum by more than a percent, the optimum of the first pass
    start = settings_of(u0)[0]
    u = optimize(u0, start, max_iter)
    best = settings_of(u)[0]
    result = evaluate(problem, best, segments)
    anchored = total_objective(problem.residuals([best], segments, anchor=start)[0])
    if abs(anchored - result.objective) > 0.01 * result.objective:
        u = optimize(np.clip(u, 2e-3, 1 - 2e-3), best, max(3, max_iter // 3))
        best = settings_of(u)[0]
        result = evaluate(problem, best, segments)
    return result


def _jacobian_intervals(
    problem: Problem, result: FitResult, params: Mapping[str, Param], segments: Sequence[int] | None
) -> dict[str, tuple[float, float]]:
    """95% intervals of smooth parameters from the Jacobian at the optimum (normalized coordinates, one batched
    rollout for all its columns), or from the profile likelihood on a side where that is wider."""
    names = list(params)
    best = result.values
    fd = max(FD_STEP, problem.adapter.fd_step)
    u = np.array([_to_unit(params[k], best[k]) for k in names])
    steps = np.where(u > 0.5, -fd, fd)
    probe = u[:, None] + np.diag(steps)
    settings = [{**best, **{k: _from_unit(params[k], float(probe[i, j])) for i, k in enumerate(names)}}
                for j in range(len(names))]  # fmt: skip
    columns = problem.residuals(settings, segments, anchor=best)
    r0 = flatten_objective(result.residuals)
    jac = np.column_stack([(flatten_objective(c) - r0) / steps[i] for i, c in enumerate(columns)])
    half = _intervals(r0, jac, result.n_eff)
    out = {k: float(half[i] * params[k].span) for i, k in enumerate(names)}
    # the Jacobian's interval is a quadratic reading of the cost; where the effect is far from linear in its
    # parameter (a servo's gain, a friction near zero) the profile likelihood is wider on one side: take the larger
    # (the profile holds the other parameters, so it is the narrower of the two where parameters correlate)
    profile = _profile_intervals(problem, best, params, segments, result)
    return {
        k: (min(best[k] - v, profile[k][0]), max(best[k] + v, profile[k][1])) if np.isfinite(v) else (-v, v)
        for k, v in out.items()
    }


def _intervals(r: np.ndarray, jac: np.ndarray, n_eff: float) -> np.ndarray:
    """95% half-widths from the Jacobian at the optimum (``mujoco.sysid.calculate_intervals``), widened by
    sqrt(n / n_eff) and with a t quantile on n_eff - p degrees of freedom, since autocorrelated residuals carry
    fewer independent samples than their count."""
    from mujoco import sysid

    p = jac.shape[1]
    if p == 0:
        return np.zeros(0)
    with np.errstate(invalid="ignore", divide="ignore"):  # a singular Jacobian gives infinite intervals, not noise
        _, half = sysid.calculate_intervals([r], jac)
    n = r.size
    dof_raw = max(n - p, 1)
    dof_eff = max(n_eff - p, 1.0)
    t_raw = stats.t.ppf(0.975, dof_raw)
    t_eff = stats.t.ppf(0.975, dof_eff)
    # calculate_intervals reads the noise off the residual (r r / (n - p)); a residual quieter than the noise level
    # it is normalized by (a servo holding still reports the same count) must not narrow the interval: variance 1
    s2 = float(r @ r) / dof_raw
    floor = math.sqrt(1.0 / s2) if 0 < s2 < 1 else 1.0
    return np.asarray(half) * math.sqrt(n / max(n_eff, 1.0)) * (t_eff / t_raw) * floor


def rise_at(problem: Problem, result: FitResult, k: str, p: Param, value: float, n_params: int, segments) -> float:
    """How far the objective with ``k`` at ``value`` (the others at the fit's values) lies above the fit's own, in
    units of the 95% profile-likelihood threshold (the chi^2(1) quantile times the residual variance, as the
    intervals use): above 1, the profile leaves the 95% interval before ``value``. Both points in one batched
    rollout, anchored alike: a carried parameter (:attr:`Param.carried`) each with its own carried state, as its
    fit measured it; others at the fit's values."""
    anchor = None if p.carried else result.values
    at_fit, at_value = costs(problem, [result.values, {**result.values, k: float(value)}], segments, anchor=anchor)
    return (at_value - at_fit) / _rise_95(result, n_params)


def _rise_95(result: FitResult, p: int) -> float:
    """The rise of the objective that bounds a 95% profile-likelihood interval: the chi^2(1) quantile times the
    residual variance (:func:`_residual_variance`)."""
    return float(stats.chi2.ppf(0.95, 1)) * _residual_variance(result, p)


def _residual_variance(result: FitResult, p: int) -> float:
    """The residual variance per effective sample for intervals: the fit's own (cost / (n - p)), at least the
    noise level's 1 (a residual quieter than the noise in its still stretches says nothing of the noise in the
    moves that carry the information), times n / n_eff for the residual's autocorrelation."""
    return max(result.objective / max(result.n - p, 1), 1.0) * (result.n / max(result.n_eff, 1.0))


def _grid_search(
    problem: Problem,
    setting: dict[str, float],
    rough: Mapping[str, Param],
    smooth: Mapping[str, Param],
    segments: Sequence[int] | None,
    local: bool = False,
) -> dict[str, float]:
    """The best grid point of the non-smooth parameters (all grid points in one batched rollout), refined by
    CMA-ES when there are several; ``local``: a grid over a quarter of each range around the start."""
    names = list(rough)
    if local:
        grids = [np.unique(np.clip(setting[k] + rough[k].span * np.linspace(-0.125, 0.125, GRID_POINTS),
                                   rough[k].low, rough[k].high)) for k in names]  # fmt: skip
    else:
        grids = [np.linspace(rough[k].low, rough[k].high, GRID_POINTS) for k in names]
    points = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(names), -1).T
    candidates = [{**setting, **dict(zip(names, map(float, pt), strict=True))} for pt in points]
    cost = costs(problem, candidates, segments, anchor=setting)
    best = candidates[int(np.argmin(cost))]
    if len(names) > 1:
        import cma

        u0 = [_to_unit(rough[k], best[k]) for k in names]
        es = cma.CMAEvolutionStrategy(u0, 0.1, {"bounds": [0, 1], "maxfevals": 60, "verbose": -9, "seed": 1})
        while not es.stop():
            us = es.ask()
            trial = [{**best, **{k: _from_unit(rough[k], u[i]) for i, k in enumerate(names)}} for u in us]
            es.tell(us, costs(problem, trial, segments, anchor=setting))
        u = es.result.xbest
        best = {**best, **{k: _from_unit(rough[k], u[i]) for i, k in enumerate(names)}}
    else:
        # refine a single parameter around the best grid point, down to its resolution
        (k,) = names
        p = rough[k]
        step = p.span / (GRID_POINTS - 1) / (4 if local else 1)
        while step > p.resolution:
            fine = np.unique(np.clip(best[k] + np.linspace(-step, step, 9), p.low, p.high))
            trial = [{**best, k: float(v)} for v in fine]
            best = trial[int(np.argmin(costs(problem, trial, segments, anchor=setting)))]
            step /= 4
    return best


def _derivative_free(
    problem: Problem,
    setting: dict[str, float],
    params: Mapping[str, Param],
    segments: Sequence[int] | None,
    local: bool | str = False,
) -> FitResult:
    """For robots whose cost is rough at small scales (contacts; ``Adapter.rough_cost``), where finite-difference
    Jacobians mislead a least-squares step: one parameter by a batched grid shrinking around its best point, several
    by CMA-ES (``cma``) in normalized coordinates, each generation one batched rollout; the start's correction is
    re-anchored at the best point once (intervals: :func:`fit_intervals`). Parameters of a ``carried`` effect (one
    that acts through the state carried between segments, which an anchor would hold fixed) are searched with each
    trial's own carried state instead, in one pass."""
    names = list(params)
    best = dict(setting)
    own = any(params[k].carried for k in names)
    for anchor_pass in range(1 if own else 2):
        anchor = None if own else dict(best)
        u0 = np.clip([_to_unit(params[k], best[k]) for k in names], 0.0, 1.0)

        def trial(u, _best=best):
            return {**_best, **{k: _from_unit(params[k], float(u[i])) for i, k in enumerate(names)}}

        found, found_cost = u0, costs(problem, [best], segments, anchor=anchor)[0]
        if len(names) == 1:  # the whole range, then windows a quarter as wide around the best point each round,
            # then the vertex of a parabola over the last window (the cost's smoothed minimum, between grid points)
            widths = [0.0, 0.25, 1 / 16] if not local else [1 / 16] if local == "fine" else [1 / 4, 1 / 16]
            widths = widths if anchor_pass == 0 else [1 / 16]  # (0: the whole range)
            for width in widths:
                grid = np.linspace(-0.5, 0.5, GRID_POINTS)
                us = np.linspace(0.0, 1.0, GRID_POINTS) if width == 0 else np.clip(found[0] + width * grid, 0, 1)
                cs = costs(problem, [trial([u]) for u in us], segments, anchor=anchor)
                if min(cs) < found_cost:
                    found, found_cost = np.array([us[int(np.argmin(cs))]]), min(cs)
            # over the whole last window, and over the five points around its best (where a cost asymmetric
            # about its minimum, as one in 1 / gain is, biases a wide parabola less)
            cs = np.asarray(cs)
            centre = int(np.clip(np.argmin(cs), 2, len(us) - 3))
            vertices = {
                _parabola_vertex(us, cs),
                _parabola_vertex(us[centre - 2 : centre + 3], cs[centre - 2 : centre + 3]),
            }
            vertices = [v for v in vertices if v is not None and abs(v - found[0]) > 1e-9]
            if vertices:
                tried = costs(problem, [trial([v]) for v in vertices], segments, anchor=anchor)
                if min(tried) < found_cost:
                    found, found_cost = np.array([vertices[int(np.argmin(tried))]]), min(tried)
        else:
            import cma

            options = {"bounds": [0, 1], "maxfevals": CMA_EVALS // (anchor_pass + 1), "verbose": -9, "seed": 1,
                       "tolx": 1e-3, "popsize": max(6, 4 + int(3 * math.log(len(names))))}  # fmt: skip
            es = cma.CMAEvolutionStrategy(list(u0), 0.15 / (anchor_pass + 1) / (3 if local else 1), options)
            while not es.stop():
                us = es.ask()
                es.tell(us, costs(problem, [trial(u) for u in us], segments, anchor=anchor))
            if es.result.fbest is not None and es.result.fbest < found_cost:
                found, found_cost = np.asarray(es.result.xbest), float(es.result.fbest)
        best = trial(found)
        result = evaluate(problem, best, segments)  # anchored at itself
        if abs(result.objective - found_cost) <= 0.01 * found_cost:
            break
    return result


def _parabola_vertex(us: np.ndarray, cs: np.ndarray) -> float | None:
    """The vertex of a least-squares parabola through (us, cs), if it opens upward and lies within the points."""
    if len(np.unique(us)) < 3:
        return None
    a, b, _c = np.polyfit(us, cs, 2)
    if a <= 0:
        return None
    vertex = -b / (2 * a)
    return float(vertex) if us.min() <= vertex <= us.max() else None


def _smoothed_profile(
    problem: Problem, best: Mapping[str, float], params: Mapping[str, Param], segments, result: FitResult
) -> dict[str, tuple[float, float]]:
    """95% intervals where the cost is rough (contacts): a half-width, the larger of two readings of the cost at
    GRID_POINTS values across a window around the best point (the others held; one batched rollout):

    - a parabola fitted by least squares to the total cost, its curvature read as the profile likelihood's (the
      chi^2(1) quantile times the residual variance, scaled by n / n_eff), plus the distance from the best point to
      the parabola's vertex (where the smoothed cost puts the optimum);
    - a bootstrap over segments (:func:`_segment_bootstrap`): the spread of the smoothed optimum when the segments
      are resampled. Where the cost is rough, its local curvature overstates what the data pin down; how far the
      optimum moves from one draw of segments to another does not.

    The window widens until it holds the interval; a parameter whose window reaches its whole range without
    curvature gets the whole range. Both readings are local; a side on which the cost stays within the threshold
    further out (a plateau: a friction above which the leg stalls anyway) is widened to where it leaves
    (:func:`_plateau_reach`), so the interval can be one-sided."""
    rise = _rise_95(result, len(params))
    out = {}
    for k, p in params.items():
        x0, width, half = best[k], 0.1 * p.span, p.span
        for _ in range(4):
            xs = np.unique(np.clip(x0 + width * np.linspace(-1.0, 1.0, GRID_POINTS), p.low, p.high))
            rollouts = problem.residuals([{**best, k: float(x)} for x in xs], segments, anchor=best)
            per_segment = np.array([[r.objective for r in rs] for rs in rollouts])
            cs = per_segment.sum(axis=1)
            a, b, _c = np.polyfit((xs - x0) / p.span, cs, 2)
            if a <= 0:
                half = p.span
            else:
                vertex = -b / (2 * a) * p.span
                half = math.sqrt(rise / a) * p.span + min(abs(vertex), p.span)
                half = max(half, _segment_bootstrap(xs, per_segment, x0))
            if half <= width or width >= p.span:
                break
            width = min(2.0 * half, p.span)
        half = float(min(max(half, p.resolution), p.span))
        centre = np.flatnonzero(xs == x0)  # the best point itself (the window is centred on it), costed alike
        at_best = total_objective(rollouts[int(centre[0])]) if len(centre) else None
        out[k] = _plateau_reach(problem, best, k, p, half, rise, segments, at_best)
    return out


PLATEAU_PROBES = 6  # per side: values from twice the half-width out to the range's end, geometrically spaced


def _plateau_reach(
    problem: Problem,
    best: Mapping[str, float],
    k: str,
    p: Param,
    half: float,
    rise: float,
    segments,
    at_best: float | None = None,
) -> tuple[float, float]:
    """The interval (low, high) of ``k`` from a local half-width, each side pushed out to the last of
    PLATEAU_PROBES values (from twice the half-width to the range's end) before the first whose cost rises above the
    best point's by ``rise``: a profile likelihood read directly, where it is flat rather than curved.

    Read in two batched rollouts (each anchored at the best point, its cost among the first): the best point and
    each side's nearest probe, then the further probes of a side only where its nearest one stayed below the
    threshold. Only the probes up to a side's first crossing decide its reach, so this reads the same as probing
    everything at once; where the cost is a bowl (most fits), it costs 3 settings instead of 13. ``at_best``: the
    best point's cost, anchored alike, where the caller already has it (2 settings then)."""
    x0 = best[k]
    probes: dict[float, list[float]] = {}  # side -> distances
    for side, room in ((-1.0, x0 - p.low), (1.0, p.high - x0)):
        if room > 2.0 * half:
            probes[side] = [float(d) for d in np.geomspace(2.0 * half, room, PLATEAU_PROBES)]
    reach = {-1.0: half, 1.0: half}

    def cost_at(values: list[float]) -> list[float]:
        return costs(problem, [{**best, k: v} for v in values], segments, anchor=best)

    def walk(probed: list[tuple[float, float]], cost: list[float], threshold: float) -> set[float]:
        """Each side's reach out to its last probe (side, distance) before its first crossing, in order; the sides
        that crossed."""
        crossed = set()
        for (side, d), c in zip(probed, cost, strict=True):
            if c > threshold:
                crossed.add(side)
            elif side not in crossed:
                reach[side] = d
        return crossed

    if probes:
        nearest = [(side, ds[0]) for side, ds in probes.items()]
        head = [] if at_best is not None else [x0]
        first = cost_at(head + [x0 + side * d for side, d in nearest])
        threshold = (at_best if at_best is not None else first.pop(0)) + rise
        crossed = walk(nearest, first, threshold)
        # the further probes of each side whose nearest one stayed inside
        further = [(side, d) for side, ds in probes.items() if side not in crossed for d in ds[1:]]
        if further:
            walk(further, cost_at([x0 + side * d for side, d in further]), threshold)
    return (max(x0 - reach[-1.0], p.low) if reach[-1.0] > half else x0 - half,
            min(x0 + reach[1.0], p.high) if reach[1.0] > half else x0 + half)  # fmt: skip


BOOTSTRAP_DRAWS = 400


def _segment_bootstrap(xs: np.ndarray, per_segment: np.ndarray, x0: float) -> float:
    """The 95% half-width of a rough 1-D fit by a bootstrap over segments: ``per_segment`` holds each segment's
    cost (columns) at each value ``xs`` (rows); each draw resamples the segments with replacement, sums their
    costs and takes the minimum of the parabola through the lowest point and its neighbours (the grid's lowest
    point where the parabola does not open upward); the half-width is the larger distance from ``x0`` to the
    draws' 2.5 and 97.5 percentiles. The segments' costs are computed once: the draws cost no rollouts."""
    n_seg = per_segment.shape[1]
    if n_seg < 2 or len(xs) < 3:
        return 0.0
    rng = np.random.default_rng(0)
    draws = rng.integers(0, n_seg, size=(BOOTSTRAP_DRAWS, n_seg))
    totals = np.stack([per_segment[:, d].sum(axis=1) for d in draws])  # (draws, values)
    optima = np.empty(BOOTSTRAP_DRAWS)
    for i, c in enumerate(totals):
        j = int(np.clip(np.argmin(c), 1, len(xs) - 2))
        a, b, _c = np.polyfit(xs[j - 1 : j + 2], c[j - 1 : j + 2], 2)
        vertex = -b / (2 * a) if a > 0 else xs[int(np.argmin(c))]
        optima[i] = float(np.clip(vertex, xs[0], xs[-1]))
    low, high = np.percentile(optima, [2.5, 97.5])
    return float(max(abs(high - x0), abs(x0 - low)))


def _profile_intervals(
    problem: Problem, best: Mapping[str, float], rough: Mapping[str, Param], segments, result: FitResult
) -> dict[str, tuple[float, float]]:
    """95% intervals (low, high) of non-smooth parameters by profile likelihood, each side on its own: how far the
    value can move (the others held) before the cost rises by the chi^2(1) quantile times the residual variance,
    scaled by n / n_eff for the residual's autocorrelation. Bracketed outward in doubling steps from the
    parameter's resolution, then refined between the last point inside and the first outside; a side that never
    leaves reaches its bound."""
    threshold = result.objective + _rise_95(result, len(rough))
    out = {}
    for k, p in rough.items():
        x0 = best[k]
        offsets = p.resolution * 2.0 ** np.arange(0, math.ceil(math.log2(max(p.span / p.resolution, 1.0))) + 1)
        reach = {}
        for side in (-1.0, 1.0):
            values = np.clip(x0 + side * offsets, p.low, p.high)
            values = values[np.abs(values - x0) > 0]
            if not len(values):
                reach[side] = (0.0, 0.0)
                continue
            cost = np.array(costs(problem, [{**best, k: float(v)} for v in values], segments, anchor=best))
            outside = np.flatnonzero(cost > threshold)
            if not len(outside):
                reach[side] = (float(abs(values[-1] - x0)), float(abs(values[-1] - x0)))
                continue
            first = int(outside[0])
            inside = float(abs(values[first - 1] - x0)) if first else 0.0
            reach[side] = (inside, float(abs(values[first] - x0)))
        # refine each side's crossing between its last point inside and first outside
        sides = {}
        for side, (inside, outside) in reach.items():
            if outside > inside:
                grid = np.linspace(inside, outside, 8)[1:-1]
                values = x0 + side * grid
                cost = np.array(costs(problem, [{**best, k: float(v)} for v in values], segments, anchor=best))
                inside = max([inside, *grid[cost <= threshold]])
            sides[side] = max(inside, p.resolution)  # values within one step of each other are not told apart
        out[k] = (x0 - sides[-1.0], x0 + sides[1.0])
    return out
