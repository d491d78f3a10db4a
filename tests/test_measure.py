"""Direct measurements of a VelociRoACH log (sysid/adapters/velociroach_measure.py; python -m sysid.measure):
planted values in a synthetic log come back within their intervals, and on a real log the firmware's gains are the
header's through its arithmetic."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy import signal

from envs.velociroach.firmware import duty_gains
from sysid import measure
from sysid.adapters import velociroach_measure as roach
from sysid.measurement import Measurement
from sysid.robots import adapter as make_adapter

ROOT = Path(__file__).resolve().parents[1]
REAL_2HZ = ROOT / "data/real/velociroach_behavior4_2Hz.txt"
GAINS = [1800, 100, 200, 0, 200]  # the 2 Hz log's header, per side
BEMF, BEMF_DUTY, BEMF_OFFSET, OPEN_CIRCUIT, BATTERY_R = 0.021, -0.4, 0.05, 3.8, 0.3  # planted


def synthetic_log(seed: int = 0, run_seconds: float = 4.0, rate: float = 1000.0) -> tuple[pd.DataFrame, dict]:
    """A VelociRoACH log of the firmware's law with planted constants: at rest 0.5 s, the legs' clock at 5 Hz for
    ``run_seconds``, at rest 0.5 s; 2% of the rows missing, as the radio loses them."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, run_seconds + 1.0, 1.0 / rate)
    t = t[rng.random(len(t)) > 0.02]
    run = (t >= 0.5) & (t < 0.5 + run_seconds)
    clock = 2 * np.pi * 5.0 * np.clip(t - 0.5, 0.0, run_seconds)
    df = {"time": t}
    gains = duty_gains(GAINS)
    emf = {}
    for side, phase in (("left", 0.0), ("right", np.pi)):
        # the tracking error: a smooth random signal of a few hertz while the clock runs
        freqs, amps, phases = rng.uniform(0.5, 12.0, 6), rng.uniform(0.03, 0.12, 6), rng.uniform(0, 2 * np.pi, 6)
        lag = (amps[:, None] * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None])).sum(axis=0) * run
        leg = clock + phase - lag + rng.normal(0, 1e-4, len(t))  # as the encoder reads it
        err = clock + phase - leg  # the firmware's error is the measured one
        rate_err = np.gradient(err, t)
        integral = np.concatenate([[0.0], np.cumsum(0.5 * (err[1:] + err[:-1]) * np.diff(t))])
        duty = gains["ff"] + gains["kp"] * err + gains["ki"] * integral + gains["kd"] * rate_err
        duty = np.clip(duty + rng.normal(0, 0.005, len(t)), -0.95, 0.95)
        w = np.gradient(leg, t)
        emf[side] = BEMF * w
        df[f"leg_angle_cmd_{side}"] = clock + phase
        df[f"leg_angle_{side}"] = leg
        df[f"duty_{side}"] = duty
        df[f"bemf_{side}"] = emf[side] + BEMF_DUTY * duty * run + BEMF_OFFSET + rng.normal(0, 0.02, len(t))
    vb = np.full(len(t), OPEN_CIRCUIT)
    for _ in range(20):  # the battery's sag and the current it feeds, to their fixed point
        current = sum(np.maximum(df[f"duty_{s}"] * run * (df[f"duty_{s}"] * vb - emf[s]) / 3.3, 0) for s in emf)
        vb = OPEN_CIRCUIT - BATTERY_R * current
    df["vbatt"] = vb + rng.normal(0, 0.005, len(t))
    meta = {"motor_gains": GAINS * 2, "duty_clip": 0.95, "stride_frequency_hz": [5.0, 5.0]}
    return pd.DataFrame(df), meta


def _by_key(found: list[Measurement]) -> dict[tuple[str, str], Measurement]:
    return {(m.quantity, m.side): m for m in found}


