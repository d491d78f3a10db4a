"""The one error of a configuration a user gave: a command line, a hyperparameter file, a run folder's record or an
optimizer's run configuration. Every tool reports it in one line, naming the file, the field and the value, without
a traceback."""

from __future__ import annotations


class ConfigError(ValueError):
    """A configuration that cannot be used; the message names the file (or flag), the field and the value."""


def closest_env(env_id: str, registered: list[str]) -> str:
    """``" (did you mean 'X'?)"`` for the registered id nearest ``env_id`` (case and version typos), or ``""``."""
    from envs.common.io import nearest

    lowered = {name.lower(): name for name in registered}
    asked = env_id.lower() if "/" in env_id else f"skitter/{env_id.lower()}"  # the namespace left out
    close = nearest(asked, lowered, cutoff=0.8)
    return f" (did you mean {lowered[close]!r}?)" if close else ""


def skitter_env_problem(env_id: str) -> str | None:
    """Why ``env_id`` is not one of skitter's registered envs (unknown, or another package's: skitter's tools run
    its own envs, whose telemetry, batching and references they rely on), with the ids that are; None if it is."""
    import gymnasium as gym

    skitter = sorted(name for name in gym.registry if name.startswith("skitter/"))
    if env_id in skitter:
        return None
    if env_id in gym.registry:
        return (
            f"{env_id!r} is not a skitter env (these tools run skitter's own); the skitter envs are "
            f"{', '.join(skitter)}"
        )
    return f"unknown env {env_id!r}{closest_env(env_id, skitter)}; the skitter envs are {', '.join(skitter)}"
