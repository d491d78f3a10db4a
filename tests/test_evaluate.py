"""evaluate.py end to end, as a user runs it."""

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers the envs)
from agents import reference_policy
from tests.conftest import ENV_IDS, main_in_process

ROOT = Path(__file__).resolve().parents[1]


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


def run_here(*args: str) -> subprocess.CompletedProcess:
    """evaluate.py's ``main`` in this process: what the command line does, without a new process loading torch (the
    tests that need the command line itself use :func:`run`)."""
    import evaluate

    return main_in_process(evaluate.main, list(args))


@pytest.fixture(scope="module")
def model_zip(tmp_path_factory) -> Path:
    """A tiny PPO run, trained by ``train.main`` in this process (the model is what the tests here need; train.py's
    command line is tested in tests/test_train.py)."""
    from agents import training

    runs = tmp_path_factory.mktemp("runs")
    hp = runs / "ppo.yml"
    hp.write_text("skitter/RoachWalk-v4:\n  n_envs: 1\n  n_steps: 64\n  batch_size: 32\n  normalize: true\n")
    done = main_in_process(training.main, [
        "--env", "skitter/RoachWalk-v4", "--algo", "ppo", "--timesteps", "128", "--seed", "0", "--hyperparams",
        str(hp), "--runs-dir", str(runs), "--run-name", "tiny", "--checkpoint-freq", "64", "--no-progress",
    ])  # fmt: skip
    assert done.returncode == 0, done.stderr
    return runs / "tiny" / "model.zip"


def test_compares_a_scripted_gait_and_a_trained_model_on_the_same_seeds(model_zip, tmp_path, capsys):
    """In this process (``run_here``): the comparison is what is tested; the command line itself is run by
    test_bad_input_gets_a_clear_message_and_no_traceback."""
    out = tmp_path / "walk"
    done = run_here("--env", "skitter/RoachWalk-v4", "--policy", "tripod:20", "--policy", str(model_zip),
                    "--episodes", "3", "--seed", "5", "--out", str(out), "--max-episode-steps", "30", "--video",
                    "--telemetry")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "tripod:20" in done.stdout and "speed_bl" in done.stdout and "[" in done.stdout  # the table, with CIs
    results = json.loads((out / "results.json").read_text())
    assert results["seeds"] == [5, 6, 7]
    with gym.make("skitter/RoachWalk-v4") as env:
        weight = env.unwrapped.metrics_context()["mass"] * 9.81
    for spec in ("tripod:20", str(model_zip)):
        policy = results["policies"][spec]
        assert [e["seed"] for e in policy["episodes"]] == [5, 6, 7]
        assert all(e["length"] == 30 for e in policy["episodes"])
        s = policy["summary"]["speed"]
        assert s["n"] == 3 and s["ci_low"] <= s["mean"] <= s["ci_high"]
        for metric in ("return", "speed", "speed_bl", "cost_of_transport", "power", "energy", "falls", "forward_speed"):
            assert metric in policy["summary"]
        # the mean power is the energy over the time: the cost of transport's energy (m g CoT distance), per second
        for e in policy["episodes"]:
            m = e["metrics"]
            if m["cost_of_transport"] is not None and m["speed"] > 0:
                assert m["power"] == pytest.approx(m["cost_of_transport"] * weight * m["speed"], rel=1e-6)
            assert m["energy"] == pytest.approx(m["power"] * e["duration"], rel=1e-6)  # the episode's energy, J
        # the ground rules' metrics: the tripod's legs only touch the ground, its body rides at its standing height
        assert policy["summary"]["non_foot_contact"]["mean"] <= 1.0 and 0.0 < policy["summary"]["body_height"]["mean"]
    assert results["policies"]["tripod:20"]["summary"]["non_foot_contact"]["mean"] == 0.0
    assert results["policies"]["tripod:20"]["summary"]["body_height"]["mean"] == pytest.approx(0.016, abs=0.003)
    tripod = results["policies"]["tripod:20"]["summary"]["speed"]["mean"]
    assert tripod > 0.5, "the 20 Hz tripod runs forward"
    diff = results["paired_differences"]["policies"][str(model_zip)]["speed"]
    assert diff["n"] == 3
    assert (out / "results.md").read_text().startswith("# skitter/RoachWalk-v4")
    pngs = sorted(p.name for p in (out / "plots").iterdir())
    assert len(pngs) == 2 and all(p.endswith(".png") for p in pngs)
    mp4s = sorted((out / "videos").glob("*.mp4"))
    assert len(mp4s) == 3 and all(p.stat().st_size > 1000 for p in mp4s)
    import imageio.v2 as imageio

    with imageio.get_reader(mp4s[0]) as reader:  # the start and every 2nd of 30 control steps: 25 frames/s at 50 Hz
        assert reader.count_frames() == 1 + 30 // 2
        assert reader.get_meta_data()["fps"] == pytest.approx(25.0)
        single = reader.get_meta_data()["size"]
    with imageio.get_reader(out / "videos" / "side_by_side.mp4") as reader:  # both policies, left to right
        assert reader.count_frames() == 1 + 30 // 2 and reader.get_meta_data()["size"] == (2 * single[0], single[1])
    assert len(list((out / "telemetry").glob("*.parquet"))) == 2
    assert not [p for p in tmp_path.iterdir() if p.name != "walk"], "no temporary folder left beside the results"
    # a second run into the same directory is refused, not silently overwritten
    again = run_here("--env", "skitter/RoachWalk-v4", "--policy", "tripod:20", "--episodes", "1", "--out",
                     str(out))  # fmt: skip
    assert again.returncode != 0 and "already holds" in again.stderr
    assert json.loads((out / "results.json").read_text())["seeds"] == [5, 6, 7]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_runs_on_every_registered_env(env_id, tmp_path):
    """No robot-specific code: the reference gait, metrics, plots and telemetry on every env (``evaluate.main`` in
    this process: the command line itself is run by the other tests here, each start of it loads torch anew)."""
    import evaluate

    steps = "40" if "Duty" not in env_id else "300"
    gait = reference_policy(gym.make(env_id).unwrapped.robot.name)
    assert evaluate.main(["--env", env_id, "--policy", gait, "--episodes", "2", "--out", str(tmp_path / "r"),
                          "--max-episode-steps", steps, "--telemetry"]) == 0  # fmt: skip
    results = json.loads((tmp_path / "r" / "results.json").read_text())
    summary = results["policies"][gait]["summary"]
    assert set(results["metrics"]) <= set(summary)
    assert summary["speed"]["mean"] > 0
    assert (tmp_path / "r" / "plots" / f"{gait}.png").stat().st_size > 10_000


