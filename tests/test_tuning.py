"""Hyperparameter tuning (agents/tuning.py): Optuna studies from train.py, in SQLite and in a real PostgreSQL."""

import contextlib
import csv
import glob
import json
import math
import os
import pwd
import shutil
import socket
import subprocess
import tempfile
from pathlib import Path

import optuna
import pytest
import yaml
from stable_baselines3 import PPO

from agents.training import RUN_CODE, load_hyperparams, main, make_env, resolve_hyperparams
from agents.tuning import LOG_STDS, TrialEvalCallback, eval_env, sample_ppo, shipped_params, tune

WALK = "skitter/RoachWalk-v4"
# a tiny entry: 2 envs, episodes of 50 steps (1 s), so that a trial of 256 steps evaluates in a blink
TINY = {"policy": "MlpPolicy", "n_envs": 2, "normalize": True, "env_kwargs": {"max_episode_steps": 50},
        "n_steps": 128, "batch_size": 64}  # fmt: skip


def train_py(*args, cwd: Path, monkeypatch) -> int:
    """train.py's exit status for ``args``, run in this process from ``cwd``."""
    monkeypatch.chdir(cwd)
    return main([str(a) for a in args])


def trials_csv(folder: Path) -> list[dict]:
    with (folder / "trials.csv").open() as f:
        return list(csv.DictReader(f))


def test_a_tiny_study_writes_its_best_entry_and_continues_where_it_stopped(tmp_path, monkeypatch, capsys):
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({WALK: TINY}))
    common = ("--env", WALK, "--algo", "ppo", "--timesteps", 256, "--hyperparams", "tiny.yml", "--runs-dir", "runs",
              "--evaluations", 2, "--eval-episodes", 1)  # fmt: skip
    assert train_py("--tune", 2, *common, cwd=tmp_path, monkeypatch=monkeypatch) == 0
    folder = tmp_path / "runs" / "tuning" / "skitter_RoachWalk-v4__ppo"
    assert [row["state"] for row in trials_csv(folder)] == ["COMPLETE", "COMPLETE"]
    assert (tmp_path / "runs" / "tuning.db").is_file(), "SQLite by default"
    # best.yml is an entry train.py takes as it is, with the drawn values over the file's own
    hp = load_hyperparams(folder / "best.yml", WALK, "ppo")
    study = json.loads((folder / "study.json").read_text())
    assert hp.n_envs == 2 and hp.env_kwargs == {"max_episode_steps": 50}
    assert study["best"]["value"] == max(float(row["value"]) for row in trials_csv(folder))
    assert hp.model_kwargs["learning_rate"] == study["best"]["hyperparams"]["learning_rate"]
    # the first trial plays the entry's own values (PPO's defaults where it sets none), the study's yardstick
    first = trials_csv(folder)[0]
    assert first["user_attrs_shipped"] == "True" and study["shipped"]["trial"] == 0
    assert study["shipped"]["value"] == float(first["value"])
    played = (int(first["params_n_steps"]), int(first["params_batch_size"]), int(first["params_n_epochs"]))
    assert played == (128, 64, 10)
    assert float(first["params_learning_rate"]) == 3e-4 and float(first["params_log_std_init"]) == 0.0
    assert study["shipped"]["moved"] == ["ent_coef: 1e-08 for the entry's 0"], "PPO's 0 lies below the log range"
    assert "The entry's own values (trial 0)" in (folder / "best.yml").read_text()
    assert train_py("--tune", 1, *common, cwd=tmp_path, monkeypatch=monkeypatch) == 0
    rows = trials_csv(folder)
    assert [int(row["number"]) for row in rows] == [0, 1, 2], "the study goes on, keeping its trials"
    assert json.loads((folder / "study.json").read_text())["trials"]["complete"] == 3
    assert [row["user_attrs_shipped"] for row in rows[1:]] == ["", ""], "the entry is played once a study"
    draws = [tuple(v for k, v in sorted(row.items()) if k.startswith("params_")) for row in rows]
    assert draws[2] not in draws[:2], "a command run again draws anew, not the earlier command's trials again"
    # another budget: its trials' returns would not compare with these, so the study refuses it
    longer = [str(a) for a in common]
    longer[longer.index("--timesteps") + 1] = "384"
    assert train_py("--tune", 1, *longer, cwd=tmp_path, monkeypatch=monkeypatch) == 2
    assert "was made with {'timesteps': 256}" in capsys.readouterr().err
    # the same study with other env kwargs (another env): refused before a trial, naming both
    assert train_py("--tune", 1, *common, "--env-kwargs", '{"sensor_noise": false}', cwd=tmp_path,
                    monkeypatch=monkeypatch) == 2  # fmt: skip
    assert "was made with {'env_kwargs': {'max_episode_steps': 50}}" in capsys.readouterr().err
    assert json.loads((folder / "study.json").read_text())["trials"]["complete"] == 3


