"""agents.optimize: the Bioloid report's PSO and CMA-ES improve on a tiny budget, a killed run resumes to what an
uninterrupted run gives, the Ray backend equals the local batch, the distance travelled [bioloid-webots, eq. 17],
randomized rollouts, one run per folder, and the command line's one-line errors."""

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from agents.optimize.__main__ import main
from agents.optimize.optimizers import PSO
from agents.optimize.problem import ConfigError, Evaluator, distance_travelled, parse_config, read_config
from agents.optimize.run import LocalBackend, RayBackend, RunError, Settings, run
from envs.common.cluster import init_ray
from envs.common.io import folder_lock
from tests.conftest import main_in_process

ROOT = Path(__file__).resolve().parents[1]
TINY = {"env": "skitter/BioloidWalk-v2", "controller": "cpg", "coupling": "experiment5", "seconds": 8.0,
        "objective": "forward", "sample_interval": 1.0}  # fmt: skip


def write_config(tmp_path: Path, **change) -> Path:
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps({**TINY, **change}))
    return path


def cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "agents.optimize", "--no-progress", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout)  # fmt: skip


def cli_here(*args: str) -> subprocess.CompletedProcess:
    """``python -m agents.optimize``'s ``main`` in the test's process: the inputs it refuses before anything runs, and
    the runs that need no process of their own (a killed run, a run refused by another's lock and the Ray cases
    use :func:`cli`)."""
    return main_in_process(main, ["--no-progress", *args])


def test_distance_travelled_is_the_straight_plus_the_integrated_distance():
    square = np.array([[[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]]], dtype=float)  # back where it started
    assert distance_travelled(square)[0] == pytest.approx(4.0)
    line = np.array([[[0, 0], [0.5, 0], [1.0, 0]]])
    assert distance_travelled(line)[0] == pytest.approx(2.0)
    backward = -line
    assert distance_travelled(backward)[0] == distance_travelled(line)[0], "it rewards walking backward as much"


def test_the_objectives_earlier_name_eq17_is_read_with_a_warning(tmp_path):
    path = write_config(tmp_path, objective="eq17")
    with pytest.warns(FutureWarning, match=r"tiny.json: field 'objective': 'eq17' is a deprecated name of "
                      r"'distance_travelled'"):  # fmt: skip
        config = read_config(path)
    assert config.objective == "distance_travelled"
    shipped = sorted((ROOT / "agents" / "bioloid" / "optimize").glob("*.json"))
    assert shipped and all(json.loads(p.read_text())["objective"] != "eq17" for p in shipped)
    done = cli_here("--config", str(path), "--iterations", "1", "--particles", "1", "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and done.stderr.splitlines()[0].startswith("python -m agents.optimize: warning: "), (
        done.stderr
    )


def test_a_key_given_twice_in_a_config_is_refused_naming_file_and_key(tmp_path):
    path = tmp_path / "twice.json"
    path.write_text('{"env": "skitter/BioloidWalk-v2", "controller": "cpg", "coupling": "experiment5", '
                    '"seconds": 8, "seconds": 1}')  # fmt: skip
    with pytest.raises(ConfigError, match=r"twice.json: key 'seconds' is given twice"):
        read_config(path)
    nested = tmp_path / "nested.json"
    nested.write_text(json.dumps(TINY)[:-1] + ', "env_kwargs": {"knee_wedge": true, "knee_wedge": false}}')
    done = cli_here("--config", str(nested), "--iterations", "1", "--particles", "4", "--out", str(tmp_path / "out"))
    assert done.returncode == 2 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"{nested}: key 'knee_wedge' is given twice" in done.stderr
    assert not (tmp_path / "out").exists()


