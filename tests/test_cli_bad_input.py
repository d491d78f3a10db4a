"""Bad --out paths and flags of calibrate.py and ``python -m sysid.synth``: one line naming the flag and value, exit
code 2, no traceback, and nothing created, replaced or deleted."""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from agents import compare as evaluate
from sysid import cli as calibrate
from sysid import synth
from tests.conftest import main_in_process

ROOT = Path(__file__).resolve().parents[1]
GEARMOTOR = ROOT / "data" / "real" / "rhex3_motor_speedRamp.csv"


def files(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its content (None for a folder)."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def call(main, capsys, *args: str) -> tuple[int, str]:
    """Exit code and stderr of a CLI's ``main``, whether it returns or exits; the message is one line."""
    done = main_in_process(main, list(args))
    err = done.stderr.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return done.returncode, err


# --- calibrate.py: --out is checked before any log is read or fitted ---------------------------------------------
def calibrate_with(capsys, out: Path, *extra: str) -> tuple[int, str]:
    logs = ["--train", f"{GEARMOTOR}@0:5", "--test", f"{GEARMOTOR}@5:"]  # good logs: the run would fit for minutes
    return call(calibrate.main, capsys, "--robot", "motor", *logs, "--out", str(out), "--quiet", *extra)


def test_calibrate_out_under_a_file_is_refused_before_fitting(capsys, tmp_path):
    (tmp_path / "somefile.txt").write_text("a user's file")
    before = files(tmp_path)
    code, err = calibrate_with(capsys, tmp_path / "somefile.txt" / "out")
    assert code == 2 and f"--out {tmp_path / 'somefile.txt' / 'out'}" in err and "is a file, not a directory" in err
    code, err = calibrate_with(capsys, tmp_path / "somefile.txt" / "deeper" / "out")
    assert code == 2 and f"{tmp_path / 'somefile.txt'} is a file" in err
    code, err = calibrate_with(capsys, tmp_path / "somefile.txt")
    assert code == 2 and "exists and is not a directory" in err
    assert files(tmp_path) == before


def test_calibrate_fit_of_one_effect_twice_is_refused_before_fitting(capsys, tmp_path):
    code, err = calibrate_with(capsys, tmp_path / "out", "--fit", "delay", "coulomb_friction", "delay")
    assert code == 2 and "--fit names delay more than once" in err
    assert not (tmp_path / "out").exists()


def test_calibrate_starting_calibration_in_another_unit_is_refused_before_fitting(capsys, tmp_path):
    start = tmp_path / "start.json"
    effects = {"delay": {"seconds": {"value": 4.0, "unit": "ms"}}}
    start.write_text(json.dumps({"format": "skitter calibration", "version": 1, "robot": "motor", "effects": effects}))
    code, err = calibrate_with(capsys, tmp_path / "out", "--calibration", str(start))
    assert code == 2 and f"{start}: field 'effects.delay.seconds.unit': 'ms'" in err and "in s" in err
    assert not (tmp_path / "out").exists()


def test_calibrate_overwrite_refuses_a_folder_with_files_it_did_not_write(capsys, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.json").write_text("{}")
    (out / "notes.txt").write_text("the user's notes")
    before = files(tmp_path)
    code, err = calibrate_with(capsys, out, "--overwrite")
    assert code == 2 and "notes.txt" in err and "--overwrite" in err and "report.json" not in err
    assert files(tmp_path) == before


def test_calibrate_refusal_names_only_the_results_that_exist(capsys, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("an earlier run")
    code, err = calibrate_with(capsys, out)
    assert code == 2 and "already holds report.md of an earlier run" in err and "--overwrite" in err
    assert "report.json" not in err and "calibration.json" not in err
    assert (out / "report.md").read_text() == "an earlier run"
    # with --overwrite, a folder of calibrate.py's own results may be replaced
    for name in calibrate.RESULTS:
        (out / name).write_text("an earlier run")
    assert calibrate.parse_args(
        ["--robot", "motor", "--train", "a.csv", "--test", "b.csv", "--out", str(out), "--overwrite"]
    ).overwrite


def test_calibrate_out_that_publishing_could_not_replace_is_refused_before_fitting(capsys, tmp_path, monkeypatch):
    """A name too long for the folders that stage and replace it beside it, or a mount point (no rename moves one):
    refused in one line before any log is read, not in a traceback after the whole run."""
    long = tmp_path / ("r" * 250)  # a name a file system takes, but not ".<name>.<8 random>" beside it
    code, err = calibrate_with(capsys, long)
    assert code == 2 and f"--out {long}: the folders that stage and replace it cannot be made beside it" in err
    assert "File name too long" in err and list(tmp_path.iterdir()) == []
    mount = tmp_path / "mounted"
    mount.mkdir()
    monkeypatch.setattr(os.path, "ismount", lambda path: Path(path) == mount)
    code, err = calibrate_with(capsys, mount)
    message = f"calibrate.py: error: --out {mount} is a mount point, which cannot be replaced; give a folder inside it"
    assert code == 2 and err == f"{message} (see --help)"
    assert list(tmp_path.iterdir()) == [mount] and not any(mount.iterdir())


def test_calibrate_results_that_cannot_be_published_are_kept_and_said_where(capsys, tmp_path, monkeypatch):
    """If putting the results at --out still fails after the run (the file system changed meanwhile), they are kept
    in a folder beside it, named in one line, exit 1: the run is not lost in a traceback."""
    import errno

    from envs.common.telemetry import write_telemetry
    from sysid.cases import pair

    # logs of 4 s, not the protocol's 10: where the results go is what is tested here
    (train,), (test,), _ = pair("motor", {"coulomb_friction": 0.2}, seed=15, seconds=4.0)
    logs = []
    for name, log in (("train", train), ("test", test)):
        write_telemetry(tmp_path / f"{name}.parquet", log.df, log.meta)
        logs.append(str(tmp_path / f"{name}.parquet"))

    def busy(*args, **kwargs):
        raise OSError(errno.EBUSY, os.strerror(errno.EBUSY))

    monkeypatch.setattr(calibrate, "publish_folder", busy)
    out = tmp_path / "cal"
    code, err = call(calibrate.main, capsys, "--robot", "motor", "--train", logs[0], "--test", logs[1], "--out",
                     str(out), "--fit", "coulomb_friction", "--quiet")  # fmt: skip
    (kept,) = [p for p in tmp_path.iterdir() if p.name.startswith("cal.unpublished-")]
    assert code == 1 and err == (
        f"calibrate.py: error: cannot put the results at {out} ({os.strerror(errno.EBUSY)}); they are kept in {kept}/"
    )
    assert sorted(p.name for p in kept.iterdir()) == sorted(calibrate.RESULTS)
    assert json.loads((kept / "report.json").read_text())["robot"] == "motor"
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == [
        kept.name,
        "test.parquet",
        "train.parquet",
    ]


# --- python -m sysid.synth --------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (
            ["--seconds", "0"],
            "--seconds must be a finite number in [1, 600] for motor (at most 600 s of logs in all), got 0",
        ),
        (
            ["--seconds", "1e9"],
            "--seconds must be a finite number in [1, 600] for motor (at most 600 s of logs in all), got 1e+09",
        ),
        (["--runs", "100000"], "--runs must be in [1, 100], got 100000"),
        (["--runs", "100", "--seconds", "10"], "--seconds must be a finite number in [1, 6] for motor with --runs 100"),
        (["--seed", str(2**64)], f"got {2**64}"),
        (["--effect", "no_such_effect"], "robot 'motor' has no effect 'no_such_effect' (see --list)"),
        (["--effect", "viscous_friction=50"], "viscous_friction.damping=50: outside its range"),
        (["--seconds", "-3"], "got -3"),
        (["--seconds", "nan"], "got nan"),
        (["--seconds", "inf"], "got inf"),
        (["--seed", "-1"], "--seed must be in [0, "),
        (["--runs", "0"], "--runs must be in [1, 100], got 0"),
        (["--effect", "viscous_friction=0.1", "--effect", "viscous_friction"], "--effect 'viscous_friction' is given"),
    ],
)
def test_synth_bad_flags_are_one_line_errors(capsys, tmp_path, monkeypatch, args, needle):
    def never(*args, **kwargs):
        raise AssertionError("simulated before the flags were checked")

    monkeypatch.setattr(synth, "record", never)  # sizes, names and values: all refused before the long part
    code, err = call(synth.main, capsys, "--robot", "motor", "--out", str(tmp_path / "log.parquet"), *args)
    assert code == 2 and needle in err
    assert files(tmp_path) == {}


