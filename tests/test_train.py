"""train.py end to end: each test runs it as a subprocess on a tiny budget and checks what it leaves behind."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import gymnasium as gym
import pytest
import yaml
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

import envs  # noqa: F401  (registers the skitter envs)
from agents.sb3 import ModelFileError, SB3Policy, read_model_file
from tests.conftest import main_in_process

ROOT = Path(__file__).resolve().parents[1]
WALK = "skitter/RoachWalk-v4"
# SAC/TD3 on a budget: learning starts after 100 steps, small networks and buffer
TINY_OFF_POLICY = """
skitter/RoachWalk-v4:
  normalize: {norm_obs: true, norm_reward: false}
  buffer_size: 1000
  learning_starts: 100
  batch_size: 32
  noise_type: normal
  noise_std: 0.1
  policy_kwargs: "dict(net_arch=[32, 32])"
"""
# PPO on a budget: one env, an update every 64 steps
TINY_PPO = f"{WALK}:\n  n_envs: 1\n  n_steps: 64\n  batch_size: 32\n  n_epochs: 1\n  normalize: true\n"


def run_train(*args: object) -> subprocess.CompletedProcess:
    command = [sys.executable, str(ROOT / "train.py"), *map(str, args), "--no-progress"]
    return subprocess.run(command, capture_output=True, text=True, cwd=ROOT, timeout=300)


def train_in_process(*args: object) -> subprocess.CompletedProcess:
    """``train.main`` in the test's process, as the command runs it (inputs refused before training, short resumes): a
    subprocess per case spent seconds loading torch each (the command line itself is checked by the tests that
    run it)."""
    from agents import training as train

    return main_in_process(train.main, [*map(str, args), "--no-progress"])


def train_ok(*args: object, command_line: bool = False) -> subprocess.CompletedProcess:
    """A run that must succeed: in this process, or as ``python train.py`` (``command_line``: the module's trained
    run and one resume go through the command line itself)."""
    result = run_train(*args) if command_line else train_in_process(*args)
    assert result.returncode == 0, result.stderr
    return result


def scalars(tb_dir: Path) -> dict[str, list[tuple[int, float]]]:
    accumulator = EventAccumulator(str(tb_dir))
    accumulator.Reload()
    return {tag: [(e.step, e.value) for e in accumulator.Scalars(tag)] for tag in accumulator.Tags()["scalars"]}


def checkpoints(run_dir: Path) -> dict[int, Path]:
    markers = (run_dir / "checkpoints").glob("step_*/checkpoint.json")
    return {json.loads(marker.read_text())["num_timesteps"]: marker.parent for marker in markers}


def assert_policy_acts(model: Path, env_id: str = WALK) -> SB3Policy:
    env = gym.make(env_id)
    policy = SB3Policy(model, env)
    observation, _ = env.reset(seed=0)
    action, _ = policy.predict(observation)
    assert action.shape == env.action_space.shape
    assert env.action_space.contains(action.astype(env.action_space.dtype))
    return policy


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory) -> Path:
    """A PPO run with the default hyperparameters: one update of 4 envs x 512 steps (each env ends an episode)."""
    runs = tmp_path_factory.mktemp("runs")
    train_ok("--env", WALK, "--algo", "ppo", "--timesteps", 2048, "--seed", 3, "--checkpoint-freq", 1024,
             "--runs-dir", runs, command_line=True)  # fmt: skip
    (run_dir,) = runs.iterdir()
    return run_dir


def test_ppo_run_writes_model_config_checkpoints_and_logs(ppo_run):
    assert re.fullmatch(r"skitter_RoachWalk-v4__ppo__3__\d{8}-\d{6}", ppo_run.name)
    for name in ("model.zip", "config.json", "command.txt"):
        assert (ppo_run / name).is_file(), name
    assert not (ppo_run / "vecnormalize.pkl").exists(), "the statistics live inside model.zip"
    with zipfile.ZipFile(ppo_run / "model.zip") as archive:
        assert {"data", "vecnormalize.pkl", "skitter.json"} <= set(archive.namelist())
        manifest = json.loads(archive.read("skitter.json"))
    assert manifest["normalized"] and manifest["algo"] == "ppo" and manifest["env_id"] == WALK
    config = json.loads((ppo_run / "config.json").read_text())
    assert (config["env_id"], config["algo"], config["seed"], config["timesteps"]) == (WALK, "ppo", 3, 2048)
    assert config["n_envs"] == 4 and config["hyperparams"]["n_steps"] == 512
    assert {"skitter", "stable-baselines3", "torch", "mujoco", "gymnasium"} <= set(config["versions"])
    assert "--algo ppo --timesteps 2048" in (ppo_run / "command.txt").read_text()

    saved = checkpoints(ppo_run)
    assert sorted(saved) == [1024, 2048]
    assert sorted(p.name for p in saved[2048].iterdir()) == ["checkpoint.json", "model.zip"]
    assert not list((ppo_run / "checkpoints").glob(".*")), "no temporary checkpoint folder left behind"

    logs = scalars(ppo_run / "tb")
    assert {"rollout/ep_rew_mean", "train/value_loss", "episode/forward_speed", "episode/fall_rate"} <= set(logs)
    assert {"episode/speed", "episode/cost_of_transport", "episode/speed_bl"} <= set(logs)
    terms = [tag for tag in logs if tag.startswith("reward/")]
    assert sorted(terms) == ["reward/energy", "reward/forward", "reward/upright"]
    # the reward terms of the same episodes add up to SB3's own episode return
    (step, mean_return) = logs["rollout/ep_rew_mean"][0]
    assert sum(dict(logs[tag])[step] for tag in terms) == pytest.approx(mean_return, rel=1e-4, abs=1e-3)

    policy = assert_policy_acts(ppo_run / "model.zip")
    assert policy.normalizer is not None


def test_resume_continues_the_run_in_its_folder(ppo_run, tmp_path):
    run_dir = shutil.copytree(ppo_run, tmp_path / ppo_run.name)
    train_ok("--resume", run_dir, "--timesteps", 4096, command_line=True)
    assert sorted(path.name for path in tmp_path.iterdir()) == [ppo_run.name]
    assert max(checkpoints(run_dir)) == 4096
    assert SB3Policy(run_dir / "model.zip").model.num_timesteps == 4096
    assert "skipping" not in (run_dir / "command.txt").read_text()
    assert json.loads((run_dir / "config.json").read_text())["timesteps"] == 4096
    assert len((run_dir / "command.txt").read_text().splitlines()) == 2
    steps = [step for step, _ in scalars(run_dir / "tb")["reward/forward"]]
    assert steps == [2048, 4096]


def test_resume_without_checkpoint_is_a_clear_error(ppo_run, tmp_path):
    shutil.copy(ppo_run / "config.json", tmp_path / "config.json")
    result = train_in_process("--resume", tmp_path, "--timesteps", 4096)
    assert result.returncode != 0
    assert "Traceback" not in result.stderr
    assert "no checkpoint" in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("algo", ["sac", "td3"])
def test_off_policy_algorithms_train(algo, tmp_path):
    hyperparams = tmp_path / "tiny.yml"
    hyperparams.write_text(TINY_OFF_POLICY)
    runs = tmp_path / "runs"
    train_ok("--env", WALK, "--algo", algo, "--timesteps", 300, "--runs-dir", runs, "--hyperparams", hyperparams)
    (run_dir,) = runs.iterdir()
    assert SB3Policy(run_dir / "model.zip").normalizer is not None
    assert (checkpoints(run_dir)[300] / "replay_buffer.pkl").is_file()
    assert "train/critic_loss" in scalars(run_dir / "tb")  # gradient steps ran after learning_starts
    policy = assert_policy_acts(run_dir / "model.zip")
    assert type(policy.model).__name__ == algo.upper()


BAD_INPUTS = {
    "unknown env": ({}, ["--env", "skitter/NoSuchEnv-v0"], ["skitter/NoSuchEnv-v0"]),
    "another package's env": ({}, ["--env", "CartPole-v1"], ["'CartPole-v1' is not a skitter env"]),
    "an old version": (
        {},
        ["--env", "skitter/RoachWalk-v2"],
        ["'skitter/RoachWalk-v2' (did you mean 'skitter/RoachWalk-v4'?)"],
    ),
    "bad env_kwargs value": ({WALK: "  env_kwargs: {max_tilt: -1.0}"}, [], ["bad.yml", "env_kwargs", "max_tilt"]),
    "unknown env_kwargs": ({WALK: "  env_kwargs: {legs: 8}"}, [], ["bad.yml", "env_kwargs", "legs"]),
    "negative seed": ({}, ["--seed", "-1"], ["--seed", "-1"]),
    "env missing from file": ({"skitter/RoachTurn-v0": "  n_steps: 64"}, [], ["bad.yml", WALK, "no entry"]),
    "bad value": ({WALK: "  gamma: 1.5"}, [], ["bad.yml", "gamma", "1.5"]),
    "a quoted word for normalize": ({WALK: '  normalize: "yes"'}, [], ["bad.yml", "normalize", "expected true, false"]),
    "wrong type": ({WALK: "  n_steps: lots"}, [], ["bad.yml", "n_steps", "lots"]),
    "unknown field": ({WALK: "  n_step: 64"}, [], ["bad.yml", "n_step", "did you mean 'n_steps'"]),
    "non-positive timesteps": ({}, ["--timesteps", "0"], ["--timesteps"]),
    "run name ..": ({}, ["--run-name", ".."], ["--run-name", "'..'"]),  # it used to make --runs-dir first
    "a string for a switch": ({WALK: "  env_kwargs: {sensor_noise: 'false'}"}, [], ["bad.yml", "sensor_noise"]),
    # a zero learning rate, and a minibatch larger than the rollout it is drawn from, trained silently
    "zero learning rate": ({WALK: "  learning_rate: lin_0"}, [], ["bad.yml", "learning_rate", "above 0"]),
    "batch larger than rollout": ({WALK: "  n_steps: 64\n  batch_size: 512"}, [], ["batch_size", "512", "64 x 1"]),
    "--env-kwargs not JSON": ({}, ["--env-kwargs", "{legs"], ["--env-kwargs", "not JSON"]),
    "--env-kwargs not an object": ({}, ["--env-kwargs", "[1]"], ["--env-kwargs", "JSON object"]),
    "--env-kwargs unknown": ({}, ["--env-kwargs", '{"legs": 8}'], ["--env-kwargs", "legs"]),
}


def test_a_hyperparameter_file_that_is_not_utf8_is_a_one_line_error(tmp_path):
    hyperparams = tmp_path / "latin1.yml"
    hyperparams.write_bytes(f"{WALK}:\n  n_steps: 64 # caf\xe9\n".encode("latin-1"))
    args = ["--env", WALK, "--algo", "ppo", "--timesteps", 100, "--runs-dir", tmp_path / "runs"]
    result = train_in_process(*args, "--hyperparams", hyperparams)
    assert result.returncode == 2 and "not UTF-8" in result.stderr and "latin1.yml" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "runs").exists()


def break_truncated_zip(folder: Path) -> None:
    model = folder / "model.zip"
    model.write_bytes(model.read_bytes()[:1000])


def break_marker(folder: Path) -> None:
    (folder / "checkpoint.json").write_text("{not json")


def rewrite_entry(model: Path, name: str, damage) -> None:
    """Rewrite the model file with its entry ``name`` damaged by ``damage(bytes)``; the zip's checksums stay right."""
    with zipfile.ZipFile(model) as src:
        entries = {item.filename: src.read(item) for item in src.infolist()}
    entries[name] = damage(entries[name])
    with zipfile.ZipFile(model, "w") as dst:
        for entry, data in entries.items():
            dst.writestr(entry, data)