def test_randomize_and_reset_noise_in_env_kwargs_change_the_rollouts_reproducibly():
    """Domain randomization per particle and iteration: the same draw key gives the same scores, another key and
    every particle its own physics; without them the scores are the nominal ones."""
    params = np.full((3, 16), 0.5)  # three copies of one controller: nominal rollouts score alike
    nominal = Evaluator(parse_config({**TINY, "seconds": 2.0}), 3, nthread=1).evaluate(params, (0, 0))
    assert np.ptp(nominal["progress_x"]) == 0
    for kwargs in ({"randomize": {"body_mass": [0.55, 0.85], "foot_friction": [0.5, 1.5]}},
                   {"reset_noise_scale": 1.0}):  # fmt: skip
        evaluator = Evaluator(parse_config({**TINY, "seconds": 2.0, "env_kwargs": kwargs}), 3, nthread=1)
        a = evaluator.evaluate(params, (0, 0))
        assert np.ptp(a["progress_x"]) > 1e-6, f"{kwargs}: every particle its own draw"
        assert not np.allclose(a["progress_x"], nominal["progress_x"]), kwargs
        assert np.array_equal(evaluator.evaluate(params, (0, 0))["progress_x"], a["progress_x"]), kwargs
        assert not np.array_equal(evaluator.evaluate(params, (0, 1))["progress_x"], a["progress_x"]), kwargs
        # a worker's share (rows from ``first``) draws what those rows drew in the whole batch
        share = Evaluator(parse_config({**TINY, "seconds": 2.0, "env_kwargs": kwargs}), 1, nthread=1)
        assert share.evaluate(params[2:], (0, 0), first=2)["progress_x"][0] == a["progress_x"][2], kwargs


def test_a_second_run_into_a_folder_in_use_is_refused_in_one_line(tmp_path):
    config = write_config(tmp_path, seconds=0.5, sample_interval=0.5)
    out = tmp_path / "run"
    with folder_lock(out, "python -m agents.optimize"):  # another run holds the folder
        done = cli("--config", str(config), "--iterations", "1", "--particles", "2", "--out", str(out))
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"{out} is in use by another python -m agents.optimize run" in done.stderr
    assert sorted(os.listdir(out)) == [".lock"]
    again = cli_here("--config", str(config), "--iterations", "1", "--particles", "2", "--out", str(out))
    assert again.returncode == 0, again.stderr  # free again: the lock file alone is not a foreign folder
    assert (out / "best.json").is_file()


def test_a_finished_run_whose_best_json_is_lost_writes_it_again(tmp_path):
    config = write_config(tmp_path, seconds=0.5, sample_interval=0.5)
    out = tmp_path / "run"
    args = ("--config", str(config), "--iterations", "1", "--particles", "2", "--out", str(out))
    assert cli_here(*args).returncode == 0
    first = json.loads((out / "best.json").read_text())
    (out / "best.json").unlink()
    again = cli_here(*args)
    assert again.returncode == 0, again.stderr
    assert f"policy {out / 'best.json'}" in again.stdout
    assert json.loads((out / "best.json").read_text()) == first


def test_the_default_out_is_in_the_working_folder(tmp_path, monkeypatch):
    config = write_config(tmp_path, seconds=0.5, sample_interval=0.5)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["--config", str(config), "--iterations", "1", "--particles", "2", "--no-progress"]) == 0
    assert (work / "runs" / "optimize" / "tiny__pso__0" / "best.json").is_file()


def test_without_a_progress_bar_a_run_prints_a_line_of_progress(tmp_path, monkeypatch, capsys):
    """With ``--no-progress`` (or output to a file) each iteration, here every one, is a line: how many of the run's
    iterations are done, the rate and the best score so far."""
    from envs.common import io

    monkeypatch.setattr(io, "PROGRESS_SECONDS", 0.0)
    config = write_config(tmp_path, seconds=0.5, sample_interval=0.5)
    args = ["--config", str(config), "--iterations", "2", "--particles", "2", "--out", str(tmp_path / "run")]
    assert main([*args, "--no-progress"]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("iteration ")]
    assert [line.split(" (")[0] for line in lines] == ["iteration 1 of 2", "iteration 2 of 2"]
    assert " left (ends about " in lines[0] and lines[-1].split(", ")[-1].startswith("best score ")


