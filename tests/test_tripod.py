"""The reference policies: the alternating tripod gait and its turning variant."""

import itertools
import json

import gymnasium as gym
import numpy as np
import pytest

from agents import load_policy
from agents.evaluation import run_episode
from agents.velociroach.tripod import TripodContext, TripodGait, TripodTurn
from benchmarks.turn_table import yaw_rate as benchmark_yaw_rate

SECONDS = 4.0


def run(env_id: str, policy_spec: str, seed: int = 0, seconds: float = SECONDS, **kwargs):
    env = gym.make(env_id, **kwargs)
    env = gym.wrappers.TimeLimit(env.unwrapped, max_episode_steps=round(seconds / env.unwrapped.dt))
    return run_episode(env, load_policy(policy_spec, env), seed=seed)


@pytest.fixture(scope="module")
def speeds() -> dict[float, float]:
    out = {}
    for f in (5.0, 10.0, 20.0, 45.0):
        episode = run("skitter/RoachWalk-v4", f"tripod:{f:g}")
        assert not episode.unstable, f"{f} Hz: simulation unstable"
        assert episode.metrics["falls"] == 0, f"{f} Hz: the robot fell"
        assert episode.length == round(SECONDS * 50), f"{f} Hz: episode ended early"
        out[f] = episode.metrics["speed"]
    return out


def test_tripod_runs_forward_at_5_to_45_hz_and_faster_with_frequency(speeds):
    freqs = sorted(speeds)
    assert all(speeds[f] > 0 for f in freqs), speeds
    assert all(speeds[a] < speeds[b] for a, b in itertools.pairwise(freqs)), speeds


def test_tripod_works_in_duty_mode_as_the_firmware_would():
    """In duty mode the policy itself runs the leg clock and PID at 1 kHz."""
    gait = run("skitter/RoachWalk-v4", "tripod:10", seconds=2.0)
    duty = run("skitter/RoachWalkDuty-v3", "tripod:10", seconds=2.0)
    assert duty.metrics["falls"] == 0
    assert duty.metrics["speed"] == pytest.approx(gait.metrics["speed"], rel=0.25)


def yaw_rate(phase_deg: float, seed: int) -> float:
    """The mean yaw rate over seconds 1 to 4 of a 10 Hz tripod's episode (the turns are steady by then: their means
    over seconds 1 to 6 differ by under 0.03 rad/s, against turns of 0.55 rad/s)."""
    env = gym.make("skitter/RoachWalk-v4", max_episode_steps=round(SECONDS * 50))
    policy = TripodGait(TripodContext.from_env(env), frequency=10.0, phase=np.radians(phase_deg))
    return benchmark_yaw_rate(env, policy, seed)


def test_turning_direction_follows_the_sign_of_the_offset_from_180_deg():
    """At 10 Hz: right legs trailing by less than half a cycle turn left (counter-clockwise), by more turn right."""
    left = np.mean([yaw_rate(140, seed) for seed in range(3)])
    straight = np.mean([yaw_rate(180, seed) for seed in range(3)])
    right = np.mean([yaw_rate(220, seed) for seed in range(3)])
    assert left > 0 > right, (left, straight, right)
    assert abs(straight) < min(left, -right), "the straight gait turns less than the offset gaits"


def test_turning_tripod_maps_the_command_through_the_measured_table():
    env = gym.make("skitter/RoachTurn-v5")
    policy = load_policy("tripod", env)
    assert isinstance(policy, TripodTurn)
    obs, _ = env.reset(seed=0)
    phases = {}
    for command in (-0.5, 0.0, 0.5):
        o = obs.copy()
        o[env.unwrapped.task.layout["yaw_rate_command"]] = command
        phases[command] = policy.predict(o)[0][2]
    assert phases[0.5] < phases[0.0] < phases[-0.5], "left turns need the right legs trailing by less than pi"


@pytest.mark.parametrize("command", [0.6, -0.6])
def test_turning_tripod_turns_the_commanded_way(command):
    env = gym.make("skitter/RoachTurn-v5", max_episode_steps=300)
    policy = load_policy("tripod", env)
    obs, info = env.reset(seed=1, options={"yaw_rate": command})
    rates = []
    for _ in range(300):
        obs, _, _terminated, _truncated, info = env.step(policy.predict(obs)[0])
        if info["time"] > 1.0:
            rates.append(info["yaw_rate"])
    assert np.sign(np.mean(rates)) == np.sign(command)


def test_predict_follows_sb3_shapes_single_and_batched():
    env = gym.make("skitter/RoachWalkDuty-v3")
    policy = load_policy("tripod:10", env)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs)
    assert action.shape == (2,) and state.shape == (4,)
    batch = np.stack([obs, obs, obs])
    actions, states = policy.predict(batch, state=None, episode_start=np.ones(3, dtype=bool))
    assert actions.shape == (3, 2) and states.shape == (3, 4)
    np.testing.assert_allclose(actions[0], action)
    assert env.action_space.contains(action)


def test_unknown_policy_names_are_rejected_clearly():
    env = gym.make("skitter/RoachWalk-v4")
    with pytest.raises(ValueError, match=r"unknown policy .hexapod-magic. for the velociroach: .*tripod"):
        load_policy("hexapod-magic", env)
    with pytest.raises(ValueError, match="not a number"):
        load_policy("tripod:fast", env)
    with pytest.raises(ValueError, match="frequency"):
        load_policy("tripod:500", env)


def test_turning_table_was_measured_on_the_current_model():
    import json

    from agents.velociroach.tripod import TURN_TABLE
    from benchmarks.turn_table import fingerprint
    from envs.velociroach.robot import VelociRoach

    table = json.loads(TURN_TABLE.read_text())
    message = "the model or the firmware changed: regenerate with python -m benchmarks.turn_table"
    assert table["model_hash"] == VelociRoach("gait").model_hash, message
    assert np.allclose(table["fingerprint"], fingerprint(), atol=1e-4), message


def test_duty_tripod_reads_its_inputs_by_name_not_position():
    """Reordering the observation (a different layout) changes nothing the tripod does, given the layout."""
    from agents.velociroach.tripod import TripodContext
    from envs.common.task import ObservationLayout

    env = gym.make("skitter/RoachWalkDuty-v3")
    obs, _ = env.reset(seed=0)
    context = TripodContext.from_env(env)
    names = list(context.layout.slices)
    shuffled_names = names[::-1]
    structure = {n: context.layout[n].stop - context.layout[n].start for n in shuffled_names}
    shuffled = ObservationLayout.from_structure(structure)
    shuffled_obs = np.concatenate([obs[context.layout[n]] for n in shuffled_names])
    a = TripodGait(context, frequency=10.0).predict(obs)[0]
    b = TripodGait(TripodContext(shuffled, context.mode, context.control_dt), 10.0)
    np.testing.assert_array_equal(a, b.predict(shuffled_obs)[0])


def test_the_realtime_benchmark_replays_the_episode_it_times(tmp_path):
    """benchmarks/realtime.py, one round: its raw reference is the tripod episode's own physics (the control blocks
    and motor gains the env gave it end where the env ended)."""
    from benchmarks import realtime

    realtime.main(["--rounds", "1", "--out", str(tmp_path)])
    result = json.loads((tmp_path / "realtime.json").read_text())
    assert result["replay_matches"] is True
    assert result["rtf_rounds"][0] > 0 and result["rtf_raw_rounds"][0] > 0
    assert 2.0 < result["speed"] < 4.0  # the 45 Hz tripod runs about 3 m/s
