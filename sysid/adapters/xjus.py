"""Calibration of the xJüs against its telemetry (``calibrate.py --robot xjus``), and the calibrated model
(``gym.make("skitter/XjusWalk-v1", calibration=PATH)``).

**Replay.** An xJüs log holds the duty ``d`` of each leg's motor (the report's simulation input, and what the PD of gait
mode puts out), the battery voltage, and per leg the hip angle, its speed and the motor current; in gait mode also
the Buehler clock (its phase, period and sweep angles). Where the log holds the clock, the replay runs the robot's
own controller ([xjus-report, sections 2.4-2.5]; envs/xjus/controller.py) once per control step, as the robot does: the
clock's target, the PD with the firmware's gains and the inverse of the *nominal* motor model (what the firmware
knows), computed for every rollout at once between native chunks of physics (``Adapter.feedback``). Replaying the
PD's logged duty open loop instead would let a stalled leg stay stalled where the PD pushed it over, and the replay
diverges by whole turns. Where the log has no clock (duty mode), the logged duty is replayed held between samples.
Either way the duty acts through the report's motor formula (envs/actuators/motor.py) at every physics step,
natively, through ``ctrl``, with the setting's motor constants. A row of the robot's telemetry holds the duty (and
the clock's period and sweeps) of the control step that *ended* at its time (``envs/common/env.py`` records after
stepping), and the clock's phase at its time, so the replay takes a step's commands from the row after its start.
Multiple shooting over one-second segments: each starts from the measured hip angles and speeds; the body (its
pose and motion, the spine) is not logged and is carried over from the previous segment, as the VelociRoACH's is
(sysid/adapters/velociroach.py), with the same replay floor and derivative-free fits (contacts make the cost
rough).

**Channels** compared: per leg the hip angle, hip speed and motor current (``current = torque / (eta N Kt)``).

**Effects** (envs/xjus/effects.py): delay of the duty; per side (three legs each) Coulomb and viscous friction and rotor
inertia at the hips; backlash between each motor and its leg (a hinge of limited play, a structural spec edit); the
driver's deadband; the motors' torque constant (an ideal motor's: Kt and Ks together), back-EMF constant, supply (a
scale on the logged battery voltage) and supply sag (the battery's resistance, in the formula's ``d^2`` term); foot
friction and ground contact (the legs' contact parameters, which take priority over the ground's); leg and spine
stiffness; body mass and centre of mass; the current sensors' gain and each side's angle offset. The motor constants
apply to all six motors (one set of numerics), the friction and inertia per side.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np
import pandas as pd

from envs.common import edits
from envs.common.effects import Effect
from envs.xjus import constants
from envs.xjus.effects import LEGS_OF, add_backlash, effects_edit, xjus_effects
from sysid.logs import Log, LogError
from sysid.problem import Adapter, Segment, Setting

SIDES = constants.SIDES


def add_bump(height: float):
    """Spec edit (synthetic data only): bumps across the robot's path every 0.6 m (a body length and its legs'
    reach), nine each way from the start: the synthetic excitation walks it 3.5 to 5.5 m and up to 1.2 m sideways."""
    return edits.add_bump(height, x=0.6, width=3.0, count=9)


# Spec edit (synthetic data only): a pitching torque on the middle segment from outside the model (a payload
# swinging, a tether): it shifts the stance load between the front and rear legs
add_disturbance = edits.add_site_disturbance("imu", axis=1)


class XjusAdapter(Adapter):
    """The xJüs replayed from its logged duty through the report's motor formula."""

    name = "xjus"
    channels = {  # noqa: RUF012
        **{f"leg_angle_{leg}": "rad" for leg in constants.LEGS},
        **{f"leg_speed_{leg}": "rad/s" for leg in constants.LEGS},
        **{f"current_{leg}": "A" for leg in constants.LEGS},
    }
    commands = (*(f"duty_{leg}" for leg in constants.LEGS), "vbatt")
    segment_seconds = 1.0
    # each leg's channels against that leg's speed, duty, current and angle (cos > 0: the leg points down, stance)
    context = {
        key: {f"{channel}_{leg}": f"{column}_{leg}" for leg in constants.LEGS for channel in ("leg_angle", "leg_speed",
                                                                                       "current")}
        for key, column in (("velocity", "leg_speed"), ("command", "duty"), ("load", "current"),
                            ("phase", "leg_angle"))
    } | {"supply": "vbatt"}  # fmt: skip
    replay_floor = True  # the body's state is not logged and its contacts make replay sensitive to it
    burn_in = True  # a log's first segment guesses the body's state: replayed, carried over, not counted
    fd_step = 0.02
    rough_cost = True
    # a heavy hexapod's leg can stall in one replay and run on in the other, and the carried body can stumble where
    # the log's robot did not: such a segment's error dwarfs the rest, even the true model's. Each segment's residual
    # variance is its own (sysid/problem.py, Residual.objective; docs/calibration.md, "5. Fitting")
    segment_variance = True
    # even the true model's replay of the carried body parts from the log within seconds, so a synthetic case is six
    # runs of 2 s, each from rest, scoring the one segment after each burn-in (docs/calibration.md, "Settings per
    # robot")
    runs = (6, 2.0)
    chain_search = (1, 2, 1)
    # the cost's basins (the replay carries a body the log does not hold) are narrower than a three-point grid's
    # spacing: nine points put one in the basin (docs/calibration.md, "Settings per robot")
    score_grid = 9
    # the robot's telemetry (envs/common/env.py) stamps a row with the time after its control step and reads the
    # sensors MuJoCo computed at the start of the step's last physics step: a physics step older
    sample_lag = 1

    def acts_on(self, effect: Effect, channel: str) -> bool:
        """A side's effect acts on that side's legs (``left``: ``leg_angle_FL``), a quantity's on its channels
        (``angle_left``: the left legs' angles; ``current``: every leg's current)."""
        leg = channel.rsplit("_", 1)[-1]
        side = next((s for s in LEGS_OF if effect.target == s or effect.target.endswith("_" + s)), None)
        if side is not None and leg not in LEGS_OF[side]:
            return False
        quantity = effect.target.removesuffix(side or "").rstrip("_")
        return not quantity or channel.startswith((quantity + "_", "leg_" + quantity + "_"))

    def __init__(self) -> None:
        super().__init__()
        from envs.xjus.robot import Xjus

        self._robot_class = Xjus
        robot = self.nominal_robot = self._make_robot(())
        m = robot.model
        self._h = float(m.opt.timestep)
        self._constants = robot.constants
        self._stand = robot.stand_height
        self._drive = {
            leg: int(m.actuator_ctrladr[m.actuator(f"{constants.HIP_JOINTS[leg]}_drive").id]) for leg in constants.LEGS
        }
        self._emf = {
            leg: int(m.actuator_ctrladr[m.actuator(f"{constants.HIP_JOINTS[leg]}_emf").id]) for leg in constants.LEGS
        }
        self._sensors = {
            name: int(m.sensor(name).adr[0])
            for leg in constants.LEGS
            for name in (constants.SENSOR_ANGLE[leg], constants.SENSOR_SPEED[leg], constants.SENSOR_TORQUE[leg])
        }
        self._gait = robot.gait
        self._hip_inertia = robot.hip_inertia.copy()  # the controller's plant inertia, from the nominal model
        self.feedback_steps = 0  # set from the logs (segments): the control step, where a log holds the clock

    def _make_robot(self, edits):
        return self._robot_class(action_mode="duty", imu_noise=None, spec_edits=list(edits))

    @property
    def physics_dt(self) -> float:
        return self._h

    def effects(self) -> dict[str, Effect]:
        return xjus_effects(self._h)

    # --- logs -------------------------------------------------------------------------------------------------------
    def check_logs(self, logs: Sequence[Log]) -> None:
        for log in logs:
            vbatt = log.df["vbatt"].to_numpy(dtype=float)
            bad = np.flatnonzero(~(vbatt > 0))
            if len(bad):
                raise LogError(f"{log.path}: row {int(bad[0])}, column 'vbatt': {vbatt[bad[0]]!r} is not a positive "
                               "battery voltage")  # fmt: skip

    CLOCK = ("clock_phase", "period", "sweep_left", "sweep_right")  # gait mode's telemetry of the Buehler clock
    optional = CLOCK

    def segments(self, log: Log) -> list[Segment]:
        """Segments, each with what acts from each sample on: a telemetry row holds the duty, period and sweeps of
        the control step that ended at its time, so what acts from row k on is row k + 1's (the last row's is held);
        the clock's phase is row k's own. With a clock, the controller runs once per sample interval (the control
        step), which every log must share."""
        out = super().segments(log)
        t = log.time
        acting = {f"acting_{leg}": self.acting(log.df[f"duty_{leg}"].to_numpy(dtype=float)) for leg in constants.LEGS}
        clocked = all(c in log.df.columns for c in self.CLOCK) and bool(np.isfinite(log.df["period"]).any())
        if clocked:
            acting["clock_phase"] = log.df["clock_phase"].to_numpy(dtype=float)
            for c in self.CLOCK[1:]:
                acting[f"acting_{c}"] = self.acting(log.df[c].to_numpy(dtype=float))
            steps = max(1, round(float(np.median(np.diff(t))) / self._h))
            if self.feedback_steps and self.feedback_steps != steps:
                raise LogError(
                    f"{log.path}: column 'time': a control step of {steps} physics steps, where the other logs have "
                    f"{self.feedback_steps}: calibrate logs of one control rate together"
                )
            self.feedback_steps = steps
        self.attach(log, out, acting)
        return out

    # --- replay -----------------------------------------------------------------------------------------------------
    def spec_edits(self, setting: Setting) -> list:
        return [effects_edit(setting), *self.structural_edits(setting, add_backlash, add_bump, add_disturbance)]

    def initial_state(self, model, data, segment: Segment, setting: Setting, carried: bool = False) -> None:
        """The measured hip angles and speeds; the body carried over, or standing level at rest on the first
        segment with its hips at the measured angles."""
        hip_qpos, hip_dof, root = self._addresses(model)  # an effect may add joints (backlash): by name
        if not carried:
            data.qpos[:] = model.qpos0
            data.qvel[:] = 0.0
            data.qpos[root : root + 7] = [0.0, 0.0, self._stand, 1.0, 0.0, 0.0, 0.0]
        before = edits.deepest_contact(model, data)
        lag = self.sample_lag * self._h  # the reading is this much older than its row: carried forward by its speed
        for side in SIDES:
            offset = setting.get(f"sensor_bias_angle_{side}.offset", 0.0)
            for leg in LEGS_OF[side]:
                speed = float(segment.data[f"leg_speed_{leg}"][0])
                data.qpos[hip_qpos[leg]] = float(segment.data[f"leg_angle_{leg}"][0]) - offset + speed * lag
                data.qvel[hip_dof[leg]] = speed
        # a leg turned to its measured angle must not start inside the ground (the carried body need not match
        # the log): the body is lifted by however much deeper than before any contact now reaches
        after = edits.deepest_contact(model, data)
        if after < min(before, 0.0):
            data.qpos[root + 2] += min(before, 0.0) - after

    def _addresses(self, model: mujoco.MjModel) -> tuple[dict[str, int], dict[str, int], int]:
        """The hips' qpos and dof addresses and the root's qpos address in ``model``."""
        hips = {leg: model.joint(constants.HIP_JOINTS[leg]) for leg in constants.LEGS}
        return ({leg: int(j.qposadr[0]) for leg, j in hips.items()}, {leg: int(j.dofadr[0]) for leg, j in hips.items()},
                int(model.joint(constants.ROOT_JOINT).qposadr[0]))  # fmt: skip

    def _motor(self, setting: Setting) -> dict[str, float]:
        c = self._constants
        k = setting.get("torque_constant.scale", 1.0)
        return {"tpa": c.torque_per_amp * k, "ks": c.speed_constant * k * setting.get("back_emf_constant.scale", 1.0),
                "ra": c.motor_resistance, "ramp": c.amplifier_resistance + setting.get("supply_sag.resistance", 0.0),
                "supply": setting.get("supply_voltage.scale", 1.0)}  # fmt: skip

    def controls(self, model, segment: Segment, setting: Setting) -> np.ndarray:
        t = self.physics_times(segment)
        delay = setting.get("delay.seconds", 0.0)
        mo = self._motor(setting)
        vs = segment.command_at("vbatt", t, delay) * mo["supply"]
        band = setting.get("deadband.duty", 0.0)
        ctrl = np.zeros((len(t), model.nu))
        for leg in constants.LEGS:
            d = np.clip(segment.command_at(f"acting_{leg}", t, delay), -1.0, 1.0)
            if band > 0:
                d = np.sign(d) * np.maximum(np.abs(d) - band, 0.0)
            r = mo["ra"] + d * d * mo["ramp"]
            ctrl[:, self._drive[leg]] = mo["tpa"] * d * vs / r
            ctrl[:, self._emf[leg]] = mo["tpa"] * mo["ks"] / r
        if setting.get("disturbance.torque", 0.0) > 0:
            f = setting.get("disturbance.frequency", 3.0)
            ctrl[:, model.actuator("disturbance").id] = setting["disturbance.torque"] * np.sin(
                2 * math.pi * f * (segment.t0 + t)
            )
        return ctrl

    def feedback(self, ctrl: np.ndarray, sensordata: np.ndarray, rows, step: int) -> None:
        """The robot's controller at a control step, for every row at once: the logged clock's targets, the PD with
        the firmware's gains on the simulated hip angles and speeds, the duty from the nominal motor model inverted
        (what the firmware knows), the driver's deadband, then the setting's motor formula; a delay shifts the
        duty by whole physics steps (before the segment: the logged duty, already in ``ctrl``). Where the clock does
        not run (a pause, a duty-mode log) the logged duty is what the driver is told."""
        from envs.xjus.controller import pd_torque, wrap_angle

        k = self.feedback_steps
        u = step // k
        if step == 0:
            self._batch = self._feedback_batch(rows, k)
        b = self._batch
        clock = b["clock"][:, u]
        live = np.isfinite(clock).all(axis=1)
        history = b["history"]
        history[:, u] = b["acting"][:, u]
        if live.any():
            angle = sensordata[:, b["angle"]]
            speed = sensordata[:, b["speed"]]
            phase = np.where(live, clock[:, 0], 0.0)
            period = np.where(live, clock[:, 1], 1.0)
            sweep = np.where(live[:, None], clock[:, 2:4], 0.0)
            target, rate, accel = self._gait.targets(phase, period, sweep)
            torque = pd_torque(
                wrap_angle(target - angle), rate - speed, accel, self._hip_inertia, constants.PD_KP, constants.PD_KD
            )
            duty = self._firmware(b["vbatt"][:, u]).duty_for_torque(torque, speed)
            history[live, u] = duty[live]
        source = (step + np.arange(ctrl.shape[1])[None, :] - b["delay"][:, None]) // k  # (rows, steps)
        held = source >= 0
        d = history[np.arange(len(rows))[:, None], np.maximum(source, 0)]  # (rows, steps, legs)
        band = b["band"][:, None, None]
        d = np.where(band > 0, np.sign(d) * np.maximum(np.abs(d) - band, 0.0), d)
        resistance = b["ra"][:, None, None] + d * d * b["ramp"][:, None, None]
        vs = (b["vbatt"][:, u] * b["supply"])[:, None, None]
        drive = b["tpa"][:, None, None] * d * vs / resistance
        emf = np.broadcast_to((b["tpa"] * b["ks"])[:, None, None] / resistance, drive.shape)
        mask = held[:, :, None]
        ctrl[:, :, b["drive"]] = np.where(mask, drive, ctrl[:, :, b["drive"]])
        ctrl[:, :, b["emf"]] = np.where(mask, emf, ctrl[:, :, b["emf"]])

    def _feedback_batch(self, rows, k: int) -> dict:
        """What the controller needs of every row for a whole rollout, gathered once: the logged clock, duty and
        battery at each update, the setting's delay, deadband and motor constants, and the duty history."""
        steps = max(seg.n_steps for _, seg in rows)
        updates = -(-steps // k)
        tau = np.arange(updates) * k * self._h
        tables = []
        for _, seg in rows:
            key = ("xjus feedback", k, updates)
            if key not in seg.cache:
                clock = np.column_stack([seg.command_at(c, tau) if c in seg.data else np.full(updates, np.nan)
                                         for c in ("clock_phase", "acting_period", "acting_sweep_left",
                                                   "acting_sweep_right")])  # fmt: skip
                acting = np.column_stack([seg.command_at(f"acting_{leg}", tau) for leg in constants.LEGS])
                seg.cache[key] = (clock, acting, seg.command_at("vbatt", tau))
            tables.append(seg.cache[key])
        motors = [self._motor(setting) for setting, _ in rows]
        s = self._sensors
        return {
            "clock": np.stack([t[0] for t in tables]),
            "acting": np.stack([t[1] for t in tables]),
            "vbatt": np.stack([t[2] for t in tables]),
            "history": np.zeros((len(rows), updates, len(constants.LEGS))),
            "delay": np.array([round(setting.get("delay.seconds", 0.0) / self._h) for setting, _ in rows]),
            "band": np.array([setting.get("deadband.duty", 0.0) for setting, _ in rows]),
            **{name: np.array([m[name] for m in motors]) for name in ("tpa", "ks", "ra", "ramp", "supply")},
            "angle": [s[constants.SENSOR_ANGLE[leg]] for leg in constants.LEGS],
            "speed": [s[constants.SENSOR_SPEED[leg]] for leg in constants.LEGS],
            "drive": [self._drive[leg] for leg in constants.LEGS],
            "emf": [self._emf[leg] for leg in constants.LEGS],
        }

    def _firmware(self, vbatt: np.ndarray):
        """The firmware's motor model (Table 1, nominal) at the logged battery voltage, per row."""
        from envs.xjus.controller import MotorArrays

        c = self._constants
        n = len(vbatt)
        return MotorArrays(vbatt, np.full(n, c.motor_resistance), np.full(n, c.amplifier_resistance),
                           np.full(n, c.torque_per_amp), np.full(n, c.speed_constant))  # fmt: skip

    def observe(self, sensordata: np.ndarray, segment: Segment, setting: Setting) -> np.ndarray:
        mo = self._motor(setting)
        gain = setting.get("sensor_gain_current.scale", 1.0)
        s = self._sensors
        angles, speeds, currents = [], [], []
        for leg in constants.LEGS:
            side = "left" if leg in constants.LEFT_LEGS else "right"
            angles.append(
                sensordata[:, s[constants.SENSOR_ANGLE[leg]]] + setting.get(f"sensor_bias_angle_{side}.offset", 0.0)
            )
            speeds.append(sensordata[:, s[constants.SENSOR_SPEED[leg]]])
            currents.append(gain * sensordata[:, s[constants.SENSOR_TORQUE[leg]]] / mo["tpa"])
        return np.column_stack([*angles, *speeds, *currents])

    # --- synthetic logs ---------------------------------------------------------------------------------------------
    def excite(self, seconds: float, rng: np.random.Generator) -> pd.DataFrame:
        """The robot's own Buehler clock and PD on the nominal model, its period redrawn in 0.5 to 1.5 s and its
        sweep per side in 40 to 80 deg every 1 to 3 s (turning when they differ), with a pause (all duties zero)
        now and then: the duty it puts out at every 8 ms control step, as telemetry records it, and the battery
        sagging slowly from 23.5 V."""
        from envs.xjus.robot import GAIT

        robot = self._robot_class(action_mode=GAIT, imu_noise=None)
        robot.reset(np.arange(1), [rng], 0.0)
        start_angles = robot.leg_angles()[0].copy()
        dt = robot.control_dt
        steps = round(seconds / dt)
        rows = np.zeros((steps + 1, len(constants.LEGS)))
        start = 0.0
        plan: list[tuple[float, float, float, float, bool]] = []
        while start < seconds:
            hold = rng.uniform(1.0, 3.0)
            pause = rng.random() < 0.15
            plan.append((start, rng.uniform(0.5, 1.5), *np.radians(rng.uniform(40.0, 80.0, 2)), pause))
            start += hold
        clock = np.full((steps + 1, 4), np.nan)  # phase, period, sweeps, as telemetry records them
        clock[0, 0] = robot.phase[0]
        k_plan = 0
        for k in range(steps):
            time = k * dt
            while k_plan + 1 < len(plan) and plan[k_plan + 1][0] <= time:
                k_plan += 1
            _, period, left, right, pause = plan[k_plan]
            if pause:  # the driver told nothing: the legs go limp, the clock stands still and is not logged
                robot.hold_duty(np.zeros((1, len(constants.LEGS))))
            else:
                robot.command(np.array([[period, left, right]]))
                clock[k + 1] = [robot.phase[0], period, left, right]
            robot.step()
            rows[k + 1] = robot.last_duty[0]
            if pause:
                clock[k + 1, 0] = robot.phase[0]
        t = np.arange(steps + 1) * dt
        battery = 23.5 - 0.5 * t / max(seconds, 1e-9) + rng.normal(0.0, 0.02, len(t))
        table = {"time": t, **{f"duty_{leg}": rows[:, i] for i, leg in enumerate(constants.LEGS)}, "vbatt": battery,
                 **dict(zip(self.CLOCK, clock.T, strict=True))}  # fmt: skip
        for channel in self.channels:
            table[channel] = 0.0
        for i, leg in enumerate(constants.LEGS):  # the start the replay begins from: the robot's reset pose
            table[f"leg_angle_{leg}"] = float(start_angles[i])
        return pd.DataFrame(table)

    def synth_noise(self) -> dict[str, float]:
        # the hip encoders (a 500-count encoder behind the gearbox: 1e-3 rad), a speed from its differences, the
        # EPOS2's current reading (20 mA)
        return {
            **{f"leg_angle_{leg}": 1e-3 for leg in constants.LEGS},
            **{f"leg_speed_{leg}": 0.05 for leg in constants.LEGS},
            **{f"current_{leg}": 0.02 for leg in constants.LEGS},
        }


ADAPTERS = {"xjus": XjusAdapter}
