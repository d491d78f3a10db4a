"""The calibration loop on data with effects nobody declared to it: synthetic logs from sysid.synth with a hidden
effect (drawn by the generator), and the null and out-of-catalog cases. One fast case per robot here; the full matrix
(every robot and effect, coverage over seeds) is ``python -m benchmarks.calibration_matrix`` (docs/calibration.md)."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

import envs  # noqa: F401 (registers the ids)
from agents import compare as evaluate
from envs.common.calibration import read_calibration
from envs.common.effects import Param, base_name
from envs.common.telemetry import read_telemetry, write_telemetry
from sysid import cli as calibrate
from sysid import fit as fit_module
from sysid import synth
from sysid.adapters import velociroach as roach_adapter
from sysid.adapters import velociroach_measure as roach_measure
from sysid.cases import TEST_SEED_OFFSET, Case, pair, run_case
from sysid.fit import FitResult, _plateau_reach, _profile_walk, fit, half_widths
from sysid.logs import Log
from sysid.pipeline import relative_excess, run
from sysid.problem import Problem, Residual, total_objective
from sysid.report import report_extra, report_markdown
from sysid.robots import adapter as make_adapter
from sysid.select import UNEXPLAINED_ABOVE, _bic_change
from tests.conftest import model_bytes


def test_robust_objective_is_least_squares_in_the_noise_and_linear_far_out():
    """An adapter's loss scale turns a fit's objective into the soft-L1 loss: within the noise it is the sum of
    squares, and a segment whose replay parted from the log (residuals of 100 noise levels) weighs linearly."""
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 1.0, (1000, 3))
    prior = np.array([0.5])
    plain, robust = Residual(noise, prior), Residual(noise, prior, loss_scale=3.0)
    assert plain.objective == plain.cost
    assert robust.objective == pytest.approx(robust.cost, rel=0.1)  # Gaussian noise, c = 3: 7% less
    assert robust.objective < robust.cost
    parted = Residual(np.full((10, 1), 100.0), np.zeros(0), loss_scale=3.0)
    assert parted.cost == pytest.approx(1e5)
    assert parted.objective == pytest.approx(10 * 2 * 9 * (math.sqrt(1 + (100 / 3) ** 2) - 1))  # about 2 c |r|
    for r in (plain, robust, parted):  # what a least-squares solver sees: its squares sum to the objective, signs kept
        flat = r.flat_objective()
        assert float(flat @ flat) == pytest.approx(r.objective)
        assert np.array_equal(np.sign(flat[: r.data.size]), np.sign(r.data.ravel()))


def test_segment_variance_is_least_squares_within_the_noise_and_logarithmic_beyond():
    """An adapter's ``segment_variance``: each segment's residual variance its own, at least the noise level. A
    segment within the noise is least squares; a segment whose replay parted from the log weighs by the log of its
    mean square (n (1 + log c)), so a true model's chaotic segments do not outweigh what the others show."""
    rng = np.random.default_rng(1)
    quiet = Residual(rng.normal(0.0, 0.5, (400, 2)), np.array([0.3]), segment_variance=True)
    assert quiet.objective == pytest.approx(quiet.cost)
    parted = Residual(np.full((50, 2), 100.0), np.zeros(0), segment_variance=True)
    assert parted.cost == pytest.approx(1e6)
    assert parted.objective == pytest.approx(100 * (1 + math.log(1e4)))
    # continuous at the noise level: a mean square of exactly 1 is n either way
    assert Residual(np.ones((10, 1)), np.zeros(0), segment_variance=True).objective == pytest.approx(10.0)
    for r in (quiet, parted):
        flat = r.flat_objective()
        assert float(flat @ flat) == pytest.approx(r.objective)
        assert np.array_equal(np.sign(flat[: r.data.size]), np.sign(r.data.ravel()))


class _TradingProblem:
    """A stand-in for a Problem with two channels whose one effect lowers channel ``a``'s residual on every segment
    (``mass.scale`` 2 against nominal 1) and raises channel ``b``'s RMS by the share ``trades``: a stand-in for
    something else where that is material."""

    def __init__(self, trades: float) -> None:
        self.channels = ["a", "b"]
        self.trades = trades
        self.adapter = SimpleNamespace(segment_variance=False)
        self.scored = list(range(9))

    def residuals(self, settings, segments, anchor=None):
        out = []
        for s in settings:
            row = []
            for i in segments:
                noise = np.random.default_rng(i).normal(0.0, 1.0, (200, 2))
                k = s["mass.scale"] - 1.0
                scale = np.array([3.0 - 2.0 * k, 1.0 + self.trades * k])
                row.append(Residual(noise * scale, np.zeros(0)))
            out.append(row)
        return out

    def segment_costs(self, residuals):
        return np.array([r.cost / r.data.size for r in residuals])


@pytest.mark.parametrize("trades", [0.0, 0.01, 1.0])
def test_the_held_out_test_refuses_an_effect_that_trades_one_channel_for_another(monkeypatch, trades):
    """An effect the model lacks lowers every channel's expected error or leaves it; one that lowers the total by
    making a channel materially worse (a right-side friction taking up a push on the body, the left side's channels
    worse) stands in for something else and is refused, naming the channel. A loss below the margin (here the RMS
    1% up, on every segment alike, so its interval lies wholly below zero: a sensor bias whose refit start shifts
    another channel a hair) is no trade."""
    import sysid.select as select
    from envs.common.effects import make

    problem = _TradingProblem(trades)
    trial = SimpleNamespace(values={"mass.scale": 2.0})
    monkeypatch.setattr(select, "fit", lambda *a, **k: trial)  # each fold's refit: the full fit
    effect = make("mass", scale=(1.0, 0.5, 2.0))
    folds = [[0, 3, 6], [1, 4, 7], [2, 5, 8]]
    verdict = select._held_out_test(problem, {"mass.scale": 1.0}, [effect], {}, problem.scored, folds, trial)
    if trades >= 1.0:
        assert verdict is not None and "makes b worse on held-out segments" in verdict
    else:
        assert verdict is None
    if trades == 0.01:  # the loss is there, consistent and immaterial: the interval lies wholly below zero
        old = problem.residuals([{"mass.scale": 1.0}], problem.scored)[0]
        new = problem.residuals([trial.values], problem.scored)[0]
        loss = [np.mean(b.data[:, 1] ** 2) - np.mean(a.data[:, 1] ** 2) for a, b in zip(old, new, strict=True)]
        assert 0.0 < min(loss) and max(loss) < select.CHANNEL_MARGIN


class _Objectives:
    """``Problem.objectives`` for the stand-ins: each setting's objective, without Problem's memory of them."""

    def objectives(self, settings, segments, anchor):
        return [total_objective(r) for r in self.residuals(settings, segments, anchor)]


class _CurveProblem(_Objectives):
    """A stand-in for a Problem whose cost, at any anchor, is a function of one parameter ``k``."""

    def __init__(self, cost):
        self.cost = cost
        self.asked: list[float] = []

    def residuals(self, settings, segments, anchor):
        self.asked += [s["k"] for s in settings]
        return [[SimpleNamespace(objective=float(self.cost(s["k"])))] for s in settings]


def test_an_interval_is_one_sided_where_the_cost_is_flat_out_to_the_end():
    """A friction above which the leg stalls anyway: the cost rises steeply below the estimate and is flat above
    it to the range's end. The interval keeps its steep side and reaches the end on the flat one; a cost that rises
    on both sides keeps the local half-width."""
    p = Param("k", "N m", 0.0, 0.0, 0.015)
    rise = 10.0
    stall = _CurveProblem(lambda x: 1e6 * max(0.007 - x, 0.0) ** 2 / 1e-6 + 0.5 * rise * (x > 0.009))
    low, high = _plateau_reach(stall, {"k": 0.007}, "k", p, 0.0015, rise, None)
    assert low == pytest.approx(0.0055) and high == pytest.approx(0.015)
    bowl = _CurveProblem(lambda x: 1e8 * (x - 0.007) ** 2)  # 10 units of cost 0.32e-3 from the optimum
    assert _plateau_reach(bowl, {"k": 0.007}, "k", p, 0.0015, rise, None) == pytest.approx((0.0055, 0.0085))
    # a side is read further out only where its nearest probe stays inside: the bowl costs the best point and one
    # probe a side; the stall's flat side is read to the end, its steep side stops at its nearest probe
    assert bowl.asked == pytest.approx([0.007, 0.004, 0.010])
    assert len(stall.asked) == 3 + 5 and min(stall.asked) == pytest.approx(0.004)
    assert half_widths({"k": 0.007}, {"k": (0.0055, 0.015)})["k"] == pytest.approx(0.008)  # the larger side


def test_given_values_come_back_unchanged():
    """A case's held-out log is made from the training truth as given values: the generator must not move them."""
    _, truth = synth.synthesize("motor", {"viscous_friction": None}, 3, seconds=4.0)
    _, again = synth.synthesize("motor", truth["effects"], 1003, seconds=4.0, show=True)
    assert again["effects"] == truth["effects"]


def test_the_generator_measures_visibility_on_all_runs_together(monkeypatch):
    """How visible a drawn effect is gets measured on every run of the recording together, as calibration sees
    them (a rig without a replay floor: against the sensor noise alone, one measure per draw)."""
    calls = []
    measure = synth.nominal_error

    def spy(adapter, logs, floor_setting=None):
        calls.append((len(logs), dict(floor_setting or {})))
        return measure(adapter, logs, floor_setting)

    monkeypatch.setattr(synth, "nominal_error", spy)
    logs, truth = synth.record("motor", {"viscous_friction": None}, 3, seconds=2.0, runs=3)
    assert len(logs) == 3 and len({log.df["duty"].to_numpy().tobytes() for log in logs}) == 3  # commands per run
    assert calls and all(n == 3 and floor == {} for n, floor in calls)
    assert truth["setting"]
    assert truth["nominal_error"] == measure(make_adapter("motor"), logs) >= synth.MIN_NOMINAL_ERROR


