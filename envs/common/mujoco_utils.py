"""Small helpers around MuJoCo shared by the robots."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import mujoco
import numpy as np


def sensor_slices(model: mujoco.MjModel, names: Sequence[str]) -> dict[str, slice]:
    """Map sensor names to their slices of ``data.sensordata``, looked up once."""
    out = {}
    for name in names:
        sensor = model.sensor(name)
        adr, dim = int(sensor.adr[0]), int(sensor.dim[0])
        out[name] = slice(adr, adr + dim)
    return out


class SensorHistory:
    """The last ``k`` physics-step samples of scalar sensors that keep a MuJoCo history buffer (``nsample``).

    MuJoCo writes every sensor with ``nsample > 0`` into ``data.history`` at each step, so the values of every
    substep between two control steps can be read afterwards without a Python loop over substeps. The buffer of a
    sensor is laid out as ``[user, cursor, times[n], values[n * dim]]`` with ``cursor`` the slot of the newest sample
    (checked in tests/test_mujoco_utils.py).
    """

    def __init__(self, model: mujoco.MjModel, names: Sequence[str], k: int):
        adrs, sizes = [], []
        for name in names:
            sid = model.sensor(name).id
            n = int(model.sensor_history[sid, 0])
            if n < k or int(model.sensor_dim[sid]) != 1:
                raise ValueError(f"sensor {name!r} needs a history of at least {k} scalar samples, has {n}")
            adrs.append(int(model.sensor_historyadr[sid]))
            sizes.append(n)
        if len(set(sizes)) != 1:
            raise ValueError("sensors read together must keep histories of the same length")
        self.k = k
        self._n = sizes[0]
        self._cursor = adrs[0] + 1
        self._values = np.asarray(adrs) + 2 + self._n  # first value slot of each sensor
        self._offsets = np.arange(k) - k + 1

    def read(self, data: mujoco.MjData) -> np.ndarray:
        """Samples of the last ``k`` physics steps, oldest first: shape (k, number of sensors)."""
        newest = int(data.history[self._cursor])
        slots = (newest + self._offsets) % self._n
        return data.history[self._values[None, :] + slots[:, None]]


def spec_hash(spec: mujoco.MjSpec) -> str:
    """A short content hash of a model spec (its MJCF), to tie telemetry and results to the exact model."""
    return hashlib.sha256(spec.to_xml().encode()).hexdigest()[:16]


def quat_to_yaw(quat: np.ndarray) -> float:
    """Heading (rotation about world z) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = quat
    return float(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))


def quat_up_z(quat: np.ndarray) -> float:
    """World-z component of the body's z axis: 1 upright, 0 on its side, -1 upside down."""
    _, x, y, _ = quat
    return float(1.0 - 2.0 * (x * x + y * y))
