"""The seed's controller in three stages (seed 001, sections 2.3 to 2.5), vectorized over simulations and legs.

1. **Buehler clock** (section 2.5): each leg's target angle over a cycle of period T, the Fourier series of a profile
   that sweeps the ground angle theta_g slowly in the first half of the cycle and the rest of the turn quickly in
   the second::

       theta_d(s) = 2 pi s + sum_{m=1..M} 4 (theta_g - pi) / ((2m-1)^2 pi^2) (1 - cos(2 pi (2m-1) s)),  s = t / T

   with M = 10. We subtract theta_g / 2 so that the slow (ground) sweep is centred on the leg pointing down, and
   start the two tripods half a cycle apart.
2. **PD** (section 2.4): the desired torque ``J (theta_d'' + kp e + kd e')`` with ``e = theta_d - theta`` (wrapped
   to a half turn: a leg only needs its angle modulo a turn), ``J`` the leg's inertia about the hip with the motor's
   reflected rotor.
3. **Motor model** (section 2.3): the voltage ``Vpd`` that makes the seed's motor give that torque at the present
   speed, ``tau = eta N Kt (d Vs - Ks w) / (Ra + d^2 Ramp)`` solved for ``d = Vpd / Vs``, then clipped to [-1, 1]
   as the seed clips it. "Combined with the motor model, this is a formal method of calculating Vpd" (section 2.4).

The robot runs these stages in its ``gait`` action mode once per control step (the seed's logic step), and the
``buehler`` policy (agents/xjus/) runs the same functions in ``duty`` mode: both hold the duty over the step while
the motor model acts at every physics step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from envs.common.locomotion import wrap
from envs.xjus import constants as C

_K = 2.0 * np.arange(1, C.FOURIER_TERMS + 1) - 1.0  # 2m - 1
_TWO_PI_K = 2.0 * np.pi * _K
# theta_d = 2 pi s + (theta_g - pi) F(s): the series' weights of F, F' and F'' on cos and sin of the harmonics
_W = 4.0 / (np.square(_K) * np.pi**2)
_W_SUM = float(_W.sum())
_W_RATE = _W * _TWO_PI_K
_W_ACCEL = _W * np.square(_TWO_PI_K)
# the three weight vectors as rows, complex, to take all three sums from the harmonics in one product
_W_ROWS = np.stack([_W, _W_RATE, _W_ACCEL]).astype(np.complex128)
wrap_angle = wrap  # to [-pi, pi], the tasks' wrap (envs/common/locomotion.py)


def _sums(s: np.ndarray) -> np.ndarray:
    """The clock's Fourier sums at ``s`` (cycles), stacked (3, ...): ``F(s) = sum W (1 - cos)``, ``F'(s)`` and
    ``F''(s)`` per cycle.

    The odd harmonics ``exp(2 pi i (2m-1) s)`` come from one complex exponential by repeated multiplication with its
    square (a cumulative product over the harmonics' axis, laid first so that each product is one array operation);
    then one matrix product weighs them for all three sums. Within 1e-12 of evaluating each harmonic directly."""
    frac = s - np.floor(s)
    z = np.exp((2j * np.pi) * frac)
    harmonics = np.empty((C.FOURIER_TERMS, *frac.shape), dtype=np.complex128)
    harmonics[0] = z
    harmonics[1:] = z * z
    np.multiply.accumulate(harmonics, axis=0, out=harmonics)
    sums = (_W_ROWS @ harmonics.reshape(C.FOURIER_TERMS, -1)).reshape(3, *frac.shape)
    out = sums.real  # a strided view, written in place: F = W_SUM - Re, F' = Im, F'' = Re
    out[0] = _W_SUM - out[0]
    out[1] = sums[1].imag
    return out


def buehler_clock(s: np.ndarray, sweep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The seed's target angle over a cycle and its first two derivatives per cycle.

    Args:
        s: the clock, in cycles (any real; the profile repeats every cycle, advancing a turn).
        sweep: ground sweep angle theta_g, rad, broadcastable against ``s``.

    Returns:
        ``theta_d(s)`` (rad), ``d theta_d / ds`` (rad per cycle) and ``d^2 theta_d / ds^2`` (rad per cycle^2). Divide
        by T and T^2 for time derivatives.
    """
    s = np.asarray(s, dtype=np.float64)
    return _clock(s, _sums(s) * (np.asarray(sweep, dtype=np.float64) - np.pi))


def _clock(s, scaled) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """theta_d = 2 pi s + (theta_g - pi) F(s) and its derivatives, from ``scaled``: :func:`_sums` times
    (theta_g - pi), stacked (3, ...)."""
    return 2.0 * np.pi * s + scaled[0], 2.0 * np.pi + scaled[1], scaled[2]


@dataclass
class Gait:
    """Where each leg's clock starts in the cycle and which side it is on.

    Attributes:
        offsets: (legs,) cycles: 0 for tripod A, 0.5 for tripod B (the alternating tripod).
        side: (legs,) 0 for a left leg, 1 for a right one (which side's sweep angle it takes).
    """

    offsets: np.ndarray
    side: np.ndarray

    def __post_init__(self) -> None:
        # legs that share an offset share their clock: its series is computed once per offset (the tripod's two)
        self._offsets, self._group = np.unique(self.offsets, return_inverse=True)

    @classmethod
    def tripod(cls) -> Gait:
        offsets = np.array([0.0 if leg in C.TRIPOD_A else 0.5 for leg in C.LEGS])
        side = np.array([0 if leg in C.LEFT_LEGS else 1 for leg in C.LEGS])
        return cls(offsets, side)

    def targets(
        self, phase: np.ndarray, period: np.ndarray, sweep: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Target leg angles (rad), rates (rad/s) and accelerations (rad/s^2), (n, legs).

        Args:
            phase: (n,) the clock, cycles since tripod A began its stance.
            period: (n,) the cycle period T, s.
            sweep: (n, 2) the ground sweep angle of the left and right legs, rad.
        """
        s = phase[:, None] + self._offsets  # per offset; gathered to the legs, the same numbers as per leg
        leg_sweep = sweep[:, self.side]
        angle, rate, accel = _clock(s[:, self._group], _sums(s)[:, :, self._group] * (leg_sweep - np.pi))
        inv_t = 1.0 / period[:, None]
        return angle - 0.5 * leg_sweep, rate * inv_t, accel * np.square(inv_t)


@dataclass
class MotorArrays:
    """The seed's motor constants per simulation, (n,) each (Table 1 nominal; randomized or calibrated per
    simulation). ``torque_per_amp`` is eta N Kt at the output shaft."""

    supply_voltage: np.ndarray
    motor_resistance: np.ndarray
    amplifier_resistance: np.ndarray
    torque_per_amp: np.ndarray
    speed_constant: np.ndarray

    def coefficients(self, duty: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(A, B), (n, legs), with torque = A - B x speed at a held duty (n, legs): the shared motor's formula
        (envs/actuators/motor.py) with per-simulation constants."""
        c = self.torque_per_amp[:, None] / (
            self.motor_resistance[:, None] + np.square(duty) * self.amplifier_resistance[:, None]
        )
        return c * duty * self.supply_voltage[:, None], c * self.speed_constant[:, None]

    def duty_for_torque(self, torque: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """The duty ``d = Vpd / Vs`` at which the motor gives ``torque`` (n, legs) at ``speed`` (n, legs), clipped to
        [-1, 1]: the root of ``tau (Ra + d^2 Ramp) = c (d Vs - Ks w)`` that is continuous through tau = 0; where no
        duty reaches the torque, full duty toward it."""
        vs = self.supply_voltage[:, None]
        c = self.torque_per_amp[:, None]
        a = torque * self.amplifier_resistance[:, None] / np.square(vs)  # in V^-1 ... x V^2
        b = torque * self.motor_resistance[:, None] + c * self.speed_constant[:, None] * speed
        disc = np.square(c) - 4.0 * a * b
        voltage = 2.0 * b / (c + np.sqrt(np.maximum(disc, 0.0)))  # the maximum: the unreachable are replaced below
        duty = voltage / vs
        reachable = disc >= 0.0
        if not reachable.all():
            duty = np.where(reachable, duty, np.sign(torque))
        return np.minimum(np.maximum(duty, -1.0), 1.0)  # np.clip's result, at a third of its overhead

    def current(self, duty: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Motor current, A, at a held duty and a speed (broadcast)."""
        r = self.motor_resistance[:, None] + np.square(duty) * self.amplifier_resistance[:, None]
        return (duty * self.supply_voltage[:, None] - self.speed_constant[:, None] * speed) / r


def pd_torque(
    error: np.ndarray, rate_error: np.ndarray, accel: np.ndarray, inertia: np.ndarray, kp: float, kd: float
) -> np.ndarray:
    """The seed's PD (section 2.4): J (theta_d'' + kp e + kd e'), N m."""
    return inertia * (accel + kp * error + kd * rate_error)


def stand_targets(n: int, legs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stand routine: every leg pointing down, at rest."""
    zero = np.zeros((n, legs))
    return zero, zero, zero
