"""What the robots' folders declare for calibration: adapters (``CALIBRATION``) and log readers (``LOG_READERS``),
found in ``envs/<robot>/__init__.py``."""

from __future__ import annotations

import importlib
import pkgutil

import envs
from sysid.problem import Adapter


def declared(name: str) -> list:
    """What every robot folder declares under ``name`` (``envs/<robot>/__init__.py``), a dict's items merged or a
    list's entries joined: how the shared tools find a robot's parts without naming it."""
    found: list = []
    for module in pkgutil.iter_modules(envs.__path__):
        if module.ispkg:
            value = getattr(importlib.import_module(f"envs.{module.name}"), name, None)
            if value:
                found += list(value.items()) if isinstance(value, dict) else list(value)
    return found


def adapters() -> dict[str, str]:
    """Robot name -> ``module:Class`` of its adapter."""
    return dict(declared("CALIBRATION"))


def adapter(name: str) -> Adapter:
    known = adapters()
    if name not in known:
        raise ValueError(f"no calibration adapter for robot {name!r}; known: {', '.join(sorted(known))}")
    module, _, cls = known[name].partition(":")
    return getattr(importlib.import_module(module), cls)()
