"""Residual policies: a learned correction on top of the robot's reference gait.

The learner's action ``a`` in [-1, 1] is scaled and added to the reference gait's action for the same observation,
and the sum clipped to the env's action space: the env receives ``clip(reference(obs) + scale * a, -1, 1)``. A new
policy's actions are near 0, so training starts from the gait (the tripod's frequencies and phase, the Buehler clock's
period and sweeps, the IK trot's servo goals) rather than from noise, and learns what to change.

Train one with a hyperparameter entry's ``residual``: the reference's name (``tripod``, ``buehler:0.6``, ``ik-trot``,
``cpg``: any scripted policy of the robot, as ``evaluate.py --policy`` takes them) or ``{policy: NAME, scale: S,
exploration: E}`` (default scale :data:`DEFAULT_SCALE`, at most 2). The run's model file records it, and
``evaluate.py`` (and every ``load_policy``) plays the model with its reference again. The reference sees the env's
own observations (before any normalization), and restarts with each episode. An entry's ``residual`` without a
``policy`` (``{scale: S, exploration: E}``) makes no run residual by itself: it says how a residual run on that env is
made when one is asked for (``train.py --residual GAIT``, the leaderboard's ``+residual`` rows).

The policy's mean action starts near 0, but PPO's and SAC's Gaussian explores around it with the standard deviation
``exp(log_std_init)``: 1 for PPO, whose sampled corrections then reach the whole scale from the first step. Where
the gait does not survive that (the Bioloid's steered trot on its turning task scores -110 with it against its own
375: docs/training.md), ``exploration`` sets the policy's initial standard deviation (``log_std_init`` =
``log(exploration)``), so that training starts from the gait in its rollouts too.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper

DEFAULT_SCALE = 0.25  # of the action range: a correction up to a quarter of each action's half-range
MAX_SCALE = 2.0
SETTINGS = ("scale", "exploration")  # what an entry's residual may set besides its policy


def action_bounds(env: Any) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of one simulation's action in ``env``: a gym env, a batched gym env or an SB3 VecEnv."""
    base = getattr(env, "unwrapped", env)
    space = getattr(base, "single_action_space", None) or env.action_space
    return np.asarray(space.low, np.float64), np.asarray(space.high, np.float64)


@dataclass(frozen=True)
class Residual:
    """What a residual policy adds to: the reference's name, the correction's scale and, if set, the policy's initial
    standard deviation (``exploration``; None: the algorithm's own)."""

    policy: str
    scale: float = DEFAULT_SCALE
    exploration: float | None = None

    def record(self) -> dict[str, Any]:
        record = {"policy": self.policy, "scale": self.scale}
        return record if self.exploration is None else {**record, "exploration": self.exploration}


def names_a_gait(value: Any) -> bool:
    """Whether an entry's ``residual`` makes its runs residual (a gait's name, or a mapping with ``policy``), rather
    than only setting how a residual run is made (:func:`residual_settings`)."""
    return not isinstance(value, dict) or "policy" in value


def residual_settings(value: Any) -> dict[str, float]:
    """The settings of an entry's ``residual`` without a policy (``{scale: S, exploration: E}``), checked; ValueError
    says what is wrong."""
    if not isinstance(value, dict) or set(value) - set(SETTINGS):
        raise ValueError(f"expected a scripted policy's name or a mapping of policy, {', '.join(SETTINGS)}")
    settings = {}
    if "scale" in value:
        settings["scale"] = _in_range("scale", value["scale"], MAX_SCALE)
    if "exploration" in value:
        settings["exploration"] = _in_range("exploration", value["exploration"], 1.0)
    return settings


def _in_range(name: str, value: Any, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0.0 < value <= high:
        raise ValueError(f"{name} must be a number in (0, {high:g}], got {value!r}")
    return float(value)


def parse_residual(value: Any) -> Residual:
    """A hyperparameter entry's ``residual`` (a name, or ``{policy, scale, exploration}``); ValueError says what is
    wrong."""
    if isinstance(value, str):
        value = {"policy": value}
    if not isinstance(value, dict) or "policy" not in value:
        raise ValueError("expected a scripted policy's name or a mapping {policy: NAME, scale: S, exploration: E}")
    policy = value["policy"]
    if not isinstance(policy, str) or not policy:
        raise ValueError(f"policy must be a scripted policy's name, got {policy!r}")
    settings = residual_settings({k: v for k, v in value.items() if k != "policy"})
    return Residual(policy, settings.get("scale", DEFAULT_SCALE), settings.get("exploration"))


def gym_env(venv: VecEnv) -> Any:
    """The gym env (or batched gym vector env) under SB3's wrappers, that a scripted policy is built for."""
    inner = venv
    while isinstance(inner, VecEnvWrapper):
        inner = inner.venv
    if isinstance(inner, DummyVecEnv):
        return inner.envs[0]
    return getattr(inner, "venv", inner)  # agents.vec_env.SkitterVecEnv holds the batched gym env


class ResidualVecEnv(VecEnvWrapper):
    """``venv`` driven by ``clip(reference(obs) + scale * action)``: the env a residual policy learns on (inside any
    normalization, so that the reference reads the env's own observations). ``reference``: the scripted policy
    ``residual.policy`` built for :func:`gym_env` of ``venv`` (``agents.load_policy``)."""

    def __init__(self, venv: VecEnv, residual: Residual, reference: Any):
        super().__init__(venv)
        self.residual = residual
        self.reference = reference
        self.low, self.high = action_bounds(venv)
        self._obs: np.ndarray | None = None
        self._state: Any = None
        self._start = np.ones(venv.num_envs, dtype=bool)

    def reset(self) -> np.ndarray:
        self._obs = self.venv.reset()
        self._state, self._start = None, np.ones(self.num_envs, dtype=bool)
        return self._obs

    def step_async(self, actions: np.ndarray) -> None:
        base, self._state = self.reference.predict(self._obs, state=self._state, episode_start=self._start)
        self._start = np.zeros(self.num_envs, dtype=bool)
        total = np.asarray(base, np.float64) + self.residual.scale * np.asarray(actions, np.float64)
        self.venv.step_async(np.clip(total, self.low, self.high).astype(np.float32))

    def step_wait(self):
        obs, reward, done, infos = self.venv.step_wait()
        self._obs, self._start = obs, np.asarray(done, dtype=bool).copy()  # a done env's obs starts its next episode
        return obs, reward, done, infos


class ResidualPolicy:
    """A trained residual model with its reference gait (built for ``env``): ``predict`` gives the env's action, as
    during training."""

    def __init__(self, model: Any, residual: Residual, reference: Any, env: Any):
        self.model, self.residual, self.reference = model, residual, reference
        self.low, self.high = action_bounds(env)

    def __repr__(self) -> str:
        return f"ResidualPolicy({self.model!r} on {self.residual.policy}, scale {self.residual.scale:g})"

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:  # fmt: skip
        reference_state, model_state = state if state is not None else (None, None)
        base, reference_state = self.reference.predict(observation, state=reference_state, episode_start=episode_start)
        action, model_state = self.model.predict(observation, state=model_state, episode_start=episode_start,
                                                 deterministic=deterministic)  # fmt: skip
        total = np.asarray(base, np.float64) + self.residual.scale * np.asarray(action, np.float64)
        return np.clip(total, self.low, self.high).astype(np.float32), (reference_state, model_state)
