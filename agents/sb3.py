"""Trained Stable-Baselines3 models behind the same ``predict()`` as the scripted gaits, saved as one file.

A trained model is its weights plus the observation-normalization statistics it was trained with. train.py writes
both into one ``model.zip``, atomically (a temporary file, then one rename): SB3's own archive with two more entries,
``vecnormalize.pkl`` (the pickled ``VecNormalize`` statistics, when the run normalized) and ``skitter.json`` (algorithm,
env id, whether the model needs statistics, observation size). SB3's ``load`` ignores both entries, so the file is
still an ordinary SB3 model. A model whose manifest says it was normalized but which lacks its statistics is an
error; a model from elsewhere (no manifest) is used with a ``vecnormalize.pkl`` beside it (RL Zoo's layout), and
without one only if the caller allows unnormalized observations.
"""

from __future__ import annotations

import json
import pickle
import re
import zipfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3 import PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from envs.common.io import atomic_write

ALGOS: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC, "td3": TD3}
MANIFEST = "skitter.json"
STATS = "vecnormalize.pkl"
FORMAT = 1
DIVERGED = re.compile(r"Expected parameter (\w+) .* but found invalid values")  # torch's distributions, on NaN


def diverged_cause(exc: ValueError) -> str | None:
    """What diverged, if ``exc`` is torch's refusal of a distribution's NaN or infinite parameter (the policy
    diverged during training), else None."""
    found = DIVERGED.search(str(exc).split("\n", 1)[0])
    return None if found is None else f"the policy's action distribution got a NaN or infinite {found.group(1)}"


class ModelFileError(ValueError):
    """A model file that cannot be used: truncated, not a model, or lacking what it needs. The message says which."""


def save_model(model: BaseAlgorithm, path: str | Path, manifest: dict[str, Any]) -> Path:
    """Write ``model`` with its normalization statistics and ``manifest`` into one zip at ``path``, atomically."""
    stats = model.get_vec_normalize_env()
    record = {
        "format": FORMAT,
        **manifest,
        "normalized": stats is not None,
        "num_timesteps": int(model.num_timesteps),
        "observation_size": int(np.prod(model.observation_space.shape)),
    }

    def write(tmp: Path) -> None:
        model.save(tmp)
        with zipfile.ZipFile(tmp, "a", compression=zipfile.ZIP_DEFLATED) as archive:
            if stats is not None:
                archive.writestr(STATS, pickle.dumps(stats))
            archive.writestr(MANIFEST, json.dumps(record, indent=2))

    return atomic_write(path, write)


def read_model_file(path: str | Path) -> tuple[dict[str, Any] | None, VecNormalize | None]:
    """The manifest (None for a model not written by train.py) and the statistics of a model file.

    Raises ModelFileError for a missing, truncated or corrupt file, or a normalized model without statistics.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"no trained model at {path}")
    try:
        with zipfile.ZipFile(path) as archive:
            bad = archive.testzip()
            if bad is not None:
                raise ModelFileError(f"{path}: corrupt model file (entry {bad!r} fails its checksum)")
            names = set(archive.namelist())
            if "data" not in names:
                raise ModelFileError(
                    f"{path}: truncated or corrupt, or not a Stable-Baselines3 model (no 'data' entry)"
                )
            manifest = json.loads(archive.read(MANIFEST)) if MANIFEST in names else None
            stats = _unpickle_stats(archive.read(STATS), f"{STATS} inside {path}") if STATS in names else None
    except ModelFileError:
        raise  # already says what is wrong (a ValueError too: not the manifest's fault)
    except (zipfile.BadZipFile, EOFError, OSError) as exc:
        raise ModelFileError(f"{path}: not a readable model file, truncated or corrupt ({exc})") from None
    except (json.JSONDecodeError, ValueError) as exc:
        raise ModelFileError(f"{path}: corrupt {MANIFEST} inside the model file ({exc})") from None
    _check_manifest(path, manifest)
    if manifest is not None and manifest.get("normalized") and stats is None:
        raise ModelFileError(
            f"{path}: the model was trained on normalized observations but its file lacks the statistics "
            f"({STATS}); it would be scored on the wrong inputs"
        )
    return manifest, stats


# the manifest's fields that evaluation reads, and their JSON types
_MANIFEST_TYPES = {"env_id": (str,), "algo": (str,), "normalized": (bool,), "residual": (dict, type(None))}


def _check_manifest(path: Path, manifest: Any) -> None:
    """A manifest train.py wrote is a JSON object whose fields have their types: one damaged by hand (an env id of
    5) is refused naming the field, not read past."""
    if manifest is None:
        return
    if not isinstance(manifest, dict):
        raise ModelFileError(f"{path}: corrupt {MANIFEST} inside the model file (a JSON object expected)")
    for field, types in _MANIFEST_TYPES.items():
        if field in manifest and not isinstance(manifest[field], types):
            raise ModelFileError(f"{path}: corrupt {MANIFEST} inside the model file (field {field!r} = "
                                 f"{manifest[field]!r})")  # fmt: skip


def _unpickle_stats(data: bytes, where: str) -> VecNormalize:
    """Observation-normalization statistics from their pickled bytes; ModelFileError naming ``where`` if damaged."""
    try:
        return pickle.loads(data)
    except Exception as exc:  # unpickling garbage raises anything
        raise ModelFileError(f"cannot read {where}: {error_reason(exc)}") from None


def load_model(
    path: str | Path, algos: Sequence[type[BaseAlgorithm]], device: str = "cpu", what: str = "checkpoint"
) -> BaseAlgorithm:
    """The model in ``path``, loaded by the first of ``algos`` that can (a model from elsewhere names none).

    Raises ModelFileError "cannot read WHAT PATH: reason" if none can, e.g. for weights damaged inside a whole zip
    (which :func:`read_model_file` cannot see); ``what`` says what the file is to the caller ("checkpoint" for
    train.py --resume, "policy file" for evaluate.py).
    """
    reasons = []
    for cls in algos:
        try:
            return cls.load(path, device=device)
        except Exception as exc:  # a damaged file raises anything: UnpicklingError, BadZipFile, RuntimeError, ...
            reasons.append(f"as {cls.__name__}: {error_reason(exc)}" if len(algos) > 1 else error_reason(exc))
    raise ModelFileError(f"cannot read {what} {path}: {'; '.join(reasons)}")


def trained_on(path: str | Path, manifest: dict[str, Any] | None) -> list[tuple[str, str]]:
    """What train.py recorded about the env the model at ``path`` was trained on, as (source, env id) pairs: the
    model file's manifest, and ``config.json`` of the run folder the file sits in (``<run>/model.zip`` or
    ``<run>/checkpoints/step_<N>/model.zip``). Empty for a model from elsewhere; a ``config.json`` that is not
    train.py's (unreadable, or without ``env_id`` and ``algo``) is not metadata."""
    found = []
    if manifest is not None and isinstance(manifest.get("env_id"), str):
        found.append((f"its manifest {MANIFEST}", manifest["env_id"]))
    config_path, config = _run_config(path)
    if config is not None:
        found.append((f"its run's {config_path}", config["env_id"]))
    return found


