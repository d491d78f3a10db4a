"""Checks every registered skitter env must pass."""

import pickle

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from agents import load_policy
from tests.conftest import ENV_IDS

N_STEPS = 60


def test_registry_has_walk_and_turn_in_both_action_modes():
    assert {
        "skitter/RoachWalk-v4",
        "skitter/RoachTurn-v5",
        "skitter/RoachWalkDuty-v3",
        "skitter/RoachTurnDuty-v4",
    } <= set(ENV_IDS)


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
        assert len(terms) >= 2
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
    env = gym.make("skitter/RoachWalk-v4")
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
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    _, _, _, _, good = env.step(action)
    env.unwrapped.data.qvel[:] = 1e12  # no physical robot survives this
    obs, reward, terminated, _truncated, info = env.step(action)
    assert info["sim_unstable"] is True
    assert terminated
    assert np.isfinite(obs).all()
    assert reward == 0.0
    # every key of a step's info, the pose and running sums of the last good step, no reward terms
    assert set(info) == set(good)
    for key in ("x_position", "y_position", "z_position", "time", "distance"):
        assert info[key] == good[key], key
    assert sum(value for key, value in info.items() if key.startswith("reward_")) == reward


def test_world_pose_is_in_info_not_in_the_observation():
    env = gym.make("skitter/RoachWalk-v4")
    obs, info = env.reset(seed=0)
    assert obs.shape == (21,)
    priv = gym.make("skitter/RoachWalk-v4", privileged_obs=True)
    obs_p, _ = priv.reset(seed=0)
    assert obs_p.shape == (28,)
    np.testing.assert_array_equal(obs_p[:21], obs)
    quat = obs_p[priv.unwrapped.task.layout["body_quaternion"]]
    assert np.isclose(np.linalg.norm(quat), 1.0)
    np.testing.assert_allclose(quat, info["quaternion"])


def test_observation_structure_names_every_entry(env_id):
    env = gym.make(env_id)
    structure = env.unwrapped.observation_structure
    assert sum(structure.values()) == env.observation_space.shape[0]
    layout = env.unwrapped.task.layout
    assert layout.size == env.observation_space.shape[0]
    assert {"leg_cos", "gyro", "heading_error"} <= set(structure)
    obs, _ = env.reset(seed=0)
    assert layout.get(obs, "battery")[0] == pytest.approx(env.unwrapped.robot.nominal_battery)
    sin_cos = layout.get(obs, "heading_error")
    scene = getattr(env.unwrapped, "scene", None)
    start = 0.0 if scene is None else scene.placement[0, 2]  # a soccer task: its start heading against +x
    assert sin_cos == pytest.approx([np.sin(start), np.cos(start)]), "the heading error starts at the start's"


