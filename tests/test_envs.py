"""Checks every registered skitter env must pass."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from tests.conftest import ENV_IDS

N_STEPS = 60


def test_registry_has_walk_and_turn_in_both_action_modes():
    assert set(ENV_IDS) == {
        "skitter/RoachWalk-v0",
        "skitter/RoachTurn-v0",
        "skitter/RoachWalkDuty-v0",
        "skitter/RoachTurnDuty-v0",
    }


def test_gymnasium_and_sb3_check_env(env_id):
    env = gym.make(env_id)
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)


def rollout(env, seed: int, actions: np.ndarray):
    obs, _ = env.reset(seed=seed)
    observations, rewards = [obs], []
    for a in actions:
        obs, reward, terminated, truncated, _ = env.step(a)
        observations.append(obs)
        rewards.append(reward)
        if terminated or truncated:
            break
    return np.array(observations), np.array(rewards)


def random_actions(env, seed: int, n: int = N_STEPS) -> np.ndarray:
    env.action_space.seed(seed)
    return np.array([env.action_space.sample() for _ in range(n)])


def test_seeded_rollout_is_deterministic(env_id):
    env_a, env_b = gym.make(env_id), gym.make(env_id)
    actions = random_actions(env_a, 1)
    obs_a, rew_a = rollout(env_a, 7, actions)
    obs_b, rew_b = rollout(env_b, 7, actions)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(rew_a, rew_b)
    obs_c, _ = rollout(env_b, 8, actions)
    assert not np.array_equal(obs_a[0], obs_c[0]), "different seeds must give different starts"


def test_reward_is_the_sum_of_info_terms(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    terms_seen = set()
    for a in random_actions(env, 2):
        _, reward, terminated, truncated, info = env.step(a)
        terms = {k: v for k, v in info.items() if k.startswith("reward_")}
        assert len(terms) == 3
        terms_seen |= set(terms)
        assert reward == sum(terms.values())
        for key in ("x_position", "y_position", "x_velocity", "power"):
            assert np.isfinite(info[key])
        if terminated or truncated:
            break
    assert terms_seen


def test_reset_restores_the_state(env_id):
    env, fresh = gym.make(env_id), gym.make(env_id)
    actions = random_actions(env, 3)
    rollout(env, 11, actions)  # leave some state behind: clocks, firmware, time
    obs_again, rew_again = rollout(env, 5, actions)
    obs_fresh, rew_fresh = rollout(fresh, 5, actions)
    np.testing.assert_array_equal(obs_again, obs_fresh)
    np.testing.assert_array_equal(rew_again, rew_fresh)


def test_env_survives_pickling(env_id):
    env = gym.make(env_id)
    env.reset(seed=4)
    actions = random_actions(env, 4, 20)
    for a in actions[:10]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in actions[10:]:
        obs, reward, *_ = env.step(a)
        obs_c, reward_c, *_ = clone.step(a)
        np.testing.assert_array_equal(obs, obs_c)
        assert reward == reward_c


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_raise(env_id, bad):
    env = gym.make(env_id)
    env.reset(seed=0)
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    action[0] = bad
    with pytest.raises(ValueError, match="finite"):
        env.step(action)


def test_wrong_action_shape_raises():
    env = gym.make("skitter/RoachWalk-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(5))


def test_out_of_range_actions_are_clipped(env_id):
    env_a, env_b = gym.make(env_id), gym.make(env_id)
    actions = random_actions(env_a, 5, 20)
    big = actions * 7.0
    obs_a, rew_a = rollout(env_a, 3, np.clip(big, -1, 1))
    obs_b, rew_b = rollout(env_b, 3, big)
    np.testing.assert_array_equal(obs_a, obs_b)
    np.testing.assert_array_equal(rew_a, rew_b)


def test_unstable_simulation_ends_the_episode_with_finite_observations(env_id):
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    env.unwrapped.robot.data.qvel[:] = 1e12  # no physical robot survives this
    obs, reward, terminated, _truncated, info = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert info["sim_unstable"] is True
    assert terminated
    assert np.isfinite(obs).all()
    assert np.isfinite(reward)


def test_world_pose_is_in_info_not_in_the_observation():
    env = gym.make("skitter/RoachWalk-v0")
    obs, info = env.reset(seed=0)
    assert obs.shape == (19,)
    priv = gym.make("skitter/RoachWalk-v0", privileged_obs=True)
    obs_p, _ = priv.reset(seed=0)
    assert obs_p.shape == (26,)
    np.testing.assert_array_equal(obs_p[:19], obs)
    quat = obs_p[-4:]
    assert np.isclose(np.linalg.norm(quat), 1.0)
    np.testing.assert_allclose(quat, info["quaternion"])


def test_turn_command_is_sampled_in_range_and_settable():
    env = gym.make("skitter/RoachTurn-v0")
    commands = []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        commands.append(info["yaw_rate_command"])
        assert obs[19] == info["yaw_rate_command"]
    assert max(np.abs(commands)) <= env.unwrapped.yaw_rate_range
    assert min(commands) < 0 < max(commands)
    obs, info = env.reset(seed=0, options={"yaw_rate": 0.42})
    assert info["yaw_rate_command"] == 0.42 and obs[19] == 0.42
    with pytest.raises(ValueError, match="yaw_rate"):
        env.reset(seed=0, options={"yaw_rate": "fast"})


def test_time_limits_are_ten_seconds():
    for env_id in ENV_IDS:
        env = gym.make(env_id)
        assert env.spec.max_episode_steps * env.unwrapped.dt == pytest.approx(10.0)


def test_rgb_array_renders_headless():
    env = gym.make("skitter/RoachWalk-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (120, 160, 3)
    assert frame.dtype == np.uint8
    assert frame.std() > 5, "the frame should show a scene, not a blank image"
