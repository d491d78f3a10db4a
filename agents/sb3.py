"""Trained Stable-Baselines3 models behind the same ``predict()`` as the scripted gaits."""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm

ALGOS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC, "td3": TD3}


class SB3Policy:
    """A trained model (``model.zip``) with the observation normalisation it was trained with, if any.

    train.py saves ``config.json`` (naming the algorithm) and ``vecnormalize.pkl`` beside the model; both are found
    there. Without a config the algorithms are tried in turn.
    """

    def __init__(self, path: str | Path, device: str = "cpu"):
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no trained model at {path}")
        self.path = path
        config = path.parent / "config.json"
        algo = json.loads(config.read_text()).get("algo") if config.is_file() else None
        candidates = [ALGOS[algo]] if algo in ALGOS else list(ALGOS.values())
        errors = []
        for cls in candidates:
            try:
                self.model = cls.load(path, device=device)
                break
            except (ValueError, KeyError, RuntimeError, TypeError) as exc:
                errors.append(f"{cls.__name__}: {exc}")
        else:
            raise ValueError(f"{path}: not a Stable-Baselines3 PPO, SAC or TD3 model ({'; '.join(errors)})")
        stats = path.parent / "vecnormalize.pkl"
        self.normalizer = None
        if stats.is_file():
            with stats.open("rb") as fh:
                self.normalizer = pickle.load(fh)

    def __repr__(self) -> str:
        return f"SB3Policy({self.path})"

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        if self.normalizer is not None:
            obs = self.normalizer.normalize_obs(obs)
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)