def test_synth_a_drawn_effect_its_seeds_commands_do_not_show_says_what_to_do(capsys, tmp_path, monkeypatch):
    """The README's ``--robot xjus --effect mass --runs 6 --seconds 2`` at the default seed: no draw of seed 0's
    commands shows the drawn mass (the nominal model's error stays about 1.5 < 3), and the tool said only that. It
    now names the seed and what to do instead, and writes nothing; here with a motor whose visibility is held low,
    so that the same path runs in seconds."""
    monkeypatch.setattr(synth, "visibility", lambda adapter, logs, reachable: 1.5)
    out = tmp_path / "log.parquet"
    code, err = call(synth.main, capsys, "--robot", "motor", "--effect", "viscous_friction", "--seconds", "1",
                     "--out", str(out))  # fmt: skip
    assert code == 2 and err.startswith("python -m sysid.synth: error: viscous_friction (seed 0): even far from"), err
    assert err.endswith("try another --seed, or give the value (--effect NAME=VALUE)"), err
    assert files(tmp_path) == {}


def test_synth_burn_in_robots_need_two_segments(capsys, tmp_path):
    code, err = call(synth.main, capsys, "--robot", "roach", "--seconds", "1.5", "--out", str(tmp_path / "r.parquet"))
    assert code == 2 and "in [2, 600] for roach (at most 600 s of logs in all), got 1.5" in err