def break_statistics(folder: Path) -> None:
    """A truncated statistics pickle inside the model file."""
    rewrite_entry(folder / "model.zip", "vecnormalize.pkl", lambda data: data[:40])


def break_weights(folder: Path) -> None:
    """Garbage in place of the policy's weights inside the model file."""
    rewrite_entry(folder / "model.zip", "policy.pth", lambda data: b"garbage" * 10)


@pytest.mark.parametrize("breaker", [break_truncated_zip, break_marker, break_statistics, break_weights])
def test_resume_falls_back_past_a_corrupt_newest_checkpoint_and_says_so(ppo_run, tmp_path, breaker):
    run_dir = shutil.copytree(ppo_run, tmp_path / ppo_run.name)
    saved = checkpoints(run_dir)
    breaker(saved[2048])
    result = train_in_process("--resume", run_dir, "--timesteps", 3072)  # a resume in this process: no torch load
    assert result.returncode == 0, result.stderr
    assert "skipping a broken checkpoint" in result.stderr and "step_0000002048" in result.stderr
    assert "from step_0000001024 (1024 steps)" in result.stdout
    assert SB3Policy(run_dir / "model.zip").model.num_timesteps == 3072


def test_a_killed_run_never_leaves_a_model_without_its_statistics(tmp_path):
    """SIGKILL at several moments after checkpoints begin (timed from the first one, not from the start, so a busy
    machine cannot make the test vacuous): every model file present is whole (weights, statistics and manifest)."""
    found = 0
    hyperparams = tmp_path / "ppo.yml"
    hyperparams.write_text(TINY_PPO)  # a checkpoint every 64 steps: many writes to be killed in
    for delay in (0.0, 1.5):  # at the first checkpoint, and some checkpoints later
        runs = tmp_path / f"runs{delay}"
        command = [sys.executable, str(ROOT / "train.py"), "--env", WALK, "--algo", "ppo", "--timesteps", "100000",
                   "--checkpoint-freq", "64", "--hyperparams", str(hyperparams), "--runs-dir", str(runs),
                   "--no-progress"]  # fmt: skip
        process = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 240.0
            while not any(runs.glob("*/checkpoints/*")) and process.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(delay)
        finally:
            process.send_signal(signal.SIGKILL)
            process.wait()
        for model in runs.rglob("model.zip"):
            manifest, stats = read_model_file(model)
            assert manifest["normalized"] and stats is not None, model
            found += 1
    assert found, "checkpoints were written before the kills"