def test_planted_constants_come_back_within_their_intervals():
    """Each planted constant is recovered closely; its 95% interval holds it in most cases (sixteen intervals of a
    log cannot all be asked to, and one that missed by far would fail the closeness)."""
    df, meta = synthetic_log()
    found = _by_key(roach.measure_roach(df, meta, "synthetic"))
    planted = duty_gains(GAINS)
    truths = {("battery_resistance", ""): BATTERY_R, ("battery_open_circuit", ""): OPEN_CIRCUIT}
    for side in ("left", "right"):
        truths |= {(g, side): planted[g] for g in ("kp", "ki", "kd")}
        truths |= {("loop_rate_from_kd", side): 1000.0, ("loop_rate_from_ki", side): 1000.0}
        truths |= {("bemf_constant", side): BEMF, ("bemf_duty", side): BEMF_DUTY}
        truths |= {("bemf_intercept", side): BEMF_OFFSET, ("bemf_at_rest", side): BEMF_OFFSET}
        assert found[("duty_sign", side)].value == 1.0
        assert found[("drive_balance", side)].value > 0
        assert found[("duty_at_clip", side)].value < 1.0  # the planted law seldom reaches its clip
        m = found[("bemf_constant", side)]
        assert m.ratio == pytest.approx(BEMF / m.nominal, rel=0.05), "compared with the model's K x gear"
        for gain in ("kp", "ki", "kd"):
            assert found[(gain, side)].nominal == pytest.approx(planted[gain]), "the header through the arithmetic"
    covered = 0
    for key, truth in truths.items():
        m = found[key]
        assert m.low <= m.value <= m.high, m
        # within 3% of the truth, or within its interval's width of it where the log holds less (the integral gain)
        assert abs(m.value - truth) < max(0.03 * abs(truth), m.high - m.low), (m, truth)
        covered += m.low <= truth <= m.high
    assert covered >= 0.7 * len(truths), f"{covered} of {len(truths)} intervals hold their planted value"


def test_the_time_a_leg_is_held_at_full_throttle():
    """A right leg held back for one second of the four-second run, its duty at the firmware's clip: a quarter of the
    running part, within the interval; the left leg, free, hardly ever there."""
    df, meta = synthetic_log()
    held = (df["time"] >= 2.0) & (df["time"] < 3.0)
    df.loc[held, "duty_right"] = meta["duty_clip"]
    found = _by_key(roach.measure_roach(df, meta, "synthetic"))
    m = found[("duty_at_clip", "right")]
    assert m.value == pytest.approx(25.0, abs=1.0) and m.low <= 25.0 <= m.high and m.unit == "%"
    assert found[("duty_at_clip", "left")].value < 1.0


def test_a_firmware_at_another_rate_is_found_at_its_rate():
    """The same law run at 500 Hz: its derivative and integral per tick read as a loop at half the rate, while the
    proportional gain stays the header's."""
    df, meta = synthetic_log(seed=1)
    planted = duty_gains(GAINS)
    # per tick at 500 Hz: the derivative term doubles and the integral's halves against time in seconds
    err = df["leg_angle_cmd_left"] - df["leg_angle_left"]
    t = df["time"].to_numpy()
    run = (t >= 0.5) & (t < 4.5)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (err.to_numpy()[1:] + err.to_numpy()[:-1]) * np.diff(t))])
    df["duty_left"] = np.clip(planted["ff"] + planted["kp"] * err + 0.5 * planted["ki"] * integral
                              + 2 * planted["kd"] * np.gradient(err, t), -0.95, 0.95) * run  # fmt: skip
    found = _by_key(roach.measure_roach(df, meta, "synthetic"))
    for source in ("kd", "ki"):
        m = found[(f"loop_rate_from_{source}", "left")]
        assert m.low <= 500.0 <= m.high and not m.low <= 1000.0 <= m.high, m
    m = found[("kp", "left")]
    assert m.low <= planted["kp"] <= m.high