def test_turn_reports_the_yaw_rate_error(tmp_path):
    import evaluate

    assert evaluate.main(["--env", "skitter/RoachTurn-v5", "--policy", "tripod", "--episodes", "2", "--out",
                          str(tmp_path / "t"), "--max-episode-steps", "100"]) == 0  # fmt: skip
    summary = json.loads((tmp_path / "t" / "results.json").read_text())["policies"]["tripod"]["summary"]
    assert 0 <= summary["yaw_rate_error"]["mean"] < 1.0


def test_two_models_with_the_same_file_name_get_their_own_plots(model_zip, tmp_path):
    """Two runs' checkpoints are both step_N/model.zip: each keeps its plot and telemetry."""
    (checkpoint,) = (model_zip.parent / "checkpoints").glob("step_*64")
    other = tmp_path / "other" / "checkpoints" / checkpoint.name
    shutil.copytree(checkpoint, other)
    out = tmp_path / "both"
    import evaluate

    assert evaluate.main(["--env", "skitter/RoachWalk-v4", "--policy", str(checkpoint / "model.zip"), "--policy",
                          str(other / "model.zip"), "--episodes", "1", "--out", str(out), "--max-episode-steps", "20",
                          "--telemetry"]) == 0  # fmt: skip
    assert len(list((out / "plots").glob("*.png"))) == 2
    assert len(list((out / "telemetry").glob("*.parquet"))) == 2
    files = json.loads((out / "results.json").read_text())["files"]
    assert len(set(files.values())) == 2


