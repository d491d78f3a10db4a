"""The leaderboard (agents/leaderboard.py), end to end on a tiny budget: tune, train, evaluate, table."""

import contextlib
import dataclasses
import json
import shutil
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from agents import leaderboard
from agents.training import main as train_main
from envs.common import host

ROOT = Path(__file__).resolve().parents[1]

WALK = "skitter/RoachWalk-v4"
XJUS = "skitter/XjusWalk-v1"


@pytest.fixture(autouse=True)
def _fewer_bootstrap_draws(monkeypatch):
    """The tables' intervals from 200 bootstrap draws, not the published 2000: the same code at a tenth of its time
    (rliable's bootstraps are nearly all of a table's)."""
    monkeypatch.setattr(leaderboard, "BOOTSTRAP_REPS", 200)


TINY = {"policy": "MlpPolicy", "n_envs": 2, "normalize": True, "env_kwargs": {"max_episode_steps": 50},
        "n_steps": 128, "batch_size": 64}  # fmt: skip


@pytest.mark.slow  # a minute: seven starts of train.py and evaluate.py; make leaderboard runs the same code
def test_the_whole_pipeline_on_a_tiny_budget(tmp_path, monkeypatch, capsys):
    """Two tuning trials write a best entry; the leaderboard trains two seeds with it, evaluates them and the
    reference and a random policy on the same seeds, and writes the table; a second command reruns nothing, and
    --rerun computes one row again."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({WALK: TINY}))
    tuning = ["--tune", "2", "--env", WALK, "--algo", "ppo", "--timesteps", "256", "--hyperparams", "tiny.yml",
              "--runs-dir", "runs", "--evaluations", "1", "--eval-episodes", "1"]  # fmt: skip
    assert train_main(tuning) == 0
    best = tmp_path / "runs" / "tuning" / "skitter_RoachWalk-v4__ppo" / "best.yml"
    out, docs = tmp_path / "board", tmp_path / "docs" / "results.md"
    argv = ["--tasks", WALK, "--algos", "ppo", "--seeds", "0", "1", "--timesteps", "256", "--episodes", "2",
            "--max-episode-steps", "50", "--hyperparams", str(best), "--videos", "--out", str(out), "--docs",
            str(docs), "--records", str(tmp_path / "kept")]  # fmt: skip
    assert leaderboard.main(argv) == 0
    summary = json.loads((out / "results.json").read_text())
    rows = summary["rows"]
    assert sorted(rows) == ["skitter_RoachWalk-v4__ppo__0", "skitter_RoachWalk-v4__ppo__1"]
    base = summary["baselines"][WALK]
    assert base["reference"] == "tripod" and base["reference_return"] > base["random_return"]
    assert base["host"]["numpy_simd"] == host.numpy_simd()  # where the reference and random were played
    for record in rows.values():
        assert record["timesteps"] >= 256 and len(record["returns"]) == 2
        assert record["software"]["torch"] == metadata.version("torch")  # what its training ran on
        assert record["software"]["torch_cpu"] == torch.backends.cpu.get_cpu_capability()  # and its code paths
        assert record["software"]["numpy_simd"] == host.numpy_simd()
        score = (record["mean_return"] - base["random_return"]) / (base["reference_return"] - base["random_return"])
        assert np.isfinite(score)
    cell = summary["per_task"][WALK]["ppo"]
    assert cell["low"] <= cell["iqm"] <= cell["high"]
    assert set(summary["overall"]) == {"ppo"}
    text = docs.read_text()
    assert "| `skitter/RoachWalk-v4` | tripod |" in text and "--rerun" in (out / "results.json").read_text()
    assert text.startswith(leaderboard.PAGE_START) and leaderboard.docs_problem(docs) is None  # its own: replaceable
    for plot in ("performance_profiles.png", "curve_skitter_RoachWalk-v4.png"):
        assert (out / "plots" / plot).stat().st_size > 5_000
    video = out / "videos" / "skitter_RoachWalk-v4" / "eval" / "videos" / "side_by_side.mp4"
    assert video.stat().st_size > 10_000 and "side_by_side.mp4" in (out / "results.md").read_text()
    # the page's media beside it (the leaderboard's folder is a run's output, not a checkout's)
    media = docs.parent / "results"
    assert (media / "videos" / "skitter_RoachWalk-v4.mp4").read_bytes() == video.read_bytes()
    assert "](results/videos/skitter_RoachWalk-v4.mp4)" in text and "](results/plots/performance_profiles.png)" in text
    assert (media / "plots" / "performance_profiles.png").is_file()
    for record in rows.values():  # trained in seconds: its policy after an hour is its final model
        assert record["one_hour"]["final"] and record["one_hour"]["timesteps"] == record["timesteps"]
    assert "## After an hour of training" in text and "(its final model)" in text
    log = out / "rows" / "skitter_RoachWalk-v4__ppo__0" / "log.txt"  # where a row's training says how far it is
    assert f"skitter_RoachWalk-v4__ppo__0: training, to 256 steps; its progress is in {log}" in capsys.readouterr().out
    # again: every row is done, nothing trains
    assert leaderboard.main(argv) == 0
    assert "(0 to run)" in capsys.readouterr().out
    # one row again, from nothing, with the same seeds: the same model, so the same evaluation
    kept = rows["skitter_RoachWalk-v4__ppo__1"]["returns"]
    assert leaderboard.main([*argv, "--rerun", f"{WALK}:ppo:1"]) == 0
    again = json.loads((tmp_path / "kept" / "rows" / "skitter_RoachWalk-v4__ppo__1" / "row.json").read_text())
    assert "(1 to run)" in capsys.readouterr().out
    assert again["returns"] == pytest.approx(kept)
    assert again["reproduction"]["within"] and again["reproduction"]["again"]["value"] == pytest.approx(
        rows["skitter_RoachWalk-v4__ppo__1"]["mean_return"]
    )
    # the same folder with another budget: refused, naming the row, before anything runs
    other = [*argv]
    other[other.index("--timesteps") + 1] = "512"
    assert leaderboard.main(other) == 2
    assert "was made with" in capsys.readouterr().err


@pytest.fixture
def ray_head(tmp_path):
    """A Ray cluster of one node on loopback, started as a user starts one (``ray start --head``) with token
    authentication (the token in a file of its own, ``RAY_AUTH_TOKEN_PATH``), and stopped after: its address and the
    environment a user's command runs in. Only this head is stopped (``ray stop`` would stop every Ray instance of
    the user)."""
    import os
    import secrets
    import socket
    import subprocess
    import sys
    import tempfile
    import time

    def free_port() -> int:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            return s.getsockname()[1]

    port = free_port()
    temp = Path(tempfile.mkdtemp(prefix="ray"))  # short: Ray's socket paths must fit in 107 characters
    log = tmp_path / "ray_head.log"
    command = [str(Path(sys.executable).with_name("ray")), "start", "--head", "--block", "--node-ip-address",
               "127.0.0.1", "--port", str(port), "--ray-client-server-port", str(free_port()), "--num-cpus", "2",
               "--include-dashboard", "false", "--disable-usage-stats", "--temp-dir", str(temp)]  # fmt: skip
    token = temp / "auth_token"
    token.write_text(secrets.token_hex(32))
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")} | {"RAY_AUTH_TOKEN_PATH": str(token)}
    with log.open("w") as out:
        head = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT, env=env)
    try:
        deadline = time.monotonic() + 120
        while "Ray runtime started" not in log.read_text() and head.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert head.poll() is None and "Ray runtime started" in log.read_text(), log.read_text()
        assert "Token authentication is enabled" in log.read_text()
        yield f"127.0.0.1:{port}", env
    finally:
        import ray

        ray.shutdown()
        head.terminate()
        head.wait(timeout=60)
        shutil.rmtree(temp, ignore_errors=True)


@pytest.mark.slow  # a minute: a Ray head, a row on it and the same row here (make leaderboard --address runs it)
@pytest.mark.xdist_group("ray")
def test_rows_run_on_a_ray_cluster_as_they_run_here(tmp_path, monkeypatch, ray_head):
    """``--address``: the command (run as a user runs it, token and all) sends its rows as Ray tasks to the cluster
    there (here a head started on loopback); they give the records that the same rows give in this process, bit
    for bit (the same seeds, the same models)."""
    import subprocess
    import sys

    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({WALK: TINY}))
    plan = ["--tasks", WALK, "--algos", "ppo", "--seeds", "0", "--timesteps", "256", "--episodes", "2",
            "--max-episode-steps", "50", "--hyperparams", str(tmp_path / "tiny.yml")]  # fmt: skip
    assert leaderboard.main([*plan, "--out", str(tmp_path / "here")]) == 0
    address, env = ray_head  # RAY_AUTH_MODE unset, as a user's: the command sends the token it finds
    done = subprocess.run([sys.executable, "-m", "agents.leaderboard", *plan, "--out", str(tmp_path / "ray"),
                           "--address", address], cwd=ROOT, capture_output=True, text=True, timeout=600,
                          env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    assert f"on Ray at {address}" in done.stdout
    here, there = (json.loads((tmp_path / out / "results.json").read_text()) for out in ("here", "ray"))
    row = "skitter_RoachWalk-v4__ppo__0"
    assert there["rows"][row]["returns"] == here["rows"][row]["returns"]
    assert there["rows"][row]["timesteps"] == here["rows"][row]["timesteps"] >= 256
    assert (tmp_path / "ray" / "runs" / row / "model.zip").is_file(), "the task wrote into the command's folder"


ACADEMY = "skitter/BioloidGoToBall-v4"


def test_an_academy_task_is_learnt_and_judged_in_the_commands_mode_against_the_scripted_player():
    """A soccer academy task's rows train and evaluate in the commands mode (the scripted player's), and the
    commands that reproduce a row say so; a walk's rows make their env as it is registered."""
    assert leaderboard.task_kwargs(ACADEMY) == {"action_mode": "commands"} and leaderboard.task_kwargs(WALK) == {}
    assert leaderboard.reference_name(ACADEMY) == "scripted" and leaderboard.reference_name(WALK) == "tripod"
    plan = leaderboard.Plan((ACADEMY,), ("ppo+residual",), (0,), ((ACADEMY, 100),), None, 2, 1000, None)
    train, evaluate = leaderboard.reproduce(plan, leaderboard.Row(ACADEMY, "ppo+residual", 0), 100, "scripted")
    for command in (train, evaluate):
        assert """--env skitter/BioloidGoToBall-v4 --env-kwargs '{"action_mode": "commands"}'""" in command
    assert "--residual reference" in train and "--policy scripted" in evaluate