@pytest.mark.parametrize(
    ("name", "needle"),
    [
        ("log.csv", "give a path ending in .parquet"),
        ("folder.parquet", "folder.parquet is a directory"),
        ("somefile.txt/log.parquet", "somefile.txt is a file, not a directory"),
        ("log.parquet", "log.parquet.truth.json is a directory"),
    ],
)
def test_synth_bad_out_paths_are_refused_even_with_overwrite(capsys, tmp_path, name, needle):
    (tmp_path / "folder.parquet").mkdir()
    (tmp_path / "log.parquet.truth.json").mkdir()
    (tmp_path / "somefile.txt").write_text("a user's file")
    before = files(tmp_path)
    code, err = call(synth.main, capsys, "--robot", "motor", "--seconds", "1", "--out", str(tmp_path / name),
                     "--overwrite")  # fmt: skip
    assert code == 2 and f"--out {tmp_path / name}" in err and needle in err
    assert files(tmp_path) == before


def test_synth_writes_the_log_and_its_truth_as_a_pair(capsys, tmp_path):
    out = tmp_path / "log.parquet"
    truth = tmp_path / "log.parquet.truth.json"
    truth.write_text("the truth of another log")
    code, err = call(synth.main, capsys, "--robot", "motor", "--seconds", "1", "--out", str(out))
    assert code == 2 and f"{truth} already exists" in err and "--overwrite" in err
    assert files(tmp_path) == {"log.parquet.truth.json": b"the truth of another log"}
    truth.unlink()
    assert synth.main(["--robot", "motor", "--seconds", "1", "--out", str(out)]) == 0
    assert sorted(files(tmp_path)) == ["log.parquet", "log.parquet.truth.json"], "no temporary file left"
    capsys.readouterr()
    before = files(tmp_path)
    code, err = call(synth.main, capsys, "--robot", "motor", "--seconds", "1", "--seed", "1", "--out", str(out))
    assert code == 2 and f"{out} and {truth} already exist" in err
    assert files(tmp_path) == before
    assert synth.main(["--robot", "motor", "--seconds", "1", "--seed", "1", "--out", str(out), "--overwrite"]) == 0
    assert json.loads(truth.read_text())["seed"] == 1 and files(tmp_path)["log.parquet"] != before["log.parquet"]
    assert math.isfinite(json.loads(truth.read_text())["nominal_error"])
    # --overwrite replaces this tool's own log and truth, never a user's file in their place
    truth.write_text('{"my": "notes"}')
    before = files(tmp_path)
    code, err = call(synth.main, capsys, "--robot", "motor", "--seconds", "1", "--out", str(out), "--overwrite")
    assert code == 2 and f"{truth} is not a synthetic log or truth this tool wrote" in err
    assert files(tmp_path) == before