def _bad_input_args(case: str, tmp_path: Path) -> list:
    entries, extra, _ = BAD_INPUTS[case]
    args = ["--env", WALK, "--algo", "ppo", "--timesteps", 100, "--runs-dir", tmp_path / "runs"]
    if entries:
        hyperparams = tmp_path / "bad.yml"
        hyperparams.write_text("".join(f"{env}:\n{body}\n" for env, body in entries.items()))
        args += ["--hyperparams", hyperparams]
    return [*args, *extra]  # later flags win


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_is_a_one_line_error(case, tmp_path):
    assert_one_line_error(train_in_process(*_bad_input_args(case, tmp_path)), *BAD_INPUTS[case][2])
    assert not (tmp_path / "runs").exists()


def test_bad_input_is_a_one_line_error_from_the_command_line(tmp_path):
    """One case through ``python train.py`` itself (the others run ``main`` in this process, above)."""
    case = "bad env_kwargs value"
    assert_one_line_error(run_train(*_bad_input_args(case, tmp_path)), *BAD_INPUTS[case][2])
    assert not (tmp_path / "runs").exists()


def test_env_kwargs_on_the_command_line_go_over_the_entrys_and_into_the_run(tmp_path):
    """``--env-kwargs`` merges over the hyperparameter entry's env_kwargs; the run keeps them (a resume makes its env
    as it was), and ``--residual reference`` on a soccer academy task in the commands mode is the scripted player."""
    academy = "skitter/BioloidGoToBall-v4"
    hyperparams = tmp_path / "tiny.yml"
    hyperparams.write_text(f"{academy}:\n  n_envs: 1\n  n_steps: 64\n  batch_size: 32\n  n_epochs: 1\n"
                           "  env_kwargs: {sensor_noise: false}\n")  # fmt: skip
    result = train_in_process("--env", academy, "--algo", "ppo", "--timesteps", 64, "--hyperparams", hyperparams,
                              "--env-kwargs", '{"action_mode": "commands"}', "--residual", "reference",
                              "--runs-dir", tmp_path / "runs", "--run-name", "a")  # fmt: skip
    assert result.returncode == 0, result.stderr
    config = json.loads((tmp_path / "runs" / "a" / "config.json").read_text())
    assert config["hyperparams"]["env_kwargs"] == {"sensor_noise": False, "action_mode": "commands"}
    assert config["hyperparams"]["residual"] == {"policy": "scripted"}
    refused = train_in_process("--soccer", "roach", "--env-kwargs", "{}", "--runs-dir", tmp_path / "other")
    assert refused.returncode == 2 and "--env-kwargs" in refused.stderr and not (tmp_path / "other").exists()


def test_batched_and_dummy_vec_envs_train_the_same_model(tmp_path):
    """The batched env gives each simulation exactly a single env's results, so PPO learns the same weights."""
    import torch

    weights = {}
    for vec_env in ("batched", "dummy"):
        hyperparams = tmp_path / f"{vec_env}.yml"
        hyperparams.write_text(f"{WALK}:\n  n_envs: 2\n  n_steps: 64\n  batch_size: 64\n  n_epochs: 2\n"
                               f"  normalize: true\n  vec_env: {vec_env}\n")  # fmt: skip
        runs = tmp_path / vec_env
        train_ok("--env", WALK, "--algo", "ppo", "--timesteps", 256, "--runs-dir", runs, "--hyperparams", hyperparams)
        (run_dir,) = runs.iterdir()
        weights[vec_env] = SB3Policy(run_dir / "model.zip").model.policy.state_dict()
    for name, tensor in weights["batched"].items():
        assert torch.equal(tensor, weights["dummy"][name]), name


def test_without_a_progress_bar_a_run_prints_a_line_of_progress(tmp_path, monkeypatch):
    """With ``--no-progress`` (or output to a file) the run says how far it has come, at the end of a rollout."""
    from envs.common import io

    monkeypatch.setattr(io, "PROGRESS_SECONDS", 0.0)  # a line every rollout, not every minute
    hyperparams = tmp_path / "ppo.yml"
    hyperparams.write_text(TINY_PPO)
    result = train_ok("--env", WALK, "--algo", "ppo", "--timesteps", 256, "--runs-dir", tmp_path / "runs",
                      "--hyperparams", hyperparams)  # fmt: skip
    lines = [line for line in result.stdout.splitlines() if line.startswith("step ")]
    steps = [int(re.match(r"step ([\d,]+) of 256 \(\d+%\), \d+ steps/s", line)[1]) for line in lines]
    assert steps == [64, 128, 192, 256], lines
    assert all(" left (ends about " in line for line in lines[:-1]) and " left " not in lines[-1]