def test_env_exposes_model_and_data_like_mujoco_env(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    base = env.unwrapped
    assert isinstance(base.model, mujoco.MjModel) and isinstance(base.data, mujoco.MjData)
    t0 = base.data.time
    env.step(env.action_space.sample())
    assert base.data.time == pytest.approx(t0 + base.dt)


def test_heading_error_follows_the_gyro_and_drifts_with_its_bias():
    """The observed heading error tracks the true yaw within the drift the gyro's bias allows."""
    env = gym.make("skitter/RoachWalk-v4")
    obs, _ = env.reset(seed=5)
    layout = env.unwrapped.task.layout
    action = env.unwrapped.robot.mode.to_action([10.0, 10.0, 2.8])  # a turning gait
    for _ in range(200):
        obs, _, _, _, info = env.step(action)
    s, c = layout.get(obs, "heading_error")
    estimate = np.arctan2(s, c)
    bias = env.unwrapped.robot.imu.gyro_bias[0, 2]
    assert abs(info["yaw"]) > 0.3, "the gait turned"
    # the firmware integrates the body's z rate, not the world's yaw rate: a few percent apart while the body rocks
    assert abs(estimate - info["yaw"]) < abs(bias) * info["time"] + 0.05 * abs(info["yaw"])
    perfect = gym.make("skitter/RoachWalk-v4", sensor_noise=False)
    obs, _ = perfect.reset(seed=5)
    for _ in range(200):
        obs, _, _, _, info = perfect.step(action)
    s, c = layout.get(obs, "heading_error")
    assert np.arctan2(s, c) == pytest.approx(info["yaw"], rel=0.05), "a perfect gyro integrates to about the yaw"


def test_gait_commands_are_bounded_to_the_real_robots_strides():
    env = gym.make("skitter/RoachWalk-v4")
    mode = env.unwrapped.robot.mode
    low = mode.to_command(-np.ones(3))
    high = mode.to_command(np.ones(3))
    assert low[:2].tolist() == [0.0, 0.0] and high[:2].tolist() == [45.0, 45.0]
    assert mode.to_command(np.zeros(3))[2] == pytest.approx(np.pi)


def test_randomize_draws_parameters_at_every_reset_and_is_checked():
    env = gym.make("skitter/RoachWalk-v4", randomize={"foot_friction": (0.3, 0.5), "battery_voltage": (3.4, 3.9)})
    base = env.unwrapped
    drawn = []
    for seed in range(3):
        env.reset(seed=seed)
        drawn.append(dict(base.parameter_values))
        assert 0.3 <= drawn[-1]["foot_friction"] <= 0.5
        assert base.robot.battery[0] == drawn[-1]["battery_voltage"]
        floor = base.model.geom("floor").id
        assert base.model.geom_friction[floor, 0] == drawn[-1]["foot_friction"]
    assert len({d["foot_friction"] for d in drawn}) == 3
    env.reset(seed=1)
    assert base.parameter_values == drawn[1], "same seed, same draw"
    off = gym.make("skitter/RoachWalk-v4")
    off.reset(seed=0)
    assert off.unwrapped.parameter_values == {}
    for bad, message in [
        ({"moon_gravity": (0, 1)}, "unknown parameter"),
        ({"foot_friction": (0.5, 0.3)}, "low <= high"),
        ({"foot_friction": (0.3, 9.0)}, "range"),
        ({"foot_friction": "rough"}, "pair of numbers"),
    ]:
        with pytest.raises(ValueError, match=message):
            gym.make("skitter/RoachWalk-v4", randomize=bad)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"max_tilt": -1.0}, "max_tilt"),
        ({"max_tilt": float("nan")}, "max_tilt"),
        ({"battery_voltage": float("inf")}, "battery_voltage"),
        ({"battery_voltage": 0.0}, "battery_voltage"),
        ({"reset_noise_scale": -0.1}, "reset_noise_scale"),
        ({"energy_cost_weight": "lots"}, "energy_cost_weight"),
        ({"control_freq": 333.0}, "control_freq"),
        ({"control_freq": -5}, "control_freq"),
        ({"action_mode": "teleport"}, "action_mode"),
        ({"width": 0}, "width"),
        ({"height": 2.5}, "height"),
        ({"render_mode": "ascii"}, "render_mode"),
        # a string would read as true ("false" too): a switch takes True or False only
        ({"sensor_noise": "false"}, "sensor_noise must be True or False, got 'false'"),
        ({"privileged_obs": "no"}, "privileged_obs must be True or False, got 'no'"),
        ({"telemetry": 1}, "telemetry must be True, False, 'control' or 'physics', got 1"),
        ({"telemetry": "false"}, "telemetry must be True, False, 'control' or 'physics', got 'false'"),
    ],
)
def test_nonsense_constructor_arguments_are_refused_at_once(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gym.make("skitter/RoachWalk-v4", **kwargs)


def test_turn_command_is_sampled_in_range_and_settable():
    env = gym.make("skitter/RoachTurn-v5")
    index = env.unwrapped.task.layout["yaw_rate_command"].start
    commands = []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        commands.append(env.unwrapped.task.yaw_rate_command[0])
        assert obs[index] == commands[-1]
    assert max(np.abs(commands)) <= env.unwrapped.task.yaw_rate_range
    assert min(commands) < 0 < max(commands)
    obs, info = env.reset(seed=0, options={"yaw_rate": 0.42})
    assert obs[index] == 0.42
    _, _, _, _, info = env.step(env.action_space.sample())
    assert info["yaw_rate_command"] == 0.42
    with pytest.raises(ValueError, match="yaw_rate"):
        env.reset(seed=0, options={"yaw_rate": "fast"})


def test_the_bioloid_turn_pays_for_staying_upright_and_the_other_turns_do_not():
    """BioloidTurn pays its body's uprightness each step, as BioloidWalk does (a fall must cost the steps it ends);
    the roach's and the xJüs's turns, which stand on their own, keep a zero upright term by default."""
    turns = (("skitter/BioloidTurn-v5", 1.0), ("skitter/RoachTurn-v5", 0.0), ("skitter/XjusTurn-v2", 0.0))
    for env_id, weight in turns:
        env = gym.make(env_id)
        env.reset(seed=3)
        for a in random_actions(env, 5):
            _, reward, terminated, truncated, info = env.step(a)
            assert info["reward_upright"] == weight * info["up_z"]
            if weight:
                assert 0.5 < info["reward_upright"] <= 1.0  # upright at the start of an episode
            if terminated or truncated:
                break
        assert env.unwrapped.task.upright_reward_weight == weight
    unpaid = gym.make("skitter/BioloidTurn-v5", upright_reward_weight=0.0)
    unpaid.reset(seed=3)
    _, reward, _, _, info = unpaid.step(unpaid.action_space.sample())
    assert info["reward_upright"] == 0.0
    assert reward == info["reward_tracking"] + info["reward_speed"] + info["reward_energy"] + info["reward_upright"]
    with pytest.raises(ValueError, match="upright_reward_weight"):
        gym.make("skitter/BioloidTurn-v5", upright_reward_weight="a lot")


def _other_rate(env_id: str) -> float:
    """A control rate other than the default that the env accepts: twice it (xJüs in gait mode needs at least
    120 Hz), or half it where twice is not a whole number of physics steps."""
    default = 1.0 / gym.make(env_id).unwrapped.dt
    for freq in (2 * default, default / 2):
        try:
            gym.make(env_id, control_freq=freq)
        except ValueError:
            continue
        return freq
    raise AssertionError(f"{env_id} takes neither twice nor half its default rate")


def test_time_limits_are_durations_at_any_control_rate(env_id):
    """The limit is a duration: its registration's (10 s unless it names one; the academy's 20 s) at the default
    rate and at another, single (gymnasium.make) and batched."""
    seconds = gym.spec(env_id).kwargs.get("episode_seconds", 10.0)
    for kwargs in ({}, {"control_freq": _other_rate(env_id)}):
        env = gym.make(env_id, **kwargs)
        assert env.spec.max_episode_steps * env.unwrapped.dt == pytest.approx(seconds), kwargs
        venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", nthread=1, **kwargs)
        assert venv.unwrapped.max_episode_steps * venv.unwrapped.dt == pytest.approx(seconds), kwargs
        venv.close()


def test_default_rate_episodes_keep_their_step_counts():
    """At the default rates the limits are the step counts they always were (10 s of control steps)."""
    steps = {"skitter/RoachWalk-v4": 500, "skitter/RoachWalkDuty-v3": 10000, "skitter/XjusWalk-v1": 1250,
             "skitter/BioloidWalk-v2": 500}  # fmt: skip
    for env_id, expected in steps.items():
        assert gym.make(env_id).spec.max_episode_steps == expected


@pytest.mark.parametrize(("env_id", "freq"), [("skitter/XjusWalk-v1", 250.0), ("skitter/BioloidWalk-v2", 25.0)])
def test_episodes_truncate_at_their_duration_not_a_step_count(env_id, freq):
    """Stepped to the end at a non-default rate, an episode is truncated when its simulated time reaches the
    duration, single and batched (a short duration keeps the test quick)."""
    seconds = 0.4
    env = gym.make(env_id, control_freq=freq, episode_seconds=seconds, max_tilt=np.pi)
    env.reset(seed=0)
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        steps += 1
        assert not terminated
    assert steps == round(seconds * freq)
    assert info["time"] == pytest.approx(seconds)
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", nthread=1, control_freq=freq,
                        episode_seconds=seconds, max_tilt=np.pi)  # fmt: skip
    venv.reset(seed=0)
    for step in range(1, steps + 1):
        *_, truncated, info = venv.step(np.zeros(venv.action_space.shape))
        assert truncated.all() == (step == steps)
    assert info["time"] == pytest.approx([seconds, seconds])