def test_a_study_can_score_the_tasks_own_metric_and_minimizes_an_error(tmp_path, monkeypatch, capsys):
    turn = "skitter/RoachTurn-v5"
    # episodes of 1.5 s: a turn's yaw-rate error leaves out its first second
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({turn: {**TINY, "env_kwargs": {"max_episode_steps": 75}},
                                                       WALK: TINY}))  # fmt: skip
    common = ("--env", turn, "--algo", "ppo", "--timesteps", 256, "--hyperparams", "tiny.yml", "--runs-dir", "runs",
              "--evaluations", 1, "--eval-episodes", 2)  # fmt: skip
    assert train_py("--tune", 2, *common, "--tune-metric", "yaw_rate_error", cwd=tmp_path, monkeypatch=monkeypatch) == 0
    folder = tmp_path / "runs" / "tuning" / "skitter_RoachTurn-v5__ppo"
    study = json.loads((folder / "study.json").read_text())
    values = [float(row["value"]) for row in trials_csv(folder)]
    assert (study["metric"], study["direction"]) == ("yaw_rate_error", "minimize")
    assert study["best"]["value"] == min(values) and all(0.0 <= v < 20.0 for v in values), "an error in rad/s"
    assert "mean yaw_rate_error" in (folder / "best.yml").read_text()
    # the same study scoring another metric: its values would not compare, so it is refused before a trial
    assert train_py("--tune", 1, *common, cwd=tmp_path, monkeypatch=monkeypatch) == 2
    assert "was made with {'metric': 'yaw_rate_error'}" in capsys.readouterr().err
    # a metric the env does not report: one line naming those it does, and no study
    assert train_py("--tune", 1, *common[:1], WALK, *common[2:], "--tune-metric", "yaw_rate_eror", cwd=tmp_path,
                    monkeypatch=monkeypatch) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "--tune-metric 'yaw_rate_eror': skitter/RoachWalk-v4 reports return, speed," in err, err
    assert len(err.strip().splitlines()) == 1 and not (folder.parent / "skitter_RoachWalk-v4__ppo").exists()


def test_a_trial_scores_the_mean_of_its_evaluation_episodes_metric():
    hp = resolve_hyperparams(TINY, "ppo", "tiny")
    study = optuna.create_study(direction="maximize")
    venv, evaluation = make_env(WALK, hp, 0), eval_env(WALK, hp, RUN_CODE)
    model = PPO(env=venv, seed=0, device="cpu", **hp.model_kwargs)
    callback = TrialEvalCallback(study.ask(), evaluation, eval_freq=128, n_eval_episodes=3, metric="speed")
    model.learn(128, callback=callback)
    ended = callback._ended
    assert callback.reported == 1 and len(ended) == 3, "one evaluation of three episodes, each seen at its end"
    speeds = [info["distance"] / info["elapsed"] for info in ended]
    assert callback.last_score == pytest.approx(sum(speeds) / 3)
    assert callback.last_score != pytest.approx(callback.last_mean_reward), "the speed, not the return"


def test_ppo_trials_draw_the_initial_exploration_unless_the_entrys_residual_sets_it():
    study = optuna.create_study()
    trial = study.ask()
    drawn = sample_ppo(trial, 2, 1000)
    assert trial.params["log_std_init"] in LOG_STDS
    hp = resolve_hyperparams({**TINY, **drawn}, "ppo", "t")
    assert hp.model_kwargs["policy_kwargs"]["log_std_init"] == trial.params["log_std_init"]
    kept = sample_ppo(study.ask(), 2, 1000, exploring=False)
    hp = resolve_hyperparams({**TINY, "residual": {"policy": "tripod", "exploration": 0.1}, **kept}, "ppo", "t")
    assert hp.model_kwargs["policy_kwargs"]["log_std_init"] == pytest.approx(math.log(0.1))


PPO_DEFAULTS = RUN_CODE.algo_defaults("ppo")


