"""Calibration inputs: every log format read into one table, and bad input refused by ``calibrate.py`` with one line
naming the file, row and column, exit code 2, and nothing written."""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from envs.common.telemetry import write_telemetry
from sysid import cli as calibrate
from sysid import synth
from sysid.logs import ColumnMap, Log, LogError, white_noise
from sysid.robots import adapter as make_adapter
from sysid.robots import read_log

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
GEARMOTOR = REAL / "rhex3_motor_speedRamp.csv"
AX12A = REAL / "ax12a_step_NOLOAD_1.csv"
ROACH_2HZ = REAL / "velociroach_behavior4_2Hz.txt"


def test_gearmotor_log_reads_in_si_units():
    log = read_log(GEARMOTOR, ("duty", "angle", "speed"))
    df = log.df
    assert len(df) == 1047
    assert df["time"].iloc[0] == pytest.approx(0.021)
    assert df["duty"].max() == pytest.approx(1.0) and df["duty"].min() == pytest.approx(10 / 255)
    # full PWM turns the shaft at about 2.15 rev/s (shared/data/real/README.md)
    full = df[(df["time"] > 0.5) & (df["time"] < 1.0)]
    assert full["speed"].median() / (2 * math.pi) == pytest.approx(2.15, abs=0.05)
    # the angle is the integral of the speed: encoder clicks of 2 pi / 3592
    travelled = np.trapezoid(df["speed"], df["time"])
    assert df["angle"].iloc[-1] - df["angle"].iloc[0] == pytest.approx(travelled, rel=0.03)
    assert log.meta["quantisation"]["angle"] == pytest.approx(2 * math.pi / 3592)


def test_dynamixel_export_drops_its_broken_row_with_a_warning():
    with pytest.warns(UserWarning) as caught:
        log = read_log(AX12A, ("present_position",))
    messages = sorted(str(w.message) for w in caught)
    # the row without a time, and one whose time lost its leading digits (71 ms between 4239 and 4288)
    assert any(re.search(r"ax12a_step_NOLOAD_1\.csv: dropped malformed row at line 206: '499'", m) for m in messages)
    assert any(re.search(r"dropped malformed row at line 195: time 0.071 s out of order", m) for m in messages)
    assert len(log.df) == 205  # 207 data lines, two broken
    assert log.df["present_position"].iloc[0] == pytest.approx(1)
    assert log.df["present_position"].iloc[-1] == pytest.approx(498, abs=10)
    dt = np.diff(log.time)
    assert dt.min() > 0 and 0.010 < np.median(dt) < 0.020  # irregular, about 16 ms


def test_roach_log_reads_in_both_header_dialects(tmp_path):
    text = ROACH_2HZ.read_text().splitlines()
    quoted = ['"' + line + '"' if line.startswith("%") else line for line in text[:1500]]
    path = tmp_path / "quoted.txt"
    path.write_text("\n".join(quoted) + "\n")
    a = read_log(ROACH_2HZ, ("leg_angle_left",))
    b = read_log(path, ("leg_angle_left",))
    pd.testing.assert_frame_equal(a.df.iloc[: len(b.df)], b.df)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_a_column_map_reads_logs_of_any_format(tmp_path, suffix):
    t = np.arange(400) * 5.0  # ms
    raw = pd.DataFrame({"t_ms": t, "enc": (t * 3).astype(int), "pwm_pct": 50.0})
    path = tmp_path / f"log{suffix}"
    raw.to_csv(path, index=False) if suffix == ".csv" else raw.to_json(path, orient="records")
    mapping = tmp_path / "map.json"
    mapping.write_text(
        json.dumps(
            {
                "time": {"column": "t_ms", "unit": "ms"},
                "angle": {"column": "enc", "unit": "rev", "counts_per_unit": 1000},
                "duty": {"column": "pwm_pct", "unit": "%"},
            }
        )
    )
    log = read_log(path, ("angle", "duty"), ColumnMap.load(mapping))
    assert log.time[1] == pytest.approx(0.005)
    assert log.df["angle"].iloc[1] == pytest.approx(15 / 1000 * 2 * math.pi)
    assert log.df["duty"].iloc[0] == pytest.approx(0.5)


def _our_channels_log(n: int = 400) -> pd.DataFrame:
    """A log in our channels (xJüs names, SI units), its first rows without a gait command (blank, as telemetry has)."""
    t = np.arange(n) * 0.008
    df = pd.DataFrame({"time": t, "duty_FL": 0.3, "leg_angle_FL": 2.0 * t, "leg_speed_FL": 2.0, "period": 0.5})
    df.loc[:9, "period"] = np.nan
    return df


def test_a_csv_named_by_our_channels_reads_as_is_without_a_column_map(tmp_path):
    df = _our_channels_log()
    path = tmp_path / "xjus.csv"
    df.to_csv(path, index=False)
    log = read_log(path, ("duty_FL", "leg_angle_FL", "leg_speed_FL"))
    assert log.meta["format"].startswith("skitter CSV")
    assert len(log.df) == len(df), "a blank channel nobody requires drops no row"
    np.testing.assert_allclose(log.df["leg_angle_FL"], df["leg_angle_FL"])
    assert log.df["period"].isna().sum() == 10


def test_a_non_finite_required_channel_is_named_as_itself_not_as_an_earlier_blank_one(tmp_path):
    df = _our_channels_log()
    df.loc[100:, "leg_angle_FL"] = np.nan  # most rows: the log is refused, naming this column and its first bad line
    path = tmp_path / "xjus.csv"
    df.to_csv(path, index=False)
    with pytest.raises(LogError, match=r"at line 102: column 'leg_angle_FL'"):
        read_log(path, ("duty_FL", "leg_angle_FL"))
    mapping = tmp_path / "map.json"  # the same file through a column map: the same message
    units = {"time": "s", "duty_FL": "1", "leg_angle_FL": "rad", "period": "s"}
    mapping.write_text(json.dumps({c: {"column": c, "unit": u} for c, u in units.items()}))
    with pytest.raises(LogError, match=r"at line 102: column 'leg_angle_FL'"):
        read_log(path, ("duty_FL", "leg_angle_FL"), ColumnMap.load(mapping))


def test_a_field_that_is_not_a_number_is_named_as_the_file_has_it(tmp_path):
    df = _our_channels_log()
    path = tmp_path / "xjus.csv"
    df.to_csv(path, index=False)
    lines = path.read_text().splitlines()
    fields = lines[7].split(",")
    fields[list(df.columns).index("leg_angle_FL")] = "abc"
    lines[7] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    with pytest.warns(UserWarning, match=r"line 8: column 'leg_angle_FL': 'abc' is not a finite number"):
        log = read_log(path, ("duty_FL", "leg_angle_FL"))
    assert json.loads(json.dumps(log.meta["unparsed"]))["leg_angle_FL"] == {"8": "abc"}  # the meta stays JSON