@pytest.mark.slow  # a minute: train.py and evaluate.py three times on a soccer academy task
def test_an_academy_row_trains_a_residual_on_the_scripted_player_and_is_judged_against_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tiny = {**TINY, "env_kwargs": {"max_episode_steps": 50}}
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({ACADEMY: tiny}))
    out = tmp_path / "board"
    argv = ["--tasks", ACADEMY, "--algos", "ppo+residual", "--seeds", "0", "--timesteps", "256", "--episodes", "2",
            "--max-episode-steps", "50", "--hyperparams", "tiny.yml", "--out", str(out)]  # fmt: skip
    assert leaderboard.main(argv) == 0
    summary = json.loads((out / "results.json").read_text())
    assert summary["baselines"][ACADEMY]["reference"] == "scripted"
    (record,) = summary["rows"].values()
    assert record["reference"] == "scripted" and len(record["returns"]) == 2
    config = json.loads((out / "runs" / record["row"] / "config.json").read_text())
    assert config["hyperparams"]["env_kwargs"] == {"max_episode_steps": 50, "action_mode": "commands"}
    assert config["hyperparams"]["residual"]["policy"] == "scripted"


def test_bad_leaderboard_input_is_refused_before_anything_runs(tmp_path, capsys):
    for argv, message in (
        (["--tasks", "skitter/Nope-v1", "--timesteps", "10"], "unknown env"),
        (["--tasks", "CartPole-v1", "--timesteps", "10"], "'CartPole-v1' is not a skitter env"),
        (["--tasks", WALK, "--timesteps", "0"], "--timesteps '0': must be at least 1, got 0"),
        (["--tasks", WALK, XJUS, "--timesteps", f"{XJUS}=abc", f"{WALK}=1"], f"--timesteps '{XJUS}=abc': expected"),
        (["--tasks", WALK, WALK, "--timesteps", "10"], "must not repeat a task"),
        (["--tasks", WALK, "--timesteps", "ten"], "expected a whole number"),
        (["--tasks", WALK, XJUS, "--timesteps", f"{WALK}=10"], f"no budget for {XJUS}"),
        (["--tasks", WALK, "--timesteps", f"{WALK}=10", "skitter/NoSuch-v1=10"], "unknown task 'skitter/NoSuch-v1'"),
        (["--tasks", WALK, "--timesteps", f"{WALK}=10", f"{WALK}=20"], "given twice"),
        (["--tasks", WALK, XJUS, "--timesteps", "10", "20"], "TASK=N for every task"),
        (["--tasks", WALK, "--timesteps", "10", "--rerun", "x"], "expected TASK:ALGO:SEED"),
        (["--tasks", WALK, "--timesteps", "10", "--seeds", "0", "-1"], "seeds must be whole numbers >= 0, got -1"),
        (["--tasks", WALK, "--timesteps", "10", "--hyperparams", str(tmp_path / "none.yml")], "no such file"),
        (["--tasks", WALK, "--timesteps", "10", "--minutes", "inf"], "--minutes must be a positive number"),
        (["--tasks", WALK, "--timesteps", "10", "--records", ""], "--records '' is the current folder"),
    ):
        with pytest.raises(SystemExit) as exited:
            leaderboard.main([*argv, "--out", str(tmp_path / "b")])
        assert exited.value.code == 2 and message in capsys.readouterr().err
    here = tmp_path / "here"
    here.mkdir()
    for out, message in (("", "--out '' is the current folder"), (".", "--out '.' is the current folder"),
                         ("..", "--out '..' is the current folder or holds it")):  # fmt: skip
        with pytest.raises(SystemExit) as exited, contextlib.chdir(here):
            leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--out", out])
        assert exited.value.code == 2 and message in capsys.readouterr().err
    assert not any(here.iterdir()) and sorted(p.name for p in tmp_path.iterdir()) == ["here"]
    assert leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--rerun", f"{WALK}:sac:0", "--out",
                             str(tmp_path / "b")]) == 2  # fmt: skip
    assert "not a row of this plan" in capsys.readouterr().err
    # a cluster address that is not one, or where nothing answers: refused at once (Ray would retry it for minutes)
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        closed = s.getsockname()[1]  # nothing listens on it once the socket is closed
    for address, message in (("head-node", "expected HOST:PORT"), (f"127.0.0.1:{closed}", "nothing answers there")):
        assert leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--address", address, "--out",
                                 str(tmp_path / "b")]) == 2  # fmt: skip
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "b").exists()


def test_baselines_of_other_settings_are_refused_with_a_remedy_that_works(tmp_path, capsys):
    """A task's baselines made under other settings (another --episodes) cannot be computed again with --rerun,
    which takes rows: the message says to give another --out or those settings; a stale row is told --rerun."""
    out = tmp_path / "b"
    path = leaderboard.task_file(out, WALK)
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"settings": {"episodes": 2}}))
    argv = [
        "--tasks",
        WALK,
        "--algos",
        "ppo",
        "--seeds",
        "0",
        "--timesteps",
        "10",
        "--episodes",
        "3",
        "--out",
        str(out),
    ]
    assert leaderboard.main(argv) == 2
    err = capsys.readouterr().err
    assert "give another --out" in err and "--rerun" not in err, err
    path.unlink()
    row = leaderboard.row_file(out, leaderboard.Row(WALK, "ppo", 0))
    row.parent.mkdir(parents=True)
    row.write_text(json.dumps({"settings": {"episodes": 2}}))
    assert leaderboard.main(argv) == 2
    assert "give --rerun for it" in capsys.readouterr().err


def test_a_docs_page_that_is_not_the_leaderboards_own_is_refused_before_anything_runs(tmp_path, capsys):
    """``--docs`` replaces a page this command wrote (docs/results.md), never a user's file, and never traces back
    on a folder or a path under a file."""
    notes = tmp_path / "notes.md"
    notes.write_text("my own notes\n")
    (tmp_path / "folder.md").mkdir()
    (tmp_path / "file").write_text("a file")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "mine.txt").write_text("a user's")
    for docs, message in (
        (notes, "exists and is not a page this command wrote"),
        (tmp_path / "folder.md", "is a folder"),
        (tmp_path / "file" / "page.md", "is a file, not a directory"),
        (tmp_path / "page.txt", "give a path ending in .md"),
        (tmp_path / "other.md", "holds other files than a page's plots and videos"),
    ):
        with pytest.raises(SystemExit) as exited:
            leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--table-only", "--out", str(tmp_path / "b"),
                              "--docs", str(docs)])  # fmt: skip
        err = capsys.readouterr().err
        assert exited.value.code == 2 and f"--docs {docs}: " in err and message in err and "Traceback" not in err, err
    assert notes.read_text() == "my own notes\n" and not (tmp_path / "b").exists() and not (tmp_path / "notes").exists()
    # the leaderboard's own page, as make leaderboard-table writes it, is taken
    page = tmp_path / "results.md"
    page.write_text((ROOT / "docs" / "results.md").read_text())
    assert leaderboard.docs_problem(page) is None and leaderboard.docs_problem(tmp_path / "new" / "page.md") is None


def test_an_out_or_records_folder_nothing_can_be_made_in_is_refused_before_anything_runs(tmp_path, capsys):
    (tmp_path / "file").write_text("a user's file")
    for flag in ("--out", "--records"):
        argv = ["--tasks", WALK, "--timesteps", "10", "--out", str(tmp_path / "b"), flag, str(tmp_path / "file" / "x")]
        with pytest.raises(SystemExit) as exited:
            leaderboard.main(argv)
        err = capsys.readouterr().err
        assert exited.value.code == 2 and f"{flag} {tmp_path / 'file' / 'x'}: " in err and "is a file" in err, err
    with pytest.raises(SystemExit) as exited:  # a table is written here: nothing goes to a cluster
        leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--out", str(tmp_path / "b"), "--table-only",
                          "--address", "notahost:6379"])  # fmt: skip
    assert exited.value.code == 2 and "--table-only trains nothing" in capsys.readouterr().err
    assert not (tmp_path / "b").exists() and (tmp_path / "file").read_text() == "a user's file"