def test_the_entrys_own_values_are_played_as_near_as_the_space_allows():
    """A value the space lacks takes the nearest choice (on a log scale), a number outside a range its nearest end, a
    schedule a draw; each is said, as is a rollout cut to the trial's budget."""
    entry = {**TINY, "n_epochs": 7, "gamma": 0.97, "learning_rate": "lin_3e-4", "ent_coef": 0.5,
             "policy_kwargs": "dict(net_arch=[100, 100], log_std_init=-1.5)"}  # fmt: skip
    params, moved = shipped_params("ppo", resolve_hyperparams(entry, "ppo", "t"), 1000, True, PPO_DEFAULTS)
    assert (params["n_epochs"], params["gamma"], params["ent_coef"], params["net_width"]) == (5, 0.98, 1e-2, 128)
    assert params["log_std_init"] in (-2.0, -1.0) and "learning_rate" not in params
    assert "learning_rate: drawn (the entry's is not a plain number)" in moved
    assert "n_epochs: 5 for the entry's 7" in moved and "ent_coef: 0.01 for the entry's 0.5" in moved
    assert "n_steps: 500 (the draw 128 cut to the budget)" not in moved, "128 an env fits 1000 steps of 2 envs"
    _, cut = shipped_params("ppo", resolve_hyperparams({**TINY, "n_steps": 1024}, "ppo", "t"), 1000, True,
                            PPO_DEFAULTS)  # fmt: skip
    assert "n_steps: 500 (the draw 1024 cut to the budget)" in cut


def test_a_trial_below_the_pruners_bar_stops_training():
    hp = resolve_hyperparams(TINY, "ppo", "tiny")
    study = optuna.create_study(direction="maximize", pruner=optuna.pruners.ThresholdPruner(lower=1e12))
    trial = study.ask()
    venv, evaluation = make_env(WALK, hp, 0), eval_env(WALK, hp, RUN_CODE)
    model = PPO(env=venv, seed=0, device="cpu", **hp.model_kwargs)
    callback = TrialEvalCallback(trial, evaluation, eval_freq=64, n_eval_episodes=1)
    model.learn(1024, callback=callback)
    assert callback.pruned and callback.reported == 1
    assert model.num_timesteps < 1024, "training stops at the first evaluation"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--algo", "td3"), "--tune tunes ppo and sac, not td3"),
        (("--algo", "ppo", "--storage", "no-url"), "--storage 'no-url': expected a database URL"),
        (("--algo", "ppo", "--storage", "postgresql://nobody:s3cret@127.0.0.1:9/none"), "cannot open the study"),
        # 128 steps on RoachWalk's 4 envs are 32 in each: an evaluation at every step is no study
        (("--algo", "ppo", "--evaluations", 1000), "--evaluations 1000: a trial of 128 steps on 4 envs takes 32"),
    ],
)
def test_bad_tuning_input_is_a_one_line_error(tmp_path, monkeypatch, capsys, args, message):
    argv = ("--tune", 1, "--env", WALK, "--timesteps", 128, "--runs-dir", "runs", *args)
    try:
        status = train_py(*argv, cwd=tmp_path, monkeypatch=monkeypatch)
    except SystemExit as exc:  # refused by the argument parser
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and message in err and "Traceback" not in err, err
    assert "s3cret" not in err and len(err.strip().splitlines()) == 1, "one line, and no password"
    assert not (tmp_path / "runs").exists(), "nothing written, not even the runs folder"


@pytest.mark.parametrize(("args", "message"), [
    (("--study", "x"), "--study goes with --tune"),
    (("--evaluations", 3), "--evaluations goes with --tune"),  # not a normal run that ignores it
    (("--eval-episodes", 3), "--eval-episodes goes with --tune"),
    (("--tune-metric", "speed"), "--tune-metric goes with --tune"),
    (("--tune", 1, "--run-name", "foo"), "--run-name is for one training run"),  # not a study that ignores it
    (("--tune", 1, "--checkpoint-freq", 64), "--checkpoint-freq is for one training run"),
])  # fmt: skip
def test_tuning_options_and_run_options_are_not_mixed(tmp_path, monkeypatch, capsys, args, message):
    with pytest.raises(SystemExit) as exited:
        train_py("--env", WALK, "--algo", "ppo", "--timesteps", 128, *args, cwd=tmp_path, monkeypatch=monkeypatch)
    assert exited.value.code == 2 and message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


def _server_binaries() -> tuple[str, str] | None:
    """initdb and pg_ctl of this machine's PostgreSQL, if it has one."""
    for folder in [os.path.dirname(shutil.which("initdb") or ""), *sorted(glob.glob("/usr/lib/postgresql/*/bin"))]:
        initdb, pg_ctl = Path(folder, "initdb"), Path(folder, "pg_ctl")
        if folder and initdb.is_file() and pg_ctl.is_file():
            return str(initdb), str(pg_ctl)
    return None


