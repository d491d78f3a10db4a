"""Policies: scripted gaits and trained models behind one ``predict()``, resolved by name or path."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np


class Policy(Protocol):
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]: ...


SCRIPTED = {
    "tripod": "the alternating tripod: straight at 45 Hz on RoachWalk, the turning table on RoachTurn",
    "tripod:F": "the alternating tripod running straight at F Hz, e.g. tripod:20",
}
WALK_TRIPOD_FREQUENCY = 45.0  # Hz: the real robot's top stride (seed 000 Table 1)


def load_policy(spec: str, env) -> Policy:
    """A policy for ``env`` from a name (see ``SCRIPTED``) or the path of a trained ``model.zip``."""
    from agents.tripod import RoachObsLayout, TripodGait, TripodTurn

    if spec.endswith(".zip") or Path(spec).is_file():
        from agents.sb3 import SB3Policy

        return SB3Policy(spec)
    name, _, arg = spec.partition(":")
    if name == "tripod":
        layout = RoachObsLayout.from_env(env)
        if arg:
            try:
                frequency = float(arg)
            except ValueError:
                raise ValueError(f"policy {spec!r}: frequency {arg!r} is not a number") from None
            return TripodGait(layout, frequency=frequency)
        if layout.command_index is not None:
            return TripodTurn(layout)
        return TripodGait(layout, frequency=WALK_TRIPOD_FREQUENCY)
    known = ", ".join(SCRIPTED)
    raise ValueError(f"unknown policy {spec!r}: give a scripted gait ({known}) or the path of a model.zip")