def test_the_real_firmware_runs_the_headers_gains_at_1_khz():
    """The 2 Hz real log: its duty is the header's gains through the firmware's arithmetic at a 1 kHz tick. A unit
    wrong in that arithmetic is a shift (a power of two: 2^12, 2^4, a tick of 0.5 or 2 ms), so each measured gain
    and loop rate lies nearer its formula's value than half or twice it. Its duty drives the legs forward, and its
    back-EMF reading per leg speed is above the model's constant."""
    from sysid.cli import read_logs

    (log,) = read_logs([REAL_2HZ], make_adapter("roach").required(), None)
    found = _by_key(roach.measure_roach(log.df, log.meta, "2 Hz"))
    for side in ("left", "right"):
        for quantity in ("kp", "ki", "kd", "loop_rate_from_kd", "loop_rate_from_ki"):
            m = found[(quantity, side)]
            assert abs(np.log2(m.ratio)) < 0.5, m
        assert found[("duty_sign", side)].value == 1.0
        assert found[("bemf_constant", side)].low > found[("bemf_constant", side)].nominal


def test_a_log_without_running_is_refused_by_name():
    df, meta = synthetic_log(run_seconds=0.5)
    with pytest.raises(ValueError, match=r"short\.txt: the commanded legs move for 0\.\d+ s; .* needs 3 strides"):
        roach.measure_roach(df, meta, "short.txt")