def test_a_model_without_its_statistics_is_an_error_not_a_silent_score(model_zip, tmp_path, capsys):
    stripped = tmp_path / "stripped.zip"
    with zipfile.ZipFile(model_zip) as src, zipfile.ZipFile(stripped, "w") as dst:
        for item in src.infolist():
            if item.filename != "vecnormalize.pkl":
                dst.writestr(item, src.read(item))
    done = run_here(
        *("--env", "skitter/RoachWalk-v4", "--policy", str(stripped), "--episodes", "1", "--out", str(tmp_path / "o")),
    )
    assert done.returncode == 2
    assert "lacks the statistics" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "o").exists()


def test_a_truncated_model_is_a_one_line_error(model_zip, tmp_path, capsys):
    truncated = tmp_path / "truncated.zip"
    truncated.write_bytes(model_zip.read_bytes()[: model_zip.stat().st_size // 2])
    args = ("--env", "skitter/RoachWalk-v4", "--policy", str(truncated), "--episodes", "1", "--out", tmp_path / "o")
    done = run_here(*map(str, args))
    assert done.returncode == 2
    assert "truncated or corrupt" in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_a_model_of_another_env_is_refused(model_zip, tmp_path, capsys):
    done = run_here(
        *("--env", "skitter/RoachTurn-v5", "--policy", str(model_zip), "--episodes", "1", "--out", str(tmp_path / "o")),
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "trained on skitter/RoachWalk-v4" in done.stderr and "not on skitter/RoachTurn-v5" in done.stderr


@pytest.mark.parametrize(
    ("args", "message", "command_line"),
    [
        (["--env", "skitter/NoSuchRobot-v0", "--policy", "tripod"], "unknown env 'skitter/NoSuchRobot-v0'", True),
        (["--env", "CartPole-v1", "--policy", "random"], "'CartPole-v1' is not a skitter env", False),
        (["--env", "roachwalk-v3", "--policy", "tripod"], "(did you mean 'skitter/RoachWalk-v4'?)", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "no/such/model.zip"], "no trained model", True),
        (["--env", "skitter/RoachWalk-v4", "--policy", "moonwalk"], "unknown policy", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "0"], "--episodes", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--seed", "-1"], "--seed", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--policy", "tripod"], "given twice", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tripod:fast"], "not a number", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tripod:"], "nothing after ':'", False),
        (["--env", "skitter/RoachWalk-v4", "--policy", "tests"], "is a folder: give the path of a model.zip", False),
        (
            ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--env-kwargs", '{"telemetry": true}'],
            "--env-kwargs 'telemetry': evaluate.py sets it from --telemetry",
            False,
        ),
        (
            [
                "--env",
                "skitter/RoachWalk-v4",
                "--policy",
                "tripod",
                "--max-episode-steps",
                "5",
                "--env-kwargs",
                '{"episode_seconds": 2}',
            ],
            "sets it from --max-episode-steps",
            False,
        ),
    ],
)
def test_bad_input_gets_a_clear_message_and_no_traceback(tmp_path, capsys, args, message, command_line):
    """Two cases from the command line itself (a new process: no traceback reaches the user), the others through
    its ``main`` in this process (where a traceback would fail the test)."""
    where = [*args, "--out", str(tmp_path / "out")]
    done = run(*where) if command_line else run_here(*where)
    assert done.returncode == 2
    assert message in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists(), "nothing is created for bad input"


