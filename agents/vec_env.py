"""Stable-Baselines3's ``VecEnv`` over a batched skitter env (envs/common/vector.py): all envs in one process, one
``mujoco.batch`` call per step on the machine's cores.

SB3 resets a finished env within the same step and returns the first observation of its next episode, with the last
one in ``info["terminal_observation"]``; this adapter does that with the batched env's partial reset
(``reset_mask``), so each simulation's random stream is the one a single env would have. ``infos`` is a list of dicts,
as SB3 wants: each step's reward terms, and on an episode's last step everything the env reports (the running sums
the episode metrics come from). Wrap it in ``VecMonitor`` for SB3's episode statistics and in ``VecNormalize`` as
before.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from envs.common.vector import SkitterVectorEnv


class OneObjectAttributes:
    """SB3's attribute methods of a VecEnv whose envs are all one object, ``self.shared`` (a batched env, a batch of
    matches): each env's attribute is that object's, and ``unwrapped`` is the object itself."""

    shared: Any

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = self.shared if attr_name == "unwrapped" else getattr(self.shared, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self.shared, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        result = getattr(self.shared, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]


class SkitterVecEnv(OneObjectAttributes, VecEnv):
    """SB3's VecEnv over :class:`SkitterVectorEnv`.

    Args:
        venv: the batched env (``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``).
    """

    def __init__(self, venv: SkitterVectorEnv):
        self.venv = venv
        base = venv.unwrapped
        if not isinstance(base, SkitterVectorEnv):
            raise TypeError(f"SkitterVecEnv needs a batched skitter env, got {type(base).__name__}")
        self.base = self.shared = base
        super().__init__(base.num_envs, base.single_observation_space, base.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> np.ndarray:
        seeds = [s for s in self._seeds] if any(s is not None for s in self._seeds) else None
        options = self._options[0] if self._options and all(o == self._options[0] for o in self._options) else None
        obs, _ = self.venv.reset(seed=seeds, options=options or None)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.venv.step(self._actions)
        done = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        terms = [k for k in info if k.startswith("reward_")]
        for key in terms:
            for i in np.flatnonzero(info[f"_{key}"]):
                infos[i][key] = float(info[key][i])
        ended = np.flatnonzero(done)
        for i in ended:
            record = infos[i]
            for key, value in info.items():
                if not key.startswith("_") and info[f"_{key}"][i]:
                    record[key] = value[i].item() if np.ndim(value[i]) == 0 else value[i].copy()
            record["terminal_observation"] = obs[i].copy()
            record["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        if len(ended):
            first, _ = self.venv.reset(options={"reset_mask": done})
            obs = obs.copy()
            obs[ended] = first[ended]
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [self.base.render()]


def make_batched_vec_env(env_id: str, num_envs: int, seed: int, env_kwargs: dict[str, Any] | None = None) -> VecEnv:
    """A monitored SB3 VecEnv of ``num_envs`` batched simulations of ``env_id``, seeded ``seed, seed + 1, ...``."""
    from stable_baselines3.common.vec_env import VecMonitor

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **(env_kwargs or {}))
    vec = VecMonitor(SkitterVecEnv(venv))
    vec.seed(seed)
    return vec