def test_the_command_line_prints_the_table_and_refuses_bad_input(tmp_path, capsys):
    out = tmp_path / "m.json"
    assert measure.main(["--robot", "roach", f"{REAL_2HZ}@1:9", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "| bemf_constant | left |" in text and out.is_file()
    with pytest.raises(SystemExit) as exited:  # never over a user's file
        measure.main(["--robot", "roach", str(REAL_2HZ), "--out", str(out)])
    assert exited.value.code == 2 and "already exists" in capsys.readouterr().err
    assert measure.main(["--robot", "roach", str(tmp_path / "none.txt")]) == 2
    assert "no such file" in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    for bad, message in (
        (["--out", str(tmp_path / "file" / "m.json")], "is a file, not a directory"),
        (["--seed", "-1"], "--seed must be a whole number >= 0, got -1"),
    ):
        with pytest.raises(SystemExit) as exited:  # refused before anything is measured
            measure.main(["--robot", "roach", str(REAL_2HZ), *bad])
        assert exited.value.code == 2 and message in capsys.readouterr().err
    (tmp_path / "dangling.json").symlink_to(tmp_path / "nowhere.json")
    with pytest.raises(SystemExit):
        measure.main(["--robot", "roach", str(REAL_2HZ), "--out", str(tmp_path / "dangling.json")])
    assert not (tmp_path / "nowhere.json").exists()
    assert measure.main(["--robot", "roach", f"{REAL_2HZ}@100:200"]) == 2
    assert "the window lies outside the log, which runs from" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exited:  # a robot whose logs measure nothing by themselves is not offered
        measure.main(["--robot", "motor", str(REAL_2HZ)])
    assert exited.value.code == 2 and "invalid choice: 'motor' (choose from 'roach')" in capsys.readouterr().err


def test_a_file_that_appears_during_the_run_is_not_written_over(tmp_path, capsys):
    target = tmp_path / "m.json"
    target.write_text("the user's\n")
    assert measure._write_new(target, "measured\n") == 1
    assert target.read_text() == "the user's\n" and "left as it was" in capsys.readouterr().err
    assert measure._write_new(tmp_path / "new.json", "measured\n") == 0
    assert (tmp_path / "new.json").read_text() == "measured\n"
    kept = [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # the refused write's, named in its message
    assert len(kept) == 1 and kept[0].read_text() == "measured\n"


def test_the_back_emf_readings_scale_scales_only_the_reading_of_its_side():
    """The roach's ``sensor_gain_bemf_<side>`` (the board's uncalibrated divider) multiplies that side's back-EMF
    reading of the motor's speed, and leaves the legs, the duty and the other side's reading as they were; the
    reading's offset is added after it."""
    from types import SimpleNamespace

    robot = make_adapter("roach")
    rng = np.random.default_rng(0)
    sensordata = rng.normal(size=(50, max(robot._sensors.values()) + 1))
    segment = SimpleNamespace(data={"battery": np.array([3.7])})
    base = {"sensor_bias_bemf_left.offset": 0.1}
    plain = robot.observe(sensordata, segment, base)
    scaled = robot.observe(sensordata, segment, {**base, "sensor_gain_bemf_left.scale": 2.5})
    names = list(robot.channels)
    left, right = names.index("bemf_left"), names.index("bemf_right")
    assert np.allclose(scaled[:, left] - 0.1, 2.5 * (plain[:, left] - 0.1))
    others = [i for i in range(len(names)) if i != left]
    assert np.array_equal(scaled[:, others], plain[:, others]) and right in others
    effect = robot.effects()["sensor_gain_bemf_left"]
    assert (effect.params[0].low, effect.params[0].high) == (0.5, 3.0) and effect.catalogued


def test_the_back_emf_readings_running_offset_acts_only_while_the_clock_runs():
    """The roach's ``sensor_running_offset_bemf_<side>`` adds to that side's reading where its commanded leg rate is
    not zero (the firmware's clock running, the drive switching) and nowhere else, nor on any other channel."""
    from types import SimpleNamespace

    robot = make_adapter("roach")
    rng = np.random.default_rng(1)
    sensordata = rng.normal(size=(40, max(robot._sensors.values()) + 1))
    rate = np.where(np.arange(40) < 15, 0.0, 12.6)  # at rest, then running at 2 Hz
    data = {"battery": np.array([3.7]), "leg_rate_cmd_left": rate, "leg_rate_cmd_right": rate}
    segment = SimpleNamespace(data=data)
    plain = robot.observe(sensordata, segment, {})
    shifted = robot.observe(sensordata, segment, {"sensor_running_offset_bemf_right.offset": 0.2})
    names = list(robot.channels)
    right = names.index("bemf_right")
    assert np.allclose(shifted[:, right] - plain[:, right], np.where(rate != 0.0, 0.2, 0.0))
    others = [i for i in range(len(names)) if i != right]
    assert np.array_equal(shifted[:, others], plain[:, others])
    effect = robot.effects()["sensor_running_offset_bemf_right"]
    assert effect.catalogued and effect.params[0].low < 0 < 0.27 < effect.params[0].high  # the 13 Hz log's intercept


def _bemf(log: str, side: str, ratio: float, low: float, high: float, nominal: float = 0.01) -> Measurement:
    return Measurement(log, "bemf_constant", side, ratio * nominal, low * nominal, high * nominal, "V s/rad",
                       nominal, "the model")  # fmt: skip


def test_logs_are_pooled_by_inverse_variance_and_disagreeing_logs_are_flagged():
    from sysid.measurement import EffectReading, pool

    def reading(log: str, value: float, half: float) -> EffectReading:
        return EffectReading(log, "gain", "scale", value, value - half, value + half, 1.0, "q")

    (one,) = pool([reading("a", 2.0, 0.5)])
    assert (one.value, one.low, one.high, one.logs, one.logs_disagree) == (2.0, 1.5, 2.5, ("a",), False)
    assert one.significant
    (two,) = pool([reading("a", 2.0, 0.2), reading("b", 2.3, 0.4)])  # weights 4:1 by the intervals' widths
    assert two.value == pytest.approx((4 * 2.0 + 2.3) / 5) and not two.logs_disagree
    assert two.high - two.low == pytest.approx(0.4 / np.sqrt(1.25)), "narrower than either log's"
    (apart,) = pool([reading("a", 2.0, 0.1), reading("b", 3.0, 0.1)])
    assert apart.logs_disagree and apart.logs == ("a", "b")


def test_only_what_the_measurements_show_goes_into_the_calibration(capsys):
    """Of the back-EMF reading's scale per side: measured away from nominal and in range, written; an interval
    holding the nominal, left nominal; a value outside the effect's range, not written; two logs that disagree, not
    written and warned about."""
    robot = make_adapter("roach")
    shown = [_bemf("a", "left", 2.0, 1.8, 2.2), _bemf("a", "right", 1.2, 0.9, 1.5)]
    effects, pooled = measure.measured_effects(robot, shown)
    unit = robot.catalog()["sensor_gain_bemf_left"].params[0].unit
    written = {"value": pytest.approx(2.0), "ci95": [pytest.approx(1.8), pytest.approx(2.2)], "unit": unit}
    assert effects == {"sensor_gain_bemf_left": {"scale": written}}
    assert "holds the nominal 1: left nominal" in capsys.readouterr().out and len(pooled) == 2
    effects, _ = measure.measured_effects(robot, [_bemf("a", "left", 5.0, 4.5, 5.5)])
    assert effects == {} and "outside the effect's range [0.5, 3]: not written" in capsys.readouterr().out
    effects, _ = measure.measured_effects(robot, [_bemf("a", "left", 2.0, 1.9, 2.1), _bemf("b", "left", 2.6, 2.5, 2.7)])
    assert effects == {} and "the logs' intervals do not overlap" in capsys.readouterr().err


def test_planted_back_emf_constants_become_a_calibration_file(tmp_path, capsys):
    """A synthetic log's planted back-EMF per leg speed, duty coupling and zero come back as the catalog's
    parameters, and the file they are written to is a calibration the roach reads; the real 2 Hz log's too, from the
    command line."""
    from envs.common.calibration import read_calibration

    df, meta = synthetic_log()
    robot = make_adapter("roach")
    effects, _ = measure.measured_effects(robot, roach.measure_roach(df, meta, "synthetic"))
    nominal = roach.Nominal.from_model().bemf_constant
    for side in ("left", "right"):
        assert effects[f"sensor_gain_bemf_{side}"]["scale"]["value"] == pytest.approx(BEMF / nominal, rel=0.05)
        assert effects[f"sensor_coupling_bemf_{side}"]["per_unit"]["value"] == pytest.approx(BEMF_DUTY, abs=0.05)
        assert effects[f"sensor_bias_bemf_{side}"]["offset"]["value"] == pytest.approx(BEMF_OFFSET, abs=0.01)
    out = tmp_path / "measured.json"
    assert measure.main(["--robot", "roach", f"{REAL_2HZ}@0:6", "--calibration-out", str(out)]) == 0
    calibration = read_calibration(out, robot.robot)
    calibration.check(robot.known_effects())
    assert calibration.effects and calibration.provenance["tool"] == "python -m sysid.measure"
    assert calibration.setting.get("sensor_coupling_bemf_right.per_unit", 0.0) < 0
    capsys.readouterr()
    for bad, message in (
        (["--test", f"{REAL_2HZ}@6:"], "--test replays the measured model: give --calibration-out FILE too"),
        (["--calibration-out", str(out)], "already exists"),
        (["--out", str(tmp_path / "x.json"), "--calibration-out", str(tmp_path / "x.json")], "give two files"),
    ):
        with pytest.raises(SystemExit) as exited:
            measure.main(["--robot", "roach", f"{REAL_2HZ}@0:6", *bad])
        assert exited.value.code == 2 and message in capsys.readouterr().err
    overlapping = ["--calibration-out", str(tmp_path / "y.json"), "--test", f"{REAL_2HZ}@5:"]
    assert measure.main(["--robot", "roach", f"{REAL_2HZ}@0:6", *overlapping]) == 2
    assert "the test logs must be data the fit does not see" in capsys.readouterr().err
    assert not (tmp_path / "y.json").exists() and not (tmp_path / "x.json").exists()


def test_how_the_tracking_error_splits_a_stride_load_or_strides_held_back():
    """A leg's error that repeats every stride (a ripple at the stride's first and third harmonics) is found to
    repeat; one that holds the leg back for strides at a time (a smooth wander under half a hertz, against 5 Hz
    strides) is found to last strides; in their sum each planted share comes back inside its interval. The repeating
    part's pattern is the ripple's. Five strides are enough to split; two are not."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 20.0, 1e-3)
    clock = 2 * np.pi * 5.0 * t
    ripple = 0.1 * np.sin(clock) + 0.05 * np.sin(3 * clock + 1.0)
    wide = signal.sosfiltfilt(signal.butter(4, 0.5, fs=1e3, output="sos"), rng.normal(0, 1, len(t) + 10_000))
    slow = wide[5_000:-5_000]  # clear of the filter's start and end
    slow *= 0.1 / slow.std()
    noise = rng.normal(0, 0.01, len(t))
    locked = roach.tracking_parts(t, ripple + noise, clock)
    held = roach.tracking_parts(t, slow + noise, clock)
    mixed = roach.tracking_parts(t, ripple + slow + noise, clock)
    assert locked["stride_hz"] == pytest.approx(5.0)
    assert locked["stride"] > 95 and locked["slow"] < 2
    grid = np.linspace(0, 2 * np.pi, len(locked["pattern"]), endpoint=False)  # the ripple's own pattern
    np.testing.assert_allclose(locked["pattern"], 0.1 * np.sin(grid) + 0.05 * np.sin(3 * grid + 1.0), atol=2e-3)
    assert held["slow"] > 90 and held["stride"] < 5
    # variances: the ripple 0.1^2/2 + 0.05^2/2, the wander 0.1^2, the noise 0.01^2
    ripple_var, slow_var = 0.1**2 / 2 + 0.05**2 / 2, 0.1**2
    total = ripple_var + slow_var + 0.01**2
    for part, planted in (("stride", 100 * ripple_var / total), ("slow", 100 * slow_var / total)):
        low, high = mixed[f"{part}_ci"]
        assert low <= planted <= high and abs(mixed[part] - planted) < 5, (part, mixed, planted)
    five = t < 1.0
    short = roach.tracking_parts(t[five], (ripple + noise)[five], clock[five])
    assert short["stride"] > 90 and np.isfinite(short["stride_ci"]).all()
    two = t < 0.4
    assert roach.tracking_parts(t[two], ripple[two], clock[two]) is None, "two strides are too few to split"
    assert roach.tracking_parts(t, ripple, np.zeros_like(t)) is None, "a clock that does not run has no stride"


def test_a_held_out_log_under_a_load_no_training_log_holds_is_named():
    """A held-out log whose right leg is held back at full throttle for a quarter of its run, against training logs
    of free legs: its time at the clip lies above every training log's, and the table names it; the left leg's
    does not. A held-out log of free legs is within the training logs' conditions."""
    from sysid.measurement import compare_conditions, conditions_table

    quantities = make_adapter("roach").condition_quantities
    assert "duty_at_clip" in quantities
    train = [m for seed in (0, 1) for m in roach.measure_roach(*synthetic_log(seed, run_seconds=3.0), f"train{seed}")]
    df, meta = synthetic_log(2, run_seconds=3.0)
    free = roach.measure_roach(df, meta, "free")
    df.loc[(df["time"] >= 2.0) & (df["time"] < 3.0), "duty_right"] = meta["duty_clip"]
    held = roach.measure_roach(df, meta, "held")
    checks = {(c.quantity, c.side, c.held_out.log): c for c in compare_conditions(train, free + held, ["duty_at_clip"])}
    assert len(checks) == 4 and all(len(c.training) == 2 for c in checks.values())
    assert checks[("duty_at_clip", "right", "held")].outside
    assert checks[("duty_at_clip", "right", "held")].direction == "above"
    assert not any(c.outside for key, c in checks.items() if key != ("duty_at_clip", "right", "held"))
    text = conditions_table(list(checks.values()))
    assert "duty_at_clip right on held" in text and "**outside, above**" in text
    within = conditions_table([checks[("duty_at_clip", "left", "free")]])
    assert "no training log holds" not in within and "within the training logs'" in within


def test_the_13_hz_runs_load_moves_from_the_left_legs_to_the_right_between_its_windows():
    """The real 13 Hz run on grass and obstacles: from 3 to 6 s its left legs are held at the clip a sixth of the
    time, from 8 to 10 s hardly ever, while its right legs are held there far more (docs/real-logs.md)."""
    from sysid.cli import read_logs
    from sysid.measurement import compare_conditions

    adapter = make_adapter("roach")
    path = ROOT / "data/real/velociroach_13Hz_beetleshell_grass_run3.txt"
    train, test = read_logs([Path(f"{path}@3:6"), Path(f"{path}@8:10")], adapter.required(), None)
    checks = compare_conditions(adapter.measure_log(train), adapter.measure_log(test), ["duty_at_clip"])
    by_side = {c.side: c for c in checks}
    assert by_side["left"].outside and by_side["left"].direction == "below"
    assert by_side["left"].training[0].value > 10.0 > 1.0 > by_side["left"].held_out.value
    assert by_side["right"].outside and by_side["right"].direction == "above"
