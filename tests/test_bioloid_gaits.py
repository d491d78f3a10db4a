"""The report's IK gait library on the Bioloid: the trot walks forward, every gait commands its table's swing and stance
order within the knee limit, the trot and the walk put their feet down as commanded, turning follows the command."""

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents import load_policy, reference_policy
from agents.bioloid.ik import GAITS, stance, touchdown_fraction
from agents.evaluation import run_episode, run_episodes
from envs.bioloid import constants
from envs.bioloid.kinematics import LegGeometry


def circular_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.mod(np.asarray(a) - np.asarray(b), 1.0)
    return np.minimum(d, 1.0 - d)


def test_the_reference_gait_is_the_trot():
    assert reference_policy("bioloid") == "ik-trot"


def test_ik_trot_at_1_5_hz_walks_forward_on_flat_ground():
    venv = gym.make_vec("skitter/BioloidWalk-v2", num_envs=3, vectorization_mode="vector_entry_point")
    episodes = run_episodes(venv, load_policy("ik-trot:1.5", venv), [0, 1, 2])
    for e in episodes:
        assert e.length == 500 and e.metrics["falls"] == 0, "10 s upright"
        assert e.metrics["forward_speed"] > 0.02, e.metrics  # m/s along +x (measured about 0.05; docs/bioloid.md)


@pytest.mark.parametrize("gait", sorted(GAITS))
def test_every_gait_commands_its_tables_swing_and_stance_order_within_the_knee_limit(gait):
    env = gym.make("skitter/BioloidWalk-v2")
    frequency = 1.0
    policy = load_policy(f"ik-{gait}:{frequency}", env)
    t = np.arange(0.0, 3.0, 0.002) + 1.0  # after the one-cycle lead-in
    goal, limited = policy.counts(t, np.ones((len(t), 4)))
    assert not limited.any(), "the report's ellipse keeps the knee within 90 deg"
    assert (
        goal[:, [constants.SERVO_INDEX[constants.KNEE[leg]] for leg in constants.LEGS]]
        <= constants.counts(constants.KNEE_LIMIT) + 1e-9
    ).all()
    heights, strides = [], []
    for leg in constants.LEGS:
        hip = (goal[:, constants.SERVO_INDEX[constants.HIP[leg]]] - constants.CENTER) * constants.RAD_PER_COUNT
        knee = (goal[:, constants.SERVO_INDEX[constants.KNEE[leg]]] - constants.CENTER) * constants.RAD_PER_COUNT
        x, z = LegGeometry.of(leg).forward(hip, knee)
        heights.append(z)
        strides.append(x)
    z, x = np.array(heights).T, np.array(strides).T
    commanded = stance(GAITS[gait], t, frequency)
    for i in range(4):
        # the stance is the lower half of the foot's path, and the foot moves backward in it
        assert z[commanded[:, i], i].max() < z[~commanded[:, i], i].min() + 1e-9
        assert np.all(np.diff(x[:, i])[commanded[1:, i] & commanded[:-1, i]] <= 1e-12)
        assert commanded[:, i].mean() == pytest.approx(0.5, abs=0.01), "duty factor 0.5"
        # touch-down (swing -> stance) at the table's phase
        down = np.flatnonzero(commanded[1:, i] & ~commanded[:-1, i]) + 1
        phases = np.mod(frequency * t[down], 1.0)
        assert circular_distance(phases, touchdown_fraction(GAITS[gait])[i]).max() < 0.01


def contact_phases(gait: str, frequency: float, seed: int, seconds: float = 8.0) -> np.ndarray:
    """Each foot's contact force, averaged over the cycle as a phase (force-weighted circular mean), after 2 s."""
    env = gym.make("skitter/BioloidWalk-v2", sensor_noise=False)
    robot = env.unwrapped.robot
    policy = load_policy(f"ik-{gait}:{frequency}", env)
    obs, _ = env.reset(seed=seed)
    state, forces = None, []
    for _ in range(round(seconds / env.unwrapped.dt)):
        action, state = policy.predict(obs, state)
        obs, *_ = env.step(action)
        forces.append(robot.foot_forces(robot.sim.substep_sensordata)[0].copy())
    force = np.concatenate(forces)
    t = (np.arange(len(force)) + 1) * robot.model.opt.timestep
    keep = t > 2.0
    angle = 2.0 * np.pi * np.mod(frequency * t[keep], 1.0)
    weighted = (force[keep] * np.exp(1j * angle)[:, None]).sum(axis=0)
    return np.mod(np.angle(weighted) / (2.0 * np.pi), 1.0)