# --- bad input, damaged checkpoints, SIGTERM ----------------------------------------------------------------------


def files(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its content (None for a folder)."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def assert_one_line_error(result: subprocess.CompletedProcess, *expected: str) -> None:
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    for text in expected:
        assert text in result.stderr, (text, result.stderr)


def train_with(tmp_path: Path, algo: str, body: str) -> subprocess.CompletedProcess:
    """train.py with a hyperparameter file ``bad.yml`` whose entry for WALK is ``body``; runs go to tmp_path/runs."""
    hyperparams = tmp_path / "bad.yml"
    hyperparams.write_text(f"{WALK}:\n{body}\n")
    args = ["--env", WALK, "--algo", algo, "--timesteps", 128, "--runs-dir", tmp_path / "runs"]
    return train_in_process(*args, "--hyperparams", hyperparams)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> Path:
    """A normalized PPO run of 128 steps with checkpoints at 64 and 128."""
    runs = tmp_path_factory.mktemp("runs")
    (runs / "ppo.yml").write_text(TINY_PPO)
    args = ["--env", WALK, "--algo", "ppo", "--timesteps", 128, "--checkpoint-freq", 64, "--run-name", "tiny"]
    train_ok(*args, "--runs-dir", runs, "--hyperparams", runs / "ppo.yml")
    return runs / "tiny"


@pytest.mark.parametrize(
    ("algo", "body", "expected"),
    [
        ("ppo", "  gamma: .nan", ["'gamma' = nan: must be a finite number"]),
        ("ppo", "  learning_rate: .inf", ["'learning_rate' = inf: must be a finite number"]),
        ("ppo", "  learning_rate: lin_nan", ["'learning_rate' = 'lin_nan': must be a finite number"]),
        ("ppo", "  policy_kwargs: {log_std_init: .nan}", ["'policy_kwargs'", "nan is not a finite number"]),
        ("sac", "  ent_coef: .nan", ["'ent_coef' = nan: must be a finite number"]),
        ("sac", "  tau: -.inf", ["'tau' = -inf: must be a finite number"]),
    ],
)
def test_non_finite_hyperparameters_are_refused(tmp_path, algo, body, expected):
    assert_one_line_error(train_with(tmp_path, algo, body), "bad.yml", *expected)
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("  device: banana", ["field 'device' = 'banana': cannot build the PPO model", "device string: banana"]),
        ("  policy_kwargs: {net_arch: [-5, 64]}", ["field 'policy_kwargs' = {'net_arch': [-5, 64]}", "dimension -5"]),
    ],
)
def test_a_model_torch_cannot_build_is_a_config_error_naming_the_field(tmp_path, body, expected):
    assert_one_line_error(train_with(tmp_path, "ppo", body), "bad.yml", *expected)
    assert not (tmp_path / "runs").exists()


def test_resume_refuses_a_checkpoint_of_another_env(tiny_run, tmp_path):
    run_dir = shutil.copytree(tiny_run, tmp_path / "run")
    config = run_dir / "config.json"
    config.write_text(config.read_text().replace(WALK, "skitter/RoachTurn-v5"))  # 22 observations, not 21
    before = files(run_dir)
    result = train_in_process("--resume", run_dir, "--timesteps", 256)
    model = run_dir / "checkpoints" / "step_0000000128" / "model.zip"
    assert_one_line_error(result, f"checkpoint {model}", "observation space", "(21,)", "(22,)")
    assert files(run_dir) == before


def test_a_checkpoint_with_corrupt_weights_is_a_one_line_error(tiny_run, tmp_path):
    from agents import compare

    run_dir = shutil.copytree(tiny_run, tmp_path / "run")
    shutil.rmtree(run_dir / "checkpoints" / "step_0000000064")
    break_weights(run_dir / "checkpoints" / "step_0000000128")
    model = run_dir / "checkpoints" / "step_0000000128" / "model.zip"
    before = files(run_dir)
    result = train_in_process("--resume", run_dir, "--timesteps", 256)
    assert_one_line_error(result, "no checkpoint to resume from", f"cannot read checkpoint {model}: corrupt contents")
    assert files(run_dir) == before

    with pytest.raises(ModelFileError, match=r"cannot read policy file .*model\.zip: corrupt"):
        SB3Policy(model, gym.make(WALK))
    foreign = tmp_path / "zoo" / "model.zip"  # RL Zoo's layout: no manifest, the statistics beside the model
    foreign.parent.mkdir()
    with zipfile.ZipFile(tiny_run / "model.zip") as src, zipfile.ZipFile(foreign, "w") as dst:
        for item in src.infolist():
            if item.filename not in ("skitter.json", "vecnormalize.pkl"):
                dst.writestr(item, src.read(item))
    (foreign.parent / "vecnormalize.pkl").write_bytes(b"garbage")
    with pytest.raises(ModelFileError, match=r"cannot read .*vecnormalize\.pkl: corrupt"):
        SB3Policy(foreign, gym.make(WALK))
    out = tmp_path / "evaluation"  # evaluate.py's main, in this process: its command line is tested in test_evaluate
    result = main_in_process(compare.main, ["--env", WALK, "--policy", str(model), "--out", str(out)])
    assert_one_line_error(result, f"--policy '{model}': cannot read policy file {model}: corrupt contents")
    assert "checkpoint" not in result.stderr.replace(str(model), "MODEL"), "a policy file is not a checkpoint here"
    assert not out.exists()