def test_a_column_map_entry_the_robot_does_not_read_is_warned_of(capsys, tmp_path):
    """A misspelt channel (``goal_position`` for the servo's ``goal``) would leave its column unread: said before
    anything runs."""
    train, test = (_write(tmp_path, f"{n}.csv", ["time,pos,speed,power", *_gearmotor_rows()]) for n in "ab")
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"time": {"column": "t", "unit": "s"}, "goal_position": {"column": "g"}}))
    code, err = _run(capsys, tmp_path, "servo", train, test, "--columns", str(mapping), "--fit", "warp_drive")
    assert code == 2
    assert (f"calibrate.py: warning: {mapping}: the servo's calibration reads no channel named 'goal_position'; "
            "those columns are ignored (it reads goal, present_position, time)") in err  # fmt: skip


def test_a_csv_with_a_name_we_do_not_know_still_needs_a_column_map(tmp_path):
    path = tmp_path / "other.csv"
    _our_channels_log().rename(columns={"leg_angle_FL": "angle_deg"}).to_csv(path, index=False)
    with pytest.raises(LogError, match=r"unknown log format .*'angle_deg' is not one of skitter's channels"):
        read_log(path, ("duty_FL",))
    _our_channels_log().rename(columns={"leg_speed_FL": "duty_FL"}).to_csv(path, index=False)
    with pytest.raises(LogError, match="column 'duty_FL' appears twice"):
        read_log(path, ("duty_FL",))


# --- bad input: calibrate.py stops before anything is written ---------------------------------------------------
def _gearmotor_rows(n: int = 300) -> list[str]:
    return [f"{10 * (i + 1)},{i * 5},{500},{128}" for i in range(n)]


def _write(tmp_path: Path, name: str, lines: list[str]) -> Path:
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _run(capsys, tmp_path: Path, robot: str, train: Path, test: Path, *extra: str) -> tuple[int, str]:
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exit_info:
        raise SystemExit(
            calibrate.main(["--robot", robot, "--train", str(train), "--test", str(test), "--out", str(out), *extra])
        )
    err = capsys.readouterr().err.strip()
    assert not out.exists(), "nothing may be written for bad input"
    return exit_info.value.code, err


def _bad(tmp_path: Path, kind: str) -> tuple[Path, str]:
    header = "time,pos,speed,power"
    rows = _gearmotor_rows()
    if kind == "missing column":
        t = np.arange(0, 3, 0.01)
        path = tmp_path / "bad.parquet"
        write_telemetry(path, pd.DataFrame({"time": t, "duty": 0.5, "angle": t}), {"robot": "motor"})
        return path, "column 'speed' is missing"
    if kind == "time backwards":  # a second recording appended: its clock starts again
        rows = rows[:150] + [f"{10 * (i + 1)},{i * 5},500,128" for i in range(150)]
        return _write(tmp_path, "bad.csv", [header, *rows]), "row at line 152, column 'time'"
    if kind == "too short":
        return _write(tmp_path, "bad.csv", [header, *rows[:30]]), "0.29 s is too short to replay"
    if kind == "many bad rows":
        for i in range(0, 300, 10):
            rows[i] = "x,y"
        return _write(tmp_path, "bad.csv", [header, *rows]), "30 of 300 rows are malformed"
    if kind == "sparse samples":  # a time column in ms read as seconds: 3000 s with a sample every 10 s
        t = np.arange(300) * 10.0
        path = tmp_path / "sparse.csv"
        pd.DataFrame({"time": t, "duty": 0.5, "angle": 0.01 * t, "speed": 0.01}).to_csv(path, index=False)
        return path, "its samples lie 10 s apart, so a 1 s segment holds fewer than 3 of them"
    if kind == "no such file":
        return tmp_path / "nothing.csv", "no such file"
    if kind == "unknown format":
        return _write(tmp_path, "bad.csv", ["a;b;c", "1;2;3"]), "unknown log format"
    raise AssertionError(kind)


@pytest.mark.parametrize(
    "kind",
    [
        "missing column",
        "time backwards",
        "too short",
        "sparse samples",
        "many bad rows",
        "no such file",
        "unknown format",
    ],
)
@pytest.mark.parametrize("side", ["train", "test"])
def test_bad_logs_stop_calibrate_with_one_line(capsys, tmp_path, kind, side):
    good = _write(tmp_path, "good.csv", ["time,pos,speed,power", *_gearmotor_rows()])
    bad, needle = _bad(tmp_path, kind)
    train, test = (bad, good) if side == "train" else (good, bad)
    code, err = _run(capsys, tmp_path, "motor", train, test)
    assert code == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert str(bad) in err and needle in err


def test_a_malformed_row_is_dropped_with_a_warning_naming_file_and_line(tmp_path):
    rows = _gearmotor_rows()
    rows[40] = "410,200"
    path = _write(tmp_path, "one_bad.csv", ["time,pos,speed,power", *rows])
    with pytest.warns(UserWarning, match=r"one_bad\.csv: dropped malformed row at line 42"):
        log = read_log(path, ("duty",))
    assert len(log.df) == 299


def test_unknown_unit_in_a_column_map_is_refused(capsys, tmp_path):
    mapping = _write(tmp_path, "map.json", [json.dumps({"time": {"column": "t", "unit": "fortnight"}})])
    data = _write(tmp_path, "x.csv", ["t,a", "0,1"])
    code, err = _run(capsys, tmp_path, "motor", data, data.with_name("y.csv"), "--columns", str(mapping))
    assert code == 2 and "map.json" in err and "unknown unit 'fortnight'" in err