@pytest.mark.parametrize(("gait", "frequency"), [("trot", 1.5), ("walk", 1.0)])
def test_measured_foot_contacts_of_trot_and_walk_follow_the_commanded_order_within_each_pair(gait, frequency):
    """Left and right feet of each pair come down half a cycle apart, and each pair's contacts keep the commanded
    timing up to one shift shared by its two feet. The shift differs between the pairs (front feet ahead of their
    command by 0.3-0.4 cycle, back feet within 0.15 of theirs: the front legs carry three quarters of the weight and
    land early out of the ellipse's 1 cm swing; docs/bioloid.md), so the trot's diagonals and the walk's lateral lag
    are not kept exactly."""
    measured = contact_phases(gait, frequency, seed=0)
    commanded = np.mod(touchdown_fraction(GAITS[gait]) + 0.25, 1.0)  # middle of each commanded stance
    shift = np.mod(measured - commanded + 0.5, 1.0) - 0.5
    for left, right in ((0, 1), (2, 3)):
        assert circular_distance(measured[left], measured[right] + 0.5) < 0.1, (gait, measured)
        assert abs(shift[left] - shift[right]) < 0.06, (gait, shift)
    assert -0.5 < shift[0] < -0.2 and abs(shift[2]) < 0.15, ("the documented shifts", shift)


@pytest.mark.parametrize("yaw_rate", [-0.25, 0.0, 0.15])
def test_the_steered_trot_turns_at_the_commanded_rate(yaw_rate):
    """The reference on BioloidTurn marks time and swings its feet sideways to turn, with a heading correction: over
    6 s episodes its mean yaw rate after the first second is within 0.06 rad/s of the command in every episode and
    0.03 on average (measured: at most 0.044 on seeds 0, 7 and 100; 0.008 on average over the 10 s episodes of seeds
    1000-1019, docs/bioloid.md), where the full trot alone veers by up to +-0.17."""
    venv = gym.make_vec("skitter/BioloidTurn-v5", num_envs=4, vectorization_mode="vector_entry_point",
                        max_episode_steps=300, nthread=1)  # fmt: skip
    policy = load_policy("ik-trot", venv)
    obs, _ = venv.reset(seed=0, options={"yaw_rate": yaw_rate})
    state, start = None, np.ones(4, dtype=bool)
    for _ in range(299):
        action, state = policy.predict(obs, state, start)
        start[:] = False
        obs, _, terminated, _, info = venv.step(action)
        assert not terminated.any()
    rates = (info["yaw_travel"] - info["yaw_travel_warmup"]) / (info["elapsed"] - 1.0)
    error = np.abs(rates - yaw_rate)
    assert error.max() < 0.06 and error.mean() < 0.03, rates


def test_shortening_one_sides_stride_turns_the_trot_toward_the_other_side():
    venv = gym.make_vec("skitter/BioloidWalk-v2", num_envs=4, vectorization_mode="vector_entry_point")
    policy = load_policy("ik-trot", venv)
    robot = venv.unwrapped.robot
    side = np.array([constants.LEG_SIDE[leg] == "right" for leg in constants.LEGS])
    strides = np.array([np.where(side, s, 1.0) if s is not None else np.where(~side, 0.0, 1.0)
                        for s in (0.0, 0.0, None, None)])  # fmt: skip
    venv.reset(seed=[0, 1, 0, 1])
    t = np.zeros(4)
    for _ in range(500):
        goal, _ = policy.counts(t, strides * policy.lead_in(t)[:, None])
        t = t + robot.control_dt
        *_, info = venv.step(robot.mode.to_action(goal))
    rates = (info["yaw_travel"] - info["yaw_travel_warmup"]) / (info["elapsed"] - 1.0)
    assert (rates[:2] > 0.1).all() and (rates[2:] < -0.1).all(), rates  # right stride 0: left turn, and back