@pytest.mark.parametrize("seconds", [0, -1, float("nan"), "10", True])
def test_episode_seconds_must_be_a_positive_duration(seconds):
    with pytest.raises(ValueError, match="episode_seconds"):
        gym.make("skitter/RoachWalk-v4", episode_seconds=seconds)
    with pytest.raises(ValueError, match="episode_seconds"):
        gym.make_vec("skitter/RoachWalk-v4", vectorization_mode="vector_entry_point", episode_seconds=seconds)


def test_episode_seconds_none_and_an_explicit_step_limit():
    """``episode_seconds=None`` leaves no limit of the env's own; ``max_episode_steps`` (Gymnasium's) still cuts
    episodes, single and batched alike: whichever limit comes first ends the episode."""
    env = gym.make("skitter/RoachWalk-v4", episode_seconds=None)
    assert env.spec.max_episode_steps is None
    assert gym.make("skitter/RoachWalk-v4", max_episode_steps=7).spec.max_episode_steps == 7
    batched = "vector_entry_point"
    venv = gym.make_vec("skitter/RoachWalk-v4", vectorization_mode=batched, max_episode_steps=700, episode_seconds=None)
    assert venv.unwrapped.max_episode_steps == 700
    for steps in (300, 700):  # 10 s at 50 Hz is 500 steps
        single = gym.make("skitter/RoachWalk-v4", max_episode_steps=steps, max_tilt=np.pi)
        venv = gym.make_vec("skitter/RoachWalk-v4", vectorization_mode=batched, max_episode_steps=steps, max_tilt=np.pi)
        single.reset(seed=0)
        count, truncated = 0, False
        while not truncated:
            *_, truncated, _ = single.step(single.action_space.sample())
            count += 1
        assert count == venv.unwrapped.max_episode_steps == min(steps, 500), (steps, count)


