"""Batched envs on mujoco.batch: the same results as single envs, Gymnasium's vector API, SB3's VecEnv, randomization
per simulation, instability per simulation, telemetry, rendering."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import data_equivalence

from tests.conftest import ENV_IDS

N = 3


def make_batched(env_id: str, n: int = N, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


def make_singles(env_id: str, n: int = N, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", **kwargs)


def run(venv, actions: np.ndarray, seed: int):
    obs, _ = venv.reset(seed=seed)
    out = {"obs": [obs], "reward": [], "terminated": [], "truncated": [], "x": []}
    for a in actions:
        obs, reward, terminated, truncated, info = venv.step(a)
        out["obs"].append(obs)
        out["reward"].append(reward)
        out["terminated"].append(terminated)
        out["truncated"].append(truncated)
        out["x"].append(np.where(info["_x_position"], info["x_position"], np.nan))
        for key in ("steps", "height_sum", "contact_time", "band_time", "non_foot_touch"):  # the ground rules' sums
            has = info.get(f"_{key}", np.zeros(len(obs), dtype=bool))  # absent where every simulation reset
            out.setdefault(key, []).append(np.where(has, info.get(key, np.nan), np.nan))
    return {k: np.array(v) for k, v in out.items()}


@pytest.fixture(scope="module", params=ENV_IDS)
def singles(request) -> tuple[str, dict, np.ndarray, dict[str, np.ndarray]]:
    """An env id's N single envs' run (its kwargs, actions and results), made once for the batched env's thread
    counts that are compared with it."""
    env_id = request.param
    duty = "Duty" in env_id
    steps, limit = (150, 60) if duty else (40, 15)
    kwargs = {"max_episode_steps": limit}
    env = gym.make(env_id)
    robot = env.unwrapped.robot
    if not robot.hosted:  # every robot's own parameters, each drawn from 90-100% of its nominal value (the academy's
        # robots share a scene with the field and take no per-robot parameters: tests/test_soccer.py)
        parameters = robot.parameters
        kwargs["randomize"] = {k: (0.9 * parameters[k].nominal, parameters[k].nominal)
                               for k in ("foot_friction", "battery_voltage")}  # fmt: skip
    actions = np.random.default_rng(7).uniform(-1, 1, (steps, N, env.action_space.shape[0]))
    return env_id, kwargs, actions, run(make_singles(env_id, **kwargs), actions, seed=11)


@pytest.mark.parametrize("nthread", [1, 2])
def test_n_single_envs_and_one_batched_env_of_n_give_identical_results_across_resets(singles, nthread):
    env_id, kwargs, actions, a = singles
    b = run(make_batched(env_id, nthread=nthread, **kwargs), actions, seed=11)
    assert a["truncated"].sum() >= 2 * N, "the run crosses resets"
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_vector_info_carries_every_step_key_with_masks():
    venv = make_batched("skitter/RoachTurn-v5", max_episode_steps=5)
    venv.reset(seed=0)
    for _ in range(5):
        *_, info = venv.step(venv.action_space.sample())
    assert {"reward_tracking", "_reward_tracking", "yaw_rate_command", "distance", "sim_unstable"} <= set(info)
    *_, info = venv.step(venv.action_space.sample())  # every simulation resets in this call (next-step autoreset)
    assert not info["_reward_tracking"].any() and info["_x_position"].all()


def test_gymnasium_vector_checks_and_spaces(env_id=ENV_IDS[0]):
    for env_id in ENV_IDS:
        venv = make_batched(env_id)
        single = gym.make(env_id)
        assert venv.single_observation_space == single.observation_space
        assert venv.single_action_space == single.action_space
        assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.NEXT_STEP
        obs, _ = venv.reset(seed=1)
        assert venv.observation_space.contains(obs)
        obs, reward, terminated, truncated, _ = venv.step(venv.action_space.sample())
        assert obs.shape == (N, *single.observation_space.shape) and reward.shape == (N,)
        assert terminated.dtype == truncated.dtype == np.bool_


def test_reset_mask_resets_only_the_chosen_simulations():
    venv = make_batched("skitter/RoachWalk-v4")
    venv.reset(seed=0)
    for _ in range(10):
        before, *_ = venv.step(venv.action_space.sample())
    obs, _ = venv.reset(options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(obs[[0, 2]], before[[0, 2]])
    assert not np.array_equal(obs[1], before[1])
    with pytest.raises(ValueError, match="reset_mask"):
        venv.reset(options={"reset_mask": np.zeros(N, dtype=bool)})


def test_an_unstable_simulation_ends_its_own_episode_and_the_others_go_on():
    venv = make_batched("skitter/RoachWalk-v4")
    venv.reset(seed=0)
    action = np.zeros((N, 3), dtype=np.float32)
    *_, good = venv.step(action)
    venv.unwrapped.robot.sim.qvel[1] = 1e12
    obs, reward, terminated, _, info = venv.step(action)
    assert info["sim_unstable"].tolist() == [False, True, False]
    for key in ("x_position", "y_position", "z_position", "time", "quaternion"):  # the last good pose, not a reset's
        np.testing.assert_array_equal(info[key][1], good[key][1], err_msg=key)
    assert terminated.tolist() == [False, True, False] and reward[1] == 0.0
    assert np.isfinite(obs).all()
    obs, reward, terminated, *_ = venv.step(action)  # simulation 1 resets, the others step
    assert np.isfinite(obs).all() and not terminated.any()
    assert reward[1] == 0.0 and reward[0] != 0.0


def test_randomize_draws_per_simulation_through_the_batch_model_fields():
    venv = make_batched("skitter/RoachWalk-v4", randomize={"foot_friction": (0.3, 0.5)})
    venv.reset(seed=0)
    drawn = [p["foot_friction"] for p in venv.unwrapped.parameter_values]
    assert len(set(drawn)) == N
    friction = venv.unwrapped.robot.sim.batch.expanded("geom_friction")
    floor = venv.unwrapped.robot.model.geom("floor").id
    np.testing.assert_array_equal(friction[:, floor, 0], drawn)


def test_batched_motor_constants_follow_randomized_parameters():
    venv = make_batched("skitter/RoachWalk-v4", randomize={"motor_resistance": (2.0, 6.0)})
    venv.reset(seed=0)
    robot = venv.unwrapped.robot
    drawn = [p["motor_resistance"] for p in venv.unwrapped.parameter_values]
    np.testing.assert_allclose(robot.motors.resistance[:, 0], drawn)


def test_seeding_per_simulation():
    venv = make_batched("skitter/RoachWalk-v4")
    a, _ = venv.reset(seed=[5, 6, 7])
    b, _ = venv.reset(seed=5)
    np.testing.assert_array_equal(a, b)
    c, _ = venv.reset(seed=6)
    np.testing.assert_array_equal(a[1], c[0])


def test_telemetry_per_simulation_and_render_one():
    venv = make_batched("skitter/RoachWalk-v4", telemetry=True, render_mode="rgb_array", render_sim=2, width=160,
                        height=120)  # fmt: skip
    venv.reset(seed=0)
    for _ in range(5):
        venv.step(venv.action_space.sample())
    recorders = venv.unwrapped.recorders
    assert len(recorders) == N and all(len(r) == 6 for r in recorders)
    frames = [r.frame() for r in recorders]
    assert not data_equivalence(frames[0]["pos_y"].to_numpy(), frames[1]["pos_y"].to_numpy())
    frame = venv.render()
    assert frame.shape == (120, 160, 3) and frame.std() > 5


def test_pickling_gives_a_clear_error():
    import pickle

    venv = make_batched("skitter/RoachWalk-v4")
    with pytest.raises(TypeError, match="cannot be pickled"):
        pickle.dumps(venv.unwrapped)


@pytest.mark.parametrize(
    ("bad", "needle"),
    [
        ({"num_envs": 0}, "num"),
        ({"num_envs": 2, "nthread": 0}, "nthread"),
        ({"num_envs": 2, "nthread": "x"}, "nthread must be a whole number of at least 1, got 'x'"),
        ({"num_envs": 2, "render_sim": 5}, "render_sim"),
    ],
)
def test_bad_batch_arguments_are_refused_by_name(bad, needle):
    with pytest.raises(ValueError, match=needle):
        gym.make_vec("skitter/RoachWalk-v4", vectorization_mode="vector_entry_point", **bad)


def test_threads_default_to_the_machines_cores():
    import os

    venv = make_batched("skitter/RoachWalk-v4")
    assert venv.unwrapped.robot.sim.nthread == len(os.sched_getaffinity(0))


def test_gymnasium_vector_wrappers_work_on_it():
    from gymnasium.wrappers.vector import DictInfoToList, RecordEpisodeStatistics

    venv = DictInfoToList(RecordEpisodeStatistics(make_batched("skitter/RoachWalk-v4", max_episode_steps=4)))
    venv.reset(seed=0)
    for _ in range(4):
        *_, infos = venv.step(venv.action_space.sample())
    assert isinstance(infos, list) and len(infos) == N
    assert all("episode" in info and info["episode"]["l"] == 4 for info in infos)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_vec_env_trains_ppo_on_every_id(env_id):
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.vec_env import make_batched_vec_env

    vec = VecNormalize(make_batched_vec_env(env_id, 2, seed=0, env_kwargs={"max_episode_steps": 24}))
    model = PPO("MlpPolicy", vec, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(64)
    assert model.num_timesteps == 64
    assert len(model.ep_info_buffer) >= 2, "VecMonitor saw the episodes end"
    obs = vec.reset()
    assert obs.shape == (2, *vec.observation_space.shape)


def test_sb3_vec_env_resets_finished_envs_in_the_same_step():
    from agents.vec_env import SkitterVecEnv

    vec = SkitterVecEnv(make_batched("skitter/RoachWalk-v4", n=2, max_episode_steps=3))
    vec.seed(4)
    obs = vec.reset()
    for _ in range(3):
        obs, _, done, infos = vec.step(np.zeros((2, 3), dtype=np.float32))
    assert done.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] and "distance" in info
        assert not np.array_equal(info["terminal_observation"], obs[i]), "the returned observation starts anew"
    single = gym.make("skitter/RoachWalk-v4", max_episode_steps=3)
    single.reset(seed=4)
    for _ in range(3):
        single.step(np.zeros(3, dtype=np.float32))
    again, _ = single.reset()
    np.testing.assert_array_equal(again, obs[0])


@pytest.mark.parametrize("env_id", ["skitter/RoachTurn-v5", "skitter/RoachWalkDuty-v3"])
def test_episodes_run_together_match_episodes_run_one_by_one(env_id):
    """evaluate.py runs a policy's episodes as one batch: the metrics equal those of single envs, seed by seed."""
    from agents import load_policy
    from agents.evaluation import run_episode, run_episodes

    limit = 70 if "Duty" not in env_id else 300
    seeds = [3, 4, 5]
    venv = make_batched(env_id, n=3, max_episode_steps=limit)
    together = run_episodes(venv, load_policy("tripod", venv), seeds)
    single = gym.make(env_id, max_episode_steps=limit)
    for episode, seed in zip(together, seeds, strict=True):
        alone = run_episode(single, load_policy("tripod", single), seed)
        np.testing.assert_equal(episode.metrics, alone.metrics)
        assert episode.length == alone.length == limit