def test_bad_gait_names_and_frequencies_are_refused():
    env = gym.make("skitter/BioloidWalk-v2")
    with pytest.raises(ValueError, match="frequency"):
        load_policy("ik-trot:fast", env)
    with pytest.raises(ValueError, match="frequency"):
        load_policy("ik-trot:50", env)
    with pytest.raises(ValueError, match="unknown policy"):
        load_policy("ik-moonwalk", env)


@pytest.mark.parametrize("batched", [False, True])
def test_ik_gaits_walk_when_the_caller_does_not_pass_the_state_back(batched):
    """A caller that drops predict()'s state (``action, _ = policy.predict(obs)``) gets the same actions as one that
    passes it back: the policy keeps its clock, and episode_start restarts a row's clock either way."""
    if batched:
        env = gym.make_vec("skitter/BioloidTurn-v5", num_envs=2, vectorization_mode="vector_entry_point", nthread=1)
    else:
        env = gym.make("skitter/BioloidTurn-v5")
    keeps, drops = load_policy("ik-trot", env), load_policy("ik-trot", env)
    obs, _ = env.reset(seed=0)
    n = 2 if batched else 1
    state, actions = None, []
    for step in range(40):
        # a new episode for the first row at step 25 (as a vector env's autoreset would flag it)
        start = np.array([step in (0, 25)] + [step == 0] * (n - 1))
        start = start if batched else start[:1]
        action, state = keeps.predict(obs, state, start)
        dropped, _ = drops.predict(obs, None, start)
        np.testing.assert_array_equal(dropped, action)
        actions.append(action)
        obs, *_ = env.step(action)
    actions = np.array(actions)
    assert np.ptp(actions, axis=0).max() > 0.1, "the legs must move, not stand still"
    first_row = actions[:, 0] if batched else actions
    np.testing.assert_array_equal(first_row[25], first_row[0])  # the restarted row is back at its lead-in's start
    drops.reset()
    np.testing.assert_array_equal(drops.predict(obs)[0], keeps.predict(obs, None, np.ones(n, dtype=bool))[0])


@pytest.mark.parametrize("gait", sorted(GAITS))
def test_every_ik_gait_fits_within_the_offset_modes_reach(gait):
    """The offset mode reaches 0.5 rad from the ready posture; every IK gait's goals, at the ends of its frequency
    range, marking time or striding, turning either way as hard as it steers, stay inside it (at most 0.384 rad)."""
    from agents.bioloid.ik import FREQUENCY_RANGE, STEER_STRIDE, TURN_LIMIT

    env = gym.make("skitter/BioloidTurn-v5")
    assert env.unwrapped.robot.action_mode == "offset"
    t = np.arange(0.0, 4.0, 0.002)
    for frequency in FREQUENCY_RANGE:
        policy = load_policy(f"ik-{gait}:{frequency}", env)
        for stride in (1.0, STEER_STRIDE):
            for turn in (-TURN_LIMIT, 0.0, TURN_LIMIT):
                goal = policy.goals.steered(t, np.full(len(t), stride), np.full(len(t), turn))
                action = policy.mode.to_action(goal)
                assert np.abs(action).max() <= 1.0, (frequency, stride, turn, np.abs(action).max())


def test_the_reference_trot_plays_the_same_in_the_offset_and_the_goal_mode():
    """Its goals are the same counts either way: the returns agree to float rounding (measured to 2e-5)."""
    returns = {}
    for mode in ("offset", "goal"):
        env = gym.make("skitter/BioloidTurn-v5", action_mode=mode, max_episode_steps=200)
        policy = load_policy("ik-trot", env)
        returns[mode] = np.array([run_episode(env, policy, seed).metrics["return"] for seed in (1000, 1001)])
    assert returns["offset"] == pytest.approx(returns["goal"], rel=1e-4), returns


def test_the_cpg_refuses_the_offset_mode_naming_the_mode_to_use():
    with pytest.raises(ValueError, match="action_mode='goal'"):
        load_policy("cpg", gym.make("skitter/BioloidTurn-v5"))
    load_policy("cpg", gym.make("skitter/BioloidTurn-v5", action_mode="goal"))