def test_test_data_may_not_overlap_training_data(capsys, tmp_path):
    code, err = _run(capsys, tmp_path, "motor", Path(f"{GEARMOTOR}@0:5"), Path(f"{GEARMOTOR}@4:8"))
    assert code == 2 and "overlaps the training log" in err
    code, err = _run(capsys, tmp_path, "motor", GEARMOTOR, GEARMOTOR)
    assert code == 2 and "overlaps" in err
    # a stretch given twice to --train would count twice (and left the replay floor's twin logs in a muddle: a
    # traceback); windows of one file that do not overlap are two logs
    out = tmp_path / "out"
    for train in ([GEARMOTOR, GEARMOTOR], [f"{GEARMOTOR}@0:5", f"{GEARMOTOR}@4:8"]):
        code = calibrate.main(["--robot", "motor", "--train", *map(str, train), "--test", "x.csv", "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2 and "both given to --train: each stretch of a log counts once" in err and not out.exists()
    missing = tmp_path / "missing.csv"  # the same missing file twice: named as missing, not as overlapping
    code, err = _run(capsys, tmp_path, "motor", missing, missing)
    assert code == 2 and f"{missing}: no such file" in err and "overlaps" not in err


def test_windows_of_one_log(tmp_path):
    logs = calibrate.read_logs([Path(f"{GEARMOTOR}@2:4.5")], ("duty",), None)
    assert logs[0].time[0] >= 2 and logs[0].time[-1] < 4.5
    with pytest.raises(LogError, match="ends"):
        calibrate.read_logs([Path(f"{GEARMOTOR}@4:2")], ("duty",), None)


def test_out_dir_with_files_is_not_overwritten(capsys, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    with pytest.raises(SystemExit) as exit_info:
        calibrate.main(["--robot", "motor", "--train", str(GEARMOTOR), "--test", str(AX12A), "--out", str(out)])
    assert exit_info.value.code == 2 and "--overwrite" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep"


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("{", "not a readable JSON"),
        ('{"format": "skitter calibration", "version": 1, "robot": "servo", "effects": {}}', "not 'motor'"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor", "effects": {"warp": {"x": 1}}}',
         "field 'effects.warp'"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor", '
         '"effects": {"viscous_friction": {"damping": {"value": 99}}}}', "'effects.viscous_friction.damping': 99"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor", '
         '"effects": {"viscous_friction": {"damping": "lots"}}}', "'lots' is not a finite number"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor", "effect": {}}',
         "unknown field 'effect' (did you mean 'effects'?)"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor"}', "no field 'effects'"),
        ('{"format": "skitter calibration", "version": 1, "robot": "motor", "effects": '
         '{"viscous_friction": {"damping": 1e-5}, "viscous_friction": {"damping": 2e-5}}}',
         "field 'viscous_friction' is given twice"),
    ],
)  # fmt: skip
def test_bad_calibration_file_is_refused(capsys, tmp_path, content, needle):
    start = _write(tmp_path, "start.json", [content])
    code, err = _run(
        capsys, tmp_path, "motor", Path(f"{GEARMOTOR}@0:5"), Path(f"{GEARMOTOR}@5:"), "--calibration", str(start)
    )
    assert code == 2 and "start.json" in err and needle in err


def test_parquet_telemetry_is_a_log(tmp_path):
    t = np.arange(0, 2, 0.01)
    df = pd.DataFrame({"time": t, "duty": 0.5, "angle": t, "speed": 1.0})
    path = tmp_path / "t.parquet"
    write_telemetry(path, df, {"robot": "motor"})
    log = read_log(path, ("duty", "angle", "speed"))
    assert len(log.df) == 200 and log.meta["format"] == "skitter telemetry"


def _telemetry_with(tmp_path: Path, df: pd.DataFrame, record: bytes | None = None, **fields) -> Path:
    """A telemetry file of ``df`` whose metadata record is ``record`` as given, or the writer's with ``fields``."""
    import pyarrow.parquet as pq

    path = tmp_path / "t.parquet"
    write_telemetry(path, df, {"robot": "motor"})
    table = pq.read_table(path)
    meta = dict(table.schema.metadata)
    meta[b"skitter"] = record if record is not None else json.dumps({**json.loads(meta[b"skitter"]), **fields}).encode()
    pq.write_table(table.replace_schema_metadata(meta), path)
    return path


def _motor_frame(n: int = 200) -> pd.DataFrame:
    t = np.arange(n) * 0.01
    return pd.DataFrame({"time": t, "duty": 0.5, "angle": t, "speed": 1.0})


def test_telemetry_numbers_stored_as_text_read_and_a_cell_that_is_not_one_is_a_malformed_row(tmp_path):
    df = _motor_frame().astype({"angle": str, "time": str})
    df.loc[5, "angle"] = "N/A"
    with pytest.warns(UserWarning, match=r"t\.parquet: dropped malformed row at line 6: column 'angle': 'N/A'"):
        log = read_log(_telemetry_with(tmp_path, df), ("duty", "angle", "speed"))
    assert len(log.df) == 199 and log.df["time"].dtype == float and log.df["angle"].iloc[5] == 0.06


def test_a_telemetry_channel_of_text_is_refused_naming_file_column_and_value(tmp_path):
    df = _motor_frame().astype({"angle": str})
    df["angle"] = "fast"
    with pytest.raises(LogError, match=r"t\.parquet: column 'angle' holds text, not numbers \(row 1: 'fast'\)"):
        read_log(_telemetry_with(tmp_path, df), ("duty", "angle", "speed"))


@pytest.mark.parametrize(
    ("record", "fields", "message"),
    [
        (b"{not json", {}, "its 'skitter' metadata record is not JSON"),
        (b"[1]", {}, "its 'skitter' metadata record is a JSON list, not an object"),
        (None, {"noise_sigma": 5}, "field 'noise_sigma' = 5: expected a channel -> number object"),
        (None, {"noise_sigma": {"angle": 0.0}}, "field 'noise_sigma.angle' = 0.0: must be a positive finite number"),
        (None, {"noise_sigma": {"speed": "x"}}, "field 'noise_sigma.speed' = 'x': must be a positive"),
        (None, {"quantisation": {"angle": -1}}, "field 'quantisation.angle' = -1: must be a finite number, 0 or"),
        (None, {"schema_version": 99}, "field 'schema_version' = 99: this skitter reads telemetry of schema 1 to"),
        (None, {"units": {"time": "ms"}}, "field 'units.time' = 'ms': skitter telemetry holds 'time' in 's'"),
    ],
)
def test_a_telemetry_record_the_calibration_cannot_use_is_refused_naming_the_field(tmp_path, record, fields, message):
    path = _telemetry_with(tmp_path, _motor_frame(), record, **fields)
    with pytest.raises(LogError, match=re.escape(message)) as caught:
        read_log(path, ("duty", "angle", "speed"))
    assert str(caught.value).startswith(str(path))


def test_calibrate_warns_of_a_log_recorded_on_another_robot(capsys, tmp_path):
    path = _telemetry_with(tmp_path, _motor_frame(400), robot="xjus")
    code = calibrate.main(["--robot", "motor", "--train", f"{path}@0:2", "--test", f"{path}@2:",
                           "--fit", "no_such_effect", "--out", str(tmp_path / "out")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "--fit 'no_such_effect'" in err and not (tmp_path / "out").exists()
    assert "its metadata says it was recorded on the 'xjus'; calibrating the 'motor' on it" in err


# --- real logs the readers were not written against (tests/data/logs/README.md) -------------------------------------
UNSEEN = Path(__file__).parent / "data" / "logs"


def test_the_labs_older_quoted_dialect_reads_with_its_header_and_drops_impossible_rows():
    path = UNSEEN / "bmltools_example_imudata_quoted_tail.txt"
    with pytest.warns(UserWarning) as caught:
        log = read_log(path, ("leg_angle_left", "duty_right"))
    messages = [str(w.message) for w in caught]
    # the first line, '"Data file recorded 2014/2/3  17:54:20"', has no '%'; the frequency is given per side
    assert log.meta["date_iso"] == "2014-02-03T17:54:20"
    assert log.meta["stride_frequency_hz"] == [5, 5]
    assert log.meta["phase_counts"] == 16384  # 'Phase (Fractional) = 16384.0'
    assert log.meta["motor_gains"] == [1800, 20, 100, 0, 0, 1800, 20, 100, 0, 0]  # no closing quote on its line
    # the hand-added rows' legs jump 48 revolutions in 2.6 ms (line 496) and up to 0.4 s later: dropped, each named
    # (a jump after a longer gap is within the 100 rev/s a leg could turn: kept)
    jumps = [m for m in messages if "jumps" in m and "faster than 100 rev/s" in m]
    assert any("dropped malformed row at line 496: 0 counts jumps -47.9 revolutions from line 495 in 2.57 ms" in m
               for m in jumps)  # fmt: skip
    assert all("dropped malformed row at line" in m for m in jumps)
    assert any("DCR/DCL reach 4000 counts, beyond the duty full scale of 3900" in m for m in messages)
    assert np.all(np.diff(log.time) > 0)
    # the first data row, by hand: 10957 us, left leg 3080372 counts of 65536 per revolution
    assert log.time[0] == pytest.approx(0.010957)
    assert log.df["leg_angle_left"].iloc[0] == pytest.approx(3080372 * 2 * np.pi / 65536)


def test_a_wizard_export_that_sends_samples_again_after_a_broken_row_keeps_the_rest():
    path = UNSEEN / "meiosis_AX12A_LOAD2_1.csv"
    with pytest.warns(UserWarning) as caught:
        log = read_log(path, ("present_position",))
    dropped = sorted(
        int(m.group(1)) for w in caught if (m := re.search(r"dropped malformed row at line (\d+)", str(w.message)))
    )
    # line 113 '5,499' (a broken time), 114-115 (2480 and 2496 ms again, after 2496), 145 '6,498' (a broken time)
    assert dropped == [113, 114, 115, 145]
    assert np.all(np.diff(log.time) > 0)
    assert log.time[-1] == pytest.approx(5.648)  # the last line, 5648 ms


def test_time_that_goes_back_for_good_is_still_refused(tmp_path):
    lines = AX12A.read_text().splitlines()
    header, rows = lines[:5], lines[5:]
    kept = [r.split(",") for r in rows[100:] if len(r.split(",")) == 2 and r.split(",")[0].isdigit()]
    restarted = [f"{int(t) - 3000},{x}" for t, x in kept]  # the clock restarted: every later row is earlier
    path = tmp_path / "restarted.csv"
    path.write_text("\n".join(header + rows[:100] + restarted) + "\n")
    with pytest.raises(LogError, match=r"restarted\.csv: row at line \d+, column 'time'.*time runs backwards"):
        read_log(path, ("present_position",))


def test_a_wizard_export_without_its_preamble_and_rows_with_a_trailing_comma_read(tmp_path):
    bare = read_log(UNSEEN / "meiosis_512_noheader.csv", ("present_position",))
    assert bare.meta["format"] == "DYNAMIXEL Wizard export" and bare.meta["model"] is None
    assert bare.df["present_position"].iloc[-1] == pytest.approx(512, abs=5)
    lines = (UNSEEN / "meiosis_AX18A_NOLOAD_1.csv").read_text().splitlines()
    trailing = tmp_path / "trailing.csv"
    trailing.write_text("\n".join(lines[:5] + [line + "," for line in lines[5:]]) + "\n")
    a = read_log(UNSEEN / "meiosis_AX18A_NOLOAD_1.csv", ("present_position",))
    b = read_log(trailing, ("present_position",))
    pd.testing.assert_frame_equal(a.df, b.df)


def test_a_logged_goal_position_is_the_servos_goal_and_another_servo_is_named(tmp_path):
    lines = (UNSEEN / "meiosis_AX18A_NOLOAD_1.csv").read_text().splitlines()
    rows = [f"{r},512" for r in lines[5:]]
    path = tmp_path / "with_goal.csv"
    path.write_text("\n".join([*lines[:4], "Time[ms],Present Position,Goal Position", *rows]) + "\n")
    log = read_log(path, ("present_position",))
    assert "goal" in log.df.columns and np.all(log.df["goal"] == 512)
    with pytest.warns(UserWarning, match=r"with_goal\.csv: the export is of an AX-18A servo; the model is an AX-12A"):
        make_adapter("servo").check_logs([log])


def _roach_2hz_with(tmp_path: Path, name: str, fields: dict[int, str]) -> Path:
    """The 2 Hz log's first 3000 lines with the given fields of every data row replaced, written as ``name``."""
    out = []
    for line in ROACH_2HZ.read_text().splitlines()[:3000]:
        row = line.split(",")
        if not line.startswith("%") and len(row) >= 16:
            for k, value in fields.items():
                row[k] = value
        out.append(",".join(row))
    path = tmp_path / name
    path.write_text("\n".join(out) + "\n")
    return path


def test_a_roach_log_whose_commanded_legs_never_move_is_refused(tmp_path):
    path = _roach_2hz_with(tmp_path, "open_loop.txt", {3: "1000", 4: "2000"})  # Commanded Right/Left Leg Pos held
    log = read_log(path, ("leg_angle_left",))
    with pytest.raises(LogError, match=r"open_loop\.txt: columns 'Commanded Right Leg Pos' and 'Commanded Left Leg"):
        make_adapter("roach").check_logs([log])


def test_a_stuck_imu_column_is_warned_of_and_a_file_of_bad_rows_names_the_first(tmp_path):
    text = ROACH_2HZ.read_text().splitlines()
    path = _roach_2hz_with(tmp_path, "stuck.txt", {12: "-32768"})  # AZ
    with pytest.warns(UserWarning, match=r"stuck\.txt: column AZ reads -32768 .* on every row"):
        read_log(path, ("leg_angle_left",))
    bad = [line if line.startswith("%") else line.replace(",", ";") for line in text[:3000]]
    path = tmp_path / "semicolons.txt"
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(LogError, match=r"no valid data rows \(\d+ malformed rows skipped; the first: .*line \d+: 1 "):
        read_log(path, ("leg_angle_left",))


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ({"column": "enc", "unit": "rev", "counts_per_unit": 0}, r"'counts_per_unit' 0 is not a positive number"),
        ({"column": "enc", "unit": "rev", "counts_per_unit": "abc"}, r"'counts_per_unit' 'abc' is not a positive"),
        ({"column": "enc", "unit": ["rev"]}, r"unknown unit \['rev'\]"),
        ({"column": 3, "unit": "rev"}, r"'column' 3 is not a column name"),
        ({"column": "enc", "unit": "rev", "count_per_unit": 1000}, r"unknown key 'count_per_unit'"),
    ],
)
def test_a_column_map_with_a_bad_entry_is_refused_naming_it(tmp_path, entry, message):
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"time": {"column": "t_ms", "unit": "ms"}, "angle": entry}))
    with pytest.raises(LogError, match=r"map\.json: entry 'angle': " + message):
        ColumnMap.load(mapping)


