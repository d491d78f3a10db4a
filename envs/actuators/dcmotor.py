"""DC motors on MuJoCo's native ``dcmotor`` actuator, driven by a PWM duty cycle or by an on-board PID.

MuJoCo's dcmotor (MuJoCo 4.0) is a brushed DC motor with back-EMF: torque ``K i``, current ``i = (v - K w) / R`` for
terminal voltage ``v`` and motor speed ``w`` (both at the motor shaft, the joint seeing ``gear`` times the torque).
Two ways to drive it here, both through ``ctrl`` only:

- **voltage**: ``ctrl = duty x supply voltage``, held over each physics step of a control block.
- **pid**: the motor's on-board controller tracks setpoints given per physics step (a firmware's clock ramps within
  a control step). MuJoCo's controller commands torque ``kp e + ki x_I + kd (u_vel - l')`` in motor-shaft units and
  drives ``v = (R/K) torque + K l'`` clipped to ``Vmax``. Firmware gains are written here as a voltage-mode
  controller writes them, in duty (fraction of the supply voltage) per radian at the joint, and converted. With
  ``compensate_back_emf=False`` a ``K^2/R`` added to the derivative gain cancels MuJoCo's back-EMF compensation, which
  leaves a plain voltage-mode controller, ``v = supply x clip(duty)``: what a hobby servo's amplifier does, and what
  a firmware's PWM PID does, ``duty = kp e + ki int(e) + kd (v_cmd - w) + ff``. Its velocity setpoint and constant
  feed-forward go through the controller's feed-forward input, ``-(K^2/R) u_vel + (K/R) supply ff`` (written with the
  setpoints at every physics step), which cancels what the extra ``K^2/R`` adds to the setpoint's term.
  A supply that changes during an episode (a sagging battery) changes those gains: :meth:`DCMotors.supply_gains`
  gives them for any supply, for a robot to write between control blocks (the model's only writes in an episode).

Electrical readouts come from the motor's torque and speed sensors (``actuatorfrc``, ``actuatorvel``) at every
physics step. The H-bridge returns no braking energy to the supply: battery power is ``max(v i, 0)`` per motor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from envs.common.parameters import FieldRef

# actuator_ctrlspec bits of a dcmotor's inputs (checked against the compiler in tests/test_actuators.py)
INPUT_POS, INPUT_VEL, INPUT_FF, INPUT_VOLTAGE = 1, 2, 4, 8
# where the compiler keeps a dcmotor's constants and controller (checked likewise)
GAIN_R, GAIN_K = 0, 1
GAIN_KP, GAIN_KI, GAIN_KD, GAIN_VMAX = 4, 5, 6, 7
# the controller's slots that follow the supply voltage, in the order :meth:`DCMotors.supply_gains` gives them
SUPPLY_SLOTS = np.array([GAIN_KP, GAIN_KI, GAIN_KD, GAIN_VMAX])
DYN_SLEW, DYN_IMAX = 7, 8


@dataclass(frozen=True)
class PIDGains:
    """A firmware's PID in its own terms: duty per unit of joint error.

    Attributes:
        kp: duty per rad of position error.
        ki: duty per (rad s) of integrated error.
        kd: duty per rad/s of velocity error.
        feedforward: constant duty added to the output (a firmware's ``ff``; voltage mode only).
        integral_limit: bound of the integral term, in duty (0: unbounded).
        velocity_setpoint: the firmware also sends a velocity setpoint (inputs ``pos vel``); else ``pos`` only.
        compensate_back_emf: keep MuJoCo's back-EMF compensation (a current-mode driver); False: plain voltage mode.
        max_duty: bound of the controller's output, a fraction of the supply voltage.
    """

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    feedforward: float = 0.0
    integral_limit: float = 0.0
    velocity_setpoint: bool = True
    compensate_back_emf: bool = True
    max_duty: float = 1.0

    def __post_init__(self) -> None:
        if self.compensate_back_emf and self.feedforward:
            raise ValueError("a constant feed-forward duty needs the plain voltage mode (compensate_back_emf=False)")
        if not 0 < self.max_duty <= 1:
            raise ValueError(f"max_duty must be in (0, 1], got {self.max_duty}")


class DCMotors:
    """A group of dcmotor actuators of a spec, configured for one drive mode.

    Args:
        actuators: names of ``dcmotor`` actuators in the spec (their R, K and gear come from the MJCF).
        supply_voltage: nominal supply (battery) voltage, V.
        pid: the on-board controller's gains, or None to drive the motors by duty cycle.
    """

    def __init__(self, actuators: Sequence[str], supply_voltage: float, pid: PIDGains | None = None):
        self.names = tuple(actuators)
        self.supply_voltage = float(supply_voltage)
        self.pid = pid

    @property
    def mode(self) -> str:
        return "voltage" if self.pid is None else "pid"

    @property
    def feeds_forward(self) -> bool:
        """Whether the controller takes the feed-forward input (a voltage-mode PID with a velocity setpoint or a
        constant feed-forward duty)."""
        g = self.pid
        return g is not None and not g.compensate_back_emf and (g.velocity_setpoint or g.feedforward != 0.0)

    def derivative_gain(
        self, supply: ArrayLike, resistance: ArrayLike, constant: ArrayLike, gear: ArrayLike
    ) -> ArrayLike:
        """The controller's derivative gain in motor-shaft units for a supply (V) and the motor's R, K and gear:
        the duty's ``kd`` converted, plus ``K^2/R`` where the back-EMF compensation is cancelled (numbers or arrays).
        It is not a product of the supply, R and K, so it is computed, not scaled, when they change."""
        g = self.pid
        to_torque = supply * constant / (resistance * gear)  # duty per joint radian -> motor torque per motor radian
        return g.kd * to_torque + (0.0 if g.compensate_back_emf else constant * constant / resistance)

    def configure(self, spec: mujoco.MjSpec) -> None:
        """Set the inputs and controller of every motor in the spec."""
        vs = self.supply_voltage
        for name in self.names:
            a = spec.actuator(name)
            a.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE  # duty is clipped in code; setpoints are unbounded
            if self.pid is None:
                a.ctrlspec = INPUT_VOLTAGE
                continue
            r, k, gear = a.gainprm[GAIN_R], a.gainprm[GAIN_K], a.gear[0]
            to_torque = vs * k / (r * gear)  # duty per joint radian -> motor torque per motor radian
            g = self.pid
            kd = self.derivative_gain(vs, r, k, gear)
            ki = g.ki * to_torque
            a.ctrlspec = INPUT_POS | (INPUT_VEL if g.velocity_setpoint else 0) | (INPUT_FF if self.feeds_forward else 0)
            a.gainprm[GAIN_KP] = g.kp * to_torque
            a.gainprm[GAIN_KI] = ki
            a.gainprm[GAIN_KD] = kd
            a.gainprm[GAIN_VMAX] = g.max_duty * vs
            a.dynprm[DYN_SLEW] = 0.0  # setpoints come per physics step: no slew limiter, no setpoint state
            a.dynprm[DYN_IMAX] = g.integral_limit * vs * k / (r * ki) if ki > 0 and g.integral_limit > 0 else 0.0
            a.actdim = 1 if ki > 0 else 0

    def bind(self, model: mujoco.MjModel, num_sims: int = 1) -> None:
        """Look up the compiled motors; their constants are kept per simulation, (num_sims, motors)."""
        self.ids = np.array([model.actuator(n).id for n in self.names])
        self.ctrl_adr = model.actuator_ctrladr[self.ids].copy()
        self.act_adr = model.actuator_actadr[self.ids].copy()
        self.gear = model.actuator_gear[self.ids, 0].copy()
        self._pos, self._vel = _as_index(self.ctrl_adr), _as_index(self.ctrl_adr + 1)
        # the inputs lie in ctrl in the order pos, vel, ff
        velocity = self.pid is not None and self.pid.velocity_setpoint
        self._ff = _as_index(self.ctrl_adr + (2 if velocity else 1)) if self.feeds_forward else None
        self.resistance = np.zeros((num_sims, len(self.ids)))
        self.motor_constant = np.zeros((num_sims, len(self.ids)))
        self._power_coefficient = np.zeros((num_sims, len(self.ids)))
        # the feed-forward input's factors, K/R and K^2/R, taken with R and K rather than at every step
        self._k_over_r = np.zeros((num_sims, len(self.ids)))
        self._k2_over_r = np.zeros((num_sims, len(self.ids)))
        # the controller's supply-following gains (supply_gains) per volt and at no volt, (num_sims, motors, 4)
        self._per_volt = np.zeros((num_sims, len(self.ids), 4))
        self._at_no_volt = np.zeros((num_sims, len(self.ids), 4))
        self.refresh(
            np.arange(num_sims), np.broadcast_to(model.actuator_gainprm, (num_sims, *model.actuator_gainprm.shape))
        )

    def refresh(self, ids: np.ndarray, gainprm: np.ndarray) -> None:
        """Take the motors' R and K of simulations ``ids`` from their gain parameters (num_sims, nu, 10)."""
        self.resistance[ids] = gainprm[ids][:, self.ids, GAIN_R]
        self.motor_constant[ids] = gainprm[ids][:, self.ids, GAIN_K]
        k = self.motor_constant[ids]
        r = self.resistance[ids]
        self._power_coefficient[ids] = r / (k * k)  # v i = R tau^2 / K^2 + w tau
        self._k_over_r[ids] = k / r
        self._k2_over_r[ids] = k * k / r
        g = self.pid
        if g is not None:  # supply_gains: affine in the supply, per simulation and motor
            to_torque = self._k_over_r[ids] / self.gear  # per volt of supply
            kd_at_no_volt = self.derivative_gain(0.0, r, k, self.gear)
            kd_per_volt = self.derivative_gain(1.0, r, k, self.gear) - kd_at_no_volt
            self._per_volt[ids] = np.stack([g.kp * to_torque, g.ki * to_torque, kd_per_volt,
                                            np.full_like(to_torque, g.max_duty)], axis=-1)  # fmt: skip
            self._at_no_volt[ids, :, 2] = kd_at_no_volt

    def supply_gains(self, supply: np.ndarray) -> np.ndarray:
        """PID mode: the controller's torque-space gains and output bound for the supplies ``supply`` (num_sims,) V
        and each simulation's R and K, as :meth:`configure` writes them for its nominal supply: (num_sims, motors, 4)
        in the order of :data:`SUPPLY_SLOTS` (kp, ki, kd, Vmax). Affine in the supply; the integral's bound, in
        motor-shaft units, does not depend on it."""
        return self._per_volt * np.asarray(supply, dtype=np.float64)[:, None, None] + self._at_no_volt

    # --- commands into the control block ------------------------------------------------------------------------
    def set_duty(self, ctrl: np.ndarray, duty: np.ndarray, supply: np.ndarray) -> None:
        """Voltage mode: hold duty (n, motors), clipped to [-1, 1], times the supply (n,) over the whole block."""
        ctrl[:, :, self._pos] = (np.minimum(np.maximum(duty, -1.0), 1.0) * supply[:, None])[:, None, :]

    def set_setpoints(self, ctrl: np.ndarray, position: np.ndarray, velocity: np.ndarray | None = None,
                      supply: np.ndarray | None = None) -> None:  # fmt: skip
        """PID mode: joint-angle setpoints (n, substeps, motors) in rad and, with a velocity input, their rates; a
        voltage-mode PID that feeds forward also takes the supply (n,), V."""
        ctrl[:, :, self._pos] = position * self.gear
        motor_rate = None
        if self.pid is not None and self.pid.velocity_setpoint:
            motor_rate = velocity * self.gear
            ctrl[:, :, self._vel] = motor_rate
        if self.feeds_forward:
            self._feed_forward(ctrl, motor_rate, supply)

    def set_ramps(self, ctrl: np.ndarray, start: np.ndarray, rate: np.ndarray, times: np.ndarray,
                  supply: np.ndarray | None = None) -> None:  # fmt: skip
        """PID mode: setpoints that ramp from ``start`` (n, motors) at ``rate`` (rad/s), sampled at ``times`` (s from
        the block's start, one per physics step, shaped (1, substeps, 1)), with ``rate`` as the velocity setpoint; a
        voltage-mode PID that feeds forward also takes the supply (n,), V."""
        g = self.gear
        motor_rate = (rate * g)[:, None, :]
        ramp = np.multiply(motor_rate, times)
        ramp += (start * g)[:, None, :]
        ctrl[:, :, self._pos] = ramp
        if self.pid is not None and self.pid.velocity_setpoint:
            ctrl[:, :, self._vel] = motor_rate
        if self.feeds_forward:
            self._feed_forward(ctrl, motor_rate if self.pid.velocity_setpoint else None, supply)

    def _feed_forward(self, ctrl: np.ndarray, motor_rate: np.ndarray | None, supply: np.ndarray | None) -> None:
        """The feed-forward input of a voltage-mode PID: ``-(K^2/R) u_vel``, which cancels the ``K u_vel`` that the
        derivative gain's ``K^2/R`` adds, plus the constant duty as a torque, ``(K/R) supply ff``."""
        if supply is None:
            raise ValueError("a voltage-mode PID that feeds forward needs the supply voltage with its setpoints")
        n = ctrl.shape[0]
        volts = np.asarray(supply, dtype=np.float64)[:, None] * self.pid.feedforward
        ff = np.broadcast_to((self._k_over_r * volts)[:, None, :], (n, ctrl.shape[1], len(self.ids)))
        if motor_rate is not None:
            ff = ff - self._k2_over_r[:, None, :] * motor_rate
        ctrl[:, :, self._ff] = ff

    # --- electrical readouts from motor torque and speed: (num_sims, motors) or (num_sims, substeps, motors) -------
    @staticmethod
    def _per_sim(constant: np.ndarray, like: np.ndarray) -> np.ndarray:
        return constant if like.ndim == 2 else constant[:, None, :]

    def current(self, torque: np.ndarray) -> np.ndarray:
        """Winding current, A, from the motor-shaft torque (N m)."""
        return torque / self._per_sim(self.motor_constant, torque)

    def terminal_voltage(self, torque: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Voltage across the motor, V: R i + K w."""
        k = self._per_sim(self.motor_constant, torque)
        return self._per_sim(self.resistance, torque) * (torque / k) + k * speed

    def battery_power(self, torque: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Power drawn from the supply per motor, W; braking energy is not returned (max(v i, 0))."""
        return np.maximum((self._per_sim(self._power_coefficient, torque) * torque + speed) * torque, 0.0)

    # --- parameters ---------------------------------------------------------------------------------------------
    def supply_fields(self) -> tuple[FieldRef, ...]:
        """Model fields that scale with the supply voltage: the PID's torque-space gains (duty x supply) and its
        output bound (the derivative term of a cancelled back-EMF compensation does not scale)."""
        if self.pid is None:
            return ()
        # the derivative gain of a cancelled compensation: kd supply K / (R gear) + K^2/R, computed by the robot
        # (derivative_gain) when the supply changes, not scaled
        slots = [GAIN_KP, GAIN_KI, GAIN_VMAX] + ([GAIN_KD] if self.pid.compensate_back_emf else [])
        return tuple(FieldRef("actuator_gainprm", (self.ids, slot), "scale") for slot in slots)


def _as_index(addresses: np.ndarray) -> slice | np.ndarray:
    """Evenly spaced addresses as a slice (basic indexing is several times faster than a gather), else as given."""
    if len(addresses) > 1 and len(set(np.diff(addresses))) == 1 and addresses[1] > addresses[0]:
        return slice(int(addresses[0]), int(addresses[-1]) + 1, int(addresses[1] - addresses[0]))
    if len(addresses) == 1:
        return slice(int(addresses[0]), int(addresses[0]) + 1)
    return addresses
