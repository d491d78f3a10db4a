"""The report's controller in three stages [xjus-report, sections 2.3 to 2.5], vectorized over simulations and legs.

1. **Buehler clock** (section 2.5): each leg's target angle over a cycle of period T, the Fourier series of a profile
   that sweeps the ground angle theta_g slowly in the first half of the cycle and the rest of the turn quickly in
   the second::

       theta_d(s) = 2 pi s + sum_{m=1..M} 4 (theta_g - pi) / ((2m-1)^2 pi^2) (1 - cos(2 pi (2m-1) s)),  s = t / T

   with M = 10. We subtract theta_g / 2 so that the slow (ground) sweep is centred on the leg pointing down, and
   start the two tripods half a cycle apart.
2. **PD** (section 2.4): the desired torque ``J (theta_d'' + kp e + kd e')`` with ``e = theta_d - theta`` (wrapped
   to a half turn: a leg only needs its angle modulo a turn), ``J`` the leg's inertia about the hip with the motor's
   reflected rotor.
3. **Motor model** (section 2.3): the voltage ``Vpd`` that makes the report's motor give that torque at the present
   speed, ``tau = eta N Kt (d Vs - Ks w) / (Ra + d^2 Ramp)`` solved for ``d = Vpd / Vs``, then clipped to [-1, 1]
   as the report clips it. "Combined with the motor model, this is a formal method of calculating Vpd" (section 2.4).

The robot runs these stages in its ``gait`` action mode once per control step (the report's logic step), and the
``buehler`` policy (agents/xjus/) runs the same functions in ``duty`` mode: both hold the duty over the step while
the motor model acts at every physics step.

One simulation (the single env, a policy's single observation) runs the ``*_one`` twins of these functions: the same
operations in the same order on Python floats, the clock's exponential, powers and weights by the same numpy calls on
arrays of the same shape, so that it gets the same numbers to the last bit. numpy's cost per call on arrays of one row
is that of some twenty float operations, and a control step makes some eighty calls. The twins take moderate values
only (:func:`moderate`): NaN would take other branches, and overflows other paths.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from envs.common.locomotion import wrap, wrap_one
from envs.xjus import constants

_K = 2.0 * np.arange(1, constants.FOURIER_TERMS + 1) - 1.0  # 2m - 1
_TWO_PI_K = 2.0 * np.pi * _K
# theta_d = 2 pi s + (theta_g - pi) F(s): the series' weights of F, F' and F'' on cos and sin of the harmonics
_W = 4.0 / (np.square(_K) * np.pi**2)
_W_SUM = float(_W.sum())
_W_RATE = _W * _TWO_PI_K
_W_ACCEL = _W * np.square(_TWO_PI_K)
# the three weight vectors as rows, complex, to take all three sums from the harmonics in one product
_W_ROWS = np.stack([_W, _W_RATE, _W_ACCEL]).astype(np.complex128)
_TWO_PI = 2.0 * np.pi
wrap_angle = wrap  # to [-pi, pi], the tasks' wrap (envs/common/locomotion.py)
wrap_angle_one = wrap_one


_MODERATE = 1e100  # no product or sum of the controller's quantities below this overflows


def moderate(*values: float) -> bool:
    """Whether all values are finite and of magnitude below 1e100: what the ``*_one`` functions take."""
    return math.hypot(*values) < _MODERATE


def _sums(s: np.ndarray) -> np.ndarray:
    """The clock's Fourier sums at ``s`` (cycles), stacked (3, ...): ``F(s) = sum W (1 - cos)``, ``F'(s)`` and
    ``F''(s)`` per cycle.

    The odd harmonics ``exp(2 pi i (2m-1) s)`` come from one complex exponential by repeated multiplication with its
    square (a cumulative product over the harmonics' axis, laid first so that each product is one array operation);
    then one matrix product weighs them for all three sums. Within 1e-12 of evaluating each harmonic directly."""
    frac = s - np.floor(s)
    sums = _weighted_harmonics(np.exp((2j * np.pi) * frac))
    out = sums.real  # a strided view, written in place: F = W_SUM - Re, F' = Im, F'' = Re
    out[0] = _W_SUM - out[0]
    out[1] = sums[1].imag
    return out


def _weighted_harmonics(z: np.ndarray) -> np.ndarray:
    """The three weighted sums of the odd powers of ``z = exp(2 pi i s)``, complex, (3, ...): the part of
    :func:`_sums` after the exponential."""
    harmonics = np.empty((constants.FOURIER_TERMS, *z.shape), dtype=np.complex128)
    harmonics[0] = z
    harmonics[1:] = z * z
    np.multiply.accumulate(harmonics, axis=0, out=harmonics)
    return (_W_ROWS @ harmonics.reshape(constants.FOURIER_TERMS, -1)).reshape(3, *z.shape)


def buehler_clock(s: np.ndarray, sweep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The report's target angle over a cycle and its first two derivatives per cycle.

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
        self._offsets_one = self._offsets.tolist()
        self._legs_one = list(zip(self._group.tolist(), self.side.tolist(), strict=True))  # (offset, side) per leg

    @classmethod
    def tripod(cls) -> Gait:
        offsets = np.array([0.0 if leg in constants.TRIPOD_A else 0.5 for leg in constants.LEGS])
        side = np.array([0 if leg in constants.LEFT_LEGS else 1 for leg in constants.LEGS])
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
        if phase.shape == period.shape == (1,) and sweep.shape == (1, 2):  # one simulation: the float twin
            p, t, sw = phase.item(), period.item(), sweep[0].tolist()
            if moderate(p, t, *sw):
                try:
                    return tuple(np.array([x]) for x in self.targets_one(p, t, sw))
                except ZeroDivisionError:  # a period of 0 (numpy: inf and NaN)
                    pass
        s = phase[:, None] + self._offsets  # per offset; gathered to the legs, the same numbers as per leg
        leg_sweep = sweep[:, self.side]
        angle, rate, accel = _clock(s[:, self._group], _sums(s)[:, :, self._group] * (leg_sweep - np.pi))
        inv_t = 1.0 / period[:, None]
        return angle - 0.5 * leg_sweep, rate * inv_t, accel * np.square(inv_t)

    def targets_one(
        self, phase: float, period: float, sweep: Sequence[float]
    ) -> tuple[list[float], list[float], list[float]]:
        """:meth:`targets` of one simulation on Python floats (phase and period floats, sweep left and right; moderate
        values): the same numbers, as lists over the legs."""
        s = [phase + offset for offset in self._offsets_one]
        # _sums' steps: the exponent 2 pi i (s - floor(s)) as numpy's product of 2j pi and a real forms it (a zero
        # real part; x % 1.0 is s - floor(s), -0.0 included), the powers and weights by the same numpy calls on an
        # array of the same shape, F, F' and F'' taken from them as _sums takes them
        z = np.exp(np.array([[complex(0.0, _TWO_PI * (x % 1.0)) for x in s]]))
        sums = _weighted_harmonics(z)[:, 0].tolist()
        f = [_W_SUM - c.real for c in sums[0]]
        f_rate = [c.imag for c in sums[1]]
        f_accel = [c.real for c in sums[2]]
        inv_t = 1.0 / period
        inv_t2 = inv_t * inv_t
        angle, rate, accel = [], [], []
        for k, side in self._legs_one:
            leg_sweep = sweep[side]
            amplitude = leg_sweep - np.pi
            angle.append(_TWO_PI * s[k] + f[k] * amplitude - 0.5 * leg_sweep)
            rate.append((_TWO_PI + f_rate[k] * amplitude) * inv_t)
            accel.append(f_accel[k] * amplitude * inv_t2)
        return angle, rate, accel


@dataclass
class MotorArrays:
    """The report's motor constants per simulation, (n,) each (Table 1 nominal; randomized or calibrated per
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
        if torque.shape == speed.shape == (1, torque.shape[-1]) and len(self.supply_voltage) == 1:  # the float twin
            t, w = torque[0].tolist(), speed[0].tolist()
            if moderate(*t, *w):
                try:
                    return np.array([self.duty_for_torque_one(t, w)])
                except ZeroDivisionError:  # a supply voltage of 0 (numpy: inf and NaN)
                    pass
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

    def constants_one(self) -> tuple[float, float, float, float, float]:
        """Supply voltage, Ra, Ramp, torque per amp and Ks of a single simulation (arrays of one row), as floats."""
        return (self.supply_voltage.item(), self.motor_resistance.item(), self.amplifier_resistance.item(),
                self.torque_per_amp.item(), self.speed_constant.item())  # fmt: skip

    def duty_for_torque_one(self, torque: Sequence[float], speed: Sequence[float]) -> list[float]:
        """:meth:`duty_for_torque` of a single simulation on Python floats (torque and speed per leg, moderate values):
        the same numbers."""
        vs, ra, ramp, c, ks = self.constants_one()
        vs2, c2, cks = vs * vs, c * c, c * ks
        duties = []
        for t, w in zip(torque, speed, strict=True):
            a = t * ramp / vs2
            b = t * ra + cks * w
            disc = c2 - 4.0 * a * b
            if disc >= 0.0:  # c + sqrt(max(disc, 0)): +-0 alike
                duty = 2.0 * b / (c + math.sqrt(disc)) / vs
                duties.append(-1.0 if duty < -1.0 else 1.0 if duty > 1.0 else duty)
            else:  # unreachable (or NaN constants): full duty toward the torque, np.sign's
                duties.append(1.0 if t > 0.0 else -1.0 if t < 0.0 else 0.0)
        return duties

    def coefficients_one(self, duty: Sequence[float]) -> tuple[list[float], list[float]]:
        """:meth:`coefficients` of a single simulation on Python floats (duty per leg, moderate values): the same
        numbers."""
        vs, ra, ramp, c, ks = self.constants_one()
        a, b = [], []
        for d in duty:
            k = c / (ra + d * d * ramp)
            a.append(k * d * vs)
            b.append(k * ks)
        return a, b

    def current(self, duty: np.ndarray, speed: np.ndarray) -> np.ndarray:
        """Motor current, A, at a held duty and a speed (broadcast)."""
        r = self.motor_resistance[:, None] + np.square(duty) * self.amplifier_resistance[:, None]
        return (duty * self.supply_voltage[:, None] - self.speed_constant[:, None] * speed) / r


def pd_torque(
    error: np.ndarray, rate_error: np.ndarray, accel: np.ndarray, inertia: np.ndarray, kp: float, kd: float
) -> np.ndarray:
    """The report's PD (section 2.4): J (theta_d'' + kp e + kd e'), N m."""
    return inertia * (accel + kp * error + kd * rate_error)


def stand_targets(n: int, legs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stand routine: every leg pointing down, at rest."""
    zero = np.zeros((n, legs))
    return zero, zero, zero
