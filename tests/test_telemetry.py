"""Telemetry: the sim's Parquet recordings, and the real VelociRoACH's text format read, written and round-tripped."""

from __future__ import annotations

import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import envs  # noqa: F401  (registers skitter/...)
from envs.common import telemetry as telemetry_module
from envs.common.telemetry import read_telemetry, write_telemetry
from envs.velociroach.roach_csv import (
    DUTY_FULL_SCALE,
    QUANTISATION,
    REAL_COLUMNS,
    SHARED_COLUMNS,
    read_roach_csv,
    write_roach_csv,
)
from envs.velociroach.robot import TELEMETRY_COLUMNS

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
FILE_2HZ = REAL / "velociroach_behavior4_2Hz.txt"
FILE_13HZ = REAL / "velociroach_13Hz_beetleshell_grass_run3.txt"

COLUMNS_LINE = (
    "% time | Right Leg Pos | Left Leg Pos | Commanded Right Leg Pos | Commanded Left Leg Pos | DCR | DCL | "
    "GyroX | GryoY | GryoZ | AX | AY | AZ | RBEMF | LBEMF | VBatt"
)  # exactly as the lab's Experiment.py writes it
HEADER = (
    "%  Data file recorded 2015/2/28  16:7:3\n"
    "%  Stride Frequency         = [2, 2]\n"
    "%  Phase                    = 32768\n"
    "%  Motor Gains    = [1800, 100, 200, 0, 200, 1800, 100, 200, 0, 200]\n"
    "% Columns: \n" + COLUMNS_LINE + "\n"
)
ROW_1 = "1002,2965052,4377936,2967408,4376432,3800,-616,105,-104,-21,-100,100,3951,8,7,831"
ROW_2 = "2003,2965060,4377940,2967408,4376432,3800,-618,104,-105,-20,-92,107,3922,-4,3,831"
ROW_3 = "3004,2965060,4377936,2967408,4376432,3800,-516,103,-103,-21,-82,108,3924,-6,-6,831"


@pytest.fixture(scope="module")
def real_2hz():
    return read_roach_csv(FILE_2HZ)


@pytest.fixture(scope="module")
def real_13hz():
    return read_roach_csv(FILE_13HZ)


def _sim_episode(env_id: str, action: np.ndarray, steps: int):
    env = gym.make(env_id, telemetry=True)
    env.reset(seed=3)
    for _ in range(steps):
        env.step(action)
    recorder = env.unwrapped.recorder
    env.close()
    return env, recorder


@pytest.fixture(scope="module")
def sim_gait():
    """2 s of tripod at 6 strides/s in gait mode (50 Hz)."""
    env = gym.make("skitter/RoachWalk-v4")
    action = env.unwrapped.robot.mode.to_action([6.0, 6.0, math.pi])
    return _sim_episode("skitter/RoachWalk-v4", action, 100)


# --- the real files --------------------------------------------------------------------------------------------
def test_real_files_read_with_header_and_sampling(real_2hz, real_13hz):
    df, meta = real_2hz
    assert len(df) == 9832 and meta["rows"] == 9832
    assert meta["robot"] == "velociroach" and meta["source"] == str(FILE_2HZ)
    assert meta["controller"].startswith("gait mode")
    assert meta["date"] == "2015/2/28  16:7:3" and meta["date_iso"] == "2015-02-28T16:07:03"
    assert meta["stride_frequency_hz"] == [2, 2]
    assert meta["phase_counts"] == 32768 and meta["phase_rad"] == pytest.approx(math.pi)
    assert meta["motor_gains"] == [1800, 100, 200, 0, 200, 1800, 100, 200, 0, 200]
    assert meta["columns"][:3] == ["time", "Right Leg Pos", "Left Leg Pos"] and len(meta["columns"]) == 16
    assert "%  Experiment.py " in meta["header_other"]
    assert meta["rate_hz"] == pytest.approx(1e6 / 1001, rel=1e-4)
    assert meta["missing_samples"] == 167  # the README: about 167 missing
    assert meta["skipped_rows"] == []
    assert set(meta["units"]) == set(df.columns) - {"episode"}
    assert all(meta["units"][c] == TELEMETRY_COLUMNS[c] for c in SHARED_COLUMNS)
    assert (df["episode"] == 0).all()
    assert (np.diff(df["time"]) > 0).all()
    assert df["time"].iloc[0] == pytest.approx(1002e-6)
    # rows kept as they are: time gaps where samples are missing, not resampled
    assert np.diff(df["time"]).max() == pytest.approx(4004e-6)

    df13, meta13 = real_13hz
    assert len(df13) == 9689 and meta13["stride_frequency_hz"] == [13, 13]
    assert 2400 <= meta13["missing_samples"] <= 2600  # the README: about 2,500