def test_a_column_map_that_is_not_text_is_refused(tmp_path):
    mapping = tmp_path / "map.json"
    mapping.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(LogError, match=r"map\.json: not a readable JSON column map"):
        ColumnMap.load(mapping)


# --- column-mapped logs: real line numbers, repeated timestamps, a map given with native logs -----------------------
MAP = {"time": {"column": "t_ms", "unit": "ms"}, "angle": {"column": "enc", "unit": "rev", "counts_per_unit": 1000}}


def _mapped(tmp_path: Path, rows: list[str], name: str = "mapped.csv") -> tuple[Path, ColumnMap]:
    """A column-mapped CSV whose data begins at line 6, after comments and blank lines, and its map."""
    mapping = _write(tmp_path, "map.json", [json.dumps(MAP)])
    path = _write(tmp_path, name, ["# bench log, 2024-05-01", "", "t_ms,enc  # ms, counts", "# motor on", "", *rows])
    return path, ColumnMap.load(mapping)


def _mapped_rows(n: int = 300) -> list[str]:
    return [f"{5 * i},{3 * i}" for i in range(n)]


def test_a_mapped_csv_names_the_real_line_after_blank_and_comment_lines(tmp_path):
    rows = _mapped_rows()
    rows[10] = "50,abc"  # line 16
    rows[20] = ""  # line 26: blank, skipped
    rows[30] = "150,90,7"  # line 36: a field too many
    path, mapping = _mapped(tmp_path, rows)
    with pytest.warns(UserWarning) as caught:
        log = read_log(path, ("angle",), mapping)
    messages = [str(w.message) for w in caught]
    assert messages == [
        f"{path}: dropped malformed row at line 16: column 'enc': 'abc' is not a finite number",
        f"{path}: dropped malformed row at line 36: 3 fields, expected 2",
    ]
    assert log.meta["file_rows"][:3] == [6, 7, 8] and len(log.df) == 297
    restarted = _mapped_rows(150) + [f"{5 * i},{3 * i}" for i in range(150)]  # the clock restarts at line 156
    path, mapping = _mapped(tmp_path, restarted, "restarted.csv")
    with pytest.raises(LogError, match=r"restarted\.csv: row at line 156, column 'time': 0 s does not increase"):
        read_log(path, ("angle",), mapping)


