"""The DC gearmotor model of the xJüs report ([xjus-report, section 2.3 and Table 1], after [seipel2006]).

    tau = eta N Kt (d Vs - Ks thetadot) / (Ra + d^2 Ramp),    d = clip(Vpd / Vs, -1, 1)

with ``thetadot`` the output-shaft speed. The duty ``d`` is held over each control step (the report's logic step was
8.3 ms); within it the torque is affine in ``thetadot``, ``tau = A(d) - B(d) thetadot``, so two native actuators per
joint give the formula exactly at every physics step, driven through ``ctrl`` alone:

- ``<joint>_drive``: a ``general`` actuator of gain 1, ``ctrl = A(d) = eta N Kt d Vs / (Ra + d^2 Ramp)``;
- ``<joint>_emf``: a ``general`` actuator with ``gainprm = [0, 0, -1]`` (force = -velocity x ctrl),
  ``ctrl = B(d) = eta N Kt Ks / (Ra + d^2 Ramp)``.

MuJoCo's ``dcmotor`` cannot express it: the report's ``eta N Kt`` (0.28 N m/A) differs from its ``Ks`` (0.75 V s), so
the model's efficiency is capped at ``eta N Kt / Ks = 0.37`` by its own constants, and its resistance grows with
``d^2``. The motor current is ``i = (d Vs - Ks thetadot) / (Ra + d^2 Ramp)`` and the battery current ``d i``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields

import mujoco
import numpy as np

from envs.common.telemetry import ChannelLimit

# a log may come from another gearmotor of this kind (the RHex3 rig's runs at about half this one's no-load speed):
# its shaft speed is bounded at this many times the model's no-load speed, far above any motor of the kind (a shaft
# does not outrun its motor's no-load speed at full duty unless something drives it) and far below a corrupted field
LOG_SPEED_MARGIN = 5.0


@dataclass(frozen=True)
class MotorConstants:
    """The report's Table 1 [xjus-report]: "taken from the specifications of purchased components, except for Kt and Ks,
    which were chosen such that the model reflects the stall torque and no load speed of the motor"."""

    gear_ratio: float = 729 / 25  # N
    efficiency: float = 0.60  # eta, net
    supply_voltage: float = 22.2  # Vs, V (a 6-cell LiPo)
    motor_resistance: float = 2.36  # Ra, ohm
    amplifier_resistance: float = 0.5  # Ramp, ohm
    torque_constant: float = 0.016  # Kt, N m/A (at the motor)
    speed_constant: float = 0.75  # Ks, V s/rad (at the output shaft)

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"motor constant {f.name} must be positive and finite, got {value!r}")
        if self.efficiency > 1:
            raise ValueError(f"motor constant efficiency must be at most 1, got {self.efficiency}")

    @property
    def torque_per_amp(self) -> float:
        """eta N Kt, N m/A at the output shaft."""
        return self.efficiency * self.gear_ratio * self.torque_constant

    def resistance(self, d: np.ndarray) -> np.ndarray:
        return self.motor_resistance + np.square(d) * self.amplifier_resistance

    def current(self, d: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Motor current, A, at duty ``d`` and output speed ``speed`` (rad/s)."""
        return (d * self.supply_voltage - self.speed_constant * speed) / self.resistance(d)

    def torque(self, d: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Output-shaft torque, N m: the report's formula."""
        return self.torque_per_amp * self.current(d, speed)

    def coefficients(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A, B) with torque = A - B x speed at a held duty."""
        r = self.resistance(d)
        return self.torque_per_amp * d * self.supply_voltage / r, self.torque_per_amp * self.speed_constant / r

    def battery_power(self, d: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Power the battery delivers, W: Vs x battery current (d i); negative when the motor regenerates."""
        return self.supply_voltage * d * self.current(d, speed)

    @property
    def stall_torque(self) -> float:
        """Output torque at d = 1 and rest, N m (2.17 for Table 1)."""
        return float(self.torque(np.float64(1.0), np.float64(0.0)))

    @property
    def no_load_speed(self) -> float:
        """Output speed at d = 1 and zero torque, rad/s: Vs / Ks (29.6 for Table 1)."""
        return self.supply_voltage / self.speed_constant

    def duty(self, vpd: np.ndarray) -> np.ndarray:
        """The report's duty factor from the controller's voltage: clip(Vpd / Vs, -1, 1)."""
        return np.clip(np.asarray(vpd) / self.supply_voltage, -1.0, 1.0)

    def channel_limits(self) -> dict[str, ChannelLimit]:
        """What a log of this motor's output shaft can read (``angle``, ``speed``, ``duty``, ``current``): a speed
        within :data:`LOG_SPEED_MARGIN` times the no-load speed (and an angle that moves no faster), a duty within
        +-1, a current within what full reverse duty at that speed drives through the winding."""
        top = LOG_SPEED_MARGIN * self.no_load_speed
        speed = (f"{LOG_SPEED_MARGIN:g} x the no-load speed Vs/Ks = {self.no_load_speed:.3g} rad/s "
                 "[xjus-report, Table 1]")  # fmt: skip
        current = (self.supply_voltage + self.speed_constant * top) / self.motor_resistance
        return {
            "angle": ChannelLimit(max_rate=top, source=speed),
            "speed": ChannelLimit(-top, top, source=speed),
            "duty": ChannelLimit(-1.0, 1.0, source="the duty factor d = clip(Vpd / Vs, -1, 1) [xjus-report, sec. 2.3]"),
            "current": ChannelLimit(
                -current, current, source=f"(Vs + Ks x {top:.3g} rad/s) / Ra [xjus-report, Table 1]"
            ),
        }


class Motor:
    """The gearmotor on joints of a spec: two native actuators per joint, ``ctrl`` computed from the held duty.

    Args:
        joints: joint names in the spec.
        constants: the motor's constants (default: the report's Table 1).
        armature: rotor inertia reflected to the joint, kg m^2 (added to the joint's own).
    """

    def __init__(self, joints: Sequence[str], constants: MotorConstants | None = None, armature: float = 0.0):
        self.joints = tuple(joints)
        self.constants = constants or MotorConstants()
        self.armature = float(armature)

    def drive_name(self, joint: str) -> str:
        return f"{joint}_drive"

    def emf_name(self, joint: str) -> str:
        return f"{joint}_emf"

    def configure(self, spec: mujoco.MjSpec) -> None:
        """Add the two actuators and a joint-speed sensor per joint."""
        for joint in self.joints:
            spec.joint(joint).armature += self.armature
            for name, gain in ((self.drive_name(joint), [1.0]), (self.emf_name(joint), [0.0, 0.0, -1.0])):
                a = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
                a.gaintype = mujoco.mjtGain.mjGAIN_AFFINE if len(gain) == 3 else mujoco.mjtGain.mjGAIN_FIXED
                a.gainprm[: len(gain)] = gain
                a.biastype = mujoco.mjtBias.mjBIAS_NONE
                a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
            spec.add_sensor(
                name=f"{joint}_speed",
                type=mujoco.mjtSensor.mjSENS_JOINTVEL,
                objtype=mujoco.mjtObj.mjOBJ_JOINT,
                objname=joint,
            )

    def bind(self, model: mujoco.MjModel) -> None:
        self.drive_adr = np.array([model.actuator_ctrladr[model.actuator(self.drive_name(j)).id] for j in self.joints])
        self.emf_adr = np.array([model.actuator_ctrladr[model.actuator(self.emf_name(j)).id] for j in self.joints])
        self.speed_adr = np.array([model.sensor_adr[model.sensor(f"{j}_speed").id] for j in self.joints])

    def set_duty(self, ctrl: np.ndarray, duty: np.ndarray) -> None:
        """Hold duty (n, joints), clipped to [-1, 1], over the control block (n, substeps, nu)."""
        a, b = self.constants.coefficients(np.clip(duty, -1.0, 1.0))
        ctrl[:, :, self.drive_adr] = a[:, None, :]
        ctrl[:, :, self.emf_adr] = b[:, None, :]

    def speed(self, sensordata: np.ndarray) -> np.ndarray:
        """Output speeds, rad/s, from sensor data with any leading axes: (..., joints)."""
        return sensordata[..., self.speed_adr]
