"""The Dynamixel AX-12 servo: a DC motor behind a 254:1 gearbox under the servo's own position controller.

Modelled as what it is, on MuJoCo's native dcmotor (see :mod:`envs.actuators.dcmotor`):

- **goal**: a position in counts, 0..1023 over 300 deg, 512 at the centre [ax12-manual].
- **controller**: the servo's amplifier drives the motor with a duty that grows linearly with the position error
  from the compliance margin to full duty at the compliance slope (ROBOTIS e-manual: "compliance slope", default 32
  counts), bounded by the torque limit (default 1023 of 1023). Natively: a position-only dcmotor controller whose
  gain is ``1 / slope`` duty per count, with MuJoCo's back-EMF compensation cancelled so that the amplifier is a plain
  voltage source (``v = supply x duty``).
- **limits**: the servo's speed and torque limits are not clamps; they come out of the motor and the supply voltage:
  stall torque ``N K V / R``, no-load speed ``V / (N K)``. K and R are set so that the model meets the AX-12
  datasheet figures at 7 V and at 10 V ([ax12-manual]: 12 kgf cm and 0.269 s/60 deg at 7 V, 16.5 kgf cm and
  0.196 s/60 deg at 10 V) with the least worst relative error, 2% (tests/test_actuators.py measures them on the
  bench rig). The figures grow a little less than in proportion to the voltage; a linear motor cannot follow that
  exactly, and 2% is what it costs.
- **reported position**: quantized to a count, as the servo reports it.

Approximations, documented: the compliance margin (deadband, default 1 count = 0.29 deg) cannot run natively and is
left out: inside it the model still pushes, with at most 1/32 of full duty. The gearbox losses are lumped into the
effective winding resistance (MuJoCo's dcmotor has one motor constant): R_eff = 11.1 ohm where the AX-12A's
1.5 A stall current at 12 V (ROBOTIS e-manual) implies 8 ohm, so the electrical current reads about 28% low; the
torque and speed are right. The moving-speed register is taken at 0 (full speed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from envs.actuators.dcmotor import GAIN_KD, GAIN_KP, GAIN_R, DCMotors, PIDGains
from envs.common.parameters import FieldRef
from envs.common.telemetry import ChannelLimit

KGF_CM = 0.0980665  # N m
# AX-12 datasheet figures ([bioloid-webots, Table 2]; [ax12-manual]): (supply V, holding torque N m, speed rad/s)
DATASHEET = ((7.0, 12.0 * KGF_CM, (math.pi / 3) / 0.269), (10.0, 16.5 * KGF_CM, (math.pi / 3) / 0.196))
GEAR_RATIO = 254.0  # [bioloid-webots, Table 2]; ROBOTIS


def _per_volt(index: int) -> float:
    """Torque (index 1) or speed (index 2) per volt that errs least, relatively, at both datasheet voltages."""
    return 2.0 / sum(row[0] / row[index] for row in DATASHEET)


TORQUE_PER_VOLT = _per_volt(1)  # N m / V at the output: stall torque = this x supply
SPEED_PER_VOLT = _per_volt(2)  # rad/s / V at the output: no-load speed = this x supply
MOTOR_CONSTANT = 1.0 / (SPEED_PER_VOLT * GEAR_RATIO)  # V s/rad = N m/A at the motor
RESISTANCE = GEAR_RATIO * MOTOR_CONSTANT / TORQUE_PER_VOLT  # ohm, effective (gearbox losses lumped in)
# the winding's own resistance, from the AX-12A's stall current, 1.5 A at 12 V (ROBOTIS e-manual [ax12-manual])
WINDING_RESISTANCE = 12.0 / 1.5  # ohm
# what RESISTANCE lumps in: with the motor constant that gives the datasheet's no-load speed, the datasheet's stall
# torque is this fraction of what the winding alone would give, the gearbox's efficiency (about 0.72)
GEARBOX_EFFICIENCY = WINDING_RESISTANCE / RESISTANCE
MAX_SUPPLY_VOLTAGE = 12.0  # V: the top of the AX-12A's operating range, 9 to 12 V (ROBOTIS e-manual)
# a log's servo moves at most this many times the model's no-load speed at MAX_SUPPLY_VOLTAGE: the datasheet's
# figures are a servo's typical ones, and a back-driven output can run somewhat faster
LOG_SPEED_MARGIN = 2.0

# where MuJoCo 4.0's compiler keeps a dcmotor's cogging torque and LuGre friction (actuator biasprm and dynprm, as
# ``set_to_dcmotor(cogging=..., lugre=...)`` fills them; checked in tests/test_servo_friction.py), beside the slots
# envs/actuators/dcmotor.py names
BIAS_COGGING_AMPLITUDE, BIAS_COGGING_POLES, BIAS_COGGING_PHASE = 0, 1, 2
BIAS_LUGRE_COULOMB, BIAS_LUGRE_STATIC, BIAS_LUGRE_STRIBECK = 3, 4, 5
DYN_LUGRE_STIFFNESS, DYN_LUGRE_DAMPING = 5, 6
# the LuGre bristles' stiffness at the output, N m/rad: a presliding deflection of at most a tenth of a count
# (0.29 deg / 10 = 5.1e-4 rad) at the top of the rig's static friction range (0.2 N m: sysid/adapters/bench.py) needs
# 390 N m/rad. No bristle damping: the motor's back-EMF (stall torque over no-load speed, 0.3 N m s/rad at 10 V)
# damps the bristles' oscillation, and a critical bristle damping made the rig's rollout diverge once the Stribeck
# term had decayed at speed (measured at its 0.5 ms step; tests/test_servo_friction.py runs the undamped ones at the
# servo's top speed)
BRISTLE_STIFFNESS = 400.0


def scale_output_torque(actuator: mujoco.MjsActuator, saturated: float, linear: float) -> None:
    """Scale an AX-12 actuator's torque at the output by ``saturated`` while its amplifier is saturated (full duty:
    further than the compliance slope from the goal) and by ``linear`` within the slope, leaving its drive law (the
    duty for a position error) as it is: a spec edit of the dcmotor's fields, after :meth:`Servo.configure`.

    The controller commands the torque ``tau_c = kp e - kd w`` and drives ``v = (R/K) tau_c + K w`` clipped to
    ``Vmax``; the motor gives ``(K/R)(v - K w)``. Saturated, that is ``(K/R)(+-Vmax - K w)``, scaled by dividing R;
    within the slope it is ``tau_c`` itself, scaled by multiplying kp and kd (whose nominal ``K^2/R`` cancels the
    back-EMF compensation: the amplifier a voltage source). Both factors 1 leave every field as it was."""
    actuator.gainprm[GAIN_R] /= saturated
    actuator.gainprm[GAIN_KP] *= linear
    actuator.gainprm[GAIN_KD] *= linear


def add_stribeck_friction(actuator: mujoco.MjsActuator, static: float, velocity: float) -> None:
    """Static friction above the Coulomb level that decays with speed, ``static exp(-(w / velocity)^2)`` at the
    output in steady sliding (N m; ``velocity`` the Stribeck velocity, rad/s at the output): the dcmotor's own LuGre
    friction with no Coulomb part of its own (the joint's frictionloss holds that), its bristle state an activation
    of the actuator. The dcmotor's LuGre sits at the motor: levels are divided by the gear, speeds multiplied."""
    gear = actuator.gear[0]
    actuator.actdim = 1
    actuator.dynprm[DYN_LUGRE_STIFFNESS] = BRISTLE_STIFFNESS / gear**2
    actuator.dynprm[DYN_LUGRE_DAMPING] = 0.0
    actuator.biasprm[BIAS_LUGRE_COULOMB] = 0.0
    actuator.biasprm[BIAS_LUGRE_STATIC] = static / gear
    actuator.biasprm[BIAS_LUGRE_STRIBECK] = velocity * gear


def add_constant_torque(actuator: mujoco.MjsActuator, torque: float) -> None:
    """A constant torque at the output (N m), natively: the dcmotor's cogging term ``amplitude sin(poles theta +
    phase)`` with no poles and a phase of 90 deg."""
    actuator.biasprm[BIAS_COGGING_AMPLITUDE] = torque / actuator.gear[0]
    actuator.biasprm[BIAS_COGGING_POLES] = 0.0
    actuator.biasprm[BIAS_COGGING_PHASE] = math.pi / 2


@dataclass(frozen=True)
class ServoConstants:
    """An AX-12's constants and its control table's settings."""

    supply_voltage: float = 10.0  # V: the report's robots ran at 10 V [bioloid-webots]
    compliance_slope: float = 32.0  # counts from the margin to full duty (ROBOTIS default 32)
    torque_limit: float = 1023.0  # of 1023: the bound of the duty (ROBOTIS default 1023)
    counts: int = 1024  # positions 0..1023
    range_deg: float = 300.0  # over 300 deg (ROBOTIS)
    center: float = 512.0  # count of the centre position
    rotor_inertia: float = 1.5e-8  # kg m^2 at the motor, assumed (1 W coreless motor class); x N^2 at the output

    def __post_init__(self) -> None:
        for name in ("supply_voltage", "compliance_slope", "torque_limit", "range_deg"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"servo constant {name} must be positive and finite, got {value!r}")
        if self.torque_limit > 1023:
            raise ValueError(f"servo torque_limit is at most 1023, got {self.torque_limit}")

    @property
    def rad_per_count(self) -> float:
        return math.radians(self.range_deg) / (self.counts - 1)

    @property
    def stall_torque(self) -> float:
        """Torque at the output when blocked at full duty, N m."""
        return TORQUE_PER_VOLT * self.supply_voltage * self.torque_limit / 1023.0

    @property
    def no_load_speed(self) -> float:
        """Output speed at full duty and no load, rad/s."""
        return SPEED_PER_VOLT * self.supply_voltage * self.torque_limit / 1023.0

    def angle(self, counts: np.ndarray) -> np.ndarray:
        """Joint angle (rad, 0 at the centre) of a position in counts."""
        return (np.asarray(counts, dtype=np.float64) - self.center) * self.rad_per_count

    def counts_of(self, angle: np.ndarray) -> np.ndarray:
        """Position in counts of a joint angle (not rounded)."""
        return np.asarray(angle) / self.rad_per_count + self.center

    def channel_limits(self) -> dict[str, ChannelLimit]:
        """What a log of this servo can read (``goal``, ``present_position``, ``angle``, ``speed``): positions within
        the control table's counts, moving no faster than :data:`LOG_SPEED_MARGIN` times the no-load speed at the
        top of the supply range."""
        top = LOG_SPEED_MARGIN * SPEED_PER_VOLT * MAX_SUPPLY_VOLTAGE
        no_load = SPEED_PER_VOLT * MAX_SUPPLY_VOLTAGE
        speed = (f"{LOG_SPEED_MARGIN:g} x the no-load speed at {MAX_SUPPLY_VOLTAGE:g} V, {no_load:.3g} rad/s "
                 "(AX-12 datasheet [bioloid-webots, Table 2])")  # fmt: skip
        counts = f"positions 0..{self.counts - 1} over {self.range_deg:g} deg (ROBOTIS e-manual)"
        return {
            "goal": ChannelLimit(0.0, self.counts - 1.0, source=counts),
            "present_position": ChannelLimit(0.0, self.counts - 1.0, top / self.rad_per_count, f"{counts}; {speed}"),
            "angle": ChannelLimit(max_rate=top, source=speed),
            "speed": ChannelLimit(-top, top, source=speed),
        }


class Servo:
    """AX-12 servos on joints of a spec: one dcmotor per joint under the servo's position controller.

    Args:
        joints: joint names in the spec.
        constants: one set for every servo (default: AX-12 at 10 V, factory settings).
    """

    def __init__(self, joints: Sequence[str], constants: ServoConstants | None = None):
        self.joints = tuple(joints)
        self.constants = constants or ServoConstants()
        c = self.constants
        self.motors = DCMotors(
            [self.actuator_name(j) for j in self.joints],
            c.supply_voltage,
            PIDGains(
                kp=1.0 / (c.compliance_slope * c.rad_per_count),
                velocity_setpoint=False,
                compensate_back_emf=False,
                max_duty=c.torque_limit / 1023.0,
            ),
        )

    def actuator_name(self, joint: str) -> str:
        return f"{joint}_servo"

    def configure(self, spec: mujoco.MjSpec) -> None:
        """Add the servo actuators and their position, torque and speed sensors."""
        c = self.constants
        for joint in self.joints:
            a = spec.add_actuator(name=self.actuator_name(joint), target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
            a.set_to_dcmotor(motorconst=[MOTOR_CONSTANT, MOTOR_CONSTANT], resistance=RESISTANCE)
            a.gear[0] = GEAR_RATIO
            a.armature = c.rotor_inertia
            spec.add_sensor(
                name=f"{joint}_pos",
                type=mujoco.mjtSensor.mjSENS_JOINTPOS,
                objtype=mujoco.mjtObj.mjOBJ_JOINT,
                objname=joint,
            )
            for kind, sensor in (
                ("torque", mujoco.mjtSensor.mjSENS_ACTUATORFRC),
                ("speed", mujoco.mjtSensor.mjSENS_ACTUATORVEL),
            ):
                spec.add_sensor(
                    name=f"{joint}_motor_{kind}",
                    type=sensor,
                    objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
                    objname=self.actuator_name(joint),
                )
        self.motors.configure(spec)

    def bind(self, model: mujoco.MjModel, num_sims: int = 1) -> None:
        self.motors.bind(model, num_sims)

        def adr(suffix: str) -> np.ndarray:
            return np.array([model.sensor_adr[model.sensor(f"{j}{suffix}").id] for j in self.joints])

        self.pos_adr, self.torque_adr, self.speed_adr = adr("_pos"), adr("_motor_torque"), adr("_motor_speed")

    def set_goal(self, ctrl: np.ndarray, goal: np.ndarray) -> None:
        """Hold goal positions (n, joints) in counts, clipped to 0..1023, over the control block."""
        c = self.constants
        angle = c.angle(np.clip(goal, 0.0, c.counts - 1))
        self.motors.set_setpoints(
            ctrl, np.broadcast_to(angle[:, None, :], (ctrl.shape[0], ctrl.shape[1], len(self.joints)))
        )

    def position(self, sensordata: np.ndarray) -> np.ndarray:
        """Joint angles, rad (..., joints)."""
        return sensordata[..., self.pos_adr]

    def present_position(self, sensordata: np.ndarray) -> np.ndarray:
        """Position as the servo reports it: counts, rounded to a whole count."""
        return np.rint(self.constants.counts_of(self.position(sensordata)))

    def output_torque(self, sensordata: np.ndarray) -> np.ndarray:
        """Torque at the output shaft, N m (motor torque x gear)."""
        return sensordata[..., self.torque_adr] * self.motors.gear

    def battery_power(self, sensordata: np.ndarray) -> np.ndarray:
        """Electrical power per servo, W (max(v i, 0))."""
        return self.motors.battery_power(sensordata[..., self.torque_adr], sensordata[..., self.speed_adr])

    def supply_fields(self) -> tuple[FieldRef, ...]:
        return self.motors.supply_fields()