def _run_config(path: str | Path) -> tuple[Path, dict[str, Any] | None]:
    """``config.json`` of the run folder a model file sits in (``<run>/model.zip`` or
    ``<run>/checkpoints/step_<N>/model.zip``) and its content, None if it is not train.py's."""
    path = Path(path)
    run_dir = path.parent.parent.parent if path.parent.parent.name == "checkpoints" else path.parent
    config_path = run_dir / "config.json"
    try:
        config = json.loads(config_path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        config = None
    if isinstance(config, dict) and isinstance(config.get("env_id"), str) and isinstance(config.get("algo"), str):
        return config_path, config
    return config_path, None


def trained_env_kwargs(path: str | Path) -> dict[str, Any] | None:
    """The ``env_kwargs`` the model at ``path`` was trained with (its run's config.json), None if unknown."""
    _, config = _run_config(path)
    kwargs = ((config or {}).get("hyperparams") or {}).get("env_kwargs")
    return dict(kwargs) if isinstance(kwargs, dict) else None


def spaces_problem(model: BaseAlgorithm, env) -> str | None:
    """Why ``model`` cannot act in ``env`` (a single or a batched env), or None: the observation shapes differ, or
    the action spaces differ in kind, shape or bounds (SB3 scales actions to the bounds it was trained with)."""
    observation_space = getattr(env, "single_observation_space", env.observation_space)  # a batched env's, per sim
    action_space = getattr(env, "single_action_space", env.action_space)
    name = env.spec.id if env.spec else "the env"
    want, have = observation_space.shape, model.observation_space.shape
    if want != have:
        return f"the model observes {have} but {name} gives {want} (trained on another env or version?)"
    want, have = action_space, model.action_space
    if isinstance(want, spaces.Box) and isinstance(have, spaces.Box):
        same = want.shape == have.shape and np.array_equal(want.low, have.low) and np.array_equal(want.high, have.high)
    else:
        same = want == have
    if not same:
        return f"the model acts in {have} but {name} takes {want} (trained on another env or version?)"
    return None


def error_reason(exc: Exception) -> str:
    """One line saying why a file did not load. Torch's unpickling errors span lines and advise unsafe loading."""
    if isinstance(exc, pickle.UnpicklingError):
        return "corrupt contents (UnpicklingError)"
    lines = str(exc).strip().splitlines()
    return f"{lines[0]} ({type(exc).__name__})" if lines else type(exc).__name__


class SB3Policy:
    """A trained model with the observation normalization it was trained with.

    Args:
        path: a ``model.zip`` written by train.py (or any SB3 PPO, SAC or TD3 model).
        env: the env it will act in: a model whose metadata (:func:`trained_on`) names another env id is refused,
            and the env's observation shape and action space are checked against the model's.
        allow_unnormalized: accept a model from elsewhere that has no statistics, in it or beside it.
    """

    def __init__(self, path: str | Path, env=None, allow_unnormalized: bool = False, device: str = "cpu"):
        path = Path(path)
        self.path = path
        manifest, stats = read_model_file(path)
        if manifest is None and stats is None:
            beside = path.parent / STATS
            if beside.is_file():
                stats = _unpickle_stats(beside.read_bytes(), str(beside))
            elif not allow_unnormalized:
                raise ModelFileError(
                    f"{path}: a model not written by train.py, with no {STATS} in it or beside it; if it was trained "
                    "without observation normalization, allow unnormalized observations (evaluate.py --unnormalized)"
                )
        self.manifest = manifest or {}
        self.normalizer = stats
        env_id = env.spec.id if env is not None and env.spec else None
        for source, trained in trained_on(path, manifest) if env_id is not None else ():
            if trained != env_id:
                raise ModelFileError(f"{path}: the model was trained on {trained} ({source} says so), not on {env_id}")
        algo = self.manifest.get("algo")
        algos = [ALGOS[algo]] if algo in ALGOS else list(ALGOS.values())
        self.model = load_model(path, algos, device, what="policy file")
        if env is not None:
            problem = spaces_problem(self.model, env)
            if problem:
                raise ModelFileError(f"{path}: {problem}")

    def __repr__(self) -> str:
        return f"SB3Policy({self.path})"

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        if self.normalizer is not None:
            obs = self.normalizer.normalize_obs(obs)
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)