@pytest.mark.parametrize(("width", "height"), [(160, 120), (800, 600)])
def test_rgb_array_renders_headless_at_any_size(width, height):
    """Frames larger than the model's default 640x480 offscreen buffer come back whole, not black-padded."""
    env = gym.make("skitter/RoachWalk-v4", render_mode="rgb_array", width=width, height=height)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (height, width, 3)
    assert frame.dtype == np.uint8
    assert frame.std() > 5, "the frame should show a scene, not a blank image"
    for edge in (frame[-20:, :, :], frame[:, -20:, :]):
        assert edge.max() > 0, "no black padding at the edges"


@pytest.mark.parametrize("batched", [False, True])
def test_rgb_array_frames_follow_the_robot(batched):
    """The frames' camera tracks the robot's body: after a walk of about a metre it still looks at the robot
    (Gymnasium 1.x's offscreen renderer set a free camera on every frame, left at the origin)."""
    kwargs = {"render_mode": "rgb_array", "width": 160, "height": 120}
    single = gym.make("skitter/XjusWalk-v1", **kwargs)
    obs, _ = single.reset(seed=0)
    action, _ = load_policy("buehler", single).predict(obs, None, np.array([True]))  # gait mode: one action
    if batched:
        env = gym.make_vec("skitter/XjusWalk-v1", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
        action = np.broadcast_to(action, (2, *action.shape))
        env.reset(seed=0)
    else:
        env = single
    first = env.render()
    for _ in range(250):  # 2 s at 125 Hz
        env.step(action)
    last = env.render()
    base = env.unwrapped
    if batched:
        body = base.robot.sim.get_data(0).xpos[base._render_model.body(base.robot.root_body).id]
    else:
        body = base.data.xpos[base.model.body(base.robot.root_body).id]
    camera = base._renderer.camera
    env.close()
    assert first.shape == last.shape == (120, 160, 3)
    assert np.linalg.norm(body[:2]) > 0.8, "the robot should have walked away from the origin"
    np.testing.assert_allclose(camera.lookat[:2], body[:2], atol=0.05)


@pytest.mark.parametrize("batched", [False, True])
def test_the_first_frame_after_the_camera_jumps_far_shows_the_scene(batched):
    """A roach 30 m from the origin, then reset from there: the first frame after each jump of the tracking camera
    is the scene (the frame a second render gives), not black."""
    kwargs = {"render_mode": "rgb_array", "width": 160, "height": 120}
    if batched:
        env = gym.make_vec("skitter/RoachWalk-v4", num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    else:
        env = gym.make("skitter/RoachWalk-v4", **kwargs)
    env.reset(seed=0)
    env.render()
    base = env.unwrapped
    if batched:
        base.robot.sim.qpos[0, 0] = 30.0  # the render reads simulation 0's state
    else:
        base.data.qpos[0] = 30.0
        mujoco.mj_forward(base.model, base.data)
    for jump in ("30 m away", "reset from there"):
        first, again = env.render(), env.render()
        assert first.std() > 5 and first.mean() > 50, f"{jump}: the first frame is blank"
        assert np.abs(first.astype(int) - again).mean() < 1.0, f"{jump}: the first frame is not the scene"
        env.reset(seed=0)
    env.close()


@pytest.mark.parametrize("bounds", ["34", ("0.02", "0.03"), (True, 1.0), b"12"])
def test_randomize_bounds_must_be_numbers_not_strings_or_bools(bounds):
    with pytest.raises(ValueError, match=r"randomize\['battery_voltage'\] must be a \(low, high\) pair of numbers"):
        gym.make("skitter/RoachWalk-v4", randomize={"battery_voltage": bounds})


def test_class_docstrings_state_the_version_history_and_the_time_limit(env_id):
    """Each env's manual (its class docstring) lists its registered version, states the episode's end by the
    duration (where it has an Episode End section; the turn envs point to their walk env's), and promises nothing
    that already exists."""
    doc = type(gym.make(env_id).unwrapped).__doc__
    version = env_id.rsplit("-", 1)[1]
    history = doc.split("## Version History", 1)[1]
    assert f"- {version}:" in history, f"{env_id}: no {version} in the version history"
    if "## Episode End" in doc:
        end = doc.split("## Episode End", 1)[1].split("##", 1)[0]
        seconds = gym.spec(env_id).kwargs.get("episode_seconds", 10.0)
        assert "episode_seconds" in end and f"{seconds:g} s" in end, f"{env_id}: the episode's end is not its duration"
    else:
        assert "episode end" in doc, f"{env_id}: neither states nor refers to its episode end"
    for stale in ("to come", "adapter yet", "registration's time limit"):
        assert stale not in doc, f"{env_id}: {stale!r}"


def test_a_keyword_the_env_does_not_take_is_named_with_the_one_meant():
    """gymnasium.make and make_vec name the keyword, the nearest one the env takes and all it takes (not Python's
    "unexpected keyword argument" with gymnasium's dump of every keyword)."""
    import re

    said = re.escape("XjusWalkEnv takes no keyword 'spine_stifness' (did you mean 'spine_stiffness'?); it takes ")
    vector = {"num_envs": 2, "vectorization_mode": "vector_entry_point"}
    for make in (gym.make, lambda *a, **kw: gym.make_vec(*a, **vector, **kw)):
        with pytest.raises(TypeError, match=said + "action_mode, .*episode_seconds"):
            make("skitter/XjusWalk-v1", spine_stifness=10.0)