def test_synth_writes_several_runs_and_their_truth_as_one_unit(capsys, tmp_path):
    """``--runs K``: K logs from rest beside one truth, drawn to show on all of them; a run's file already there is
    named and nothing is written."""
    out = tmp_path / "log.parquet"
    (tmp_path / "log.run2.parquet").write_text("a user's file")
    before = files(tmp_path)
    code, err = call(synth.main, capsys, "--robot", "motor", "--seconds", "1", "--runs", "3", "--out", str(out))
    assert code == 2 and f"{tmp_path / 'log.run2.parquet'} already exists" in err and "--overwrite" in err
    assert files(tmp_path) == before
    (tmp_path / "log.run2.parquet").unlink()
    argv = ["--robot", "motor", "--effect", "viscous_friction", "--seconds", "1", "--runs", "3", "--out", str(out)]
    assert synth.main(argv) == 0
    names = ["log.parquet.truth.json", "log.run1.parquet", "log.run2.parquet", "log.run3.parquet"]
    assert sorted(files(tmp_path)) == names, "no temporary file left, and no log at --out itself"
    logs, truth = synth.record("motor", {"viscous_friction": None}, 0, 1.0, 3)
    written = json.loads((tmp_path / names[0]).read_text())
    assert written["effects"] == truth["effects"] and written["nominal_error"] == truth["nominal_error"] >= 3
    for name, log in zip(names[1:], logs, strict=True):
        assert pd.read_parquet(tmp_path / name)["duty"].to_numpy().tolist() == log.df["duty"].tolist()


def test_synth_list_into_a_closed_pipe_is_no_traceback():
    """``--list | head -1``: the reader stops before the listing is written."""
    proc = subprocess.Popen([sys.executable, "-m", "sysid.synth", "--list"], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=60) == 1
    assert err == ""


# --- evaluate.py: what counts as an earlier run, and the current folder ----------------------------------------------


def test_evaluate_overwrite_keeps_a_users_images_where_no_earlier_run_was(tmp_path, monkeypatch):
    """plots/ of .png files without results.json is the user's folder, not an earlier run: refused even with
    --overwrite (it would be deleted)."""
    out = tmp_path / "out"
    (out / "plots").mkdir(parents=True)
    (out / "plots" / "my_figure.png").write_bytes(b"a user's figure")
    base = ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--out", str(out)]
    for extra in ([], ["--overwrite"]):
        with pytest.raises(SystemExit) as exit_:
            evaluate.parse_args([*base, *extra])
        assert exit_.value.code == 2
    assert (out / "plots" / "my_figure.png").read_bytes() == b"a user's figure"
    (out / "results.json").write_text("{}")  # an earlier run's results: now the plots are its own
    assert evaluate.parse_args([*base, "--overwrite"]).overwrite


@pytest.mark.parametrize("out", [".", ""])
def test_the_current_folder_is_refused_as_out(tmp_path, monkeypatch, capsys, out):
    monkeypatch.chdir(tmp_path)
    for parse in (
        lambda: evaluate.parse_args(["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--out", out]),
        lambda: calibrate.parse_args(["--robot", "motor", "--train", "a.csv", "--test", "b.csv", "--out", out]),
    ):
        with pytest.raises(SystemExit) as exit_:
            parse()
        assert exit_.value.code == 2
        assert "is the current folder or holds it" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


# --- every tool's bad-input messages begin the same way: "<how it is run>: error: " ---------------------------------


