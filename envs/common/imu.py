"""An inertial measurement unit's errors: white noise per sample and a bias per episode, as its datasheet gives them.

The robots read their IMU in firmware at ``sample_rate``; a control step sees the newest sample, and a heading
estimate integrates the z-axis gyro over every physics step, as firmware integrating at its own rate would (the
body's z rate, not the world's yaw rate: the firmware has no attitude estimate). The bias is what remains after the
firmware's start-up calibration (averaging the gyro at rest), so the integral drifts by ``bias x time``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ImuNoise:
    """Noise densities and residual biases of an IMU.

    Defaults: the InvenSense MPU-6000 of the VelociRoACH's ImageProc 2.5 board (shared/data/real/README.md), from
    its product specification (PS-MPU-6000A rev. 3.4): gyro rate noise spectral density 0.005 deg/s/sqrt(Hz),
    accelerometer noise power spectral density 400 ug/sqrt(Hz). The gyro's zero-rate output varies by +-20 deg/s
    over -40..85 C (0.16 deg/s per C); the residual bias after a start-up calibration, with a few degrees of warm-up,
    is taken as 0.5 deg/s per axis (1 sigma, assumed: the datasheet gives the temperature slope, not the warm-up).
    """

    gyro_noise_density: float = math.radians(0.005)  # rad/s/sqrt(Hz)
    gyro_bias_sigma: float = math.radians(0.5)  # rad/s, per axis, drawn once per episode
    accel_noise_density: float = 400e-6 * 9.81  # m/s^2/sqrt(Hz)
    sample_rate: float = 1000.0  # Hz: the firmware's read rate

    @property
    def gyro_sample_sigma(self) -> float:
        """Standard deviation of one gyro sample's noise, rad/s (white noise over the Nyquist band)."""
        return self.gyro_noise_density * math.sqrt(self.sample_rate / 2.0)

    @property
    def accel_sample_sigma(self) -> float:
        return self.accel_noise_density * math.sqrt(self.sample_rate / 2.0)


NOISE_BLOCK = 128  # control steps of noise drawn at once per simulation (one generator call instead of 128)


class Imu:
    """Noisy gyro and accelerometer readings and an integrated-gyro heading, for ``n`` simulations.

    Each simulation's noise comes from its own generator, drawn a block of ``NOISE_BLOCK`` steps at a time (at reset,
    and again when a block is used up), so that a simulation's random stream is the same whether it runs alone or in
    a batch, at a fraction of the cost of a generator call per simulation and step.

    Args:
        n: number of simulations.
        noise: the error model, or None for a perfect IMU.
        step_time: the control step, s (the heading's random walk accumulates over it).
        substep_time: the physics step, s (the heading integrates the gyro at every one).
    """

    def __init__(self, n: int, noise: ImuNoise | None, step_time: float, substep_time: float):
        self.noise = noise
        self.gyro_bias = np.zeros((n, 3))
        self.heading = np.zeros(n)
        self._bias = np.zeros((n, 6))  # gyro bias, then zeros for the accelerometer
        self._bias_step = np.zeros(n)  # the heading the z bias adds over a control step
        self._step_time, self._substep_time = step_time, substep_time
        self._rows = np.arange(n)
        if noise is not None:
            walk = noise.gyro_noise_density * math.sqrt(step_time)  # the heading's random walk over a step
            self._scale = np.array([noise.gyro_sample_sigma] * 3 + [noise.accel_sample_sigma] * 3 + [walk])
            self._block = np.zeros((n, NOISE_BLOCK + 1, 7))  # a spare row of zeros past the end
            self._next = np.full(n, NOISE_BLOCK)
            # steps every simulation's block surely has left: until they are taken, _draw checks no block (each
            # step takes at most one row; a reset only adds rows)
            self._rows_left = 0

    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator]) -> None:
        self.heading[ids] = 0.0
        if self.noise is None:
            return
        for i, rng in zip(ids, rngs, strict=True):
            self.gyro_bias[i] = rng.normal(0.0, self.noise.gyro_bias_sigma, 3)
            self._block[i, :NOISE_BLOCK] = rng.standard_normal((NOISE_BLOCK, 7)) * self._scale
            self._next[i] = 0
        self._bias[:, :3] = self.gyro_bias
        self._bias_step = self.gyro_bias[:, 2] * self._step_time

    def _draw(self, rngs: Sequence[np.random.Generator | None]) -> np.ndarray:
        """This step's noise (n, 7): gyro and accelerometer sample noise, and the heading's random walk. A simulation
        whose generator is None draws nothing (its row is not used)."""
        if self._rows_left <= 0:
            for i in np.flatnonzero(self._next >= NOISE_BLOCK):
                if rngs[i] is not None:
                    self._block[i, :NOISE_BLOCK] = rngs[i].standard_normal((NOISE_BLOCK, 7)) * self._scale
                    self._next[i] = 0
            self._rows_left = NOISE_BLOCK - int(self._next.max())
        self._rows_left -= 1
        if len(self._rows) == 1:  # one simulation: its row by basic indexing, a view at a third of a gather's cost
            draws = self._block[:, int(self._next[0])]
        else:
            draws = self._block[self._rows, self._next]  # a used-up block that draws nothing reads its row of zeros
        if None in rngs:
            self._next += np.array([r is not None for r in rngs])
        else:
            self._next += 1
        return draws

    def update(
        self,
        imu: np.ndarray,
        gyro_z: np.ndarray,
        rngs: Sequence[np.random.Generator | None],
        stepped: bool | np.ndarray = True,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Noisy gyro and accelerometer (n, 6) from the true ones (n, 6), after advancing the heading over a control
        step from the true z rate at every physics step (``gyro_z``, (n, substeps)); only where ``stepped`` (False,
        or False per simulation, right after a reset). ``out``: where to write them (a robot's senses), else a new
        array."""
        if self.noise is not None:
            draws = self._draw(rngs)
        if stepped is not False:
            change = gyro_z.sum(axis=1) * self._substep_time + self._bias_step
            if self.noise is not None:
                change += draws[:, 6]
            self.heading += change if stepped is True else np.where(stepped, change, 0.0)
        if self.noise is None:
            if out is None:
                return imu.copy()
            out[...] = imu
            return out
        out = np.add(imu, self._bias, out=out)
        out += draws[:, :6]
        return out
