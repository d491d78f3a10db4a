"""Calibration of the VelociRoACH against its telemetry (``calibrate.py --robot roach``), and the calibrated model
(``gym.make("skitter/RoachWalk-v4", calibration=PATH)``).

**Replay.** The real logs hold the firmware's commanded leg angles (its leg clock), the measured leg angles, the PWM
duty it applied and the battery voltage, at 1 kHz. They are replayed through the firmware's own PID law with the
gains in the log's header (the lab's ``pid-ip2.5.c``, ``UpdatePID``)::

    p = (Kp * e) >> 12;  i = (Ki * i_error) >> 12;  d = Kd * v_error
    out = ff + p + (i >> 4) + (d >> 4),  clipped to +-MAXTHROT;   i_error += e >> 4 every 1 ms tick

with ``e`` in encoder counts (65536 per leg revolution), ``v_error`` the commanded minus the measured counts per
tick (the firmware's first-difference velocity), and the output in PWM counts of a 3900-count period. In duty per
radian: Kp 1800 -> 1.175 /rad, Ki 100 -> 0.255 /(rad s), Kd 200 -> 0.033 /(rad/s), ff 200 -> 0.051 (a regression
of the logged duty on these terms gives the same gains, docs/calibration.md). The law runs natively as MuJoCo's
``dcmotor`` controller in plain voltage mode (terminal voltage = battery x duty, clipped to MAXTHROT): its gains are
written per segment for the segment's logged battery voltage; the derivative gain also cancels MuJoCo's back-EMF
compensation, and the feed-forward rides on the velocity input (:func:`firmware_gains`). What the log does not hold
is carried over from the previous segment (the body's pose and motion) or read off the log (the firmware's
integrator, from the logged duty at the segment's start).

**Channels** compared: leg angle, duty and back-EMF reading per side. **Effects** (per side where the robot has
sides): delay of the commands, Coulomb and viscous friction and rotor inertia of each side's drive, each motor's
torque (= back-EMF) constant, the supply (a scale on the logged battery voltage), foot friction, ground stiffness
and damping, leg stiffness, body mass and centre of mass, the back-EMF reading's offset. Backlash and deadband are
not offered: the crank linkage has no free play to give, and the firmware's duty is its own output (no driver
deadband is observable beside it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import mujoco
import numpy as np

from envs.actuators.dcmotor import (
    DYN_IMAX,
    DYN_SLEW,
    GAIN_K,
    GAIN_KD,
    GAIN_KI,
    GAIN_KP,
    GAIN_R,
    GAIN_VMAX,
    INPUT_POS,
    INPUT_VEL,
)
from envs.common import edits
from envs.common.effects import Effect, Param
from envs.velociroach import constants
from envs.velociroach.effects import effects_edit, periodic_load, roach_effects
from envs.velociroach.firmware import COUNTS_PER_RAD, PWM_PERIOD, TICK, duty_gains  # noqa: F401 (its names here too)
from envs.velociroach.robot import linkage, set_crank
from sysid.adapters.velociroach_measure import CLIPPED, MIN_STRIDES, tracking_parts
from sysid.logs import Log, LogError
from sysid.problem import Adapter, Segment, Setting, simulate

SIDES = constants.SIDES


def firmware_gains(gains: Mapping[str, float], battery: float, resistance: float, k: float, gear: float) -> dict:
    """MuJoCo dcmotor controller gains that make its terminal voltage the firmware's ``battery x duty``.

    MuJoCo drives ``v = (R/K) [kp_m e_m + ki_m x_m + kd_m (u_vel - w_m)] + K w_m`` in motor-shaft units (``e_m = gear
    e``, ``w_m = gear w``); the firmware wants ``v = Vb [ff + kp e + ki int(e) + kd (v_cmd - w)]``. Matching the terms:
    ``kp_m = Vb kp K / (R gear)`` (and ki alike), ``kd_m = (Vb kd + K gear) K / (R gear)`` (which also cancels the
    back-EMF compensation), and the velocity input ``u_vel = (Vb kd v_cmd + Vb ff) gear / (Vb kd + K gear)``.
    """
    scale = battery * k / (resistance * gear)
    kd_m = (battery * gains["kd"] + k * gear) * k / (resistance * gear)
    return {"kp": gains["kp"] * scale, "ki": gains["ki"] * scale, "kd": kd_m,
            "vel_per_cmd": battery * gains["kd"] * gear / (battery * gains["kd"] + k * gear),
            "vel_offset": battery * gains["ff"] * gear / (battery * gains["kd"] + k * gear)}  # fmt: skip


def configure_firmware(spec: mujoco.MjSpec) -> None:
    """Spec edit: both motors take a position and a velocity input and run a PID with an integrator (gains are
    written per segment)."""
    for side in SIDES:
        a = spec.actuator(constants.MOTORS[side])
        a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        a.ctrlspec = INPUT_POS | INPUT_VEL
        a.gainprm[GAIN_KP] = 1.0
        a.gainprm[GAIN_KI] = 1.0
        a.gainprm[GAIN_KD] = 1.0
        a.gainprm[GAIN_VMAX] = 3.7
        a.dynprm[DYN_SLEW] = 0.0
        a.dynprm[DYN_IMAX] = 0.0  # the firmware's integrator is unbounded (Kaw = 0 in the logs)
        a.actdim = 1


def add_bump(height: float):
    """Spec edit (synthetic data only): bumps of the floor across the robot's path every 0.25 m, sixteen each way from
    the start: the synthetic excitation runs it 2 to 4 m and up to 1.9 m sideways."""
    return edits.add_bump(height, x=0.25, width=2.5, count=16)


# Spec edit (synthetic data only): a yaw torque on the body from outside the model
add_disturbance = edits.add_site_disturbance("imu", axis=2)


class RoachAdapter(Adapter):
    """The VelociRoACH replayed from its logged leg commands through the firmware's PID with the logged gains."""

    name = "roach"
    robot = "velociroach"
    channels = {"leg_angle_left": "rad", "leg_angle_right": "rad", "duty_left": "1", "duty_right": "1",  # noqa: RUF012
                "bemf_left": "V", "bemf_right": "V"}  # fmt: skip
    commands = ("leg_angle_cmd_left", "leg_angle_cmd_right", "vbatt")
    segment_seconds = 1.0
    # each side's channels against that side's leg rate, clock, duty and crank angle (cos > 0: the side's legs in
    # the lower half of their stroke, stance)
    context = {
        key: {f"{channel}_{side}": f"{column}_{side}" for side in SIDES for channel in ("leg_angle", "duty", "bemf")}
        for key, column in (("velocity", "leg_rate"), ("command", "leg_angle_cmd"), ("load", "duty"),
                            ("phase", "leg_angle"))
    } | {"supply": "vbatt"}  # fmt: skip
    replay_floor = True  # the body's state is not logged and its contacts make replay sensitive to it
    burn_in = True  # a log's first segment guesses the body's state: replayed, carried over, not counted
    # a short run is cut into segments of a stride at least: each leg's stance and swing once in each
    min_segment_strides = 1.0
    fd_step = 0.02  # contacts make the cost rough at small scales: difference over 2% of each range,
    rough_cost = True  # and fit without derivatives
    chain_search = (1, 1, 1)  # each joint fit costs minutes (thousands of segment rollouts): one chain per length
    # a leg held back at full throttle, and for strides at a time: the load of the ground it ran on, which a flat
    # floor's replay does not have (the back-EMF, the gains and the battery are the robot's own)
    condition_quantities = ("duty_at_clip", "tracking_slow")

    def __init__(self) -> None:
        super().__init__()
        from envs.velociroach.robot import VelociRoach

        self._robot_class = VelociRoach
        robot = self.nominal_robot = self._make_robot(())
        self._nominal_gains = robot.model.actuator_gainprm.copy()
        self._h = float(robot.model.opt.timestep)
        self._crank_qpos = {s: int(robot.model.joint(constants.CRANK_JOINTS[s]).qposadr[0]) for s in SIDES}
        self._crank_dof = {s: int(robot.model.joint(constants.CRANK_JOINTS[s]).dofadr[0]) for s in SIDES}
        self._motor = {s: robot.model.actuator(constants.MOTORS[s]).id for s in SIDES}
        self._gear = float(robot.model.actuator_gear[self._motor["left"], 0])
        names = (
            *constants.SENSOR_LEG_POS.values(),
            *constants.SENSOR_MOTOR_TORQUE.values(),
            *constants.SENSOR_MOTOR_VEL.values(),
        )
        self._sensors = {name: int(robot.model.sensor(name).adr[0]) for name in names}
        self._sensors_gyro = int(robot.model.sensor(constants.SENSOR_GYRO).adr[0])

    def _make_robot(self, edits):
        return self._robot_class(action_mode="duty", imu_noise=None, spec_edits=[configure_firmware, *edits])

    @property
    def physics_dt(self) -> float:
        return self._h

    def effects(self) -> dict[str, Effect]:
        return roach_effects(self._h)

    # --- logs -------------------------------------------------------------------------------------------------------
    def check_logs(self, logs: Sequence[Log]) -> None:
        for log in logs:
            gains = log.meta.get("motor_gains")
            if gains is None or len(gains) != 10:
                raise LogError(
                    f"{log.path}: header field 'Motor Gains' is missing or not 10 numbers ({gains!r}): the replay "
                    "runs the firmware's PID with the logged gains"
                )
            if float(log.meta.get("duty_clip") or 0) <= 0:
                raise LogError(f"{log.path}: no duty clip level in the log's record")
            still = [c for c in ("leg_angle_cmd_right", "leg_angle_cmd_left") if np.ptp(log.df[c].to_numpy()) == 0]
            if len(still) == 2:
                raise LogError(
                    f"{log.path}: columns 'Commanded Right Leg Pos' and 'Commanded Left Leg Pos' never change: not a "
                    "gait-mode run (an open-loop duty test?); the replay runs the firmware's PID after the commanded "
                    "legs"
                )

    def stride_seconds(self, log: Log) -> float | None:
        """The slower side's stride while its commanded leg moves: one revolution of the leg clock."""
        t = log.time
        periods = []
        for side in SIDES:
            rate = np.abs(np.gradient(log.df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float), t))
            if (rate > 0).any():
                periods.append(2 * math.pi / float(np.median(rate[rate > 0])))
        return max(periods) if periods else None

    def segments(self, log: Log) -> list[Segment]:
        out = super().segments(log)
        gains = log.meta["motor_gains"]
        # the log's columns put the right side first: [Kp, Ki, Kd, Kaw, ff] right, then left
        per_side = {"right": duty_gains(gains[0:5]), "left": duty_gains(gains[5:10])}
        clip = float(log.meta["duty_clip"])
        t = log.time
        # the firmware's v_input (its clock's rate) and the measured leg rate, once per log
        clock_rate = {s: np.gradient(log.df[f"leg_angle_cmd_{s}"].to_numpy(dtype=float), t) for s in SIDES}
        leg_rate = {s: np.gradient(log.df[f"leg_angle_{s}"].to_numpy(dtype=float), t) for s in SIDES}
        for seg in out:
            lead = np.searchsorted(t, seg.lead.get("time", np.zeros(0)))
            for side in SIDES:
                for key, value in per_side[side].items():
                    seg.data[f"gain_{key}_{side}"] = np.array([value])
                seg.data[f"leg_rate_cmd_{side}"] = clock_rate[side][seg.samples]
                seg.lead[f"leg_rate_cmd_{side}"] = clock_rate[side][lead]
                seg.data[f"leg_rate_{side}"] = leg_rate[side][seg.samples]
            seg.data["duty_clip"] = np.array([clip])
            seg.data["battery"] = np.array([float(np.mean(seg.data["vbatt"]))])
        return out

    # --- replay -----------------------------------------------------------------------------------------------------
    def structure(self, setting: Setting) -> tuple:
        """The structural effects of :class:`~sysid.problem.Adapter`, and the harmonics of each crank's periodic load
        (each adds a spring, and a higher one a joint)."""
        return (*super().structure(setting), *(tuple(periodic_load(setting, side)) for side in SIDES))

    def spec_edits(self, setting: Setting) -> list:
        return [effects_edit(setting), *self.structural_edits(setting, bump=add_bump, disturbance=add_disturbance)]

    def segment_edits(self, segment: Segment, setting: Setting) -> tuple[tuple, list]:
        """The firmware's gains for the segment's battery voltage and duty clip (after the setting's edits, which
        set the motor constant the gains are matched through)."""
        battery = self._battery(segment, setting)
        clip = float(segment.data["duty_clip"][0])
        gains = {side: self._gains(segment, side) for side in SIDES}

        def edit(spec: mujoco.MjSpec) -> None:
            for side in SIDES:
                a = spec.actuator(constants.MOTORS[side])
                g = firmware_gains(gains[side], battery, a.gainprm[GAIN_R], a.gainprm[GAIN_K], self._gear)
                a.gainprm[GAIN_KP], a.gainprm[GAIN_KI], a.gainprm[GAIN_KD] = g["kp"], g["ki"], g["kd"]
                a.gainprm[GAIN_VMAX] = clip * battery

        key = (round(battery, 9), clip, tuple(tuple(sorted(g.items())) for g in gains.values()))
        return key, [edit]

    def _gains(self, segment: Segment, side: str) -> dict[str, float]:
        return {k: float(segment.data[f"gain_{k}_{side}"][0]) for k in ("kp", "ki", "kd", "ff")}

    def _battery(self, segment: Segment, setting: Setting) -> float:
        return float(segment.data["battery"][0]) * setting.get("supply_voltage.scale", 1.0)

    def initial_state(self, model, data, segment: Segment, setting: Setting, carried: bool = False) -> None:
        """The measured leg angles and rates (the linkage moved with them); the body carried over, or standing at
        rest on the first segment; the firmware's integrator read off the logged duty."""
        if not carried:
            data.qpos[:] = model.qpos0  # standing; the cranks and the linkage set below
            data.qvel[:] = 0.0
        for side in SIDES:
            crank = self._crank_qpos[side]
            tied = linkage(model, crank)  # the model's own: a periodic load's springs are geared to the crank
            target = float(segment.data[f"leg_angle_{side}"][0])
            rate = float(segment.data[f"leg_rate_{side}"][0])
            if carried:  # the carried linkage turned with its crank
                for adr, _c0, c1 in tied:
                    data.qpos[adr] += c1 * (target - data.qpos[crank])
                data.qpos[crank] = target
            else:  # from rest, by the model's own references (a leg phase moves the cranks')
                set_crank(data.qpos, model.qpos0, crank, tied, target)
            data.qvel[self._crank_dof[side]] = rate
            for adr, _c0, c1 in tied:
                dof = int(np.flatnonzero(model.jnt_qposadr == adr)[0])
                data.qvel[model.jnt_dofadr[dof]] = c1 * rate
            integral = self._integral(segment, side, setting.get("delay.seconds", 0.0))
            if integral is not None:
                data.act[model.actuator_actadr[self._motor[side]]] = self._gear * integral

    def _integral(self, segment: Segment, side: str, delay: float = 0.0) -> float | None:
        """The firmware's integrated error (rad s) at the segment's start, from its logged duty: (duty - ff - kp e -
        kd (v_cmd - v)) / ki, with the commands as the delayed controller sees them; None when the duty is clipped
        there (the integrator is then not observable)."""
        g = self._gains(segment, side)
        duty = float(segment.data[f"duty_{side}"][0])
        if g["ki"] <= 0 or abs(duty) >= CLIPPED * float(segment.data["duty_clip"][0]):
            return None
        t0 = np.zeros(1)
        e = float(segment.command_at(f"leg_angle_cmd_{side}", t0, delay)[0] - segment.data[f"leg_angle_{side}"][0])
        dv = float(segment.command_at(f"leg_rate_cmd_{side}", t0, delay)[0] - segment.data[f"leg_rate_{side}"][0])
        return (duty - g["ff"] - g["kp"] * e - g["kd"] * dv) / g["ki"]

    def initial_uncertainty(self, model, segment: Segment, setting: Setting) -> list[tuple[str, int, float]]:
        """The integrators: read off a duty quantised to 1/3900 and measured a tick apart from the angles."""
        out = []
        for side in SIDES:
            g = self._gains(segment, side)
            if g["ki"] > 0:
                sd = self._gear * max(segment.sigma.get(f"duty_{side}", 1e-3), 1e-3) / g["ki"]
                out.append(("act", int(model.actuator_actadr[self._motor[side]]), sd))
        return out

    def controls(self, model, segment: Segment, setting: Setting) -> np.ndarray:
        t = self.physics_times(segment)
        delay = setting.get("delay.seconds", 0.0)
        battery = self._battery(segment, setting)
        ctrl = np.zeros((len(t), model.nu))
        for side in SIDES:
            a = self._motor[side]
            g = firmware_gains(self._gains(segment, side), battery, model.actuator_gainprm[a, GAIN_R],
                               model.actuator_gainprm[a, GAIN_K], self._gear)  # fmt: skip
            adr = model.actuator_ctrladr[a]
            ctrl[:, adr] = self._gear * segment.command_at(f"leg_angle_cmd_{side}", t, delay)
            rate = segment.command_at(f"leg_rate_cmd_{side}", t, delay)
            ctrl[:, adr + 1] = g["vel_per_cmd"] * rate + g["vel_offset"]
        if setting.get("disturbance.torque", 0.0) > 0:
            f = setting.get("disturbance.frequency", 3.0)
            ctrl[:, model.actuator("disturbance").id] = setting["disturbance.torque"] * np.sin(
                2 * math.pi * f * (segment.t0 + t)
            )
        return ctrl

    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        gains = self._nominal_gains
        battery = self._battery(segment, setting)
        columns = [sensordata[:, self._sensors[constants.SENSOR_LEG_POS[s]]] for s in SIDES]
        duty = {}
        for side in SIDES:
            a = self._motor[side]
            r = gains[a, GAIN_R] / setting.get(f"gearbox_efficiency_{side}.efficiency", 1.0)
            k = gains[a, GAIN_K] * setting.get(f"torque_constant_{side}.scale", 1.0)
            torque = sensordata[:, self._sensors[constants.SENSOR_MOTOR_TORQUE[side]]]
            speed = sensordata[:, self._sensors[constants.SENSOR_MOTOR_VEL[side]]]
            duty[side] = (r * torque / k + k * speed) / battery
            columns.append(duty[side])
        for side in SIDES:  # the back-EMF the board reads between PWM pulses: K x motor speed at the reading's scale,
            a = self._motor[side]  # its offset, the duty's coupling
            k = gains[a, GAIN_K] * setting.get(f"torque_constant_{side}.scale", 1.0)
            k = k * setting.get(f"sensor_gain_bemf_{side}.scale", 1.0)
            speed = sensordata[:, self._sensors[constants.SENSOR_MOTOR_VEL[side]]]
            reading = (k * speed + setting.get(f"sensor_bias_bemf_{side}.offset", 0.0)
                       + setting.get(f"sensor_coupling_bemf_{side}.per_unit", 0.0) * duty[side])  # fmt: skip
            running = setting.get(f"sensor_running_offset_bemf_{side}.offset", 0.0)
            if running:  # while the firmware's clock runs (its commanded rate not zero) the drive switches
                reading = reading + running * (segment.data[f"leg_rate_cmd_{side}"] != 0.0)
            columns.append(reading)
        return np.column_stack(columns)

    def nuisance(self, logs: Sequence[Log]) -> dict[str, Param]:
        return {}

    # --- channels that cannot be time-aligned -----------------------------------------------------------------------
    BODY_RATES = ("gyro_x", "gyro_y", "gyro_z")
    optional = BODY_RATES  # the IMU's rates, where logged
    BANDS = ((0.5, 5.0), (5.0, 20.0), (20.0, 100.0))  # Hz: body sway, stride, vibration

    def report_extra(self, result) -> dict:
        """Two views of the held-out logs simulated without a break (the log's commands through the logged firmware,
        nothing re-measured) under the nominal and the calibrated model:

        - **tracking**, the quantities of the tracking table: the leg's tracking error (median and 95th percentile,
          deg), the mean |duty|, the share of the time the duty is held at its clip (%), and the back-EMF per leg
          speed (the reading's least-squares ratio to the leg's
          rate, mV s/rad), the shares of the tracking error that repeat every stride and that last strides
          (:func:`~sysid.adapters.velociroach_measure.tracking_parts`) and how the repeating part's pattern over a
          stride correlates with the log's, per side, over the commanded stretch from its first second on;
        - **body rates compared as distributions**: the body's pose is not logged, so its rates cannot be aligned
          in time with the model's; the gyro readings are compared with the log's by spread (standard deviation),
          the share of power in three bands and the Wasserstein distance between the samples (over the log's
          standard deviation). The IMU board's axes are taken as the body's (its mounting is not recorded).

        Neither enters the fit."""
        from scipy.stats import wasserstein_distance

        gyro = slice(self._sensors_gyro, self._sensors_gyro + 3)
        n = len(self.channels)

        def channels_and_rates(sensordata, segment, setting):
            return np.column_stack([self.observe(sensordata, segment, setting), sensordata[:, gyro]])

        tracking: dict[str, dict] = {}
        rates: dict[str, dict] = {}
        for log in result.test:
            t = log.time
            covered = np.zeros(len(t), dtype=bool)  # the rows a replay of the log's segments simulates
            for segment in self.segments(log):
                covered[segment.samples] = True
            window = self._commanded(log) & covered
            # rates from the simulated rows alone: a difference across the first row not simulated would be a jump
            clip = float(log.meta["duty_clip"])
            tracking[log.path], patterns = {}, {}
            tracking[log.path]["log"], patterns["log"] = self._tracking(log.df[covered], t[covered], window[covered],
                                                                        clip)  # fmt: skip
            has_rates = all(c in log.df for c in self.BODY_RATES)
            for name, setting in (("nominal", result.outcome.nominal), ("calibrated", result.outcome.setting)):
                sim = simulate(self, setting, log.df, log.meta, channels_and_rates)
                model = log.df.copy()
                for i, c in enumerate(self.channels):
                    model[c] = sim[:, i]
                tracking[log.path][name], patterns[name] = self._tracking(model[covered], t[covered],
                                                                          window[covered], clip)  # fmt: skip
                if not has_rates:
                    continue
                measured = log.df[list(self.BODY_RATES)].to_numpy(dtype=float)
                for axis, column in enumerate(self.BODY_RATES):
                    key = f"{log.path}:{column}"
                    entry = rates.setdefault(key, {"log": _spread(measured[window, axis], t[window], self.BANDS)})
                    entry[name] = _spread(sim[window, n + axis], t[window], self.BANDS)
                    scale = max(float(np.std(measured[window, axis])), 1e-9)
                    entry[name]["wasserstein"] = float(
                        wasserstein_distance(sim[window, n + axis], measured[window, axis]) / scale
                    )
            _compare_patterns(tracking[log.path], patterns)
        # a run from an earlier calibration compares with that calibration's model: it is the "nominal" setting here
        before = "starting calibration" if result.outcome.started else "nominal model"
        sections = {"Tracking on the held-out logs": _tracking_table(tracking, before)}
        if rates:
            sections["Body rates compared as distributions"] = _rates_table(rates, self.BANDS)
        return {"tracking": tracking, "distributions": rates, "sections": sections}

    def measure_log(self, log: Log, seed: int = 0) -> list:
        """The firmware's gains and loop rate, the duty's sign, the back-EMF per leg speed, the battery and the drive
        balance, read off the log (sysid/adapters/velociroach_measure.py)."""
        from sysid.adapters.velociroach_measure import measure_roach

        return measure_roach(log.df, log.meta, log.path, seed=seed)

    def effect_readings(self, measurements: Sequence) -> list:
        """The back-EMF reading's scale, duty coupling and zero per side, as the catalog's ``sensor_gain_bemf_<side>``
        (the measured back-EMF per leg speed over the model's motor constant x gear), ``sensor_coupling_bemf_<side>``
        (the measured volts per unit duty, the effect's own unit) and ``sensor_bias_bemf_<side>`` (the reading at
        rest in volts; not the running relation's intercept, which a reading that grows with the running moves)."""
        from sysid.measurement import EffectReading

        out = []
        for m in measurements:
            if m.quantity == "bemf_constant" and m.nominal:
                out.append(EffectReading(m.log, f"sensor_gain_bemf_{m.side}", "scale", m.value / m.nominal,
                                         m.low / m.nominal, m.high / m.nominal, 1.0, m.quantity))  # fmt: skip
            elif m.quantity in READ_AS_IS:
                effect, param = READ_AS_IS[m.quantity]
                out.append(EffectReading(m.log, f"{effect}_bemf_{m.side}", param, m.value, m.low, m.high, 0.0,
                                         m.quantity))  # fmt: skip
        return out

    def _commanded(self, log: Log) -> np.ndarray:
        """The samples from one second after the legs were first commanded to move to the last commanded move; in a
        run shorter than two seconds, its second half."""
        t = log.time
        moving = np.zeros(len(t), dtype=bool)
        for side in SIDES:
            moving |= np.abs(np.gradient(log.df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float), t)) > 1e-6
        if not moving.any():
            return np.ones(len(t), dtype=bool)
        first, last = t[np.flatnonzero(moving)[[0, -1]]]
        return (t >= first + min(1.0, 0.5 * (last - first))) & (t <= last)

    def _tracking(self, df, t: np.ndarray, window: np.ndarray, clip: float) -> tuple[dict[str, float], dict]:
        """The tracking table's quantities, and per side the pattern of the error's repeating part (or None)."""
        out, patterns = {}, {}
        for side in SIDES:
            duty = np.abs(df[f"duty_{side}"].to_numpy(dtype=float))[window]
            # the firmware's output held at its clip (MAXTHROT): a leg the drive cannot keep on its clock
            out[f"duty_at_clip_{side}"] = 100.0 * float(np.mean(duty >= CLIPPED * clip)) if len(duty) else float("nan")
            angle = df[f"leg_angle_{side}"].to_numpy(dtype=float)
            error = np.degrees(np.abs(df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float) - angle))[window]
            rate = np.gradient(angle, t)[window]
            bemf = df[f"bemf_{side}"].to_numpy(dtype=float)[window]
            # through the origin, as a back-EMF constant is: a slope with an intercept is lost where the legs run
            # at one steady rate (a 5 Hz clock tracked closely)
            slope = float(np.dot(rate, bemf) / np.dot(rate, rate)) if np.any(rate) else float("nan")
            out.update({f"error_median_{side}": float(np.median(error)), f"error_p95_{side}": float(np.percentile(
                error, 95)), f"duty_mean_abs_{side}": float(np.mean(duty)),
                f"bemf_per_speed_{side}": 1e3 * slope})  # fmt: skip
            # how the error splits: what repeats every stride, and what lasts strides
            clock = df[f"leg_angle_cmd_{side}"].to_numpy(dtype=float)
            parts = tracking_parts(t[window], (clock - angle)[window], clock[window]) if window.sum() > 2 else None
            out[f"error_stride_{side}"] = parts["stride"] if parts else float("nan")
            out[f"error_slow_{side}"] = parts["slow"] if parts else float("nan")
            patterns[side] = parts["pattern"] if parts else None
        return out, patterns

    # --- synthetic logs ---------------------------------------------------------------------------------------------
    SYNTH_GAINS = (1800, 100, 200, 0, 200)  # the 2 Hz real log's, per side
    SYNTH_CLIP = 3800 / PWM_PERIOD
    SYNTH_MAX_HZ = 12.0

    def synth_meta(self) -> dict:
        return {"motor_gains": [*self.SYNTH_GAINS, *self.SYNTH_GAINS], "duty_clip": self.SYNTH_CLIP,
                "duty_full_scale_counts": PWM_PERIOD}  # fmt: skip

    def excite(self, seconds: float, rng: np.random.Generator):
        """The firmware's leg clocks at 1 kHz (a few samples dropped, as the real board drops them): the stride
        frequency redrawn in 0.5 to 12 Hz every 0.5 to 2 s, a pause now and then, the right side half a cycle
        behind the left with a wandering offset (turning); the battery sagging slowly from 3.8 V."""
        import pandas as pd

        t = np.arange(0.0, seconds, 1e-3)
        keep = rng.random(len(t)) > 0.02
        keep[0] = True
        t = t[keep]
        freq = np.zeros_like(t)
        offset = np.zeros_like(t)
        start = 0.0
        while start < seconds:
            hold = rng.uniform(0.5, 2.0)
            here = (t >= start) & (t < start + hold)
            freq[here] = 0.0 if rng.random() < 0.15 else rng.uniform(0.5, self.SYNTH_MAX_HZ)
            offset[here] = rng.uniform(-0.6, 0.6)
            start += hold
        phase = 2 * np.pi * np.concatenate([[0.0], np.cumsum(freq[:-1] * np.diff(t))])
        smooth = np.convolve(offset, np.ones(200) / 200, mode="same")
        left = phase
        right = phase - np.pi - smooth
        battery = 3.8 - 0.2 * t / max(seconds, 1e-9) + rng.normal(0.0, 0.005, len(t))
        return pd.DataFrame({"time": t, "leg_angle_cmd_left": left, "leg_angle_cmd_right": right, "vbatt": battery,
                             "leg_angle_left": left, "leg_angle_right": right, "duty_left": 0.0, "duty_right": 0.0,
                             "bemf_left": 0.0, "bemf_right": 0.0})  # fmt: skip

    def synth_noise(self) -> dict[str, float]:
        # the encoders' count (9.6e-5 rad) and vibration; the duty's PWM count; the back-EMF ADC's 10 mV and ripple
        return {"leg_angle_left": 2e-4, "leg_angle_right": 2e-4, "duty_left": 0.01, "duty_right": 0.01,
                "bemf_left": 0.03, "bemf_right": 0.03}  # fmt: skip

    def measure(self, channel: str, values: np.ndarray) -> np.ndarray:
        if channel.startswith("leg_angle"):
            return np.round(values * COUNTS_PER_RAD) / COUNTS_PER_RAD
        if channel.startswith("duty"):
            return np.round(values * PWM_PERIOD) / PWM_PERIOD
        return values