def test_synth_errors_begin_like_its_parsers_and_an_empty_out_is_refused(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    base = ["--robot", "motor", "--seconds", "1", "--out", str(tmp_path / "log.parquet")]
    for extra, needle in [
        (["--seed", "-1"], "--seed must be in [0, "),  # the parser's check
        (["--out", str(tmp_path / "log.csv")], "give a path ending in .parquet"),  # main's check
        (["--out", ""], "give the log's file name, FILE.parquet"),  # no traceback from Path('').with_name
    ]:
        code, err = call(synth.main, capsys, *base, *extra)
        assert code == 2 and err.startswith("python -m sysid.synth: error: ") and needle in err, err
    assert files(tmp_path) == {}


def test_optimize_errors_begin_like_the_other_tools(capsys, tmp_path):
    from agents.optimize.__main__ import main as optimize

    out = tmp_path / "out"
    for args, needle in [
        (["--config", str(tmp_path / "nope.json")], "nope.json: no such run configuration"),
        (["--config", str(tmp_path)], f"{tmp_path}: a directory, not a run configuration"),
        (["--config", str(tmp_path / "nope.json"), "--iterations", "x"], "argument --iterations: invalid int value"),
    ]:
        code, err = call(optimize, capsys, *args, "--out", str(out), "--no-progress")
        assert code == 2 and err.startswith("python -m agents.optimize: error: ") and needle in err, err
    assert files(tmp_path) == {}


def test_a_results_folder_that_appears_during_a_run_is_not_replaced(tmp_path):
    """--out is checked when a run begins; a folder that appears there meanwhile (or takes a user's file) is left
    alone at the end, and the results go beside it."""
    from envs.common.io import foreign_unless, publish_folder

    def staged(name: str) -> Path:
        folder = tmp_path / f".staging-{name}"
        folder.mkdir()
        (folder / "report.json").write_text(name)
        return folder

    out = tmp_path / "out"
    assert publish_folder(staged("first"), out, existed=False) == out  # the usual case
    assert publish_folder(staged("again"), out, True, foreign_unless(("report.json",))) == out  # --overwrite
    assert (out / "report.json").read_text() == "again"
    # appeared during the run: left as it is
    appeared = tmp_path / "appeared"
    appeared.mkdir()
    (appeared / "notes.txt").write_text("a user's notes")
    assert publish_folder(staged("third"), appeared, existed=False) == tmp_path / "appeared-2"
    assert (appeared / "notes.txt").read_text() == "a user's notes" and len(list(appeared.iterdir())) == 1
    # there when the run began, with a user's file put in it since: left as it is
    (out / "notes.txt").write_text("put there during the run")
    assert publish_folder(staged("fourth"), out, True, foreign_unless(("report.json",))) == tmp_path / "out-2"
    assert (out / "report.json").read_text() == "again" and (tmp_path / "out-2" / "report.json").read_text() == "fourth"


def test_calibrate_stopped_by_sigterm_leaves_nothing_and_says_so(tmp_path):
    import signal

    out = tmp_path / "out"
    argv = [sys.executable, "calibrate.py", "--robot", "motor", "--train", f"{GEARMOTOR}@0:5", "--test",
            f"{GEARMOTOR}@5:", "--out", str(out)]  # fmt: skip
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=Path(__file__).resolve().parents[1])  # fmt: skip
    # its first progress line: imports done, fitting (the whole run takes minutes), however loaded the host is
    assert proc.stdout.readline().startswith("nominal model: error")
    assert proc.poll() is None
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM
    assert err.strip() == f"calibrate.py: interrupted; {out} is as it was", err
    assert list(tmp_path.iterdir()) == []  # no results, no staging folder


def test_a_publish_that_fails_halfway_puts_the_earlier_results_back(tmp_path, monkeypatch):
    """publish_folder moves the earlier results aside, then the new ones in: if the second rename fails, the earlier
    results are back at ``out`` (not left under a hidden name) and the new ones are still in their staging folder."""
    import os

    from envs.common.io import publish_folder

    out, staging = tmp_path / "out", tmp_path / ".staging"
    out.mkdir()
    staging.mkdir()
    (out / "results.json").write_text("earlier")
    (staging / "results.json").write_text("new")
    replace, calls = os.replace, []

    def second_fails(source, target):
        calls.append(source)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return replace(source, target)

    monkeypatch.setattr(os, "replace", second_fails)
    with pytest.raises(OSError, match="No space left"):
        publish_folder(staging, out)
    monkeypatch.undo()
    assert (out / "results.json").read_text() == "earlier" and (staging / "results.json").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".staging", "out"]


def test_a_tools_help_shows_its_docstring_once():
    """``--help`` shows a tool's docstring's first paragraph as its description and, where the docstring is also the
    epilog, the rest of it after the options: no paragraph twice."""
    from agents.optimize.__main__ import parse_args

    with pytest.raises(SystemExit), contextlib.redirect_stdout(io.StringIO()) as out:
        parse_args(["--help"])
    text = out.getvalue()
    first = "Tune a controller's parameters by particle swarm or CMA-ES"
    assert text.count(first) == 1 and text.count("Examples::") == 1
    assert text.index(first) < text.index("options:") < text.index("Examples::")


# --- the other tools: a user's folder, a stretch of log counted twice, a run that diverges or is stopped ----------
REAL_2HZ = ROOT / "data" / "real" / "velociroach_behavior4_2Hz.txt"


