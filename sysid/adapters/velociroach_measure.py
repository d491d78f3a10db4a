"""What a VelociRoACH log measures by itself, before any simulator (the roach's ``Adapter.measure_log``; ``python -m
sysid.measure --robot roach LOG ...``).

A calibration fits the model's effects to a replay. Some of the robot's constants need no replay: the log holds
them directly, and reading them first says where the nominal model is wrong and by how much. For each log (or
window ``FILE@START:END``) and side:

- **The firmware's PID** (``kp``, ``ki``, ``kd``): the logged duty regressed on the tracking error, its integral and
  its rate over the running part (rows at the duty clip left out). The header's integer gains through the
  firmware's arithmetic (``envs/velociroach/firmware.py``, ``duty_gains``) give what the regression should find;
  their ratio is the gain unit check. The derivative and the integral are per firmware tick, so each also measures
  the **loop rate**: ``kd`` falls and ``ki`` grows in proportion to it.
- **The duty's sign**: the sign of the measured ``kp`` (+1: a positive duty turns the leg forward, its counts up).
- **Back-EMF per leg speed** (``bemf_constant``, V s/rad: the motor's constant times the gear ratio): the back-EMF
  reading regressed on the leg speed, the duty and a constant over the running part and the rest before and after
  it. The duty's coefficient (``bemf_duty``) is what the reading holds besides the back-EMF: a sample taken while
  the winding's current still flows reads lower the higher the duty. The constant (``bemf_intercept``, V) is where
  the running relation meets zero speed and duty; the reading's mean over the rest rows whose leg is still
  (``bemf_at_rest``, V) is the board's zero. On a reading linear in speed and duty the two agree; an intercept above
  the zero is what the reading holds only while the motor runs (the catalog's ``sensor_running_offset_bemf_<side>``).
  It is reported, not written: on a run at one steady speed it trades against the back-EMF constant.
- **The battery's internal resistance** (``battery_resistance``, ohm) and open-circuit voltage: the logged battery
  voltage regressed on the battery current the duty draws, ``sum over sides of max(d (d Vb - E) / R, 0)`` with ``E``
  the measured back-EMF and ``R`` the motor's nominal winding resistance (an assumption the result scales with).
- **The time at the clip** (``duty_at_clip``, %): the share of the running part the duty is held at the firmware's
  clip (MAXTHROT): a leg held back, at full throttle, by more than the drive can carry. A log never at the clip
  has the interval [0, 3/n] (n its bootstrap blocks: the rule of three), not the point 0.
- **The drive balance** (``drive_balance``): the mean terminal voltage a braking (synchronous) H-bridge would apply,
  ``duty x Vb`` at the nominal 3900-count full scale, over the mean back-EMF. Legs that do work need it above 1; below
  1 the driver cannot be braking at that full scale: it coasts through its off-time (the motor then sees its
  back-EMF, not 0 V), or the full scale is smaller.
- **How the tracking error splits** (``tracking_stride``, ``tracking_slow``, % of the variance of the leg's error
  against its clock; :func:`tracking_parts`): the part that repeats every stride, and the part that lasts strides
  (a leg held back, or let run ahead, for strides at a time). A load that repeats every stride (the body's weight
  in stance, friction that depends on the crank's angle) gives an error that repeats; obstacles, uneven ground and
  slips do not.

The running part is where the commanded legs move; before and after it the motors are off (the firmware still logs
its PID's output). Intervals are 95% circular block bootstrap intervals (``arch``) with blocks of one stride, since
the residuals of a stride are not independent. Every value is reported beside the nominal model's and its source.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from envs.velociroach import constants
from envs.velociroach.firmware import TICK, duty_gains
from sysid.measurement import Measurement, bootstrap, lstsq

CLIPPED = 0.995  # a duty at this share of the clip or above is held at the clip (the PWM's count and rounding)

SIDES = constants.SIDES
MIN_STRIDES = 3  # strides of running a log needs: the bootstrap resamples whole strides
MIN_SPEED = 1.0  # rad/s: slower running rows do not enter the back-EMF regression's moving part
REST_BLOCK = 20  # rows: the bootstrap's blocks for the reading at rest (20 ms at the logs' 1 kHz)
HARMONICS = 5  # harmonics of the clock's angle that the tracking error's part repeating every stride is fitted on
BLOCK_STRIDES = 4  # strides a bootstrap block of the tracking error spans: its slow part lasts strides
PATTERN_POINTS = 72  # the repeating part's pattern, every 5 degrees of the clock's angle
ROWS_PER_STRIDE = 40  # the tracking error resampled at most this finely: eight samples a period of the fifth harmonic


@dataclass(frozen=True)
class Nominal:
    """The nominal model's constants the measurements are compared with."""

    bemf_constant: float  # V s/rad at the leg: motor constant x gear
    resistance: float  # ohm, the winding
    full_scale: int  # PWM counts of full duty
    battery_voltage: float  # V, the battery's open-circuit voltage
    battery_resistance: float  # ohm, its internal resistance
    source_bemf: str
    source_resistance: str

    @classmethod
    @functools.cache
    def from_model(cls) -> Nominal:
        """The VelociRoACH's MJCF (its motors' ``motorconst``, ``gear`` and ``resistance``)."""
        import mujoco

        from envs.actuators.dcmotor import GAIN_K, GAIN_R

        model = mujoco.MjModel.from_xml_path(str(constants.SCENE_XML))
        motor = model.actuator(constants.MOTORS["left"])

        return cls(
            bemf_constant=float(motor.gainprm[GAIN_K] * motor.gear[0]),
            resistance=float(motor.gainprm[GAIN_R]),
            full_scale=3900,
            source_bemf="assets/velociroach/velociroach.xml: Kt = 1.41 mN m/A (the lab's scaling script, unchecked) "
            "x gear 7 (chosen for 45 Hz strides)",
            source_resistance="assets/velociroach/velociroach.xml: R = 3.3 ohm (the lab's scaling script)",
            battery_voltage=float(model.numeric(constants.NUMERIC_BATTERY).data[0]),
            battery_resistance=float(model.numeric(constants.NUMERIC_BATTERY_RESISTANCE).data[0]),
        )


