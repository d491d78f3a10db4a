"""The Bioloid quadruped of [bioloid-webots]: 16 AX-12 servos on goal positions, an IMU and telemetry, on the robot
contract; it knows no task."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import ClassVar

import mujoco
import numpy as np

from envs.actuators.dcmotor import GAIN_KP
from envs.actuators.servo import Servo, ServoConstants
from envs.bioloid import constants
from envs.bioloid.effects import add_backlash, bioloid_effects, delay_edit, effects_edit
from envs.bioloid.kinematics import Ellipse, LegGeometry
from envs.common.calibration import Calibration
from envs.common.effects import Effect
from envs.common.imu import Imu, ImuNoise
from envs.common.parameters import FieldRef, Parameter, ParameterMap, SpecEdit
from envs.common.robot import ActionMode, Facts, PlotGroup, Robot, check_flag, check_number, standing_band
from envs.common.telemetry import ChannelLimit

GOAL = "goal"
OFFSET = "offset"
# rad: the offset mode's reach, a servo's goal is its ready-posture angle plus this times the action, as MuJoCo
# Playground's Go1 joystick (action_scale 0.5 around its default pose); every IK gait's goals stay within 0.384 rad of
# the ready posture at any frequency and steering (tests/test_bioloid_gaits.py, docs/bioloid.md)
OFFSET_SCALE = 0.5
LOAD_FULL_SCALE = 1023.0  # an AX-12 reports its load as 0..1023 of its maximum torque, with a direction bit


def _telemetry_channels() -> dict[str, str]:
    cols = {"time": "s"}
    for channel, unit in (
        ("goal", "count"),
        ("present_position", "count"),
        ("angle", "rad"),
        ("speed", "rad/s"),
        ("torque", "N m"),
        ("load", "count"),
        ("servo_power", "W"),
    ):
        cols.update({f"{channel}_{servo}": unit for servo in constants.SERVOS})
    cols.update({f"touch_{leg}": "N" for leg in constants.LEGS})
    cols["vbatt"] = "V"
    cols.update({f"gyro_{a}": "rad/s" for a in "xyz"})
    cols.update({f"accel_{a}": "m/s^2" for a in "xyz"})
    cols.update({f"pos_{a}": "m" for a in "xyz"})
    cols.update({f"quat_{a}": "1" for a in "wxyz"})
    cols["power"] = "W"
    return cols


TELEMETRY_COLUMNS: dict[str, str] = _telemetry_channels()


def ready_angles(wedge: float = 0.0) -> dict[str, float]:
    """The gaits' ready posture, servo -> rad: the standing posture with every sole at the centre of the report's
    ellipse under its hip (knees bent by the IK)."""
    angles = dict(constants.STAND_ANGLES)
    for leg in constants.LEGS:
        geometry = LegGeometry.of(leg, wedge)
        ellipse = Ellipse.seed_rules(geometry)
        hip, knee, _ = geometry.inverse(ellipse.h, ellipse.k)
        angles[constants.HIP[leg]], angles[constants.KNEE[leg]] = float(hip), float(knee)
    return angles


def offset_mode(wedge: float = 0.0) -> ActionMode:
    """The ``offset`` action mode: each servo's goal is its ready-posture angle (:func:`ready_angles`) plus
    :data:`OFFSET_SCALE` rad times its action, in counts, so that an action of 0 holds the ready posture."""
    ready = ready_angles(wedge)
    centre = np.array([constants.CENTER + ready[s] / constants.RAD_PER_COUNT for s in constants.SERVOS])
    reach = OFFSET_SCALE / constants.RAD_PER_COUNT
    return ActionMode(
        OFFSET,
        constants.SERVOS,
        ("count",) * len(constants.SERVOS),
        tuple((centre - reach).tolist()),
        tuple((centre + reach).tolist()),
        constants.CONTROL_FREQ,
        f"goal position of each servo, counts: its ready-posture angle +- {OFFSET_SCALE} rad (action 0 holds the "
        "ready posture; goals outside the servo's allowed range are clipped to it)",
    )


def knee_wedge_edit(angle: float = constants.KNEE_WEDGE) -> SpecEdit:
    """Spec edit: every shank turned by ``angle`` about its knee axis (the "aibo style" wedge, [bioloid-webots,
    IV.A])."""

    def edit(spec: mujoco.MjSpec) -> None:
        half = angle / 2.0
        for leg in constants.LEGS:
            body = spec.body(constants.KNEE[leg])
            # the knee axis is the shank body's own z; turning the body's frame turns the shank and its crutch
            body.quat = [math.cos(half), 0.0, 0.0, math.sin(half)]

    return edit


def _as_slice(addresses: np.ndarray) -> slice | np.ndarray:
    """Evenly spaced addresses as a slice (basic indexing is several times faster than a gather), else as given."""
    a = np.asarray(addresses)
    if len(a) > 1 and len(set(np.diff(a))) == 1 and a[1] > a[0]:
        return slice(int(a[0]), int(a[-1]) + 1, int(a[1] - a[0]))
    return a


class Bioloid(Robot):
    """A Bioloid quadruped [bioloid-webots] in a MuJoCo scene: 16 AX-12 servos (envs/actuators/servo.py) on the joints
    the report names (PELVIS; F_L_1..3, F_R_1..3, B_L_1..3, B_R_1..3; N_1, N_2, HEAD), crutch feet, 1.76 kg.

    Two action modes, each the 16 servos' goal positions in counts (0..1023 over 300 deg, 512 = 0 rad), clipped to
    each servo's allowed range (``constants.SERVO_RANGE``: the full span, the knees from straight to bent 90 deg),
    held over the control step as the servos hold a goal packet; 50 Hz by default. ``goal`` maps [-1, 1] onto the
    allowed range (an action of 0 puts the legs out sideways); ``offset`` onto the ready posture +-
    :data:`OFFSET_SCALE` rad (an action of 0 stands). Each servo's own position
    controller (compliance slope, torque and speed limits from its motor and supply) acts at every physics step,
    natively.

    Args:
        action_mode: ``"goal"`` or ``"offset"``.
        control_freq: control steps per second (default 50).
        knee_wedge: add the 18 deg wedge at each knee ([bioloid-webots, IV.A]; False: the design the seed validated).
        servo: the servos' constants and control-table settings (default: AX-12 at 10 V, factory compliance).
        battery_voltage: the servos' supply, V (default: ``servo``'s, 10 V); a shorthand for ``servo``'s.
        imu_noise: the IMU's error model (the report's robot has no IMU; one on the CM-5 is assumed so that heading
            tasks can run); None for a perfect IMU.
        spec_edits, num_sims, nthread, batched, calibration: as for every robot (``calibration``: a file written by
            ``calibrate.py --robot bioloid``, sysid/adapters/bioloid.py).
    """

    name = "bioloid"
    root_body = constants.ROOT_BODY
    feet = constants.FEET
    height_band = standing_band(constants.STANDING_HEIGHT, constants.BELLY_CLEARANCE)
    action_modes: ClassVar[dict[str, ActionMode]] = {
        GOAL: ActionMode(
            GOAL,
            constants.SERVOS,
            ("count",) * len(constants.SERVOS),
            tuple(constants.RANGE_LOW.tolist()),
            tuple(constants.RANGE_HIGH.tolist()),
            constants.CONTROL_FREQ,
            "goal position of each servo, counts (512 = 0 rad, 0.293 deg per count)",
        ),
        OFFSET: offset_mode(),
    }

    def __init__(
        self,
        action_mode: str = GOAL,
        control_freq: float | None = None,
        knee_wedge: bool = False,
        servo: ServoConstants | None = None,
        battery_voltage: float | None = None,
        imu_noise: ImuNoise | None = ImuNoise(),  # noqa: B008 (frozen dataclass)
        spec_edits: Sequence[SpecEdit] = (),
        num_sims: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
        calibration: str | Path | Calibration | None = None,
    ):
        knee_wedge = check_flag("knee_wedge", knee_wedge)
        if servo is not None and not isinstance(servo, ServoConstants):
            raise ValueError(f"servo must be a ServoConstants, got {servo!r}")
        servo_constants = servo or ServoConstants(supply_voltage=constants.BATTERY_VOLTAGE)
        if battery_voltage is not None:
            supply = check_number("battery_voltage", battery_voltage, 0, strict=True)
            servo_constants = replace(servo_constants, supply_voltage=supply)
        self.knee_wedge = knee_wedge
        self.wedge = constants.KNEE_WEDGE if knee_wedge else 0.0
        self.servo = Servo(constants.SERVOS, servo_constants)
        self.nominal_battery = servo_constants.supply_voltage
        self.imu_noise = imu_noise
        super().__init__(action_mode, control_freq, spec_edits, num_sims, nthread, batched, calibration)

    def action_mode_of(self, name: str) -> ActionMode:
        """The ``offset`` mode centred on this robot's ready posture (the knee wedge moves its knees)."""
        return offset_mode(self.wedge) if name == OFFSET else super().action_mode_of(name)

    @classmethod
    def xml_path(cls) -> Path:
        return constants.SCENE_XML

    # --- building -----------------------------------------------------------------------------------------------
    def configure(self, spec: mujoco.MjSpec) -> None:
        for name in constants.SERVOS:
            joint = spec.joint(name)
            knee = name in constants.KNEE.values()
            joint.range = (
                [-constants.KNEE_EXTENSION, constants.KNEE_LIMIT]
                if knee
                else [-constants.JOINT_STOP, constants.JOINT_STOP]
            )
            joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        if self.knee_wedge:
            knee_wedge_edit(self.wedge)(spec)
        self.servo.configure(spec)

    def calibration_effects(self) -> dict[str, Effect]:
        dt = float(mujoco.MjSpec.from_file(str(self.xml_path())).option.timestep)
        return {name: e for name, e in bioloid_effects(dt).items() if e.catalogued}

    def calibration_edits(self, calibration: Calibration) -> Sequence[SpecEdit]:
        """The calibration's model effects as spec edits (envs/bioloid/effects.py): joint friction and inertia,
        the servos' gain and supply, the crutches' contact, BODY's mass and centre of mass, the gear trains' play and
        the goals' delay. A position offset describes the logging robot's sensors and changes nothing here."""
        setting = calibration.setting
        gap, delay = setting.get("backlash.gap", 0.0), setting.get("delay.seconds", 0.0)
        return [effects_edit(setting), *([add_backlash(gap)] if gap > 1e-6 else []),
                *([delay_edit(delay)] if delay > 0 else [])]  # fmt: skip

    def setup(self) -> None:
        m, n = self.model, self.num_sims
        self.servo.bind(m, n)

        def idx(*names: str) -> np.ndarray:
            return np.concatenate([np.arange(self.sensors[k].start, self.sensors[k].stop) for k in names])

        s = self.servo
        self._i_pos, self._i_torque, self._i_speed = (_as_slice(a) for a in (s.pos_adr, s.torque_adr, s.speed_adr))
        self._i_gyro, self._i_accel = idx(constants.SENSOR_GYRO), idx(constants.SENSOR_ACCEL)
        self._i_imu = _as_slice(np.concatenate([self._i_gyro, self._i_accel]))
        self._i_body = _as_slice(idx(constants.SENSOR_BODY_POS, constants.SENSOR_BODY_QUAT, constants.SENSOR_BODY_VEL))
        self._i_touch = _as_slice(idx(*(constants.SENSOR_TOUCH[leg] for leg in constants.LEGS)))
        self._i_gyro_z = int(self._i_gyro[2])
        c = s.constants
        self._count_per_rad, self._rad_per_count, self._center = 1.0 / c.rad_per_count, c.rad_per_count, c.center
        self._inv_gear = 1.0 / s.motors.gear
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, constants.ROOT_JOINT)
        self._root_qpos = int(m.jnt_qposadr[root]) if root >= 0 else None
        self._root_qvel = int(m.jnt_dofadr[root]) if root >= 0 else None
        self._servo_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in constants.SERVOS])
        self._servo_dofs = np.array([m.jnt_dofadr[m.joint(j).id] for j in constants.SERVOS])
        joints = np.array([m.joint(j).id for j in constants.SERVOS])
        self._joint_low, self._joint_high = m.jnt_range[joints, 0].copy(), m.jnt_range[joints, 1].copy()
        self._mass = float(m.body_subtreemass[m.body(constants.ROOT_BODY).id])
        self.ready = ready_angles(self.wedge)
        self.ready_counts = np.array([self.servo.constants.counts_of(self.ready[s]) for s in constants.SERVOS])
        self.goal = np.tile(self.ready_counts, (n, 1))
        self.battery = np.full(n, self.nominal_battery)
        self.imu = Imu(n, self.imu_noise, self.control_dt, float(m.opt.timestep))
        self._imu = np.zeros((n, 6))
        self._servo_power = np.zeros((n, len(constants.SERVOS)))
        self._senses = np.zeros((n, sum(self.sense_structure.values())))

    def build_parameters(self, model: mujoco.MjModel) -> ParameterMap:
        """The Bioloid's physical parameters, each with the model fields it sets (docs/bioloid.md)."""
        c = self.servo.constants
        actuators = self.servo.motors.ids
        robot_geoms = np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] != 0])
        feet = np.array([model.geom(constants.FOOT_GEOM[leg]).id for leg in constants.LEGS]
                        + [model.geom(constants.CRUTCH_GEOM[leg]).id for leg in constants.LEGS])  # fmt: skip
        body = model.body(constants.ROOT_BODY).id
        dofs = self._servo_dofs
        p = ParameterMap()
        p.add(Parameter("battery_voltage", "V", c.supply_voltage, 6.0, 12.6,
                        "the servos' supply (AX-12: 7-10 V; the CM-5's 9.6 V pack; AX-12A up to 12 V)",
                        self.servo.supply_fields(), attribute="battery"))  # fmt: skip
        p.add(Parameter("compliance_slope", "count", c.compliance_slope, 8.0, 128.0,
                        "every servo's compliance slope: counts of error from the margin to full duty",
                        (FieldRef("actuator_gainprm", (actuators, GAIN_KP), "inverse"),)))  # fmt: skip
        p.add(Parameter("servo_armature", "kg m^2", c.rotor_inertia, 0.25 * c.rotor_inertia, 4.0 * c.rotor_inertia,
                        "rotor inertia at the motor of every servo (x 254^2 at the joint)",
                        (FieldRef("actuator_armature", (actuators,)),), setconst=True))  # fmt: skip
        p.add(Parameter("joint_friction", "N m", 0.0, 0.0, 0.2, "Coulomb friction at every servo's output",
                        (FieldRef("dof_frictionloss", (dofs,)),)))  # fmt: skip
        p.add(Parameter("joint_damping", "N m s/rad", 0.0, 0.0, 0.1,
                        "viscous friction at every servo's output (beside the motor's back-EMF)",
                        (FieldRef("dof_damping", (dofs,)),)))  # fmt: skip
        p.add(Parameter("foot_friction", "1", float(model.geom_friction[feet[0], 0]), 0.2, 1.5,
                        "sliding friction of the crutches on the ground (their contact parameters take priority)",
                        (FieldRef("geom_friction", (feet, 0)),)))  # fmt: skip
        p.add(Parameter("body_friction", "1", float(model.geom_friction[robot_geoms[0], 0]), 0.2, 1.5,
                        "sliding friction of the brackets and cases on the ground",
                        (FieldRef("geom_friction", (np.setdiff1d(robot_geoms, feet), 0)),)))  # fmt: skip
        p.add(Parameter("body_mass", "kg", float(model.body_mass[body]), 0.55, 0.85,
                        "BODY: the CM-5 with its battery (Table 3: 0.692 kg), inertia scaled with it",
                        (FieldRef("body_mass", (body,), "scale"), FieldRef("body_inertia", (body,), "scale")),
                        setconst=True))  # fmt: skip
        for axis, i in (("x", 0), ("y", 1), ("z", 2)):
            p.add(Parameter(f"body_com_{axis}", "m", float(model.body_ipos[body, i]),
                            float(model.body_ipos[body, i]) - 0.02, float(model.body_ipos[body, i]) + 0.02,
                            f"BODY's centre of mass along {axis} (the report suspects the CM-5's is off, "
                            "[bioloid-webots, V.B])",
                            (FieldRef("body_ipos", (body, i)),), setconst=True))  # fmt: skip
        return p

    def parameters_changed(self, ids: np.ndarray) -> None:
        self.servo.motors.refresh(ids, self.field("actuator_gainprm"))

    # --- the contract -------------------------------------------------------------------------------------------
    @property
    def facts(self) -> Facts:
        return Facts(
            mass=self._mass,
            length=constants.LENGTH,
            legs=constants.LEGS,
            extra={
                "servos": constants.SERVOS,
                "knee_wedge": self.knee_wedge,
                "supply_voltage": self.nominal_battery,
                "stall_torque": self.servo.constants.stall_torque,
            },
        )

    @property
    def sense_structure(self) -> dict[str, int]:
        n = len(constants.SERVOS)
        return {"leg_cos": n, "leg_sin": n, "servo_speed": n, "servo_load": n, "gyro": 3, "accel": 3, "battery": 1}

    @property
    def telemetry_channels(self) -> dict[str, str]:
        return TELEMETRY_COLUMNS

    @property
    def channel_limits(self) -> dict[str, ChannelLimit]:
        servo = self.servo.constants.channel_limits()  # every servo an AX-12
        return {f"{channel}_{s}": servo[channel] for channel in servo for s in constants.SERVOS}

    @property
    def plot_groups(self) -> tuple[PlotGroup, ...]:
        front_left = tuple(f"present_position_{s}" for s in ("F_L_1", "F_L_3"))
        return (
            PlotGroup(
                "front-left hip and knee, present minus goal",
                "count",
                front_left,
                1.0,
                tuple(f"goal_{s}" for s in ("F_L_1", "F_L_3")),
            ),
            PlotGroup("hip torques", "N m", tuple(f"torque_{constants.HIP[leg]}" for leg in constants.LEGS)),
            PlotGroup("foot contact force", "N", tuple(f"touch_{leg}" for leg in constants.LEGS)),
            PlotGroup("battery power", "W", ("power",)),
        )

    def stand_height(self, angles: np.ndarray) -> float:
        """Height of the body's origin (m) at which the lowest sole of a level robot in posture ``angles`` (rad, in
        ``SERVOS`` order) touches the ground."""
        m = self.model
        data = getattr(self, "_kinematics", None)
        if data is None:  # one scratch MjData for the kinematics (making one per reset took most of a reset's time)
            data = self._kinematics = mujoco.MjData(m)
        data.qpos[:] = m.qpos0
        data.qpos[self._servo_qpos] = angles
        if self._root_qpos is not None:
            data.qpos[self._root_qpos : self._root_qpos + 7] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
        mujoco.mj_kinematics(m, data)
        lowest = min(data.site(constants.SOLE_SITE[leg]).xpos[2] for leg in constants.LEGS)
        return float(-lowest)

    def reset(
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float = 0.0, options: Mapping | None = None
    ) -> None:
        """The gaits' ready posture (legs down, soles at the centre of the report's ellipse), level, its lowest sole on
        the ground; servo angles perturbed by U(-noise, noise) x 0.2 rad, body angular velocity by N(0, noise / 2)
        rad/s and linear velocity by N(0, noise / 20) m/s. The goals hold the perturbed posture. ``options`` may give
        ``counts`` (16 servo positions, counts) or ``angles`` (16, rad) exactly, and ``height`` (m) of the body's
        origin (default: the lowest sole on the ground)."""
        options = options or {}
        m = self.model
        k = len(ids)
        qpos, qvel = np.tile(m.qpos0, (k, 1)), np.zeros((k, m.nv))
        base = np.array([self.ready[s] for s in constants.SERVOS])
        if "counts" in options or "angles" in options:
            base = self._option_posture(options)
        fixed_height = None if "height" not in options else check_number("options['height']", options["height"], 0)
        heights: dict[bytes, float] = {}
        for j, rng in enumerate(rngs):
            angles = base + 0.2 * rng.uniform(-noise, noise, len(constants.SERVOS))
            lin, ang = rng.normal(0.0, noise / 20.0, 3), rng.normal(0.0, noise / 2.0, 3)
            angles = np.clip(angles, self._joint_low, self._joint_high)
            qpos[j, self._servo_qpos] = angles
            if self._root_qpos is not None:
                key = angles.tobytes()
                if key not in heights:
                    heights[key] = self.stand_height(angles) + 1e-4 if fixed_height is None else fixed_height
                qpos[j, self._root_qpos : self._root_qpos + 7] = [0.0, 0.0, heights[key], 1.0, 0.0, 0.0, 0.0]
                qvel[j, self._root_qvel : self._root_qvel + 6] = np.concatenate([lin, ang])
            self.goal[ids[j]] = self.servo.constants.counts_of(angles)
        self.sim.reset(ids, {"qpos": qpos, "qvel": qvel, "act": np.zeros((k, m.na)), "ctrl": np.zeros((k, m.nu))})
        self.imu.reset(ids, rngs)
        self._servo_power[ids] = 0.0
        self.command(self.goal)

    @staticmethod
    def _option_posture(options: Mapping) -> np.ndarray:
        key = "counts" if "counts" in options else "angles"
        values = np.asarray(options[key], dtype=np.float64)
        if values.shape != (len(constants.SERVOS),) or not np.isfinite(values).all():
            raise ValueError(
                f"options[{key!r}] must be {len(constants.SERVOS)} finite numbers in SERVOS order, got {values!r}"
            )
        return (values - constants.CENTER) * constants.RAD_PER_COUNT if key == "counts" else values

    def command(self, command: np.ndarray) -> None:
        """Goal positions (n, 16) in counts, clipped to each servo's allowed range, held over the control block."""
        self.goal[:] = np.minimum(np.maximum(command, constants.RANGE_LOW), constants.RANGE_HIGH)
        self.servo.set_goal(self.sim.ctrl, self.goal)

    def read(self, rngs: Sequence[np.random.Generator], stepped: bool | np.ndarray = True) -> dict[str, np.ndarray]:
        sd = self.sim.sensordata
        sub = self.sim.substep_sensordata
        if stepped is False:
            self._servo_power[:] = 0.0
        else:
            self._servo_power = self.servo.battery_power(sub).mean(axis=1)
            if stepped is not True:
                self._servo_power[~np.asarray(stepped)] = 0.0
        self._imu = self.imu.update(sd[:, self._i_imu], sub[:, :, self._i_gyro_z], rngs, stepped)
        # the angle as the servo reports it: a whole count
        angle = (np.rint(sd[:, self._i_pos] * self._count_per_rad + self._center) - self._center) * self._rad_per_count
        n = len(constants.SERVOS)
        senses = self._senses
        np.cos(angle, out=senses[:, 0:n])
        np.sin(angle, out=senses[:, n : 2 * n])
        np.multiply(sd[:, self._i_speed], self._inv_gear, out=senses[:, 2 * n : 3 * n])
        senses[:, 3 * n : 4 * n] = self.load(sd)
        senses[:, 4 * n : 4 * n + 6] = self._imu
        senses[:, 4 * n + 6] = self.battery
        body = sd[:, self._i_body].copy()  # readings outlive the step: not a view of the simulator's buffer
        return {
            "time": self.sim.time,
            "position": body[:, 0:3],
            "quaternion": body[:, 3:7],
            "velocity": body[:, 7:10],
            "power": self._servo_power.sum(axis=1),
            "heading": self.imu.heading.copy(),
            "senses": senses,  # the robot's buffer: valid until the next read
        }

    def load(self, sensordata: np.ndarray) -> np.ndarray:
        """Each servo's load as it reports it: output torque over its stall torque at the present supply, signed, in
        counts of 1023 (ROBOTIS "present load"), rounded to a whole count."""
        scale = LOAD_FULL_SCALE * self.nominal_battery / (self.servo.constants.stall_torque * self.battery)
        load = sensordata[:, self._i_torque] * self.servo.motors.gear * scale[:, None]
        return np.rint(np.clip(load, -LOAD_FULL_SCALE, LOAD_FULL_SCALE, out=load), out=load)

    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        sd = self.sim.sensordata if sensordata is None else sensordata
        s = self.servo
        present = s.present_position(sd)
        columns = [
            readings["time"][:, None],
            self.goal,
            present,
            s.position(sd),
            sd[:, self._i_speed] * self._inv_gear,
            s.output_torque(sd),
            self.load(sd),
            self._servo_power,
            sd[:, self._i_touch],
            self.battery[:, None],
            self._imu,
            readings["position"],
            readings["quaternion"],
            readings["power"][:, None],
        ]
        return np.concatenate(columns, axis=1)

    # --- helpers for policies, tests and benchmarks -----------------------------------------------------------
    def servo_angles(self) -> np.ndarray:
        """Servo angles, rad: (num_sims, 16) in ``SERVOS`` order."""
        return self.servo.position(self.sim.sensordata)

    def foot_forces(self, sensordata: np.ndarray | None = None) -> np.ndarray:
        """Normal force on each foot, N: (num_sims, 4) in ``LEGS`` order (or per physics step with substep data)."""
        sd = self.sim.sensordata if sensordata is None else sensordata
        return sd[..., self._i_touch].copy()