@pytest.mark.slow  # the calibration matrix measures every drawn effect's visibility (benchmarks/calibration_matrix.py)
def test_a_drawn_effect_shows_against_both_replay_floors():
    """A legged robot's visibility is measured against two replay floors: the true model's (as the held-out
    evaluation judges a calibrated model) and the nominal model's (as the loop, starting from it, first sees the
    data). A miss this guards against: the Bioloid's servo gain drawn with seed 0 read 3.54 against the true model's
    floor, 2.01
    against the nominal model's, and nothing was kept. The draw now has to show against both."""
    logs, truth = synth.record("bioloid", {"servo_gain": None}, 0)
    adapter = make_adapter("bioloid")
    both = [synth.nominal_error(adapter, logs), synth.nominal_error(adapter, logs, truth["setting"])]
    assert truth["nominal_error"] == min(both) >= synth.MIN_NOMINAL_ERROR, both


def _check_recovery(robot: str, effect: str, seed: int) -> Case:
    case = run_case(robot, {effect: None}, seed)
    assert case.nominal_error >= synth.MIN_NOMINAL_ERROR
    assert case.first is not None, f"nothing chosen for {effect}; rejected: {case.result.outcome.rejected}"
    assert case.first_in_alias_group, f"picked {case.first} for {effect}"
    if case.first == effect:
        assert case.recovered, case.values
    # the held-out error's excess over the noise floor at least halves
    assert case.halved, (case.result.before.error, case.result.after.error)
    return case


# one drawn effect per robot (robot, effect, seed, exact): exact, the first pick is the effect itself, its interval
# covers the truth and the held-out residual is explained. The legged robots' seeds are the matrix's for their
# effects (effect k of the catalog: seed k + 1); the matrix's coverage runs count its misses at other seeds.
RECOVERY = [
    ("motor", "viscous_friction", 11, False),
    # the servo's delay takes 20 s: the matrix runs it at every draw and its coverage over 20 seeds
    # (python -m benchmarks.calibration_matrix --robots servo), make test-slow too
    pytest.param("servo", "delay", 12, False, marks=pytest.mark.slow),
    # the servo's friction forms and gearbox efficiency at the matrix's seeds for them; the load friction and the
    # efficiency recorded on the loaded bench (sysid.synth.recording). The Stribeck friction at seed 3: at the
    # matrix's seed 10 its Stribeck velocity is low (0.28 rad/s), where a lower velocity and a higher static level
    # replay alike (the training error 1.101 at the fit against 1.104 at the truth) and the fit lands off the truth
    # the four take 10-20 s each: the matrix runs them (python -m benchmarks.calibration_matrix --robots servo
    # --effects load_friction stribeck_friction asymmetric_friction gearbox_efficiency), make test-slow too
    pytest.param("servo", "load_friction", 9, True, marks=pytest.mark.slow),
    pytest.param("servo", "stribeck_friction", 3, True, marks=pytest.mark.slow),
    pytest.param("servo", "asymmetric_friction", 11, True, marks=pytest.mark.slow),
    pytest.param("servo", "gearbox_efficiency", 12, True, marks=pytest.mark.slow),
    # the xJüs's case takes half a minute: the calibration matrix runs it (python -m benchmarks.calibration_matrix
    # --robots xjus ..., its configuration in benchmarks/results/calibration_matrix_xjus.md), make test-slow too
    pytest.param("xjus", "viscous_friction_left", 5, False, marks=pytest.mark.slow),
    # the Bioloid's case takes a quarter of a minute: the matrix runs it too (--robots bioloid,
    # benchmarks/results/calibration_matrix_bioloid.md), make test-slow as well
    pytest.param("bioloid", "servo_gain", 3, True, marks=pytest.mark.slow),
]


@pytest.mark.parametrize(("robot", "effect", "seed", "exact"), RECOVERY)
def test_a_drawn_effect_is_recovered(robot: str, effect: str, seed: int, exact: bool):
    """A robot recorded as several runs from rest (``Adapter.runs``: the xJüs, six runs of 2 s) is recorded so for
    training and held-out alike."""
    case = _check_recovery(robot, effect, seed)
    if exact:
        assert case.first == effect, case.first
        assert case.recovered and all(case.covered.values()), case.values
        assert not case.result.unexplained, (case.result.before.error, case.result.after.error)
    protocol = make_adapter(robot).runs
    if protocol is not None:
        runs, seconds = protocol
        for logs in (case.result.train, case.result.test):
            assert len(logs) == runs > 1 and len({log.path for log in logs}) == runs
            assert all(log.time[-1] - log.time[0] == pytest.approx(seconds, abs=0.02) for log in logs)


def _check_pair(robot: str, effects: dict, seed: int) -> Case:
    """Two hidden effects at once: an effect kept from each one's alias group and nothing else, each injected effect
    that was kept recovered with its interval covering the truth, the held-out residual explained."""
    case = run_case(robot, effects, seed)
    chosen = [c.effect.name for c in case.result.outcome.chosen]
    assert case.all_found, (chosen, case.found, case.result.outcome.rejected)
    for name, found in case.found.items():
        if found["chosen"] == name:
            assert found["recovered"] and all(found["covered"].values()), (name, found)
    assert not case.result.unexplained, (case.result.before.error, case.result.after.error)
    return case


@pytest.mark.slow  # half a minute; the matrix's motor pairs (python -m benchmarks.calibration_matrix --kinds pairs)
def test_two_hidden_effects_are_both_found_and_the_first_is_refitted_with_the_second():
    """Found once: the motor's viscous friction was kept first and fitted without the delay, 3.8% high; a third
    effect (a torque constant 1.04) was then kept to make up for it. The effects kept before are now refitted
    jointly with each new one (backfitting): two effects, both values inside their intervals, nothing else."""
    case = _check_pair("motor", {"delay": None, "viscous_friction": None}, seed=1)
    assert len(case.result.outcome.chosen) == 2


@pytest.mark.slow  # pair 504 of the matrix's motor pairs (python -m benchmarks.calibration_matrix --kinds pairs)
def test_a_second_effect_is_fitted_with_the_first_and_an_effect_it_replaced_is_dropped():
    """A case once missed: the motor's back-EMF constant (1.77) and PWM decay: a supply voltage (of another alias group)
    is kept first in the back-EMF constant's place. The back-EMF constant then scored 0.3 beside it: its column nearly
    shares the supply's, and the score did not take the supply as refitted. Now the ranking projects the kept effects'
    columns out (the score test with them refitted), each candidate is fitted with them, and once the back-EMF constant
    is kept, the supply, taken out and the rest refitted, costs nothing by the information criterion: it is dropped
    (backward step), its reason in ``rejected``."""
    case = _check_pair("motor", {"back_emf_constant": None, "pwm_decay": None}, seed=504)
    outcome = case.result.outcome
    assert [c.effect.name for c in outcome.chosen] == ["pwm_decay", "back_emf_constant"], outcome.chosen
    dropped = [r for r in outcome.rejected if r["reason"].startswith("kept, then dropped")]
    assert [r["name"] for r in dropped] == ["supply_voltage"], outcome.rejected
    # the history holds one setting per kept effect after the nominal one, the last the final model
    assert len(outcome.history) == len(outcome.chosen) + 1 and outcome.history[-1] == outcome.setting


@pytest.mark.parametrize("segment_variance", [False, True])
def test_the_information_criterion_reads_the_same_adding_an_effect_or_dropping_it(segment_variance: bool):
    """The BIC change of the backward step (a kept effect dropped) is a candidate's read the other way: from the
    larger model to the smaller, with the parameters counted negative, under either likelihood (one noise variance
    profiled out, or each segment's: ``Adapter.segment_variance``)."""
    problem = SimpleNamespace(adapter=SimpleNamespace(segment_variance=segment_variance))
    small, large = FitResult({}, 1200.0, 1000, 200.0), FitResult({}, 1000.0, 1000, 200.0)
    added = _bic_change(problem, large, small, 2)
    fit_term = (1000.0 - 1200.0) * 200.0 / 1000 if segment_variance else 200.0 * math.log(1000.0 / 1200.0)
    assert added == pytest.approx(fit_term + 2 * math.log(200.0))
    assert _bic_change(problem, small, large, -2) == pytest.approx(-added)


@pytest.mark.parametrize(("best", "start", "expected"), [(0.0233, 0.010, 0.023), (0.0233, 0.040, 0.023),
                                                      (0.080, 0.010, 0.050), (0.010, 0.010, 0.010)])  # fmt: skip
def test_the_profile_walk_finds_the_profiles_floor_from_either_side_and_stops_at_the_range(
    monkeypatch, best: float, start: float, expected: float
):
    """``_profile_walk`` on a profile with a known floor (the least-squares fit at each value stood in by the
    profile itself): it walks there from either side (overshooting on the doubling steps and coming back), to
    the nearest resolution step; it stops at the range's end when the floor lies beyond; and it does not move
    from a start at the floor. It never takes more than PROFILE_FITS fits."""
    calls = []

    def profile(problem, setting, smooth, segments, max_iter):
        calls.append(setting["d"])
        return FitResult({**setting, "g": 2 * setting["d"]}, 1.0 + 1e6 * (setting["d"] - best) ** 2, 100, 50.0)

    monkeypatch.setattr(fit_module, "_least_squares", profile)
    delay = Param("d", "s", 0.0, 0.0, 0.05, smooth=False, step=0.001)
    gain = Param("g", "1", 1.0, 0.0, 1.0)
    start_fit = FitResult({"d": start, "g": 2 * start}, 1.0 + 1e6 * (start - best) ** 2, 100, 50.0)
    out = _profile_walk(None, start_fit, {"d": delay}, {"g": gain}, None, 10)
    assert out.values["d"] == pytest.approx(expected, abs=1e-9), calls
    assert out.values["g"] == pytest.approx(2 * out.values["d"])  # the smooth ones as fitted at that value
    assert all(delay.low <= d <= delay.high for d in calls) and len(calls) <= fit_module.PROFILE_FITS