def test_a_repeated_timestamp_is_named_as_such_and_dropped_like_any_malformed_row(tmp_path):
    rows = _gearmotor_rows()
    one = _write(tmp_path, "one.csv", ["time,pos,speed,power", *rows[:100], rows[99], *rows[100:]])
    with pytest.warns(UserWarning, match=r"one\.csv: dropped malformed row at line 102: time 1 s, "
                      r"the same as the row at line 101 \(a repeated timestamp\)"):  # fmt: skip
        log = read_log(one, ("duty",))
    assert len(log.df) == 300 and np.all(np.diff(log.time) > 0)
    doubled = _write(tmp_path, "doubled.csv", ["time,pos,speed,power", *[r for r in rows[:150] for _ in (0, 1)]])
    with pytest.raises(LogError, match=r"150 of 300 rows are malformed.*line 3: time 0\.01 s, "
                       r"the same as the row at line 2 \(a repeated timestamp\)"):  # fmt: skip
        read_log(doubled, ("duty",))
    stalled = _write(tmp_path, "stalled.csv", ["time,pos,speed,power", *rows[:100], *[rows[99]] * 20, *rows[100:]])
    with pytest.raises(LogError) as refused:
        read_log(stalled, ("duty",))
    assert (
        str(refused.value)
        == f"{stalled}: row at line 102, column 'time': 1 s, the same as the row at line 101: a repeated timestamp"
    )


def test_a_column_map_applies_only_to_the_logs_of_no_native_format(tmp_path, capsys, monkeypatch):
    t = np.arange(0, 2, 0.01)
    telemetry = tmp_path / "t.parquet"
    write_telemetry(telemetry, pd.DataFrame({"time": t, "duty": 0.5, "angle": t, "speed": 1.0}), {"robot": "motor"})
    mapped, mapping = _mapped(tmp_path, _mapped_rows())
    monkeypatch.setattr(calibrate, "_WARNED", set())  # each warning is printed once a process
    logs = calibrate.read_logs([mapped, GEARMOTOR, AX12A, ROACH_2HZ, telemetry], (), mapping)
    formats = [log.meta["format"] for log in logs]
    assert formats[0] == "mapped csv" and formats[2:] == [
        "DYNAMIXEL Wizard export",
        "ImageProc 2.5 VelociRoACH telemetry text (Experiment.py)",
        "skitter telemetry",
    ]
    assert formats[1].startswith("gearmotor CSV") and len(logs[1].df) == 1047
    unused = [line for line in capsys.readouterr().err.splitlines() if "the column map (--columns) is not used" in line]
    assert [m.split(": ")[2] for m in unused] == [str(p) for p in (GEARMOTOR, AX12A, ROACH_2HZ, telemetry)], unused


def test_a_log_without_the_column_maps_columns_is_named(capsys, tmp_path, monkeypatch):
    """The native training log reads past the map (said so); the test log of no known format lacks its columns."""
    monkeypatch.setattr(calibrate, "_WARNED", set())  # each warning is printed once a process
    mapping = _write(tmp_path, "map.json", [json.dumps(MAP)])
    other = _write(tmp_path, "other.csv", ["stamp,enc", *_mapped_rows()])
    code, err = _run(capsys, tmp_path, "motor", GEARMOTOR, other, "--columns", str(mapping))
    warning, error = err.splitlines()
    assert code == 2 and f"warning: {GEARMOTOR}: read as gearmotor CSV" in warning and "--columns" in warning
    assert f"{other}: the column map's column 't_ms' (for 'time') is missing; the file has ['stamp', 'enc']" in error


# --- column map units: of the channel's kind ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("channel", "unit", "message"),
    [
        ("angle", "A", "unit 'A' is a current, but channel 'angle' is an angle (rad); give one of rad, deg, rev"),
        ("angle", "V", "unit 'V' is a voltage, but channel 'angle' is an angle (rad)"),
        ("angle", "count", "give one of rad, deg, rev with counts_per_unit for a column of counts"),
        ("current_FL", "deg", "unit 'deg' is an angle, but channel 'current_FL' is a current (A); give one of A, mA"),
        ("time", "rad", "unit 'rad' is an angle, but channel 'time' is a time (s)"),
        ("leg_angle_cmd_left", "%", "unit '%' is a fraction, but channel 'leg_angle_cmd_left' is an angle (rad)"),
        ("duty", "V", "unit 'V' is a voltage, but channel 'duty' is a fraction (1); give one of 1, %"),
    ],
)
def test_a_column_map_unit_of_the_wrong_kind_is_refused_naming_file_channel_and_unit(tmp_path, channel, unit, message):
    entries = {"time": {"column": "t_ms", "unit": "ms"}, channel: {"column": "x", "unit": unit}}
    mapping = _write(tmp_path, "map.json", [json.dumps(entries)])
    with pytest.raises(LogError) as refused:
        ColumnMap.load(mapping)
    assert str(refused.value).startswith(f"{mapping}: entry {channel!r}: unit {unit!r} is ") and "\n" not in str(
        refused.value
    )
    assert message in str(refused.value)