def test_pso_inertia_decreases_and_the_social_term_follows_the_best_of_the_nearest():
    pso = PSO(dimension=2, particles=6, iterations=5, seed=0, neighbours=3)
    assert pso.inertia() == pytest.approx(0.9)
    x = pso.ask()
    scores = -np.linalg.norm(x - 0.5, axis=1)
    pso.tell(scores)
    assert pso.inertia() == pytest.approx(0.9 - 0.5 / 4)
    for _ in range(3):
        pso.tell(-np.linalg.norm(pso.ask() - 0.5, axis=1))
    assert pso.inertia() == pytest.approx(0.4)
    assert ((pso.x >= 0) & (pso.x <= 1)).all()


@pytest.mark.parametrize("optimizer", ["pso", "cmaes"])
def test_optimizers_improve_the_objective_on_a_tiny_budget(tmp_path, optimizer):
    """10 particles x 5 iterations x 4 s: the best forward progress at the end beats the first iteration's best."""
    config = parse_config({**TINY, "seconds": 4.0})
    settings = Settings(config.to_dict(), optimizer, 5, 10, 1)
    result = run(config, settings, tmp_path / optimizer, lambda: LocalBackend(config, 10, 2), progress=False)
    best = [row["best_so_far"] for row in result["history"]]
    assert len(best) == 5 and best == sorted(best)
    assert best[-1] > best[0], best
    policy = json.loads((tmp_path / optimizer / "best.json").read_text())
    assert policy["policy"] == "cpg" and len(policy["parameters"]) == 16
    assert policy["score"] == pytest.approx(best[-1])
    # the policy file replays its score through the evaluator: same parameters, same rollout
    again = Evaluator(config, 1, nthread=1).evaluate(np.array([policy["parameters"]]))
    assert again["score"][0] == pytest.approx(policy["score"], abs=1e-12)


def test_a_killed_run_resumes_from_its_checkpoint_to_the_uninterrupted_result(tmp_path):
    config = write_config(tmp_path, seconds=2.0)
    args = ["--config", str(config), "--optimizer", "pso", "--iterations", "8", "--particles", "6", "--seed", "3",
            "--workers", "1"]  # fmt: skip
    # the kill needs a process of its own; the uninterrupted run and the resume run main in this process
    straight = cli_here(*args, "--out", str(tmp_path / "straight"))
    assert straight.returncode == 0, straight.stderr
    killed = tmp_path / "killed"
    process = subprocess.Popen([sys.executable, "-m", "agents.optimize", "--no-progress", *args, "--out", str(killed)],
                               cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    deadline = time.monotonic() + 120
    while not (killed / "history.json").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)  # as soon as the first checkpoint is in: the run is far from done
    process.wait()
    done_before = len(json.loads((killed / "history.json").read_text())["history"])
    assert 1 <= done_before < 8, "the run was killed part of the way"
    resumed = cli_here(*args, "--out", str(killed))
    assert resumed.returncode == 0, resumed.stderr
    a = json.loads((tmp_path / "straight" / "history.json").read_text())
    b = json.loads((killed / "history.json").read_text())
    assert a["history"] == b["history"]
    best_a = json.loads((tmp_path / "straight" / "best.json").read_text())
    best_b = json.loads((killed / "best.json").read_text())
    assert best_a["parameters"] == best_b["parameters"] and best_a["score"] == best_b["score"]


def test_the_ray_backend_gives_the_local_batchs_result():
    import ray  # a dependency (pyproject.toml): its test never skips

    config = parse_config({**TINY, "seconds": 3.0})
    settings = Settings(config.to_dict(), "pso", 2, 6, 5)
    init_ray(num_cpus=2)
    try:
        import tempfile

        with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
            local = run(config, settings, Path(a), lambda: LocalBackend(config, 6, 1), progress=False)
            spread = run(config, settings, Path(b), lambda: RayBackend(config, 6, workers=2), progress=False)

        # a local instance's workers run at the driver's priority (Ray's default niceness, 15, starves them beside
        # other work: envs/common/cluster.py)
        def niceness() -> int:  # defined here: shipped to the worker by value
            return os.nice(0)

        assert ray.get(ray.remote(num_cpus=1)(niceness).remote()) == niceness()
    finally:
        ray.shutdown()
    assert local["history"] == spread["history"]
    assert local["best"] == spread["best"]