@pytest.mark.slow  # pair 502 of the matrix's motor pairs (python -m benchmarks.calibration_matrix --kinds pairs)
def test_a_delay_and_a_drive_along_one_valley_are_fitted_by_walking_the_profile():
    """A case once missed: the motor's delay 0.0291 s and torque constant 2.77: a longer delay wants a stronger drive,
    and
    turns of grid (the delay) and least squares (the drive) stalled in that valley (torque constant 2.45, training
    error 4.2). The delay's profile (the drive fitted at each delay) is now walked from the fit: both recovered,
    the residual at the floor."""
    _check_pair("motor", {"delay": None, "torque_constant": None}, seed=502)


@pytest.mark.slow
def test_a_chain_left_partly_at_nominal_is_tried_without_those_members():
    """A case once missed: a large Coulomb friction and a low back-EMF constant (which pull the top speed opposite
    ways): no
    single effect earns its place, and the chain grown from the best single (the torque constant) fitted it back to
    nominal with the two true effects beside it, and was refused as a whole. The chain without the member the
    joint fit leaves at nominal is now tried, and kept. (About 2 min; the matrix's pairs run more: --kinds pairs.)"""
    _check_pair("motor", {"coulomb_friction": None, "back_emf_constant": None}, seed=2)


@pytest.mark.slow  # the matrix's motor cases draw the torque constant too (python -m benchmarks.calibration_matrix)
def test_the_motors_torque_constant_below_nominal_is_one_effect_with_a_rotor_inertia():
    """On the motor rig the torque constant scales the drive and the back-EMF brake alike, and the shaft has no
    friction of its own: a torque constant s moves the load as an inertia 1/s does. A torque constant
    of 0.45 was once fitted as an armature (to the noise floor); the catalog now puts the armature in the torque
    constant's
    alias group on this robot, as it says of a load's inertia."""
    effects = make_adapter("motor").effects()
    assert effects["armature"].alias == effects["torque_constant"].alias
    case = run_case("motor", {"torque_constant": 0.45}, seed=3)
    assert case.first_in_alias_group and case.halved, (case.first, case.excess_ratio)


def _evaluate(tmp_path, name: str, calibration: str | None) -> dict[str, float]:
    out = tmp_path / name
    argv = ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "2", "--out", str(out),
            "--max-episode-steps", "150", *(["--calibration", calibration] if calibration else [])]  # fmt: skip
    assert evaluate.main(argv) == 0
    summary = json.loads((out / "results.json").read_text())["policies"]["tripod"]["summary"]
    return {m: summary[m]["mean"] for m in ("forward_speed", "heading_drift")}


def _roach_calibration_walks_closer(tmp_path, *options: str, seconds: float | None = None) -> None:
    """The VelociRoACH's case, end to end: synthetic logs of a robot with a hidden left-side friction (drawn by the
    generator) go through calibrate.py (with ``options``); the calibrated model, run by evaluate.py, walks the tripod
    gait closer to the 'measured' robot (the model with the true effect) in speed and heading drift than the nominal
    model does. The logs are a case's (``pair``), or training and held-out logs of ``seconds`` each."""
    effect, seed = "viscous_friction_left", 1
    if seconds is None:
        (train,), (test,), truth = pair("roach", {effect: None}, seed)
    else:
        (train,), truth = synth.record("roach", {effect: None}, seed, seconds)
        (test,), _ = synth.record("roach", truth["effects"], seed + TEST_SEED_OFFSET, seconds, show=True)
    assert truth["nominal_error"] >= synth.MIN_NOMINAL_ERROR
    paths = []
    for name, log in (("train", train), ("test", test)):
        paths.append(tmp_path / f"{name}.parquet")
        write_telemetry(paths[-1], log.df, log.meta)
    out = tmp_path / "cal"
    argv = ["--robot", "roach", "--train", str(paths[0]), "--test", str(paths[1]), "--out", str(out), "--quiet"]
    assert calibrate.main([*argv, *options]) == 0
    report = json.loads((out / "report.json").read_text())
    injected = make_adapter("roach").effects()[effect]
    first = report["chosen"][0]
    assert make_adapter("roach").effects()[first["name"]].alias == injected.alias, first["name"]
    assert relative_excess(report["error_before"], report["error_after"]) <= 0.5, report
    if first["name"] == effect:
        p = injected.params[0]
        entry = first["params"][p.name]
        assert abs(entry["value"] - truth["effects"][effect][p.name]) <= max(2 * entry["ci95"], 0.05 * p.span)
    measured_file = tmp_path / "truth.json"
    measured_file.write_text(json.dumps({"format": "skitter calibration", "version": 1, "robot": "velociroach",
                                         "effects": truth["effects"]}))  # fmt: skip
    measured = _evaluate(tmp_path, "measured", str(measured_file))
    nominal = _evaluate(tmp_path, "nominal", None)
    calibrated = _evaluate(tmp_path, "calibrated", str(out / "calibration.json"))
    for metric in ("forward_speed", "heading_drift"):
        assert abs(calibrated[metric] - measured[metric]) < abs(nominal[metric] - measured[metric]), (
            metric, measured, nominal, calibrated)  # fmt: skip


@pytest.mark.slow  # the selection over the roach's whole catalog: the matrix's roach cases run it on every effect
def test_roach_calibration_from_its_logs_brings_the_tripod_closer_to_the_measured_robot(tmp_path):
    _roach_calibration_walks_closer(tmp_path)


@pytest.mark.slow  # half a minute; the matrix's roach cases run calibrate.py on the roach's logs of every effect
def test_a_roach_effect_fitted_from_its_logs_brings_the_tripod_closer_to_the_measured_robot(tmp_path):
    """The same chain with the effect named (``calibrate.py --fit``), without the search over the catalog, on logs
    of 4 s (a case's are 10 s)."""
    _roach_calibration_walks_closer(tmp_path, "--fit", "viscous_friction_left", seconds=4.0)


# the legged robots' null and out-of-catalog cases take minutes each, the motor's out-of-catalog case one: the
# matrix runs them too (--kinds null ooc)
SLOW = pytest.mark.slow


@pytest.mark.parametrize(("robot", "seed"), [("motor", 13), ("servo", 13), pytest.param("xjus", 21, marks=SLOW),
                                             pytest.param("bioloid", 21, marks=SLOW)])  # fmt: skip
def test_null_noise_only_chooses_nothing(robot: str, seed: int):
    train, test, _ = pair(robot, {}, seed=seed)
    result = run(make_adapter(robot), train, test, say=lambda s: None)
    assert result.outcome.chosen == []
    assert result.after.error < result.threshold and not result.unexplained, result.after.error


def test_null_on_the_loaded_servo_bench_chooses_nothing():
    """The loaded bench the servo's load friction and gearbox efficiency are recorded on (a load friction of 0
    records it, nothing hidden): its replay with the declared load leaves only the noise."""
    train, test, _ = pair("servo", {"load_friction": 0.0}, seed=13)
    adapter = make_adapter("servo")
    assert train[0].meta["load_inertia"] == test[0].meta["load_inertia"] > adapter.nominal_robot.load_inertia
    result = run(adapter, train, test, say=lambda s: None)
    assert result.outcome.chosen == []
    assert result.after.error < result.threshold and not result.unexplained, result.after.error


# every out-of-catalog case is slow (the servo rig's takes a quarter of a minute): the matrix runs them all
# (--kinds ooc; benchmarks/results/calibration_matrix_roach_motor_servo.md), make test-slow too
@pytest.mark.parametrize(("robot", "seed"), [pytest.param("servo", 14, marks=SLOW),
                                             pytest.param("motor", 14, marks=SLOW),
                                             pytest.param("xjus", 22, marks=SLOW),
                                             pytest.param("bioloid", 22, marks=SLOW)])  # fmt: skip
def test_out_of_catalog_disturbance_is_unexplained(robot: str, seed: int):
    """The servo rig's case runs in about a third of the motor's time, which the slow run and the matrix take."""
    train, test, truth = pair(robot, {"disturbance": None}, seed=seed)
    assert truth["nominal_error"] >= synth.MIN_NOMINAL_ERROR
    result = run(make_adapter(robot), train, test, say=lambda s: None)
    assert result.unexplained and result.after.error > UNEXPLAINED_ABOVE
    assert "above the noise floor" in result.where()
    traced = result.trace()  # what remains is traced to a mechanism, and the verdict ends with it
    assert traced is None or result.where().endswith(traced["why"] + ".")
    # no catalog effect claims to have fixed it: whatever was kept leaves most of the excess
    assert relative_excess(result.before.error, result.after.error) > 0.5


def _xjus_walk(env) -> None:
    """7 s of the xJüs's gait mode (the clock, the duty, the hips, the currents), its gait changed after 4 s."""
    env.reset(seed=0)
    action = env.unwrapped.robot.mode.to_action(np.array([[0.8, 1.0, 1.0]]))[0]
    for k in range(875):
        if k == 500:
            action = env.unwrapped.robot.mode.to_action(np.array([[0.6, 1.2, 0.9]]))[0]
        env.step(action)


def _bioloid_trot(env) -> None:
    """7 s of the Bioloid's trot at 50 Hz (the servos' goals and reported positions)."""
    from agents.bioloid.ik import ik_for

    obs, _ = env.reset(seed=0)
    policy = ik_for(env, "trot", "1.5")
    state = None
    for _ in range(350):
        action, state = policy.predict(obs, state)
        obs, *_ = env.step(action)