def test_an_existing_telemetry_file_is_caught_before_any_episode_runs(tmp_path, capsys):
    out = tmp_path / "out"
    (out / "telemetry").mkdir(parents=True)
    (out / "telemetry" / "tripod.parquet").write_bytes(b"a user's file")
    args = ("--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "1", "--out", out, "--telemetry")
    done = run_here(*map(str, args))
    # no results.json beside it: the user's folder, not an earlier run's
    assert done.returncode == 2 and "holds files evaluate.py does not write (telemetry/)" in done.stderr
    assert "Traceback" not in done.stderr
    assert (out / "telemetry" / "tripod.parquet").read_bytes() == b"a user's file"


def test_an_out_path_under_a_file_is_refused_before_any_episode_runs(tmp_path, capsys):
    (tmp_path / "somefile.txt").write_text("a user's file")
    for out, message in [
        (tmp_path / "somefile.txt" / "out", f"{tmp_path / 'somefile.txt'} is a file, not a directory"),
        (tmp_path / "somefile.txt", "exists and is not a directory"),
    ]:
        done = run_here("--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "1", "--out",
                        str(out))  # fmt: skip
        assert done.returncode == 2 and f"--out {out}" in done.stderr and message in done.stderr
        assert "Traceback" not in done.stderr and len(done.stderr.strip().splitlines()) == 1
    assert [p.name for p in tmp_path.iterdir()] == ["somefile.txt"]
    assert (tmp_path / "somefile.txt").read_text() == "a user's file"


def test_overwrite_replaces_only_an_earlier_runs_results(tmp_path, capsys):
    out = tmp_path / "out"
    (out / "plots").mkdir(parents=True)
    (out / "results.json").write_text("{}")
    (out / "plots" / "old.png").write_bytes(b"an earlier plot")
    args = ("--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "1", "--max-episode-steps", "10")
    # without --overwrite: only what is there is named
    done = run_here(*args, "--out", str(out))
    assert done.returncode == 2 and "already holds plots/, results.json of an earlier run" in done.stderr
    assert "results.md" not in done.stderr and "Traceback" not in done.stderr
    # files evaluate.py does not write are never deleted, not even with --overwrite
    (out / "notes.txt").write_text("the user's notes")
    (out / "plots" / "sketch.svg").write_text("the user's sketch")
    done = run_here(*args, "--out", str(out), "--overwrite")
    assert done.returncode == 2 and "notes.txt, plots/sketch.svg" in done.stderr and "--overwrite" in done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "notes.txt", "plots", "plots/old.png", "plots/sketch.svg", "results.json"
    ]  # fmt: skip
    # a folder of its own results is replaced
    (out / "notes.txt").unlink()
    (out / "plots" / "sketch.svg").unlink()
    done = run_here(*args, "--out", str(out), "--overwrite")
    assert done.returncode == 0, done.stderr
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "plots", "plots/tripod.png", "results.json", "results.md"
    ]  # fmt: skip
    assert (out / "results.md").read_text().startswith("# skitter/RoachWalk-v4")


# --- a model must fit --env: train.py's record of it, its spaces; a damaged policy file ---------------------------


def copy_model(src: Path, dst: Path, drop: tuple[str, ...] = (), replace: dict | None = None) -> Path:
    """``src`` rewritten to ``dst`` without the entries ``drop`` and with ``replace``'s entries (name -> bytes)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(src) as source, zipfile.ZipFile(dst, "w") as target:
        for item in source.infolist():
            if item.filename not in drop:
                target.writestr(item.filename, (replace or {}).get(item.filename, source.read(item)))
    return dst


def evaluate_main(capsys, model: Path, out: Path, env_id: str = "skitter/RoachWalk-v4") -> tuple[int, str]:
    from agents import compare as evaluate

    code = evaluate.main(["--env", env_id, "--policy", str(model), "--episodes", "1", "--out", str(out)])
    return code, capsys.readouterr().err


def test_a_model_trained_on_another_env_with_the_same_shapes_is_refused_naming_both(model_zip, tmp_path, capsys):
    """RoachWalk-v0's observations and actions have v1's shapes: only train.py's record tells them apart."""
    with zipfile.ZipFile(model_zip) as archive:
        manifest = json.loads(archive.read("skitter.json"))
    manifest["env_id"] = "skitter/RoachWalk-v0"
    model = copy_model(model_zip, tmp_path / "model.zip", replace={"skitter.json": json.dumps(manifest).encode()})
    code, err = evaluate_main(capsys, model, tmp_path / "out")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "trained on skitter/RoachWalk-v0 (its manifest skitter.json says so), not on skitter/RoachWalk-v4" in err
    assert not (tmp_path / "out").exists()

    # a model without a manifest, in a run folder whose config.json names another env
    run_dir = tmp_path / "run"
    model = copy_model(model_zip, run_dir / "checkpoints" / "step_0000000064" / "model.zip", drop=("skitter.json",))
    config = json.loads((model_zip.parent / "config.json").read_text())
    (run_dir / "config.json").write_text(json.dumps({**config, "env_id": "skitter/RoachWalk-v0"}))
    code, err = evaluate_main(capsys, model, tmp_path / "out")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"trained on skitter/RoachWalk-v0 (its run's {run_dir / 'config.json'} says so)" in err
    assert "not on skitter/RoachWalk-v4" in err and not (tmp_path / "out").exists()


