"""The calibration adapters of every robot, found in the robots' folders (``CALIBRATION`` in ``envs/<robot>/``)."""

from __future__ import annotations

import importlib
import pkgutil

import envs
from sysid.problem import Adapter


def adapters() -> dict[str, str]:
    """Robot name -> ``module:Class`` of its adapter."""
    found: dict[str, str] = {}
    for module in pkgutil.iter_modules(envs.__path__):
        if module.ispkg:
            found.update(getattr(importlib.import_module(f"envs.{module.name}"), "CALIBRATION", {}))
    return found


def adapter(name: str) -> Adapter:
    known = adapters()
    if name not in known:
        raise ValueError(f"no calibration adapter for robot {name!r}; known: {', '.join(sorted(known))}")
    module, _, cls = known[name].partition(":")
    return getattr(importlib.import_module(module), cls)()