def test_2hz_legs_advance_two_strides_per_second(real_2hz):
    df, _ = real_2hz
    run = df[(df["time"] >= 1.1) & (df["time"] <= 9.1)]
    for side in ("left", "right"):
        slope = np.polyfit(run["time"], run[f"leg_angle_cmd_{side}"], 1)[0]
        assert slope == pytest.approx(2 * 2 * math.pi, rel=0.05)
        measured = np.polyfit(run["time"], run[f"leg_angle_{side}"], 1)[0]
        assert measured == pytest.approx(2 * 2 * math.pi, rel=0.05)
    # before 1.1 s the commanded legs stand still
    rest = df[df["time"] < 1.0]
    assert rest["leg_angle_cmd_left"].nunique() == 1 and rest["leg_angle_cmd_right"].nunique() == 1


def test_real_battery_and_gravity(real_2hz, real_13hz):
    for df, _ in (real_2hz, real_13hz):
        rest = df[df["time"] < 0.1]
        assert 3.4 <= rest["vbatt"].median() <= 4.0
        assert 3.4 <= df["vbatt"].median() <= 4.0
        # under load the 2 Hz run's battery sags to 3.21 V (see docs/telemetry.md), never below 3.2 V
        assert df["vbatt"].min() > 3.2 and df["vbatt"].max() < 4.0
        assert rest["accel_z"].mean() == pytest.approx(9.81, rel=0.10)
        assert abs(rest["accel_x"].mean()) < 1.0 and abs(rest["accel_y"].mean()) < 2.0


def test_13hz_keeps_shell_sensors_and_reports_duty_clip(real_13hz):
    df, meta = real_13hz
    sensors = [f"S{i}" for i in range(1, 9)]
    assert list(df.columns[-8:]) == sensors
    assert meta["columns"][-8:] == sensors
    assert all(meta["units"][s] == "count" for s in sensors)
    assert all(df[s].dtype == np.int64 for s in sensors)
    assert df.loc[0, sensors].tolist() == [1011, 1329, 1184, 1193, 1582, 1220, 1340, 1728]  # first row, raw
    assert meta["duty_clip_counts"] == 3000
    assert meta["duty_clip"] == pytest.approx(3000 / DUTY_FULL_SCALE)
    assert meta["duty_clipped_samples"]["right"] > 1000 and meta["duty_clipped_samples"]["left"] > 500
    for side in ("left", "right"):
        assert df[f"duty_{side}"].max() == pytest.approx(3000 / 3900)
        assert df[f"duty_{side}"].min() == pytest.approx(-3000 / 3900)


def test_real_file_survives_read_write_read(real_13hz, tmp_path):
    df, meta = real_13hz
    out = write_roach_csv(df, tmp_path / "copy.txt", meta)
    original = FILE_13HZ.read_text().splitlines()
    written = out.read_text().splitlines()
    # every original line is there, in order; we add one provenance line
    assert [line for line in written if not line.startswith("%  Written by skitter")] == original
    df2, meta2 = read_roach_csv(out)
    pd.testing.assert_frame_equal(df, df2)
    for key in ("stride_frequency_hz", "phase_counts", "motor_gains", "columns", "date", "duty_clip_counts"):
        assert meta2[key] == meta[key]


