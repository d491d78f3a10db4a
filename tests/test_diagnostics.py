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