def test_the_leaderboard_refuses_a_folder_of_the_users_own(capsys, tmp_path):
    """--out and --records: the leaderboard adds to them and rewrites their table, so a folder holding anything it
    does not write (a results page of another tool, a user's file) is refused before anything is made."""
    from agents.leaderboard import main as leaderboard

    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "results.md").write_text("my own notes")
    (mine / "results.json").write_text('{"mine": 1}')
    theirs = tmp_path / "theirs"
    (theirs / "rows").mkdir(parents=True)
    (theirs / "thesis.tex").write_text("a thesis")
    before = files(tmp_path)
    common = ("--tasks", "skitter/RoachWalk-v4", "--timesteps", "512", "--table-only")
    code, err = call(leaderboard, capsys, *common, "--out", str(mine))
    assert code == 2 and f"--out {mine}: holds what the leaderboard does not write (results.json, results.md)" in err
    code, err = call(leaderboard, capsys, *common, "--out", str(tmp_path / "new"), "--records", str(theirs))
    assert code == 2 and f"--records {theirs}: holds what the leaderboard does not write (thesis.tex)" in err
    assert files(tmp_path) == before
    code, err = call(leaderboard, capsys, *common, "--out", str(mine), "--workers", str(10 * (os.cpu_count() or 1)))
    assert code == 2 and "cores and each row runs on one at least" in err


def test_measure_counts_each_stretch_of_a_log_once_and_writes_two_files(capsys, tmp_path):
    from sysid.measure import main as measure

    window = f"{REAL_2HZ}@0:4"
    code, err = call(measure, capsys, "--robot", "roach", window, window, "--calibration-out", str(tmp_path / "c.json"))
    assert code == 2 and "both given to the measured logs: each stretch of a log counts once" in err
    code, err = call(measure, capsys, "--robot", "roach", window, "--calibration-out", str(tmp_path / "c.json"),
                     "--test", f"{REAL_2HZ}@2:6")  # fmt: skip
    assert code == 2 and f"overlaps the measured log {window}" in err
    same = str(tmp_path / "." / "x.json")
    code, err = call(measure, capsys, "--robot", "roach", window, "--out", str(tmp_path / "x.json"),
                     "--calibration-out", same)  # fmt: skip
    assert code == 2 and "are one file: give two files" in err
    code, err = call(measure, capsys, "--robot", "roach", f"{REAL_2HZ}@0:1000")
    assert code == 2 and "the window ends at 1000 s, past the log's end at 10 s; give" in err
    assert files(tmp_path) == {}


def test_a_column_map_that_names_a_channel_twice_is_refused(tmp_path):
    from sysid.logs import ColumnMap, LogError

    path = tmp_path / "map.json"
    path.write_text('{"time": {"column": "t"}, "duty": {"column": "a"}, "duty": {"column": "b"}}')
    with pytest.raises(LogError, match="entry 'duty' is given twice"):
        ColumnMap.load(path)


def test_train_refuses_normalization_that_trains_on_nothing_and_says_a_run_diverged(capsys, tmp_path, monkeypatch):
    """VecNormalize's epsilon and clips must be above 0 (checked before the run folder is made); a learning rate that
    makes the policy NaN ends the run in one line that names the file to change, not torch's traceback."""
    from agents.training import main as train

    monkeypatch.chdir(tmp_path)
    entry = (
        "skitter/RoachWalk-v4:\n  n_envs: 2\n  n_steps: 128\n  batch_size: 64\n  env_kwargs: {max_episode_steps: 50}\n"
    )
    common = ("--env", "skitter/RoachWalk-v4", "--algo", "ppo", "--runs-dir", "runs", "--no-progress")
    for normalize, needle in [("{clip_obs: -1}", "clip_obs: must be a finite number above 0, got -1.0"),
                              ("{epsilon: 0}", "epsilon: must be a finite number above 0"),
                              ("{clip_reward: 0}", "clip_reward: must be a finite number above 0")]:  # fmt: skip
        (tmp_path / "h.yml").write_text(entry + f"  normalize: {normalize}\n")
        code, err = call(train, capsys, *common, "--timesteps", "256", "--hyperparams", "h.yml")
        assert code == 2 and needle in err and not (tmp_path / "runs").exists(), err
    (tmp_path / "h.yml").write_text(entry + "  learning_rate: 1000.0\n")
    code, err = call(train, capsys, *common, "--timesteps", "1024", "--hyperparams", "h.yml")
    assert code == 1 and "train.py: error: training diverged at " in err and "lower learning_rate" in err, err
    assert "h.yml" in err


def test_optimize_stopped_by_ctrl_c_says_so_in_one_line(capsys, tmp_path, monkeypatch):
    import agents.optimize.__main__ as optimize

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(optimize, "run", stopped)
    config = ROOT / "agents" / "bioloid" / "optimize" / "experiment5.json"
    code, err = call(optimize.main, capsys, "--config", str(config), "--out", str(tmp_path / "out"), "--no-progress")
    assert code == 130 and "interrupted; no iteration was finished" in err and "run the same command again" in err
