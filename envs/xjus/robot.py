"""The xJüs robot: three segments on a passive spine, six compliant legs on the report's gearmotors, the Buehler clock
and PD, an IMU and telemetry, on the robot contract; it knows no task."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

from envs.actuators.motor import Motor, MotorConstants
from envs.common.calibration import Calibration
from envs.common.effects import Effect
from envs.common.imu import Imu, ImuNoise
from envs.common.parameters import FieldRef, Parameter, ParameterMap, SpecEdit
from envs.common.robot import ActionMode, Facts, PlotGroup, Robot, check_number, standing_band
from envs.common.telemetry import ChannelLimit
from envs.xjus import constants
from envs.xjus.controller import Gait, MotorArrays, moderate, pd_torque, wrap_angle, wrap_angle_one
from envs.xjus.effects import add_backlash, delay_edit, effects_edit, xjus_effects

GAIT, DUTY = "gait", "duty"
COMPLIANT, RIGID = "compliant", "rigid"
_TWO_PI = 2.0 * np.pi
SpineSetting = float | Mapping[str, float] | None


def _telemetry_channels() -> dict[str, str]:
    cols = {"time": "s", "clock_phase": "cycle", "period": "s"}
    cols.update({f"sweep_{side}": "rad" for side in constants.SIDES})
    per_leg = (
        ("leg_angle_cmd", "rad"),
        ("leg_angle", "rad"),
        ("leg_speed", "rad/s"),
        ("duty", "1"),
        ("current", "A"),
        ("torque", "N m"),
        ("power", "W"),
        ("deflection", "m"),
        ("grf_z", "N"),
    )
    for channel, unit in per_leg:
        cols.update({f"{channel}_{leg}": unit for leg in constants.LEGS})
    cols["vbatt"] = "V"
    cols.update({f"spine_{joint}": "rad" for joint in constants.SPINE_JOINTS})
    cols.update({f"gyro_{a}": "rad/s" for a in "xyz"})
    cols.update({f"accel_{a}": "m/s^2" for a in "xyz"})
    cols.update({f"pos_{a}": "m" for a in "xyz"})
    cols.update({f"quat_{a}": "1" for a in "wxyz"})
    cols["power"] = "W"
    return cols


TELEMETRY_COLUMNS: dict[str, str] = _telemetry_channels()  # name -> unit, in table order


def _spine_values(
    name: str, value: SpineSetting, default: float, zero_allowed: bool, high: float | None = None
) -> dict[str, float]:
    """Per joint and axis values from one number or a mapping {"front_pitch": ..., ...} (missing: the default)."""
    if value is None:
        return dict.fromkeys(constants.SPINE_JOINTS, default)
    strict = not zero_allowed
    if isinstance(value, Mapping):
        unknown = set(value) - set(constants.SPINE_JOINTS)
        if unknown:
            raise ValueError(
                f"{name} names unknown spine axes {sorted(unknown)}; known: {list(constants.SPINE_JOINTS)}"
            )
        values = {
            j: check_number(f"{name}[{j!r}]", value.get(j, default), 0, strict=strict) for j in constants.SPINE_JOINTS
        }
    else:
        values = dict.fromkeys(constants.SPINE_JOINTS, check_number(name, value, 0, strict=strict))
    for joint, x in values.items():
        if high is not None and x > high:
            raise ValueError(
                f"{name}[{joint!r}] must be <= {high:.0f} N m/rad ({constants.SPINE_STIFFNESS_MAX_SCALE:g}x the design "
                f"stiffness; stiffer goes numerically unstable at the 2 ms physics step; spine='rigid' is the rigid "
                f"chassis), got {x!r}"
            )
    return values


class Xjus(Robot):
    """An xJüs hexapod in a MuJoCo scene: three chassis segments joined by two passive pitch-and-roll spine joints,
    six compliant semicircular legs, each on one of the report's gearmotors (envs/actuators/motor.py).

    Two action modes, both at 125 Hz by default (an 8 ms step, at least as fast as the report's 8.3 ms logic step):

    - ``gait``: ``(period, sweep_left, sweep_right)``: the robot's own Buehler clock (one per robot, tripods half a
      cycle apart) and PD ([xjus-report, sections 2.4 and 2.5]; envs/xjus/controller.py) run once per control step, at
      the control rate, which must be at least 120 Hz. Equal sweeps walk straight; a larger sweep on one side makes
      that side's legs sweep the ground faster over the same period, and the robot turns away from it. The duty the PD
      gives is held over the control step, as the report's logic step held it. ``backward`` (n, 2), False unless a
      caller sets it (the soccer steering), runs a side's legs through the same clock backward: one side backward
      and the other forward turns the robot on the spot, as RHex turns in place (Saranli, Buehler, Koditschek,
      "RHex: a simple and highly mobile hexapod robot", IJRR 2001).
    - ``duty``: the duty ``d`` per leg in [-1, 1], held over the control step (the report's simulation input).

    The motor model acts at every physics step natively (its back-EMF at the present speed): every input to the
    physics is a ``ctrl`` value.

    Args:
        action_mode: ``"gait"`` or ``"duty"``.
        control_freq: control steps per second (default 125; in gait mode at least 120).
        spine: ``"compliant"`` (two passive joints, pitch and roll) or ``"rigid"`` (the joints removed: one rigid
            chassis).
        spine_stiffness: N m/rad, one value for all four spine axes or a mapping over ``front_pitch``,
            ``front_roll``, ``rear_pitch``, ``rear_roll`` (default: the report's design stiffness, 19.4 N m/rad, 60 lbf
            in at 20 deg), at most 50x that (971 N m/rad: stiffer goes unstable at the 2 ms physics step). Compliant
            spine only.
        spine_damping: N m s/rad, the same way (default 0.1). Compliant spine only.
        battery_voltage: supply voltage Vs, V (default the report's 22.2 V).
        current_limit: a motor driver's current limit, A per motor, or None (default; the report gives 1.08 A
            continuous). The limit clamps the torque each motor puts on its hip, natively.
        imu_noise: the IMU's error model (default the MPU-6000's, as on the VelociRoACH; the report names no IMU); None
            for a perfect IMU.
        starts: where an episode may start, (x, y) on level ground; each reset draws one (default: the origin).
        spec_edits, num_sims, nthread, batched, calibration: as for every robot (``calibration``: a file written by
            ``calibrate.py --robot xjus``, sysid/adapters/xjus.py).
    """

    name = "xjus"
    root_body = constants.ROOT_BODY
    feet = constants.FEET
    height_band = standing_band(constants.STANDING_HEIGHT, constants.BELLY_CLEARANCE)
    action_modes: ClassVar[dict[str, ActionMode]] = {
        GAIT: ActionMode(
            GAIT,
            ("period", "sweep_left", "sweep_right"),
            ("s", "rad", "rad"),
            (constants.PERIOD_RANGE[0], constants.SWEEP_RANGE[0], constants.SWEEP_RANGE[0]),
            (constants.PERIOD_RANGE[1], constants.SWEEP_RANGE[1], constants.SWEEP_RANGE[1]),
            constants.CONTROL_FREQ,
            "Buehler-clock period and ground sweep angle per side (equal: straight; larger on the right: turns left)",
        ),
        DUTY: ActionMode(
            DUTY,
            tuple(f"duty_{leg}" for leg in constants.LEGS),
            ("1",) * len(constants.LEGS),
            (-1.0,) * len(constants.LEGS),
            (1.0,) * len(constants.LEGS),
            constants.CONTROL_FREQ,
            "duty factor d per leg [xjus-report, section 2.3]",
        ),
    }

    def __init__(
        self,
        action_mode: str = GAIT,
        control_freq: float | None = None,
        spine: str = COMPLIANT,
        spine_stiffness: SpineSetting = None,
        spine_damping: SpineSetting = None,
        battery_voltage: float | None = None,
        current_limit: float | None = None,
        imu_noise: ImuNoise | None = ImuNoise(),  # noqa: B008 (frozen dataclass)
        starts: Sequence[Sequence[float]] | None = None,
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
        calibration: str | Path | Calibration | None = None,
    ):
        if spine not in (COMPLIANT, RIGID):
            raise ValueError(f"spine must be {COMPLIANT!r} or {RIGID!r}, got {spine!r}")
        if spine == RIGID and (spine_stiffness is not None or spine_damping is not None):
            raise ValueError("spine_stiffness and spine_damping apply to a compliant spine, not spine='rigid'")
        self.spine = spine
        self.spine_stiffness = _spine_values(
            "spine_stiffness", spine_stiffness, constants.SPINE_DESIGN_STIFFNESS, False, constants.SPINE_STIFFNESS_MAX
        )
        self.spine_damping = _spine_values("spine_damping", spine_damping, constants.SPINE_DAMPING, True)
        self._battery_arg = (
            None if battery_voltage is None else check_number("battery_voltage", battery_voltage, 0, strict=True)
        )
        self.current_limit = (
            None if current_limit is None else check_number("current_limit", current_limit, 0, strict=True)
        )
        if action_mode == GAIT and control_freq is not None:
            freq = check_number("control_freq", control_freq, 0, strict=True)
            if freq < constants.MIN_GAIT_CONTROL_FREQ:
                raise ValueError(
                    f"control_freq={control_freq!r}: gait mode runs the clock and PD at the control rate, which must "
                    f"be at least {constants.MIN_GAIT_CONTROL_FREQ:g} Hz (the report's 8.3 ms logic step)"
                )
        self.starts = self._check_starts(starts)
        self.imu_noise = imu_noise
        super().__init__(action_mode, control_freq, spec_edits, num_sims, nthread, batched, calibration)

    @staticmethod
    def _check_starts(starts: Sequence[Sequence[float]] | None) -> np.ndarray:
        if starts is None:
            return np.zeros((1, 2))
        try:
            array = np.asarray(starts, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"starts must be a sequence of (x, y) pairs, got {starts!r}") from None
        if array.ndim != 2 or array.shape[1] != 2 or len(array) == 0 or not np.isfinite(array).all():
            raise ValueError(f"starts must be a non-empty sequence of finite (x, y) pairs, got {starts!r}")
        return array

    @classmethod
    def xml_path(cls) -> Path:
        return constants.SCENE_XML

    # --- building -----------------------------------------------------------------------------------------------
    def configure(self, spec: mujoco.MjSpec) -> None:
        if self._battery_arg is not None:
            spec.numeric("battery_voltage").data = [self._battery_arg]
        self.constants = MotorConstants(
            **{field: float(spec.numeric(numeric).data[0]) for field, numeric in constants.NUMERIC_MOTOR}
        )
        self.nominal_battery = self.constants.supply_voltage
        if self.spine == RIGID:
            for joint in constants.SPINE_JOINTS:
                spec.delete(spec.joint(joint))
        else:
            for joint in constants.SPINE_JOINTS:
                j = spec.joint(joint)
                j.stiffness = [self.spine_stiffness[joint], 0.0, 0.0]
                j.damping = [self.spine_damping[joint], 0.0, 0.0]
                spec.add_sensor(
                    name=constants.SENSOR_SPINE[joint],
                    type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                    objtype=mujoco.mjtObj.mjOBJ_JOINT,
                    objname=joint,
                )
        self.motor = Motor([constants.HIP_JOINTS[leg] for leg in constants.LEGS], self.constants)
        self.motor.configure(spec)
        if self.current_limit is not None:
            limit = self.current_limit * self.constants.torque_per_amp
            for leg in constants.LEGS:
                j = spec.joint(constants.HIP_JOINTS[leg])
                j.actfrclimited = mujoco.mjtLimited.mjLIMITED_TRUE
                j.actfrcrange = [-limit, limit]

    # --- calibration (calibrate.py --robot xjus; envs/xjus/effects.py holds the effects) ------------------------------
    def calibration_effects(self) -> dict[str, Effect]:
        dt = float(mujoco.MjSpec.from_file(str(self.xml_path())).option.timestep)
        return {name: e for name, e in xjus_effects(dt).items() if e.catalogued}

    def calibration_edits(self, calibration: Calibration) -> Sequence[SpecEdit]:
        """The calibration's model effects as spec edits (envs/xjus/effects.py): the hips' friction and inertia,
        the motor numerics (which the motor arrays are read from), contacts, stiffnesses, masses, the gearboxes'
        play and the motors' delay. The driver's deadband is applied to every duty the robot holds; sensor effects
        (an angle offset, a current gain) describe the logging robot's sensors and change nothing here."""
        setting = calibration.setting
        self._deadband = setting.get("deadband.duty", 0.0)
        gap, delay = setting.get("backlash.gap", 0.0), setting.get("delay.seconds", 0.0)
        return [effects_edit(setting), *([add_backlash(gap)] if gap > 1e-6 else []),
                *([delay_edit(delay)] if delay > 0 else [])]  # fmt: skip

    def setup(self) -> None:
        m, n = self.model, self.num_sims
        self.motor.bind(m)
        # the two actuators per hip alternate in ctrl: their columns as strided slices (a view, not a gather; a list
        # takes them too)
        self._drive_at, self._emf_at = _as_slice(self.motor.drive_adr), _as_slice(self.motor.emf_adr)
        self._sliced_ctrl = isinstance(self._drive_at, slice) and isinstance(self._emf_at, slice)

        def idx(*names: str) -> np.ndarray:
            return np.concatenate([np.arange(self.sensors[k].start, self.sensors[k].stop) for k in names])

        legs = constants.LEGS
        self._i_angle = idx(*(constants.SENSOR_ANGLE[leg] for leg in legs))
        self._i_speed = idx(*(constants.SENSOR_SPEED[leg] for leg in legs))
        self._i_torque = idx(*(constants.SENSOR_TORQUE[leg] for leg in legs))
        self._i_deflection = idx(*(constants.SENSOR_DEFLECTION[leg] for leg in legs))
        self._i_grf = idx(*(constants.SENSOR_GRF[leg] for leg in legs))
        self._i_gyro, self._i_accel = idx(constants.SENSOR_GYRO), idx(constants.SENSOR_ACCEL)
        self._i_pos, self._i_quat, self._i_vel = (
            idx(constants.SENSOR_BODY_POS),
            idx(constants.SENSOR_BODY_QUAT),
            idx(constants.SENSOR_BODY_VEL),
        )
        self._i_spine = idx(*constants.SENSOR_SPINE.values()) if self.spine == COMPLIANT else None
        # one gather per step: angles 0:6, speeds 6:12, gyro 12:15, accel 15:18, position 18:21, quaternion 21:25,
        # body velocity 25:28
        self._i_read = np.concatenate(
            [self._i_angle, self._i_speed, self._i_gyro, self._i_accel, self._i_pos, self._i_quat, self._i_vel]
        )
        # the per-step reads of angles, speeds and torques as slices where their sensors lie side by side (a view
        # is a tenth of a gather's cost); the helpers below keep the gathers: they hand out copies
        self._at_angle, self._at_speed, self._at_torque = map(_as_slice, (self._i_angle, self._i_speed, self._i_torque))
        self._at_gyro_z = int(self._i_gyro[2])
        self._numeric = {f: int(m.numeric_adr[m.numeric(name).id]) for f, name in constants.NUMERIC_MOTOR}
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, constants.ROOT_JOINT)
        self._root_qpos = int(m.jnt_qposadr[root]) if root >= 0 else None  # a bench clamp removes the free joint
        self._root_qvel = int(m.jnt_dofadr[root]) if root >= 0 else None
        self._hip_qpos = np.array([m.jnt_qposadr[m.joint(constants.HIP_JOINTS[leg]).id] for leg in legs])
        # the controller's plant inertia J: leg, hub and reflected rotor about the hip, from the nominal model
        self.hip_inertia = np.array([m.dof_M0[m.jnt_dofadr[m.joint(constants.HIP_JOINTS[leg]).id]] for leg in legs])
        self._hip_inertia_one = self.hip_inertia.tolist()
        # the gait command's bounds, (period, sweep_left, sweep_right): one clip for all three
        self._gait_low = np.array([constants.PERIOD_RANGE[0], constants.SWEEP_RANGE[0], constants.SWEEP_RANGE[0]])
        self._gait_high = np.array([constants.PERIOD_RANGE[1], constants.SWEEP_RANGE[1], constants.SWEEP_RANGE[1]])
        self._mass = float(m.body_subtreemass[m.body(constants.ROOT_BODY).id])
        self.stand_height = self._standing_height()
        self.gait = Gait.tripod()
        # per-simulation motor constants, controller state and readings
        self.motors = MotorArrays(*(np.zeros(n) for _ in range(5)))
        self.parameters_changed(np.arange(n))
        self.phase = np.zeros(n)  # the Buehler clock, cycles since tripod A began its stance
        self.period = np.full(n, np.nan)
        self.sweep = np.full((n, 2), np.nan)
        self.backward = np.zeros((n, 2), dtype=bool)  # per side (left, right): its legs run the clock backward
        self.last_duty = np.zeros((n, len(legs)))
        self.target = np.full((n, len(legs)), np.nan)  # the last clock target (gait mode), near the measured angle
        self.start_index = np.zeros(n, dtype=np.int64)
        self.imu = Imu(n, self.imu_noise, self.control_dt, float(m.opt.timestep))
        self._senses = np.zeros((n, sum(self.sense_structure.values())))
        self._imu = np.zeros((n, 6))
        self._leg_power = np.zeros((n, len(legs)))

    def _standing_height(self) -> float:
        """Height of the hips above flat ground with a leg pointing down, its toe just touching (m)."""
        m = self.model
        tip = m.site(f"{constants.LEGS[0]}_tip").pos[2]
        radius = max(
            m.geom_size[g, 0] for g in range(m.ngeom) if m.body(m.geom_bodyid[g]).name == f"{constants.LEGS[0]}_leg"
        )
        return float(-tip + radius)

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        """xJüs's physical parameters, each with the model fields it sets (docs/xjus.md)."""
        num = {f: (FieldRef("numeric_data", (adr,)),) for f, adr in self._numeric.items()}
        c = self.constants
        hips = np.array([model.joint(constants.HIP_JOINTS[leg]).id for leg in constants.LEGS])
        hip_dofs = model.jnt_dofadr[hips]
        springs = np.array([model.joint(constants.SPRING_JOINTS[leg]).id for leg in constants.LEGS])
        spring_dofs = model.jnt_dofadr[springs]
        leg_bodies = {model.body(f"{leg}_leg").id for leg in constants.LEGS}
        feet = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] in leg_bodies])
        segments = np.array([model.body(s).id for s in constants.SEGMENTS])
        limit = (FieldRef("jnt_actfrcrange", (hips,), "scale"),) if self.current_limit is not None else ()
        p = ParameterMap()
        p.add(Parameter("battery_voltage", "V", c.supply_voltage, 18.0, 25.2,
                        "supply voltage Vs (6-cell LiPo: 3.0 to 4.2 V per cell)", num["supply_voltage"]))  # fmt: skip
        p.add(Parameter("motor_resistance", "ohm", c.motor_resistance, 0.5 * c.motor_resistance,
                        2.0 * c.motor_resistance, "motor winding resistance Ra, all six motors",
                        num["motor_resistance"]))  # fmt: skip
        p.add(Parameter("amplifier_resistance", "ohm", c.amplifier_resistance, 0.0, 4.0 * c.amplifier_resistance,
                        "amplifier resistance Ramp (the d^2 Ramp term), all six motors",
                        num["amplifier_resistance"]))  # fmt: skip
        p.add(Parameter("torque_constant", "N m/A", c.torque_constant, 0.5 * c.torque_constant,
                        1.5 * c.torque_constant, "Kt at the motor (the output torque per amp eta N Kt scales with it)",
                        (*num["torque_constant"], *limit)))  # fmt: skip
        p.add(Parameter("speed_constant", "V s/rad", c.speed_constant, 0.5 * c.speed_constant,
                        1.5 * c.speed_constant, "Ks at the output shaft (back-EMF per leg speed)",
                        num["speed_constant"]))  # fmt: skip
        armature = float(model.dof_armature[hip_dofs[0]])
        p.add(Parameter("motor_armature", "kg m^2", armature, 0.0, 3.0 * armature,
                        "rotor inertia reflected to each hip", (FieldRef("dof_armature", (hip_dofs,)),),
                        setconst=True))  # fmt: skip
        k = float(model.jnt_stiffness[springs[0]])
        p.add(Parameter("leg_stiffness", "N/m", k, 0.25 * k, 4.0 * k, "radial stiffness of each leg",
                        (FieldRef("jnt_stiffness", (springs,)),)))  # fmt: skip
        b = float(model.dof_damping[spring_dofs[0]])
        p.add(Parameter("leg_damping", "N s/m", b, 0.0, 5.0 * b, "radial damping of each leg",
                        (FieldRef("dof_damping", (spring_dofs,)),)))  # fmt: skip
        p.add(Parameter("foot_friction", "1", float(model.geom_friction[feet[0], 0]), 0.2, 1.5,
                        "sliding friction of the legs on the ground (the legs' contact parameters take priority)",
                        (FieldRef("geom_friction", (feet, 0)),)))  # fmt: skip
        p.add(Parameter("segment_mass_scale", "1", 1.0, 0.8, 1.25,
                        "x the three segments' masses and inertias (battery and legs unchanged)",
                        (FieldRef("body_mass", (segments,), "scale"), FieldRef("body_inertia", (segments,), "scale")),
                        setconst=True))  # fmt: skip
        if self.spine == COMPLIANT:
            spine = np.array([model.joint(j).id for j in constants.SPINE_JOINTS])
            low, high = constants.SPINE_STIFFNESS_RANGE
            stable = "N m/rad; stiffer goes numerically unstable at the 2 ms physics step"
            stiffness = FieldRef("jnt_stiffness", (spine,), "scale", constants.SPINE_STIFFNESS_MAX, stable)
            p.add(Parameter("spine_stiffness_scale", "1", 1.0, low, high,
                            "x the spine's stiffness per joint and axis as built", (stiffness,)))  # fmt: skip
            p.add(Parameter("spine_damping_scale", "1", 1.0, 0.1, 10.0,
                            "x the spine's damping per joint and axis as built",
                            (FieldRef("dof_damping", (model.jnt_dofadr[spine],), "scale"),)))  # fmt: skip
        return p

    def parameters_changed(self, ids: np.ndarray) -> None:
        values = self.field("numeric_data")[ids]
        mo, adr = self.motors, self._numeric
        mo.supply_voltage[ids] = values[:, adr["supply_voltage"]]
        mo.motor_resistance[ids] = values[:, adr["motor_resistance"]]
        mo.amplifier_resistance[ids] = values[:, adr["amplifier_resistance"]]
        mo.speed_constant[ids] = values[:, adr["speed_constant"]]
        mo.torque_per_amp[ids] = (
            values[:, adr["efficiency"]] * values[:, adr["gear_ratio"]] * values[:, adr["torque_constant"]]
        )
        # what every read divides and multiplies by, per leg (refreshed with the motors): an operand of the arrays' own
        # shape spares numpy the broadcasting, which costs as much as the operation
        legs = len(constants.LEGS)
        self._torque_per_amp_legs = np.repeat(mo.torque_per_amp[:, None], legs, axis=1)
        self._volts_per_torque_legs = np.repeat((mo.supply_voltage / mo.torque_per_amp)[:, None], legs, axis=1)

    @property
    def battery(self) -> np.ndarray:
        """Supply voltage per simulation, V."""
        return self.motors.supply_voltage

    # --- the contract -------------------------------------------------------------------------------------------
    @property
    def facts(self) -> Facts:
        return Facts(
            mass=self._mass,
            length=constants.LENGTH,
            sides=constants.SIDES,
            legs=constants.LEGS,
            extra={
                "spine": self.spine,
                "gear": self.constants.gear_ratio,
                "leg_diameter": constants.LEG_DIAMETER,
                "hip_inertia": float(self.hip_inertia[0]),
                "current_limit": self.current_limit,
                "efficiency_cap": self.constants.torque_per_amp / self.constants.speed_constant,
            },
        )

    @property
    def sense_structure(self) -> dict[str, int]:
        legs = len(constants.LEGS)
        senses = {"leg_cos": legs, "leg_sin": legs, "leg_velocity": legs, "gyro": 3, "accel": 3,
                  "motor_current": legs, "battery": 1}  # fmt: skip
        if self.action_mode == GAIT:
            senses.update({"clock_cos": 1, "clock_sin": 1})
        return senses

    @property
    def telemetry_channels(self) -> dict[str, str]:
        return TELEMETRY_COLUMNS

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        motor = self.constants.channel_limits()  # each leg on its own gearmotor [xjus-report, Table 1]
        names = {"leg_angle": "angle", "leg_speed": "speed", "duty": "duty", "current": "current"}
        return {f"{channel}_{leg}": motor[limit] for channel, limit in names.items() for leg in constants.LEGS}

    @property
    def plot_groups(self) -> tuple[PlotGroup, ...]:
        a = constants.TRIPOD_A
        return (
            PlotGroup(
                "leg angle minus clock target, tripod A",
                "deg",
                tuple(f"leg_angle_{leg}" for leg in a),
                180 / np.pi,
                tuple(f"leg_angle_cmd_{leg}" for leg in a),
            ),
            PlotGroup("duty, tripod A", "1", tuple(f"duty_{leg}" for leg in a)),
            PlotGroup("motor current, tripod A", "A", tuple(f"current_{leg}" for leg in a)),
            PlotGroup("battery power", "W", ("power",)),
            PlotGroup("spine angles", "deg", tuple(f"spine_{j}" for j in constants.SPINE_JOINTS), 180 / np.pi),
        )

    def reset(
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float = 0.0, options: Mapping | None = None
    ) -> None:
        """Tripod A (front-left, back-left, middle-right) standing with its legs pointing down, tripod B pointing
        up, the clock at the middle of tripod A's stance; at one of ``starts`` (drawn), level. Leg angles perturbed
        by U(-noise, noise) rad, body angular velocity by N(0, noise) rad/s and linear velocity by N(0, noise / 10)
        m/s. ``options`` may give ``start`` (an index into ``starts``) and ``leg_angles`` (six, rad) exactly."""
        options = options or {}
        m = self.model
        k = len(ids)
        qpos, qvel = np.tile(m.qpos0, (k, 1)), np.zeros((k, m.nv))
        rest = np.array([0.0 if leg in constants.TRIPOD_A else np.pi for leg in constants.LEGS])
        for j, rng in enumerate(rngs):
            start = int(rng.integers(len(self.starts))) if len(self.starts) > 1 else 0
            angles = rest + rng.uniform(-noise, noise, len(constants.LEGS))
            lin, ang = rng.normal(0.0, noise * 0.1, 3), rng.normal(0.0, noise, 3)
            if "start" in options:
                start = self._option_start(options["start"])
            if "leg_angles" in options:
                angles = self._option_angles(options["leg_angles"])
            qpos[j, self._hip_qpos] = angles
            if self._root_qpos is not None:
                x, y = self.starts[start]
                qpos[j, self._root_qpos : self._root_qpos + 7] = [x, y, self.stand_height, 1.0, 0.0, 0.0, 0.0]
                qvel[j, self._root_qvel : self._root_qvel + 6] = np.concatenate([lin, ang])
            self.start_index[ids[j]] = start
        self.phase[ids] = 0.25  # the middle of tripod A's stance
        self.period[ids] = np.nan
        self.sweep[ids] = np.nan
        self.backward[ids] = False
        self.target[ids] = np.nan
        self.last_duty[ids] = 0.0
        state = {"qpos": qpos, "qvel": qvel, "act": np.zeros((k, m.na)), "ctrl": np.zeros((k, m.nu))}
        self.sim.reset(ids, state)
        self.imu.reset(ids, rngs)

    def _option_start(self, value) -> int:
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= value < len(self.starts):
            raise ValueError(f"options['start'] must be a whole number in [0, {len(self.starts)}), got {value!r}")
        return int(value)

    @staticmethod
    def _option_angles(value) -> np.ndarray:
        angles = np.asarray(value, dtype=np.float64)
        if angles.shape != (len(constants.LEGS),) or not np.isfinite(angles).all():
            raise ValueError(f"options['leg_angles'] must be {len(constants.LEGS)} finite angles (rad), got {value!r}")
        return angles

    def command(self, command: np.ndarray) -> None:
        """Gait mode: (n, 3) period (s) and ground sweep per side (rad); duty mode: (n, 6) duty per leg."""
        if self.action_mode == DUTY:
            if self.num_sims == 1 and self._hold_one([_clip(d, -1.0, 1.0) for d in command[0].tolist()]):
                return
            self._hold_array(np.minimum(np.maximum(command, -1.0), 1.0))  # the float path declined: not again
            return
        backward = self.backward.any()
        if self.num_sims == 1 and not backward and self._command_one(command[0].tolist()):
            return
        bounded = np.minimum(np.maximum(command, self._gait_low), self._gait_high)
        period, sweep = bounded[:, 0], bounded[:, 1:3]
        self.period[:], self.sweep[:] = period, sweep
        sd = self.sim.sensordata
        angle, speed = sd[:, self._at_angle], sd[:, self._at_speed]
        target, rate, accel = self.gait.targets(self.phase, period, sweep)
        if backward:  # the clock's angle mirrored: the slow stance still crosses the bottom, the legs turn backward
            sign = np.where(self.backward[:, self.gait.side], -1.0, 1.0)
            target, rate, accel = sign * target, sign * rate, sign * accel
        error = wrap_angle(target - angle)
        self.target = angle + error
        torque = pd_torque(error, rate - speed, accel, self.hip_inertia, constants.PD_KP, constants.PD_KD)
        self.hold_duty(self.motors.duty_for_torque(torque, speed))
        self.phase = np.mod(self.phase + self.control_dt / period, 1.0)

    def _command_one(self, command: list[float]) -> bool:
        """The gait command of a single simulation on Python floats (the controller's ``*_one`` functions): the vector
        path's numbers at under half its cost. False, having changed nothing, unless the values are moderate."""
        period = _clip(command[0], *constants.PERIOD_RANGE)
        sweep = [_clip(command[1], *constants.SWEEP_RANGE), _clip(command[2], *constants.SWEEP_RANGE)]
        sd = self.sim.sensordata[0]
        angles, speeds = sd[self._at_angle].tolist(), sd[self._at_speed].tolist()
        phase = self.phase.item()
        if not moderate(period, *sweep, phase, *angles, *speeds):
            return False
        target, rate, accel = self.gait.targets_one(phase, period, sweep)
        errors = [wrap_angle_one(t - a) for t, a in zip(target, angles, strict=True)]
        torque = [
            pd_torque(e, r - w, acc, j, constants.PD_KP, constants.PD_KD)
            for e, r, w, acc, j in zip(errors, rate, speeds, accel, self._hip_inertia_one, strict=True)
        ]
        try:
            duty = self.motors.duty_for_torque_one(torque, speeds)
        except ZeroDivisionError:  # a supply voltage of 0 (numpy: inf and NaN)
            return False
        self.period[0], self.sweep[0] = period, sweep
        self.target = np.array([[a + e for a, e in zip(angles, errors, strict=True)]])
        if not self._hold_one(duty):
            self._hold_array(np.array([duty]))
        self.phase = np.array([(phase + self.control_dt / period) % 1.0])  # np.mod's result
        return True

    def hold_duty(self, duty: np.ndarray) -> None:
        """Hold duty (n, legs) in [-1, 1] over the control block: the motor's two native actuators per hip."""
        if self.num_sims == 1 and self._hold_one(duty[0].tolist()):
            return
        self._hold_array(duty)

    def _hold_array(self, duty: np.ndarray) -> None:
        """:meth:`hold_duty` on arrays, for any number of simulations (where :meth:`_hold_one` declines)."""
        band = getattr(self, "_deadband", 0.0)  # a calibrated driver's deadband (calibration_edits)
        if band > 0:
            duty = np.sign(duty) * np.maximum(np.abs(duty) - band, 0.0)
        self.last_duty[:] = duty
        ctrl = self.sim.ctrl
        first = ctrl[:, 0]  # a view: written once, then copied over the block's other physics steps
        first[:, self._drive_at], first[:, self._emf_at] = self.motors.coefficients(duty)
        ctrl[:, 1:] = first[:, None]

    def _hold_one(self, duty: list[float]) -> bool:
        """:meth:`hold_duty` of a single simulation (duty per leg) on Python floats, the ctrl row as a list: the same
        numbers. False, having changed nothing, for a calibrated deadband (hold_duty applies it) or values that are
        not moderate."""
        if getattr(self, "_deadband", 0.0) > 0 or not (self._sliced_ctrl and moderate(*duty)):
            return False
        ctrl = self.sim.ctrl
        row = ctrl[0, 0].tolist()
        try:
            row[self._drive_at], row[self._emf_at] = self.motors.coefficients_one(duty)
        except ZeroDivisionError:  # Ra + d^2 Ramp = 0 (numpy: inf and NaN)
            return False
        self.last_duty[0] = duty
        ctrl[0] = row  # every physics step of the block
        return True

    def read(self, rngs: Sequence[np.random.Generator], stepped: bool | np.ndarray = True) -> dict[str, np.ndarray]:
        sd = self.sim.sensordata
        v = sd[:, self._i_read]
        sub = self.sim.substep_sensordata  # per physics step, read through views
        if stepped is False:
            self._leg_power[:] = 0.0
        else:
            per_step = self._battery_power(sub[:, :, self._at_speed], sub[:, :, self._at_torque])
            self._leg_power = np.add.reduce(per_step, axis=1) * (1.0 / per_step.shape[1])  # the mean, less overhead
            if stepped is not True:
                self._leg_power[~np.asarray(stepped)] = 0.0
        power = self._leg_power.sum(axis=1)
        senses = self._senses  # written in place: the senses' own order
        np.cos(v[:, 0:6], out=senses[:, 0:6])
        np.sin(v[:, 0:6], out=senses[:, 6:12])
        senses[:, 12:18] = v[:, 6:12]
        self._imu = self.imu.update(v[:, 12:18], sub[:, :, self._at_gyro_z], rngs, stepped, out=senses[:, 18:24])
        np.divide(sd[:, self._at_torque], self._torque_per_amp_legs, out=senses[:, 24:30])
        senses[:, 30] = self.motors.supply_voltage
        if self.action_mode == GAIT:
            clock = _TWO_PI * self.phase
            senses[:, 31] = np.cos(clock)
            senses[:, 32] = np.sin(clock)
        return {
            "time": self.sim.time,
            "position": v[:, 18:21],
            "quaternion": v[:, 21:25],
            "velocity": v[:, 25:28],
            "power": power,
            "heading": self.imu.heading.copy(),
            "senses": senses,  # the robot's buffer: valid until the next read
        }

    def _battery_power(self, speed: np.ndarray, torque: np.ndarray) -> np.ndarray:
        """Battery power per leg at every physics step, W, (n, substeps, legs): ``max(d Vs i, 0)`` (seed formula;
        the H-bridge returns no braking energy). Under a current limit the driver lowers its effective duty so that
        ``d Vs = i (Ra + d^2 Ramp) + Ks w`` holds at the limited current."""
        mo = self.motors
        if self.current_limit is None:  # d Vs i = (d Vs / k) torque, the factor taken once per leg
            volts_per_torque = self.last_duty * self._volts_per_torque_legs
            power = torque * volts_per_torque[:, None, :]
            return np.maximum(power, 0.0, out=power)
        vs = mo.supply_voltage[:, None, None]
        current = torque / mo.torque_per_amp[:, None, None]
        duty = np.broadcast_to(self.last_duty[:, None, :], current.shape)
        limited = np.abs(current) >= self.current_limit * (1 - 1e-9)
        duty = np.where(limited, self._limited_duty(current, speed), duty)
        return np.maximum(duty * vs * current, 0.0)

    def _limited_duty(self, current: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """The duty at which the motor draws ``current`` at ``speed``: i Ramp d^2 - Vs d + (i Ra + Ks w) = 0."""
        mo = self.motors
        vs, ra = mo.supply_voltage[:, None, None], mo.motor_resistance[:, None, None]
        ramp, ks = mo.amplifier_resistance[:, None, None], mo.speed_constant[:, None, None]
        c = current * ra + ks * speed
        disc = np.maximum(vs * vs - 4.0 * current * ramp * c, 0.0)
        return np.clip(2.0 * c / (vs + np.sqrt(disc)), -1.0, 1.0)

    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        sd = self.sim.sensordata if sensordata is None else sensordata
        n = len(sd)
        angle, speed, torque = sd[:, self._i_angle], sd[:, self._i_speed], sd[:, self._i_torque]
        gait = self.action_mode == GAIT
        nan = np.full((n, 1), np.nan)
        spine = sd[:, self._i_spine] if self._i_spine is not None else np.zeros((n, len(constants.SPINE_JOINTS)))
        columns = [
            readings["time"][:, None],
            self.phase[:, None] if gait else nan,
            self.period[:, None] if gait else nan,
            self.sweep if gait else np.full((n, 2), np.nan),
            self.target,
            angle,
            speed,
            self.last_duty,
            torque / self.motors.torque_per_amp[:, None],
            torque,
            self._leg_power,
            sd[:, self._i_deflection],
            -sd[:, self._i_grf].reshape(n, len(constants.LEGS), 3)[:, :, 2],
            self.motors.supply_voltage[:, None],
            spine,
            self._imu,
            readings["position"],
            readings["quaternion"],
            readings["power"][:, None],
        ]
        return np.concatenate(columns, axis=1)

    # --- helpers for tests, benchmarks and the spine study ----------------------------------------------------
    def leg_angles(self) -> np.ndarray:
        """Hip angles, unwrapped, rad: (num_sims, 6) in the order of ``constants.LEGS``."""
        return self.sim.sensordata[:, self._i_angle]

    def leg_speeds(self) -> np.ndarray:
        return self.sim.sensordata[:, self._i_speed]

    def hip_torques(self) -> np.ndarray:
        """Torque each motor puts on its hip, N m: (num_sims, 6)."""
        return self.sim.sensordata[:, self._i_torque]

    def spine_angles(self) -> np.ndarray:
        """Spine joint angles (front pitch, front roll, rear pitch, rear roll), rad; zeros for a rigid spine."""
        if self._i_spine is None:
            return np.zeros((self.num_sims, len(constants.SPINE_JOINTS)))
        return self.sim.sensordata[:, self._i_spine]

    def segment_quaternions(self) -> np.ndarray:
        """World orientation of the front, middle and rear segments, (num_sims, 3, 4) (w, x, y, z)."""
        sd = self.sim.sensordata
        parts = [self.sensor(constants.SENSOR_SEGMENT_QUAT["front"], sd), sd[:, self._i_quat],
                 self.sensor(constants.SENSOR_SEGMENT_QUAT["rear"], sd)]  # fmt: skip
        return np.stack(parts, axis=1)

    def ground_reaction_forces(self) -> np.ndarray:
        """Force of the ground on each leg, world frame, N: (num_sims, 6, 3)."""
        return -self.sim.sensordata[:, self._i_grf].reshape(-1, len(constants.LEGS), 3)


def _clip(x: float, low: float, high: float) -> float:
    """``np.minimum(np.maximum(x, low), high)`` of one float: a tie gives the bound, as numpy gives its second
    operand (-0.0 against a bound of 0.0 gives 0.0); NaN stays NaN."""
    return low if x <= low else high if x >= high else x


def _as_slice(index: np.ndarray) -> slice | np.ndarray:
    """``index`` as a slice if it runs in equal steps forward, else as it is."""
    if len(index) == 0:
        return index
    start = int(index[0])
    step = int(index[1] - index[0]) if len(index) > 1 else 1
    if step > 0 and np.array_equal(index, start + step * np.arange(len(index))):
        return slice(start, start + step * (len(index) - 1) + 1, step)
    return index


def efficiency_cap(constants: MotorConstants | None = None) -> float:
    """eta N Kt / Ks: the most electrical power the report's motor model turns into shaft power (0.37 for Table 1)."""
    c = constants or MotorConstants()
    return c.torque_per_amp / c.speed_constant
