"""The VelociRoACH robot: model, motors, firmware, IMU and telemetry, on the robot contract; it knows no task."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

from envs.actuators.battery import loaded_voltage
from envs.actuators.dcmotor import GAIN_K, GAIN_KD, GAIN_KP, GAIN_R, SUPPLY_SLOTS, DCMotors, PIDGains
from envs.common.calibration import Calibration
from envs.common.effects import Effect
from envs.common.imu import Imu, ImuNoise
from envs.common.parameters import FieldRef, Parameter, ParameterMap, SpecEdit
from envs.common.robot import ActionMode, Facts, PlotGroup, Robot, check_number, standing_band
from envs.common.telemetry import ChannelLimit
from envs.velociroach import constants, firmware
from envs.velociroach.effects import delay_edit, effects_edit, roach_effects

GAIT, DUTY = "gait", "duty"
_FIRMWARE = firmware.duty_gains(constants.FIRMWARE_GAINS)
FIRMWARE_PID = PIDGains(
    kp=_FIRMWARE["kp"], ki=_FIRMWARE["ki"], kd=_FIRMWARE["kd"], feedforward=_FIRMWARE["ff"],
    integral_limit=constants.PID_INTEGRAL_LIMIT, compensate_back_emf=False,
)  # fmt: skip


def wrap_angle(x: np.ndarray | float) -> np.ndarray | float:
    """Wrap to [-pi, pi]."""
    return np.arctan2(np.sin(x), np.cos(x))


def set_crank(
    q: np.ndarray, q0: np.ndarray, crank: int, tied: Sequence[tuple[int, float, float]], theta: float
) -> None:
    """Put a crank (its qpos address) at ``theta`` in ``q`` and the joints ``tied`` to it, (address, c0, c1), where
    their equalities hold them: q - q0 = c0 + c1 (crank - crank0), with the model's ``q0`` (a leg phase moves the
    crank's)."""
    q[crank] = theta
    for adr, c0, c1 in tied:
        q[adr] = q0[adr] + c0 + c1 * (theta - q0[crank])


def linkage(model: mujoco.MjModel, crank: int) -> list[tuple[int, float, float]]:
    """Every joint a model's equalities tie to a crank (its qpos address), (address, c0, c1) with q = q0 + c0 + c1
    (crank - crank0): the linkage's, and a calibration's springs geared to the crank."""
    joint = int(np.flatnonzero(model.jnt_qposadr == crank)[0])
    return [(int(model.jnt_qposadr[model.eq_obj1id[e]]), float(model.eq_data[e, 0]), float(model.eq_data[e, 1]))
            for e in range(model.neq)
            if model.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and model.eq_obj2id[e] == joint]  # fmt: skip


def _telemetry_channels() -> dict[str, str]:
    cols = {"time": "s"}
    channels = (("leg_angle_cmd", "rad"), ("leg_angle", "rad"), ("duty", "1"), ("torque", "N m"), ("bemf", "V"))
    for channel, unit in channels:
        cols.update({f"{channel}_{side}": unit for side in constants.SIDES})
    cols["vbatt"] = "V"
    cols.update({f"gyro_{a}": "rad/s" for a in "xyz"})
    cols.update({f"accel_{a}": "m/s^2" for a in "xyz"})
    cols.update({f"pos_{a}": "m" for a in "xyz"})
    cols.update({f"quat_{a}": "1" for a in "wxyz"})
    cols.update({f"grf_{leg}_{a}": "N" for leg in constants.LEGS for a in "xyz"})
    cols["power"] = "W"
    return cols


TELEMETRY_COLUMNS: dict[str, str] = _telemetry_channels()  # name -> unit, in table order
FULL_CELL_VOLTAGE = 4.2  # V: a fully charged lithium-polymer cell, the top of the robot's one-cell battery
LOG_SPEED_MARGIN = 2.0  # a log's legs turn at most this many times the model's no-load leg speed


