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


def test_trace_names_the_mechanism_and_each_effect_of_its_kind():
    """The strongest finding on what remains (the right duty follows the load) names its mechanism and, for every
    catalog effect of that kind on the right side or on no side, what became of it; effects of other kinds and of
    the left side are not asked about, and kinds the robot's catalog lacks are named."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    roach = adapter("roach")
    outcome = _outcome(
        roach,
        chosen=[("gearbox_efficiency_right", {"efficiency": 0.4})],
        rejected=[("coulomb_friction_right", "coulomb_friction_right.torque pushes against the end of its range")],
        ranked=[("mass", 0.004), ("leg_stiffness", 0.001), ("coulomb_friction_left", 0.2)],
    )
    found = [
        diagnostics.Finding(9.0, "duty_right", "with_load", "duty_right: the residual follows the load"),
        diagnostics.Finding(2.0, "bemf_left", "bias", "bemf_left: a constant offset"),
    ]
    t = trace(roach, outcome, found)
    assert t["channel"] == "duty_right" and t["mechanism"] == diagnostics.MECHANISMS["with_load"][0]
    fates = {name: e["fate"] for name, e in t["effects"].items()}
    assert fates["gearbox_efficiency_right"] == "kept" and "0.4" in t["effects"]["gearbox_efficiency_right"]["words"]
    assert fates["coulomb_friction_right"] == "refused"
    assert "end of its range" in t["effects"]["coulomb_friction_right"]["words"]
    assert fates["mass"] == fates["leg_stiffness"] == "ranked" and "0.4%" in t["effects"]["mass"]["words"]
    assert "gearbox_efficiency_left" not in fates and "coulomb_friction_left" not in fates  # the other side
    assert "sensor_bias_bemf_right" not in fates and "delay" not in fates  # other kinds
    # the load kinds the roach's catalog has no effect of
    assert set(t["missing"]) == {"load_friction", "supply_sag", "terrain_bump"}
    assert "gearbox_efficiency_right kept" in t["why"] and "coulomb_friction_right refused" in t["why"]
    assert "load_friction" in t["why"]


def test_trace_says_when_the_catalog_has_no_effect_of_the_kind():
    """A periodic residual on a robot whose catalog holds no disturbance: the trace says so, and nothing is listed
    as tried; with nothing standing out there is no trace."""
    from sysid.pipeline import trace
    from sysid.robots import adapter

    motor = adapter("motor")
    assert not any(name.startswith(("disturbance", "terrain_bump")) for name in motor.catalog())
    t = trace(motor, _outcome(motor), [diagnostics.Finding(5.0, "speed", "spectral", "speed: a spectral peak")])
    assert t["effects"] == {} and "has no effect of that kind" in t["why"]
    assert t["missing"] == ["disturbance", "terrain_bump"]
    assert trace(motor, _outcome(motor), []) is None
    # an effect of the calibration the run started from is said to be held there
    started = _outcome(motor)
    started.nominal["supply_sag.resistance"] = 0.5
    t = trace(motor, started, [diagnostics.Finding(5.0, "speed", "with_supply", "speed: follows the supply")])
    assert t["effects"]["supply_sag"]["fate"] == "start" and t["effects"]["supply_voltage"]["fate"] == "unranked"