def test_resume_refuses_a_corrupt_replay_buffer(tmp_path):
    (tmp_path / "tiny.yml").write_text(TINY_OFF_POLICY)
    args = ["--env", WALK, "--algo", "sac", "--timesteps", 120, "--runs-dir", tmp_path / "runs", "--run-name", "sac"]
    assert train_in_process(*args, "--hyperparams", tmp_path / "tiny.yml").returncode == 0  # in this process: fast
    run_dir = tmp_path / "runs" / "sac"
    buffer = checkpoints(run_dir)[120] / "replay_buffer.pkl"
    buffer.write_bytes(buffer.read_bytes()[:100])
    before = files(run_dir)
    result = train_in_process("--resume", run_dir, "--timesteps", 240)
    assert_one_line_error(result, f"cannot read checkpoint {buffer}: ", "delete it to continue with an empty")
    assert files(run_dir) == before


@pytest.mark.parametrize(
    ("where", "problem"),
    [
        ("notes.txt", "exists and is not a directory"),
        ("notes.txt/runs", "notes.txt is a file, not a directory"),
        ("/proc/nope", "cannot create folders in /proc"),  # tmp_path / "/proc/nope" is /proc/nope
    ],
)
def test_a_runs_dir_where_no_folder_can_be_made_is_refused_up_front(tmp_path, where, problem):
    (tmp_path / "notes.txt").write_text("a user's file")
    before = files(tmp_path)
    result = train_in_process("--env", WALK, "--algo", "ppo", "--timesteps", 128, "--runs-dir", tmp_path / where)
    assert_one_line_error(result, f"--runs-dir {tmp_path / where}", problem)
    assert files(tmp_path) == before


def test_sigterm_saves_a_checkpoint_and_exits_cleanly(tmp_path):
    (tmp_path / "ppo.yml").write_text(TINY_PPO)
    runs = tmp_path / "runs"
    command = [sys.executable, str(ROOT / "train.py"), "--env", WALK, "--algo", "ppo", "--timesteps", "10000000",
               "--checkpoint-freq", "10000000", "--runs-dir", str(runs), "--hyperparams", str(tmp_path / "ppo.yml"),
               "--no-progress"]  # fmt: skip
    # faulthandler: a child that does not end in time is sent SIGABRT, and its threads' stacks come back in stderr
    process = subprocess.Popen([sys.executable, "-X", "faulthandler", *command[1:]], cwd=ROOT, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 60.0
        while not any(runs.glob("*/tb/events.*")) and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(1.0)  # well into learning
        process.send_signal(signal.SIGTERM)
        try:  # a loaded 2-core host (the suite's workers beside a training job) can take long to save and exit
            _, stderr = process.communicate(timeout=150)
        except subprocess.TimeoutExpired:
            process.send_signal(signal.SIGABRT)
            _, stderr = process.communicate(timeout=30)
            pytest.fail(f"train.py did not end within 150 s of SIGTERM; its stacks:\n{stderr}")
    finally:
        process.kill()
    assert process.returncode == 128 + signal.SIGTERM, stderr
    assert "Traceback" not in stderr and "checkpoint saved" in stderr and "continue with" in stderr
    (run_dir,) = runs.iterdir()
    (saved,) = checkpoints(run_dir).values()
    manifest, stats = read_model_file(saved / "model.zip")
    assert manifest["normalized"] and stats is not None
    assert not list((run_dir / "checkpoints").glob(".*")), "no temporary checkpoint folder left behind"


def test_resume_removes_what_a_killed_run_left_half_written(tiny_run, tmp_path):
    run_dir = shutil.copytree(tiny_run, tmp_path / "run")
    stale = run_dir / "checkpoints" / ".step_0000000192.k1ll3d_0"  # tempfile's 8 random characters
    stale.mkdir()
    (stale / "model.zip").write_bytes(b"half a model")
    (run_dir / ".model.k1ll3d_0.tmp.zip").write_bytes(b"half a model")
    result = train_ok("--resume", run_dir, "--timesteps", 192)
    assert "removed what a killed run left half-written" in result.stderr
    assert not stale.exists() and not list(run_dir.glob(".*"))
    assert max(checkpoints(run_dir)) == 192


def test_a_second_train_process_on_a_run_folder_is_refused_while_the_first_runs(tiny_run, tmp_path):
    """Two resumes of one run at once would delete each other's temporary files and overwrite each other's
    checkpoints: the second is refused in one line, before it reads or removes anything, and the first goes on."""
    run_dir = shutil.copytree(tiny_run, tmp_path / "run")
    first = subprocess.Popen(
        [sys.executable, str(ROOT / "train.py"), "--resume", str(run_dir), "--timesteps", "10000000",
         "--checkpoint-freq", "10000000", "--no-progress"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        assert first.stdout.readline().startswith(f"resuming {run_dir}")  # it holds the lock and is training
        config = (run_dir / "config.json").read_bytes()
        stale = run_dir / ".model.k1ll3d_0.tmp.zip"  # a file the second would remove as a killed run's leftover
        stale.write_bytes(b"the first run's")
        for args in (["--resume", run_dir, "--timesteps", 10000000], ["--resume", "run", "--runs-dir", tmp_path]):
            second = train_in_process(*args)  # the lock is the first process's, so refused here just the same
            assert second.returncode == 1 and "Traceback" not in second.stderr, second.stderr
            assert second.stderr.strip() == (
                f"train.py: {run_dir} is in use by another train.py run (lock {run_dir / 'train.lock'}); wait for it "
                "to end, or choose another folder"
            )
            assert not second.stdout
        assert (run_dir / "config.json").read_bytes() == config and stale.read_bytes() == b"the first run's"
        assert first.poll() is None, "the first run goes on"
        deadline = time.monotonic() + 60.0  # SIGTERM once it learns (its logger is set up just before), as a user's
        while not any((run_dir / "tb").glob("events.*")) and time.monotonic() < deadline:  # Ctrl-C mid-run
            time.sleep(0.1)
        time.sleep(1.0)
        first.send_signal(signal.SIGTERM)
        # it saves its checkpoint, then closes its logger and exits: once, on a loaded host, that took over 60 s
        _, stderr = first.communicate(timeout=180)
    finally:
        first.kill()
    assert first.returncode == 128 + signal.SIGTERM and "checkpoint saved" in stderr, stderr
    stale.unlink()
    assert train_ok("--resume", run_dir, "--timesteps", max(checkpoints(run_dir)) + 64).returncode == 0  # released


def test_resume_of_a_folder_that_is_not_a_run_is_refused_before_anything_is_made_in_it(tmp_path):
    folder = tmp_path / "notes"
    folder.mkdir()
    (folder / "mine.txt").write_text("a user's file")
    result = train_in_process("--resume", folder)
    assert_one_line_error(result, f"cannot read {folder / 'config.json'}", "not a run folder")
    assert sorted(p.name for p in folder.iterdir()) == ["mine.txt"]


@pytest.mark.parametrize(("key", "value"), [("n_envs", None), ("timesteps", None), ("timesteps", "lots")])
def test_resume_names_a_bad_field_of_config_json(ppo_run, tmp_path, key, value):
    config = json.loads((ppo_run / "config.json").read_text())
    if value is None:
        config.pop(key)
    else:
        config[key] = value
    (tmp_path / "config.json").write_text(json.dumps(config))
    result = train_in_process("--resume", tmp_path)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert f"config.json: field '{key}' = {value!r}" in result.stderr


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda c: [c], "expected a JSON object of the run's settings, got list"),
        (lambda c: {k: v for k, v in c.items() if k != "soccer"}, "field 'soccer' = None: a self-play run"),
        (lambda c: {**c, "soccer": {**c["soccer"], "match_seconds": "abc"}}, "field 'soccer.match_seconds' = 'abc'"),
        (lambda c: {**c, "algo": "dqn"}, "field 'algo' = 'dqn': expected one of"),
    ],
)
def test_a_damaged_config_json_is_named_before_the_run_folder_is_locked(ppo_run, tmp_path, edit, message):
    config = json.loads((ppo_run / "config.json").read_text())
    config.update(env_id="soccer/bioloid", soccer={"robot": "bioloid", "players_per_team": 1, "match_seconds": 60.0})
    (tmp_path / "config.json").write_text(json.dumps(edit(config)))
    result = train_in_process("--resume", tmp_path)
    assert_one_line_error(result, f"{tmp_path / 'config.json'}: ", message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["config.json"]  # no lock file left in the user's folder


def test_a_bad_thread_cap_is_named_as_itself(tmp_path, monkeypatch):
    monkeypatch.setenv("SKITTER_THREADS", "abc")  # read as train.main starts: in this process as in a new one
    result = train_in_process("--env", WALK, "--algo", "ppo", "--timesteps", 64, "--runs-dir", tmp_path)
    assert result.returncode == 2 and "SKITTER_THREADS='abc'" in result.stderr and "env_kwargs" not in result.stderr
    assert not any(tmp_path.iterdir())


# --- in-process checks of the command line and the hyperparameter file (nothing is trained) -----------------------


def train_main(capsys, *args: object) -> tuple[int, str]:
    """Exit code and stderr of ``train.main`` (in this process: fast), whether it returns or exits."""
    from agents import training as train

    done = main_in_process(train.main, [*map(str, args), "--no-progress"])
    return done.returncode, done.stderr


def assert_refused(code: int, err: str, *expected: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    for text in expected:
        assert text in err, (text, err)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            f"{WALK}:\n  n_steps: 64\n  gamma: 0.9\n  n_steps: 128\n",
            "line 4: duplicate key 'n_steps' (first on line 2)",
        ),
        (f"{WALK}:\n  n_steps: 64\n{WALK}:\n  n_steps: 128\n", f"line 3: duplicate key '{WALK}' (first on line 1)"),
        (f"{WALK}:\n  policy_kwargs: {{net_arch: [8], net_arch: [16]}}\n", "line 2: duplicate key 'net_arch'"),
    ],
)
def test_a_key_given_twice_in_a_hyperparameter_file_is_refused(capsys, tmp_path, text, expected):
    hyperparams = tmp_path / "twice.yml"
    hyperparams.write_text(text)
    args = ["--env", WALK, "--algo", "ppo", "--timesteps", 64, "--runs-dir", tmp_path / "runs"]
    code, err = train_main(capsys, *args, "--hyperparams", hyperparams)
    assert_refused(code, err, f"train.py: error: {hyperparams}: {expected}", "give each key once")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["twice.yml"]