OWN_TELEMETRY = {
    "xjus": ("skitter/XjusWalk-v1", _xjus_walk, {"clock_phase", "period", "duty_FL", "current_FL", "leg_angle_FL"}),
    "bioloid": ("skitter/BioloidWalk-v2", _bioloid_trot, {"goal_F_L_1", "present_position_F_L_1"}),
}


@pytest.mark.parametrize("robot", list(OWN_TELEMETRY))
def test_calibrate_runs_on_the_robots_own_telemetry(tmp_path, robot):
    """The env's telemetry goes through calibrate.py: the model replays itself, so nothing is chosen and the held-out
    residual is explained (within what a right model's replay of these few segments may miss: the replay floor's
    own uncertainty)."""
    env_id, drive, columns = OWN_TELEMETRY[robot]
    env = gym.make(env_id, telemetry=True, max_episode_steps=1000)
    drive(env)
    path = env.unwrapped.recorder.save(tmp_path / "walk.parquet")
    df, _ = read_telemetry(path)
    assert {*columns, "vbatt"} <= set(df.columns)
    out = tmp_path / "cal"
    argv = ["--robot", robot, "--train", f"{path}@0:4", "--test", f"{path}@4:", "--out", str(out), "--quiet"]
    assert calibrate.main(argv) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["robot"] == robot and report["chosen"] == [], report["chosen"]
    assert not report["unexplained"], (report["error_after"], report["noise"]["threshold_unexplained"])


def test_synth_cli_lists_every_effect_and_writes_log_and_truth(tmp_path, capsys):
    assert synth.main(["--list"]) == 0
    listing = capsys.readouterr().out
    for robot in ("motor", "servo", "roach"):
        for name, effect in make_adapter(robot).effects().items():
            row = next(line for line in listing.splitlines() if line.startswith(f"{name} | {robot} |"))
            cells = row.split(" | ")
            assert cells[3] == effect.alias
            assert (cells[4] == "yes") == effect.catalogued
            assert cells[5] == "yes" if effect.observable else cells[5].startswith("barely: ")
    assert "disturbance" in listing and "| no" in listing
    out = tmp_path / "log.parquet"
    assert synth.main(["--robot", "motor", "--effect", "armature", "--seed", "3", "--out", str(out)]) == 0
    truth = json.loads(out.with_name("log.parquet.truth.json").read_text())
    assert set(truth["effects"]) == {"armature"} and truth["nominal_error"] >= synth.MIN_NOMINAL_ERROR
    df = pd.read_parquet(out)
    assert {"time", "duty", "angle", "speed"} <= set(df.columns)
    # the log carries no truth
    assert "armature" not in out.read_bytes().decode("latin-1")
    # never overwritten silently; a value outside the range is refused
    assert synth.main(["--robot", "motor", "--effect", "armature", "--out", str(out)]) == 2
    assert synth.main(["--robot", "motor", "--effect", "armature=5", "--out", str(tmp_path / "b.parquet")]) == 2
    assert "outside its range" in capsys.readouterr().err


def test_calibrate_cli_writes_its_results_as_one_folder(tmp_path, capsys, monkeypatch):
    # logs of 4 s, not the matrix's 10: the command's files and its second run are what is tested here
    (train,), truth = synth.record("motor", {"coulomb_friction": 0.2}, 15, seconds=4.0)
    (test,), _ = synth.record("motor", truth["effects"], 15 + TEST_SEED_OFFSET, seconds=4.0, show=True)
    paths = []
    for name, log in (("train", train), ("test", test)):
        path = tmp_path / f"{name}.parquet"
        write_telemetry(path, log.df, log.meta)
        paths.append(path)
    out = tmp_path / "cal"
    argv = ["--robot", "motor", "--train", str(paths[0]), "--test", str(paths[1]), "--out", str(out), "--quiet"]
    assert calibrate.main(argv) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "calibration.json", "report.json", "report.md", "residual_after.png", "residual_before.png"
    ]  # fmt: skip
    report = json.loads((out / "report.json").read_text())
    for key in ("robot", "train", "test", "error_before", "error_after", "per_channel", "chosen", "rejected",
                "unexplained", "unexplained_reason"):  # fmt: skip
        assert key in report
    assert report["robot"] == "motor" and report["train"] == [str(paths[0])]
    assert report["error_before"] > 3 and report["error_after"] < report["error_before"]
    assert report["worse_on_test"] is False and "worse on the held-out logs" not in (out / "report.md").read_text()
    # a calibration that leaves the held-out error above the nominal model's says so first thing in report.md
    worse = {**report, "error_after": report["error_before"] * 1.1, "worse_on_test": True}
    assert "**The calibrated model is worse on the held-out logs than the nominal model**" in report_markdown(worse)
    started = {**worse, "start": "earlier/calibration.json"}
    assert "than the calibration it started from (earlier/calibration.json)**" in report_markdown(started)
    # an unexplained result's trace: its mechanism and each effect of that kind, with what became of it
    assert report["unexplained"] or report["trace"] is None
    kept = {"coulomb_friction": {"fate": "kept", "words": "kept (torque 0.2)"}}
    trace = {"text": "speed: the residual follows the load", "mechanism": "what the drive carries", "channel": "speed",
             "out_of_catalog": ["disturbance"], "missing": ["load_friction"], "effects": kept}  # fmt: skip
    text = report_markdown({**report, "trace": trace})
    assert (
        "## What the remaining residual points to\n\nThe strongest finding on the held-out residual after "
        "calibration, `speed: the residual follows the load`, points to what the drive carries."
    ) in text
    assert "- **coulomb_friction**: kept (torque 0.2)" in text and "out of its catalog: disturbance." in text
    assert "not declared for this robot: load_friction." in text
    assert set(report["per_channel"]) == {"angle", "speed"}
    first = report["chosen"][0]
    assert base_name(make_adapter("motor").effects()[first["name"]]) in ("coulomb_friction", "backlash", "deadband")
    assert {"value", "ci95"} <= set(next(iter(first["params"].values())))
    assert math.isfinite(first["error_after"])
    calibration = read_calibration(out / "calibration.json", "motor")
    assert first["name"] in calibration.effects
    # a second run starts from the first one's calibration and does not offer its effects again
    out2 = tmp_path / "cal2"
    argv2 = [*argv[:6], "--out", str(out2), "--calibration", str(out / "calibration.json"), "--quiet"]
    assert calibrate.main(argv2) == 0
    report2 = json.loads((out2 / "report.json").read_text())
    assert report2["error_before"] == pytest.approx(report["error_after"], rel=0.05)
    assert all(c["name"] != first["name"] for c in report2["chosen"])
    # no stall in these logs; one found in a training log is warned of on stderr even with --quiet, and in the report
    assert report["train_stall"] is None and "stall" not in capsys.readouterr().err
    found = {"channel": "speed", "log": str(paths[0]), "start": 1.0, "end": 1.25, "share": 0.5}
    monkeypatch.setattr("sysid.pipeline.training_stall", lambda problem, start=None: found)
    out3 = tmp_path / "cal3"
    assert calibrate.main([*argv[:6], "--out", str(out3), "--fit", "coulomb_friction", "--quiet"]) == 0
    assert (
        f"calibrate.py: warning: {paths[0]} holds a stall on speed between 1.00 and 1.25 s" in capsys.readouterr().err
    )
    assert json.loads((out3 / "report.json").read_text())["train_stall"] == found
    assert f"**A training log holds a stall**: {paths[0]}, 1.00 to 1.25 s on speed" in (out3 / "report.md").read_text()
    assert np.isfinite(report2["error_after"])


def test_roach_report_tables_mark_what_a_log_cannot_give_and_name_each_log():
    """A held-out log too short for the tracking error's split shows "-" in those rows, with a note that says why,
    not "nan"; the body rates' table names the log each row is from."""
    keys = ("error_median", "error_p95", "duty_mean_abs", "duty_at_clip", "bemf_per_speed", "error_stride",
            "error_slow", "error_pattern")  # fmt: skip
    full = {f"{k}_{side}": 1.0 for k in keys for side in ("left", "right")}
    short = {**full, "error_stride_left": math.nan, "error_stride_right": math.nan, "error_pattern_left": math.nan}
    text = roach_adapter._tracking_table({"a.txt": {s: full for s in ("log", "nominal", "calibrated")},
                                          "b.txt": {"log": short, "nominal": full, "calibrated": full}})  # fmt: skip
    assert "nan" not in text
    assert "| tracking error repeating every stride (% of its variance) | - \\| - | 1 \\| 1 | 1 \\| 1 |" in text
    first, second = text.split("b.txt (left")
    assert "- : not measured" not in first
    assert "- : not measured on this log's compared rows (tracking error repeating every stride" in second
    assert "lasting strides" not in second.split("- : not measured")[1].split(").")[0]
    spread = {"std": 1.0, "bands": [0.5, 0.5]}
    rates = {f"{path}:{rate}": {"log": spread, "nominal": {**spread, "wasserstein": 0.25},
                                "calibrated": {**spread, "wasserstein": 0.125}}
             for path in ("a.txt@8:", "b.txt") for rate in ("gyro_x", "gyro_z")}  # fmt: skip
    table = roach_adapter._rates_table(rates, [(0.5, 5), (5, 20)])
    assert "a.txt@8: (body rates):\n\n| rate | source |" in table and "b.txt (body rates):\n\n| rate |" in table
    assert "| gyro_z | log | 1 | 50% | 50% | - |" in table and "| gyro_z | nominal | 1 | 50% | 50% | 0.25 |" in table
    assert table.split("b.txt (body")[1].count("| gyro_x |") == 3 and "nan" not in table