def test_a_column_map_unit_of_the_wrong_kind_stops_calibrate_before_anything_is_written(capsys, tmp_path):
    mapping = _write(tmp_path, "map.json", [json.dumps({**MAP, "angle": {"column": "enc", "unit": "mA"}})])
    data = _write(tmp_path, "x.csv", ["t_ms,enc", *_mapped_rows()])
    before = sorted(p.name for p in tmp_path.iterdir())
    code, err = _run(capsys, tmp_path, "motor", data, GEARMOTOR, "--columns", str(mapping))
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{mapping}: entry 'angle': unit 'mA' is a current, but channel 'angle' is an angle (rad)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_column_map_units_of_the_right_kind_convert_and_a_missing_unit_is_the_channels_si_unit(tmp_path):
    entries = {"time": {"column": "t_ms", "unit": "ms"}, "angle": {"column": "enc"}, "leg_angle_left": {
        "column": "enc", "unit": "rev", "counts_per_unit": 2}, "current_FL": {"column": "enc", "unit": "mA"},
        "mystery": {"column": "enc", "unit": "V"}}  # fmt: skip
    mapping = _write(tmp_path, "map.json", [json.dumps(entries)])
    data = _write(tmp_path, "x.csv", ["t_ms,enc", *_mapped_rows()])
    log = read_log(data, (), ColumnMap.load(mapping))
    enc = log.df["angle"].to_numpy()  # no unit: the channel's own, rad
    assert np.allclose(log.df["leg_angle_left"], enc / 2 * 2 * math.pi) and np.allclose(log.df["current_FL"], enc / 1e3)
    assert np.allclose(log.df["mystery"], enc), "a channel skitter does not know is read as given"


def test_the_channel_kinds_agree_with_what_the_robots_declare():
    """sysid/logs.py's CHANNEL_UNITS against every robot's telemetry channels and every calibration adapter's
    channels: each declared channel has a known kind, the same as its declaration."""
    from envs.bench.robot import POSE_CHANNELS, MotorRig, ServoRig
    from envs.bioloid.robot import TELEMETRY_COLUMNS as BIOLOID
    from envs.velociroach.robot import TELEMETRY_COLUMNS as ROACH
    from envs.xjus.robot import TELEMETRY_COLUMNS as XJUS
    from sysid.logs import UNIT_KINDS, channel_unit
    from sysid.robots import adapters

    declared = [BIOLOID, ROACH, XJUS, MotorRig.actuator_channels, ServoRig.actuator_channels, POSE_CHANNELS]
    for adapter_class in adapters().values():
        declared.append(adapter_class.channels)
    for channels in declared:
        for channel, unit in channels.items():
            assert channel_unit(channel) == unit, (channel, unit)
            assert unit in set(UNIT_KINDS.values()), unit


# --- logs whose clock misbehaves ------------------------------------------------------------------------------------
def test_a_roach_log_whose_clock_goes_back_for_good_is_refused_naming_the_time_column(tmp_path):
    """A few rows that go back and rejoin are a broken sample (dropped); a clock that goes back and stays (a second
    recording appended) is time running backwards, refused like every other reader's."""
    lines = ROACH_2HZ.read_text().splitlines()[:3000]
    data = [k for k, line in enumerate(lines) if not line.startswith("%") and len(line.split(",")) >= 16]
    shifted = []
    for k, line in enumerate(lines):
        row = line.split(",")
        if k >= data[1500]:
            row[0] = str(int(row[0]) - 1_000_000)  # 1 s back, from the 1500th row on
        shifted.append(",".join(row))
    path = tmp_path / "restarted.txt"
    path.write_text("\n".join(shifted) + "\n")
    with pytest.raises(
        LogError, match=rf"restarted\.txt, line {data[1500] + 1}, field 1 \(time\): time runs backwards"
    ):
        read_log(path, ("leg_angle_left",))
    glitch = list(lines)
    row = glitch[data[1500]].split(",")
    row[0] = str(int(row[0]) - 1_000_000)  # one broken time: dropped, the log read
    glitch[data[1500]] = ",".join(row)
    path = tmp_path / "glitch.txt"
    path.write_text("\n".join(glitch) + "\n")
    with pytest.warns(UserWarning, match=rf"glitch\.txt: dropped malformed row at line {data[1500] + 1}: "):
        log = read_log(path, ("leg_angle_left",))
    assert len(log.df) == len(data) - 1


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_a_non_finite_value_is_a_malformed_row_in_every_reader(tmp_path, value):
    rows = _gearmotor_rows()
    rows[40] = f"410,{value},500,128"
    path = _write(tmp_path, "nan.csv", ["time,pos,speed,power", *rows])
    with pytest.warns(UserWarning, match=rf"nan\.csv: dropped malformed row at line 42: column 'angle': {value}"):
        log = read_log(path, make_adapter("motor").required())
    assert len(log.df) == 299 and np.isfinite(log.df[["time", "angle", "speed", "duty"]].to_numpy()).all()
    lines = AX12A.read_text().splitlines()
    broken = [*lines[:100], lines[100].split(",")[0] + f",{value}", *lines[101:]]
    path = _write(tmp_path, "ax_nan.csv", broken)
    with pytest.warns(UserWarning, match=r"ax_nan\.csv: dropped malformed row at line 101: column 'present_position'"):
        read_log(path, ("present_position",))


def test_a_gearmotor_csv_without_a_column_names_the_column(tmp_path):
    rows = [",".join(r.split(",")[:3]) for r in _gearmotor_rows()]
    path = _write(tmp_path, "three.csv", ["time,pos,speed", *rows])
    with pytest.raises(LogError, match=r"three\.csv: line 1 names the gearmotor CSV's columns .* lacks column 'power'"):
        read_log(path, ("duty",))


def test_a_byte_order_mark_is_not_part_of_the_first_line(tmp_path):
    """Excel's "CSV UTF-8" starts the file with a BOM: every reader, the column map and the calibration file skip it."""
    bom = b"\xef\xbb\xbf"
    for source, required in ((GEARMOTOR, ("duty",)), (AX12A, ("present_position",)), (ROACH_2HZ, ("leg_angle_left",))):
        path = tmp_path / f"bom_{source.name}"
        path.write_bytes(bom + source.read_bytes())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the real files' own dropped rows
            a, b = read_log(source, required), read_log(path, required)
        pd.testing.assert_frame_equal(a.df, b.df)
    mapped = tmp_path / "mapped.csv"
    mapped.write_bytes(bom + b"t_ms,enc\n" + b"".join(f"{10 * i},{i}\n".encode() for i in range(400)))
    column_map = tmp_path / "map.json"
    column_map.write_bytes(bom + json.dumps(MAP).encode())
    log = read_log(mapped, ("angle",), ColumnMap.load(column_map))
    assert log.time[1] == pytest.approx(0.01)


