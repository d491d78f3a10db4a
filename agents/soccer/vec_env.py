"""Batched soccer matches as one Stable-Baselines3 ``VecEnv``: every player of ``num_matches`` matches is one of its
envs, all driven by one shared policy, all matches stepped by one ``mujoco.batch`` call.

It gives what SuperSuit's ``pettingzoo_env_to_vec_env_v1`` and ``concat_vec_envs_v1`` give over the PettingZoo env
(envs/soccer/match.py), without a process or a Python env per match: the same :class:`~envs.soccer.match.Matches`
engine runs them all, and match ``m`` is bit for bit the PettingZoo match seeded with the seed of its first player's
env (SB3's ``seed(s)`` gives env ``i`` the seed ``s + i``; match ``m``'s first player is env ``m * players``). A match
that ends (``max_goals``) or runs out of time (``max_cycles``) starts again in the same step, its players' last
observations in ``info["terminal_observation"]``, as SB3 expects.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env import VecEnv

from agents.vec_env import OneObjectAttributes
from envs.soccer.match import Matches


class MatchesVecEnv(OneObjectAttributes, VecEnv):
    """What the SB3 VecEnvs over a :class:`~envs.soccer.match.Matches` engine share: its spaces, ``per_match`` envs a
    match (match ``m`` seeded with env ``m * per_match``'s seed), no rendering."""

    def __init__(self, engine: Matches, per_match: int):
        self.engine = self.shared = engine
        engine.render_mode = None  # what SB3's VecEnv reads from its envs: these render nothing
        observation_space = spaces.Box(-np.inf, np.inf, shape=(engine.task.layout.size,), dtype=np.float64)
        action_space = spaces.Box(-1.0, 1.0, shape=(engine.mode.size,), dtype=np.float32)
        super().__init__(engine.num_matches * per_match, observation_space, action_space)
        self.per_match = per_match
        self._actions: np.ndarray | None = None

    @property
    def observation_structure(self) -> dict[str, int]:
        return self.engine.task.observation_structure

    def _reset_matches(self) -> None:
        """Every match from its kickoff, each seeded with its first env's seed (when one was set)."""
        engine = self.engine
        for m in range(engine.num_matches):
            seed = self._seeds[m * self.per_match] if self._seeds else None
            if seed is not None:
                engine.seed(m, seed)
        engine.reset(np.arange(engine.num_matches))
        self._reset_seeds()
        self._reset_options()

    def close(self) -> None:
        pass

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]


class SoccerVecEnv(MatchesVecEnv):
    """``num_matches`` matches (arguments: :class:`envs.soccer.match.SoccerParallelEnv`'s, without rendering) as an
    SB3 VecEnv of ``num_matches x players`` envs, match-major (env ``m * players + p`` is agent ``p`` of match ``m``,
    agents in ``possible_agents`` order: the home team, then the away team)."""

    def __init__(self, num_matches: int, nthread: int | None = None, **kwargs: Any):
        engine = Matches(num_matches=num_matches, nthread=nthread, batched=True, **kwargs)
        super().__init__(engine, engine.players)
        self.possible_agents = engine.possible_agents
        self._match_of = np.arange(self.num_envs) // engine.players  # each env's match

    def reset(self) -> np.ndarray:
        self._reset_matches()
        return self.engine.obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        actions = np.asarray(actions, dtype=np.float64)
        shape = (self.num_envs, *self.action_space.shape)
        if actions.size != math.prod(shape):
            raise ValueError(f"actions must be {shape} (an action per player of every match), got {actions.shape}")
        actions = actions.reshape(shape)
        if not np.isfinite(actions).all():
            bad = int(np.flatnonzero(~np.isfinite(actions).all(axis=1))[0])
            raise ValueError(f"actions must be finite; env {bad} got {actions[bad]}")
        self._actions = actions

    def step_wait(self):
        engine = self.engine
        out = engine.step(self._actions)
        match_of = self._match_of
        finishing = out["ended"] | out["truncated"]
        done = finishing[match_of]
        obs = engine.obs.copy()
        columns = [out[k].tolist() for k in ("reward", "fallen", "off", "approach", "ball_progress")]
        infos: list[dict[str, Any]] = [
            {"reward_goal": r, "fallen": f, "off": o, "approach": a, "ball_progress": b}
            for r, f, o, a, b in zip(*columns, strict=True)
        ]
        if finishing.any():
            finished = np.flatnonzero(finishing)
            truncated = out["truncated"][match_of]
            for i in np.flatnonzero(done):
                infos[i]["terminal_observation"] = obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(truncated[i])
                infos[i]["score"] = engine.scores[match_of[i]].tolist()
            engine.reset(finished)
            rows = engine.rows_of(finished)
            obs[rows] = engine.obs[rows]
        return obs, out["reward"].astype(np.float32), done, infos