def test_a_damaged_manifest_or_a_zip_that_is_no_model_is_named_for_what_it_is(model_zip, tmp_path, capsys):
    """A manifest field of the wrong type is refused naming it (it was read past); a zip of something else is said
    to be no model, not to hold a corrupt manifest."""
    model = copy_model(model_zip, tmp_path / "model.zip", replace={"skitter.json": b'{"env_id": 5}'})
    code, err = evaluate_main(capsys, model, tmp_path / "out")
    assert code == 2 and "corrupt skitter.json inside the model file (field 'env_id' = 5)" in err, err
    other = tmp_path / "other.zip"
    with zipfile.ZipFile(other, "w") as archive:
        archive.writestr("notes.txt", "not a model")
    code, err = evaluate_main(capsys, other, tmp_path / "out")
    assert code == 2 and "not a Stable-Baselines3 model (no 'data' entry)" in err and "skitter.json" not in err, err
    assert not (tmp_path / "out").exists()


def test_a_model_without_metadata_must_match_the_envs_action_space(model_zip, tmp_path):
    from gymnasium.wrappers import RescaleAction

    from agents.sb3 import ModelFileError, SB3Policy

    foreign = copy_model(model_zip, tmp_path / "zoo" / "model.zip", drop=("skitter.json",))  # no record of its env
    env = gym.make("skitter/RoachWalk-v4")
    assert SB3Policy(foreign, env).predict(env.reset(seed=0)[0])[0].shape == (3,)  # works as before
    with pytest.raises(ModelFileError, match=r"the model acts in Box\(-1\.0, 1\.0, \(3,\), float32\) but .* takes Box"):
        SB3Policy(foreign, RescaleAction(env, np.full(3, -2.0, np.float32), np.full(3, 2.0, np.float32)))


def test_a_corrupt_policy_file_is_named_as_a_policy_file(model_zip, tmp_path, capsys):
    model = copy_model(model_zip, tmp_path / "model.zip", replace={"policy.pth": b"garbage" * 10})
    code, err = evaluate_main(capsys, model, tmp_path / "out")
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert f"--policy '{model}': cannot read policy file {model}: corrupt contents" in err
    assert "checkpoint" not in err and not (tmp_path / "out").exists()


def test_intervals_from_few_episodes_are_not_narrower_than_the_data_allow():
    """A bootstrap from 3 values spans about their min to max (a percentile bootstrap gave [2237.6, 2438.8]
    from three returns whose t interval is [2087, 2587]); one value has no interval at all."""
    from scipy import stats

    from agents.evaluation import MIN_BOOTSTRAP, bootstrap_ci

    x = np.array([2237.6, 2338.0, 2438.8])
    low, high = bootstrap_ci(x)
    half = stats.t.ppf(0.975, 2) * x.std(ddof=1) / np.sqrt(3)
    assert (low, high) == pytest.approx((x.mean() - half, x.mean() + half))
    assert low < x.min() and high > x.max()
    assert all(np.isnan(bootstrap_ci(np.array([810.0]))))
    many = np.random.default_rng(0).normal(size=MIN_BOOTSTRAP)
    assert bootstrap_ci(many) == bootstrap_ci(many, seed=0)  # the bootstrap from MIN_BOOTSTRAP on, seeded