def test_a_checkpoint_resumes_only_under_its_own_settings(tmp_path):
    config = parse_config({**TINY, "seconds": 1.0})
    out = tmp_path / "run"
    run(config, Settings(config.to_dict(), "pso", 1, 4, 0), out, lambda: LocalBackend(config, 4, 1), progress=False)
    with pytest.raises(RunError, match="particles = 4, not 5"):
        run(config, Settings(config.to_dict(), "pso", 1, 5, 0), out, lambda: LocalBackend(config, 5, 1))
    other = parse_config({**TINY, "seconds": 2.0})
    with pytest.raises(RunError, match="'seconds'"):
        run(other, Settings(other.to_dict(), "pso", 1, 4, 0), out, lambda: LocalBackend(other, 4, 1))


@pytest.mark.parametrize(
    ("change", "args", "message"),
    [
        ({"objective": "distance"}, [], "field 'objective'"),
        ({"env": "skitter/NoSuchRobot-v0"}, [], "field 'env'"),
        ({"controller": "buehler"}, [], "field 'controller'"),
        ({"coupling": "no_such_coupling"}, [], "no_such_coupling"),
        ({"seconds": -4}, [], "field 'seconds'"),
        ({}, ["--particles", "1"], "--particles"),
        ({}, ["--iterations", "0"], "--iterations"),
        ({}, ["--address", "10.0.0.1:6379"], "--address"),
        ({}, ["--backend", "ray", "--address", "head-node"], "--address 'head-node': expected HOST:PORT"),
        ({}, ["--seed", "-1"], "--seed must be in [0, 4294967295], got -1"),
        ({}, ["--seed", str(2**32)], "--seed"),
        ({}, ["--particles", "0"], "--particles"),
        ({}, ["--workers", "0"], "--workers"),
        ({}, ["--stop-after", "0"], "--stop-after"),
        ({}, ["--particles", "100000"], "--particles must be in [2, 1024] (one simulation each), got 100000"),
        ({}, ["--iterations", "10000000"], "--iterations must be in [1, 100000], got 10000000"),
        ({}, ["--workers", "100000"], "--workers must be in [1, 1024] for the local backend, got 100000"),
        ({}, ["--stop-after", "10000000"], "--stop-after must be in [1, 100000]"),
    ],
)
def test_bad_configs_and_flags_are_one_line_errors_before_anything_is_made(tmp_path, change, args, message):
    config = write_config(tmp_path, **change)
    out = tmp_path / "out"
    done = cli_here("--config", str(config), "--iterations", "1", "--particles", "4", *args, "--out", str(out))
    assert done.returncode == 2, done.stderr
    assert message in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not out.exists()


def test_stop_after_pauses_a_run_that_the_same_call_resumes(tmp_path):
    config = parse_config({**TINY, "seconds": 1.0})
    settings = Settings(config.to_dict(), "cmaes", 3, 4, 2)
    paused = run(config, settings, tmp_path / "a", lambda: LocalBackend(config, 4, 1), progress=False, stop_after=1)
    assert not paused["finished"] and len(paused["history"]) == 1
    resumed = run(config, settings, tmp_path / "a", lambda: LocalBackend(config, 4, 1), progress=False)
    straight = run(config, settings, tmp_path / "b", lambda: LocalBackend(config, 4, 1), progress=False)
    assert resumed["finished"] and resumed["history"] == straight["history"]


@pytest.mark.parametrize(
    ("env_kwargs", "args", "message"),
    [
        ({"knee_wedge": "yes"}, [], "knee_wedge must be True or False, got 'yes'"),
        ({"knee_wedge": "yes"}, ["--backend", "ray"], "knee_wedge must be True or False, got 'yes'"),
        ({"calibration": "no_such_calibration.json"}, [], "no such calibration file"),
        ({"calibration": "not_a_calibration.json"}, [], "field 'format'"),
        ({"legs": 8}, [], "BioloidWalkEnv takes no keyword 'legs'"),
    ],
)
def test_bad_env_kwargs_are_one_line_errors_naming_the_config_and_field(tmp_path, env_kwargs, args, message):
    (tmp_path / "not_a_calibration.json").write_text('{"robot": "bioloid"}')
    if "calibration" in env_kwargs:
        env_kwargs = {"calibration": str(tmp_path / env_kwargs["calibration"])}
    config = write_config(tmp_path, env_kwargs=env_kwargs)
    out = tmp_path / "out"
    run_cli = cli if "ray" in args else cli_here  # the Ray case starts its cluster: in a process of its own
    done = run_cli("--config", str(config), "--iterations", "1", "--particles", "4", *args, "--out", str(out))
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"{config}: field 'env_kwargs' = {env_kwargs!r}: " in done.stderr and message in done.stderr
    assert not out.exists()