def test_roach_report_compares_tracking_and_body_rates():
    """The roach's report: the tracking table (log, nominal and calibrated model), and the gyro, which cannot
    be aligned in time with a log whose body pose is unknown, compared by spread, band power and distribution."""
    adapter = make_adapter("roach")
    (log,) = calibrate.read_logs([Path("data/real/velociroach_behavior4_2Hz.txt@0:4")], adapter.required(), None)
    nominal = adapter.catalog_nominal()
    stronger = {**nominal, "torque_constant_left.scale": 2.0, "torque_constant_right.scale": 2.0}
    outcome = SimpleNamespace(nominal=nominal, setting=stronger, started=[])
    result = SimpleNamespace(train=[], test=[log], outcome=outcome)
    extra = report_extra(adapter, result)  # the adapter's own sections, and what the logs measure by themselves
    assert set(extra["sections"]) == {"Tracking on the held-out logs", "Body rates compared as distributions",
                                      "Measured directly (no simulator)"}  # fmt: skip
    assert "| | log | nominal model | calibrated model |" in extra["sections"]["Tracking on the held-out logs"]
    # a run from an earlier calibration compares with that calibration's model, and says so
    started = roach_adapter._tracking_table(extra["tracking"], "starting calibration")
    assert "| | log | starting calibration | calibrated model |" in started
    measured = {(m["quantity"], m["side"]) for m in extra["measured"]}
    assert {("kp", "left"), ("bemf_constant", "right"), ("battery_resistance", "")} <= measured
    assert "| bemf_constant |" in extra["sections"]["Measured directly (no simulator)"]
    table = extra["tracking"][log.path]
    t = log.time
    window = (t >= 1.1 + 1.0) & (t <= 4.0)  # the legs are commanded from 1.1 s (data/real/README.md)
    error = np.degrees(np.abs(log.df["leg_angle_cmd_left"] - log.df["leg_angle_left"]).to_numpy()[window])
    assert table["log"]["error_median_left"] == pytest.approx(np.median(error), rel=0.05)
    # the share of the time the firmware's output is held at its clip (MAXTHROT, the header's)
    duty = np.abs(log.df["duty_right"].to_numpy())[window]
    clipped = 100 * np.mean(duty >= 0.995 * log.meta["duty_clip"])
    assert table["log"]["duty_at_clip_right"] == pytest.approx(clipped, abs=2.0)
    assert all(0 <= table[s][f"duty_at_clip_{side}"] <= 100 for s in table for side in ("left", "right"))
    # how the error splits: what repeats every stride and what lasts strides, shares of its variance
    clock, leg = log.df["leg_angle_cmd_left"].to_numpy(), log.df["leg_angle_left"].to_numpy()
    parts = roach_measure.tracking_parts(t[window], (clock - leg)[window], clock[window])
    assert table["log"]["error_stride_left"] == pytest.approx(parts["stride"], abs=5.0)
    assert all(0 <= table[s][f"error_{part}_{side}"] <= 100 for s in table for side in ("left", "right")
               for part in ("stride", "slow"))  # fmt: skip
    # the models' stride patterns of the error against the log's: a correlation, the log's own 1
    assert table["log"]["error_pattern_left"] == 1.0
    models = [table[s][f"error_pattern_{side}"] for s in ("nominal", "calibrated") for side in ("left", "right")]
    assert all(-1 <= r <= 1 for r in models), models
    assert "| tracking error repeating every stride (% of its variance) |" in extra["sections"][
        "Tracking on the held-out logs"]  # fmt: skip
    # the back-EMF constant doubles with the motor constant
    for side in ("left", "right"):
        ratio = table["calibrated"][f"bemf_per_speed_{side}"] / table["nominal"][f"bemf_per_speed_{side}"]
        assert 1.8 < ratio < 2.2, ratio
    for key, entry in extra["distributions"].items():
        column = key.rsplit(":", 1)[1]
        measured = log.df[column].to_numpy()[window]
        assert entry["log"]["std"] == pytest.approx(float(np.std(measured)), rel=0.05)
        for source in ("nominal", "calibrated"):
            assert entry[source]["std"] > 0 and math.isfinite(entry[source]["wasserstein"])
            assert 0.0 <= sum(entry[source]["bands"]) <= 1.0 + 1e-9


class _StandIn(_Objectives):
    """What sysid.select and sysid.fit ask of a Problem besides its residuals, for the stand-ins below."""

    def __init__(self) -> None:
        self.adapter = SimpleNamespace(fd_step=1e-3, rough_cost=True, score_grid=None)
        self.t = np.linspace(0.0, 1.0, 200)

    def effective_samples(self, residuals) -> float:
        return float(sum(len(r.data) for r in residuals))


class _CarriedProblem(_StandIn):
    """A stand-in for sysid.problem.Problem whose one effect ``mass.scale`` (truth 1.4) reaches the residual only
    through the carried state: a prediction anchored elsewhere carries the anchor's state and so does not see the
    setting's value, as a legged robot's body carried between segments does not see its own mass."""

    truth = 1.4

    def residuals(self, settings, segments=None, anchor=None):
        out = []
        for s in settings:
            carried = (anchor if anchor is not None else s).get("mass.scale", 1.0)
            wave = np.sin(2 * np.pi * 3 * self.t)[:, None]
            data = (self.truth - carried) * wave + 0.01 * np.cos(40 * self.t)[:, None]
            out.append([Residual(data, np.zeros(0))])
        return out


def test_a_carried_effect_is_ranked_and_fitted_with_its_own_carried_state():
    from envs.common.effects import make
    from sysid.fit import fit
    from sysid.select import _params, score

    problem = _CarriedProblem()
    carried = make("mass", scale=(1.0, 0.5, 2.0), carried=True)
    plain = make("mass", scale=(1.0, 0.5, 2.0))
    assert carried.carried and all(p.carried for p in carried.params) and not plain.carried
    # declared carried, its grid runs each point with its own carried state and sees the residual; undeclared, every
    # probe is anchored at nominal and sees nothing
    nominal = {"mass.scale": 1.0}
    (seen,) = score(problem, nominal, {"mass": carried}, None)
    (unseen,) = score(problem, nominal, {"mass": plain}, None)
    assert seen["explained_fraction"] > 0.5 and unseen["explained_fraction"] < 1e-6
    result = fit(problem, nominal, _params(carried), start=seen["start"], intervals=False)
    assert abs(result.values["mass.scale"] - problem.truth) < 0.02


class _BasinProblem(_StandIn):
    """A stand-in for Problem whose one effect ``spine_stiffness.scale`` (truth 0.4) explains the residual only in a
    basin a factor of two wide and makes it worse outside, as the xJüs's spine stiffness does (lowest from
    about 0.3 to 0.55, above the nominal model's cost at 0.1, 0.2 and from 2 up)."""

    truth = 0.4

    def residuals(self, settings, segments=None, anchor=None):
        wave = np.sin(2 * np.pi * 3 * self.t)[:, None]
        out = []
        for s in settings:
            distance = abs(math.log(s.get("spine_stiffness.scale", 1.0) / self.truth))  # in e-folds of the ratio
            size = 1.0 if distance > 0.9 else distance / 0.9  # flat away from the truth: no slope to linearize
            out.append([Residual(size * wave + 0.01 * np.cos(40 * self.t)[:, None], np.zeros(0))])
        return out


def test_a_scale_over_decades_is_ranked_on_a_geometric_grid():
    from envs.common.effects import make
    from sysid.select import score, score_grid

    geometric = make("spine_stiffness", scale=(1.0, 0.1, 10.0), log=True)
    linear = make("spine_stiffness", scale=(1.0, 0.1, 10.0))
    grid = [p["spine_stiffness.scale"] for p in score_grid(geometric)]
    assert grid == pytest.approx([0.1, 0.1 * 10**0.5, 1.0, 10**0.5, 10.0])
    assert [p["spine_stiffness.scale"] for p in score_grid(linear)] == pytest.approx([0.1, 5.05, 10.0])
    # the linear grid's points all lie outside the basin and its Jacobian at nominal sees no slope: nothing to rank;
    # the geometric grid's 0.316 lies in it and explains most of the residual, and the fit starts there
    problem, nominal = _BasinProblem(), {"spine_stiffness.scale": 1.0}
    (seen,) = score(problem, nominal, {"spine_stiffness": geometric}, None)
    (unseen,) = score(problem, nominal, {"spine_stiffness": linear}, None)
    assert seen["explained_fraction"] > 0.5 and seen["start"]["spine_stiffness.scale"] == pytest.approx(0.316, 0.01)
    assert unseen["explained_fraction"] < 1e-6
    with pytest.raises(ValueError, match=r"spine_stiffness.scale: a log scale needs 0 < low < high"):
        make("spine_stiffness", scale=(1.0, 0.0, 10.0), log=True)


def test_a_phase_is_ranked_around_its_turn():
    """A periodic parameter (the roach's leg phase) is ranked on twelve points 30 degrees apart, its two ends (one
    angle) counted once: a three-point grid (-pi, 0, pi) would try one phase, nominal's."""
    from envs.common.effects import make
    from sysid.select import score_grid

    phase = make("leg_phase", "left", offset=(0.0, -math.pi, math.pi))
    assert phase.params[0].periodic
    grid = [p["leg_phase_left.offset"] for p in score_grid(phase)]
    assert grid == pytest.approx(np.radians(np.arange(-180, 180, 30)))