def test_keys_merged_from_an_anchor_may_still_be_overridden(tmp_path):
    from agents import training as train

    hyperparams = tmp_path / "anchors.yml"
    hyperparams.write_text(
        f"defaults: &defaults\n  n_steps: 64\n  gamma: 0.9\n{WALK}:\n  <<: *defaults\n  gamma: 0.99\n"
    )
    assert train.read_yaml(hyperparams)[WALK] == {"n_steps": 64, "gamma": 0.99}
    for shipped in sorted((ROOT / "hyperparams").glob("*.yml")):
        assert train.read_yaml(shipped), shipped  # the shipped files give each key once


@pytest.mark.parametrize("device", ["cuda", "cuda:0"])
def test_a_cuda_device_without_cuda_is_refused_not_run_on_the_cpu(capsys, tmp_path, monkeypatch, device):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    hyperparams = tmp_path / "gpu.yml"
    hyperparams.write_text(f"{WALK}:\n  n_steps: 64\n  device: {device}\n")
    args = ["--env", WALK, "--algo", "ppo", "--timesteps", 64, "--runs-dir", tmp_path / "runs"]
    code, err = train_main(capsys, *args, "--hyperparams", hyperparams)
    assert_refused(code, err, f"{hyperparams}: {WALK}: field 'device' = '{device}': CUDA is not available here")
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("flag", ["--runs-dir", "--resume"])
def test_an_empty_runs_dir_or_resume_is_refused_not_taken_as_the_current_folder(capsys, tmp_path, monkeypatch, flag):
    monkeypatch.chdir(tmp_path)
    code, err = train_main(capsys, "--env", WALK, "--algo", "ppo", "--timesteps", 64, flag, "")
    assert_refused(code, err, f"argument {flag}: expected a folder, got an empty path ''")
    assert not any(tmp_path.iterdir())


