"""The VelociRoACH robot: model, actuators, firmware and sensors. It knows nothing of tasks or rewards."""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import mujoco
import numpy as np

from envs.common.mujoco_utils import SensorHistory, quat_up_z, sensor_slices, spec_hash
from envs.velociroach import constants as C

ActionMode = Literal["duty", "gait"]

# Slots of MuJoCo's dcmotor parameters (checked against the compiler in tests/test_velociroach_model.py).
DC_GAIN_R, DC_GAIN_K = 0, 1
DC_GAIN_PID = slice(4, 8)  # kp, ki, kd, Vmax (torque-space gains)
DC_DYN_SLEW, DC_DYN_IMAX = 7, 8
CTRLSPEC_POS_VEL = 3  # mjINPUT_POS | mjINPUT_VEL
_BAD_STATE = [
    int(w)
    for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)
]


def wrap_angle(x: np.ndarray | float) -> np.ndarray | float:
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - x, 2.0 * np.pi)


class VelociRoach:
    """A VelociRoACH in a MuJoCo scene, stepped at a control rate with the physics running natively in between.

    Two ways to drive it, chosen when it is built:

    - ``duty``: the PWM duty cycle per side in [-1, 1]; the motor sees duty x battery voltage.
    - ``gait``: the robot's firmware runs a leg clock per side at a commanded stride frequency, with a commanded
      left/right phase, and a PID per side tracks it. The PID is MuJoCo's own dcmotor controller (P, I, D on the leg
      angle, back-EMF compensation, output clipped to the battery voltage) evaluated at every physics step; the clock
      is its rate-limited setpoint, advanced once per control step. No Python runs per physics step.

    Args:
        action_mode: ``"duty"`` or ``"gait"``.
        control_dt: seconds between control steps; a whole number of physics steps (0.5 ms each).
        battery_voltage: supply voltage; ``None`` takes the model's nominal 3.7 V.
        spec_edit: optional function applied to the ``MjSpec`` before it compiles (terrain, calibration effects).
    """

    def __init__(
        self,
        action_mode: ActionMode = "gait",
        control_dt: float = 0.02,
        battery_voltage: float | None = None,
        spec_edit: Callable[[mujoco.MjSpec], None] | None = None,
    ):
        if action_mode not in ("duty", "gait"):
            raise ValueError(f"action_mode must be 'duty' or 'gait', got {action_mode!r}")
        self.action_mode: ActionMode = action_mode
        spec = mujoco.MjSpec.from_file(str(C.SCENE_XML))
        timestep = spec.option.timestep
        self.n_substeps = round(control_dt / timestep)
        if self.n_substeps < 1 or abs(self.n_substeps * timestep - control_dt) > 1e-9:
            raise ValueError(f"control_dt={control_dt} s is not a whole number of {timestep} s physics steps")
        self.control_dt = self.n_substeps * timestep
        if battery_voltage is None:
            battery_voltage = float(spec.numeric(C.NUMERIC_BATTERY).data[0])
        if not battery_voltage > 0:
            raise ValueError(f"battery_voltage must be positive, got {battery_voltage}")
        self.battery_voltage = float(battery_voltage)
        self._configure(spec)
        if spec_edit is not None:
            spec_edit(spec)
        self.model = spec.compile()
        self.model_hash = spec_hash(spec)
        self.data = mujoco.MjData(self.model)
        self._lookup()
        self.phase = C.STRAIGHT_PHASE  # firmware's current left/right phase (gait mode)

    # --- building ---------------------------------------------------------------------------------------------
    def _configure(self, spec: mujoco.MjSpec) -> None:
        """Edit the nominal spec for this instance: battery, firmware, history buffers."""
        vb = self.battery_voltage
        for side in C.SIDES:
            motor = spec.actuator(C.MOTORS[side])
            motor.ctrlrange = [-vb, vb]
            if self.action_mode == "gait":
                r, k = motor.gainprm[DC_GAIN_R], motor.gainprm[DC_GAIN_K]
                gear = motor.gear[0]
                to_torque = vb * k / (r * gear)  # duty per leg radian -> motor torque per motor radian
                ki = C.PID_KI * to_torque
                motor.ctrlspec = CTRLSPEC_POS_VEL
                motor.ctrllimited = 0
                motor.gainprm[DC_GAIN_PID] = [C.PID_KP * to_torque, ki, C.PID_KD * to_torque, vb]
                motor.dynprm[DC_DYN_SLEW] = 1.0  # rewritten at every control step
                motor.dynprm[DC_DYN_IMAX] = C.PID_INTEGRAL_LIMIT * vb * k / (r * ki)
                motor.actdim = 2  # [clock (rate-limited setpoint), integral]
            # keep every physics step of a control step for power and telemetry
            for sensor in (C.SENSOR_MOTOR_TORQUE[side], C.SENSOR_MOTOR_VEL[side]):
                spec.sensor(sensor).nsample = self.n_substeps

    def _lookup(self) -> None:
        """Look up addresses once."""
        m = self.model
        self._motor_ids = np.array([m.actuator(C.MOTORS[s]).id for s in C.SIDES])
        self.gear = float(m.actuator_gear[self._motor_ids[0], 0])
        self.resistance = m.actuator_gainprm[self._motor_ids, DC_GAIN_R].copy()
        self.motor_constant = m.actuator_gainprm[self._motor_ids, DC_GAIN_K].copy()
        self._ctrl_adr = m.actuator_ctrladr[self._motor_ids].copy()
        self._act_adr = m.actuator_actadr[self._motor_ids].copy()
        self._crank_qpos = np.array([m.joint(C.CRANK_JOINTS[s]).qposadr[0] for s in C.SIDES])
        # a spec edit may clamp the body to the world (a bench test): then there is no free joint
        root = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, C.ROOT_JOINT)
        self._root_qvel = int(m.jnt_dofadr[root]) if root >= 0 else None
        self.sweep_amplitude = float(m.numeric(C.NUMERIC_SWEEP).data[0])
        self.lift_amplitude = float(m.numeric(C.NUMERIC_LIFT).data[0])
        # every joint that the linkage ties to a crank: q = q0 + c0 + c1 (crank - crank0), read off the equalities
        self._linkage = []
        for crank in self._crank_qpos:
            crank_joint = int(np.flatnonzero(m.jnt_qposadr == crank)[0])
            tied = []
            for e in range(m.neq):
                if m.eq_type[e] == mujoco.mjtEq.mjEQ_JOINT and m.eq_obj2id[e] == crank_joint:
                    q1 = int(m.jnt_qposadr[m.eq_obj1id[e]])
                    tied.append((q1, float(m.eq_data[e, 0]), float(m.eq_data[e, 1])))
            self._linkage.append(tied)
        sl = sensor_slices(m, [m.sensor(i).name for i in range(m.nsensor)])
        self.sensor_slice = sl

        def idx(*names: str) -> np.ndarray:
            return np.concatenate([np.arange(sl[n].start, sl[n].stop) for n in names])

        self._i_leg_pos = idx(*(C.SENSOR_LEG_POS[s] for s in C.SIDES))
        self._i_leg_vel = idx(*(C.SENSOR_LEG_VEL[s] for s in C.SIDES))
        self._i_motor_torque = idx(*(C.SENSOR_MOTOR_TORQUE[s] for s in C.SIDES))
        self._i_motor_vel = idx(*(C.SENSOR_MOTOR_VEL[s] for s in C.SIDES))
        self._i_imu = idx(C.SENSOR_GYRO, C.SENSOR_ACCEL)
        # what the robot senses, in one gather: leg angles, leg rates, gyro, accelerometer, motor speeds
        self._i_senses = np.concatenate(
            [self._i_leg_pos, self._i_leg_vel, self._i_imu, idx(*(C.SENSOR_MOTOR_VEL[s] for s in C.SIDES))]
        )
        self._i_pose = idx(C.SENSOR_BODY_POS, C.SENSOR_BODY_QUAT)
        self._i_body_vel = idx(C.SENSOR_BODY_VEL)
        self._i_grf = idx(*(C.SENSOR_GRF[leg] for leg in C.LEGS))
        self._history = SensorHistory(
            m,
            [C.SENSOR_MOTOR_TORQUE[s] for s in C.SIDES] + [C.SENSOR_MOTOR_VEL[s] for s in C.SIDES],
            self.n_substeps,
        )
        self.mass = float(m.body_subtreemass[m.body(C.ROOT_BODY).id])

    # --- state ------------------------------------------------------------------------------------------------
    def set_crank_angles(self, left: float, right: float) -> None:
        """Put the cranks at the given angles (rad) with every linkage joint consistent with them."""
        q, q0 = self.data.qpos, self.model.qpos0
        for tied, theta, crank in zip(self._linkage, (left, right), self._crank_qpos, strict=True):
            q[crank] = theta
            for adr, c0, c1 in tied:
                q[adr] = q0[adr] + c0 + c1 * (theta - q0[crank])

    def reset(self, crank_left: float = 0.0, phase: float = C.STRAIGHT_PHASE) -> None:
        """Reset to the home pose: tripod A (FL, BL, MR) at the bottom of its stroke when ``crank_left`` is 0, the
        right crank ``phase`` behind the left."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        self.set_crank_angles(crank_left, crank_left - phase)
        self.phase = float(phase)
        if self.action_mode == "gait":
            d.act[self._act_adr] = self.gear * d.qpos[self._crank_qpos]
            d.act[self._act_adr + 1] = 0.0
            d.ctrl[self._ctrl_adr] = d.act[self._act_adr]
            d.ctrl[self._ctrl_adr + 1] = 0.0
        mujoco.mj_forward(m, d)

    def set_body_velocity(self, linear: np.ndarray, angular: np.ndarray) -> None:
        """Set the free joint's velocity (world-frame linear, body-frame angular), e.g. to randomise a reset."""
        if self._root_qvel is None:
            raise ValueError("this robot's body is clamped to the world")
        self.data.qvel[self._root_qvel : self._root_qvel + 3] = linear
        self.data.qvel[self._root_qvel + 3 : self._root_qvel + 6] = angular
        mujoco.mj_forward(self.model, self.data)

    # --- acting -----------------------------------------------------------------------------------------------
    def command_duty(self, duty: np.ndarray) -> None:
        """PWM duty cycle per side (left, right), each in [-1, 1]."""
        self.data.ctrl[self._ctrl_adr] = np.clip(duty, -1.0, 1.0) * self.battery_voltage

    def command_gait(self, freq_left: float, freq_right: float, phase: float) -> None:
        """Advance the firmware's leg clocks over the next control step.

        Each side's clock runs at its stride frequency (Hz); the right clock trails the left by ``phase`` (rad),
        which the firmware moves toward the command at most ``PHASE_SLEW`` rad/s. With equal frequencies the offset
        between the sides is ``phase``; with different ones it drifts by 2 pi (f_left - f_right) per second.
        """
        dt = self.control_dt
        step = C.PHASE_SLEW * dt
        dphi = float(np.clip(wrap_angle(phase - self.phase), -step, step))
        self.phase += dphi
        clock = self.data.act[self._act_adr]
        advance = self.gear * np.array([2.0 * np.pi * freq_left * dt, 2.0 * np.pi * freq_right * dt - dphi])
        rate = advance / dt
        self.data.ctrl[self._ctrl_adr] = clock + advance
        self.data.ctrl[self._ctrl_adr + 1] = rate
        # a slew limit of 0 would switch the limiter (and its state) off; a standing clock gets a tiny one instead
        self.model.actuator_dynprm[self._motor_ids, DC_DYN_SLEW] = np.maximum(np.abs(rate), 1e-9)

    def step(self) -> bool:
        """Advance one control step (``n_substeps`` physics steps). Returns False if the simulation went unstable."""
        d = self.data
        before = d.warning.number[_BAD_STATE].sum()
        mujoco.mj_step(self.model, d, nstep=self.n_substeps)
        # MuJoCo counts (and resets the data on) NaN, infinite or huge positions, velocities and accelerations
        return d.warning.number[_BAD_STATE].sum() == before and np.isfinite(d.qvel).all()

    # --- sensing (values at the end of the last physics step) --------------------------------------------------
    def senses(self) -> np.ndarray:
        """Leg angles (2), leg rates (2), gyro (3), accelerometer (3), motor speeds (2), gathered at once."""
        return self.data.sensordata[self._i_senses]

    def leg_angles(self) -> np.ndarray:
        """Crank (leg) angles per side, unwrapped, rad."""
        return self.data.sensordata[self._i_leg_pos]

    def leg_velocities(self) -> np.ndarray:
        return self.data.sensordata[self._i_leg_vel]

    def commanded_leg_angles(self) -> np.ndarray:
        """The firmware clock per side (rad); NaN in duty mode, where there is no firmware clock."""
        if self.action_mode == "duty":
            return np.full(2, np.nan)
        return self.data.act[self._act_adr] / self.gear

    def imu(self) -> np.ndarray:
        """Gyro (rad/s, body frame) then accelerometer (m/s^2, body frame, +g upward at rest)."""
        return self.data.sensordata[self._i_imu]

    def back_emf(self) -> np.ndarray:
        """Motor back-EMF per side, V."""
        return self.motor_constant * self.data.sensordata[self._i_motor_vel]

    def duty(self) -> np.ndarray:
        """The duty cycle the motor driver applies per side, from terminal voltage = R i + Ke w."""
        sd = self.data.sensordata
        current = sd[self._i_motor_torque] / self.motor_constant
        volts = self.resistance * current + self.motor_constant * sd[self._i_motor_vel]
        return volts / self.battery_voltage

    def crank_torques(self) -> np.ndarray:
        """Torque each motor applies to its crank (motor torque x gear), N m."""
        return self.gear * self.data.sensordata[self._i_motor_torque]

    def electrical_power(self) -> float:
        """Mean electrical power drawn from the battery over the last control step, W, from every physics step.

        Per motor, power = terminal voltage x current, counted only when positive: the H-bridge does not return
        braking energy to the battery.
        """
        h = self._history.read(self.data)
        current = h[:, :2] / self.motor_constant
        volts = self.resistance * current + self.motor_constant * h[:, 2:]
        return float(np.maximum(volts * current, 0.0).sum()) / self.n_substeps

    def body_pose(self) -> np.ndarray:
        """World position (3) and orientation quaternion w, x, y, z (4) of the body."""
        return self.data.sensordata[self._i_pose]

    def body_velocity(self) -> np.ndarray:
        """Linear velocity of the body in its own frame, m/s."""
        return self.data.sensordata[self._i_body_vel]

    def com_position(self) -> np.ndarray:
        return self.data.subtree_com[self.model.body(C.ROOT_BODY).id]

    def ground_reaction_forces(self) -> np.ndarray:
        """Force of the ground on each leg (FL, ML, BL, FR, MR, BR), world frame, N, shape (6, 3)."""
        return -self.data.sensordata[self._i_grf].reshape(6, 3)

    def up_z(self) -> float:
        return quat_up_z(self.body_pose()[3:])

    # --- telemetry ----------------------------------------------------------------------------------------------
    def telemetry_row(self, power: float) -> np.ndarray:
        """One row of telemetry in the order of ``TELEMETRY_COLUMNS``; ``power`` is the step's mean power (W)."""
        return np.concatenate(
            [
                [self.data.time],
                self.commanded_leg_angles(),
                self.leg_angles(),
                self.duty(),
                self.crank_torques(),
                self.back_emf(),
                [self.battery_voltage],
                self.imu(),
                self.body_pose(),
                self.ground_reaction_forces().ravel(),
                [power],
            ]
        )


def _telemetry_columns() -> dict[str, str]:
    cols = {"time": "s"}
    channels = (("leg_angle_cmd", "rad"), ("leg_angle", "rad"), ("duty", "1"), ("torque", "N m"), ("bemf", "V"))
    for channel, unit in channels:
        cols.update({f"{channel}_{side}": unit for side in C.SIDES})
    cols["vbatt"] = "V"
    cols.update({f"gyro_{a}": "rad/s" for a in "xyz"})
    cols.update({f"accel_{a}": "m/s^2" for a in "xyz"})
    cols.update({f"pos_{a}": "m" for a in "xyz"})
    cols.update({f"quat_{a}": "1" for a in "wxyz"})
    cols.update({f"grf_{leg}_{a}": "N" for leg in C.LEGS for a in "xyz"})
    cols["power"] = "W"
    return cols


TELEMETRY_COLUMNS: dict[str, str] = _telemetry_columns()  # name -> unit
