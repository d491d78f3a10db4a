"""Small helpers around MuJoCo shared by the robots."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import mujoco


def sensor_slices(model: mujoco.MjModel, names: Sequence[str]) -> dict[str, slice]:
    """Map sensor names to their slices of ``data.sensordata``, looked up once."""
    out = {}
    for name in names:
        sensor = model.sensor(name)
        adr, dim = int(sensor.adr[0]), int(sensor.dim[0])
        out[name] = slice(adr, adr + dim)
    return out


def spec_hash(spec: mujoco.MjSpec) -> str:
    """A short content hash of a model spec (its MJCF), to tie telemetry and results to the exact model."""
    return hashlib.sha256(spec.to_xml().encode()).hexdigest()[:16]
