"""evaluate.py end to end, as a user runs it."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(ROOT / "evaluate.py"), *args], cwd=ROOT, capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def model_zip(tmp_path_factory) -> Path:
    runs = tmp_path_factory.mktemp("runs")
    hp = runs / "ppo.yml"
    hp.write_text("skitter/RoachWalk-v0:\n  n_envs: 1\n  n_steps: 64\n  batch_size: 32\n  normalize: true\n")
    done = subprocess.run(
        [sys.executable, str(ROOT / "train.py"), "--env", "skitter/RoachWalk-v0", "--algo", "ppo", "--timesteps",
         "128", "--seed", "0", "--hyperparams", str(hp), "--runs-dir", str(runs), "--run-name", "tiny",
         "--no-progress"],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    return runs / "tiny" / "model.zip"


def test_compares_a_scripted_gait_and_a_trained_model_on_the_same_seeds(model_zip, tmp_path):
    out = tmp_path / "walk"
    done = run("--env", "skitter/RoachWalk-v0", "--policy", "tripod:20", "--policy", str(model_zip),
               "--episodes", "3", "--seed", "5", "--out", str(out), "--max-episode-steps", "60", "--video",
               "--telemetry")  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "tripod:20" in done.stdout and "speed_bl" in done.stdout and "[" in done.stdout  # the table, with CIs
    results = json.loads((out / "results.json").read_text())
    assert results["seeds"] == [5, 6, 7]
    for spec in ("tripod:20", str(model_zip)):
        policy = results["policies"][spec]
        assert [e["seed"] for e in policy["episodes"]] == [5, 6, 7]
        assert all(e["length"] == 60 for e in policy["episodes"])
        s = policy["summary"]["speed"]
        assert s["n"] == 3 and s["ci_low"] <= s["mean"] <= s["ci_high"]
        for metric in ("return", "speed", "speed_bl", "cost_of_transport", "falls"):
            assert metric in policy["summary"]
    tripod = results["policies"]["tripod:20"]["summary"]["speed"]["mean"]
    assert tripod > 0.5, "the 20 Hz tripod runs forward"
    diff = results["paired_differences"]["policies"][str(model_zip)]["speed"]
    assert diff["n"] == 3
    assert (out / "results.md").read_text().startswith("# skitter/RoachWalk-v0")
    pngs = sorted(p.name for p in (out / "plots").iterdir())
    assert len(pngs) == 2 and all(p.endswith(".png") for p in pngs)
    mp4s = list((out / "videos").glob("*.mp4"))
    assert len(mp4s) == 2 and all(p.stat().st_size > 1000 for p in mp4s)
    assert len(list((out / "telemetry").glob("*.parquet"))) == 2
    # a second run into the same directory is refused, not silently overwritten
    again = run("--env", "skitter/RoachWalk-v0", "--policy", "tripod:20", "--episodes", "1", "--out", str(out))
    assert again.returncode != 0 and "already holds results.json" in again.stderr


def test_turn_reports_the_yaw_rate_error(tmp_path):
    done = run("--env", "skitter/RoachTurn-v0", "--policy", "tripod", "--episodes", "2", "--out", str(tmp_path / "t"),
               "--max-episode-steps", "100")  # fmt: skip
    assert done.returncode == 0, done.stderr
    summary = json.loads((tmp_path / "t" / "results.json").read_text())["policies"]["tripod"]["summary"]
    assert 0 <= summary["yaw_rate_error"]["mean"] < 1.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--env", "skitter/NoSuchRobot-v0", "--policy", "tripod"], "not registered"),
        (["--env", "skitter/RoachWalk-v0", "--policy", "no/such/model.zip"], "no trained model"),
        (["--env", "skitter/RoachWalk-v0", "--policy", "moonwalk"], "unknown policy"),
        (["--env", "skitter/RoachWalk-v0", "--policy", "tripod", "--episodes", "0"], "--episodes"),
    ],
)
def test_bad_input_gets_a_clear_message_and_no_traceback(tmp_path, args, message):
    done = run(*args, "--out", str(tmp_path / "out"))
    assert done.returncode != 0
    assert message in done.stderr
    assert "Traceback" not in done.stderr
