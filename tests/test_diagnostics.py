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
    problem = SimpleNamespace(segments=[SimpleNamespace(data=data)], scored=[0], channels=["angle_left", "angle_right"])
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