@pytest.mark.slow  # a Ray head's start-up is most of it; make bench runs the matrix as Ray tasks (--workers 2)
def test_the_matrix_gives_the_same_cases_on_ray_as_in_turn():
    """benchmarks/calibration_matrix.py --workers K runs its cases as Ray tasks, each on its share of the cores: same
    seeds, same results as one after another (the wall time of a case aside)."""
    from benchmarks.calibration_matrix import _on_ray, run_job

    plan = [("effect", "servo", "delay", 1)]  # one case: the Ray path is what is tested, the cases are elsewhere
    spread = {job: row for job, row, _ in _on_ray(plan, lambda: True, workers=2, threads=1, address=None)}
    for job in plan:
        here, there = run_job(job)[0], spread[job]
        here.pop("seconds"), there.pop("seconds")
        assert json.dumps(here, sort_keys=True) == json.dumps(there, sort_keys=True)


@pytest.mark.parametrize("value", ["0", "two", "-1"])
def test_a_bad_thread_cap_is_named(monkeypatch, value):
    from envs.common.batch import THREADS_VARIABLE, default_threads

    monkeypatch.setenv(THREADS_VARIABLE, value)
    with pytest.raises(ValueError, match=f"{THREADS_VARIABLE}='{value}'"):
        default_threads()
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    assert default_threads() == 1


def test_the_run_cache_keeps_what_a_call_asks_for_when_it_overflows():
    """A call that brings the cache of runs over its size must still find the settings it asked for that were cached
    before (a carried effect's grid with its anchor among them raised a KeyError in the xJüs's foot friction case)."""
    from sysid.problem import Problem

    log, _ = synth.synthesize("motor", {}, 0, seconds=2.0)
    problem = Problem(make_adapter("motor"), [log])
    nominal = problem.adapter.catalog_nominal()
    key = next(k for k in nominal if k.startswith("viscous_friction"))
    first = [{**nominal, key: 1e-4 * k} for k in range(60)]
    problem.residuals(first)
    again = [first[0], *({**nominal, key: 1e-4 * k + 5e-5} for k in range(10))]
    out = problem.residuals(again)
    assert len(out) == len(again)
    assert np.array_equal(out[0][0].data, problem.residuals([first[0]])[0][0].data)


def test_a_setting_that_adds_only_a_spring_rolls_out_beside_the_nominal_model():
    """A roach periodic load of the first harmonic adds a tendon and two sites and no joint: its rollouts get MjData
    of their own sizes (data shared by models that differ in any size is written out of bounds), and its
    residuals differ from the nominal model's, with the same segments."""
    from sysid.problem import model_sizes

    adapter = make_adapter("roach")
    log, _ = synth.synthesize("roach", {}, 0, seconds=4.0)
    problem = Problem(adapter, [log], nthread=1)
    nominal = adapter.catalog_nominal()
    loaded = {**nominal, "periodic_load_right.cos1": -3e-3}
    assert model_sizes(adapter.model_for(loaded)) != model_sizes(adapter.model_for(nominal))
    plain, spring = problem.residuals([nominal, loaded])
    assert len(plain) == len(spring) > 0
    assert all(np.isfinite(r.data).all() for r in spring)
    assert total_objective(spring) != total_objective(plain)


def test_two_logs_with_one_path_are_kept_apart():
    """A problem tells its logs apart by their place, not their path: two logs that share a path (two windows of one
    file, two synthetic runs) are scored, carried over and given a replay floor each as if their paths differed."""
    from sysid.problem import Problem

    adapter = make_adapter("bioloid")
    logs = [synth.synthesize("bioloid", {}, seed, seconds=3.0)[0] for seed in (0, 1)]
    for log in logs:
        log.path = "one.csv"
    apart = [synth.synthesize("bioloid", {}, seed, seconds=3.0)[0] for seed in (0, 1)]
    apart[0].path, apart[1].path = "a.csv", "b.csv"
    same, distinct = Problem(adapter, logs, nthread=1), Problem(adapter, apart, nthread=1)
    assert [s.source for s in same.segments] == [s.source for s in distinct.segments]
    assert same.scored == distinct.scored and len(same.scored) == len(same.segments) - 2
    assert same.replay_sigma == pytest.approx(distinct.replay_sigma, rel=1e-12)
    nominal = adapter.catalog_nominal()
    a, b = same.residuals([nominal])[0], distinct.residuals([nominal])[0]
    assert all(np.array_equal(x.data, y.data) for x, y in zip(a, b, strict=True))


def test_an_anchored_objective_asked_again_is_not_rolled_out_again():
    """A fit's grid shrinking around its best point asks for that point again, and grid points clipped to a range's
    end coincide: under the same anchor and noise levels, such a setting is not rolled out again, and its objective
    is the one a rollout gives. It is kept per segment: part of the segments measured before (a held-out fold's
    refit) costs no rollout, and a set that overlaps them rolls out only the segments it adds. New noise levels (a
    moved replay floor) measure it anew."""
    from sysid.fit import costs

    adapter = make_adapter("bioloid")
    problem = Problem(adapter, [synth.synthesize("bioloid", {}, 0, seconds=3.0)[0]], nthread=2)
    nominal = adapter.catalog_nominal()
    key = next(k for k in nominal if k.startswith("servo_gain"))
    settings = [{**nominal, key: v} for v in (0.8, 1.2, 0.8, 1.0)]
    costs(problem, [settings[3]], None, nominal)  # the anchor's own run and start sensitivities measured
    before = problem.rollouts
    first = costs(problem, settings, None, nominal)
    assert problem.rollouts - before == 2 * len(problem.scored)  # 0.8 once, 1.2; 1.0 measured before
    assert first[0] == first[2]
    direct = [total_objective(r) for r in problem.residuals(settings, None, anchor=nominal)]
    assert first == direct
    before = problem.rollouts
    assert costs(problem, settings[::-1], None, nominal) == first[::-1] and problem.rollouts == before
    assert len(problem.scored) >= 2
    part = problem.scored[1:]
    assert costs(problem, settings[:2], part, nominal) == [
        total_objective(r) for r in problem.residuals(settings[:2], part, anchor=nominal)
    ]
    assert problem.rollouts == before + len(part) * 2  # the direct residuals above; the costs themselves: none
    new = {**nominal, key: 0.9}
    before = problem.rollouts
    first_new = costs(problem, [new], part, nominal)
    assert problem.rollouts - before == len(part)
    both = costs(problem, [new, settings[1]], None, nominal)
    assert problem.rollouts - before == len(problem.scored)  # only the segment the new setting lacked
    assert both == [total_objective(r) for r in problem.residuals([new, settings[1]], None, anchor=nominal)]
    assert first_new == [total_objective(problem.residuals([new], part, anchor=nominal)[0])]
    problem.set_floor({**nominal, key: 1.1})
    before = problem.rollouts
    again = costs(problem, settings[:2], None, nominal)
    assert problem.rollouts > before and again != first[:2]


def test_the_replay_floor_keeps_the_logs_own_run_as_a_replay_of_them_makes_it():
    """The replay floor replays every reading of each log's twin in one chain, and the logs themselves beside them
    at the floor's setting; that run of the logs is kept as the setting's run. It must be the run a replay of the
    logs alone makes (predictions, starts and carried states, to the bit), and the floor the one measured twin by
    twin, log by log, as before the twins were batched."""
    from sysid.logs import Log
    from sysid.problem import FLOOR_TWINS, simulate

    adapter = make_adapter("bioloid")
    logs = [synth.synthesize("bioloid", {}, seed, seconds=3.0)[0] for seed in (0, 1)]
    problem = Problem(adapter, logs, nthread=2)
    nominal = adapter.catalog_nominal()
    kept = problem._carry[tuple(sorted(nominal.items()))]
    problem._carry.clear()
    fresh = problem._runs([nominal])
    for mine, theirs in zip(kept, fresh, strict=True):
        assert mine.keys() == theirs[0].keys() and len(mine) == len(problem.segments)
        for i, value in mine.items():
            assert (value is None and theirs[0][i] is None) or np.array_equal(value, theirs[0][i])
    # the floor, twin by twin (each reading's chain alone, one log at a time), as it was measured before
    squares, count = 0.0, 0
    real = problem.segments
    for source, log in enumerate(logs):
        clean = simulate(adapter, nominal, log.df, log.meta)
        index = problem._by_log[source]
        for seed in range(FLOOR_TWINS):
            noise = np.random.default_rng(seed)
            twin = log.df.copy()
            for j, c in enumerate(adapter.channels):
                twin[c] = adapter.measure(c, clean[:, j] + noise.normal(0.0, problem.sensor_sigma[c], len(clean)))
            problem.segments = list(real)
            for i, seg in zip(index, adapter.segments(Log(log.path, twin, log.meta)), strict=True):
                seg.n_steps, seg.source = problem.n_steps, source
                problem.segments[i] = seg
            problem._carry.clear()
            scored = [i for i in index if i in problem.scored]
            predictions, _ = problem._chain([nominal], scored)
            for i in scored:
                d = clean[real[i].samples] - predictions[(0, i)]
                squares, count = squares + np.sum(d * d, axis=0), count + len(d)
    problem.segments = real
    assert problem.replay_sigma == dict(zip(adapter.channels, np.sqrt(squares / count).tolist(), strict=True))


def test_two_servo_logs_with_one_path_keep_their_own_unlogged_goals():
    """An unlogged goal is fitted as nuisance parameters per log, keyed by the log's place in its problem as well as
    its path: two logs that share a path each keep their own goal steps (with the path alone, the second log's plan
    overwrote the first's and both replayed its goal)."""
    from sysid.problem import Problem

    adapter = make_adapter("servo")
    logs = [synth.synthesize("servo", {}, seed, seconds=4.0)[0] for seed in (0, 1)]
    for log in logs:
        log.df = log.df.drop(columns="goal")
    positions = [log.df["present_position"].to_numpy()[:200] for log in logs]
    assert np.abs(positions[0] - positions[1]).max() > 50  # counts: the two logs move differently
    apart = [dataclasses.replace(log, path=name) for log, name in zip(logs, ("a.csv", "b.csv"), strict=True)]
    for log in logs:
        log.path = "one.csv"
    plans = [adapter.goal_plan(log, k) for k, log in enumerate(logs)]
    same, distinct = adapter.nuisance(logs), adapter.nuisance(apart)
    assert len(same) == len(distinct) == sum(len(p) for p in plans)  # no log's plan lost
    replays = []
    for problem_logs, nuisance in ((logs, same), (apart, distinct)):
        setting = {**adapter.catalog_nominal(), **{k: p.nominal for k, p in nuisance.items()}}
        replays.append(Problem(adapter, problem_logs, nthread=1).residuals([setting])[0])
    # each log replays its own goal plan: the same residuals as with two paths
    assert all(np.array_equal(x.data, y.data) for x, y in zip(*replays, strict=True))