def test_real_table_saves_as_parquet(real_2hz, tmp_path):
    df, meta = real_2hz
    path = write_telemetry(tmp_path / "real.parquet", df, meta)
    df2, meta2 = read_telemetry(path)
    pd.testing.assert_frame_equal(df, df2)
    assert meta2 == {**meta, "schema_version": meta2["schema_version"]}


# --- simulated telemetry, Parquet ------------------------------------------------------------------------------
def test_sim_episode_parquet_round_trip(sim_gait, tmp_path):
    env, recorder = sim_gait
    df = recorder.frame()
    assert len(df) == 101 and list(df.columns) == ["episode", *TELEMETRY_COLUMNS]
    path = recorder.save(tmp_path / "walk.parquet")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["walk.parquet"]  # no temporary file left beside it
    df2, meta = read_telemetry(path)
    pd.testing.assert_frame_equal(df, df2)
    assert meta == recorder.meta
    assert meta["robot"] == "velociroach"
    assert meta["model_hash"] == env.unwrapped.robot.model_hash
    assert meta["rate_hz"] == pytest.approx(50.0)
    assert meta["units"] == TELEMETRY_COLUMNS
    # readable without skitter: plain Parquet, the record as JSON under b"skitter"
    assert b"skitter" in pq.read_schema(path).metadata
    pd.testing.assert_frame_equal(pd.read_parquet(path), df)


def test_parquet_write_is_atomic(sim_gait, tmp_path, monkeypatch):
    _, recorder = sim_gait
    path = tmp_path / "walk.parquet"
    path.write_bytes(b"earlier run")

    def failing_write(table, where, **kwargs):
        Path(where).write_bytes(b"half a fi")
        raise OSError("disk full")

    monkeypatch.setattr(telemetry_module.pq, "write_table", failing_write)
    with pytest.raises(FileExistsError):
        recorder.save(path)  # never replaced silently
    with pytest.raises(OSError, match="disk full"):
        recorder.save(path, overwrite=True)
    assert path.read_bytes() == b"earlier run"  # the old file is untouched
    assert [p.name for p in tmp_path.iterdir()] == ["walk.parquet"]  # the partial temporary file is gone


# --- simulated telemetry, real format --------------------------------------------------------------------------
def _assert_within_quantisation(df: pd.DataFrame, back: pd.DataFrame, columns) -> None:
    for column in columns:
        error = np.abs(back[column].to_numpy() - df[column].to_numpy())
        assert error.max() <= QUANTISATION[column] / 2 * (1 + 1e-6) + 1e-12, column


def test_sim_to_real_csv_round_trip(sim_gait, tmp_path):
    env, recorder = sim_gait
    df = recorder.frame()
    meta = {**recorder.meta, "stride_frequency_hz": [6, 6], "phase_rad": math.pi}
    path = write_roach_csv(df, tmp_path / "sim.txt", meta)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sim.txt"]
    lines = path.read_text().splitlines()
    assert "%  Stride Frequency         = [6, 6]" in lines
    assert "%  Phase                    = 32768" in lines
    assert lines[-len(df) - 2 :][:2] == ["% Columns: ", COLUMNS_LINE]
    assert not any(line.startswith("%  Not in the source") for line in lines)  # gait mode has every column
    back, back_meta = read_roach_csv(path)
    assert len(back) == len(df)
    assert list(back.columns) == ["episode", *(c for c in TELEMETRY_COLUMNS if c in SHARED_COLUMNS)]
    _assert_within_quantisation(df, back, SHARED_COLUMNS)
    assert back_meta["stride_frequency_hz"] == [6, 6] and back_meta["phase_counts"] == 32768
    assert back_meta["rate_hz"] == pytest.approx(50.0)
    # the provenance line carries the model hash and controller through the text format
    assert back_meta["model_hash"] == env.unwrapped.robot.model_hash
    assert back_meta["controller"] == "gait mode"
    assert back_meta["zero_filled"] == []


