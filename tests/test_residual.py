"""Residual policies (agents/residual.py): a learned correction on top of the reference gait."""

import json

import numpy as np
import pytest
import yaml

from agents import load_policy
from agents.config import ConfigError
from agents.residual import ResidualPolicy, ResidualVecEnv, gym_env
from agents.training import main as train_main
from agents.training import make_env, resolve_hyperparams

TURN = "skitter/RoachTurn-v5"
TINY = {"policy": "MlpPolicy", "n_envs": 2, "normalize": True, "env_kwargs": {"max_episode_steps": 40},
        "n_steps": 64, "batch_size": 64}  # fmt: skip


def test_a_zero_correction_plays_the_reference_gait_exactly():
    """With no correction the residual env is driven by the tripod's turning table itself: the same observations
    as the plain env stepped by the tripod, across an episode's end and its reset."""
    residual = make_env(TURN, resolve_hyperparams({**TINY, "residual": "tripod"}, "ppo", "test"), 3)
    plain = make_env(TURN, resolve_hyperparams({**TINY, "normalize": False}, "ppo", "test"), 3)
    inner = residual.venv
    assert isinstance(inner, ResidualVecEnv) and inner.residual.scale == 0.25
    tripod = load_policy("tripod", gym_env(plain))
    inner.reset()
    obs = plain.reset()
    state, start = None, np.ones(2, dtype=bool)
    for _ in range(60):  # past the 40-step episodes
        inner.step_async(np.zeros((2, 3), dtype=np.float32))
        got, _, done_r, _ = inner.step_wait()
        action, state = tripod.predict(obs, state=state, episode_start=start)
        obs, _, done, _ = plain.step(action)
        start = done
        np.testing.assert_array_equal(got, obs)
        np.testing.assert_array_equal(done_r, done)


def test_a_residual_model_records_its_gait_and_plays_on_top_of_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    entry = {**TINY, "residual": {"policy": "tripod", "scale": 0.5}}
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({TURN: entry}))
    assert train_main(["--env", TURN, "--algo", "ppo", "--timesteps", "128", "--hyperparams", "tiny.yml",
                       "--runs-dir", "runs", "--run-name", "r", "--no-progress"]) == 0  # fmt: skip
    import gymnasium as gym

    env = gym.make(TURN)
    policy = load_policy("runs/r/model.zip", env)
    assert isinstance(policy, ResidualPolicy) and policy.residual.scale == 0.5
    tripod = load_policy("tripod", env)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        action, _ = policy.predict(obs)
        correction, _ = policy.model.predict(obs)
        expected = np.clip(tripod.predict(obs)[0] + 0.5 * correction, -1.0, 1.0)
        np.testing.assert_allclose(action, expected, rtol=0, atol=1e-6)
        obs, *_ = env.step(action)


@pytest.mark.parametrize(
    ("residual", "message"),
    [
        ("nope", "unknown policy 'nope'"),
        ({"policy": "tripod", "scale": 5}, "scale must be a number in (0, 2]"),
        ({"policy": "tripod", "gain": 1}, "expected a scripted policy's name"),
        ("runs/x/model.zip", "a residual adds to a scripted gait"),
    ],
)
def test_a_bad_residual_is_named_in_one_line(residual, message):
    with pytest.raises(ConfigError, match="field 'residual'") as error:
        make_env(TURN, resolve_hyperparams({**TINY, "residual": residual}, "ppo", "tiny.yml: " + TURN), 0)
    assert message in str(error.value)


def test_residual_reference_takes_the_robots_reference_gait(tmp_path, monkeypatch, capsys):
    """``train.py --residual reference`` trains on the robot's own reference gait (the tripod) with the entry's
    scale; with --resume it is refused, since a run keeps its own."""
    monkeypatch.chdir(tmp_path)
    entry = {**TINY, "residual": {"policy": "tripod:20", "scale": 0.4}}
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({TURN: entry}))
    argv = ["--env", TURN, "--algo", "ppo", "--timesteps", "64", "--hyperparams", "tiny.yml", "--runs-dir", "runs",
            "--run-name", "r", "--no-progress", "--residual", "reference"]  # fmt: skip
    assert train_main(argv) == 0
    from agents.sb3 import read_model_file

    manifest, _ = read_model_file(tmp_path / "runs" / "r" / "model.zip")
    assert manifest["residual"] == {"policy": "tripod", "scale": 0.4}
    with pytest.raises(SystemExit):
        train_main(["--resume", "runs/r", "--residual", "tripod"])
    assert "--residual starts a new run" in capsys.readouterr().err