def test_visibility_is_the_same_against_either_floor_where_replay_has_no_floor(tmp_path, monkeypatch, capsys):
    """benchmarks/calibration_visibility measures an effect's error against the nominal model's replay floor and the
    truth's; a bench rig replays its whole state (no floor), so the two agree and a strong effect shows in both. A
    bad effect is refused with a message naming it, before anything is written."""
    from benchmarks import calibration_visibility as vis

    rows = vis.measure("motor", "viscous_friction", 0.02, [0], 2)["rows"]
    assert [(r["seed"], r["draw"]) for r in rows] == [(0, 0), (0, 1)]
    for r in rows:
        assert r["against_nominal_floor"] == pytest.approx(r["against_truth_floor"], rel=1e-12)
        assert r["against_nominal_floor"] > synth.MIN_NOMINAL_ERROR
    assert rows[0]["against_nominal_floor"] != rows[1]["against_nominal_floor"]  # the draws' commands differ
    # a matrix's results: each effect case measured at its truth, on its training and held-out seeds
    matrix = tmp_path / "matrix.json"
    matrix.write_text(json.dumps({"effects": [{"robot": "motor", "injected": {"viscous_friction": {"damping": 0.02}},
                                               "seed": 0, "nominal_error": 9.0, "error_before": 8.0}]}))  # fmt: skip
    (case,) = vis.matrix_cases(matrix)
    assert case["train"]["against_nominal_floor"] == pytest.approx(rows[0]["against_nominal_floor"], rel=1e-12)
    assert case["held_out"]["seed"] == 1000 and case["case_error_before"] == 8.0
    matrix.unlink()
    monkeypatch.setattr("benchmarks.common.RESULTS", tmp_path)
    with pytest.raises(SystemExit) as exit_info:
        vis.main(["--robot", "motor", "--effect", "no_such_effect=1"])
    assert exit_info.value.code == 2 and not list(tmp_path.iterdir())
    assert "no_such_effect" in capsys.readouterr().err


# 15 s: the draw-1 matrix runs this case (benchmarks/results/calibration_matrix_motor_servo_bioloid_draw1.md)
@pytest.mark.slow
def test_a_fit_that_stalls_below_a_measured_point_is_fitted_again_from_it():
    """A second draw: the motor's PWM decay at 0.785 (seed 1011) has a cost so curved (491 noise levels at
    nominal, 274 at 0.5, 1.03 at the truth, 626 at 1) that least squares from nominal stalls at 0.002, where the
    ranking's Jacobian promised more than its grid measured. The loop now refits from the grid's measured point when
    the fit ends above it (sysid.select.calibrate), and keeps the better fit."""
    from sysid.select import _params, calibrate, score

    (train,), _, truth = pair("motor", {"pwm_decay": None}, seed=1011)
    adapter = make_adapter("motor")
    problem = Problem(adapter, [train])
    nominal = adapter.catalog_nominal()
    effect = adapter.catalog()["pwm_decay"]
    (entry,) = score(problem, nominal, {"pwm_decay": effect}, None)
    assert entry["start"] == {} and entry["measured"] is not None  # the fit starts at nominal; a point is measured
    stalled = fit(problem, nominal, _params(effect), start=entry["start"], intervals=False)
    assert stalled.values["pwm_decay.coast"] < 0.05 and stalled.objective > entry["measured"][1]
    outcome = calibrate(problem, say=lambda s: None)
    value = truth["setting"]["pwm_decay.coast"]
    assert outcome.chosen[0].effect.name == "pwm_decay"
    assert outcome.chosen[0].values["pwm_decay.coast"] == pytest.approx(value, abs=0.01)


class _EndProblem(_StandIn):
    """A stand-in for Problem whose one carried effect ``leg_stiffness.scale`` (range 0.3 to 3) has the cost
    ``cost`` of its value (the carried state its own: anchored elsewhere the cost would not see it)."""

    def __init__(self, cost) -> None:
        super().__init__()
        self.cost = cost

    def residuals(self, settings, segments=None, anchor=None):
        assert anchor is None  # a carried parameter's cost is read with its own carried state
        return [[SimpleNamespace(objective=float(self.cost(s["leg_stiffness.scale"])))] for s in settings]


@pytest.mark.parametrize("at_end, refused", [(12790.0, False), (10250.0, True)])
def test_an_estimate_near_the_end_is_refused_only_where_the_cost_does_not_rise_there(monkeypatch, at_end, refused):
    """A second draw of the xJüs's leg stiffness (truth 2.8, range to 3): the fit found 2.916, with a rough
    cost's symmetric interval +-0.27, so the end 3 lay within one standard error; it was refused though the cost at
    3 was 12,790 against 10,245 at the estimate. Now the cost at the end is read: far above the estimate's (by more
    than the interval's threshold), the estimate is kept and its interval cut at 3; flat out to the end, the data
    would take it further, and it is refused as before."""
    from envs.common.effects import make
    from sysid import select
    from sysid.fit import FitResult

    effect = make("leg_stiffness", scale=(1.0, 0.3, 3.0), carried=True, log=True)
    problem = _EndProblem(lambda x: 10245.0 + (at_end - 10245.0) * ((x - 2.916) / 0.084) ** 2)
    trial = FitResult({"leg_stiffness.scale": 2.916}, 10245.0, n=100_000, n_eff=5_000)
    monkeypatch.setattr(select, "fit_intervals", lambda *a: {"leg_stiffness.scale": (2.646, 3.186)})
    verdict = select._identified(problem, [effect], {}, None, trial)
    if refused:
        assert verdict is not None and "within one standard error of the end of its range (3)" in verdict
    else:
        assert verdict is None and trial.bounds95["leg_stiffness.scale"] == (2.646, 3.0)


def nominal_log(robot: str, seed: int, seconds: float) -> Log:
    """The log ``synth.synthesize(robot, {}, seed, seconds=seconds)`` gives (the nominal model under the seed's
    commands, read with the robot's sensor noise), without the visibility that synthesize measures for the effects
    it injects: with none, that is a whole replay problem's floor (on the roach, most of the time)."""
    adapter = make_adapter(robot)
    return synth.noisy_log(adapter, {}, synth.excitation_commands(adapter, seconds, seed, 0), seed, robot)


def test_decisions_on_part_of_a_long_log_replay_only_that_part(monkeypatch):
    """The loop decides on a few segments of a long log (``decision_segments``). Where the body is carried from
    segment to segment, each run of decision segments is replayed from the one segment before it (its burn-in, as
    a log's first segment is), not from the log's start: a decision replay costs about two segments per decision
    segment however long the log, and a segment's residual does not depend on which others are asked for (the
    held-out test's folds). A bench rig, whose state the log holds, decides on its whole problem."""
    import sysid.select as select
    from sysid.problem import DecisionProblem

    monkeypatch.setattr(select, "MAX_DECISION_SEGMENTS", 3)
    whole = Problem(make_adapter("roach"), [nominal_log("roach", 0, 7.0)])
    fitting = select.decision_segments(whole)
    assert len(whole.scored) == 6 and len(fitting) == 3
    deciding = whole.decisions(fitting)
    assert isinstance(deciding, DecisionProblem) and deciding.scored == fitting
    for chain in deciding._by_log:  # each starts with a burn-in segment that is not scored, then consecutive ones
        assert chain[0] not in fitting and chain[1:] == list(range(chain[0] + 1, chain[-1] + 1))
        assert set(chain[1:]) <= set(fitting)
    setting = make_adapter("roach").catalog_nominal()
    before = whole.rollouts
    deciding._runs([setting])
    assert whole.rollouts - before == sum(len(chain) for chain in deciding._by_log) <= 2 * len(fitting)
    together = deciding.residuals([setting])[0]
    for k, i in enumerate(fitting):
        alone = deciding.residuals([setting], [i])[0][0]
        assert np.array_equal(alone.data, together[k].data)
    # a segment right after the log's first one is burnt in by that segment either way: the same residual
    everything = whole.residuals([setting])[0]
    second = whole.scored[0]
    assert fitting[0] == second  # (seeded: the spread over excitation picks the log's second segment)
    assert np.array_equal(together[0].data, everything[0].data)
    assert not np.array_equal(together[1].data, everything[whole.scored.index(fitting[1])].data)  # burnt in anew
    # noise levels and replay floor are the whole problem's, and measured there
    assert deciding.sigma == whole.sigma
    deciding.set_floor(setting)
    assert deciding.sigma == whole.sigma and deciding._sensitivity == {}
    with pytest.raises(ValueError, match="not scored"):
        whole.decisions([0, *fitting])  # the log's first segment burns in: it is never decided on
    with pytest.raises(ValueError, match="not decision segments"):
        deciding.residuals([setting], [whole.scored[1]])  # replayed by the whole problem only
    rig_log = synth.synthesize("motor", {}, 0, seconds=2.0)[0]
    rig = Problem(make_adapter("motor"), [rig_log])
    assert rig.decisions(rig.scored[:2]) is rig
    shortcut = nominal_log("motor", 0, 2.0)  # the log synthesize gives, as the roach's above (checked where it is fast)
    assert shortcut.df.equals(rig_log.df) and shortcut.meta == rig_log.meta


