"""A battery with an internal resistance: its terminal voltage sags with the power its load draws.

A cell of open-circuit voltage ``E`` and internal resistance ``R`` delivering power ``P`` holds ``V = E - R I`` at its
terminals with ``P = V I``, so ``V^2 - E V + R P = 0`` and ``V = (E + sqrt(E^2 - 4 R P)) / 2`` (the root that is ``E``
at no load). Beyond ``E^2 / (4 R)``, more than the cell can deliver, the voltage is held at ``E / 2`` (the point of
maximum power). The robots evaluate it once per control step, on the power drawn over the step before: the quasi-static
sag (the ohmic part; a real pack also recovers over seconds, which is not modelled), with no Python per physics step.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def loaded_voltage(open_circuit: ArrayLike, resistance: ArrayLike, power: ArrayLike) -> np.ndarray:
    """The terminal voltage (V) of batteries of open-circuit voltage ``open_circuit`` (V) and internal resistance
    ``resistance`` (ohm) delivering ``power`` (W, >= 0), elementwise."""
    e = np.asarray(open_circuit, dtype=np.float64)
    return 0.5 * (e + np.sqrt(np.maximum(e * e - 4.0 * np.asarray(resistance) * np.asarray(power), 0.0)))