def test_a_proportion_has_wilsons_interval_and_a_paired_difference_newcombes():
    """20 successes of 20 are not certain: Wilson's interval is [n / (n + z^2), 1]; two policies that both succeed in
    every pair differ by 0 +- about 0.16 (Newcombe), where a bootstrap gave the point 0. A value that is not 1 or 0
    is refused."""
    from agents.evaluation import Z95, paired_proportion_ci, proportion_ci

    ones = np.ones(20)
    assert proportion_ci(ones) == pytest.approx((20 / (20 + Z95**2), 1.0))
    assert proportion_ci(np.zeros(20)) == pytest.approx((0.0, 1 - 20 / (20 + Z95**2)))
    low, high = paired_proportion_ci(ones, ones)
    assert low == pytest.approx(-high) and high == pytest.approx(1 - 20 / (20 + Z95**2))
    # 15 of 20 against 20 of 20, the five misses the second's own: the difference -0.25 lies inside, 0 outside
    first, second = ones, np.r_[np.ones(15), np.zeros(5)]
    low, high = paired_proportion_ci(first, second)
    assert low < -0.25 < high < 0.0
    with pytest.raises(ValueError, match="1 or 0"):
        proportion_ci(np.array([0.0, 0.5, 1.0]))


def test_newcombes_interval_covers_a_paired_difference_where_the_bootstrap_does_not():
    """Simulated pairs of 20 episodes (two policies' successes on the same seeds, correlated through shared seeds):
    the interval holds the true difference in 95% of draws or more in every setting, where the bootstrap's falls far
    short near the ends and with correlated pairs."""
    from agents.evaluation import bootstrap_ci, paired_proportion_ci

    rng = np.random.default_rng(0)
    draws, n = 400, 20
    for p_first, p_second, shared in [(0.9, 0.6, 0.5), (0.5, 0.5, 0.3), (0.1, 0.2, 0.0), (0.6, 0.65, 0.9),
                                      (0.98, 0.9, 0.5)]:  # fmt: skip
        held = boot = 0
        for _ in range(draws):
            same = rng.random(n) < shared  # a seed both policies meet alike: one draw decides both
            u = rng.random(n)
            first = np.where(same, u < p_first, rng.random(n) < p_first).astype(float)
            second = np.where(same, u < p_second, rng.random(n) < p_second).astype(float)
            low, high = paired_proportion_ci(first, second)
            held += low <= p_second - p_first <= high
            if shared == 0.9:  # the bootstrap where the pairs are most alike
                d = second - first
                low, high = bootstrap_ci(d) if np.ptp(d) else (d.mean(), d.mean())
                boot += low <= p_second - p_first <= high
        assert held / draws >= 0.93, (p_first, p_second, shared, held / draws)
        if shared == 0.9:
            assert boot / draws < 0.85  # what evaluate.py gave before


def test_a_model_trained_with_env_kwargs_is_evaluated_with_them_or_warned_of(model_zip, tmp_path, capsys):
    """A model trained with env_kwargs (its run's config.json) was evaluated silently on the
    default env. --env-kwargs makes the env as it was trained; a difference is warned of, and a shape mismatch
    names the env_kwargs it was trained with."""
    from agents import compare as evaluate

    run_dir = tmp_path / "run"
    model = copy_model(model_zip, run_dir / "model.zip")
    config = json.loads((model_zip.parent / "config.json").read_text())
    config["hyperparams"]["env_kwargs"] = {"sensor_noise": False}
    (run_dir / "config.json").write_text(json.dumps(config))
    base = ["--env", "skitter/RoachWalk-v4", "--policy", str(model), "--episodes", "1", "--max-episode-steps", "5"]
    code = evaluate.main([*base, "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err
    assert code == 0 and "was trained with env_kwargs {'sensor_noise': False}; it is evaluated with {}" in err
    code = evaluate.main([*base, "--out", str(tmp_path / "b"), "--env-kwargs", '{"sensor_noise": false}'])
    err = capsys.readouterr().err
    assert code == 0 and "warning" not in err
    results = json.loads((tmp_path / "b" / "results.json").read_text())
    assert results["env_kwargs"] == {"sensor_noise": False}
    # another observation than the model's: refused, naming what it was trained with
    code = evaluate.main([*base, "--out", str(tmp_path / "c"), "--env-kwargs", '{"privileged_obs": true}'])
    err = capsys.readouterr().err
    assert code == 2 and "trained with env_kwargs {'sensor_noise': False}: pass them with --env-kwargs" in err
    for bad, message in (('{"legs": 8}', "legs"), ("[1]", "JSON object"), ("{", "not JSON")):
        with pytest.raises(SystemExit) as exit_info:
            evaluate.main([*base, "--out", str(tmp_path / "d"), "--env-kwargs", bad])
        assert exit_info.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "c").exists() and not (tmp_path / "d").exists()


def test_a_plot_group_not_recorded_in_a_run_is_said_so_not_warned_of(tmp_path, recwarn):
    """The xJüs in duty mode records its clock target as NaN; matplotlib warned of an empty legend."""
    env = gym.make("skitter/XjusWalk-v1", action_mode="duty", telemetry=True, max_episode_steps=5)
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample() * 0)
    telemetry = tmp_path / "episode.parquet"
    env.unwrapped.recorder.save(telemetry)
    from agents import compare as evaluate

    evaluate.plot_episode(env.unwrapped.robot, telemetry, tmp_path / "plot.png", "duty mode")
    assert (tmp_path / "plot.png").stat().st_size > 0
    assert not [w for w in recwarn if "legend" in str(w.message)]