def test_an_out_that_is_a_file_is_refused_and_left_alone(tmp_path):
    config = write_config(tmp_path)
    mine = tmp_path / "notes.txt"
    mine.write_text("keep")
    for out in (mine, mine / "run"):
        done = cli_here("--config", str(config), "--iterations", "1", "--particles", "4", "--out", str(out))
        assert done.returncode == 2, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert f"--out {out}: {mine} is a file, not a directory" in done.stderr
    assert mine.read_text() == "keep"


def _checkpoint(**change) -> bytes:
    settings = Settings(parse_config({**TINY}).to_dict(), "pso", 1, 4, 0).as_dict()
    state = {"version": 1, "settings": settings, "optimizer": PSO(16, 4, 1, 0), "best": None, "history": [],
             "wall_seconds": 0.0, **change}  # fmt: skip
    return pickle.dumps(state)


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        pytest.param(b"\x80\x04garbage", "not a readable checkpoint (UnpicklingError", id="garbage"),
        pytest.param(_checkpoint()[:40], "not a readable checkpoint", id="truncated"),
        pytest.param(b"", "not a readable checkpoint (EOFError", id="empty"),
        pytest.param(pickle.dumps([1, 2]), "not a checkpoint of this version of agents.optimize", id="a list"),
        pytest.param(pickle.dumps({"version": 1}), "it has no 'settings', 'optimizer', 'best', 'history', "
                     "'wall_seconds'", id="missing keys"),
        pytest.param(_checkpoint(settings={"seed": 0}), "its 'settings' are not a dict of config, iterations",
                     id="settings"),
        pytest.param(_checkpoint(optimizer="pso"), "its 'optimizer' is a str, not the 'pso' of its settings",
                     id="optimizer"),
        pytest.param(_checkpoint(best={"score": 1.0}), "its 'best' is not None nor a dict", id="best"),
        pytest.param(_checkpoint(history={}), "its 'history' is a dict, not a list", id="history"),
    ],
)  # fmt: skip
def test_a_damaged_checkpoint_is_refused_naming_it_and_left_alone(tmp_path, content, reason):
    config = write_config(tmp_path)
    out = tmp_path / "run"
    out.mkdir()
    (out / "checkpoint.pkl").write_bytes(content)
    done = cli_here("--config", str(config), "--iterations", "1", "--particles", "4", "--out", str(out))
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert f"cannot resume from {out / 'checkpoint.pkl'}: {reason}" in done.stderr
    assert os.listdir(out) == ["checkpoint.pkl"] and (out / "checkpoint.pkl").read_bytes() == content


def test_a_run_from_before_the_objectives_rename_resumes_under_its_new_name(tmp_path, capsys):
    config = write_config(tmp_path, seconds=0.5, sample_interval=0.5, objective="distance_travelled")
    out = tmp_path / "run"
    args = ["--config", str(config), "--iterations", "1", "--particles", "2", "--out", str(out), "--no-progress"]
    assert main(args) == 0
    state = pickle.loads((out / "checkpoint.pkl").read_bytes())
    state["settings"]["config"]["objective"] = "eq17"  # as a run of the earlier name wrote it
    metrics = state["best"]["metrics"]
    metrics["eq17"] = metrics.pop("distance_travelled")
    (out / "checkpoint.pkl").write_bytes(pickle.dumps(state))
    capsys.readouterr()
    assert main(args) == 0
    assert f"distance travelled {metrics['eq17']:.3f} m" in capsys.readouterr().out
