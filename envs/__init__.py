"""skitter environments: importing this package registers them under ``skitter/`` and does nothing else.

Each robot is a subpackage (``envs/<robot>/``) whose ``__init__`` lists its registrations in ``ENVS``; adding a robot
adds a folder and edits nothing here.
"""

import importlib
import pkgutil

from gymnasium.envs.registration import register

for _module in pkgutil.iter_modules(__path__):
    if _module.ispkg:
        for _spec in getattr(importlib.import_module(f"{__name__}.{_module.name}"), "ENVS", ()):
            register(**_spec)