def test_duty_mode_commanded_angles_written_as_zero(tmp_path):
    _, recorder = _sim_episode("skitter/RoachWalkDuty-v3", np.array([0.8, -0.3]), 200)
    df = recorder.frame()
    assert df["leg_angle_cmd_left"].isna().all()
    path = write_roach_csv(df, tmp_path / "duty.txt", recorder.meta)
    assert "%  Not in the source (written as 0) = Commanded Right Leg Pos, Commanded Left Leg Pos" in (
        path.read_text().splitlines()
    )
    back, back_meta = read_roach_csv(path)
    assert (back["leg_angle_cmd_left"] == 0).all() and (back["leg_angle_cmd_right"] == 0).all()
    assert back_meta["zero_filled"] == ["leg_angle_cmd_right", "leg_angle_cmd_left"]
    assert back_meta["controller"] == "duty mode"
    # written again from what was read, the file still says which columns are fill
    again = write_roach_csv(back, tmp_path / "again.txt", back_meta)
    assert read_roach_csv(again)[1]["zero_filled"] == ["leg_angle_cmd_right", "leg_angle_cmd_left"]
    _assert_within_quantisation(df, back, [c for c in SHARED_COLUMNS if not c.startswith("leg_angle_cmd")])
    assert back["duty_right"].iloc[-1] == pytest.approx(-0.3, abs=1 / 3900)


def test_write_takes_one_episode_and_needs_time(sim_gait, tmp_path):
    _, recorder = sim_gait
    df = recorder.frame()
    two = pd.concat([df, df.assign(episode=1)], ignore_index=True)
    with pytest.raises(ValueError, match=r"episodes \[0, 1\]"):
        write_roach_csv(two, tmp_path / "two.txt")
    with pytest.raises(ValueError, match="no 'time' column"):
        write_roach_csv(df.drop(columns="time"), tmp_path / "no_time.txt")
    assert list(tmp_path.iterdir()) == []


def test_write_refuses_to_overwrite(sim_gait, tmp_path):
    _, recorder = sim_gait
    df = recorder.frame()
    path = tmp_path / "run.txt"
    path.write_text("keep me\n")
    with pytest.raises(FileExistsError, match=re.escape(str(path))):
        write_roach_csv(df, path)
    assert path.read_text() == "keep me\n"
    write_roach_csv(df, path, overwrite=True)
    back, _ = read_roach_csv(path)
    assert len(back) == len(df)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.txt"]


# --- malformed files -------------------------------------------------------------------------------------------
def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_good_small_file_reads(tmp_path):
    df, meta = read_roach_csv(_write(tmp_path, "good.txt", HEADER + "\n".join([ROW_1, ROW_2, ROW_3]) + "\n"))
    assert len(df) == 3 and meta["rate_hz"] == pytest.approx(1e6 / 1001, rel=1e-3)
    # ROW_1 converted by hand with the lab's scaling (right before left in the file)
    expected = {
        "time": 1002e-6,
        "leg_angle_right": 2965052 * 2 * math.pi / 65536,
        "leg_angle_left": 4377936 * 2 * math.pi / 65536,
        "leg_angle_cmd_right": 2967408 * 2 * math.pi / 65536,
        "leg_angle_cmd_left": 4376432 * 2 * math.pi / 65536,
        "duty_right": 3800 / 3900,
        "duty_left": -616 / 3900,
        "gyro_x": math.radians(105 / 16.384),
        "gyro_y": math.radians(-104 / 16.384),
        "gyro_z": math.radians(-21 / 16.384),
        "accel_x": -100 / 4096 * 9.81,
        "accel_y": 100 / 4096 * 9.81,
        "accel_z": 3951 / 4096 * 9.81,
        "bemf_right": 8 * 3.3 / 1024 / (15 / 47),
        "bemf_left": 7 * 3.3 / 1024 / (15 / 47),
        "vbatt": 831 * (3.7 / 2.7) * 3.3 / 1023,
    }
    assert set(expected) == set(SHARED_COLUMNS)
    for column, value in expected.items():
        assert df[column].iloc[0] == pytest.approx(value, rel=1e-12), column
    assert df["vbatt"].iloc[0] == pytest.approx(3.674, abs=1e-3)


