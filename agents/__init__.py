"""Policies: scripted gaits and trained models behind one ``predict()``, resolved by name or path.

Each robot's scripted gaits live in ``agents/<robot>/``, whose ``__init__`` lists them in ``POLICIES`` (name ->
:class:`ScriptedPolicy`); :func:`load_policy` finds them there, so adding a robot adds a folder and edits nothing
here. A name may carry an argument after a colon (``tripod:20``).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np


class Policy(Protocol):
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]: ...


@dataclass(frozen=True)
class ScriptedPolicy:
    """A scripted gait: for which robots, what it does, and how to build it for an env (``arg``: after the colon)."""

    robots: tuple[str, ...]
    description: str
    build: Callable[[Any, str], Policy]


def scripted_policies() -> dict[str, list[ScriptedPolicy]]:
    """Every robot folder's scripted policies, by name (one name may serve several robots with different gaits)."""
    found: dict[str, list[ScriptedPolicy]] = {}
    for module in pkgutil.iter_modules(__path__):
        if module.ispkg:
            for name, entry in getattr(importlib.import_module(f"{__name__}.{module.name}"), "POLICIES", {}).items():
                found.setdefault(name, []).append(entry)
    return found


def reference_policy(robot: str) -> str:
    """The name of a robot's reference gait: its agents folder's ``REFERENCE`` (the gait the shared tools and tests
    run on every env of that robot)."""
    for module in pkgutil.iter_modules(__path__):
        if module.ispkg:
            package = importlib.import_module(f"{__name__}.{module.name}")
            entries = getattr(package, "POLICIES", {})
            name = getattr(package, "REFERENCE", None)
            if name is not None and any(robot in e.robots for e in [entries[name]]):
                return name
    raise ValueError(f"no reference gait for the {robot}: its agents/<robot>/__init__.py names none (REFERENCE)")


def env_reference(env) -> str:
    """The scripted policy a learner on ``env`` is compared with: what an agents package's ``reference_for(env)``
    names (agents/soccer: the scripted player on a soccer academy task in the ``commands`` mode), else the robot's
    reference gait (:func:`reference_policy`)."""
    for module in pkgutil.iter_modules(__path__):
        if module.ispkg:
            hook = getattr(importlib.import_module(f"{__name__}.{module.name}"), "reference_for", None)
            name = None if hook is None else hook(env)
            if name is not None:
                return name
    return reference_policy(env.unwrapped.robot.name)


class RandomPolicy:
    """Uniform actions over the env's action space, from a generator of its own (``random:SEED``, default seed 0):
    the zero of a normalized score (the leaderboard's), on every robot."""

    def __init__(self, env, arg: str = ""):
        try:
            seed = int(arg) if arg else 0
        except ValueError:
            seed = -1
        if seed < 0:
            raise ValueError(f"random:{arg}: the seed after 'random:' must be a whole number >= 0")
        from agents.residual import action_bounds

        self.low, self.high = action_bounds(env)
        self.rng = np.random.default_rng(seed)

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        obs = np.asarray(observation)
        rows = () if obs.ndim == 1 else (len(obs),)
        action = self.rng.uniform(self.low, self.high, (*rows, len(self.low))).astype(np.float32)
        return action, state


def describe_policies() -> str:
    """One line per scripted policy, for --help texts."""
    return "; ".join(
        [f"{name} ({', '.join(e.robots)}): {e.description}" for name, entries in scripted_policies().items()
         for e in entries] + ["random (every robot): uniform actions, random:SEED (default 0)"]
    )  # fmt: skip


def residual_reference(name: str, env) -> Policy:
    """The scripted gait a residual policy adds to (agents/residual.py): any scripted policy of the robot."""
    if name.endswith(".zip") or Path(name).is_file():
        raise ValueError(f"policy {name!r}: a residual adds to a scripted gait, not to a model")
    return load_policy(name, env)


def load_policy(spec: str, env) -> Policy:
    """A policy for ``env`` from a scripted gait's name (see :func:`scripted_policies`) or a trained ``model.zip``."""
    if spec.endswith(".zip") or Path(spec).is_file():
        from agents.residual import ResidualPolicy, parse_residual
        from agents.sb3 import SB3Policy

        model = SB3Policy(spec, env)
        residual = model.manifest.get("residual")  # a residual policy plays on top of its reference gait
        if residual is None:
            return model
        residual = parse_residual(residual)
        return ResidualPolicy(model, residual, residual_reference(residual.policy, env), env)
    if Path(spec).is_dir():  # a run folder: its final model is inside
        inside = Path(spec) / "model.zip"
        hint = f"; its model is {inside}" if inside.is_file() else ""
        raise ValueError(f"policy {spec!r} is a folder: give the path of a model.zip{hint}")
    name, colon, arg = spec.partition(":")
    if colon and not arg:
        raise ValueError(f"policy {spec!r}: nothing after ':' (give {name!r} alone, or {name}:VALUE)")
    if name == "random":
        return RandomPolicy(env, arg)
    robot = env.unwrapped.robot.name
    policies = scripted_policies()
    for entry in policies.get(name, []):
        if robot in entry.robots:
            return entry.build(env, arg)
    fitting = ", ".join(n for n, entries in policies.items() if any(robot in e.robots for e in entries)) or "none"
    raise ValueError(
        f"unknown policy {spec!r} for the {robot}: give a scripted gait ({fitting}), random, or the path of a model.zip"
    )
