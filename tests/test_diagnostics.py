"""Residual diagnostics point to a cause: each is checked on a residual built with that cause and no other."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from sysid import diagnostics

T = np.arange(0.0, 4.0, 1e-3)
RATE = 2 * np.pi * 3.0  # a crank turning at 3 Hz


def _diagnose(residual_left: np.ndarray, residual_right: np.ndarray | None = None, **context):
    rng = np.random.default_rng(0)
    phase = RATE * T
    data = {"time": T, "rate_left": np.full_like(T, RATE) * np.sign(np.sin(2 * T)), "angle_left": phase,
            "rate_right": np.full_like(T, RATE), "angle_right": phase + np.pi, "cmd_left": np.sin(2 * T),
            "load_left": np.cos(phase)}  # fmt: skip
    right = rng.normal(0, 1, len(T)) if residual_right is None else residual_right
    segment = SimpleNamespace(data=data, source=0, log="run.txt")
    problem = SimpleNamespace(segments=[segment], scored=[0], channels=["angle_left", "angle_right"])
    residuals = [SimpleNamespace(data=np.column_stack([residual_left, right]))]
    return diagnostics.diagnose(problem, residuals, context)


def test_per_channel_context_and_sign_of_velocity():
    noise = np.random.default_rng(1).normal(0, 1, len(T))
    velocity = {"angle_left": "rate_left", "angle_right": "rate_right"}
    d = _diagnose(3 * np.sign(np.sin(2 * T)) + noise, velocity=velocity)
    assert d["angle_left"]["with_sign_of_velocity"] > 0.9
    assert "with_sign_of_velocity" in d["angle_right"]  # its own column, constant: no correlation
    assert abs(d["angle_right"]["with_sign_of_velocity"]) < 0.1
    assert any("sign of velocity" in s for s in diagnostics.summarize(d))


def test_stance_against_swing():
    rng = np.random.default_rng(2)
    stance = np.cos(RATE * T) > 0
    residual = rng.normal(0, 1, len(T)) * np.where(stance, 4.0, 1.0)
    d = _diagnose(residual, phase={"angle_left": "angle_left", "angle_right": "angle_right"})
    assert d["angle_left"]["stance_over_swing"] == pytest.approx(4.0, rel=0.1)
    assert d["angle_right"]["stance_over_swing"] == pytest.approx(1.0, rel=0.1)
    assert any("larger in stance" in s for s in diagnostics.summarize(d))


def test_left_against_right_and_load():
    rng = np.random.default_rng(3)
    load = np.cos(RATE * T)
    d = _diagnose(5 * load + rng.normal(0, 1, len(T)), load={"angle_left": "load_left"})
    assert d["angle_left"]["left_over_right"] > 2.5
    assert d["angle_left"]["with_load"] > 0.9 and "with_load" not in d["angle_right"]
    found = diagnostics.summarize(d, limit=5)
    assert any("left side's residual" in s for s in found) and any("follows the load" in s for s in found)


def test_lag_of_command():
    u = np.sin(2 * T)
    lag = 0.02
    du = np.diff(u, prepend=u[0])
    residual = np.concatenate([np.zeros(20), du[:-20]]) * 1e3
    d = _diagnose(residual, command={"angle_left": "cmd_left"})
    assert d["angle_left"]["lag_of_command"] == pytest.approx(lag, abs=2e-3)


def _two_logs(residual: np.ndarray, rate: np.ndarray, effort: np.ndarray):
    """Diagnostics of one channel over two logs of 4 s each (the second's residual is noise), with a velocity and a
    drive effort column."""
    noise = np.random.default_rng(7).normal(0, 1, len(T))
    segments, residuals = [], []
    for source, (r, v, u) in enumerate(
        [(residual, rate, effort), (noise, np.full_like(T, RATE), np.full_like(T, 0.5))]
    ):
        data = {"time": T, "rate": v, "effort": u}
        segments.append(SimpleNamespace(data=data, source=source, log=f"run{source}.txt"))
        residuals.append(SimpleNamespace(data=r[:, None]))
    problem = SimpleNamespace(segments=segments, scored=[0, 1], channels=["angle"])
    return diagnostics.diagnose(problem, residuals, {"velocity": "rate", "load": "effort"})["angle"]


def test_a_residual_gathered_at_a_moment_is_found_there_and_a_held_drive_is_a_stall():
    """A residual gathered in 0.3 s of one of two 4 s logs is a moment found in that log at that time; with the
    drive's effort at its clip and the joint still there, a stall. A residual spread over the run, or growing
    steadily with time, is no moment."""
    rng = np.random.default_rng(5)
    moment = (T >= 2.5) & (T < 2.8)
    residual = rng.normal(0, 1, len(T)) + np.where(moment, 12.0, 0.0)
    rate = np.where(moment, 0.0, RATE)
    effort = np.where(moment, 1.0, 0.4 + 0.2 * np.sin(RATE * T))  # held at its clip at the moment
    d = _two_logs(residual, rate, effort)
    assert d["event_share"] > 0.6 and d["event_log"] == "run0.txt"  # the moment holds 84%; the span, 90% of it
    assert d["event_start"] == pytest.approx(2.5, abs=0.05) and d["event_end"] == pytest.approx(2.8, abs=0.05)
    assert d["event_fraction"] == pytest.approx(0.3 / 8, abs=0.01)
    assert d["event_stall"]
    found = [f for f in diagnostics.findings({"angle": d}) if f.key in ("moment", "stall")]
    assert len(found) == 1 and found[0].key == "stall"
    assert "run0.txt between" in found[0].text and "a stall" in found[0].text
    # the same moment with the joint moving the way the drive pushes (the response to a command, say): no stall
    moving = _two_logs(residual, np.full_like(T, RATE), effort)
    assert moving["event_share"] > 0.6 and not moving["event_stall"]
    assert "stall" not in next(f.text for f in diagnostics.findings({"angle": moving}) if f.key == "moment")
    # spread residuals: noise, a periodic one, and one growing linearly with time over both logs
    for spread in (rng.normal(0, 3, len(T)), 4 * np.sin(RATE * T), 3 * T / T[-1] + rng.normal(0, 0.3, len(T))):
        d = _two_logs(spread, np.full_like(T, RATE), np.full_like(T, 0.5))
        assert d["event_share"] < diagnostics.EVENT_SHARE
        assert not any(f.key in ("moment", "stall") for f in diagnostics.findings({"angle": d}))


def test_a_leg_held_in_a_synthetic_roach_log_is_found_as_a_stall():
    """A synthetic roach log whose right legs are held for 0.3 s (angle frozen, duty at its clip, no back-EMF), as a
    hand or an obstacle would hold them; nobody tells the diagnostics: the nominal model's residual is found
    gathered there, as a stall, on the right side."""
    from sysid.fit import evaluate
    from sysid.problem import Problem
    from sysid.robots import adapter
    from sysid.synth import synthesize

    log, _ = synthesize("roach", {}, seed=0, seconds=4.0)  # its right legs turn throughout
    t = log.df["time"].to_numpy()
    # the 0.3 s inside one replayed segment (the second, 2-3 s) where the right legs turn the most (the excitation
    # rests at times)
    angle = log.df["leg_angle_right"].to_numpy()
    starts = np.arange(2.1, 2.65, 0.05)
    start = max(starts, key=lambda a: abs(np.interp(a + 0.3, t, angle) - np.interp(a, t, angle)))
    held = (t >= start) & (t < start + 0.3)
    log.df.loc[held, "leg_angle_right"] = log.df["leg_angle_right"][held].iloc[0]
    log.df.loc[held, "duty_right"] = float(log.meta["duty_clip"])
    log.df.loc[held, "bemf_right"] = 0.0
    roach = adapter("roach")
    problem = Problem(roach, [log], 1)
    d = diagnostics.diagnose(problem, evaluate(problem, {}).residuals, roach.context)
    events = [f for f in diagnostics.findings(d) if f.key in ("moment", "stall")]
    assert events and events[0].channel == "leg_angle_right" and events[0].key == "stall"
    leg = d["leg_angle_right"]
    assert leg["event_share"] > 0.5 and leg["event_stall"] and "a stall" in events[0].text
    assert start - 0.05 <= leg["event_start"] and leg["event_end"] <= start + 0.35
    # the held-out error without the stall's span (every channel's samples of that log, between its start and end)
    # is the sum of squares outside it over the samples outside it, and falls with the stall left out
    residuals = evaluate(problem, {}).residuals
    outside = problem.error_outside(residuals, leg["event_log"], leg["event_start"], leg["event_end"])
    kept = [
        r.data[
            (problem.segments[i].data["time"] < leg["event_start"])
            | (problem.segments[i].data["time"] > leg["event_end"])
        ]
        for i, r in zip(problem.scored, residuals, strict=True)
    ]
    prior = sum(float(r.prior @ r.prior) for r in residuals)
    expected = np.sqrt((sum(float(np.sum(k * k)) for k in kept) + prior) / sum(k.size for k in kept))
    assert outside == pytest.approx(expected, rel=1e-12)
    assert outside < 0.5 * problem.error(residuals)
    assert problem.error_outside(residuals, "another.txt", leg["event_start"], leg["event_end"]) == pytest.approx(
        problem.error(residuals), rel=1e-12
    )
    # the same log given for training: the loop finds the stall before its fit (and warns); the log unheld holds none
    from sysid.pipeline import HeldOut, Result, training_stall

    warned = training_stall(problem, {})
    assert (warned["channel"], warned["log"], warned["start"], warned["end"]) == (
        "leg_angle_right",
        leg["event_log"],
        leg["event_start"],
        leg["event_end"],
    )
    assert training_stall(Problem(roach, [synthesize("roach", {}, seed=0, seconds=4.0)[0]], 1), {}) is None
    # the calibration result names that span and gives the error without it, before and after

    nominal = HeldOut(problem.error(residuals), problem.channel_errors(residuals), residuals)
    result = Result(roach, [], [log], None, nominal, nominal, [], problem, problem, _diagnostics=d)
    found = result.without_stall()
    assert found["channel"] == "leg_angle_right" and found["log"] == leg["event_log"]
    assert (found["start"], found["end"]) == (leg["event_start"], leg["event_end"])
    assert found["before"] == found["after"] == pytest.approx(outside, rel=1e-12)
    d_quiet = {k: {**v, "event_stall": False} for k, v in d.items()}
    assert (
        Result(roach, [], [log], None, nominal, nominal, [], problem, problem, _diagnostics=d_quiet).without_stall()
        is None
    )


def test_a_stall_is_traced_to_no_catalog_effect_and_a_moment_to_the_drive_s_transients():
    """A stall's trace names no catalog effect (the catalog's act throughout a run) and the bump kept out of it; a
    moment without a stall (a step's transient, most often) asks the lag, inertia and friction effects on its
    channel."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    roach = adapter("roach")
    t = trace(roach, _outcome(roach), [diagnostics.Finding(9.0, "leg_angle_right", "stall", "leg_angle_right: 70%")])
    assert t["finding"] == "stall" and t["effects"] == {} and t["out_of_catalog"] == ["terrain_bump"]
    assert "not a property of the robot" in t["why"] and "has no effect of that kind" in t["why"]
    motor = adapter("motor")
    t = trace(motor, _outcome(motor), [diagnostics.Finding(9.0, "speed", "moment", "speed: 57%")])
    assert {"delay", "armature", "coulomb_friction"} <= set(t["effects"]) and "change of the command" in t["why"]


def _outcome(adapter, chosen=(), rejected=(), ranked=()):
    """An outcome as the selection leaves it: ``chosen`` effect names with values, ``rejected`` (name, reason),
    ``ranked`` names with the share of the residual each explains, in one round."""
    from sysid.select import Choice, Outcome

    catalog = adapter.catalog()
    nominal = adapter.catalog_nominal()
    choices = []
    for name, values in chosen:
        e = catalog[name]
        choices.append(Choice(e, {e.key(k): v for k, v in values.items()}, {}, 10.0, 2.0))
    ranking = [{"effect": n, "alias_group": catalog[n].alias, "score": 5.0, "p_value": 0.01,
                "explained_fraction": share} for n, share in ranked]  # fmt: skip
    return Outcome(setting=dict(nominal), nominal=dict(nominal), chosen=choices,
                   rejected=[{"name": n, "reason": r} for n, r in rejected], rounds=[ranking],
                   history=[dict(nominal)])  # fmt: skip


def test_every_mechanism_names_catalog_templates():
    from envs.common.effects import TEMPLATES

    for key, (_, kinds) in diagnostics.MECHANISMS.items():
        assert set(kinds) <= set(TEMPLATES), (key, set(kinds) - set(TEMPLATES))
    assert diagnostics.BODY_KINDS <= set(TEMPLATES)


def test_trace_names_the_mechanism_and_each_effect_of_its_kind():
    """The strongest finding on what remains (the right duty follows the load) names its mechanism and, for every
    catalog effect of that kind on the right side or on no side, what became of it; effects of other kinds and of
    the left side are not asked about; kinds the robot declares out of its catalog, and those it lacks, are named."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    roach = adapter("roach")
    outcome = _outcome(
        roach,
        chosen=[("gearbox_efficiency_right", {"efficiency": 0.4})],
        rejected=[("coulomb_friction_right", "coulomb_friction_right.torque pushes against the end of its range"),
                  ("armature_left + ground_contact", "together: ground_contact.timeconst pushes against the end")],
        ranked=[("mass", 0.004), ("leg_stiffness", 0.001), ("coulomb_friction_left", 0.2)],
    )  # fmt: skip
    found = [
        diagnostics.Finding(9.0, "duty_right", "with_load", "duty_right: the residual follows the load"),
        diagnostics.Finding(2.0, "bemf_left", "bias", "bemf_left: a constant offset"),
    ]
    t = trace(roach, outcome, found)
    assert t["channel"] == "duty_right" and t["mechanism"] == diagnostics.MECHANISMS["with_load"][0]
    fates = {name: e["fate"] for name, e in t["effects"].items()}
    words = {name: e["words"] for name, e in t["effects"].items()}
    assert fates["gearbox_efficiency_right"] == "kept" and "0.4" in words["gearbox_efficiency_right"]
    assert fates["coulomb_friction_right"] == "refused" and "end of its range" in words["coulomb_friction_right"]
    # refused only in a chain: said so, with its partner
    assert fates["ground_contact"] == "together" and "in a chain with armature_left" in words["ground_contact"]
    assert fates["mass"] == fates["leg_stiffness"] == "ranked" and "ranked 1 of 3" in words["mass"]
    assert "0.4%" in words["mass"] and "barely seen" in words["mass"]
    assert "gearbox_efficiency_left" not in fates and "coulomb_friction_left" not in fates  # the other side
    assert "sensor_bias_bemf_right" not in fates and "delay" not in fates  # other kinds
    assert "sensor_coupling_bemf_right" not in fates  # a load kind, but it acts on the back-EMF reading alone
    assert t["out_of_catalog"] == ["terrain_bump"] and set(t["missing"]) == {
        "load_friction",
        "supply_sag",
        "spine_stiffness",
    }
    assert t["why"].startswith(t["mechanism"] + ": of the catalog's effects of that kind, gearbox_efficiency_right")
    assert "coulomb_friction_right refused" in t["why"] and "ground_contact refused in a chain only" in t["why"]


def test_trace_asks_only_the_effects_on_the_finding_s_legs():
    """The xJüs's and the Bioloid's side effects act on their side's legs, whose channels do not end with the side."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    xjus = adapter("xjus")
    finding = [diagnostics.Finding(5.0, "leg_angle_FL", "with_sign_of_velocity", "leg_angle_FL: sign of velocity")]
    t = trace(xjus, _outcome(xjus), finding)
    assert "coulomb_friction_left" in t["effects"] and "coulomb_friction_right" not in t["effects"]
    t = trace(xjus, _outcome(xjus), [diagnostics.Finding(5.0, "current_MR", "bias", "current_MR: offset")])
    assert not any(name.endswith("_left") or name.startswith("sensor_bias_angle") for name in t["effects"])
    bioloid = adapter("bioloid")
    finding = [diagnostics.Finding(5.0, "present_position_B_R_2", "bias", "present_position_B_R_2: offset")]
    t = trace(bioloid, _outcome(bioloid), finding)
    assert "sensor_bias_position_right" in t["effects"] and "sensor_bias_position_left" not in t["effects"]
    t = trace(bioloid, _outcome(bioloid), [diagnostics.Finding(5.0, "present_position_HEAD", "bias", "HEAD")])
    assert not any(name.endswith(("_left", "_right")) for name in t["effects"])


def test_trace_says_when_the_catalog_has_no_effect_of_the_kind():
    """A periodic residual on the gearmotor rig, whose catalog holds no disturbance: the trace says so, names the
    disturbance declared out of the catalog and no body effect (a rig has no body); with nothing standing out there
    is no trace."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    motor = adapter("motor")
    t = trace(motor, _outcome(motor), [diagnostics.Finding(5.0, "speed", "spectral", "speed: a spectral peak")])
    assert t["effects"] == {} and "has no effect of that kind" in t["why"]
    assert t["out_of_catalog"] == ["disturbance"] and t["missing"] == []
    assert trace(motor, _outcome(motor), []) is None
    # an effect of the calibration the run started from is said to be held there
    started = _outcome(motor)
    started.started = ["supply_sag.resistance"]
    t = trace(motor, started, [diagnostics.Finding(5.0, "speed", "with_supply", "speed: follows the supply")])
    assert t["effects"]["supply_sag"]["fate"] == "start" and t["effects"]["supply_voltage"]["fate"] == "unranked"
    started.mode = "fit"
    t = trace(motor, started, [diagnostics.Finding(5.0, "speed", "with_supply", "speed: follows the supply")])
    assert "--fit" in t["effects"]["supply_voltage"]["words"]