def test_a_channel_that_never_moves_has_no_noise_level_and_one_that_rests_takes_its_step(tmp_path):
    """Its errors would be divided by nothing (a test window of the gearmotor at rest read 1e12 noise levels): the
    reader's own step where it knows one, else the smallest step between the values, else refused."""
    adapter = make_adapter("motor")
    whole = read_log(GEARMOTOR, ("duty",))
    rest = whole.between(9.0, 1e9)  # the motor stopped: speed reads 0
    assert white_noise(rest.df["speed"].to_numpy()) == 0
    # a window at rest takes its file's estimate; a log of its own, the reader's step (the speed's is one click/s)
    file_white = white_noise(whole.df["speed"].to_numpy())
    assert file_white > 0 and adapter.noise(rest)["speed"] == pytest.approx(file_white)
    alone = Log(str(GEARMOTOR), rest.df, {"quantisation": whole.meta["quantisation"]})
    assert adapter.noise(alone)["speed"] == pytest.approx(whole.meta["quantisation"]["speed"] / np.sqrt(12))
    frozen = Log("frozen.csv", rest.df.assign(angle=1.5), {})  # no file, no step: refused
    with pytest.raises(LogError, match=r"frozen\.csv: channel 'angle' reads 1\.5 throughout"):
        adapter.noise(frozen)
    stepped = Log("stepped.csv", rest.df.assign(angle=np.where(np.arange(len(rest.df)) < 50, 1.0, 1.25)), {})
    assert adapter.noise(stepped)["angle"] == pytest.approx(0.25 / np.sqrt(12))


def test_a_window_before_or_past_its_log_is_refused_as_such(capsys, tmp_path):
    """A window must lie in its log: one that starts before the log (a negative time) is a typo, not the log's
    start, and one past its end says so before any overlap with another window is judged."""
    code, err = _run(capsys, tmp_path, "motor", Path(f"{GEARMOTOR}@-3:2"), Path(f"{GEARMOTOR}@5:"))
    assert code == 2 and "@-3:2: the window starts at -3 s, before the log, which runs from" in err
    code, err = _run(capsys, tmp_path, "motor", Path(f"{GEARMOTOR}@500:600"), Path(f"{GEARMOTOR}@5:"))
    assert code == 2 and "@500:600: the window lies outside the log" in err and "overlaps" not in err


def test_file_arguments_that_are_not_files_or_windows_say_so(capsys, tmp_path):
    folder = tmp_path / "adir"
    folder.mkdir()
    code, err = _run(capsys, tmp_path, "motor", folder, GEARMOTOR)
    assert code == 2 and f"{folder}: a directory, not a log file" in err
    for window in ("@abc:", "@5"):
        code, err = _run(capsys, tmp_path, "motor", Path(f"{GEARMOTOR}{window}"), AX12A)
        assert code == 2 and f"the window {window!r} is not @START:END in seconds" in err
    code = calibrate.main(["--robot", "motor", "--train", f"{GEARMOTOR}@0:5", "--test", f"{GEARMOTOR}@5:", "--out",
                           str(tmp_path / "out"), "--calibration", str(folder)])  # fmt: skip
    assert code == 2 and f"{folder}: a directory, not a calibration file" in capsys.readouterr().err


# --- samples the robot could not have produced ------------------------------------------------------------------
CLICKS_PER_RAD = 3592 / (2 * math.pi)  # the gearmotor log's encoder (data/real/README.md)


@pytest.mark.parametrize(
    ("field", "value", "needle"),
    [
        ("pos", f"{1e3 * CLICKS_PER_RAD:.0f}", "column 'angle': 1000 is "),  # an angle of 1e3 rad among ~10
        ("pos", "1e300", "column 'angle': 1.74922e+297 is "),  # clicks: 1.7e297 rad
        ("speed", "1e300", "column 'speed': 1.74922e+297 is outside what the channel can read, [-148, 148]"),
        ("power", "-700", "column 'duty': -2.7451 is outside what the channel can read, [-1, 1]"),
    ],
)
def test_one_impossible_sample_in_a_real_motor_log_is_dropped_naming_file_and_line(capsys, tmp_path, field, value,
                                                                                   needle):  # fmt: skip
    """One absurd finite value among 1,047 rows of the RHex3 gearmotor log was read without a word (and with 1e300
    every ranking score of the calibration was NaN): by the motor's own limits (its no-load speed, its duty) the row
    is dropped with a warning naming the file and its line, as a NaN row is, and the rest reads as before."""
    lines = GEARMOTOR.read_text().splitlines()
    row = 400  # line 401 of the file
    fields = lines[row].split(",")
    fields[("time", "pos", "speed", "power").index(field)] = value
    path = _write(tmp_path, "corrupt.csv", [*lines[:row], ",".join(fields), *lines[row + 1 :]])
    adapter = make_adapter("motor")
    [log] = calibrate.read_logs([path], adapter.required(), None, adapter.channel_limits())
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"calibrate.py: warning: {path}: dropped malformed row at line 401: "
                                               "a sample the robot could not produce: "), err  # fmt: skip
    assert needle in err[0] and "xjus-report" in err[0], err[0]
    clean = read_log(GEARMOTOR, adapter.required())
    assert len(log.df) == len(clean.df) - 1
    pd.testing.assert_frame_equal(log.df, clean.df.drop(index=row - 1).reset_index(drop=True))


def test_impossible_servo_positions_are_dropped_by_the_servos_range_and_speed(tmp_path):
    lines = AX12A.read_text().splitlines()
    header = next(i for i, line in enumerate(lines) if line.lower().startswith("time"))
    at = header + 60
    limits = make_adapter("servo").channel_limits()
    for value, needle in [("5000", "is outside what the channel can read, [0, 1023]"),
                          ("1023", "from its neighbours' median")]:  # fmt: skip
        t, position = lines[at].split(",")[:2]
        assert abs(float(position) - 1023) > 300, "a full-scale jump within one 16 ms sample"
        path = _write(tmp_path, "ax.csv", [*lines[:at], f"{t},{value}", *lines[at + 1 :]])
        with pytest.warns(UserWarning) as caught:
            log = read_log(path, ("present_position",), limits=limits)
        impossible = [str(w.message) for w in caught if "could not produce" in str(w.message)]
        assert len(impossible) == 1 and f"ax.csv: dropped malformed row at line {at + 1}: " in impossible[0]
        assert needle in impossible[0], impossible[0]
        assert (log.df["present_position"] <= 1023).all() and float(value) not in log.df["present_position"].tolist()


@pytest.mark.parametrize(
    ("robot", "path"),
    [
        ("motor", GEARMOTOR),
        ("servo", AX12A),
        *[("servo", p) for p in sorted((REAL.parents[1] / "tests" / "data" / "logs").glob("meiosis_*.csv"))],
        ("roach", ROACH_2HZ),
        ("roach", REAL / "velociroach_13Hz_beetleshell_grass_run3.txt"),
    ],
    ids=lambda v: getattr(v, "name", v),
)
def test_the_real_logs_hold_no_sample_their_robot_could_not_produce(robot, path):
    """The limits come from the hardware, not from these files; a general check must still pass every real log."""
    adapter = make_adapter(robot)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        log = read_log(path, adapter.required(), limits=adapter.channel_limits())
    assert not [str(w.message) for w in caught if "could not produce" in str(w.message)]
    assert len(log.df) > 100