@contextlib.contextmanager
def postgresql_server():
    """A PostgreSQL server of its own on loopback, in a temporary folder, stopped and removed after: yields its URL.
    As root, the server runs as the ``postgres`` user (PostgreSQL refuses to run as root)."""
    binaries = _server_binaries()
    if binaries is None:
        pytest.skip("no PostgreSQL server binary (initdb, pg_ctl) on this machine: apt install postgresql")
    initdb, pg_ctl = binaries
    user = None
    if os.geteuid() == 0:
        user = next((name for name in ("postgres", "nobody") if _has_user(name)), None)
        if user is None:
            pytest.skip("running as root with no unprivileged user for the PostgreSQL server")
    folder = Path(tempfile.mkdtemp(prefix="skitter-pg-"))
    if user is not None:
        os.chown(folder, pwd.getpwnam(user).pw_uid, -1)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    data = folder / "data"

    def run(*args: str) -> None:
        subprocess.run(args, user=user, check=True, capture_output=True, timeout=120)

    try:
        run(initdb, "-D", str(data), "-U", "skitter", "--auth=trust", "-E", "UTF8")
        run(pg_ctl, "-D", str(data), "-l", str(folder / "log"), "-w", "start",
            "-o", f"-p {port} -h 127.0.0.1 -k {folder} -c fsync=off")  # fmt: skip
        try:
            yield f"postgresql://skitter@127.0.0.1:{port}/postgres"
        finally:
            run(pg_ctl, "-D", str(data), "-m", "immediate", "-w", "stop")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _has_user(name: str) -> bool:
    try:
        pwd.getpwnam(name)
    except KeyError:
        return False
    return True


def test_two_workers_share_one_study_in_postgresql(tmp_path):
    """Two processes' worth of trials (two seeds) go into one study on a real PostgreSQL server; the study holds
    both, and a third reader sees them."""
    with postgresql_server() as url:
        for seed in (0, 1):
            tune(RUN_CODE, WALK, "ppo", TINY, "tiny", 1, 256, tmp_path / "runs", storage=url, study="shared", seed=seed,
                 evaluations=1, eval_episodes=1)  # fmt: skip
        study = optuna.load_study(study_name="shared", storage=url)
        assert [t.state.name for t in study.trials] == ["COMPLETE", "COMPLETE"]
        summary = json.loads((tmp_path / "runs" / "tuning" / "shared" / "study.json").read_text())
        assert summary["storage"].startswith("postgresql://skitter@127.0.0.1")
        assert summary["trials"]["complete"] == 2


def test_a_study_stopped_by_ctrl_c_says_so_in_one_line_and_keeps_its_trials(tmp_path, monkeypatch, capsys, caplog):
    """Ctrl-C in a trial: no traceback (Optuna logs a failed trial's), one line saying where the study is, exit 130;
    the study's files are written and the stopped trial counts as failed."""
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({WALK: TINY}))

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(PPO, "learn", interrupted)
    with caplog.at_level("WARNING", logger="optuna"):
        status = train_py("--tune", 2, "--env", WALK, "--algo", "ppo", "--timesteps", 256, "--hyperparams", "tiny.yml",
                          "--runs-dir", "runs", cwd=tmp_path, monkeypatch=monkeypatch)  # fmt: skip
    err = capsys.readouterr().err
    assert status == 130 and "Traceback" not in err and "interrupted: study skitter_RoachWalk-v4__ppo" in err, err
    assert not [r for r in caplog.records if "failed" in r.getMessage()], "Optuna's failed-trial warnings are dropped"
    assert [row["state"] for row in trials_csv(tmp_path / "runs" / "tuning" / "skitter_RoachWalk-v4__ppo")] == ["FAIL"]


def test_a_diverged_trial_is_failed_and_the_study_goes_on_but_another_fault_is_shown(tmp_path, monkeypatch, capsys):
    """torch's refusal of a NaN action distribution fails that trial alone; any other ValueError in training is a
    fault in the code or the env, raised rather than recorded as a trial's bad luck."""
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({WALK: TINY}))
    message = "Expected parameter loc (Tensor of shape (2, 4)) of distribution Normal(...) to satisfy the constraint "
    faults = iter([ValueError(message + "Real(), but found invalid values:\ntensor([[nan]])"), None])

    def learn(self, *args, **kwargs):
        fault = next(faults)
        if fault is not None:
            raise fault
        return self

    monkeypatch.setattr(PPO, "learn", learn)
    argv = ("--env", WALK, "--algo", "ppo", "--timesteps", 256, "--hyperparams", "tiny.yml", "--runs-dir", "runs")
    assert train_py("--tune", 2, *argv, cwd=tmp_path, monkeypatch=monkeypatch) == 0
    folder = tmp_path / "runs" / "tuning" / "skitter_RoachWalk-v4__ppo"
    # the second trial ran on (its stand-in learn evaluates nothing, so it is pruned unscored)
    assert [row["state"] for row in trials_csv(folder)] == ["FAIL", "PRUNED"]

    def broken(self, *args, **kwargs):
        raise ValueError("operands could not be broadcast together with shapes (2,) (3,)")

    monkeypatch.setattr(PPO, "learn", broken)
    with pytest.raises(ValueError, match="could not be broadcast"):
        train_py("--tune", 1, *argv, cwd=tmp_path, monkeypatch=monkeypatch)