@pytest.mark.parametrize(
    ("name", "body", "line", "needle"),
    [
        ("float.txt", HEADER + ROW_1 + "\n" + ROW_2.replace(",-618,", ",-61.8,") + "\n", 8, "'-61.8'"),
        ("word.txt", HEADER + ROW_1 + "\n" + ROW_2.replace(",831", ",n/a") + "\n", 8, "'n/a'"),
        ("short.txt", HEADER + ROW_1 + "\n" + ROW_2.rsplit(",", 1)[0] + "\n", 8, "15 fields, expected 16"),
        ("long.txt", HEADER + ROW_1 + ",7\n" + ROW_2 + "\n", 7, "17 fields, expected 16"),
        ("time.txt", HEADER + ROW_2 + "\n" + ROW_1 + "\n", 8, "does not increase"),
    ],
)
def test_malformed_rows_raise_with_file_and_line(tmp_path, name, body, line, needle):
    path = _write(tmp_path, name, body)
    with pytest.raises(ValueError) as info:
        read_roach_csv(path)
    message = str(info.value)
    assert str(path) in message and f"line {line}" in message and needle in message


def test_non_integer_field_names_the_column(tmp_path):
    path = _write(tmp_path, "col.txt", HEADER + ROW_1.replace(",3951,", ",1e3,") + "\n")
    with pytest.raises(ValueError, match=r"line 7, field 13 \(AZ\): '1e3' is not an integer"):
        read_roach_csv(path)


def test_skip_bad_rows_reports_them(tmp_path):
    body = HEADER + "\n".join([ROW_1, ROW_2.replace(",-618,", ",x,"), ROW_3]) + "\n"
    path = _write(tmp_path, "skip.txt", body)
    with pytest.warns(UserWarning, match="skipped 1 malformed rows"):
        df, meta = read_roach_csv(path, skip_bad_rows=True)
    assert len(df) == 2
    assert [s["line"] for s in meta["skipped_rows"]] == [8]
    assert "'x' is not an integer" in meta["skipped_rows"][0]["reason"]


def test_header_without_columns_line_raises(tmp_path):
    body = "\n".join(line for line in HEADER.splitlines() if "|" not in line) + "\n" + ROW_1 + "\n"
    path = _write(tmp_path, "nocols.txt", body)
    with pytest.raises(ValueError, match=r"line 6: data begins but the header has no columns line") as info:
        read_roach_csv(path)
    assert str(path) in str(info.value)


def test_unknown_and_missing_columns_raise(tmp_path):
    unknown = HEADER.replace("| Left Leg Pos |", "| Llegs |")
    path = _write(tmp_path, "unknown.txt", unknown + ROW_1 + "\n")
    with pytest.raises(ValueError, match=r"line 6: column 3 is 'Llegs', expected 'Left Leg Pos'") as info:
        read_roach_csv(path)
    assert str(path) in str(info.value)

    missing = HEADER.replace(" | RBEMF | LBEMF | VBatt", "")
    path = _write(tmp_path, "missing.txt", missing + ",".join(ROW_1.split(",")[:13]) + "\n")
    with pytest.raises(ValueError, match=r"line 6: the columns line lacks the required columns") as info:
        read_roach_csv(path)
    assert "'VBatt'" in str(info.value) and str(path) in str(info.value)

    clash = HEADER.replace("| VBatt", "| VBatt | vbatt")
    path = _write(tmp_path, "clash.txt", clash + ROW_1 + ",1\n")
    with pytest.raises(ValueError, match=r"line 6: extra column 17 'vbatt' clashes"):
        read_roach_csv(path)