def test_the_channel_limits_are_the_robots_from_its_actuators_constants():
    from envs.actuators.motor import LOG_SPEED_MARGIN, MotorConstants
    from envs.actuators.servo import MAX_SUPPLY_VOLTAGE, SPEED_PER_VOLT

    motor = make_adapter("motor").channel_limits()
    top = LOG_SPEED_MARGIN * MotorConstants().no_load_speed  # 5 x 29.6 rad/s
    assert (motor["speed"].low, motor["speed"].high, motor["angle"].max_rate) == (-top, top, top)
    assert (motor["duty"].low, motor["duty"].high) == (-1.0, 1.0)
    servo = make_adapter("servo").channel_limits()["present_position"]
    assert (servo.low, servo.high) == (0.0, 1023.0)
    assert servo.max_rate == pytest.approx(2 * SPEED_PER_VOLT * MAX_SUPPLY_VOLTAGE / (math.radians(300) / 1023))
    xjus = make_adapter("xjus")
    limits = xjus.channel_limits()
    assert limits == dict(xjus.nominal_robot.channel_limits)
    assert {c for c in xjus.required() if c in limits} >= set(xjus.channels), "every compared channel is bounded"
    for robot in ("motor", "servo", "bioloid"):
        adapter = make_adapter(robot)
        assert set(adapter.channels) <= set(adapter.channel_limits()), robot
    roach = make_adapter("roach").channel_limits()
    assert {"leg_angle_left", "leg_angle_right", "duty_left", "duty_right"} <= set(roach)


def test_a_synthetic_motor_log_at_full_duty_trips_no_limit():
    from sysid import synth
    from sysid.logs import check_log

    adapter = make_adapter("motor")
    log, _ = synth.synthesize("motor", {"supply_voltage": 1.5, "back_emf_constant": 0.3}, 0, seconds=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        checked = check_log(log, adapter.required(), adapter.channel_limits())
    assert len(checked.df) == len(log.df)


def test_an_impossible_bioloid_goal_is_dropped_and_many_are_refused(tmp_path, capsys):
    """A servo goal the AX-12 cannot take (1500 counts of 0..1023) in one row of the Bioloid's own telemetry is
    dropped with a warning naming the file, the column and the value; in more than 5% of the rows, the log is refused
    before anything runs, in one line naming them."""
    log, _ = synth.synthesize("bioloid", {}, 0, seconds=4.0)
    adapter = make_adapter("bioloid")
    df = log.df.copy()
    df.loc[40, "goal_F_L_3"] = 1500.0
    path = write_telemetry(tmp_path / "bad.parquet", df, log.meta)
    [read] = calibrate.read_logs([path], adapter.required(), None, adapter.channel_limits())
    err = capsys.readouterr().err
    assert "bad.parquet" in err and "goal_F_L_3" in err and "1500" in err and "could not produce" in err
    assert len(read.df) == len(df) - 1 and read.df["goal_F_L_3"].max() <= 1023
    df.loc[::10, "goal_F_L_3"] = 1500.0
    path = write_telemetry(tmp_path / "worse.parquet", df, log.meta)
    out = tmp_path / "cal"
    code = calibrate.main(["--robot", "bioloid", "--train", f"{path}@0:2", "--test", f"{path}@2:", "--out", str(out)])
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err
    assert "worse.parquet" in err and "goal_F_L_3" in err and "1500" in err


def test_bad_rows_of_every_kind_count_together_towards_the_refusal(tmp_path):
    """4% rows with a NaN and 4% with a duty the motor cannot take: each kind within 5%, together 8% refuse the log."""
    t = np.arange(1000) * 0.001
    duty = np.full(1000, 0.5)
    angle = t.copy()
    angle[10:50] = np.nan
    duty[500:540] = 3.0
    path = write_telemetry(tmp_path / "bad.parquet", pd.DataFrame({"time": t, "duty": duty, "angle": angle}),
                           {"robot": "motor"})  # fmt: skip
    adapter = make_adapter("motor")
    with pytest.warns(UserWarning), pytest.raises(LogError, match=r"80 of 1000 rows are malformed .*every kind"):
        read_log(path, ("duty", "angle"), limits=adapter.channel_limits())


def test_a_short_roach_run_is_cut_into_segments_of_its_strides():
    """A second of the 13 Hz log holds thirteen strides: it is cut into a burn-in and a scored segment of half a
    second each, so it can be fitted and tested on. Half a second of the 2 Hz log holds one stride, fewer than the
    two segments of a stride the replay needs: refused, naming the shortest usable log."""
    adapter = make_adapter("roach")
    (fast,) = calibrate.read_logs([Path(f"{REAL}/velociroach_13Hz_beetleshell_grass_run3.txt@8:8.99")],
                                  adapter.required(), None)  # fmt: skip
    assert adapter.stride_seconds(fast) == pytest.approx(1 / 13, rel=0.02)
    segments = adapter.segments(fast)
    assert len(segments) == 2
    for seg in segments:
        span = seg.data["time"][-1] - seg.data["time"][0]
        assert span >= 1 / 13 and span == pytest.approx(fast.duration / 2, abs=0.01)
    adapter.check_length([fast])
    (long,) = calibrate.read_logs([Path(f"{REAL}/velociroach_13Hz_beetleshell_grass_run3.txt@0:4")],
                                  adapter.required(), None)  # fmt: skip
    assert adapter.segment_length(long) == adapter.segment_seconds, "a long log keeps the robot's segments"
    (slow,) = calibrate.read_logs([Path(f"{REAL}/velociroach_behavior4_2Hz.txt@2:2.5")], adapter.required(), None)
    with pytest.raises(
        LogError,
        match=r"2Hz.txt@2:2.5: 0.498 s is too short to replay; the shortest usable log is "
        r"1 s \(a burn-in segment and a scored one, each of 1 stride of 0.50\d s\)",
    ):
        adapter.check_length([slow])


def test_another_robots_one_second_run_at_5_hz_is_replayed_and_measured():
    """The lab's 2014 log in its older dialect: five strides at 5 Hz in 0.99 s. It reads, it holds a burn-in and a
    scored segment of two and a half strides each, and it is measured directly (Adapter.measure_log)."""
    adapter = make_adapter("roach")
    (log,) = calibrate.read_logs([REAL / "velociroach_5Hz_bmltools_2014.txt"], adapter.required(), None)
    assert log.duration == pytest.approx(0.988, abs=0.002) and log.meta["motor_gains"][:5] == [1800, 20, 100, 0, 0]
    assert adapter.stride_seconds(log) == pytest.approx(0.2, rel=0.02)
    segments = adapter.segments(log)
    assert len(segments) == 2
    assert sorted(np.concatenate([s.samples for s in segments])) == list(range(len(log.df))), "every row, the last too"
    adapter.check_length([log])
    window = adapter._commanded(log)  # the tracking table's stretch: the run's second half, not empty
    assert log.time[window][0] == pytest.approx(log.time[0] + 0.5 * (log.time[-1] - log.time[0]), abs=0.003)
    found = {(m.quantity, m.side): m for m in adapter.measure_log(log)}
    assert found[("duty_sign", "left")].value == 1.0 and found[("kp", "right")].nominal == pytest.approx(1.175, 1e-3)