def test_a_hyperparameter_entry_train_py_would_refuse_is_refused_before_anything_runs(tmp_path, capsys):
    bad = tmp_path / "ppo.yml"
    bad.write_text(f'{WALK}:\n  n_envs: "four"\n')
    assert leaderboard.main(["--tasks", WALK, "--timesteps", "10", "--seeds", "0", "--out", str(tmp_path / "b"),
                             "--hyperparams", str(bad)]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert str(bad) in err and "n_envs" in err and "four" in err, err
    assert not (tmp_path / "b").exists()


def test_a_budget_per_task_reaches_its_rows_and_the_command_that_reproduces_them():
    args = leaderboard.parse_args(["--tasks", WALK, XJUS, "--timesteps", f"{XJUS}=3_000", f"{WALK}=1000"])
    assert args.timesteps == ((WALK, 1000), (XJUS, 3000))
    alone = leaderboard.parse_args(["--tasks", XJUS, "--timesteps", f"{WALK}=1000", f"{XJUS}=3000"])
    assert alone.timesteps == ((XJUS, 3000),)  # the Makefile's budgets serve a run of one of their tasks
    plan = leaderboard.Plan(tuple(args.tasks), ("ppo",), (0,), args.timesteps, None, 5, 1000, None)
    assert plan.row_settings(XJUS)["timesteps"] == 3000 and plan.row_settings(WALK)["timesteps"] == 1000
    again = leaderboard.parse_args(leaderboard.plan_arguments(plan))
    assert again.timesteps == args.timesteps
    same = leaderboard.parse_args(["--tasks", WALK, XJUS, "--timesteps", "500"])
    assert same.timesteps == ((WALK, 500), (XJUS, 500))
    assert "--timesteps 500 " in " ".join(
        leaderboard.plan_arguments(dataclasses.replace(plan, timesteps=same.timesteps))
    )


def test_the_table_normalizes_to_random_and_reference_and_lists_rows_not_run(tmp_path):
    """Rows made up of returns: a task's score is 0 at the random policy's return and 1 at the reference's; the IQM
    of three seeds lies in its interval; a row not run says so, and its algorithm gets no overall score."""
    plan = leaderboard.Plan((WALK, XJUS), ("ppo", "sac"), (0, 1, 2), ((WALK, 100), (XJUS, 100)), None, 5, 1000, None)
    baselines = {t: {"reference": "gait", "reference_return": 110.0, "random_return": 10.0} for t in plan.tasks}
    rows = {}
    for row in plan.rows:
        if row.algo == "sac" and row.seed == 2 and row.task == WALK:
            rows[row] = None
            continue
        ret = 10.0 + 100.0 * (0.5 + 0.25 * row.seed)  # normalized 0.5, 0.75, 1.0
        rows[row] = {"mean_return": ret, "timesteps": 100, "capped": False, "paired_differences": {}}
    summary = leaderboard.build_table(plan, tmp_path, baselines, rows, tmp_path / "results.md")
    cell = summary["per_task"][WALK]["ppo"]
    assert cell["iqm"] == pytest.approx(0.75) and cell["low"] <= 0.75 <= cell["high"]
    assert set(summary["overall"]) == {"ppo"}, "sac misses a row: no score over all tasks"
    text = (tmp_path / "results.md").read_text()
    assert "| skitter_RoachWalk-v4__sac__2 | not run |" in text
    assert leaderboard.normalized(10.0, baselines[WALK]) == 0.0
    assert leaderboard.normalized(110.0, baselines[WALK]) == 1.0
    assert "(2 of 3 seeds)" in text
    # where each task's reference and random were played: neither baseline here records it
    assert f"- not recorded (played before the records kept them): `{WALK}`, `{XJUS}`." in text
    played = {**baselines, XJUS: {**baselines[XJUS], "host": {"numpy_simd": "X86_V3", "cpu": "some"}}}
    leaderboard.build_table(plan, tmp_path, played, rows, None)
    text = (tmp_path / "results.md").read_text()
    assert (
        f"- numpy X86_V3: `{XJUS}`." in text
        and f"not recorded (played before the records kept them): `{WALK}`." in text
    )
    # a task whose reference is no better than random: not normalized, and said so
    xjus = "skitter/XjusWalk-v1"
    flat = {**baselines, xjus: {"reference": "gait", "reference_return": 5.0, "random_return": 5.0}}
    summary = leaderboard.build_table(plan, tmp_path, flat, rows, None)
    assert xjus not in summary["per_task"] and np.isnan(leaderboard.normalized(7.0, flat[xjus]))
    assert f"no better than random there): `{xjus}`" in (tmp_path / "results.md").read_text()
    # one whose reference beats random by a small share of its return: the page says a score there magnifies
    narrow = {**baselines, xjus: {"reference": "gait", "reference_return": 110.0, "random_return": 100.0}}
    leaderboard.build_table(plan, tmp_path, narrow, rows, None)
    text = (tmp_path / "results.md").read_text()
    assert f"beats a random policy by little on `{xjus}` (10 of 110)" in text and f"`{WALK}` (" not in text


def test_each_row_is_judged_on_its_tasks_own_metric_beside_the_reference(tmp_path):
    """A walk's row shows its speed against the reference's, a turn's its yaw-rate error, an academy task's its
    success: each the paired difference its evaluation recorded."""
    turn, academy = "skitter/RoachTurn-v5", "skitter/RoachGoToBall-v5"
    plan = leaderboard.Plan((WALK, turn, academy), ("ppo",), (0,), ((WALK, 100), (turn, 100), (academy, 100)), None,
                            5, 1000, None)  # fmt: skip
    baselines = {t: {"reference": "gait", "reference_return": 110.0, "random_return": 10.0} for t in plan.tasks}

    def diff(mean: float) -> dict:
        return {"mean": mean, "ci_low": mean - 0.01, "ci_high": mean + 0.01, "n": 5}

    common = {"speed": diff(0.5), "cost_of_transport": diff(-0.2)}
    differences = {
        WALK: common,
        turn: {**common, "yaw_rate_error": diff(-0.25), "power": diff(-0.1)},
        academy: {**common, "success": diff(0.4)},
    }
    rows = {row: {"mean_return": 60.0, "timesteps": 100, "capped": False,
                  "paired_differences": differences[row.task]} for row in plan.rows}  # fmt: skip
    leaderboard.build_table(plan, tmp_path, baselines, rows, tmp_path / "results.md")
    rows_table = (tmp_path / "results.md").read_text().split("## Rows")[1].split("\n## ")[0]
    lines = {line.split(" |")[0][2:]: line for line in rows_table.splitlines() if line.startswith("| skitter_")}
    walk = "| speed +0.500 [+0.490, +0.510] m/s | cost of transport -0.200 [-0.210, -0.190] |"
    assert walk in lines["skitter_RoachWalk-v4__ppo__0"]
    turning = "| yaw_rate_error -0.250 [-0.260, -0.240] rad/s | power -0.100 [-0.110, -0.090] W |"  # a turn's energy
    assert turning in lines["skitter_RoachTurn-v5__ppo__0"]
    assert "| success +0.400 [+0.390, +0.410] | cost of transport" in lines["skitter_RoachGoToBall-v5__ppo__0"]


def test_a_resumed_row_is_credited_the_training_behind_its_checkpoint(tmp_path):
    """Killed and resumed, a row trains --minutes in all: each attempt is credited the time from its start to the
    newest checkpoint it wrote, plus its own credit; what it did after that checkpoint is not counted."""
    import os

    folder, run = tmp_path / "row", tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    assert leaderboard._begin_attempt(folder, run) == 0.0  # a fresh row
    start = json.loads((folder / leaderboard.ATTEMPTS).read_text())[0]["start"]
    first = run / "checkpoints" / "step_0000100000"
    first.mkdir()
    os.utime(first, (start + 30.0, start + 30.0))
    assert leaderboard._begin_attempt(folder, run) == pytest.approx(30.0)
    attempts = json.loads((folder / leaderboard.ATTEMPTS).read_text())
    second = run / "checkpoints" / "step_0000200000"
    second.mkdir()
    first.rmdir()  # (only the newest checkpoint counts)
    when = attempts[1]["start"] + 45.0
    os.utime(second, (when, when))
    assert leaderboard._begin_attempt(folder, run) == pytest.approx(75.0)


def test_a_rows_policy_after_an_hour_is_its_newest_checkpoint_within_an_hour_of_training(tmp_path, monkeypatch):
    """Training time runs across a kill and resume (the second attempt is credited the first's time to its newest
    checkpoint); the policy after an hour is the newest checkpoint written within 60 minutes of it, evaluated against
    the reference on the row's seeds, or the final model where the training took less."""
    import os

    plan = leaderboard.Plan((WALK,), ("ppo",), (0,), ((WALK, 4_000_000),), None, 20, 1000, None)
    row = plan.rows[0]
    folder, run = tmp_path / "rows" / row.name, tmp_path / "runs" / row.name
    folder.mkdir(parents=True)
    (run / "checkpoints").mkdir(parents=True)
    t0 = 1_000_000.0
    # the first attempt ran 40 min, its newest checkpoint at 35 min; the second started 3 h later, credited 35 min
    attempts = [{"start": t0, "credit": 0.0}, {"start": t0 + 3 * 3600, "credit": 35 * 60.0}]
    (folder / leaderboard.ATTEMPTS).write_text(json.dumps(attempts))
    written = {  # the first attempt's at 20 and 35 min of training, the second's at 55 and 65
        500_000: t0 + 20 * 60,
        900_000: t0 + 35 * 60,
        1_300_000: t0 + 3 * 3600 + 20 * 60,
        1_700_000: t0 + 3 * 3600 + 30 * 60,
    }
    for steps, when in written.items():
        checkpoint = run / "checkpoints" / f"step_{steps:010d}"
        checkpoint.mkdir()
        (checkpoint / "model.zip").write_bytes(b"")
        os.utime(checkpoint, (when, when))
    assert leaderboard.training_seconds(folder, t0 + 3 * 3600 + 20 * 60) == pytest.approx(55 * 60)
    model, steps, seconds = leaderboard.hour_checkpoint(folder, run)
    assert steps == 1_300_000 and seconds == pytest.approx(55 * 60)
    # a checkpoint's time is its checkpoint.json's: its folder's changes when an older one's replay buffer is dropped
    newest = run / "checkpoints" / "step_0001700000"
    (newest / "checkpoint.json").write_text("{}")
    os.utime(newest / "checkpoint.json", (t0 + 3 * 3600 + 24 * 60,) * 2)  # 59 min of training
    assert leaderboard.hour_checkpoint(folder, run)[1] == 1_700_000
    (newest / "checkpoint.json").unlink()
    (run / "model.zip").write_bytes(b"")
    os.utime(run / "model.zip", (t0 + 3 * 3600 + 50 * 60,) * 2)  # the final model at 85 min of training
    commands = []

    def evaluate(command, threads, log):  # what evaluate.py writes, for the policies it was given
        commands.append(command)
        out = Path(command[command.index("--out") + 1])
        out.mkdir(parents=True, exist_ok=True)
        episodes = [{"metrics": {"return": 7.0}}]
        policies = {"tripod": {"episodes": episodes}, str(model): {"episodes": episodes, "summary": {}}}
        results = {"policies": policies, "paired_differences": {"policies": {str(model): {}}}}
        (out / "results.json").write_text(json.dumps(results))

    monkeypatch.setattr(leaderboard, "_run", evaluate)
    hour = leaderboard.one_hour(plan, row, tmp_path, 1, 2_000_000)
    assert str(model) in commands[0] and "tripod" in commands[0] and "1000" in commands[0]
    assert hour["timesteps"] == 1_300_000 and hour["training_minutes"] == pytest.approx(55.0) and not hour["final"]
    assert hour["mean_return"] == 7.0
    os.utime(run / "model.zip", (t0 + 3 * 3600 + 20 * 60,) * 2)  # done at 55 min: the final model is the hour's
    assert leaderboard.one_hour(plan, row, tmp_path, 1, 2_000_000) == {"timesteps": 2_000_000,
                                                                       "training_minutes": pytest.approx(55.0),
                                                                       "final": True}  # fmt: skip
    assert len(commands) == 1
    (folder / leaderboard.ATTEMPTS).unlink()  # a run from before the leaderboard kept its attempts: not judged
    assert leaderboard.one_hour(plan, row, tmp_path, 1, 2_000_000) is None


def test_a_record_is_given_its_hour_only_from_its_own_run(tmp_path):
    """A record keeps its model's digest, and a run with another model (a rerun killed after its training) is not
    its run; a record from before it kept one is matched by the returns its evaluation of the run's model gave."""
    row = leaderboard.Row(WALK, "ppo", 0)
    model = tmp_path / "runs" / row.name / "model.zip"
    model.parent.mkdir(parents=True)
    model.write_bytes(b"the first run")
    record = {"returns": [1.0, 2.0], "model_sha256": leaderboard._sha256(model)}
    assert leaderboard._record_of_run(record, tmp_path, row)
    model.write_bytes(b"a rerun's")
    assert not leaderboard._record_of_run(record, tmp_path, row)
    old = {"returns": [1.0, 2.0]}
    assert not leaderboard._record_of_run(old, tmp_path, row)  # no evaluation to match it by
    evaluation = tmp_path / "rows" / row.name / "eval" / "results.json"
    evaluation.parent.mkdir(parents=True)
    episodes = [{"metrics": {"return": r}} for r in (1.0, 2.0)]
    evaluation.write_text(json.dumps({"policies": {str(model): {"episodes": episodes}}}))
    assert leaderboard._record_of_run(old, tmp_path, row)
    assert not leaderboard._record_of_run({"returns": [1.0, 3.0]}, tmp_path, row)


def test_a_record_lacking_a_metric_is_judged_again_from_its_own_run(tmp_path, monkeypatch, capsys):
    """A finished row whose record lacks metrics evaluate.py now reports (power, energy) is judged again from its kept
    run, and takes the new judgment only if it gives the record's returns; a record whose run is gone stays."""
    plan = leaderboard.Plan((WALK,), ("ppo",), (0,), ((WALK, 100),), None, 1, 1000, None)
    row = plan.rows[0]
    model = tmp_path / "runs" / row.name / "model.zip"
    model.parent.mkdir(parents=True)
    model.write_bytes(b"the run's model")
    old_metrics = {m: {"mean": 0.0} for m in leaderboard.GENERIC_METRICS if m not in ("power", "energy")}
    record = {"returns": [7.0], "model_sha256": leaderboard._sha256(model), "timesteps": 100,
              "paired_differences": old_metrics, "one_hour": {"timesteps": 100, "final": True}}  # fmt: skip
    returns, commands = [7.0], []

    def evaluate(command, threads, log):  # what evaluate.py writes now, with the power and the energy
        commands.append(command)
        out = Path(command[command.index("--out") + 1])
        out.mkdir(parents=True, exist_ok=True)
        episodes = [{"metrics": {"return": r}} for r in returns]
        diff = {**old_metrics, "power": {"mean": -1.0, "ci_low": -1.5, "ci_high": -0.5},
                "energy": {"mean": -10.0, "ci_low": -15.0, "ci_high": -5.0}}  # fmt: skip
        results = {"policies": {"tripod": {"episodes": episodes}, str(model): {"episodes": episodes, "summary": {}}},
                   "paired_differences": {"policies": {str(model): diff}}}  # fmt: skip
        (out / "results.json").write_text(json.dumps(results))

    monkeypatch.setattr(leaderboard, "_run", evaluate)
    records = tmp_path / "records"
    updated = leaderboard.backfill_judgment(plan, row, record, tmp_path, records, 1)
    assert updated["paired_differences"]["power"]["mean"] == -1.0 and updated["one_hour"] == record["one_hour"]
    assert json.loads(leaderboard.row_file(records, row).read_text()) == updated
    assert "judged again for power, energy" in capsys.readouterr().out
    assert leaderboard.backfill_judgment(plan, row, updated, tmp_path, records, 1) is updated  # nothing lacking
    assert len(commands) == 1
    returns[0] = 6.0  # the model no longer gives its record's returns: the record stays as it was
    assert leaderboard.backfill_judgment(plan, row, record, tmp_path, records, 1) is record
    assert "other returns" in capsys.readouterr().err
    model.unlink()  # its run is gone: nothing to judge again
    assert leaderboard.backfill_judgment(plan, row, record, tmp_path, records, 1) is record
    assert len(commands) == 2


def test_the_hour_is_judged_on_the_tasks_metric_and_its_energy(tmp_path):
    """A speed is not worse when its interval reaches zero from below, a yaw-rate error, a cost of transport or a
    power when it reaches zero from above; a turn's energy is its mean power where its record has one (a turn on
    the spot travels no distance), else the cost of transport; the hour's section says which fell short."""
    assert leaderboard.at_least_as_good({"speed": {"ci_low": -0.2, "ci_high": 0.01}}, "speed")
    assert not leaderboard.at_least_as_good({"speed": {"ci_low": -0.2, "ci_high": -0.01}}, "speed")
    assert leaderboard.at_least_as_good({"yaw_rate_error": {"ci_low": -0.01, "ci_high": 0.2}}, "yaw_rate_error")
    assert not leaderboard.at_least_as_good({"cost_of_transport": {"ci_low": 0.1, "ci_high": 0.2}},
                                            "cost_of_transport")  # fmt: skip
    assert leaderboard.at_least_as_good({}, "speed") is None
    turn = "skitter/RoachTurn-v5"
    plan = leaderboard.Plan((WALK, turn), ("ppo",), (0,), ((WALK, 100), (turn, 100)), None, 20, 1000, None)
    baselines = {t: {"reference": "tripod", "reference_return": 10.0, "random_return": 0.0} for t in plan.tasks}
    faster = {"speed": {"mean": 0.1, "ci_low": 0.05, "ci_high": 0.15},
              "cost_of_transport": {"mean": 0.5, "ci_low": 0.2, "ci_high": 0.8}}  # fmt: skip
    turning = {"yaw_rate_error": {"mean": 0.0, "ci_low": -0.01, "ci_high": 0.01},
               "cost_of_transport": {"mean": -0.5, "ci_low": -0.8, "ci_high": -0.2}}  # fmt: skip
    rows = {plan.rows[0]: {"timesteps": 100, "capped": False, "mean_return": 12.0, "paired_differences": faster,
                           "one_hour": {"timesteps": 100, "training_minutes": 30.0, "final": True}},
            plan.rows[1]: {"timesteps": 100, "capped": False, "mean_return": 9.0, "paired_differences": turning,
                           "one_hour": {"timesteps": 60, "training_minutes": 59.5, "final": False,
                                        "mean_return": 5.0, "paired_differences": turning}}}  # fmt: skip
    text = "\n".join(leaderboard._hour_section(baselines, rows))
    assert "| skitter_RoachWalk-v4__ppo__0 | 100 (its final model) | 30 | 1.20 |" in text
    assert ("speed +0.100 [+0.050, +0.150] m/s | cost of transport +0.500 [+0.200, +0.800] | no: cost of transport "
            "worse |") in text  # fmt: skip
    assert "| skitter_RoachTurn-v5__ppo__0 | 60 | 60 | 0.50 | yaw_rate_error" in text and text.endswith("| yes |")
    # the same turn with its power: judged on the power (here worse), whatever its cost of transport says
    turning["power"] = {"mean": 0.3, "ci_low": 0.1, "ci_high": 0.5}
    text = "\n".join(leaderboard._hour_section(baselines, rows))
    assert text.endswith("| power +0.300 [+0.100, +0.500] W | no: power worse |")
    assert leaderboard.energy_metric(turning) == ("power", " W")
    assert leaderboard.energy_metric({**faster, "power": turning["power"]}) == ("cost_of_transport", "")
    # an academy task: the energy of its episode, which ends when the task is done (a record without it: the CoT)
    touched = {
        "success": {"mean": 0.0, "ci_low": 0.0, "ci_high": 0.0},
        "cost_of_transport": faster["cost_of_transport"],
    }
    assert leaderboard.energy_metric(touched) == ("cost_of_transport", "")
    touched["energy"] = {"mean": -40.0, "ci_low": -60.0, "ci_high": -20.0}
    assert leaderboard.energy_metric(touched) == ("energy", " J")
    assert leaderboard._energy_cell(touched) == "energy -40.000 [-60.000, -20.000] J"
    assert leaderboard.at_least_as_good(touched, "energy"), "less energy is better"
    assert not leaderboard.at_least_as_good({"energy": {"ci_low": 5.0, "ci_high": 9.0}}, "energy")
    del rows[plan.rows[1]]["one_hour"]
    assert "not judged" in "\n".join(leaderboard._hour_section(baselines, rows))


def test_elo_against_the_scripted_team_follows_the_record():
    even = leaderboard.elo_against(5, 10, 5)
    assert even["elo"] == pytest.approx(1000.0) and even["low"] < 1000.0 < even["high"]
    three_to_one = leaderboard.elo_against(15, 0, 5)
    assert three_to_one["elo"] == pytest.approx(1000.0 + 400.0 * np.log10(3.0))
    sweep = leaderboard.elo_against(20, 0, 0)
    assert sweep["elo"] == np.inf and np.isfinite(sweep["low"]) and sweep["low"] > 1000.0
    assert leaderboard.elo_against(0, 0, 20)["elo"] == -np.inf
    # written by the interval's finite end, not as an infinite rating
    assert leaderboard._rating(leaderboard.elo_against(0, 0, 20)).startswith("at most ")
    assert leaderboard._rating(sweep) == f"at least {sweep['low']:.0f} (every match won)"
    assert leaderboard._rating(even) == f"1000 [{even['low']:.0f}, {even['high']:.0f}]"


def test_an_interval_is_the_same_each_time_and_leaves_numpys_generator_alone():
    """rliable draws its bootstrap resamples from numpy's global generator whatever it is handed: the same scores
    give the same interval every time (a table built again reads the same), and a caller's draws are not moved."""
    scores = np.random.default_rng(1).normal(size=(2, 16))
    np.random.seed(7)  # noqa: NPY002
    expected = np.random.random()  # noqa: NPY002
    np.random.seed(7)  # noqa: NPY002
    first = leaderboard.aggregate({"a": scores})
    assert np.random.random() == expected  # noqa: NPY002
    assert leaderboard.aggregate({"a": scores}) == first
    assert leaderboard.aggregate({"a": scores[:1]}, over_tasks=True) == leaderboard.aggregate(
        {"a": scores[:1]}, over_tasks=True
    )


def test_before_every_row_is_done_all_tasks_are_scored_on_the_seeds_they_share(tmp_path):
    """Until every row is done, the score over all tasks takes the seeds every task has for every algorithm: with
    one such seed its interval resamples the tasks (a spread of tasks gives a spread of scores, where resampling the
    one run of each would give none), with two the seeds within each task; the profiles are drawn from those rows."""
    plan = leaderboard.Plan((WALK, XJUS), ("ppo", "sac"), (0, 1, 2), ((WALK, 100), (XJUS, 100)), None, 5, 1000, None)
    baselines = {t: {"reference": "gait", "reference_return": 110.0, "random_return": 10.0} for t in plan.tasks}
    score = {(WALK, "ppo"): 0.5, (XJUS, "ppo"): 1.5, (WALK, "sac"): 0.2, (XJUS, "sac"): 0.4}

    def rows_of(seeds: dict[tuple[str, str], tuple[int, ...]]) -> dict:
        return {r: ({"mean_return": 10.0 + 100.0 * (score[r.task, r.algo] + 0.01 * r.seed), "timesteps": 100,
                     "capped": False, "paired_differences": {}} if r.seed in seeds[r.task, r.algo] else None)
                for r in plan.rows}  # fmt: skip

    # seed 0 everywhere, seed 1 on all but one task of sac: the interim is over seed 0 alone, tasks resampled
    seeds = {key: (0, 1) for key in score} | {(XJUS, "sac"): (0,)}
    summary = leaderboard.build_table(plan, tmp_path, baselines, rows_of(seeds), tmp_path / "results.md")
    assert summary["overall"] == {}
    interim = summary["interim"]
    assert interim["seeds"] == [0] and interim["over_tasks"] and interim["tasks"] == 2
    ppo = interim["scores"]["ppo"]
    assert ppo["iqm"] == pytest.approx(1.0) and ppo["low"] == pytest.approx(0.5) and ppo["high"] == pytest.approx(1.5)
    text = (tmp_path / "results.md").read_text()
    assert "on the rows every task has for every algorithm (seed 0;" in text and "task bootstrap" in text
    assert "![performance profiles](" in text and "plots/performance_profiles.png)" in text
    assert (tmp_path / "plots" / "performance_profiles.png").is_file()
    # two seeds shared: the seeds are resampled within each task, and the interval is theirs
    seeds[XJUS, "sac"] = (0, 1)
    interim = leaderboard.build_table(plan, tmp_path, baselines, rows_of(seeds), None)["interim"]
    assert interim["seeds"] == [0, 1] and not interim["over_tasks"]
    ppo = interim["scores"]["ppo"]
    assert ppo["low"] <= ppo["iqm"] <= ppo["high"] and ppo["high"] - ppo["low"] < 0.02  # the seeds' spread alone
    # a task one algorithm has no row of: no interim, and no profiles promised
    seeds[XJUS, "sac"] = ()
    summary = leaderboard.build_table(plan, tmp_path / "none", baselines, rows_of(seeds), tmp_path / "none.md")
    assert summary["interim"] is None and "performance profiles" not in (tmp_path / "none.md").read_text()


def test_soccer_tasks_are_rated_beside_the_normalized_table(tmp_path):
    """A soccer task's rows are rated against the scripted team in their own section; the walking task's table and
    its overall score are those of the walking rows alone."""
    soccer = "soccer/roach"
    plan = leaderboard.Plan((WALK, soccer), ("ppo",), (0, 1), ((WALK, 100), (soccer, 100)), None, 20, 1000, None)
    record = {"wins": {"count": 4}, "draws": {"count": 1}, "losses": {"count": 15},
              "goal_difference": {"mean": -1.2, "ci_low": -1.8, "ci_high": -0.6}}  # fmt: skip
    baselines = {WALK: {"reference": "gait", "reference_return": 110.0, "random_return": 10.0},
                 soccer: {"soccer": True, "reference": "scripted", "random_elo": leaderboard.elo_against(0, 2, 18),
                          "scripted_vs_random": {**record, "wins": {"count": 18}, "draws": {"count": 2},
                                                 "losses": {"count": 0}}}}  # fmt: skip
    rows = {}
    for row in plan.rows:
        if row.task == WALK:
            rows[row] = {"mean_return": 60.0 + row.seed, "timesteps": 100, "capped": False, "paired_differences": {}}
        elif row.seed == 0:
            rows[row] = {"soccer": True, "timesteps": 100, "wall_seconds": 120.0, "against_scripted": record,
                         "elo": leaderboard.elo_against(4, 1, 15), "selfplay_elo": 1012.0}  # fmt: skip
        else:
            rows[row] = None
    summary = leaderboard.build_table(plan, tmp_path, baselines, rows, None)
    assert set(summary["per_task"]) == {WALK} and set(summary["overall"]) == {"ppo"}
    text = (tmp_path / "results.md").read_text()
    assert "## Soccer" in text and "| soccer_roach__ppo__0 | 100 | 2 | 4-1-15 | -1.20 [-1.80, -0.60] |" in text
    assert "| soccer_roach__ppo__1 | not run |" in text and "1000 (anchor); random" in text
    assert "`soccer/roach` | scripted" not in text.split("## Soccer")[0], "not in the normalized table"


def test_a_soccer_task_s_matches_last_as_long_as_its_plan_says(capsys):
    """``--match-seconds TASK=S``: the task's settings (which make older records stale), its training and evaluation
    commands, the command that reproduces the plan, and the table's soccer section carry the length; the default
    length is left out of all of them, so that records made before the option still hold."""
    from envs.soccer.match import MATCH_SECONDS

    assert leaderboard.MATCH_SECONDS == MATCH_SECONDS
    args = leaderboard.parse_args(["--tasks", "soccer/bioloid", "soccer/roach", "--timesteps", "10",
                                   "--match-seconds", "soccer/bioloid=600", "soccer/roach=60"])  # fmt: skip
    assert args.match_seconds == (("soccer/bioloid", 600.0),)
    plan = leaderboard.Plan(tuple(args.tasks), ("ppo",), (0,), args.timesteps, None, 20, 1000, None,
                            match_seconds=args.match_seconds)  # fmt: skip
    assert plan.task_settings("soccer/bioloid")["match_seconds"] == 600.0
    assert "match_seconds" not in plan.task_settings("soccer/roach")
    assert leaderboard._matches(plan, "soccer/bioloid")[-2:] == ["--match-seconds", "600"]
    assert "--match-seconds" not in leaderboard._matches(plan, "soccer/roach")
    again = leaderboard.plan_arguments(plan)
    assert again[again.index("--match-seconds") + 1 :] == ["soccer/bioloid=600"]
    assert leaderboard.parse_args([*again]).match_seconds == plan.match_seconds
    section = "\n".join(leaderboard._soccer_section(plan, {t: {"scripted_vs_random": {
        "wins": {"count": 1}, "draws": {"count": 0}, "losses": {"count": 0}, "goal_difference": {"mean": 1.0}},
        "random_elo": leaderboard.elo_against(0, 0, 1)} for t in plan.tasks}, {}))  # fmt: skip
    assert "Matches last 600 s (soccer/bioloid), 60 s (soccer/roach), in training and evaluation." in section
    # a length for a soccer task the run leaves out is ignored (the Makefile's one list serves any run)
    assert leaderboard.parse_args(["--tasks", "soccer/bioloid", "--timesteps", "10", "--match-seconds",
                                   "soccer/xjus=600"]).match_seconds == ()  # fmt: skip
    for bad, message in ((["soccer/bioloid=0"], "must be in (0, 3600]"), (["soccer/nope=600"], "a soccer task ("),
                         ([f"{WALK}=600"], "a soccer task ("),
                         (["soccer/bioloid"], "expected TASK=S"), (["soccer/bioloid=long"], "not a number"),
                         (["soccer/bioloid=600", "soccer/bioloid=300"], "given twice")):  # fmt: skip
        with pytest.raises(SystemExit):
            leaderboard.parse_args(["--tasks", "soccer/bioloid", "--timesteps", "10", "--match-seconds", *bad])
        assert message in capsys.readouterr().err


def test_a_soccer_task_s_baselines_keep_the_match_length_they_were_played_with(tmp_path, monkeypatch):
    """The scripted team's record against random, played with 600 s matches, is kept under the task's settings
    (its match length among them): the next command of the same plan reuses it, one of another length refuses it."""
    played = []

    def evaluate(command, threads, log):  # the matches' results, as evaluate.py --soccer writes them
        played.append(command)
        out = Path(command[command.index("--out") + 1])
        counts = {k: {"count": n} for k, n in (("wins", 3), ("draws", 1), ("losses", 0))}
        leaderboard.write_json(out / "results.json", {**counts, "goal_difference": {"mean": 1.0}})

    monkeypatch.setattr(leaderboard, "_run", evaluate)
    plan = leaderboard.Plan(("soccer/bioloid",), ("ppo",), (0,), (("soccer/bioloid", 10),), None, 4, 1000, None,
                            match_seconds=(("soccer/bioloid", 600.0),))  # fmt: skip
    first = leaderboard.task_baselines(plan, "soccer/bioloid", tmp_path, 1)
    assert played[0][played[0].index("--match-seconds") + 1] == "600"
    assert first["settings"]["match_seconds"] == 600.0
    assert leaderboard.task_baselines(plan, "soccer/bioloid", tmp_path, 1) == first and len(played) == 1
    shorter = dataclasses.replace(plan, match_seconds=())  # the default 60 s matches
    with pytest.raises(leaderboard.StaleResult, match="match_seconds"):
        leaderboard.task_baselines(shorter, "soccer/bioloid", tmp_path, 1)


def test_soccer_tasks_are_checked_before_anything_runs(tmp_path, capsys):
    for argv, message in (
        (["--tasks", "soccer/nope", "--timesteps", "10"], "soccer/ROBOT takes one of"),
        (["--tasks", "soccer/roach", "--algos", "sac", "--timesteps", "10"], "self-play trains with ppo alone"),
        (["--tasks", "soccer/roach", WALK, "--algos", "ppo+residual", "--timesteps", "10"], "has none of it"),
    ):
        with pytest.raises(SystemExit) as exited:
            leaderboard.main([*argv, "--out", str(tmp_path / "b")])
        assert exited.value.code == 2 and message in capsys.readouterr().err
    assert leaderboard.parse_args(["--tasks", "soccer/xjus", WALK, "--timesteps", "10"]).tasks[0] == "soccer/xjus"


def test_one_plan_holds_the_gym_tasks_residual_rows_and_the_soccer_rows():
    args = leaderboard.parse_args(["--tasks", WALK, "soccer/xjus", "--algos", "ppo", "ppo+residual", "--seeds", "0",
                                   "1", "--timesteps", "10"])  # fmt: skip
    plan = leaderboard.Plan(tuple(args.tasks), tuple(args.algos), tuple(args.seeds), args.timesteps, None, 2, 1000,
                            None)  # fmt: skip
    soccer = [r for r in plan.rows if r.task == "soccer/xjus"]
    assert [r.algo for r in soccer] == ["ppo", "ppo"] and [r.seed for r in soccer] == [0, 1]
    assert {r.algo for r in plan.rows if r.task == WALK} == {"ppo", "ppo+residual"} and len(plan.rows) == 6


@pytest.mark.slow  # a minute or more: a self-play run, the scripted team's matches and the row's
def test_a_soccer_row_trains_by_self_play_and_is_rated_against_the_scripted_team(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tiny = {"policy": "MlpPolicy", "n_envs": 2, "normalize": True, "n_steps": 64, "batch_size": 64, "n_epochs": 1}
    (tmp_path / "tiny.yml").write_text(yaml.safe_dump({"soccer/roach": tiny}))
    out = tmp_path / "board"
    argv = ["--tasks", "soccer/roach", "--seeds", "0", "--timesteps", "256", "--episodes", "2", "--hyperparams",
            "tiny.yml", "--out", str(out)]  # fmt: skip
    assert leaderboard.main(argv) == 0
    record = json.loads((out / "rows" / "soccer_roach__ppo__0" / "row.json").read_text())
    assert record["timesteps"] >= 256 and record["against_scripted"]["matches"] == 2
    counts = [record["against_scripted"][k]["count"] for k in ("wins", "draws", "losses")]
    assert record["elo"] == pytest.approx(leaderboard.elo_against(*counts))
    assert record["reproduce"][0].startswith("python train.py --soccer roach --players 1")
    assert "## Soccer" in (out / "results.md").read_text()


def test_table_only_trains_nothing_and_lists_the_rows_not_run(tmp_path, monkeypatch, capsys):
    baselines = {"reference": "tripod", "reference_return": 110.0, "random_return": 10.0}
    monkeypatch.setattr(leaderboard, "task_baselines", lambda plan, task, *args: {**baselines, "task": task})

    def train(*args):
        raise AssertionError("--table-only ran a row")

    monkeypatch.setattr(leaderboard, "run_row", train)
    out = tmp_path / "board"
    argv = ["--tasks", WALK, "--seeds", "0", "1", "--timesteps", "100", "--out", str(out), "--table-only"]
    assert leaderboard.main(argv) == 0
    assert "not run, so listed as such: 2 rows" in capsys.readouterr().out
    text = (out / "results.md").read_text()
    assert f"| {WALK.replace('/', '_')}__ppo__0 | not run |" in text
    with pytest.raises(SystemExit):
        leaderboard.main([*argv, "--rerun", f"{WALK}:ppo:0"])
    assert "cannot --rerun" in capsys.readouterr().err


def test_a_fresh_checkout_keeps_the_finished_rows_from_their_records(tmp_path, monkeypatch, capsys):
    """The records folder alone (no runs, no evaluations: what a checkout holds) is enough: its rows are not run
    again, the table takes their returns and learning curves from the records, and the published video stays
    while its row is the best."""
    plan = leaderboard.Plan((WALK,), ("ppo",), (0, 1), ((WALK, 100),), None, 2, 1000, None)
    kept, docs = tmp_path / "kept", tmp_path / "docs" / "results.md"
    baselines = {"task": WALK, "reference": "tripod", "reference_return": 110.0, "random_return": 10.0,
                 "settings": plan.eval_settings}  # fmt: skip
    leaderboard.write_json(leaderboard.task_file(kept, WALK), baselines)
    row = leaderboard.Row(WALK, "ppo", 0)
    record = {"mean_return": 85.0, "returns": [80.0, 90.0], "timesteps": 100, "capped": False, "wall_seconds": 60.0,
              "paired_differences": {}, "curve": {"steps": [0, 50, 100], "values": [10.0, 50.0, 85.0]},
              "settings": plan.row_settings(WALK)}  # fmt: skip
    leaderboard.write_json(leaderboard.row_file(kept, row), {**record, "training_attempts": 3})
    leaderboard.write_text(leaderboard.video_marker(kept, WALK), row.name + "\n")
    (docs.parent / "results" / "videos").mkdir(parents=True)
    (docs.parent / "results" / "videos" / "skitter_RoachWalk-v4.mp4").write_bytes(b"published")
    ran = []
    monkeypatch.setattr(leaderboard, "run_row", lambda plan, row, *args: ran.append(row) or {**record, "curve": None})
    argv = ["--tasks", WALK, "--seeds", "0", "1", "--timesteps", "100", "--episodes", "2", "--out",
            str(tmp_path / "fresh"), "--records", str(kept), "--docs", str(docs), "--videos"]  # fmt: skip
    (tmp_path / "fresh" / "plots").mkdir(parents=True)
    (tmp_path / "fresh" / "plots" / "curve_skitter_Gone-v1.png").write_bytes(b"an earlier plan's")
    gone = tmp_path / "fresh" / "videos" / "skitter_Gone-v1" / "eval" / "videos" / "side_by_side.mp4"
    gone.parent.mkdir(parents=True)
    gone.write_bytes(b"an earlier plan's")
    assert leaderboard.main(argv) == 0
    assert not (docs.parent / "results" / "plots" / "curve_skitter_Gone-v1.png").exists(), "only the page's plots"
    assert not (docs.parent / "results" / "videos" / "skitter_Gone-v1.mp4").exists(), "and the page's videos"
    assert ran == [leaderboard.Row(WALK, "ppo", 1)], "the kept row is not trained again"
    assert "(1 to run)" in capsys.readouterr().out
    text = docs.read_text()
    assert f"| {row.name} | 100 | 1 | 85.0 | 0.75 |" in text
    assert "Rows trained in several attempts (killed and resumed" in text and f"{row.name} (3)." in text
    assert f"[the reference and {row.name}](results/videos/skitter_RoachWalk-v4.mp4)" in text
    assert (docs.parent / "results" / "plots" / "curve_skitter_RoachWalk-v4.png").stat().st_size > 5_000
    assert not (tmp_path / "fresh" / "runs").exists()


def test_a_row_computed_again_keeps_its_record_until_replaced_and_says_if_it_reproduced(tmp_path, monkeypatch, capsys):
    """--rerun: a killed rerun leaves the published record as it was; a finished one replaces it with its own, which
    says whether its number lies within the earlier record's 95% interval (and the page lists it)."""
    plan = leaderboard.Plan((WALK,), ("ppo",), (0,), ((WALK, 100),), None, 2, 1000, None)
    kept, docs = tmp_path / "kept", tmp_path / "docs" / "results.md"
    baselines = {"task": WALK, "reference": "tripod", "reference_return": 110.0, "random_return": 10.0,
                 "settings": plan.eval_settings}  # fmt: skip
    leaderboard.write_json(leaderboard.task_file(kept, WALK), baselines)
    row = leaderboard.Row(WALK, "ppo", 0)

    def record(mean: float) -> dict:
        return {"mean_return": mean, "returns": [mean - 5, mean + 5], "timesteps": 100, "capped": False,
                "wall_seconds": 60.0, "paired_differences": {}, "curve": None, "settings": plan.row_settings(WALK),
                "summary": {"return": {"mean": mean, "ci_low": mean - 5, "ci_high": mean + 5, "n": 2}}}  # fmt: skip

    published = record(85.0)
    leaderboard.write_json(leaderboard.row_file(kept, row), published)
    argv = ["--tasks", WALK, "--seeds", "0", "--timesteps", "100", "--episodes", "2", "--out", str(tmp_path / "b"),
            "--records", str(kept), "--docs", str(docs), "--rerun", f"{WALK}:ppo:0"]  # fmt: skip

    def killed(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(leaderboard, "run_row", killed)
    assert leaderboard.main(argv) != 0
    assert json.loads(leaderboard.row_file(kept, row).read_text()) == published, "the published row stays"
    # the same where the records are the row's own folder (no --records): its other files go, its record stays
    alone = tmp_path / "alone"
    shutil.copytree(kept, alone)
    (alone / "rows" / row.name / "log.txt").write_text("the killed run's")
    default = ["--tasks", WALK, "--seeds", "0", "--timesteps", "100", "--episodes", "2", "--out", str(alone),
               "--rerun", f"{WALK}:ppo:0"]  # fmt: skip
    assert leaderboard.main(default) != 0
    assert sorted(p.name for p in (alone / "rows" / row.name).iterdir()) == [leaderboard.ROW_LOCK, "row.json"]
    assert json.loads(leaderboard.row_file(alone, row).read_text()) == published
    for mean, verdict in ((88.0, "within"), (95.0, "OUTSIDE")):
        monkeypatch.setattr(leaderboard, "run_row", lambda plan, row, *args, mean=mean: record(mean))
        marker = leaderboard.video_marker(kept, WALK)  # the task's published video shows this row's model
        leaderboard.write_text(marker, row.name + "\n")
        capsys.readouterr()
        assert leaderboard.main(argv) == 0
        assert not marker.exists(), "the video of the model the new record replaced is made again, not kept"
        printed = capsys.readouterr().out
        assert f"again: mean return {mean:.2f} against 85.00 [80.00, 90.00] before: {verdict}" in printed
        assert "bit for bit" not in printed, "other returns are not the same episodes"
        again = json.loads(leaderboard.row_file(kept, row).read_text())
        assert again["mean_return"] == mean and again["reproduction"]["within"] is (verdict == "within")
        assert again["reproduction"]["before"]["value"] == 85.0
        assert f"{row.name}: mean return {mean:.2f}" in docs.read_text()
        leaderboard.write_json(leaderboard.row_file(kept, row), published)


def test_a_row_computed_again_says_which_library_versions_each_ran_on(tmp_path):
    def record(mean: float, found: dict | None = None) -> dict:
        summary = {"return": {"mean": mean, "ci_low": mean - 5, "ci_high": mean + 5, "n": 2}}
        return {"mean_return": mean, "summary": summary, "settings": {}, **({"software": found} if found else {})}

    ran = {k: "1.0" for k in leaderboard.LIBRARIES}
    unknown = leaderboard.verdict(leaderboard.reproduction(record(85.0), record(95.0, ran)))
    assert unknown.endswith(
        "OUTSIDE its 95% interval; the earlier record does not say which library versions it ran on"
    )
    other = leaderboard.verdict(leaderboard.reproduction(record(85.0, {**ran, "torch": "2.0"}), record(88.0, ran)))
    assert "within its 95% interval; the earlier one ran on python 1.0, stable-baselines3 1.0, torch 2.0" in other
    assert "this one on python 1.0, stable-baselines3 1.0, torch 1.0" in other
    silent = leaderboard.verdict(leaderboard.reproduction(record(85.0, ran), record(88.0)))
    assert silent.endswith("this one does not say on which library versions")
    # another commit is the code's change, which the row's settings and version say; the libraries are the same
    same = leaderboard.reproduction(record(85.0, {**ran, "git_commit": "a"}), record(88.0, {**ran, "git_commit": "b"}))
    assert leaderboard.verdict(same).endswith("within its 95% interval")
    # the CPU code paths (numpy's SIMD targets, torch's capability) change the last bits on the same versions
    avx512 = {**ran, "numpy_simd": "X86_V3 X86_V4 baseline(X86_V2)", "torch_cpu": "AVX512"}
    avx2 = {**ran, "numpy_simd": "X86_V3 baseline(X86_V2)", "torch_cpu": "AVX2"}
    paths = leaderboard.verdict(leaderboard.reproduction(record(85.0, avx2), record(88.0, avx512)))
    assert paths.endswith(
        "within its 95% interval; the earlier one ran the CPU code paths numpy X86_V3 baseline(X86_V2), torch AVX2, "
        "this one numpy X86_V3 X86_V4 baseline(X86_V2), torch AVX512"
    )
    untold = leaderboard.verdict(leaderboard.reproduction(record(85.0, ran), record(88.0, avx512)))
    assert untold.endswith("within its 95% interval; the earlier record does not say which CPU code paths it ran")
    same_paths = leaderboard.reproduction(record(85.0, avx512), record(88.0, {**avx512, "cpu": "another model"}))
    assert leaderboard.verdict(same_paths).endswith("within its 95% interval")
    # a run's versions come from its config.json; a run without them has none
    run = tmp_path / "run"
    run.mkdir()
    assert leaderboard.software(run) is None
    (run / "config.json").write_text(json.dumps({"versions": ran}))
    assert leaderboard.software(run) == ran
    (run / "config.json").write_text("[1, 2]")
    assert leaderboard.software(run) is None
    rows = {leaderboard.Row(WALK, "ppo", 0): record(1.0, ran), leaderboard.Row(WALK, "ppo", 1): record(1.0),
            leaderboard.Row(WALK, "ppo", 2): None,
            leaderboard.Row(WALK, "ppo+residual", 0): record(1.0, avx512)}  # fmt: skip
    lines = leaderboard._software_lines(rows)
    assert f"- {leaderboard.libraries(ran)}: skitter_RoachWalk-v4__ppo__0." in lines
    assert (f"- {leaderboard.libraries(ran)}; CPU code paths numpy X86_V3 X86_V4 baseline(X86_V2), torch AVX512: "
            "skitter_RoachWalk-v4__ppo+residual__0.") in lines  # fmt: skip
    assert "- not recorded (rows trained before records kept them): skitter_RoachWalk-v4__ppo__1." in lines


def test_a_rows_command_computes_that_row_alone_into_its_own_folders():
    plan = leaderboard.Plan((WALK, XJUS), ("ppo", "ppo+residual"), (0, 1), ((WALK, 100), (XJUS, 200)), None, 20,
                            1000, None)  # fmt: skip
    command = leaderboard.row_command(plan, leaderboard.Row(XJUS, "ppo+residual", 1), "board", "kept")
    assert command == (
        f"python -m agents.leaderboard --tasks {XJUS} --algos ppo+residual --seeds 1 --timesteps 200 "
        f"--episodes 20 --eval-seed 1000 --out board --records kept --rerun {XJUS}:ppo+residual:1"
    )
    assert "--records" not in leaderboard.row_command(plan, leaderboard.Row(WALK, "ppo", 0), "board", "board")


def test_two_commands_share_one_folder_each_computing_its_own_rows(tmp_path, monkeypatch, capsys):
    """A row another command computes (it holds the row's lock) is left to it, and the rest go on; --rerun of such a
    row is refused, naming it, before any row's work goes; a record another command wrote meanwhile with other
    settings stays out of the table."""
    baselines = {"reference": "tripod", "reference_return": 110.0, "random_return": 10.0}
    monkeypatch.setattr(leaderboard, "task_baselines", lambda plan, task, *args: {**baselines, "task": task})
    ran = []

    def record(plan: leaderboard.Plan) -> dict:
        return {"mean_return": 60.0, "returns": [55.0, 65.0], "timesteps": 100, "capped": False, "wall_seconds": 1.0,
                "paired_differences": {}, "curve": None, "settings": plan.row_settings(WALK),
                "summary": {"return": {"mean": 60.0, "ci_low": 55.0, "ci_high": 65.0, "n": 2}}}  # fmt: skip

    def run_row(plan, row, out, threads, records, again):  # as the real one: the record, kept as the row's
        ran.append(row)
        (out / "rows" / row.name / "log.txt").write_text("its work")
        leaderboard.write_json(leaderboard.row_file(records, row), record(plan))
        return record(plan)

    monkeypatch.setattr(leaderboard, "run_row", run_row)
    out = tmp_path / "board"
    argv = ["--tasks", WALK, "--seeds", "0", "1", "--timesteps", "100", "--episodes", "2", "--out", str(out)]
    other, mine = leaderboard.Row(WALK, "ppo", 0), leaderboard.Row(WALK, "ppo", 1)
    with leaderboard.row_lock(out, other):  # another command computes seed 0 in the same folder
        assert leaderboard.main(argv) == 0
        printed = capsys.readouterr().out
        assert ran == [mine], "the other command's row is not computed twice"
        assert f"{other.name}: another command computes it in {out}" in printed and "left to it" in printed
        assert f"| {other.name} | not run |" in (out / "results.md").read_text()
        rerun = [*argv, "--rerun", f"{WALK}:ppo:1", "--rerun", f"{WALK}:ppo:0"]
        assert leaderboard.main(rerun) == 1
        assert f"{out / 'rows' / other.name} is in use by another leaderboard run" in capsys.readouterr().err
        assert (out / "rows" / mine.name / "log.txt").is_file(), "refused before any row's work went"
    # the other command done, its row is computed by the next that wants it; the finished one is kept
    assert leaderboard.main(argv) == 0
    assert ran == [mine, other]
    # a rerun clears the row's work under its lock, keeps its record until replaced, and says if it reproduced
    assert leaderboard.main([*argv, "--rerun", f"{WALK}:ppo:1"]) == 0
    assert ("again: mean return 60.00 against 60.00 [55.00, 65.00] before: within its 95% interval, the same in every "
            "evaluation episode, bit for bit") in capsys.readouterr().out  # fmt: skip
    assert json.loads(leaderboard.row_file(out, mine).read_text())["reproduction"]["identical"]
    # seed 0 left to another command, which finishes it meanwhile with other settings: not in this one's table
    leaderboard.row_file(out, other).unlink()

    def job(plan, row, *args):
        if row == other:
            return row, None, None
        stale = {**record(plan), "settings": {**plan.row_settings(WALK), "timesteps": 999}}
        leaderboard.write_json(leaderboard.row_file(out, other), stale)
        return row, record(plan), None

    monkeypatch.setattr(leaderboard, "_row_job", job)
    assert leaderboard.main([*argv, "--rerun", f"{WALK}:ppo:1"]) == 0
    said = capsys.readouterr().err
    assert f"row {other.name}" in said and "not in this command's table" in said
    assert f"| {other.name} | not run |" in (out / "results.md").read_text()


def test_a_second_command_waits_for_the_table_and_says_so(tmp_path, monkeypatch, capsys):
    import threading
    import time

    from envs.common.io import Busy, folder_lock

    out = tmp_path / "board"
    build_table, built = leaderboard.build_table, []

    def build_table_locked(*args):  # the table is written under its lock
        with pytest.raises(Busy), folder_lock(out, "leaderboard", leaderboard.TABLE_LOCK):
            pass
        built.append(True)
        return build_table(*args)

    baselines = {"reference": "tripod", "reference_return": 110.0, "random_return": 10.0}
    monkeypatch.setattr(leaderboard, "task_baselines", lambda plan, task, *args: {**baselines, "task": task})
    monkeypatch.setattr(leaderboard, "build_table", build_table_locked)
    argv = ["--tasks", WALK, "--seeds", "0", "--timesteps", "100", "--out", str(out), "--table-only"]
    assert leaderboard.main(argv) == 0 and built == [True]
    taken = threading.Event()

    def second() -> None:
        with folder_lock(out, "leaderboard", leaderboard.TABLE_LOCK, wait=True):
            taken.set()

    said = ""
    with folder_lock(out, "leaderboard", leaderboard.TABLE_LOCK):
        waiting = threading.Thread(target=second)
        waiting.start()
        deadline = time.monotonic() + 60
        while "waiting for another leaderboard run" not in said and time.monotonic() < deadline:
            said += capsys.readouterr().err
            time.sleep(0.05)
        assert f"waiting for another leaderboard run to finish with {out}" in said
        assert not taken.is_set(), "the second waits while the first holds the lock"
    waiting.join(timeout=60)
    assert taken.is_set()


def test_a_soccer_task_gets_no_video_and_its_row_breaks_nothing(tmp_path):
    """--videos with a soccer task: its finished row (rated in matches, no mean return) makes no video."""
    plan = leaderboard.Plan(("soccer/xjus",), ("ppo",), (0,), (("soccer/xjus", 10),), None, 2, 1000, None)
    row = leaderboard.Row("soccer/xjus", "ppo", 0)
    assert leaderboard.task_video(plan, "soccer/xjus", tmp_path, {row: {"soccer": True, "elo": 785.0}}, 1) is None
    assert not (tmp_path / "videos").exists()


def test_a_command_of_one_row_leaves_the_video_to_a_better_row_recorded_before(tmp_path):
    """The task's video shows its best finished row over every record under the plan's settings: a command that
    computes one worse row (its model at hand) does not take the video from a better one it did not plan."""
    plan = leaderboard.Plan((WALK,), ("ppo",), (0,), ((WALK, 100),), None, 2, 1000, None)
    worse, better = leaderboard.Row(WALK, "ppo", 0), leaderboard.Row(WALK, "ppo+residual", 0)
    records = tmp_path / "records"
    for row, mean in ((worse, 1.0), (better, 2.0)):
        path = leaderboard.row_file(records, row)
        path.parent.mkdir(parents=True)
        record = {"task": WALK, "algo": row.algo, "seed": 0, "mean_return": mean, "settings": plan.row_settings(WALK)}
        path.write_text(json.dumps(record))
    other = leaderboard.Row(WALK, "sac", 0)  # another budget's record: not this table's, whatever its return
    leaderboard.row_file(records, other).parent.mkdir(parents=True)
    leaderboard.row_file(records, other).write_text(json.dumps({**record, "algo": "sac", "mean_return": 9.0,
                                                                "settings": {"timesteps": 5}}))  # fmt: skip
    marker = leaderboard.video_marker(records, WALK)
    marker.parent.mkdir(parents=True)
    marker.write_text(better.name + "\n")
    (tmp_path / "runs" / worse.name).mkdir(parents=True)
    (tmp_path / "runs" / worse.name / "model.zip").write_bytes(b"a model")  # the planned row's run is at hand
    rows = {worse: json.loads(leaderboard.row_file(records, worse).read_text())}
    folder = leaderboard.task_video(plan, WALK, tmp_path, rows, 1, records)
    assert folder == tmp_path / "videos" / WALK.replace("/", "_") and not folder.exists(), "nothing made again"
    assert marker.read_text() == better.name + "\n"


def test_the_page_names_a_video_whose_run_is_not_kept_instead_of_linking_to_nothing(tmp_path):
    """A fresh checkout has a row's video marker but neither the run that made the mp4 nor a published copy: the
    page says so and how to make it, and a published video is still linked."""
    docs, out, records = tmp_path / "docs" / "results.md", tmp_path / "run", tmp_path / "records"
    media = docs.with_suffix("")
    for task in ("skitter_Kept-v1", "skitter_Gone-v1"):
        (records / "videos" / task).mkdir(parents=True)
        (records / "videos" / task / "row.txt").write_text(f"{task}__ppo__0\n")
    (media / "videos").mkdir(parents=True)
    (media / "videos" / "skitter_Kept-v1.mp4").write_bytes(b"published")
    text = "\n".join(
        f"- `{t}`: [the reference and {t}__ppo__0](videos/{t}/eval/videos/side_by_side.mp4)"
        for t in ("skitter_Kept-v1", "skitter_Gone-v1")
    )
    page = leaderboard.publish_media(text, out, docs, records)
    assert "[the reference and skitter_Kept-v1__ppo__0](results/videos/skitter_Kept-v1.mp4)" in page
    assert "side_by_side.mp4" not in page, "no link into a run folder that is not there"
    assert "`skitter_Gone-v1`: no video: skitter_Gone-v1__ppo__0's run" in page and "--rerun" in page


def test_a_residual_variant_is_compared_with_its_plain_algorithm_where_both_have_rows(tmp_path):
    """Per task with rows of both: each one's IQM and interval, told apart only by intervals of two seeds or more that
    do not overlap; one seed on a side is said to tell nothing; a task missing one of them is counted out."""
    xjus = "skitter/XjusWalk-v1"
    plan = leaderboard.Plan((WALK, xjus), ("ppo", "ppo+residual"), (0, 1, 2), ((WALK, 100), (xjus, 100)), None, 5,
                            1000, None)  # fmt: skip
    baselines = {t: {"reference": "gait", "reference_return": 110.0, "random_return": 10.0} for t in plan.tasks}
    rows = {}
    for row in plan.rows:
        if row.task == xjus and (row.algo == "ppo+residual" or row.seed > 0):
            rows[row] = None  # xJüs: one plain seed, no residual row
            continue
        level = 2.0 if row.algo == "ppo+residual" else 1.0  # the residual well ahead on the walk
        rows[row] = {"mean_return": 10.0 + 100.0 * (level + 0.01 * row.seed), "timesteps": 100, "capped": False,
                     "paired_differences": {}}  # fmt: skip
    leaderboard.build_table(plan, tmp_path, baselines, rows, tmp_path / "results.md")
    text = (tmp_path / "results.md").read_text()
    assert "ppo+residual against ppo, on the 1 of 2 tasks with rows of both" in text
    assert f"- `{WALK}`: ppo+residual 2.01 [" in text and "(3 seeds) against ppo 1.01 [" in text
    assert text.count("the residual ahead") == 1 and f"`{xjus}`: ppo+residual" not in text
    # one seed on a side tells nothing, whatever the gap
    one = {r: (v if r.seed == 0 else None) for r, v in rows.items()}
    leaderboard.build_table(plan, tmp_path, baselines, one, tmp_path / "results.md")
    text = (tmp_path / "results.md").read_text()
    assert "not told apart: one seed on a side" in text
    # a bootstrap of one run has no spread: the score alone, not a zero-width interval
    assert f"- `{WALK}`: ppo+residual 2.00 (1 seed) against ppo 1.00 (1):" in text
    assert "| 1.00 (1 of 3 seeds: no interval) | 2.00 (1 of 3 seeds: no interval) |" in text


def test_a_record_judged_with_bootstrap_intervals_gets_a_proportions_where_its_numbers_determine_them(tmp_path):
    """An academy row judged when a success's and a fall's intervals were a bootstrap's: the summaries get Wilson's
    (from mean and count), the paired falls that agreed on every seed get Newcombe's (0 +- 0.16, not [0, 0]); the
    paired success, whose pairs disagreed, keeps its bootstrap interval and says so, unless the evaluation's
    episodes are kept, from which it is computed. The record is written, once."""
    from agents.evaluation import Z95, paired_proportion_ci

    task = "skitter/RoachGoToBall-v5"
    row = leaderboard.Row(task, "ppo", 0)
    records, out = tmp_path / "records", tmp_path / "board"
    point = {"mean": 0.0, "ci_low": 0.0, "ci_high": 0.0, "n": 20}
    record = {"task": task, "algo": "ppo", "seed": 0, "returns": [1.0] * 20,
              "summary": {"falls": dict(point), "success": {"mean": 0.75, "ci_low": 0.55, "ci_high": 0.9, "n": 20}},
              "paired_differences": {"falls": dict(point),
                                     "success": {"mean": -0.2, "ci_low": -0.4, "ci_high": -0.05, "n": 20}}}  # fmt: skip
    updated = leaderboard.backfill_intervals(row, record, out, records)
    wilson = 1 - 20 / (20 + Z95**2)
    assert updated["summary"]["falls"]["ci_high"] == pytest.approx(wilson)
    assert (updated["paired_differences"]["falls"]["ci_low"], updated["paired_differences"]["falls"]["ci_high"]) == (
        pytest.approx(-wilson),
        pytest.approx(wilson),
    )
    assert updated["paired_differences"]["success"]["ci_low"] == -0.4
    assert updated["bootstrap_intervals_kept"] == ["eval:success"] and updated["intervals"] == leaderboard.INTERVALS
    assert json.loads(leaderboard.row_file(records, row).read_text()) == updated
    assert leaderboard.backfill_intervals(row, updated, out, records) is updated  # done once
    # the evaluation kept: the paired success from its episodes (the reference scores on every seed, the model on 16)
    evaluation = out / "rows" / row.name / "eval"
    evaluation.mkdir(parents=True)
    episodes = {"scripted": [{"seed": s, "metrics": {"return": 1.4, "success": 1.0, "falls": 0.0}} for s in range(20)],
                "model.zip": [{"seed": s, "metrics": {"return": 1.0, "success": float(s < 16), "falls": 0.0}}
                              for s in range(20)]}  # fmt: skip
    (evaluation / "results.json").write_text(
        json.dumps({"policies": {k: {"episodes": v} for k, v in episodes.items()}})
    )
    again = leaderboard.backfill_intervals(row, record, out, records)
    expected = paired_proportion_ci(np.ones(20), np.r_[np.ones(16), np.zeros(4)])
    assert (again["paired_differences"]["success"]["ci_low"], again["paired_differences"]["success"]["ci_high"]) == (
        pytest.approx(expected[0]),
        pytest.approx(expected[1]),
    )
    assert "bootstrap_intervals_kept" not in again


def test_the_docs_page_links_every_task_of_the_plan_to_the_section_that_discusses_its_rows(tmp_path):
    """Each task of the whole plan (the command that reproduces docs/results.md) links to a section of a guide beside
    the page, by that section's heading; a folder without the guides gets no paragraph (a run's own --out page)."""
    import re

    command = re.search(r"Reproduce the table: `([^`]+)`", (ROOT / "docs" / "results.md").read_text()).group(1)
    tasks = command.split(" --tasks ")[1].split(" --")[0].split()
    assert len(tasks) > 10 and "soccer/bioloid" in tasks
    text = leaderboard.discussion(tasks, ROOT / "docs")
    links = dict(re.findall(r"\]\(([\w.]+#[\w-]+)\) \(([^)]*)\)", text))
    assert sorted(t for ts in links.values() for t in re.findall(r"`([^`]+)`", ts)) == sorted(tasks)
    for link in links:
        guide, anchor = link.split("#")
        headings = [line.lstrip("#").strip() for line in (ROOT / "docs" / guide).read_text().splitlines()
                    if line.startswith("#")]  # fmt: skip
        slugs = {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in headings}
        assert anchor in slugs, (link, sorted(slugs))
    assert leaderboard.discussion(tasks, tmp_path) == ""