def running_mask(time: np.ndarray, commanded: np.ndarray) -> np.ndarray:
    """Rows from the first to the last change of any commanded leg angle (n, sides): the firmware's clock runs."""
    moving = np.any(np.abs(np.diff(commanded, axis=0)) > 0, axis=1)
    mask = np.zeros(len(time), dtype=bool)
    if moving.any():
        idx = np.flatnonzero(moving)
        mask[idx[0] : idx[-1] + 2] = True
    return mask


def measure_roach(
    df: Any, meta: dict[str, Any], name: str, nominal: Nominal | None = None, seed: int = 0
) -> list[Measurement]:
    """Measure a VelociRoACH log (our telemetry table, SI units, and its reader's record); see the module docstring.

    Raises ValueError naming the log when it has too little running for the regressions."""
    nominal = nominal or Nominal.from_model()
    t = df["time"].to_numpy(dtype=float)
    cmd = np.column_stack([df[f"leg_angle_cmd_{s}"].to_numpy(dtype=float) for s in SIDES])
    run = running_mask(t, cmd)
    stride = _stride_seconds(meta)
    span = 0.0 if run.sum() < 2 else t[run][-1] - t[run][0]
    if span < MIN_STRIDES * stride:
        raise ValueError(
            f"{name}: the commanded legs move for {span:.2f} s; measuring the firmware and the back-EMF needs "
            f"{MIN_STRIDES} strides of running ({MIN_STRIDES * stride:.2f} s at its {1 / stride:g} Hz)"
        )
    dt = float(np.median(np.diff(t)))
    block = max(round(stride / dt), 20)
    gains = meta.get("motor_gains")
    per_side = {}
    if gains is not None and len(gains) == 10:  # right first, as in the log's columns
        per_side = {"right": duty_gains(gains[0:5]), "left": duty_gains(gains[5:10])}
    clip = meta.get("duty_clip")
    vb = df["vbatt"].to_numpy(dtype=float)
    out: list[Measurement] = []
    speeds, emf = {}, {}

    def add(quantity: str, side: str, value: float, ci: np.ndarray, unit: str, nom: float | None, src: str,
            note: str = "") -> None:  # fmt: skip
        out.append(Measurement(name, quantity, side, float(value), float(ci[0]), float(ci[1]), unit,
                               None if nom is None else float(nom), src, note))  # fmt: skip

    for side in SIDES:
        q = df[f"leg_angle_{side}"].to_numpy(dtype=float)
        qc = df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float)
        d = df[f"duty_{side}"].to_numpy(dtype=float)
        e = df[f"bemf_{side}"].to_numpy(dtype=float)
        w = np.gradient(q, t)
        speeds[side] = w
        err = qc - q
        rate = np.gradient(err, t)
        integral = np.concatenate([[0.0], np.cumsum(0.5 * (err[1:] + err[:-1]) * np.diff(t))])
        limit = np.max(np.abs(d)) if clip is None else float(clip)
        use = run & (np.abs(d) < limit - 1e-9)
        x = np.column_stack([err, integral - integral[use][0], rate, np.ones_like(err)])[use]
        coef = lstsq(x, d[use])
        ci = bootstrap(lambda x, y: lstsq(x, y)[:3], block, x, d[use], seed=seed)
        formula = per_side.get(side, {})
        src = "the header's gains through the firmware's arithmetic at a 1 kHz tick (envs/velociroach/firmware.py)"
        add("kp", side, coef[0], ci[:, 0], "duty/rad", formula.get("kp"), src)
        add("ki", side, coef[1], ci[:, 1], "duty/(rad s)", formula.get("ki"), src)
        add("kd", side, coef[2], ci[:, 2], "duty s/rad", formula.get("kd"), src)
        if formula.get("kd") and formula.get("ki"):
            # kd per tick: measured kd = formula kd x (1 kHz / rate); ki per tick: measured ki = formula ki x rate/1 kHz
            rates = np.array([formula["kd"] / coef[2], coef[1] / formula["ki"]]) / TICK
            add("loop_rate_from_kd", side, rates[0], np.sort(formula["kd"] / ci[:, 2] / TICK), "Hz", 1 / TICK,
                "the firmware's 1 kHz PID tick (envs/velociroach/firmware.py)")  # fmt: skip
            add("loop_rate_from_ki", side, rates[1], ci[:, 1] / formula["ki"] / TICK, "Hz", 1 / TICK,
                "the firmware's 1 kHz PID tick (envs/velociroach/firmware.py)")  # fmt: skip
        sign = np.sign(ci[:, 0])
        add("duty_sign", side, np.sign(coef[0]), sign, "1", 1.0,
            "positive duty turns the leg forward (docs/telemetry.md)",
            "+1: a positive duty drives the leg's counts up" if coef[0] > 0 else "-1: a positive duty drives the leg "
            "back")  # fmt: skip
        # back-EMF reading against leg speed, duty and a constant: running rows that move, and the rest around them
        rows = (run & (np.abs(w) > MIN_SPEED)) | ~run
        x = np.column_stack([w, d * run, np.ones_like(w)])[rows]  # off: the reading holds no drive
        coef = lstsq(x, e[rows])
        ci = bootstrap(lambda x, y: lstsq(x, y)[:3], block, x, e[rows], seed=seed)
        add("bemf_constant", side, coef[0], ci[:, 0], "V s/rad", nominal.bemf_constant, nominal.source_bemf,
            "the motor's constant x gear ratio, from the back-EMF reading")  # fmt: skip
        add("bemf_duty", side, coef[1], ci[:, 1], "V", 0.0, "a back-EMF sample holds no drive",
            "what the reading holds besides the back-EMF, per unit duty")  # fmt: skip
        add("bemf_intercept", side, coef[2], ci[:, 2], "V", 0.0, "a linear reading: its zero (bemf_at_rest)",
            "the running relation at zero speed and duty")  # fmt: skip
        still = ~run & (np.abs(w) <= MIN_SPEED)
        # blocks of REST_BLOCK rows: at rest no stride correlates the noise, and a stride's blocks would leave the
        # rest before and after the run two or three of them. A log that starts running at once has no zero to read
        if still.sum() >= 10 * REST_BLOCK:
            zero = bootstrap(lambda y: np.array([np.mean(y)]), REST_BLOCK, e[still], seed=seed)
            add("bemf_at_rest", side, np.mean(e[still]), zero[:, 0], "V", 0.0, "a still leg reads no back-EMF",
                "the board's zero: the reading with the leg still and the motor off")  # fmt: skip
        emf[side] = coef[0] * w
    # the battery: open-circuit voltage and internal resistance against the current the duty draws
    current = np.zeros_like(t)
    for side in SIDES:
        d = df[f"duty_{side}"].to_numpy(dtype=float) * run
        current += np.maximum(d * (d * vb - emf[side]) / nominal.resistance, 0.0)
    x = np.column_stack([np.ones_like(t), -current])
    coef = lstsq(x, vb)
    ci = bootstrap(lambda x, y: lstsq(x, y), block, x, vb, seed=seed)
    add("battery_open_circuit", "", coef[0], ci[:, 0], "V", nominal.battery_voltage, "assets/velociroach/"
        f"velociroach.xml: a 1-cell LiPo, nominal {nominal.battery_voltage:g} V")  # fmt: skip
    add("battery_resistance", "", coef[1], ci[:, 1], "ohm", nominal.battery_resistance, "assets/velociroach/"
        f"velociroach.xml: {nominal.battery_resistance:g} ohm, the middle of the three real logs' measurements",
        f"with the winding's nominal {nominal.resistance:g} ohm")  # fmt: skip
    # the share of the running part the firmware's output is held at its clip (MAXTHROT): a leg the motor cannot
    # keep on its clock at full throttle (stalled or held back)
    for side in SIDES:
        d = np.abs(df[f"duty_{side}"].to_numpy(dtype=float))
        at_clip = (d >= CLIPPED * (np.max(d) if clip is None else float(clip)))[run].astype(float)
        ci = bootstrap(lambda a: np.array([100.0 * a.mean()]), block, at_clip, seed=seed)
        if at_clip.min() == at_clip.max():  # never (or always) at the clip: every resample agrees, the interval is
            # the point; the rule of three over the log's independent blocks bounds the share the log cannot see
            bound = 100.0 * min(1.0, 3.0 / max(len(at_clip) / max(block, 1), 1.0))
            ci[:, 0] = (0.0, bound) if at_clip.max() == 0 else (100.0 - bound, 100.0)
        add("duty_at_clip", side, 100.0 * at_clip.mean(), ci[:, 0], "%", None,
            "a leg the drive keeps on its clock never needs full throttle", "share of the running part")  # fmt: skip
    # the drive balance: a braking driver's mean terminal voltage over the mean back-EMF, per side
    for side in SIDES:
        d = df[f"duty_{side}"].to_numpy(dtype=float)
        moving = run & (np.abs(speeds[side]) > MIN_SPEED)
        drive, back = (d * vb)[moving], emf[side][moving]
        ci = bootstrap(lambda a, b: np.array([a.mean() / b.mean()]), block, drive, back, seed=seed)
        add("drive_balance", side, drive.mean() / back.mean(), ci[:, 0], "1", None,
            f"above 1 for a braking driver at {nominal.full_scale} counts full scale",
            "mean duty x Vb over mean back-EMF")  # fmt: skip
    for side in SIDES:
        error = df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float) - df[f"leg_angle_{side}"].to_numpy(dtype=float)
        parts = tracking_parts(t[run], error[run], cmd[run, SIDES.index(side)], seed=seed)
        if parts is None:
            continue
        src = "a load that repeats every stride (stance, the crank's angle) gives an error that repeats"
        add("tracking_stride", side, parts["stride"], parts["stride_ci"], "%", None, src,
            f"of the tracking error's variance: what repeats every stride ({parts['stride_hz']:.3g} Hz)")  # fmt: skip
        add("tracking_slow", side, parts["slow"], parts["slow_ci"], "%", None, src,
            "of the tracking error's variance: its mean over a stride (a leg held back for strides)")  # fmt: skip
    return out