def test_a_run_name_given_to_resume_is_looked_up_in_runs_dir(capsys, tmp_path, monkeypatch):
    from agents import training as train

    runs = tmp_path / "elsewhere"
    (runs / "run").mkdir(parents=True)
    assert train.resume_folder("run", str(runs)) == runs / "run"
    monkeypatch.chdir(tmp_path)
    assert train.resume_folder("elsewhere/run", "runs") == Path("elsewhere/run")  # a path is taken as given
    (tmp_path / "here").mkdir()
    before = files(tmp_path)
    code, err = train_main(capsys, "--resume", "here", "--runs-dir", runs)
    assert_refused(code, err, f"--resume here: no run folder {runs / 'here'}", f"--runs-dir {runs}", "--resume ./here")
    code, err = train_main(capsys, "--resume", "nowhere/run")
    assert_refused(code, err, "--resume nowhere/run: does not exist")
    assert files(tmp_path) == before
    # what train.py prints to continue an interrupted run resolves to the same folder
    assert train.resume_argument(Path("runs") / "x") == "runs/x" and train.resume_argument(Path("x")) == "./x"


def test_resume_by_name_in_runs_dir_removes_only_its_own_temporary_files(tiny_run, tmp_path):
    """A killed run's temporary files (atomic_write's ``.<stem>.<8 random>.tmp<suffix>`` beside config.json,
    command.txt and model.zip; save_checkpoint's ``.step_<N>.<8 random>`` folders) go; a user's look-alikes stay."""
    runs = tmp_path / "runs"
    run_dir = shutil.copytree(tiny_run, runs / "mine")
    ours = [run_dir / ".model.ab12_xyz.tmp.zip", run_dir / ".config.0123abcd.tmp.json",
            run_dir / ".command.zz99zz99.tmp.txt"]  # fmt: skip
    for path in ours:
        path.write_bytes(b"half written")
    (run_dir / "checkpoints" / ".step_0000000192.q1w2e3r4").mkdir()
    users = [run_dir / ".notes.tmp.txt", run_dir / ".model.tmp.zip", run_dir / ".config.json.tmp",
             run_dir / ".model.mine.tmp.zip", run_dir / ".results.abcd1234.tmp.csv",
             run_dir / "checkpoints" / ".step_notes"]  # fmt: skip
    for path in users:
        path.write_text("the user's")
    result = train_ok("--resume", "mine", "--runs-dir", runs, "--timesteps", 192)
    assert f"resuming {run_dir} from step_0000000128" in result.stdout and max(checkpoints(run_dir)) == 192
    assert (
        not any(path.exists() for path in ours) and not (run_dir / "checkpoints" / ".step_0000000192.q1w2e3r4").exists()
    )
    assert all(path.read_text() == "the user's" for path in users)
    assert sorted(p.name for p in runs.iterdir()) == ["mine"]


def test_the_leftover_patterns_match_the_writers_own_temporary_names(tmp_path):
    """What resume removes is exactly what atomic_write and save_checkpoint's mkdtemp name their temporary saves."""
    import tempfile

    from agents import training as train
    from envs.common.io import atomic_write, atomic_write_leftovers

    seen = []
    for name in train.RUN_FILES:
        atomic_write(tmp_path / name, lambda tmp: seen.append((tmp, atomic_write_leftovers(tmp_path, train.RUN_FILES))))
    assert [found for _, found in seen] == [[tmp] for tmp, _ in seen]
    assert atomic_write_leftovers(tmp_path, train.RUN_FILES) == []  # written in full: nothing left over
    folder = Path(tempfile.mkdtemp(prefix=".step_0000000064.", dir=tmp_path))  # as save_checkpoint names it
    assert train.UNFINISHED_CHECKPOINT.fullmatch(folder.name)


def test_an_off_policy_minibatch_larger_than_its_replay_buffer_is_refused():
    from agents import training as train

    with pytest.raises(train.ConfigError, match=r"x.yml: field 'batch_size' = 256: larger than the replay buffer"):
        train.resolve_hyperparams({"buffer_size": 100, "batch_size": 256}, "sac", where="x.yml")
    hp = train.resolve_hyperparams({"buffer_size": 256, "batch_size": 256}, "sac", where="x.yml")
    assert hp.model_kwargs["batch_size"] == 256


# A Ctrl-C delivered at a set point of the loading, not after a sleep: a CI run sent it after a 0.3 s sleep and
# found calibrate.py --help already finished (exit 0). The child sends SIGINT to itself as the named library is first
# looked up, so the test no longer races the machine's speed.
_CTRL_C_AT_IMPORT = """
import os, runpy, signal, sys
tool, library = sys.argv[1], sys.argv[2]
class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == library:
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None
sys.meta_path.insert(0, CtrlC())
sys.argv = [tool, "--help"]
runpy.run_path(tool, run_name="__main__")
"""


@pytest.mark.parametrize(
    ("tool", "library"),
    [("train.py", "numpy"), ("train.py", "torch"), ("evaluate.py", "numpy"), ("calibrate.py", "mujoco")],
)
def test_ctrl_c_while_a_tool_loads_its_libraries_is_a_quiet_exit(tool, library):
    """A Ctrl-C in the first seconds (torch, mujoco and SB3 loading) printed a traceback."""
    process = subprocess.run([sys.executable, "-c", _CTRL_C_AT_IMPORT, str(ROOT / tool), library], cwd=ROOT,
                             capture_output=True, text=True, timeout=120)  # fmt: skip
    assert process.returncode == 130 and "Traceback" not in process.stderr and not process.stdout, (
        process.returncode,
        process.stderr[-2000:],
        process.stdout[:200],
    )


@pytest.mark.parametrize("algo", ["ppo", "sac", "td3"])
def test_every_registered_env_has_a_checked_entry_in_the_shipped_hyperparameters(algo):
    """``train.py --env <any skitter id>`` finds its hyperparameters out of the box, and they pass the checks."""
    from agents import training as train

    ids = sorted(env_id for env_id in gym.registry if env_id.startswith("skitter/"))
    assert {"skitter/XjusWalk-v1", "skitter/BioloidWalk-v2"} <= set(ids)
    for env_id in ids:
        hp = train.load_hyperparams(ROOT / "hyperparams" / f"{algo}.yml", env_id, algo)
        assert hp.n_envs >= 1, env_id