def test_an_entrys_residual_settings_shape_only_residual_runs_and_set_their_exploration(tmp_path, monkeypatch):
    """An entry's ``residual`` without a policy leaves its plain runs plain. A residual run (``--residual``) takes
    the ``<id>+residual`` entry where the file has one, with its scale, exploration and PPO settings: the new
    policy's standard deviation is the exploration, not PPO's 1."""
    monkeypatch.chdir(tmp_path)
    entry = {**TINY, "residual": {"scale": 0.3, "exploration": 0.05}}
    own = {**entry, "target_kl": 0.02}
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({TURN: entry, TURN + "+residual": own}))
    plain = resolve_hyperparams(entry, "ppo", "tiny.yml: " + TURN)
    assert plain.residual is None and "log_std_init" not in (plain.model_kwargs.get("policy_kwargs") or {})
    base = ["--env", TURN, "--algo", "ppo", "--timesteps", "64", "--hyperparams", "tiny.yml", "--runs-dir", "runs",
            "--no-progress"]  # fmt: skip
    assert train_main([*base, "--run-name", "plain"]) == 0
    assert train_main([*base, "--run-name", "res", "--residual", "reference"]) == 0
    from agents.sb3 import read_model_file

    config = {name: json.loads((tmp_path / "runs" / name / "config.json").read_text()) for name in ("plain", "res")}
    assert config["plain"]["hyperparams_entry"] == TURN and "target_kl" not in config["plain"]["hyperparams"]
    assert (
        config["res"]["hyperparams_entry"] == TURN + "+residual" and config["res"]["hyperparams"]["target_kl"] == 0.02
    )
    assert "residual" not in read_model_file(tmp_path / "runs" / "plain" / "model.zip")[0]
    manifest, _ = read_model_file(tmp_path / "runs" / "res" / "model.zip")
    assert manifest["residual"] == {"policy": "tripod", "scale": 0.3, "exploration": 0.05}
    from stable_baselines3 import PPO

    std = np.exp(PPO.load(tmp_path / "runs" / "res" / "model.zip", device="cpu").policy.log_std.detach().numpy())
    np.testing.assert_allclose(std, 0.05, rtol=0.05)  # 64 steps of one update move it little
    std = np.exp(PPO.load(tmp_path / "runs" / "plain" / "model.zip", device="cpu").policy.log_std.detach().numpy())
    np.testing.assert_allclose(std, 1.0, rtol=0.05)


@pytest.mark.parametrize(
    ("algo", "residual", "extra", "message"),
    [
        ("ppo", {"scale": 0.3, "gain": 1}, {}, "expected a scripted policy's name or a mapping of policy"),
        ("ppo", {"policy": "tripod", "exploration": 0}, {}, "exploration must be a number in (0, 1]"),
        ("ppo", {"policy": "tripod", "exploration": 0.1}, {"policy_kwargs": "dict(log_std_init=-1.0)"},
         "policy_kwargs sets too (-1.0): give one"),
        ("td3", {"policy": "tripod", "exploration": 0.1}, {}, "TD3 explores by its noise_std"),
    ],
)  # fmt: skip
def test_bad_residual_settings_are_named_in_one_line(algo, residual, extra, message):
    entry = {"policy": "MlpPolicy", "n_envs": 2, "env_kwargs": {"max_episode_steps": 40}, "residual": residual,
             **({"n_steps": 64, "batch_size": 64} if algo == "ppo" else {}), **extra}  # fmt: skip
    with pytest.raises(ConfigError, match="field 'residual'") as error:
        resolve_hyperparams(entry, algo, "tiny.yml: " + TURN)
    assert message in str(error.value)


def test_a_bad_residual_on_the_command_line_is_named_as_itself(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({TURN: TINY}))
    status = train_main(["--env", TURN, "--algo", "ppo", "--timesteps", "64", "--hyperparams", "tiny.yml",
                         "--runs-dir", "runs", "--residual", "nope"])  # fmt: skip
    err = capsys.readouterr().err
    assert status == 2 and "--residual nope: unknown policy 'nope'" in err and not (tmp_path / "runs").exists()


@pytest.mark.parametrize(("env_id", "gait"), [("skitter/BioloidWalk-v2", "ik-trot"), ("skitter/RoachWalkDuty-v3",
                                                                                    "tripod")])  # fmt: skip
def test_a_gait_with_a_state_of_its_own_restarts_with_each_episode(env_id, gait):
    """The IK trot's clock and the duty-mode tripod's firmware state: with no correction, the residual env plays
    the gait exactly, across episode ends, as the plain env stepped by the gait with its episode starts."""
    entry = {**TINY, "env_kwargs": {"max_episode_steps": 30}}
    residual = make_env(env_id, resolve_hyperparams({**entry, "residual": gait}, "ppo", "test"), 1).venv
    plain = make_env(env_id, resolve_hyperparams({**entry, "normalize": False}, "ppo", "test"), 1)
    reference = load_policy(gait, gym_env(plain))
    residual.reset()
    obs = plain.reset()
    state, start = None, np.ones(2, dtype=bool)
    for _ in range(70):
        residual.step_async(np.zeros((2, plain.action_space.shape[0]), dtype=np.float32))
        got, *_ = residual.step_wait()
        action, state = reference.predict(obs, state=state, episode_start=start)
        obs, _, start, _ = plain.step(action)
        np.testing.assert_array_equal(got, obs)