READ_AS_IS = {"bemf_duty": ("sensor_coupling", "per_unit"), "bemf_at_rest": ("sensor_bias", "offset")}
"""The roach's measurements that are a back-EMF reading effect's parameter of their side in its own unit:
quantity -> (effect, parameter) (:meth:`RoachAdapter.effect_readings`)."""


def _spread(x: np.ndarray, t: np.ndarray, bands) -> dict:
    """A signal's standard deviation and the share of its power in each band (periodogram on its median step)."""
    from scipy.signal import periodogram

    x = np.asarray(x, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1e-3
    f, power = periodogram(x - x.mean(), fs=1.0 / dt)
    total = float(power[f >= bands[0][0]].sum()) or 1.0
    return {"std": float(np.std(x)), "bands": [float(power[(f >= lo) & (f < hi)].sum() / total) for lo, hi in bands]}


def _compare_patterns(entry: dict[str, dict], patterns: Mapping[str, Mapping[str, np.ndarray | None]]) -> None:
    """Each model's stride pattern of the tracking error (what repeats every stride, over the log's clock angle)
    against the log's: their correlation per side, into ``entry`` (the log's own 1)."""
    for side in SIDES:
        ours = patterns["log"][side]
        entry["log"][f"error_pattern_{side}"] = 1.0 if ours is not None else float("nan")
        for name in ("nominal", "calibrated"):
            theirs = patterns[name][side]
            usable = ours is not None and theirs is not None and np.std(ours) > 0 and np.std(theirs) > 0
            entry[name][f"error_pattern_{side}"] = float(np.corrcoef(ours, theirs)[0, 1]) if usable else float("nan")


def _tracking_table(tracking: Mapping[str, Mapping[str, Mapping[str, float]]], before: str = "nominal model") -> str:
    rows = [("leg tracking error, median (deg)", "error_median", ".1f"),
            ("leg tracking error, 95th percentile (deg)", "error_p95", ".0f"),
            ("mean \\|duty\\|", "duty_mean_abs", ".2f"),
            ("time at the duty's clip (%)", "duty_at_clip", ".0f"),
            ("back-EMF per leg speed (mV s/rad)", "bemf_per_speed", ".0f"),
            ("tracking error repeating every stride (% of its variance)", "error_stride", ".0f"),
            ("tracking error lasting strides (% of its variance)", "error_slow", ".0f"),
            ("the repeating part's pattern, correlation with the log's", "error_pattern", "+.2f")]  # fmt: skip
    out = []
    for path, entry in tracking.items():
        out.append(f"{path} (left \\| right):\n\n| | log | {before} | calibrated model |\n|---|---|---|---|")
        blank = []
        for label, key, fmt in rows:
            cells = [f"{_cell(entry[s][f'{key}_left'], fmt)} \\| {_cell(entry[s][f'{key}_right'], fmt)}"
                     for s in ("log", "nominal", "calibrated")]  # fmt: skip
            out.append(f"| {label} | " + " | ".join(cells) + " |")
            if not all(math.isfinite(entry[s][f"{key}_{side}"]) for s in ("log", "nominal", "calibrated")
                       for side in SIDES):  # fmt: skip
                blank.append(label)
        if blank:
            out.append(f"\n- : not measured on this log's compared rows ({'; '.join(blank)}). How the tracking "
                       f"error splits needs {MIN_STRIDES} strides of the clock running in the rows compared (from "
                       "a second, or half the commanded time if shorter, after the commands start); a pattern's "
                       "correlation needs both patterns.")  # fmt: skip
        out.append("")
    return "\n".join(out) + "\n"


def _rates_table(rates: Mapping[str, Mapping[str, Mapping]], bands) -> str:
    """Per held-out log, each body rate's spread and band powers under the log and both models."""
    by_log: dict[str, list[str]] = {}
    for key, entry in rates.items():
        path, rate = key.rsplit(":", 1)
        for name in ("log", "nominal", "calibrated"):
            e = entry[name]
            by_log.setdefault(path, []).append(
                f"| {rate} | {name} | {e['std']:.3g} | " + " | ".join(f"{x:.0%}" for x in e["bands"])
                + f" | {_cell(e.get('wasserstein', float('nan')), '.2f')} |"
            )  # fmt: skip
    header = " | ".join(f"{lo:g}-{hi:g} Hz" for lo, hi in bands)
    head = f"| rate | source | std (rad/s) | {header} | Wasserstein / log std |\n" + "|---" * (4 + len(bands)) + "|\n"
    tables = [f"{path} (body rates):\n\n{head}" + "\n".join(rows) + "\n" for path, rows in by_log.items()]
    return (
        "Body rates cannot be aligned in time with the log (the body's pose is not logged): the held-out logs "
        "are simulated without a break under each model and the distributions compared.\n\n" + "\n".join(tables)
    )


def _cell(value: float, fmt: str) -> str:
    """A table cell, "-" where there is no number (a quantity the rows cannot give; the log against itself)."""
    return format(value, fmt) if math.isfinite(value) else "-"


ADAPTERS = {"roach": RoachAdapter}
