import os

os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym
import pytest

import envs  # noqa: F401  (registers the envs)

ENV_IDS = sorted(env_id for env_id in gym.registry if env_id.startswith("skitter/"))


@pytest.fixture(params=ENV_IDS)
def env_id(request) -> str:
    return request.param