def test_missing_file_and_bad_header_values_raise(tmp_path):
    missing = tmp_path / "nope.txt"
    with pytest.raises(ValueError, match=re.escape(f"{missing}: no such file")):
        read_roach_csv(missing)
    path = _write(tmp_path, "phase.txt", HEADER.replace("= 32768", "= half") + ROW_1 + "\n")
    with pytest.raises(ValueError, match=r"line 3: Phase 'half' is not an integer"):
        read_roach_csv(path)
    path = _write(tmp_path, "empty.txt", HEADER)
    with pytest.raises(ValueError, match="no data rows"):
        read_roach_csv(path)


def test_real_columns_match_schema():
    assert len(REAL_COLUMNS) == 16
    assert set(SHARED_COLUMNS) <= set(TELEMETRY_COLUMNS)


def _stride_peak(df: pd.DataFrame) -> float:
    """The frequency (Hz) of the strongest line in sin(left leg angle), as the table's sampling shows it."""
    t = df["time"].to_numpy()
    signal = np.sin(df["leg_angle_left"].to_numpy())
    spectrum = np.abs(np.fft.rfft(signal - signal.mean()))
    return float(np.fft.rfftfreq(len(signal), t[1] - t[0])[np.argmax(spectrum)])


def test_physics_rate_telemetry_resolves_a_45_hz_stride_that_control_rate_aliases():
    """The tripod at 45 Hz under 50 Hz control: at the control rate the legs seem to turn at 5 Hz (aliased); at the
    physics rate (2 kHz) the stride shows at 45 Hz. The last physics step of each control step is the control-rate
    row, bit for bit."""
    from agents import load_policy

    tables = {}
    for rate in ("control", "physics"):
        env = gym.make("skitter/RoachWalk-v4", telemetry=rate)
        policy = load_policy("tripod", env)
        obs, _ = env.reset(seed=0)
        for _ in range(100):
            obs, *_ = env.step(policy.predict(obs)[0])
        tables[rate] = env.unwrapped.recorder.frame().iloc[1:]  # the steps, not the reset state
        assert env.unwrapped.recorder.meta["rate_hz"] == (50.0 if rate == "control" else 2000.0)
    control, physics = tables["control"], tables["physics"]
    assert len(physics) == 40 * len(control)
    assert np.allclose(np.diff(physics["time"]), 0.0005)
    pd.testing.assert_frame_equal(physics.iloc[39::40].reset_index(drop=True), control.reset_index(drop=True))
    assert abs(_stride_peak(physics) - 45.0) < 1.0
    assert _stride_peak(control) < 10.0, "the control rate cannot show a 45 Hz stride"


def test_physics_rate_telemetry_is_the_same_batched_and_single():
    single = gym.make("skitter/XjusWalk-v1", telemetry="physics", max_episode_steps=12)
    batched = gym.make_vec("skitter/XjusWalk-v1", num_envs=2, vectorization_mode="vector_entry_point",
                           telemetry="physics", max_episode_steps=12)  # fmt: skip
    actions = np.random.default_rng(0).uniform(-1, 1, (15, 2, 3))
    batched.reset(seed=5)
    single.reset(seed=6)
    for a in actions:
        batched.step(a)
        _, _, terminated, truncated, _ = single.step(a[1])
        if terminated or truncated:
            single.reset()
    mine = single.unwrapped.recorder.frame()
    theirs = batched.unwrapped.recorders[1].frame()
    pd.testing.assert_frame_equal(mine.query("episode == 0"), theirs.query("episode == 0"))
    with pytest.raises(ValueError, match="telemetry must be"):
        gym.make("skitter/XjusWalk-v1", telemetry="fast")
