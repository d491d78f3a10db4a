"""xJüs's tasks, terrain, reference controller and telemetry: what a user of the envs relies on."""

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents import load_policy
from agents.evaluation import run_episodes
from envs.common.terrain import Terrain
from envs.xjus import constants
from tests.conftest import main_in_process

WALK, TURN, ROUGH = "skitter/XjusWalk-v1", "skitter/XjusTurn-v2", "skitter/XjusRough-v1"
XJUS_IDS = [WALK, TURN, ROUGH]
SEEDS = [0, 1, 2]


def batched(env_id: str, n: int, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize(("period", "least_speed"), [(0.5, 0.45), (1.0, 0.35)])
def test_the_tripod_walks_forward_at_half_and_one_second_periods(period, least_speed):
    """The Buehler-clock tripod (60 deg sweep) on flat ground over 10 s episodes; heading drift is measured
    (docs/xjus.md) and bounded here: straight within 0.05 rad/s on average."""
    venv = batched(WALK, len(SEEDS), max_episode_steps=1250)
    episodes = run_episodes(venv, load_policy(f"buehler:{period}", venv), SEEDS)
    speeds = np.array([e.metrics["forward_speed"] for e in episodes])
    drift = np.array([e.metrics["heading_drift"] for e in episodes])
    assert not any(e.metrics["falls"] for e in episodes)
    assert speeds.min() > least_speed, speeds
    assert np.abs(drift).max() < 0.05, drift


@pytest.mark.parametrize("yaw_rate", [-0.3, 0.3])
def test_the_turn_routine_follows_a_commanded_yaw_rate(yaw_rate):
    """A 10 s episode at a set command; the mean yaw rate after the first second within 0.06 rad/s of it. The
    rate the reward tracks is the mean over the last stride (0.5 s: 62 steps at 125 Hz; since the reset before),
    and its term is exp(-(rate - command)^2 / 0.15^2)."""
    env = gym.make(TURN)
    policy = load_policy("buehler", env)
    obs, _ = env.reset(seed=1, options={"yaw_rate": yaw_rate})
    travel, window, dt = [0.0], 62, 0.008
    for step in range(1, 1251):
        obs, _, terminated, _, info = env.step(policy.predict(obs)[0])
        assert not terminated
        travel.append(info["yaw_travel"])
        rate = (travel[-1] - travel[max(0, step - window)]) / (min(step, window) * dt)
        assert info["yaw_rate_window"] == pytest.approx(rate, abs=1e-9)
        assert info["reward_tracking"] == pytest.approx(np.exp(-(((rate - yaw_rate) / 0.15) ** 2)), abs=1e-12)
    mean_rate = (info["yaw_travel"] - info["yaw_travel_warmup"]) / (info["elapsed"] - 1.0)
    assert mean_rate == pytest.approx(yaw_rate, abs=0.06)
    assert env.unwrapped.task.episode_metrics(info)["yaw_rate_error"] == pytest.approx(abs(mean_rate - yaw_rate))


def test_gait_mode_is_the_duty_mode_controller_run_by_the_robot():
    """The robot's clock and PD (gait mode) and the buehler policy's (duty mode) give the same physics."""
    runs = {}
    for mode in ("gait", "duty"):
        env = gym.make(WALK, action_mode=mode)
        policy = load_policy("buehler", env)
        obs, _ = env.reset(seed=3)
        state, start, xs = None, np.array([True]), []
        for _ in range(150):
            action, state = policy.predict(obs, state, start)
            start = np.array([False])
            obs, *_, info = env.step(action)
            xs.append([info["x_position"], info["y_position"], info["z_position"]])
        runs[mode] = np.array(xs)
    np.testing.assert_allclose(runs["gait"], runs["duty"], atol=1e-9)


def test_the_gait_mode_walk_sends_its_one_action_as_fresh_arrays():
    """The walk's gait-mode action is computed once: still the period and sweep it names, one row per
    observation, and each call's array the caller's own."""
    env = gym.make(WALK)
    policy = load_policy("buehler:0.8", env)
    obs, _ = env.reset(seed=0)
    first, state = policy.predict(obs)
    assert state is None and first.dtype == np.float32 and first.shape == env.action_space.shape
    command = env.unwrapped.robot.mode.to_command(first.astype(np.float64))
    np.testing.assert_allclose(command, [0.8, constants.WALK_SWEEP, constants.WALK_SWEEP], rtol=1e-6)
    first[:] = 0.0  # the caller's to change
    again = policy.predict(obs)[0]
    np.testing.assert_array_equal(again, policy.predict(obs)[0])
    assert not np.array_equal(again, first)
    rows = policy.predict(np.stack([obs, obs, obs]))[0]
    assert rows.shape == (3, *env.action_space.shape) and (rows == again).all()
    rows[0] = 0.0
    np.testing.assert_array_equal(policy.predict(obs)[0], again)


def test_a_compliant_spine_pitches_and_rolls_over_rough_ground_and_a_rigid_one_does_not():
    angles = {}
    for spine in ("compliant", "rigid"):
        env = gym.make(ROUGH, roughness=0.04, spine=spine, sensor_noise=False)
        policy = load_policy("buehler", env)
        obs, _ = env.reset(seed=0, options={"start": 3})
        robot = env.unwrapped.robot
        rows = []
        for _ in range(500):
            obs, *_ = env.step(policy.predict(obs)[0])
            q = robot.segment_quaternions()[0]
            relative = [_angle_between(q[0], q[1]), _angle_between(q[2], q[1])]
            rows.append([*robot.spine_angles()[0], *relative])
        angles[spine] = np.array(rows)
    compliant, rigid = angles["compliant"], angles["rigid"]
    assert (np.degrees(compliant[:, :4].std(axis=0)) > 1.0).all(), "each spine axis moves by degrees"
    assert np.degrees(compliant[:, 4:].max()) > 5.0, "the end segments turn against the middle one"
    assert np.abs(rigid[:, :4]).max() == 0.0
    assert np.degrees(rigid[:, 4:].max()) < 1e-4, "a rigid chassis stays one body"


def _angle_between(q1: np.ndarray, q2: np.ndarray) -> float:
    return 2.0 * np.arccos(min(1.0, abs(float(np.dot(q1, q2)))))


def test_telemetry_has_currents_battery_power_and_spine_angles_that_add_up():
    env = gym.make(WALK, telemetry=True)
    policy = load_policy("buehler", env)
    obs, _ = env.reset(seed=0)
    for _ in range(60):
        obs, *_, info = env.step(policy.predict(obs)[0])
    df = env.unwrapped.recorder.frame()
    channels = env.unwrapped.robot.telemetry_channels
    for leg in constants.LEGS:
        for name in ("current", "duty", "leg_angle", "leg_speed", "power", "torque"):
            assert f"{name}_{leg}" in channels
    assert {f"spine_{j}" for j in constants.SPINE_JOINTS} <= set(channels)
    assert channels["current_FL"] == "A" and channels["power"] == "W" and channels["spine_front_pitch"] == "rad"
    last = df.iloc[-1]
    c = env.unwrapped.robot.constants
    assert last["current_FL"] == pytest.approx(last["torque_FL"] / c.torque_per_amp)
    assert last["power"] == pytest.approx(sum(last[f"power_{leg}"] for leg in constants.LEGS))
    assert last["power"] == pytest.approx(info["power"])
    assert df["power"].iloc[1:].gt(0).all()
    assert df[[f"spine_{j}" for j in constants.SPINE_JOINTS]].abs().to_numpy().max() > 0.01
    assert df["leg_angle_cmd_FL"].iloc[1:].notna().all() and df["duty_FL"].abs().max() <= 1.0


@pytest.mark.parametrize("env_id", XJUS_IDS)
def test_n_single_envs_and_one_batched_env_of_n_agree_with_xjus_parameter_ranges(env_id):
    """tests/test_batch.py's equivalence check, with randomized ranges within xJüs's parameters (its own draws the
    VelociRoACH's 3.4-3.9 V battery)."""
    randomize = {"foot_friction": (0.5, 1.0), "battery_voltage": (20.0, 24.0), "spine_stiffness_scale": (0.5, 2.0)}
    kwargs = {"max_episode_steps": 15, "randomize": randomize}
    singles = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", **kwargs)
    together = batched(env_id, 3, nthread=2, **kwargs)
    actions = np.random.default_rng(7).uniform(-1, 1, (40, 3, singles.single_action_space.shape[0]))
    out = []
    for venv in (singles, together):
        obs, _ = venv.reset(seed=11)
        rows = [obs]
        for a in actions:
            obs, reward, terminated, truncated, _ = venv.step(a)
            rows += [obs, reward[:, None], terminated[:, None], truncated[:, None]]
        out.append(rows)
    for a, b in zip(*out, strict=True):
        np.testing.assert_array_equal(a, b)
    stiffness = together.unwrapped.robot.sim.batch.expanded("jnt_stiffness")
    joint = together.unwrapped.robot.model.joint("front_pitch").id
    drawn = [p["spine_stiffness_scale"] for p in together.unwrapped.parameter_values]
    np.testing.assert_allclose(stiffness[:, joint], constants.SPINE_DESIGN_STIFFNESS * np.array(drawn))


def test_terrain_roughness_is_its_rms_height_and_the_same_seed_gives_the_same_ground():
    for roughness in (0.01, 0.05):
        assert Terrain(roughness=roughness, seed=2).rms_roughness() == pytest.approx(roughness, rel=0.05)
    a, b, c = Terrain(roughness=0.03, seed=1), Terrain(roughness=0.03, seed=1), Terrain(roughness=0.03, seed=2)
    np.testing.assert_array_equal(a.heights(), b.heights())
    assert not np.array_equal(a.heights(), c.heights())
    x, _ = a.grid()
    assert np.abs(a.heights()[:, x <= a.pad]).max() == 0.0, "every lane starts on level ground"
    assert len(a.starts()) == a.lanes and np.ptp(a.starts()[:, 1]) == pytest.approx(a.width - a.lane_width)


@pytest.mark.parametrize("height", [0.05, 0.1])
def test_step_and_stairs_have_the_asked_heights(height):
    x = np.array([1.9, 2.1, 2.35, 2.65, 2.95, 3.5])
    np.testing.assert_allclose(Terrain(obstacle="step", step_height=height).obstacle_profile(x),
                               [0, height, height, height, height, height])  # fmt: skip
    np.testing.assert_allclose(Terrain(obstacle="stairs", step_height=height).obstacle_profile(x),
                               np.array([0, 1, 2, 3, 4, 4]) * height)  # fmt: skip
    course = Terrain(obstacle="course", step_height=height).obstacle_profile(np.linspace(0, 10, 2001))
    assert course.max() == pytest.approx(height + 0.06, abs=0.01) and course.min() == 0.0


def test_rough_env_starts_on_the_lane_asked_and_reports_the_obstacle():
    env = gym.make(ROUGH, obstacle="step", step_height=0.05, roughness=0.0)
    _, info = env.reset(seed=0, options={"start": 7})
    terrain = env.unwrapped.task.terrain
    assert info["y_position"] == pytest.approx(terrain.starts()[7, 1], abs=1e-3)
    _, *_, info = env.step(env.action_space.sample())
    assert info["lane"] == 7
    metrics = env.unwrapped.task.episode_metrics({**info, "progress_x": 2.5, "elapsed": 10.0})
    assert metrics["obstacle_cleared"] == 1.0 and metrics["progress"] == 2.5


@pytest.mark.parametrize(
    ("env_id", "kwargs", "message"),
    [
        (ROUGH, {"roughness": 0.5}, "roughness"),
        (ROUGH, {"obstacle": "moat"}, "obstacle"),
        (ROUGH, {"step_height": -0.1}, "step_height"),
        (ROUGH, {"terrain_seed": -3}, "terrain_seed must be a whole number >= 0, got -3"),
        (ROUGH, {"terrain_seed": 1.5}, "terrain_seed"),
        (WALK, {"spine": "bendy"}, "spine"),
        (WALK, {"control_freq": 50.0}, "control_freq"),
        (TURN, {"current_limit": -1.0}, "current_limit"),
        (ROUGH, {"sensor_noise": "false"}, "sensor_noise"),
    ],
)
def test_bad_env_arguments_are_refused_in_one_line(env_id, kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        gym.make(env_id, **kwargs)
    assert "\n" not in str(error.value)


def test_a_randomized_spine_scale_stays_within_the_stiffness_bound_of_the_spine_as_built():
    """A stiffness scale multiplies the spine as built: near its bound, a scale of 20 would take it 20 times past
    (and launch the robot); refused at construction, single and batched, and when set directly. The design spine
    takes the whole range."""
    near_bound = 0.98 * constants.SPINE_STIFFNESS_MAX
    randomize = {"spine_stiffness_scale": (1.0, 20.0)}
    for make in (gym.make, batched):
        kwargs = {"n": 1} if make is batched else {}
        with pytest.raises(ValueError, match=r"spine_stiffness_scale.*above its bound") as error:
            make(WALK, spine_stiffness=near_bound, randomize=randomize, **kwargs)
        assert "\n" not in str(error.value)
        make(WALK, spine_stiffness=near_bound, randomize={"spine_stiffness_scale": (0.1, 1.0)}, **kwargs)
    gym.make(WALK, randomize={"spine_stiffness_scale": constants.SPINE_STIFFNESS_RANGE})
    robot = gym.make(WALK, spine_stiffness=near_bound).unwrapped.robot  # and a value set directly
    with pytest.raises(ValueError, match=r"spine_stiffness_scale'\] = 20 takes jnt_stiffness"):
        robot.set_parameters(np.array([0]), {"spine_stiffness_scale": 20.0})


def test_bad_reset_options_are_refused():
    env = gym.make(ROUGH)
    for options, message in (({"start": 99}, "start"), ({"leg_angles": [0, 1]}, "leg_angles")):
        with pytest.raises(ValueError, match=message):
            env.reset(seed=0, options=options)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--obstacles", "step"], "--obstacles: 'step' is not KIND:HEIGHT"),
        (["--obstacles", "lava:0.05"], "obstacle must be one of"),
        (["--roughness", "0.5"], "roughness must be <= "),
        (["--seconds", "0"], "--seconds must be a positive number"),
    ],
)
def test_the_spine_study_refuses_bad_arguments_in_one_line_before_running(args, message, tmp_path):
    from benchmarks import spine_study

    done = main_in_process(spine_study.main, [*args, "--name", "test_refused_" + tmp_path.name])
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert not list((Path(__file__).parents[1] / "benchmarks" / "results").glob("test_refused_*"))