class VelociRoach(Robot):
    """A VelociRoACH in a MuJoCo scene: two DC motors driving six C-legs through a crank linkage, and its firmware.

    Two action modes:

    - ``gait`` (50 Hz): the firmware runs a leg clock per side at a commanded stride frequency (0 to 45 Hz, the real
      robot's range), the right clock trailing the left by a commanded phase, which the firmware moves at most
      ``PHASE_SLEW``; a PID per side tracks its clock. The PID is the firmware's voltage-mode law (a PWM duty from
      P, I, D on the clock's angle and rate; no back-EMF compensation; clipped to the battery voltage) on MuJoCo's
      dcmotor controller, evaluated at every physics step; the clock is its setpoint, given for every physics step
      of the control block. No Python runs per physics step; between control steps the controller's torque-space
      gains follow the battery's voltage (the model's only writes during an episode).
    - ``duty`` (1 kHz): the PWM duty cycle per side in [-1, 1]; the motor sees duty x battery voltage.

    The battery is a cell with an internal resistance (the MJCF's ``battery_resistance``, measured on the real logs):
    over each control step it holds the voltage it sags to under the power the motors drew over the step before
    (:func:`envs.actuators.battery.loaded_voltage`), which the ``battery`` sense reads, as the real board's does, and
    which the firmware's duty multiplies: in duty mode through ``ctrl`` (duty x voltage), in gait mode through the
    controller's torque-space gains and output bound, written for each control step (:meth:`block_gains` says what
    a replay writes).

    Args:
        action_mode: ``"gait"`` or ``"duty"``.
        control_freq: control steps per second (default 50 in gait mode, 1000 in duty mode).
        battery_voltage: the battery's open-circuit voltage, V (default the model's nominal 3.7 V).
        battery_resistance: the battery's internal resistance, ohm (default the model's, 0.2 ohm; 0: an ideal
            source).
        calibration: a calibration file from ``calibrate.py --robot roach`` (docs/calibration.md): its friction,
            rotor inertia, motor constant, delay, supply scale (on the battery voltage), foot friction, ground
            contact, leg stiffness, mass and centre-of-mass effects are added to the nominal model; its sensor
            effects (back-EMF offsets) describe the log's instruments and leave the env's senses alone.
        imu_noise: the IMU's error model (default the MPU-6000's); None for a perfect IMU.
        spec_edits: functions applied to the spec before it compiles.
        num_sims, nthread, batched: simulations stepped together, on how many threads (see ``Robot``).
    """

    name = "velociroach"
    root_body = constants.ROOT_BODY
    feet = constants.FEET
    height_band = standing_band(constants.STANDING_HEIGHT, constants.BELLY_CLEARANCE)
    action_modes: ClassVar[dict[str, ActionMode]] = {
        GAIT: ActionMode(
            GAIT,
            ("freq_left", "freq_right", "phase"),
            ("Hz", "Hz", "rad"),
            (0.0, 0.0, 0.0),
            (constants.MAX_COMMAND_FREQUENCY, constants.MAX_COMMAND_FREQUENCY, 2 * np.pi),
            50.0,
            "stride frequency per side and how far the right clock trails the left (pi: alternating tripod)",
        ),
        DUTY: ActionMode(DUTY, ("duty_left", "duty_right"), ("1", "1"), (-1.0, -1.0), (1.0, 1.0), 1000.0, "PWM duty"),
    }

    def __init__(
        self,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        battery_voltage: float | None = None,
        battery_resistance: float | None = None,
        imu_noise: ImuNoise | None = ImuNoise(),  # noqa: B008 (frozen dataclass)
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
        calibration: str | Path | Calibration | None = None,
    ):
        self._battery_arg = (
            None if battery_voltage is None else check_number("battery_voltage", battery_voltage, 0, strict=True)
        )
        self._resistance_arg = (
            None if battery_resistance is None else check_number("battery_resistance", battery_resistance, 0)
        )
        self.imu_noise = imu_noise
        super().__init__(action_mode, control_freq, spec_edits, num_sims, nthread, batched, calibration)

    @classmethod
    def xml_path(cls) -> Path:
        return constants.SCENE_XML

    # --- building -----------------------------------------------------------------------------------------------
    def configure(self, spec: mujoco.MjSpec) -> None:
        nominal = float(spec.numeric(constants.NUMERIC_BATTERY).data[0])
        resistance = float(spec.numeric(constants.NUMERIC_BATTERY_RESISTANCE).data[0])
        self.nominal_battery_resistance = resistance if self._resistance_arg is None else self._resistance_arg
        self.nominal_battery = nominal if self._battery_arg is None else self._battery_arg
        if self.calibration is not None:  # what reaches the motors of the calibrated robot's battery
            self.nominal_battery *= self.calibration.setting.get("supply_voltage.scale", 1.0)
        pid = FIRMWARE_PID if self.action_mode == GAIT else None
        self.motors = DCMotors([constants.MOTORS[s] for s in constants.SIDES], self.nominal_battery, pid)
        self.motors.configure(spec)

    def setup(self) -> None:
        m, n = self.model, self.num_sims
        self.motors.bind(m, n)
        self.gear = float(self.motors.gear[0])
        self._crank_qpos = np.array([m.joint(constants.CRANK_JOINTS[s]).qposadr[0] for s in constants.SIDES])
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, constants.ROOT_JOINT)
        self._root_qvel = int(m.jnt_dofadr[root]) if root >= 0 else None  # a bench clamp removes the free joint
        self.sweep_amplitude = float(m.numeric(constants.NUMERIC_SWEEP).data[0])
        self.lift_amplitude = float(m.numeric(constants.NUMERIC_LIFT).data[0])
        self._linkage = [linkage(m, crank) for crank in self._crank_qpos]

        def idx(*names: str) -> np.ndarray:
            return np.concatenate([np.arange(self.sensors[k].start, self.sensors[k].stop) for k in names])

        self._i_leg_pos = idx(*(constants.SENSOR_LEG_POS[s] for s in constants.SIDES))
        self._i_leg_vel = idx(*(constants.SENSOR_LEG_VEL[s] for s in constants.SIDES))
        self._i_torque = idx(*(constants.SENSOR_MOTOR_TORQUE[s] for s in constants.SIDES))
        self._i_speed = idx(*(constants.SENSOR_MOTOR_VEL[s] for s in constants.SIDES))
        self._i_gyro, self._i_accel = idx(constants.SENSOR_GYRO), idx(constants.SENSOR_ACCEL)
        self._i_pos, self._i_quat = idx(constants.SENSOR_BODY_POS), idx(constants.SENSOR_BODY_QUAT)
        self._i_vel = idx(constants.SENSOR_BODY_VEL)
        self._i_grf = idx(*(constants.SENSOR_GRF[leg] for leg in constants.LEGS))
        # one gather per step: legs 0:2, leg rates 2:4, gyro 4:7, accel 7:10, motor speeds 10:12, position 12:15,
        # quaternion 15:19, body velocity 19:22; and per physics step: torques, speeds, z gyro
        self._i_read = np.concatenate(
            [self._i_leg_pos, self._i_leg_vel, self._i_gyro, self._i_accel, self._i_speed, self._i_pos, self._i_quat,
             self._i_vel]
        )  # fmt: skip
        self._i_motor = np.concatenate([self._i_torque, self._i_speed, self._i_gyro[2:]])
        self._mass = float(m.body_subtreemass[m.body(constants.ROOT_BODY).id])
        # per-simulation firmware state
        self.open_circuit = np.full(n, self.nominal_battery)  # the battery's open-circuit voltage, V
        self.battery_resistance = np.full(n, self.nominal_battery_resistance)  # its internal resistance, ohm
        self.battery = self.open_circuit.copy()  # its voltage over the current control step, V
        self._drawn = np.zeros(n)  # the power the motors drew over the last control step, W
        self.clock = np.zeros((n, 2))  # firmware leg clocks, rad at the leg (gait mode)
        self.phase = np.full(n, constants.STRAIGHT_PHASE)  # firmware's current left/right phase
        self.last_duty = np.zeros((n, 2))  # duty mode: the duty of the last command
        self.imu = Imu(n, self.imu_noise, self.control_dt, float(m.opt.timestep))
        self._senses = np.zeros((n, sum(self.sense_structure.values())))
        self._imu = np.zeros((n, 6))  # the last (noisy) gyro and accelerometer readings
        self._substep_times = (np.arange(1, self.n_substeps + 1) * float(m.opt.timestep))[None, :, None]

    # --- calibration (envs/velociroach/effects.py holds the effects) -------------------------------------------------
    def calibration_effects(self) -> dict[str, Effect]:
        return {name: e for name, e in roach_effects(self.physics_dt()).items() if e.catalogued}

    @classmethod
    def physics_dt(cls) -> float:
        """The scene's physics time step (s)."""
        return float(mujoco.MjSpec.from_file(str(cls.xml_path())).option.timestep)

    def calibration_edits(self, calibration: Calibration) -> Sequence[SpecEdit]:
        setting = calibration.setting

        def firmware(spec: mujoco.MjSpec) -> None:  # its torque-space gains carry the motors' calibrated R and K
            self.motors.configure(spec)

        delay = setting.get("delay.seconds", 0.0)
        return [effects_edit(setting), *([firmware] if self.action_mode == GAIT else []),
                *([delay_edit(delay)] if delay > 0 else [])]  # fmt: skip

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        """The VelociRoACH's physical parameters, each with the model fields it sets (see docs/velociroach.md)."""
        ids = np.array([model.actuator(constants.MOTORS[s]).id for s in constants.SIDES])
        chassis = model.body(constants.ROOT_BODY).id
        springs = np.array([model.joint(f"{leg}_spring").id for leg in constants.LEGS])
        spring_dofs = model.jnt_dofadr[springs]
        feet = np.array([g for g in range(model.ngeom) if model.body(model.geom_bodyid[g]).name.endswith("_leg")])
        floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, constants.FLOOR_GEOM)
        contact = np.append(feet, floor) if floor >= 0 else feet
        r0, k0 = (float(model.actuator_gainprm[ids[0], s]) for s in (0, 1))
        pid = self.action_mode == GAIT
        # the firmware's torque-space P and I gains: duty gains x V K / (R gear); its D gain is computed
        # (parameters_changed), since the K^2/R that cancels MuJoCo's back-EMF compensation does not scale with V
        gain = (ids, slice(GAIN_KP, GAIN_KD))
        p = ParameterMap()
        p.add(Parameter("battery_voltage", "V", self.nominal_battery, 2.5, 4.5,
                        "the battery's open-circuit voltage (1-cell LiPo, 3.6-3.8 V in the real logs)",
                        self.motors.supply_fields(), attribute="open_circuit"))  # fmt: skip
        p.add(Parameter("battery_resistance", "ohm", self.nominal_battery_resistance, 0.0, 0.5,
                        "the battery's internal resistance (0.11-0.34 ohm measured on the real logs)",
                        attribute="battery_resistance"))  # fmt: skip
        firmware_r = (FieldRef("actuator_gainprm", gain, "inverse"),) if pid else ()
        firmware_k = (FieldRef("actuator_gainprm", gain, "scale"),) if pid else ()

        def both(slot: int) -> tuple[FieldRef, ...]:
            """R or K (the left motor's value): set on both motors where they are alike, as built; a calibrated
            robot's right motor (its own R or K) scales with the left's."""
            values = model.actuator_gainprm[ids, slot]
            if values[1] == values[0]:
                return (FieldRef("actuator_gainprm", (ids, slot)),)
            return FieldRef("actuator_gainprm", (ids[:1], slot)), FieldRef("actuator_gainprm", (ids[1:], slot), "scale")

        p.add(Parameter("motor_resistance", "ohm", r0, 0.5 * r0, 3.0 * r0,
                        "winding resistance, both motors (a calibrated right motor scales with the left)",
                        (*both(0), *firmware_r)))  # fmt: skip
        p.add(Parameter("motor_constant", "N m/A", k0, 0.5 * k0, 2.0 * k0,
                        "torque and back-EMF constant, both motors (a calibrated right motor scales with the left)",
                        (*both(1), *firmware_k)))  # fmt: skip
        p.add(Parameter("chassis_mass", "kg", float(model.body_mass[chassis]), 0.01, 0.06,
                        "mass of the chassis body (its inertia scales with it)",
                        (FieldRef("body_mass", (chassis,), "scale"), FieldRef("body_inertia", (chassis,), "scale")),
                        setconst=True))  # fmt: skip
        p.add(Parameter("leg_stiffness", "N/m", float(model.jnt_stiffness[springs[0]]), 50.0, 1000.0,
                        "radial stiffness of each C-leg", (FieldRef("jnt_stiffness", (springs,)),)))  # fmt: skip
        p.add(Parameter("leg_damping", "N s/m", float(model.dof_damping[spring_dofs[0]]), 0.05, 5.0,
                        "radial damping of each C-leg", (FieldRef("dof_damping", (spring_dofs,)),)))  # fmt: skip
        p.add(Parameter("foot_friction", "1", float(model.geom_friction[feet[0], 0]), 0.05, 1.5,
                        "sliding friction of foot-ground contact (feet and floor together: MuJoCo takes the larger)",
                        (FieldRef("geom_friction", (contact, 0)),)))  # fmt: skip
        armature = float(model.actuator_armature[ids].max())  # a calibrated model may carry more than 1e-7
        p.add(Parameter("motor_armature", "kg m^2", armature, 0.0, max(1e-7, 2 * armature),
                        "rotor inertia at the motor shaft (up to 1e-7, or twice a calibrated model's)",
                        (FieldRef("actuator_armature", (ids,)),)))  # fmt: skip
        if pid:
            p.derived.append(self._derivative_gain)
        return p

    def _derivative_gain(self, target: Callable[[str], np.ndarray], values: Mapping[str, float]) -> None:
        """The firmware's D gain in the model, from the drawn battery and each motor's drawn R and K (already set):
        the duty's kd converted plus the K^2/R that cancels the back-EMF compensation, a sum no scaling gives."""
        m = self.motors
        gains = target("actuator_gainprm")
        gains[m.ids, GAIN_KD] = m.derivative_gain(values["battery_voltage"], gains[m.ids, GAIN_R], gains[m.ids, GAIN_K],
                                                  m.gear)  # fmt: skip

    def parameters_changed(self, ids: np.ndarray) -> None:
        self.motors.refresh(ids, self.field("actuator_gainprm"))

    # --- the contract -------------------------------------------------------------------------------------------
    @property
    def facts(self) -> Facts:
        return Facts(
            mass=self._mass,
            length=constants.LENGTH,
            sides=constants.SIDES,
            legs=constants.LEGS,
            extra={"sweep_amplitude": self.sweep_amplitude, "lift_amplitude": self.lift_amplitude, "gear": self.gear},
        )

    @property
    def sense_structure(self) -> dict[str, int]:
        senses = {"leg_cos": 2, "leg_sin": 2, "leg_velocity": 2, "gyro": 3, "accel": 3, "back_emf": 2, "battery": 1}
        if self.action_mode == GAIT:
            senses.update({"clock_cos": 2, "clock_sin": 2})
        return senses

    @property
    def telemetry_channels(self) -> dict[str, str]:
        return TELEMETRY_COLUMNS

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        # a leg turns no faster than its motor's no-load speed V / K at a full cell through the gear (the MJCF's
        # motor constants), twice over for motors of the kind; the duty is a fraction of the PWM's full scale
        top = LOG_SPEED_MARGIN * FULL_CELL_VOLTAGE / float(np.min(self.motors.motor_constant * self.motors.gear))
        source = (
            f"{LOG_SPEED_MARGIN:g} x the no-load leg speed V / (K gear) at {FULL_CELL_VOLTAGE:g} V, the MJCF's motors"
        )
        legs = ChannelLimit(max_rate=top, source=source)
        duty = ChannelLimit(-1.0, 1.0, source="the PWM duty's full scale")
        return {
            **{f"leg_angle_{side}": legs for side in constants.SIDES},
            **{f"duty_{side}": duty for side in constants.SIDES},
        }

    @property
    def plot_groups(self) -> tuple[PlotGroup, ...]:
        return (
            PlotGroup(
                "leg angle minus firmware clock",
                "deg",
                ("leg_angle_left", "leg_angle_right"),
                180 / np.pi,
                ("leg_angle_cmd_left", "leg_angle_cmd_right"),
            ),
            PlotGroup("PWM duty", "1", ("duty_left", "duty_right")),
            PlotGroup("crank torques", "mN m", ("torque_left", "torque_right"), scale=1e3),
            PlotGroup("vertical ground reaction force, left legs", "N", ("grf_FL_z", "grf_ML_z", "grf_BL_z")),
            PlotGroup("vertical ground reaction force, right legs", "N", ("grf_FR_z", "grf_MR_z", "grf_BR_z")),
        )

    def linkage_qpos(self, left: float, right: float) -> np.ndarray:
        """A qpos with the cranks at these angles (rad) and every linkage joint consistent with them."""
        q0 = self.model.qpos0
        q = q0.copy()
        for tied, theta, crank in zip(self._linkage, (left, right), self._crank_qpos, strict=True):
            set_crank(q, q0, crank, tied, theta)
        return q

    def reset(
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float = 0.0, options: Mapping | None = None
    ) -> None:
        """Home pose: tripod A (FL, BL, MR) at the bottom of its stroke, the right crank half a cycle behind the left;
        crank angle and phase perturbed by U(-noise, noise) rad, body angular velocity by N(0, noise) rad/s and linear
        velocity by N(0, noise / 10) m/s. ``options`` may give ``crank_left`` and ``phase`` (rad) exactly."""
        options = options or {}
        m = self.model
        qpos, qvel = np.zeros((len(ids), m.nq)), np.zeros((len(ids), m.nv))
        for j, rng in enumerate(rngs):
            crank = rng.uniform(-noise, noise)
            phase = constants.STRAIGHT_PHASE + rng.uniform(-noise, noise)
            lin, ang = rng.normal(0.0, noise * 0.1, 3), rng.normal(0.0, noise, 3)
            crank = float(options.get("crank_left", crank))
            phase = float(options.get("phase", phase))
            qpos[j] = self.linkage_qpos(crank, crank - phase)
            if self._root_qvel is not None:
                qvel[j, self._root_qvel : self._root_qvel + 6] = np.concatenate([lin, ang])
            self.phase[ids[j]] = phase
        cranks = qpos[:, self._crank_qpos]
        self.clock[ids] = cranks
        self.last_duty[ids] = 0.0
        self.battery[ids] = self.open_circuit[ids]  # nothing drawn yet
        self._drawn[ids] = 0.0
        self._write_gains()  # the reset state's controller is the full battery's, whatever ran before it
        state = {"qpos": qpos, "qvel": qvel, "act": np.zeros((len(ids), m.na))}
        ctrl = np.zeros((len(ids), m.nu))
        if self.action_mode == GAIT:
            ctrl[:, self.motors.ctrl_adr] = cranks * self.gear
        state["ctrl"] = ctrl
        self.sim.reset(ids, state)
        self.imu.reset(ids, rngs)

    def command(self, command: np.ndarray) -> None:
        """Gait mode: (n, 3) stride frequencies (Hz) and phase (rad); duty mode: (n, 2) duty per side."""
        ctrl = self.sim.ctrl
        self.battery[:] = loaded_voltage(self.open_circuit, self.battery_resistance, self._drawn)
        if self.action_mode == DUTY:
            self.last_duty[:] = np.minimum(np.maximum(command, -1.0), 1.0)
            self.motors.set_duty(ctrl, self.last_duty, self.battery)
            return
        dt = self.control_dt
        step = constants.PHASE_SLEW * dt
        dphi = np.minimum(np.maximum(wrap_angle(command[:, 2] - self.phase), -step), step)
        self.phase += dphi
        rate = 2.0 * np.pi * command[:, :2]
        rate[:, 1] -= dphi / dt  # the right clock falls behind by the phase change over the step
        # as the firmware advances its clock, then runs its PID: the clock at the end of each physics step is the
        # setpoint during that step (the last one ends the block at the new clock)
        self._write_gains()
        self.motors.set_ramps(ctrl, self.clock, rate, self._substep_times, self.battery)
        self.clock += rate * dt

    def block_gains(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """What the robot writes into the model for the current control block, for a replay to write too: (actuators,
        gain slots, values (num_sims, actuators, slots)) in gait mode (the firmware's gains for the battery's
        voltage), None in duty mode (every input a ``ctrl`` value)."""
        if self.action_mode != GAIT:
            return None
        return self.motors.ids, SUPPLY_SLOTS, self.motors.supply_gains(self.battery)

    def _write_gains(self) -> None:
        """Gait mode: the firmware's duty gains in MuJoCo's torque space carry the voltage the duty multiplies, each
        simulation's battery now (a simulation whose battery has not changed keeps the same values)."""
        gains = self.block_gains()
        if gains is not None:
            self.sim.set_actuator_gains(*gains)

    def read(self, rngs: Sequence[np.random.Generator], stepped: bool | np.ndarray = True) -> dict[str, np.ndarray]:
        v = self.sim.sensordata[:, self._i_read]  # every sensor the readings use, in one gather
        sub = self.sim.substep_sensordata[:, :, self._i_motor]  # motor torques and speeds, z gyro, per physics step
        if stepped is False:
            power = np.zeros(len(v))
        else:
            power = self.motors.battery_power(sub[:, :, :2], sub[:, :, 2:4]).sum(axis=(1, 2)) / self.n_substeps
            if stepped is not True:
                power = np.where(stepped, power, 0.0)
        self._drawn[:] = power  # the battery's load over the next control step
        imu = self.imu.update(v[:, 4:10], sub[:, :, 4], rngs, stepped)
        self._imu = imu
        senses = self._senses
        senses[:, 0:2] = np.cos(v[:, 0:2])
        senses[:, 2:4] = np.sin(v[:, 0:2])
        senses[:, 4:6] = v[:, 2:4]
        senses[:, 6:12] = imu
        senses[:, 12:14] = v[:, 10:12] * self.motors.motor_constant
        senses[:, 14] = self.battery
        if self.action_mode == GAIT:
            senses[:, 15:17] = np.cos(self.clock)
            senses[:, 17:19] = np.sin(self.clock)
        return {
            "time": self.sim.time,
            "position": v[:, 12:15],
            "quaternion": v[:, 15:19],
            "velocity": v[:, 19:22],
            "power": power,
            "heading": self.imu.heading.copy(),
            "senses": senses,  # the robot's buffer: valid until the next read
        }

    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        sd = self.sim.sensordata if sensordata is None else sensordata
        torque, speed = sd[:, self._i_torque], sd[:, self._i_speed]
        n = len(sd)
        clock = self.clock if self.action_mode == GAIT else np.full((n, 2), np.nan)
        columns = [
            readings["time"][:, None],
            clock,
            sd[:, self._i_leg_pos],
            self.motors.terminal_voltage(torque, speed) / self.battery[:, None],
            torque * self.gear,
            speed * self.motors.motor_constant,
            self.battery[:, None],
            self._imu,
            readings["position"],
            readings["quaternion"],
            -sd[:, self._i_grf],
            readings["power"][:, None],
        ]
        return np.concatenate(columns, axis=1)

    # --- helpers for tests, benchmarks and facts ------------------------------------------------------------------
    def leg_angles(self) -> np.ndarray:
        """Crank (leg) angles per side, unwrapped, rad: (num_sims, 2)."""
        return self.sim.sensordata[:, self._i_leg_pos]

    def leg_velocities(self) -> np.ndarray:
        return self.sim.sensordata[:, self._i_leg_vel]

    def crank_torques(self) -> np.ndarray:
        """Torque each motor applies to its crank (motor torque x gear), N m: (num_sims, 2)."""
        return self.gear * self.sim.sensordata[:, self._i_torque]

    def ground_reaction_forces(self) -> np.ndarray:
        """Force of the ground on each leg (FL, ML, BL, FR, MR, BR), world frame, N: (num_sims, 6, 3)."""
        return -self.sim.sensordata[:, self._i_grf].reshape(-1, 6, 3)

    def com_position(self) -> np.ndarray:
        return self.data.subtree_com[self.model.body(constants.ROOT_BODY).id]

    def set_body_velocity(self, linear: np.ndarray, angular: np.ndarray) -> None:
        """Set simulation 0's free-joint velocity (world-frame linear, body-frame angular)."""
        if self._root_qvel is None:
            raise ValueError("this robot's body is clamped to the world")
        self.data.qvel[self._root_qvel : self._root_qvel + 6] = np.concatenate([linear, angular])
        mujoco.mj_forward(self.model, self.data)