@pytest.mark.parametrize("env_id", ["skitter/XjusWalk-v1", "skitter/BioloidWalk-v2"])
def test_ppo_trains_the_later_robots_with_the_shipped_hyperparameters(env_id, tmp_path):
    done = train_in_process("--env", env_id, "--algo", "ppo", "--timesteps", 1, "--n-envs", 2, "--runs-dir", tmp_path)
    assert done.returncode == 0, done.stderr
    # PPO learns whole rollouts: the run says where it ends, up front
    n_steps = yaml.safe_load((ROOT / "hyperparams" / "ppo.yml").read_text())[env_id]["n_steps"]
    rollout = 2 * n_steps
    assert (
        f"whole rollouts of {rollout} steps (2 envs x {n_steps}): this run ends at {rollout} steps, not 1"
        in done.stderr
    )
    (run_dir,) = tmp_path.iterdir()
    assert (run_dir / "model.zip").is_file()
    assert_policy_acts(run_dir / "model.zip", env_id)


def test_the_commands_are_thin_and_nothing_in_the_package_or_benchmarks_imports_them():
    """train.py, evaluate.py and calibrate.py only call the package's main; the package and the benchmarks import
    the package modules, never the root scripts."""
    import ast

    from agents import compare, training
    from sysid import cli

    for script, module in (("train.py", training), ("evaluate.py", compare), ("calibrate.py", cli)):
        tree = ast.parse((ROOT / script).read_text())
        imported = [
            (node.module, [a.name for a in node.names]) for node in tree.body if isinstance(node, ast.ImportFrom)
        ]
        assert imported == [(module.__name__, ["main"])], script
        assert not [node for node in tree.body if isinstance(node, ast.FunctionDef | ast.ClassDef)], script
    for folder in ("agents", "envs", "sysid", "benchmarks"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
                names += [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
                assert not {"train", "evaluate", "calibrate"} & {str(n).split(".")[0] for n in names}, path


def test_one_config_error_and_no_callback_under_sb3s_name():
    """One ConfigError for the trainer and the optimizer; the run's checkpoint callback is not SB3's name."""
    from stable_baselines3.common import callbacks

    from agents import training
    from agents.config import ConfigError
    from agents.optimize import problem

    assert training.ConfigError is ConfigError and problem.ConfigError is ConfigError
    assert issubclass(ConfigError, ValueError)
    assert not hasattr(training, "CheckpointCallback") and not hasattr(callbacks, "RunCheckpointCallback")
    assert issubclass(training.RunCheckpointCallback, callbacks.BaseCallback)


def test_a_time_budget_ends_training_as_finished(tmp_path):
    """--minutes: past the budget, training stops and the run ends as at --timesteps (its model saved), short of the
    timesteps asked for; a budget that is no number of minutes is refused."""
    done = train_in_process("--env", WALK, "--algo", "ppo", "--timesteps", 10**7, "--n-envs", 2, "--minutes", "0.0001",
                            "--runs-dir", tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "time budget" in done.stderr
    (run_dir,) = tmp_path.iterdir()
    manifest, _ = read_model_file(run_dir / "model.zip")
    assert 0 < manifest["num_timesteps"] < 10**7
    refused = train_in_process("--env", WALK, "--algo", "ppo", "--timesteps", 10, "--minutes", "-1",
                               "--runs-dir", tmp_path / "x")  # fmt: skip
    assert refused.returncode == 2 and "--minutes" in refused.stderr


@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_a_buffer_larger_than_the_memory_available_is_refused_before_anything_is_made(capsys, tmp_path, monkeypatch,
                                                                                      algo):  # fmt: skip
    """PPO's rollout buffer holds n_steps x n_envs steps (n_envs 100000 and 512 steps: 51 million) and a replay
    buffer its buffer_size: one that would not fit in the memory available is refused, naming its size."""
    from agents import training as train

    monkeypatch.setattr(train, "available_memory", lambda: 2**30)  # a machine with 1 GiB free
    steps = 64 if algo == "ppo" else 100_000_000  # a replay buffer fills as the run goes: as many steps as it takes
    args = ["--env", WALK, "--algo", algo, "--timesteps", steps, "--runs-dir", tmp_path / "runs"]
    if algo == "ppo":
        size = ["--n-envs", 100_000]
    else:
        (tmp_path / "big.yml").write_text(f"{WALK}:\n  buffer_size: 100000000\n")
        size = ["--hyperparams", tmp_path / "big.yml"]
    code, err = train_main(capsys, *args, *size)
    what = "PPO's rollout buffer (n_steps 512 x n_envs 100000)" if algo == "ppo" else "buffer (buffer_size 100000000)"
    assert_refused(code, err, what, "GiB, more than the 1.0 GiB of memory available")
    assert not (tmp_path / "runs").exists()
    hp = train.load_hyperparams(ROOT / "hyperparams" / f"{algo}.yml", WALK, algo)
    env = gym.make(WALK)
    _, fits = train.buffer_bytes(hp, algo, env.observation_space, env.action_space)
    assert fits < 2**30, "the shipped entry fits"


def test_the_buffer_sizes_checked_are_what_stable_baselines3_allocates():
    import numpy as np
    from stable_baselines3.common.buffers import ReplayBuffer, RolloutBuffer

    from agents import training as train

    env = gym.make(WALK)
    obs, act = env.observation_space, env.action_space
    hp = train.resolve_hyperparams({"n_steps": 100, "n_envs": 4}, "ppo", "x")
    rollout = RolloutBuffer(100, obs, act, n_envs=4)
    held = sum(v.nbytes for v in vars(rollout).values() if isinstance(v, np.ndarray))
    assert train.buffer_bytes(hp, "ppo", obs, act)[1] == held
    hp = train.resolve_hyperparams({"buffer_size": 1000}, "sac", "x")
    replay = ReplayBuffer(1000, obs, act)
    held = sum(v.nbytes for v in vars(replay).values() if isinstance(v, np.ndarray))
    assert train.buffer_bytes(hp, "sac", obs, act)[1] == held
    assert train.buffer_bytes(hp, "sac", obs, act, timesteps=100)[1] == held // 10  # filled as the run goes