def tracking_parts(t: np.ndarray, error: np.ndarray, clock: np.ndarray, seed: int = 0) -> dict[str, Any] | None:
    """How a leg's tracking error (``error``, rad, against its ``clock``, the commanded angle, at times ``t``)
    splits: ``stride``, the share (%) of its variance that repeats every stride (its least-squares fit on the first
    ``HARMONICS`` harmonics of the clock's angle, which follows the stride through changes of frequency); ``slow``,
    the share of the error averaged over one stride (a running mean one stride long, at the clock's median rate,
    which cancels what repeats every stride): the leg held back, or let run ahead, for strides at a time. The rest
    varies within a stride without repeating. 95% intervals from a circular block bootstrap of the rows in blocks of
    ``BLOCK_STRIDES`` strides (a third of a shorter record); ``pattern``, the repeating part over one turn of the
    clock's angle (``PATTERN_POINTS`` points from 0), rad. None where the clock does not run or the record holds
    under three strides."""
    rate = np.abs(np.gradient(clock, t)) if len(t) > 2 else np.zeros(len(t))
    if not (rate > 0).any():
        return None
    stride_hz = float(np.median(rate[rate > 0])) / (2 * np.pi)
    if not stride_hz > 0 or t[-1] - t[0] < MIN_STRIDES / stride_hz:
        return None
    # the log's step, or ROWS_PER_STRIDE rows a stride where it is finer: enough for the harmonics, and fast
    dt = max(float(np.median(np.diff(t))), 1.0 / (ROWS_PER_STRIDE * stride_hz))
    grid = np.arange(t[0], t[-1], dt)
    e, phase = np.interp(grid, t, error), np.interp(grid, t, clock)
    per = max(round(1.0 / (stride_hz * dt)), 1)  # rows a stride
    averaged = np.convolve(e, np.ones(per) / per, mode="valid")
    lead = (per - 1) // 2  # the rows the running mean is centred on
    e, phase = e[lead : lead + len(averaged)], phase[lead : lead + len(averaged)]
    k = np.arange(1, HARMONICS + 1)
    x = np.column_stack([np.ones_like(phase), np.cos(np.outer(phase, k)), np.sin(np.outer(phase, k))])

    def shares(x: np.ndarray, e: np.ndarray, averaged: np.ndarray) -> np.ndarray:
        spread = max(float(np.var(e)), 1e-300)
        repeat = x @ lstsq(x, e)
        return 100.0 * np.array([np.var(repeat), np.var(averaged)]) / spread

    value = shares(x, e, averaged)
    # the part that repeats, over one stride of the clock's angle: its pattern, to compare with another's
    angles = np.linspace(0.0, 2 * np.pi, PATTERN_POINTS, endpoint=False)
    beta = lstsq(x, e)[1:]
    pattern = np.column_stack([np.cos(np.outer(angles, k)), np.sin(np.outer(angles, k))]) @ beta
    block = min(BLOCK_STRIDES * per, max(len(e) // 3, 1))  # a short record: at least three blocks to resample
    ci = bootstrap(shares, block, x, e, averaged, seed=seed)
    return {"stride": float(value[0]), "slow": float(value[1]), "stride_ci": ci[:, 0], "slow_ci": ci[:, 1],
            "stride_hz": stride_hz, "pattern": pattern}  # fmt: skip


def _stride_seconds(meta: dict[str, Any]) -> float:
    """One stride (s) from the header's stride frequency, else 0.25 s."""
    freq = meta.get("stride_frequency_hz")
    values = [f for f in (freq or []) if f and f > 0]
    return 1.0 / min(values) if values else 0.25