@pytest.mark.parametrize("robot", ["roach", "xjus", "bioloid", "motor", "servo"])
def test_a_settings_model_is_the_model_of_a_robot_built_with_its_edits(robot):
    """Each adapter compiles a setting's model from a copy of its nominal robot's spec (Robot.compile_with), not by
    building a robot: byte for byte the model a robot built with the setting's edits holds, for every catalogued
    effect at once at a random value and for each structural effect (backlash, bump, disturbance) on its own."""
    adapter = make_adapter(robot)
    rng = np.random.default_rng(3)
    every = adapter.catalog_nominal()
    settings = [every]
    for effect in adapter.effects().values():
        drawn = {effect.key(p.name): float(rng.uniform(p.low, p.high)) for p in effect.params}
        if adapter.structure(drawn) != adapter.structure({}):
            settings.append({**adapter.catalog_nominal(), **drawn})
        elif effect.catalogued:
            every.update(drawn)
    assert len(settings) >= 2  # a structural effect besides the setting of every catalogued one
    make = adapter._make_robot if hasattr(adapter, "_make_robot") else adapter._rig
    for setting in settings:
        edits = adapter.spec_edits(setting)
        assert model_bytes(adapter.build(edits)) == model_bytes(make(edits).model), setting


def test_the_matrix_runs_every_effect_then_the_next_draws_until_its_cases_per_robot():
    """benchmarks/calibration_matrix.py: a robot's effect cases are every observable effect at the first draw (the
    seeds reported before), then again at the next draws, until ``--seeds`` cases; effect k of the catalog at draw d
    takes seed 1000 d + k + 1, whichever effects run beside it."""
    from types import SimpleNamespace

    from benchmarks.calibration_matrix import effect_cases

    catalogued = ["a", "weak", "b", "c"]
    observable = ["a", "b", "c"]
    cases = effect_cases(catalogued, observable, SimpleNamespace(seeds=7, draw=0, effects=None))
    assert cases == [("a", 1), ("b", 3), ("c", 4), ("a", 1001), ("b", 1003), ("c", 1004), ("a", 2001)]
    assert effect_cases(catalogued, observable, SimpleNamespace(seeds=2, draw=1, effects=None)) == [
        ("a", 1001),
        ("b", 1003),
        ("c", 1004),
    ]  # every effect at least once
    assert effect_cases(catalogued, observable, SimpleNamespace(seeds=2, draw=0, effects=["c"])) == [
        ("c", 4),
        ("c", 1004),
    ]
    assert effect_cases(catalogued, observable, SimpleNamespace(seeds=5, draw=0, effects=["weak"])) == []


def test_the_matrix_says_where_its_time_went():
    """The matrix's report sums each case's own wall time per robot and kind, the weak declarations' checks
    included (they are not cases of the issue's counts, but they take time), and cases not run count nothing."""
    from benchmarks.calibration_matrix import _time_spent

    plan = [("effect", "roach", "delay", 1), ("effect", "roach", "mass", 2), ("weak", "roach", "mass", 0),
            ("null", "motor", None, 2), ("ooc", "motor", "disturbance", 3)]  # fmt: skip
    done = {plan[0]: {"seconds": 120.0}, plan[1]: {"seconds": 60.0}, plan[2]: {"seconds": 30.0},
            plan[3]: {"seconds": 6.0}}  # fmt: skip
    assert _time_spent(plan, done) == (
        "Case-minutes (each case's own wall time, summed): 3.6 in all; roach effect 3.0, weak 0.5; motor null 0.1."
    )


class _BeyondProblem(_StandIn):
    """A stand-in for Problem whose one effect ``mass.scale`` explains the residual at 3.4, beyond its range (to 2)."""

    truth = 3.4

    def residuals(self, settings, segments=None, anchor=None):
        wave = np.sin(2 * np.pi * 3 * self.t)[:, None]
        return [[Residual((self.truth - s.get("mass.scale", 1.0)) * wave, np.zeros(0))] for s in settings]


def test_an_effect_refused_at_the_end_of_its_range_says_what_the_data_ask_for():
    """The data want 3.4 of a scale whose range ends at 2: the fit stops at 2 and the effect is refused, saying which
    range it hit and, from a fit with that end moved out by the range's span, what the data ask for."""
    from envs.common.effects import make
    from sysid import select
    from sysid.fit import FitResult

    effect = make("mass", scale=(1.0, 0.5, 2.0))
    before = FitResult({}, 1.0, n=200, n_eff=200)
    reason, trial, _ = select._fit_candidate(_BeyondProblem(), {"mass.scale": 1.0}, [effect], {}, None, before,
                                             {"mass.scale": 1.5})  # fmt: skip
    assert trial.values["mass.scale"] == pytest.approx(2.0, abs=0.02)
    assert reason is not None and "pushes against the end of its range (2 1, range [0.5, 2])" in reason, reason
    asked = float(re.search(r"over \[0\.5, 3\.5\] the data ask for ([\d.]+)", reason).group(1))
    assert asked == pytest.approx(3.4, abs=0.02) and "again at that end" not in reason


class _BelowProblem(_BeyondProblem):
    """The data want a mass scale of 0.2, below its range (from 0.5); a model below ``unbuildable`` does not compile,
    as a body of (nearly) no mass does not."""

    truth = 0.2
    unbuildable = 0.0

    def residuals(self, settings, segments=None, anchor=None):
        for s in settings:
            if s.get("mass.scale", 1.0) <= self.unbuildable:
                raise ValueError("Error: mass and inertia of moving bodies must be larger than mjMINVAL\nElement")
        return super().residuals(settings, segments, anchor)


@pytest.mark.parametrize("unbuildable", [0.0, 0.3])
def test_what_the_data_ask_below_a_positive_range_stays_above_zero(unbuildable):
    """A scale pushed to the low end of its range (0.5, the data wanting 0.2) is asked about over a range moved out by
    its ratio, [0.125, 2], not down to 0, where a body has no mass and the model no longer compiles (which ended a
    calibration run); where the wider range's model cannot be built at all, the reason says so and the run goes
    on."""
    from envs.common.effects import make
    from sysid import select
    from sysid.fit import FitResult

    effect = make("mass", scale=(1.0, 0.5, 2.0))
    before = FitResult({}, 1.0, n=200, n_eff=200)
    problem = _BelowProblem()
    problem.unbuildable = unbuildable
    reason, trial, _ = select._fit_candidate(problem, {"mass.scale": 1.0}, [effect], {}, None, before,
                                             {"mass.scale": 0.8})  # fmt: skip
    assert trial.values["mass.scale"] == pytest.approx(0.5, abs=0.02)
    assert reason is not None and "range [0.5, 2]" in reason, reason
    if unbuildable == 0.0:
        asked = float(re.search(r"over \[0\.125, 2\] the data ask for ([\d.]+)", reason).group(1))
        assert asked == pytest.approx(0.2, abs=0.02)
    else:
        assert "over [0.125, 2] the model cannot be built (Error: mass and inertia" in reason, reason


def test_a_report_names_held_out_logs_run_under_conditions_no_training_log_holds():
    """The report measures every training and held-out log by itself and compares the adapter's condition
    quantities: a held-out log outside every training log's interval is named in its own section, in report.json,
    and beside the trace of what the residual points to."""
    from sysid.measurement import Measurement
    from sysid.report import CONDITIONS

    def measured(log: str, value: float) -> list[Measurement]:
        return [Measurement(log, "duty_at_clip", "right", value, value - 2.0, value + 2.0, "%", None, "-"),
                Measurement(log, "kp", "right", 1.0, 0.9, 1.1, "duty/rad", 1.0, "-")]  # fmt: skip

    values = {"a": 10.0, "b": 12.0, "c": 11.0, "d": 30.0}
    adapter = SimpleNamespace(report_extra=lambda result: {}, condition_quantities=("duty_at_clip",),
                              measure_log=lambda log: measured(log.path, values[log.path]))  # fmt: skip
    logs = {name: SimpleNamespace(path=name) for name in values}
    result = SimpleNamespace(train=[logs["a"], logs["b"]], test=[logs["c"], logs["d"]])
    extra = report_extra(adapter, result)
    assert [(c["log"], c["outside"]) for c in extra["conditions"]] == [("c", False), ("d", True)]
    section = extra["sections"][CONDITIONS]
    assert "| duty_at_clip (%) | right | 10 [8, 12]; 12 [10, 14] | d | 30 [28, 32] | **outside, above** |" in section
    assert "duty_at_clip right on d (30 [28, 32], above)" in section
    trace = {"text": "duty_right: follows the load", "mechanism": "what the drive carries", "channel": "duty_right",
             "out_of_catalog": [], "missing": [], "effects": {}}  # fmt: skip
    report = {"robot": "roach", "train": ["a", "b"], "test": ["c", "d"], "error_before": 5.0, "error_after": 4.0,
              "unexplained": True, "unexplained_reason": "", "per_channel": {}, "mode": "select", "chosen": [],
              "rejected": [], "trace": trace, "diagnostics": {"findings_before": []}, "ranking": [], "extra": extra,
              "segments": {"train": 1, "test": 1, "seconds_each": 1.0}, "rollouts": 1, "wall_seconds": 1.0}  # fmt: skip
    text = report_markdown(report)
    assert f'ran under conditions no training log holds (duty_at_clip right; section "{CONDITIONS}")' in text
    assert f"## {CONDITIONS}" in text
    # without a training log's measurement of the quantity, nothing is compared
    lone = report_extra(adapter, SimpleNamespace(train=[], test=[logs["c"]]))
    assert "conditions" not in lone and CONDITIONS not in lone["sections"]