def test_videos_are_rendered_at_most_30_frames_a_second():
    from agents.compare import VIDEO_FPS, video_stride

    for control_hz, stride in [(25, 1), (30, 1), (50, 2), (125, 5), (1000, 34)]:
        assert video_stride(control_hz) == stride
        assert control_hz / stride <= VIDEO_FPS


def test_results_are_strict_json_and_a_mean_over_some_episodes_says_how_many(tmp_path, monkeypatch, capsys):
    """An episode without a cost of transport (no distance travelled) has NaN there: results.json writes null (bare
    NaN is not JSON), and the table says that the mean is over the episodes that have one."""
    from agents import compare

    run_episodes = compare.run_episodes

    def first_without_a_distance(*args, **kwargs):
        episodes = run_episodes(*args, **kwargs)
        episodes[0].metrics["cost_of_transport"] = float("nan")  # as episode_metrics gives it for no distance
        return episodes

    monkeypatch.setattr(compare, "run_episodes", first_without_a_distance)
    out = tmp_path / "r"
    argv = ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--policy", "tripod:20", "--episodes", "3",
            "--max-episode-steps", "10", "--out", str(out)]  # fmt: skip
    assert compare.main(argv) == 0
    text = (out / "results.json").read_text()

    def refuse(constant: str):
        raise ValueError(f"{constant} is not JSON")

    results = json.loads(text, parse_constant=refuse)
    tripod = results["policies"]["tripod"]
    assert tripod["episodes"][0]["metrics"]["cost_of_transport"] is None
    assert tripod["summary"]["cost_of_transport"]["n"] == 2
    assert results["paired_differences"]["policies"]["tripod:20"]["cost_of_transport"]["n"] == 2
    assert tripod["summary"]["speed"]["n"] == 3
    table = {line.split(" | ")[0]: line for line in (out / "results.md").read_text().splitlines()}
    assert table["| cost_of_transport"].count("(2 of 3 episodes)") == 2 and "of 3 episodes" not in table["| speed"]
    (paired,) = [line for line in table.values() if line.startswith("| tripod:20 |")]
    assert paired.count("(2 of 3 episodes)") == 1  # the cost of transport's column
    assert (
        "A value marked (n of 3 episodes) is the mean over the n episodes that have the metric"
        in capsys.readouterr().out
    )


def test_telemetry_at_the_physics_rate(tmp_path):
    """``--telemetry-rate physics``: a row per physics step of every control step, the rate in the file's record."""
    import evaluate
    from envs.common.telemetry import read_telemetry

    assert evaluate.main(["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "2", "--out",
                          str(tmp_path / "r"), "--max-episode-steps", "20", "--telemetry", "--telemetry-rate",
                          "physics"]) == 0  # fmt: skip
    df, meta = read_telemetry(tmp_path / "r" / "telemetry" / "tripod.parquet")
    assert meta["rate_hz"] == 2000.0
    assert df.groupby("episode").size().tolist() == [1 + 20 * 40] * 2
