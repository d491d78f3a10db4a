"""Train a Stable-Baselines3 agent (PPO, SAC or TD3) on a skitter environment: the code of the ``train.py`` command.

    python train.py --env skitter/RoachWalk-v4 --algo ppo --timesteps 500000 --seed 0
    python train.py --resume runs/skitter_RoachWalk-v4__ppo__0__20250101-120000 --timesteps 1000000
    tensorboard --logdir runs

Hyperparameters come from ``hyperparams/<algo>.yml`` (RL Baselines3 Zoo style: one entry per env id, YAML anchors
for shared defaults). An entry may set any argument of the algorithm's constructor except those train.py sets itself
(env, seed, verbose, tensorboard_log), plus:

- ``n_envs``: number of environments stepped together (default 1);
- ``vec_env``: ``batched`` (default: every env in one ``mujoco.batch`` on the machine's cores, agents/vec_env.py) or
  ``dummy`` (SB3's DummyVecEnv, one env after another); ``nthread``: the batch's threads (default: the cores);
- ``normalize``: ``true`` to wrap the envs in VecNormalize (observations and rewards), or a mapping of VecNormalize
  arguments such as ``{norm_obs: true, norm_reward: false}`` (default false);
- ``env_kwargs``: a mapping passed to ``gymnasium.make``;
- ``noise_type`` (``normal`` or ``ornstein-uhlenbeck``) and ``noise_std``: exploration noise for SAC and TD3.

``policy_kwargs`` may be a mapping or a Zoo-style string such as ``"dict(net_arch=[64, 64], activation_fn=nn.Tanh)"``
(read without ``eval``: only literals, ``dict(...)`` and torch classes are allowed). ``learning_rate`` and
``clip_range`` accept ``lin_<value>``, a linear decay from the value to zero over the run.

Each run writes ``<runs-dir>/<env>__<algo>__<seed>__<YYYYmmdd-HHMMSS>/`` holding ``config.json``, ``command.txt``,
TensorBoard logs (``tb/``), checkpoints (``checkpoints/step_<N>/``) and, at the end, ``model.zip``. A model file is
one unit: SB3's archive with the observation-normalization statistics and a manifest inside it (agents/sb3.py),
written atomically, so a kill during the save leaves the previous file or none, never a model without its statistics.
A checkpoint is one folder, written under a temporary name and renamed into place: ``model.zip``, for SAC and TD3 the
replay buffer (kept only in the newest checkpoint), and ``checkpoint.json``. ``--resume`` takes a run folder's path
or a run's name (no ``/``), looked up in ``--runs-dir``; it continues from the newest checkpoint that loads, says
which ones it skipped and why, and removes the temporary folders and files a killed run left (only the names
train.py's own writers give them). Ctrl-C and SIGTERM save a checkpoint first.
One train.py process at a time writes a run folder: a new run and a resume hold its lock (``train.lock``), and a
second process on the folder is refused at once, before it reads or removes anything. The guide is docs/training.md.

Every input is checked before anything is created: the command line (``--runs-dir`` by making and removing a probe
folder; an empty path is refused), the hyperparameter file (a key given twice in one mapping is refused; each field
against the algorithm's constructor; numbers must be finite; a CUDA ``device`` only where CUDA is available),
``env_kwargs`` (by making the env once) and the model (built before the run folder; if SB3 or torch cannot build it,
the error names the field to blame).
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import inspect
import json
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime
from importlib import metadata
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
import yaml
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import Logger, TensorBoardOutputFormat
from stable_baselines3.common.noise import (
    ActionNoise,
    NormalActionNoise,
    OrnsteinUhlenbeckActionNoise,
    VectorizedActionNoise,
)
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.utils import LinearSchedule, set_random_seed
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize
from torch.utils.tensorboard import SummaryWriter

import envs  # noqa: F401  (registers the skitter envs)
from agents import residual_reference
from agents.config import ConfigError, skitter_env_problem
from agents.evaluation import episode_metrics
from agents.residual import (
    SETTINGS,
    Residual,
    ResidualVecEnv,
    gym_env,
    names_a_gait,
    parse_residual,
    residual_settings,
)
from agents.sb3 import (
    ALGOS,
    ModelFileError,
    diverged_cause,
    error_reason,
    load_model,
    read_model_file,
    save_model,
)
from agents.tuning import RunCode, tune
from agents.vec_env import make_batched_vec_env
from envs.common.batch import default_threads
from envs.common.env import creator_error
from envs.common.host import numerics
from envs.common.io import (
    TEMP_RANDOM,
    Busy,
    ProgressLines,
    ToolParser,
    at_least_one,
    atomic_write_leftovers,
    current_umask,
    folder_lock,
    interrupted_exit_code,
    json_object,
    nearest,
    non_negative,
    parent_problem,
    progress_bar_wanted,
    refuse_overwrite,
    sigterm_as_interrupt,
    write_json,
    write_text,
)
from envs.soccer.steering import COMMANDS

ROOT = Path(__file__).resolve().parents[1]  # the repository (an editable install's source tree)
HYPERPARAMS_DIR = ROOT / "hyperparams"
DEFAULT_CHECKPOINT_FREQ = 50_000  # env steps
# One torch thread: on a 2-core machine a second thread made PPO 6x and SAC 10x slower (the MLPs are tiny, and the
# MuJoCo envs share the cores).
TORCH_THREADS = 1

# Entries train.py understands besides the algorithm's own arguments, with their defaults.
TRAIN_DEFAULTS: dict[str, Any] = {
    "policy": "MlpPolicy",
    "n_envs": 1,
    "normalize": False,
    "env_kwargs": {},
    "vec_env": "batched",
    "nthread": None,
}
# --tune's defaults (given here, not as argparse defaults, so that the options are refused without --tune)
TUNE_EVALUATIONS, TUNE_EVAL_EPISODES = 4, 5
SOCCER_ROBOTS = ("bioloid", "roach", "xjus")  # train.py --soccer (envs/soccer/robots.py, by its lower-case names)
VEC_ENVS = ("batched", "dummy")  # the batched env on mujoco.batch (one process, every core), or SB3's DummyVecEnv
NOISE_DEFAULTS: dict[str, Any] = {"noise_type": None, "noise_std": 0.1}  # SAC and TD3 only; None: no noise
NOISE_TYPES = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
SET_BY_TRAIN = {
    "env": "--env",
    "seed": "--seed",
    "verbose": "train.py",
    "tensorboard_log": "train.py (logs go to the run folder's tb/)",
    "_init_setup_model": "train.py",
    "action_noise": "noise_type and noise_std",
}
SCHEDULES = ("learning_rate", "clip_range")  # accept "lin_<value>"
# Inclusive bounds (low, high) for numeric entries; None is unbounded.
LIMITS: dict[str, tuple[float | None, float | None]] = {
    "n_envs": (1, None),
    "nthread": (1, None),
    "n_steps": (1, None),
    "batch_size": (1, None),
    "n_epochs": (1, None),
    "buffer_size": (1, None),
    "learning_starts": (0, None),
    "gradient_steps": (-1, None),
    "target_update_interval": (1, None),
    "policy_delay": (1, None),
    "stats_window_size": (1, None),
    "learning_rate": (0, None),
    "gamma": (0, 1),
    "gae_lambda": (0, 1),
    "tau": (0, 1),
    "clip_range": (0, None),
    "ent_coef": (0, None),
    "vf_coef": (0, None),
    "max_grad_norm": (0, None),
    "target_policy_noise": (0, None),
    "target_noise_clip": (0, None),
    "noise_std": (0, None),
}
# Entries whose low bound is excluded: a zero learning rate or clip range trains nothing.
ABOVE_LOW = frozenset({"learning_rate", "clip_range"})
# Names a policy_kwargs expression may use for torch classes, e.g. nn.Tanh or th.optim.Adam.
TORCH_MODULES = {
    "nn": torch.nn,
    "th.nn": torch.nn,
    "torch.nn": torch.nn,
    "optim": torch.optim,
    "th.optim": torch.optim,
    "torch.optim": torch.optim,
}


# --- hyperparameters --------------------------------------------------------------------------------------------


@dataclass
class Hyperparams:
    """One env's entry of a hyperparameter file, checked and split into what each consumer needs."""

    where: str  # "FILE: ENV_ID", the prefix of error messages
    raw: dict[str, Any]  # as written (anchors merged, train.py defaults filled in): what config.json records
    model_kwargs: dict[str, Any]  # arguments of the algorithm's constructor, parsed
    n_envs: int
    normalize: dict[str, Any] | None  # VecNormalize arguments, or None for no normalisation
    env_kwargs: dict[str, Any]
    noise: tuple[str, float] | None  # (noise_type, noise_std)
    vec_env: str = "batched"
    nthread: int | None = None
    residual: Residual | None = None  # a residual policy's reference gait (agents/residual.py)


class DuplicateKeyError(yaml.constructor.ConstructorError):
    """A key given twice in one mapping of a YAML file (YAML would keep the last one silently)."""


class UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping. Keys merged in from an anchor (``<<:
    *defaults``) may still be overridden: only the keys written in the mapping itself must be unique."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.get(key)
                except TypeError:  # an unhashable key: SafeLoader's own error names it
                    continue
                if first is not None:
                    raise DuplicateKeyError(
                        None, None, f"duplicate key {key!r} (first on line {first})", key_node.start_mark
                    )
                seen[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: Path) -> Any:
    """The YAML file ``path``, read with :class:`UniqueKeyLoader`; ConfigError naming the file (and the line, key or
    byte) if it cannot be read, is not UTF-8, is not YAML or gives a key twice in one mapping."""
    try:
        return yaml.load(path.read_text(encoding="utf-8"), Loader=UniqueKeyLoader)  # a SafeLoader: no arbitrary objects
    except OSError as exc:
        raise ConfigError(f"cannot read hyperparameter file {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason})") from None
    except DuplicateKeyError as exc:
        raise ConfigError(
            f"{path}: line {exc.problem_mark.line + 1}: {exc.problem}; YAML would keep the last one silently, "
            "so give each key once"
        ) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(f"{path}:{line}: not valid YAML ({problem})") from None


def load_hyperparams(path: Path, env_id: str, algo: str, overrides: dict[str, Any] | None = None,
                     players: int = 1) -> Hyperparams:  # fmt: skip
    """The checked hyperparameters for ``env_id`` in the YAML file ``path``, with ``overrides`` (e.g. n_envs);
    ``players``: the learner's envs per ``n_envs`` (a soccer team's players per match)."""
    table = read_yaml(path)
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: expected a mapping from env ids to hyperparameters")
    if env_id not in table:
        entries = ", ".join(str(key) for key in table) or "none"
        raise ConfigError(f"{path}: no entry for env {env_id!r} (entries: {entries})")
    entry = table[env_id]
    if not isinstance(entry, dict):
        raise ConfigError(f"{path}: {env_id}: expected a mapping of hyperparameters, got {entry!r}")
    return resolve_hyperparams({**entry, **(overrides or {})}, algo, where=f"{path}: {env_id}", players=players)


RESIDUAL_ENTRY = "+residual"  # an entry key's suffix: the entry a residual run on that env takes


def entry_key(path: Path, env_id: str, residual: bool) -> str:
    """The key of the entry in the hyperparameter file ``path`` that a run on ``env_id`` takes: a residual run's
    (``--residual``) is ``<env_id>+residual`` where the file has one, with the settings a correction on the gait
    learns with; else ``env_id``."""
    if residual:
        table = read_yaml(path)
        if isinstance(table, dict) and env_id + RESIDUAL_ENTRY in table:
            return env_id + RESIDUAL_ENTRY
    return env_id


def resolve_hyperparams(entry: dict[str, Any], algo: str, where: str, players: int = 1) -> Hyperparams:
    """Check every field of ``entry`` for ``algo`` and parse the values; errors name ``where``, the field and value."""
    defaults = algo_defaults(algo)
    own_defaults = {**TRAIN_DEFAULTS, **(NOISE_DEFAULTS if "action_noise" in defaults else {})}
    allowed = (set(defaults) - set(SET_BY_TRAIN)) | set(own_defaults) | {"residual"}
    for key in entry:
        if key not in allowed:
            raise ConfigError(f"{where}: {_unknown_field_message(key, allowed, algo)}")
    raw = {**own_defaults, **entry}

    def check(key: str, parse):
        try:
            return parse(raw[key])
        except ValueError as exc:
            raise ConfigError(f"{where}: field {key!r} = {raw[key]!r}: {exc}") from None

    model_kwargs = {
        key: check(key, lambda value, key=key: parse_model_value(key, value, defaults[key], algo))
        for key in raw
        if key in defaults
    }
    gamma = model_kwargs.get("gamma", defaults["gamma"])
    noise = None
    if raw.get("noise_type") is not None:
        noise = (check("noise_type", _noise_type), check("noise_std", lambda v: _number("noise_std", v, float)))
    n_envs = check("n_envs", lambda v: _number("n_envs", v, int))
    if isinstance(model_kwargs.get("train_freq"), tuple) and model_kwargs["train_freq"][1] == "episode" and n_envs > 1:
        raise ConfigError(f"{where}: field 'train_freq' = {raw['train_freq']!r}: needs n_envs 1, not {n_envs}")
    _check_batch_size(model_kwargs, defaults, n_envs, algo, where, players)
    residual = None
    if "residual" in raw and names_a_gait(raw["residual"]):
        residual = check("residual", parse_residual)
    elif "residual" in raw:  # how a residual run is made, when one is asked for: checked here, applied there
        check("residual", residual_settings)
    if residual is not None and residual.exploration is not None:
        model_kwargs["policy_kwargs"] = _exploring(model_kwargs.get("policy_kwargs"), residual, algo, where, raw)
    return Hyperparams(
        where=where,
        raw=raw,
        model_kwargs=model_kwargs,
        n_envs=n_envs,
        normalize=check("normalize", lambda v: _normalize_kwargs(v, gamma)),
        env_kwargs=check("env_kwargs", _mapping),
        noise=noise,
        vec_env=check("vec_env", _vec_env),
        nthread=check("nthread", lambda v: None if v is None else _number("nthread", v, int)),
        residual=residual,
    )


def _exploring(policy_kwargs: dict[str, Any] | None, residual: Residual, algo: str, where: str,
               raw: dict[str, Any]) -> dict[str, Any]:  # fmt: skip
    """``policy_kwargs`` with the residual's ``exploration`` as the Gaussian policy's ``log_std_init``."""
    if algo not in ("ppo", "sac"):
        raise ConfigError(
            f"{where}: field 'residual' = {raw['residual']!r}: exploration is the initial standard deviation of "
            f"PPO's and SAC's Gaussian; {algo.upper()} explores by its noise_std"
        )
    if policy_kwargs and "log_std_init" in policy_kwargs:
        raise ConfigError(
            f"{where}: field 'residual' = {raw['residual']!r}: exploration sets log_std_init, which "
            f"policy_kwargs sets too ({policy_kwargs['log_std_init']!r}): give one"
        )
    return {**(policy_kwargs or {}), "log_std_init": math.log(residual.exploration)}


def _check_batch_size(
    model_kwargs: dict[str, Any], defaults: dict[str, Any], n_envs: int, algo: str, where: str, players: int = 1
) -> None:
    """A minibatch no larger than what it is drawn from: an on-policy rollout (``n_steps`` x ``n_envs``) or an
    off-policy replay buffer. SB3 only warns (PPO) or samples with repeats (SAC, TD3), and trains on a mistake."""
    batch_size = model_kwargs.get("batch_size", defaults.get("batch_size"))
    if not isinstance(batch_size, int):
        return
    if not issubclass(ALGOS[algo], OffPolicyAlgorithm):
        n_steps = model_kwargs.get("n_steps", defaults["n_steps"])
        if batch_size > n_steps * n_envs * players:
            rollout = "n_steps x n_envs" if players == 1 else "n_steps x n_envs (matches) x players"
            sizes = f"{n_steps} x {n_envs}" + ("" if players == 1 else f" x {players}")
            raise ConfigError(
                f"{where}: field 'batch_size' = {batch_size}: larger than a rollout, {rollout} = {sizes} = "
                f"{n_steps * n_envs * players}"
            )
    else:
        buffer_size = model_kwargs.get("buffer_size", defaults["buffer_size"])
        if batch_size > buffer_size:
            raise ConfigError(
                f"{where}: field 'batch_size' = {batch_size}: larger than the replay buffer (buffer_size {buffer_size})"
            )


def algo_defaults(algo: str) -> dict[str, Any]:
    """The constructor arguments of ``algo`` and their defaults (``inspect.Parameter.empty`` for none)."""
    params = inspect.signature(ALGOS[algo].__init__).parameters
    return {name: p.default for name, p in params.items() if name not in ("self", "args", "kwargs")}


def _unknown_field_message(key: str, allowed: set[str], algo: str) -> str:
    if key in SET_BY_TRAIN:
        return f"field {key!r} is set by {SET_BY_TRAIN[key]}, not in the hyperparameter file"
    close = nearest(str(key), allowed)
    hint = f"; did you mean {close!r}?" if close else ""
    return f"unknown field {key!r} for {algo.upper()}{hint}"


def parse_model_value(key: str, value: Any, default: Any, algo: str) -> Any:
    """``value`` as the algorithm's constructor argument ``key`` wants it; ValueError saying why if it is not."""
    if key == "policy":
        if value not in ALGOS[algo].policy_aliases:
            raise ValueError(f"expected one of {', '.join(ALGOS[algo].policy_aliases)}")
        return value
    if key == "policy_kwargs":
        return parse_policy_kwargs(value)
    if key == "train_freq":
        return _train_freq(value)
    if key == "device":
        return _device(value)
    if key in SCHEDULES and isinstance(value, str) and value.startswith("lin_"):
        start = _number(key, value.removeprefix("lin_"), float)
        return LinearSchedule(start, 0.0, 1.0)
    return _like_default(key, value, default)


def _like_default(key: str, value: Any, default: Any) -> Any:
    """``value`` checked against the type of the argument's ``default``: bool, int, float, str or None."""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ValueError("expected true or false")
        return value
    if isinstance(default, int | float):
        return _number(key, value, type(default))
    if isinstance(default, str):  # e.g. SAC's ent_coef "auto" or a number, device "cpu"
        return value if isinstance(value, str) else _number(key, value, float)
    if default is None and key.endswith("_kwargs"):
        return _mapping(value)
    if default is None and not key.endswith("_class"):  # optional numbers such as target_kl, clip_range_vf
        return None if value is None else _number(key, value, float)
    raise ValueError("train.py cannot set this field from a hyperparameter file")


def _number(key: str, value: Any, kind: type) -> int | float:
    """``value`` as an int or float within ``LIMITS[key]``. Floats may be strings: YAML reads ``3e-4`` as one."""
    if kind is float and isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise ValueError("expected a number") from None
    if isinstance(value, bool) or not isinstance(value, int if kind is int else int | float):
        raise ValueError("expected an integer" if kind is int else "expected a number")
    if not math.isfinite(value):
        raise ValueError("must be a finite number")
    low, high = LIMITS.get(key, (None, None))
    above = key in ABOVE_LOW
    if (low is not None and (value <= low if above else value < low)) or (high is not None and value > high):
        bounds = f"between {low} and {high}" if high is not None else f"{'above' if above else 'at least'} {low}"
        raise ValueError(f"must be {bounds}")
    return kind(value)


def _mapping(value: Any) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError("expected a mapping")
    return dict(value)


def _train_freq(value: Any) -> int | tuple[int, str]:
    if isinstance(value, list | tuple) and len(value) == 2 and value[1] in ("step", "episode"):
        return (_number("train_freq", value[0], int), value[1])
    if isinstance(value, int) and not isinstance(value, bool) and value >= 1:
        return value
    raise ValueError('expected a positive integer or [N, "step" | "episode"]')


def _device(value: Any) -> Any:
    """``device`` as given, refused if it names CUDA on a machine without it (SB3 would run on the CPU silently).
    A string torch cannot read is left to the model's build, whose error names the field."""
    if not isinstance(value, str):
        raise ValueError('expected a device name such as "cpu", "cuda", "cuda:0" or "auto"')
    try:
        device = torch.device(value)
    except (RuntimeError, ValueError):
        return value
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise ValueError('CUDA is not available here (torch.cuda.is_available() is False); use "cpu" or "auto"')
        if device.index is not None and device.index >= torch.cuda.device_count():
            raise ValueError(f"this machine has {torch.cuda.device_count()} CUDA device(s), numbered from 0")
    return value


def _vec_env(value: Any) -> str:
    if value not in VEC_ENVS:
        raise ValueError(f"expected one of {', '.join(VEC_ENVS)}")
    return value


def _noise_type(value: Any) -> str:
    if value not in NOISE_TYPES:
        raise ValueError(f"expected one of {', '.join(NOISE_TYPES)}")
    return value


def _normalize_kwargs(value: Any, gamma: float) -> dict[str, Any] | None:
    """VecNormalize arguments from ``normalize``: a bool, a mapping, or a Zoo-style string of a dict."""
    if isinstance(value, str):  # a quoted word ("yes") is no expression: say what the field takes
        try:
            value = parse_expression(value)
        except ValueError:
            raise ValueError("expected true, false or a mapping of VecNormalize arguments (unquoted)") from None
    if isinstance(value, bool):
        return {"gamma": gamma} if value else None
    if not isinstance(value, dict):
        raise ValueError("expected true, false or a mapping of VecNormalize arguments")
    params = inspect.signature(VecNormalize.__init__).parameters
    known = {name: p.default for name, p in params.items() if name not in ("self", "venv")}
    unknown = sorted(set(value) - set(known))
    if unknown:
        raise ValueError(f"VecNormalize has no argument {unknown[0]!r} (it takes {', '.join(sorted(known))})")
    checked = {}
    for key, item in value.items():
        try:
            checked[key] = _like_default(key, item, known[key])
        except ValueError as exc:
            raise ValueError(f"{key}: {exc}") from None
    # what VecNormalize divides by (epsilon) and clips to (+-clip_obs, +-clip_reward) must be above 0: 0 or less
    # gives NaN observations, or every observation or reward one constant, and the run trains on nothing
    for key in ("epsilon", "clip_obs", "clip_reward"):
        if key in checked and not (math.isfinite(checked[key]) and checked[key] > 0):
            raise ValueError(f"{key}: must be a finite number above 0, got {checked[key]!r}")
    if "gamma" in checked and not 0 < checked["gamma"] <= 1:
        raise ValueError(f"gamma: must lie in (0, 1], got {checked['gamma']!r}")
    return {"gamma": gamma, **checked}


def parse_policy_kwargs(value: Any) -> dict[str, Any]:
    """``policy_kwargs`` from a mapping or a Zoo-style string; class names (``nn.Tanh``) become torch classes."""
    if isinstance(value, str):
        value = parse_expression(value)
    value = _mapping(value)
    for key in ("activation_fn", "optimizer_class"):
        if isinstance(value.get(key), str):
            value[key] = parse_expression(value[key])
    _check_finite(value)
    return value


def _check_finite(value: Any) -> None:
    """ValueError if a float anywhere in ``value`` (nested lists and mappings) is NaN or infinite."""
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"{value} is not a finite number")
    if isinstance(value, dict):
        value = list(value.values())
    if isinstance(value, list | tuple):
        for item in value:
            _check_finite(item)


def parse_expression(text: str) -> Any:
    """Read a Python literal, ``dict(...)`` call or torch class name (``nn.Tanh``) without ``eval``."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ValueError(f"not a valid expression ({exc.msg})") from None
    return _evaluate(tree.body)


def _evaluate(node: ast.expr) -> Any:
    match node:
        case ast.Constant():
            return node.value
        case ast.UnaryOp(op=ast.USub(), operand=ast.Constant(value=int() | float())):
            return -node.operand.value
        case ast.List(elts=items):
            return [_evaluate(item) for item in items]
        case ast.Tuple(elts=items):
            return tuple(_evaluate(item) for item in items)
        case ast.Dict(keys=keys, values=values) if None not in keys:
            return {_evaluate(k): _evaluate(v) for k, v in zip(keys, values, strict=True)}
        case ast.Call(func=ast.Name(id="dict"), args=[], keywords=keywords) if all(kw.arg for kw in keywords):
            return {kw.arg: _evaluate(kw.value) for kw in keywords}
        case ast.Attribute(attr=name):
            module = TORCH_MODULES.get(ast.unparse(node.value))
            cls = getattr(module, name, None) if module is not None else None
            if isinstance(cls, type):
                return cls
    raise ValueError(f"{ast.unparse(node)!r} is not allowed (only literals, dict(...) and torch classes like nn.Tanh)")


# --- environments and models ------------------------------------------------------------------------------------


def make_env(env_id: str, hp: Hyperparams, seed: int, checkpoint: Checkpoint | None = None) -> VecEnv:
    """``hp.n_envs`` copies of ``env_id`` seeded ``seed``, ``seed + 1``, ..., normalised as ``hp`` says: by default
    the batched env (all of them in one ``mujoco.batch`` on ``hp.nthread`` threads), or SB3's ``DummyVecEnv``.

    ``checkpoint``: when resuming, the checkpoint the envs must fit, whose VecNormalize statistics continue.
    """
    try:
        if hp.vec_env == "batched" and gym.spec(env_id).vector_entry_point is not None:
            venv = make_batched_vec_env(env_id, hp.n_envs, seed, {**hp.env_kwargs, "nthread": hp.nthread})
        else:
            venv = make_vec_env(env_id, hp.n_envs, seed=seed, env_kwargs=hp.env_kwargs, vec_env_cls=DummyVecEnv)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{hp.where}: field 'env_kwargs' = {hp.env_kwargs!r}: {exc}") from None
    if hp.residual is not None:  # inside the normalization: the reference reads the env's own observations
        try:
            venv = ResidualVecEnv(venv, hp.residual, residual_reference(hp.residual.policy, gym_env(venv)))
        except ValueError as exc:
            raise ConfigError(f"{hp.where}: field 'residual' = {hp.raw['residual']!r}: {exc}") from None
    if checkpoint is not None:
        check_fits(checkpoint, venv, env_id)
    if hp.normalize is None:
        return venv
    if checkpoint is not None and checkpoint.stats is not None:
        checkpoint.stats.set_venv(venv)
        checkpoint.stats.training = True
        return checkpoint.stats
    return VecNormalize(venv, **hp.normalize)


def make_action_noise(hp: Hyperparams, venv: VecEnv) -> ActionNoise | None:
    if hp.noise is None:
        return None
    noise_type, std = hp.noise
    n_actions = venv.action_space.shape[-1]
    noise = NOISE_TYPES[noise_type](mean=np.zeros(n_actions), sigma=std * np.ones(n_actions))
    return VectorizedActionNoise(noise, venv.num_envs) if venv.num_envs > 1 else noise


def build_model(algo: str, hp: Hyperparams, venv: VecEnv, seed: int) -> BaseAlgorithm:
    """A new ``algo`` model on ``venv`` from ``hp``.

    Whatever SB3 or torch raise while building it (a bad ``device``, a negative layer size in ``policy_kwargs``, ...)
    is a ConfigError naming the field without which the model builds, found by building it again without each field.
    """

    def build(model_kwargs: dict[str, Any]) -> BaseAlgorithm:
        kwargs = {"device": "cpu", **model_kwargs}
        if hp.noise is not None:
            kwargs["action_noise"] = make_action_noise(hp, venv)
        return ALGOS[algo](env=venv, seed=seed, verbose=0, **kwargs)

    try:
        return build(hp.model_kwargs)
    except Exception as exc:  # SB3 and torch raise anything: RuntimeError, ValueError, AssertionError, ...
        message = f"cannot build the {algo.upper()} model: {error_reason(exc)}"
    for key in hp.model_kwargs:
        try:
            build({k: v for k, v in hp.model_kwargs.items() if k != key})
        except Exception:
            continue
        raise ConfigError(f"{hp.where}: field {key!r} = {hp.raw[key]!r}: {message}")
    raise ConfigError(f"{hp.where}: {message}")


# --- run folders, checkpoints, saving ---------------------------------------------------------------------------


RUN_CODE = RunCode(resolve_hyperparams, make_env, build_model, TORCH_THREADS, algo_defaults)
"""The functions a tuning trial trains with (agents/tuning.py): a run's own."""


def run_name(env_id: str, algo: str, seed: int) -> str:
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    return f"{env_id.replace('/', '_')}__{algo}__{seed}__{stamp}"


def check_runs_dir(runs_dir: Path) -> None:
    """Refuse a ``--runs-dir`` where no run folder can be made (a file, under a file, not writable), creating
    nothing (:func:`envs.common.io.parent_problem`)."""
    if runs_dir.exists() and not runs_dir.is_dir():
        raise ConfigError(f"--runs-dir {runs_dir} exists and is not a directory")
    problem = parent_problem(runs_dir / "run")
    if problem:
        raise ConfigError(f"--runs-dir {runs_dir}: {problem}")


def make_run_dir(runs_dir: Path, name: str) -> Path:
    """Create the empty run folder ``runs_dir/name``; never reuse an existing one."""
    run_dir = runs_dir / name
    try:
        refuse_overwrite(run_dir, "run folder")
        runs_dir.mkdir(parents=True, exist_ok=True)
        run_dir.mkdir()
    except FileExistsError:
        raise ConfigError(f"run folder {run_dir} already exists; runs are never overwritten") from None
    except OSError as exc:
        raise ConfigError(f"cannot create the run folder {run_dir}: {exc.strerror}") from None
    return run_dir


def versions() -> dict[str, str]:
    """The Python, library versions and commit a run trains on, and the CPU code paths numpy and torch take there
    (envs/common/host.py: the same seed trains the same model on the same versions and code paths)."""
    found = {"python": sys.version.split()[0]}
    for package in ("skitter", "stable-baselines3", "torch", "mujoco", "gymnasium", "numpy"):
        try:
            found[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            found[package] = "not installed"
    found["git_commit"] = _git_commit()
    return {**found, **numerics(), "torch_cpu": torch.backends.cpu.get_cpu_capability()}


def _git_commit() -> str:
    """The repository's commit, with "-dirty" if tracked files changed; "unknown" outside a git checkout."""

    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=10)

    try:
        commit = git("rev-parse", "HEAD")
        if commit.returncode != 0:
            return "unknown"
        dirty = git("status", "--porcelain", "--untracked-files=no").stdout.strip()
        return commit.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def command_line() -> str:
    return shlex.join(sys.orig_argv)


CHECKPOINT_PREFIX = "step_"  # a checkpoint's folder: step_<N>, N in ten digits, so that names sort by step


def save_checkpoint(model: BaseAlgorithm, checkpoints_dir: Path, manifest: dict[str, Any]) -> Path:
    """Save ``checkpoints_dir/step_<N>/`` as one unit: written under a temporary name, then renamed into place.

    SAC and TD3 also save their replay buffer, kept only in the newest checkpoint (it can be hundreds of MB).
    """
    folder = checkpoints_dir / f"{CHECKPOINT_PREFIX}{model.num_timesteps:010d}"
    checkpoints_dir.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=checkpoints_dir))
    try:
        save_model(model, tmp / "model.zip", manifest)
        if isinstance(model, OffPolicyAlgorithm):
            model.save_replay_buffer(tmp / "replay_buffer.pkl")
        write_json(tmp / "checkpoint.json", {"num_timesteps": model.num_timesteps, "saved": _now()})
        os.chmod(tmp, 0o777 & ~current_umask())
        if folder.exists():  # the same step saved again (Ctrl-C right after a scheduled save): keep the newer one
            shutil.rmtree(folder)
        os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    for old in checkpoints_dir.glob(f"{CHECKPOINT_PREFIX}*/replay_buffer.pkl"):
        if old.parent != folder:
            old.unlink(missing_ok=True)
    return folder


@dataclass
class Checkpoint:
    folder: Path
    num_timesteps: int
    model: BaseAlgorithm  # loaded without an env
    stats: VecNormalize | None


def checkpoints_newest_first(run_dir: Path) -> list[Path]:
    return sorted((run_dir / "checkpoints").glob(f"{CHECKPOINT_PREFIX}*"), key=lambda p: p.name, reverse=True)


def load_checkpoint(folder: Path, algo: str, device: str) -> Checkpoint:
    """Load one checkpoint folder: its marker, its model (and statistics if it needs them); ConfigError if it fails."""
    try:
        record = json.loads((folder / "checkpoint.json").read_text())
        steps = int(record["num_timesteps"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ConfigError(f"{folder.name}: bad or missing checkpoint.json ({exc})") from None
    try:
        _, stats = read_model_file(folder / "model.zip")
        model = load_model(folder / "model.zip", [ALGOS[algo]], device)
    except ModelFileError as exc:
        raise ConfigError(str(exc)) from None
    return Checkpoint(folder, steps, model, stats)


def latest_checkpoint(run_dir: Path, algo: str, device: str) -> Checkpoint:
    """The newest checkpoint of ``run_dir`` that loads; the broken ones newer than it are reported on stderr."""
    skipped = []
    for folder in checkpoints_newest_first(run_dir):
        try:
            checkpoint = load_checkpoint(folder, algo, device)
        except ConfigError as exc:
            skipped.append(str(exc))
            continue
        for reason in skipped:
            print(f"train.py: skipping a broken checkpoint: {reason}", file=sys.stderr)
        return checkpoint
    detail = f" ({'; '.join(skipped)})" if skipped else ""
    raise ConfigError(f"{run_dir}: no checkpoint to resume from (expected {run_dir / 'checkpoints'}/step_*/){detail}")


def check_fits(checkpoint: Checkpoint, venv: VecEnv, env_id: str) -> None:
    """ConfigError if the checkpoint's model was trained on envs unlike ``venv``."""
    model = checkpoint.model
    for what, have, want in (
        ("observation space", model.observation_space, venv.observation_space),
        ("action space", model.action_space, venv.action_space),
        ("number of envs", model.n_envs, venv.num_envs),
    ):
        if have != want:
            venv.close()
            raise ConfigError(
                f"checkpoint {checkpoint.folder / 'model.zip'} does not fit the run's env {env_id}: its {what} is "
                f"{have}, the env's is {want} (trained on another env or version?)"
            )


# what train.py writes into a run folder with envs.common.io.atomic_write (a kill may leave its temporary file)
RUN_FILES = ("config.json", "command.txt", "model.zip")
# a checkpoint folder under the temporary name save_checkpoint gives it: mkdtemp(prefix=".step_<N>.")
UNFINISHED_CHECKPOINT = re.compile(re.escape(f".{CHECKPOINT_PREFIX}") + r"\d{10,}\." + TEMP_RANDOM)


def remove_unfinished_saves(run_dir: Path) -> None:
    """Delete what a killed run left half-written: checkpoint folders under the temporary names save_checkpoint
    gives them (``checkpoints/.step_<N>.<8 random characters>``) and the temporary files atomic_write leaves beside
    config.json, command.txt and model.zip (``.model.<8 random characters>.tmp.zip``, ...). Only these exact names:
    a user's file such as ``.notes.tmp.txt`` stays. Resuming never reads them."""
    checkpoints_dir = run_dir / "checkpoints"
    unfinished = [
        path
        for path in (checkpoints_dir.iterdir() if checkpoints_dir.is_dir() else ())
        if path.is_dir() and not path.is_symlink() and UNFINISHED_CHECKPOINT.fullmatch(path.name)
    ]
    leftovers = sorted([*unfinished, *atomic_write_leftovers(run_dir, RUN_FILES)])
    for path in leftovers:
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    if leftovers:
        names = ", ".join(str(path.relative_to(run_dir)) for path in leftovers)
        print(f"train.py: removed what a killed run left half-written: {names}", file=sys.stderr)


def _now() -> str:
    return datetime.now().isoformat(timespec="seconds")


# --- callbacks --------------------------------------------------------------------------------------------------


class EpisodeMetricsCallback(BaseCallback):
    """Log, per finished episode, each reward term's sum (``reward/<term>``) and the env's episode metrics
    (``episode/<metric>``: speed, cost of transport, the task's own; see agents/evaluation.py).

    The metrics come from the episode's last ``info`` (the running sums every task reports), so they survive the
    vectorized env's auto-reset. Values are averaged over the episodes finished since the last log dump. At the end
    of training the logger is dumped once more, so the last update's train/ metrics and last episodes are not lost.
    """

    def _on_training_start(self) -> None:
        self._terms = [dict() for _ in range(self.training_env.num_envs)]
        self._env = self.training_env.get_attr("unwrapped", [0])[0]

    def _on_step(self) -> bool:
        for i, (info, done) in enumerate(zip(self.locals["infos"], self.locals["dones"], strict=True)):
            terms = self._terms[i]
            for key, value in info.items():
                if key.startswith("reward_"):
                    terms[key[7:]] = terms.get(key[7:], 0.0) + value
            if done:
                self._record(terms, info)
                self._terms[i] = {}
        return True

    def _on_training_end(self) -> None:
        self.logger.dump(self.num_timesteps)

    def _record(self, terms: dict[str, float], info: dict[str, Any]) -> None:
        for term, total in terms.items():
            self.logger.record_mean(f"reward/{term}", total)
        unstable = bool(info.get("sim_unstable", False))
        if not unstable:
            metrics = episode_metrics(self._env, sum(terms.values()), info, bool(info.get("fallen", False)))
            for name, value in metrics.items():
                if name not in ("return", "falls") and np.isfinite(value):
                    self.logger.record_mean(f"episode/{name}", value)
        self.logger.record_mean("episode/fall_rate", float(bool(info.get("fallen", False))))
        self.logger.record_mean("episode/sim_unstable_rate", float(unstable))
        if "episode" in info:
            self.logger.record_mean("episode/length", info["episode"]["l"])


class TimeBudgetCallback(BaseCallback):
    """Stop training (as finished: the final model is saved) once ``minutes`` of wall time have passed since this
    process started learning."""

    def __init__(self, minutes: float):
        super().__init__()
        self.seconds = 60.0 * minutes

    def _on_training_start(self) -> None:
        self._start = time.monotonic()

    def _on_step(self) -> bool:
        if time.monotonic() - self._start < self.seconds:
            return True
        print(f"train.py: the time budget of {self.seconds / 60:g} min is spent at {self.num_timesteps} steps",
              file=sys.stderr)  # fmt: skip
        return False


class ProgressLineCallback(BaseCallback):
    """Without a progress bar (``--no-progress``, or output that is not a terminal), a line of progress a minute, at
    the end of a rollout (:class:`envs.common.io.ProgressLines`: the steps taken of the run's total, the rate, the
    time left) with the mean return of the last episodes (SB3's ``ep_info_buffer``). A log file (``nohup``, the
    leaderboard's rows) then says how far a run of hours has come."""

    def __init__(self, total: int, seconds: float | None = None):
        super().__init__()
        self.lines = ProgressLines(total, "step", seconds)

    def _on_training_start(self) -> None:
        self.lines.start(self.num_timesteps)

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        episodes = self.model.ep_info_buffer
        extra = ""
        if episodes:
            mean = float(np.mean([e["r"] for e in episodes]))
            shown = f"{mean:,.0f}" if abs(mean) >= 1000 else f"{mean:.3g}"
            extra = f"mean return {shown} over the last {len(episodes)} episodes"
        self.lines.update(self.num_timesteps, extra)


class RunCheckpointCallback(BaseCallback):
    """Save a checkpoint folder of the run (:func:`save_checkpoint`) every ``freq`` env steps (all envs together)
    and at the end of training."""

    def __init__(self, checkpoints_dir: Path, freq: int, manifest: dict[str, Any]):
        super().__init__()
        self.checkpoints_dir = checkpoints_dir
        self.freq = freq
        self.manifest = manifest

    def _on_training_start(self) -> None:
        self._last_saved = self.num_timesteps

    def _on_step(self) -> bool:
        if self.num_timesteps - self._last_saved >= self.freq:
            self._save()
        return True

    def _on_training_end(self) -> None:
        if self.num_timesteps != self._last_saved:
            self._save()

    def _save(self) -> None:
        save_checkpoint(self.model, self.checkpoints_dir, self.manifest)
        self._last_saved = self.num_timesteps


# --- training ---------------------------------------------------------------------------------------------------


class ResumedTensorBoard(TensorBoardOutputFormat):
    """SB3's TensorBoard output whose writer hides what earlier writers logged at ``purge_step`` or later (the
    ``SummaryWriter``'s own ``purge_step``): a run killed after its last checkpoint logged steps the resumed run logs
    again, and TensorBoard would draw both."""

    def __init__(self, folder: str, purge_step: int):
        # not super().__init__: it would open a second writer (and events file) without the purge
        self.writer = SummaryWriter(log_dir=folder, purge_step=purge_step)
        self._is_closed = False


def run_manifest(config: dict[str, Any]) -> dict[str, Any]:
    """What a run's model files record about it (a soccer run also its match configuration, a residual policy its
    reference gait and scale)."""
    manifest = {"algo": config["algo"], "env_id": config["env_id"], "seed": config["seed"]}
    residual = config.get("hyperparams", {}).get("residual")
    if residual is not None and names_a_gait(residual):
        manifest["residual"] = parse_residual(residual).record()
    return {**manifest, "soccer": config["soccer"]} if "soccer" in config else manifest


def _say_whole_rollouts(model: BaseAlgorithm, timesteps: int) -> None:
    """An on-policy algorithm (PPO) learns from whole rollouts of ``n_envs x n_steps``: where ``timesteps`` is not a
    whole number of them past the model's steps, the run ends at the next whole one, and says so up front."""
    n_steps = getattr(model, "n_steps", None)
    if not isinstance(n_steps, int) or model.num_timesteps >= timesteps:
        return
    rollout = n_steps * model.n_envs
    left = timesteps - model.num_timesteps
    if left % rollout:
        end = model.num_timesteps + -(-left // rollout) * rollout
        print(f"note: {type(model).__name__} learns from whole rollouts of {rollout} steps ({model.n_envs} envs x "
              f"{n_steps}): this run ends at {end} steps, not {timesteps}", file=sys.stderr)  # fmt: skip


class TrainingDiverged(RuntimeError):
    """The policy's parameters or outputs became NaN or infinite during training."""


def train(model: BaseAlgorithm, run_dir: Path, config: dict[str, Any], progress: bool,
          callbacks: list[BaseCallback] | None = None) -> Path:  # fmt: skip
    """Train ``model`` until it has taken ``config["timesteps"]`` env steps in all, logging and checkpointing into
    ``run_dir``. Returns the path of the final ``model.zip``. On Ctrl-C, saves a checkpoint and re-raises. A resumed
    model (``num_timesteps`` > 0) hides the TensorBoard events the run logged after its checkpoint. ``callbacks``
    log the episodes (default :class:`EpisodeMetricsCallback`)."""
    torch.set_num_threads(TORCH_THREADS)
    folder = str(run_dir / "tb")
    tensorboard = (
        ResumedTensorBoard(folder, model.num_timesteps + 1) if model.num_timesteps else TensorBoardOutputFormat(folder)
    )
    model.set_logger(Logger(folder, [tensorboard]))
    checkpoints_dir = run_dir / "checkpoints"
    manifest = run_manifest(config)
    checkpointing = RunCheckpointCallback(checkpoints_dir, config["checkpoint_freq"], manifest)
    logging = [EpisodeMetricsCallback()] if callbacks is None else callbacks
    if config.get("minutes"):
        logging = [*logging, TimeBudgetCallback(config["minutes"])]
    if not progress:
        logging = [*logging, ProgressLineCallback(config["timesteps"])]
    _say_whole_rollouts(model, config["timesteps"])
    try:
        model.learn(
            config["timesteps"] - model.num_timesteps,
            callback=CallbackList([*logging, checkpointing]),
            reset_num_timesteps=False,
            progress_bar=progress,
        )
    except KeyboardInterrupt:
        folder = save_checkpoint(model, checkpoints_dir, manifest)
        print(f"\ninterrupted at {model.num_timesteps} steps; checkpoint saved in {folder}", file=sys.stderr)
        print(f"continue with: python train.py --resume {resume_argument(run_dir)}", file=sys.stderr)
        raise
    except ValueError as exc:
        cause = diverged_cause(exc)
        if cause is None:
            raise
        kept = checkpoints_newest_first(run_dir)  # the model itself is NaN now: not saved
        where = f"its last checkpoint, {kept[0]}, is kept" if kept else "no checkpoint was saved before it"
        source = config.get("hyperparams_file", "the hyperparameter file")
        raise TrainingDiverged(
            f"training diverged at {model.num_timesteps} steps ({cause}); {where}. A learning rate or clip range too "
            f"large for the task does this: lower learning_rate (or max_grad_norm) in {source}"
        ) from None
    finally:
        model.logger.close()
    return save_model(model, run_dir / "model.zip", manifest)


def new_run_config(args: argparse.Namespace, env_id: str, seed: int, hp: Hyperparams, hyperparams_file: Path,
                   run_dir: Path, extra: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """A new run's ``config.json`` (with ``extra`` entries) and ``command.txt``, written into ``run_dir``."""
    config = {
        "env_id": env_id,
        "algo": args.algo,
        "seed": seed,
        "timesteps": args.timesteps,
        "n_envs": hp.n_envs,
        "normalize": hp.normalize is not None,
        "checkpoint_freq": args.checkpoint_freq,
        "minutes": args.minutes,
        **(extra or {}),
        "hyperparams_file": str(hyperparams_file),
        "hyperparams": hp.raw,
        "versions": versions(),
        "created": _now(),
    }
    write_json(run_dir / "config.json", config)
    write_text(run_dir / "command.txt", command_line() + "\n")
    return config


def start_run(args: argparse.Namespace) -> Path:
    """A new run from the command line's settings; returns the final model's path."""
    if args.soccer is not None:
        return start_selfplay(args)
    for flag, value in (("--env", args.env), ("--algo", args.algo), ("--timesteps", args.timesteps)):
        if value is None:
            raise ConfigError(f"{flag} is required (unless you --resume a run)")
    check_runs_dir(Path(args.runs_dir))
    check_env_id(args.env)
    hyperparams_file = Path(args.hyperparams) if args.hyperparams else HYPERPARAMS_DIR / f"{args.algo}.yml"
    overrides: dict[str, Any] = {"n_envs": args.n_envs} if args.n_envs is not None else {}
    key = entry_key(hyperparams_file, args.env, args.residual is not None)
    hp = load_hyperparams(hyperparams_file, key, args.algo, overrides)
    if args.env_kwargs or args.residual is not None:  # the command line's over the entry's: checked, then again
        env_kwargs = overrides["env_kwargs"] = command_line_env_kwargs(args, hp.env_kwargs)
        if args.residual is not None:
            overrides["residual"] = residual_override(args.residual, args.env, hyperparams_file, env_kwargs, key)
        hp = load_hyperparams(hyperparams_file, key, args.algo, overrides)
    seed = 0 if args.seed is None else args.seed
    set_random_seed(seed)
    check_memory(hp, args.algo, args.env, args.timesteps)
    venv = make_env(args.env, hp, seed)  # a bad env_kwargs fails here, before the run folder is made
    model = build_model(args.algo, hp, venv, seed)
    run_dir = make_run_dir(Path(args.runs_dir), args.run_name or run_name(args.env, args.algo, seed))
    with contextlib.ExitStack() as stack:
        lock_run(run_dir, stack)
        config = new_run_config(args, args.env, seed, hp, hyperparams_file, run_dir, {"hyperparams_entry": key})
        print(f"run folder: {run_dir}")
        return train(model, run_dir, config, progress=progress_bar_wanted(args.no_progress))


def buffer_bytes(hp: Hyperparams, algo: str, observation: gym.Space, action: gym.Space,
                 timesteps: int | None = None) -> tuple[str, int]:  # fmt: skip
    """The algorithm's buffer, in words, and the bytes it fills (as stable-baselines3 allocates them): PPO's rollout
    buffer, every step of a rollout (observations and actions in their spaces' dtypes, six float32 a step besides);
    an off-policy replay buffer, as many steps as the run takes up to its size (``np.zeros`` pages are only used
    once written): observations twice (this one and the next, once with ``optimize_memory_usage``), the action as
    float32 at most, reward, done and timeout."""
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

    obs, act = gym.spaces.flatdim(observation), gym.spaces.flatdim(action)
    obs_item = np.dtype(observation.dtype or np.float64).itemsize
    act_item = np.dtype(action.dtype or np.float32).itemsize
    defaults = algo_defaults(algo)
    if issubclass(ALGOS[algo], OnPolicyAlgorithm):
        n_steps = hp.model_kwargs.get("n_steps", defaults["n_steps"])
        what = f"PPO's rollout buffer (n_steps {n_steps} x n_envs {hp.n_envs})"
        return what, n_steps * hp.n_envs * (obs * obs_item + act * act_item + 6 * 4)
    size = hp.model_kwargs.get("buffer_size", defaults["buffer_size"])
    filled = size if timesteps is None else min(size, timesteps)
    copies = 1 if hp.model_kwargs.get("optimize_memory_usage", defaults["optimize_memory_usage"]) else 2
    what = f"the replay buffer (buffer_size {size}" + ("" if filled == size else f", {filled} steps filled") + ")"
    return what, filled * (copies * obs * obs_item + act * min(act_item, 4) + 3 * 4)


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (Linux's MemAvailable), or None where it cannot be read."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def check_memory(hp: Hyperparams, algo: str, env_id: str, timesteps: int | None = None) -> None:
    """Refuse a run whose buffer would not fit in the memory available (``n_envs`` 100000 and a rollout of 512 steps
    each: 51 million steps held at once), before anything is made; SB3 would allocate it, or only warn."""
    available = available_memory()
    if available is None:
        return
    try:
        env = gym.make(env_id, **hp.env_kwargs)
    except (TypeError, ValueError):
        return  # a bad env_kwargs: make_env names it
    try:
        what, size = buffer_bytes(hp, algo, env.observation_space, env.action_space, timesteps)
    finally:
        env.close()
    if size > available:
        raise ConfigError(f"{hp.where}: {what} would take {size / 2**30:.1f} GiB, more than the "
                          f"{available / 2**30:.1f} GiB of memory available; use fewer envs or a smaller "
                          "buffer")  # fmt: skip


def command_line_env_kwargs(args: argparse.Namespace, entry: dict[str, Any]) -> dict[str, Any]:
    """The entry's env_kwargs with ``--env-kwargs`` over them; where the flag is given, the env is made once, so that
    a bad one is a line naming the flag, before anything is created."""
    if not args.env_kwargs:
        return entry
    env_kwargs = {**entry, **args.env_kwargs}
    try:
        gym.make(args.env, **env_kwargs).close()
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"--env-kwargs {json.dumps(env_kwargs)}: {creator_error(exc)}") from None
    return env_kwargs


def residual_override(name: str, env_id: str, hyperparams_file: Path, env_kwargs: dict[str, Any] | None = None,
                      key: str | None = None) -> dict[str, Any]:  # fmt: skip
    """``--residual NAME``: the residual of the entry ``key`` (default ``env_id``'s) with its gait replaced
    (``reference``: the env's reference, :func:`agents.env_reference`, with ``env_kwargs``), keeping the entry's
    scale and exploration if it sets them."""
    from agents import env_reference

    given_name = name
    env = gym.make(env_id, **(env_kwargs or {}))
    try:
        if name == "reference":
            name = env_reference(env)
        residual_reference(name, env)  # a gait of this robot, named on the command line
    except ValueError as exc:
        raise ConfigError(f"--residual {given_name}: {exc}") from None
    finally:
        env.close()
    return with_entry_settings(name, hyperparams_file, key or env_id)


def start_tuning(args: argparse.Namespace) -> Path:
    """An Optuna study from the command line (``--tune``; agents/tuning.py); returns its folder."""
    check_runs_dir(Path(args.runs_dir))
    check_env_id(args.env)
    hyperparams_file = Path(args.hyperparams) if args.hyperparams else HYPERPARAMS_DIR / f"{args.algo}.yml"
    table = read_yaml(hyperparams_file)
    key = entry_key(hyperparams_file, args.env, args.residual is not None)
    entry = table.get(key) if isinstance(table, dict) else None
    if not isinstance(entry, dict):
        raise ConfigError(f"{hyperparams_file}: no entry (a mapping of hyperparameters) for env {key!r}")
    base = {**entry, **({"n_envs": args.n_envs} if args.n_envs is not None else {})}
    env_kwargs = entry.get("env_kwargs") or {}
    if not isinstance(env_kwargs, dict):
        raise ConfigError(f"{hyperparams_file}: {args.env}: field 'env_kwargs' = {env_kwargs!r}: expected a mapping")
    if args.env_kwargs:
        env_kwargs = base["env_kwargs"] = command_line_env_kwargs(args, env_kwargs)
    if args.residual is not None:
        base["residual"] = residual_override(args.residual, args.env, hyperparams_file, env_kwargs, key)
    return tune(RUN_CODE, args.env, args.algo, base, f"{hyperparams_file}: {key}", args.tune, args.timesteps,
                Path(args.runs_dir), args.storage, args.study, 0 if args.seed is None else args.seed,
                args.evaluations, args.eval_episodes, args.minutes, command_line(),
                args.tune_metric or "return")  # fmt: skip


def start_selfplay(args: Any) -> Path:
    """A new self-play run from train.py's command line (``--soccer``); returns the final model's path."""
    from agents.soccer.selfplay import SCRIPTED, SelfPlayCallback, SelfPlayVecEnv

    check_runs_dir(Path(args.runs_dir))
    key = f"soccer/{args.soccer}"
    hyperparams_file = Path(args.hyperparams) if args.hyperparams else HYPERPARAMS_DIR / "ppo.yml"
    overrides = {"n_envs": args.n_envs} if args.n_envs is not None else {}
    if args.residual is not None:
        overrides["residual"] = selfplay_residual(args.residual, key, hyperparams_file)
    hp = load_hyperparams(hyperparams_file, key, "ppo", overrides, players=args.players)
    if hp.residual is not None and hp.residual.policy != SCRIPTED:
        raise ConfigError(f"{hp.where}: field 'residual' = {hp.raw['residual']!r}: self-play corrects the "
                          f"scripted team (policy {SCRIPTED!r}), not a gait (the commands mode runs it)")  # fmt: skip
    seed = 0 if args.seed is None else args.seed
    set_random_seed(seed)
    soccer = {"robot": args.soccer, "players_per_team": args.players, "action_mode": COMMANDS,
              "match_seconds": args.match_seconds, "scripted_share": args.scripted_share, **hp.env_kwargs}  # fmt: skip
    if hp.residual is not None:
        soccer["residual"] = hp.residual.scale
    try:
        venv = SelfPlayVecEnv(hp.n_envs, pool_seed=seed, nthread=hp.nthread, **soccer)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{hp.where}: field 'env_kwargs' = {hp.env_kwargs!r}: {exc}") from None
    pool = venv.pool
    learner_env: VecEnv = VecNormalize(venv, **hp.normalize) if hp.normalize is not None else venv
    model = build_model("ppo", hp, learner_env, seed)
    run_dir = make_run_dir(Path(args.runs_dir), args.run_name or run_name(key, "ppo", seed))
    with contextlib.ExitStack() as stack:
        lock_run(run_dir, stack)
        extra = {"snapshot_freq": args.snapshot_freq or args.checkpoint_freq, "soccer": soccer}
        config = new_run_config(args, key, seed, hp, hyperparams_file, run_dir, extra)
        print(f"run folder: {run_dir} ({hp.n_envs} matches, {args.players} a side, {venv.num_envs} learner players)")
        callback = SelfPlayCallback(pool, run_dir, config["snapshot_freq"], run_manifest(config))
        return train(model, run_dir, config, progress=progress_bar_wanted(args.no_progress), callbacks=[callback])


def selfplay_residual(name: str, key: str, hyperparams_file: Path) -> dict[str, Any]:
    """``--residual NAME`` for self-play: the scripted team (``scripted``, or ``reference``, which is it for a team),
    keeping the entry's scale and exploration if it sets them."""
    from agents.soccer.selfplay import SCRIPTED

    if name not in (SCRIPTED, "reference"):
        raise ConfigError(f"--residual {name}: self-play corrects the scripted team: give {SCRIPTED!r}")
    return with_entry_settings(SCRIPTED, hyperparams_file, key)


def with_entry_settings(policy: str, hyperparams_file: Path, key: str) -> dict[str, Any]:
    """A residual on ``policy`` with the scale and exploration the hyperparameter file's entry ``key`` sets, if it
    sets them (its ``residual``, with a policy or without)."""
    table = read_yaml(hyperparams_file)
    entry = table.get(key) if isinstance(table, dict) else None
    given = entry.get("residual") if isinstance(entry, dict) else None
    settings = {k: given[k] for k in SETTINGS if k in given} if isinstance(given, dict) else {}
    return {"policy": policy, **settings}


def resumed_selfplay(config: dict[str, Any], hp: Any, seed: int, checkpoint: Any, run_dir: Path):
    """The learner's env and callbacks for ``train.py --resume`` of a self-play run: its matches as ``config`` made
    them, its pool of the snapshots taken up to the checkpoint (later ones, which a killed run may leave, are
    removed) and the ratings as last written. Returns (env, callbacks)."""
    from agents.sb3 import SB3Policy
    from agents.soccer.selfplay import POOL_DIR, RATINGS_FILE, SelfPlayCallback, SelfPlayVecEnv, SnapshotOpponent

    soccer = dict(config["soccer"])
    try:
        venv = SelfPlayVecEnv(hp.n_envs, pool_seed=seed, nthread=hp.nthread, **soccer)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{run_dir / 'config.json'}: field 'soccer' = {soccer!r}: {exc}") from None
    check_fits(checkpoint, venv, config["env_id"])
    pool = venv.pool
    snapshots = sorted((run_dir / POOL_DIR).glob("step_*.zip"))
    for path in snapshots:
        if int(path.stem.split("_")[1]) > checkpoint.num_timesteps:
            path.unlink()
    kept = [p for p in snapshots if p.exists()][-pool.pool_size :]
    for path in kept:
        policy = SB3Policy(path)
        pool.opponents[path.stem] = SnapshotOpponent(policy.model.policy, policy.normalizer, pool.base, pool.residual)
    ratings_file = run_dir / RATINGS_FILE
    if ratings_file.is_file():
        try:
            saved = json.loads(ratings_file.read_text())
            pool.ratings.update(
                {k: float(v) for k, v in saved["ratings"].items() if k in pool.opponents or k == "learner"}
            )
            for name, record in saved["learner_record"].items():
                if name in pool.opponents:
                    pool.records[name] = [int(record[k]) for k in ("wins", "draws", "losses")]
        except (ValueError, KeyError, TypeError) as exc:
            raise ConfigError(f"{ratings_file}: cannot read the ratings ({exc})") from None
    for name in pool.opponents:
        pool.ratings.setdefault(name, pool.ratings["learner"])
        pool.records.setdefault(name, [0, 0, 0])
    learner_env: VecEnv = venv
    if hp.normalize is not None:
        checkpoint.stats.set_venv(venv)
        checkpoint.stats.training = True
        learner_env = checkpoint.stats
    callback = SelfPlayCallback(pool, run_dir, config.get("snapshot_freq") or config["checkpoint_freq"],
                                run_manifest(config))  # fmt: skip
    return learner_env, [callback]


RUN_LOCK = "train.lock"  # in the run folder: held while a train.py process writes it (envs.common.io.folder_lock)


def lock_run(run_dir: Path, stack: contextlib.ExitStack) -> None:
    """Hold the lock of ``run_dir`` until ``stack`` closes, so that one train.py process at a time writes the run
    folder: a second one (a resume of a running run, two resumes at once) gets :class:`envs.common.io.Busy` at once,
    before it reads or removes anything. The kernel releases the lock when the process ends, however it ends."""
    try:
        stack.enter_context(folder_lock(run_dir, "train.py", RUN_LOCK))
    except OSError as exc:
        raise ConfigError(f"{run_dir}: cannot lock the run folder ({exc.strerror or exc})") from None


def resume_folder(target: str, runs_dir: str) -> Path:
    """The run folder ``--resume TARGET`` names: a run's name (no ``/``) is a folder of ``--runs-dir``; anything
    else (``runs/x``, ``./x``, an absolute path) is the folder's path as given."""
    if Path(target).name != target or target in (".", ".."):
        path = Path(target)
        if not path.is_dir():
            problem = "is not a folder" if path.exists() else "does not exist"
            raise ConfigError(f"--resume {target}: {problem}; give a run folder (one holding config.json)")
        return path
    run_dir = Path(runs_dir) / target
    if not run_dir.is_dir():
        here = f"; to resume the folder {target} here, give --resume ./{target}" if Path(target).is_dir() else ""
        raise ConfigError(
            f"--resume {target}: no run folder {run_dir} (a run's name is looked up in --runs-dir {runs_dir}){here}"
        )
    return run_dir


def resume_argument(run_dir: Path) -> str:
    """What to pass to ``--resume`` to continue ``run_dir`` from the same folder with the same ``--runs-dir``."""
    return shlex.quote(str(run_dir) if Path(run_dir.name) != run_dir else f"./{run_dir}")


def resume_run(args: argparse.Namespace) -> Path:
    """Continue the run ``args.resume`` names (:func:`resume_folder`) from its newest whole checkpoint; returns the
    final model's path. The run folder is locked first (:func:`lock_run`): a second resume of it is refused."""
    run_dir = resume_folder(args.resume, args.runs_dir)
    config_path = run_dir / "config.json"
    if not config_path.is_file():  # not a run folder: refused before its lock file is made in it
        raise ConfigError(f"--resume {run_dir}: cannot read {config_path} (no such file: not a run folder)")
    read_run_config(run_dir)  # a damaged config.json is refused before the lock file is made, too
    with contextlib.ExitStack() as stack:
        lock_run(run_dir, stack)
        return _resume_locked(args, run_dir)


SOCCER_NUMBERS = ("match_seconds", "scripted_share", "residual")  # a self-play run's numeric match settings


def read_run_config(run_dir: Path) -> dict[str, Any]:
    """A run's ``config.json``, checked for what ``--resume`` reads from it; a :class:`ConfigError` names the file,
    the field and its value."""
    config_path = run_dir / "config.json"
    try:
        config = json.loads(config_path.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"--resume {run_dir}: cannot read {config_path} ({exc})") from None
    if not isinstance(config, dict):
        raise ConfigError(f"{config_path}: expected a JSON object of the run's settings, got {type(config).__name__}")
    missing = [key for key in ("algo", "seed", "env_id", "hyperparams") if key not in config]
    if missing:
        raise ConfigError(f"{config_path}: field {missing[0]!r} is missing")
    for key, least in (("seed", 0), ("timesteps", 1), ("n_envs", 1)):  # what the resume reads
        value = config.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < least:
            raise ConfigError(f"{config_path}: field {key!r} = {value!r}: expected a whole number of at least {least}")
    if config["algo"] not in ALGOS:
        raise ConfigError(f"{config_path}: field 'algo' = {config['algo']!r}: expected one of {', '.join(ALGOS)}")
    env_id = config["env_id"]
    if isinstance(env_id, str) and env_id.startswith("soccer/"):  # a self-play run: its matches' settings
        soccer = config.get("soccer")
        if not isinstance(soccer, dict):
            raise ConfigError(f"{config_path}: field 'soccer' = {soccer!r}: a self-play run ({env_id}) needs its "
                              "match settings as a JSON object")  # fmt: skip
        for key in SOCCER_NUMBERS:
            value = soccer.get(key)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not math.isfinite(value)):  # fmt: skip
                raise ConfigError(f"{config_path}: field 'soccer.{key}' = {value!r}: expected a finite number")
    return config


def _resume_locked(args: argparse.Namespace, run_dir: Path) -> Path:
    config_path = run_dir / "config.json"
    config = read_run_config(run_dir)
    algo, seed, env_id, hyperparams = config["algo"], config["seed"], config["env_id"], config["hyperparams"]
    check_resume_flags(args, config)
    if "soccer" not in config:
        check_env_id(env_id, f"{config_path}: field 'env_id': ")
    players = config["soccer"].get("players_per_team", 1) if isinstance(config.get("soccer"), dict) else 1
    hp = resolve_hyperparams(hyperparams, algo, where=str(config_path), players=players)
    checkpoint = latest_checkpoint(run_dir, algo, hp.model_kwargs.get("device", "cpu"))
    done = checkpoint.num_timesteps
    timesteps = args.timesteps or config["timesteps"]
    if timesteps <= done:
        raise ConfigError(f"{run_dir} has already trained {done} steps; pass a larger --timesteps to continue")
    if hp.normalize is not None and checkpoint.stats is None:
        raise ConfigError(f"{checkpoint.folder}: the run normalizes observations but the checkpoint has no statistics")
    set_random_seed(seed + done)  # not the first run's seeds: the resumed episodes should differ from its first ones
    callbacks = None
    if "soccer" in config:  # a self-play run: its matches, and its pool and ratings as the checkpoint left them
        venv, callbacks = resumed_selfplay(config, hp, seed + done, checkpoint, run_dir)
    else:
        venv = make_env(env_id, hp, seed + done, checkpoint)
    model = checkpoint.model
    model.set_env(venv)
    replay_buffer = checkpoint.folder / "replay_buffer.pkl"
    if isinstance(model, OffPolicyAlgorithm):
        if replay_buffer.is_file():
            try:
                model.load_replay_buffer(replay_buffer)
            except Exception as exc:  # unpickling a damaged file raises anything
                raise ConfigError(
                    f"cannot read checkpoint {replay_buffer}: {error_reason(exc)}; delete it to continue with an "
                    "empty replay buffer"
                ) from None
        else:
            print(
                f"train.py: {checkpoint.folder.name} has no replay buffer; continuing with an empty one",
                file=sys.stderr,
            )
    remove_unfinished_saves(run_dir)
    config["timesteps"] = timesteps
    config["checkpoint_freq"] = args.checkpoint_freq or config.get("checkpoint_freq", DEFAULT_CHECKPOINT_FREQ)
    config["minutes"] = args.minutes  # a budget for this process's training, not the run's
    config.setdefault("resumed", []).append({"from_timesteps": done, "timesteps": timesteps, "time": _now()})
    write_json(config_path, config)
    command_file = run_dir / "command.txt"
    previous = command_file.read_text() if command_file.is_file() else ""
    write_text(command_file, previous + command_line() + "\n")
    print(f"resuming {run_dir} from {checkpoint.folder.name} ({done} steps) to {timesteps} steps")
    return train(model, run_dir, config, progress=progress_bar_wanted(args.no_progress), callbacks=callbacks)


def check_env_id(env_id: str, source: str = "") -> None:
    """Refuse an id that is not a skitter env; ``source`` names where it came from (a run's config.json)."""
    problem = skitter_env_problem(env_id)
    if problem is not None:
        raise ConfigError(f"{source}{problem}")


def check_resume_flags(args: argparse.Namespace, config: dict[str, Any]) -> None:
    """With --resume, settings come from the run's config.json; flags may repeat them but not change them."""
    for flag, given, recorded in (
        ("--env", args.env, config["env_id"]),
        ("--algo", args.algo, config["algo"]),
        ("--seed", args.seed, config["seed"]),
        ("--n-envs", args.n_envs, config["n_envs"]),
    ):
        if given is not None and given != recorded:
            raise ConfigError(f"{flag} {given} differs from the resumed run's {recorded}; drop {flag} to resume")
    for flag, given in (("--hyperparams", args.hyperparams), ("--run-name", args.run_name)):
        if given is not None:
            raise ConfigError(f"{flag} cannot be used with --resume: the run keeps its own folder and hyperparameters")


# --- command line -----------------------------------------------------------------------------------------------


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = ToolParser(prog="train.py", description="Train an SB3 agent on a skitter env (see the module docstring).")
    parser.add_argument("--env", help="gymnasium env id, e.g. skitter/RoachWalk-v4")
    parser.add_argument("--algo", choices=sorted(ALGOS), help="algorithm")
    parser.add_argument("--timesteps", type=at_least_one, help="total env steps (with --resume: default the run's)")
    parser.add_argument("--seed", type=non_negative, help="random seed, >= 0 (default 0)")
    parser.add_argument("--n-envs", type=at_least_one, help="override the hyperparameter file's n_envs")
    parser.add_argument("--hyperparams", help="hyperparameter YAML file (default hyperparams/<algo>.yml)")
    parser.add_argument(
        "--resume",
        metavar="RUN",
        help="continue this run from its latest checkpoint: a run folder's path (runs/<run>, ./<run>, /abs/<run>) or a "
        "run's name without '/', which is looked up in --runs-dir",
    )
    parser.add_argument(
        "--runs-dir",
        default="runs",
        help="where run folders are created, and where --resume looks up a run's name (default runs)",
    )
    parser.add_argument("--run-name", help="run folder name (default <env>__<algo>__<seed>__<date-time>)")
    parser.add_argument(
        "--checkpoint-freq",
        type=at_least_one,
        help=f"env steps between checkpoints (default {DEFAULT_CHECKPOINT_FREQ})",
    )
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar: a line of progress a minute instead (as when the output is not a terminal)",
    )
    parser.add_argument("--residual", metavar="GAIT",
                        help="train a residual policy on top of this scripted gait ('reference': the env's own, the "
                             "robot's reference gait or on a soccer academy task in the commands mode the scripted "
                             "player; agents/residual.py), whatever the hyperparameter entry says; with --soccer, "
                             "'scripted': on top of the scripted team")  # fmt: skip
    parser.add_argument("--env-kwargs", metavar="JSON",
                        help="the env's keyword arguments as a JSON object, over the hyperparameter entry's "
                             "env_kwargs, e.g. '{\"action_mode\": \"commands\"}'")  # fmt: skip
    parser.add_argument("--minutes", type=float,
                        help="stop after this much wall time (the model is saved as at --timesteps)")  # fmt: skip
    tuning = parser.add_argument_group("hyperparameter tuning (agents/tuning.py; Optuna, PPO and SAC)")
    tuning.add_argument("--tune", type=at_least_one, metavar="TRIALS",
                        help="run this many Optuna trials of --timesteps each instead of one run")  # fmt: skip
    tuning.add_argument("--storage", help="the study's database URL (default sqlite:///<runs-dir>/tuning.db)")
    tuning.add_argument("--study", help="the study's name (default <env>__<algo>); processes sharing it share trials")
    tuning.add_argument(
        "--evaluations",
        type=at_least_one,
        help=f"evaluations per trial, each reported to the pruner (default {TUNE_EVALUATIONS})",
    )
    tuning.add_argument("--eval-episodes", type=at_least_one,
                        help=f"episodes per evaluation (default {TUNE_EVAL_EPISODES})")  # fmt: skip
    tuning.add_argument("--tune-metric", metavar="METRIC",
                        help="what a trial scores: the mean return (default), or an episode metric of the env, "
                             "such as speed or yaw_rate_error (minimized where smaller is better)")  # fmt: skip
    soccer = parser.add_argument_group("soccer self-play (agents/soccer/selfplay.py; PPO, the commands mode)")
    soccer.add_argument("--soccer", choices=SOCCER_ROBOTS, help="train a team of this robot by self-play")
    soccer.add_argument("--players", type=at_least_one, help="players a side, 1 to 4 (default 3)")
    soccer.add_argument("--match-seconds", type=float, help="each match's length, s (default 60)")
    soccer.add_argument(
        "--scripted-share",
        type=float,
        help="the share of matches against the scripted team (default 0.5; else past snapshots)",
    )
    soccer.add_argument(
        "--snapshot-freq",
        type=at_least_one,
        help="env steps between the learner's snapshots into its pool (default --checkpoint-freq)",
    )
    args = parser.parse_args(argv)
    self_play = {"players": 3, "match_seconds": 60.0, "scripted_share": 0.5, "snapshot_freq": None}
    if args.soccer is None:
        given = [name for name in self_play if getattr(args, name) is not None]
        if given and args.resume:
            parser.error(f"--{given[0].replace('_', '-')}: --resume takes the run's settings from its folder (a "
                         "self-play run keeps its own): give --resume alone")  # fmt: skip
        if given:
            parser.error(f"--{given[0].replace('_', '-')} is a self-play option: give --soccer ROBOT with it")
    for name, default in self_play.items():
        if getattr(args, name) is None:
            setattr(args, name, default)
    if args.soccer is not None:
        if args.env is not None:
            parser.error("give --env (one robot's env) or --soccer (a team by self-play), not both")
        if args.resume:
            parser.error("--resume takes the run's settings from its folder: give --resume alone, without --soccer")
        if args.algo not in (None, "ppo"):
            parser.error(f"--soccer trains with PPO, not {args.algo}")
        args.algo = "ppo"
        if args.players > 4:
            parser.error(f"--players must be from 1 to 4, got {args.players}")
        if not 0 < args.match_seconds <= 3600:
            parser.error(f"--match-seconds must be in (0, 3600], got {args.match_seconds}")
        if not 0.0 <= args.scripted_share <= 1.0:
            parser.error(f"--scripted-share must be in [0, 1], got {args.scripted_share}")
    if args.env_kwargs is not None:
        if args.resume or args.soccer is not None:
            parser.error("--env-kwargs sets a new run's env: not with --resume (the run keeps its own) or --soccer")
        try:
            args.env_kwargs = json_object(args.env_kwargs, "--env-kwargs")
        except ValueError as exc:
            parser.error(str(exc))
    if args.residual is not None and args.resume:
        parser.error("--residual starts a new run: not with --resume (the run keeps its own)")
    if args.tune is not None:
        if args.resume or args.soccer is not None:
            parser.error("--tune runs a study of one env's training: not with --resume or --soccer")
        for flag, value in (("--env", args.env), ("--algo", args.algo), ("--timesteps", args.timesteps)):
            if value is None:
                parser.error(f"--tune needs {flag}")
        if args.algo not in ("ppo", "sac"):
            parser.error(f"--tune tunes ppo and sac, not {args.algo}")
        for flag, value in (("--run-name", args.run_name), ("--checkpoint-freq", args.checkpoint_freq)):
            if value is not None:  # a trial keeps no run folder or checkpoints: the study's files are its output
                parser.error(f"{flag} is for one training run: --tune writes its study under "
                             "<runs-dir>/tuning/<study>/ and keeps no checkpoints")  # fmt: skip
        args.evaluations = TUNE_EVALUATIONS if args.evaluations is None else args.evaluations
        args.eval_episodes = TUNE_EVAL_EPISODES if args.eval_episodes is None else args.eval_episodes
    else:
        for flag, value in (("--storage", args.storage), ("--study", args.study), ("--evaluations", args.evaluations),
                            ("--eval-episodes", args.eval_episodes), ("--tune-metric", args.tune_metric)):  # fmt: skip
            if value is not None:
                parser.error(f"{flag} goes with --tune")
    for flag, value in (("--runs-dir", args.runs_dir), ("--resume", args.resume)):
        if value is not None and not value.strip():
            parser.error(f"argument {flag}: expected a folder, got an empty path {value!r}")
    if args.run_name is not None and (
        not args.run_name or Path(args.run_name).name != args.run_name or args.run_name in (".", "..")
    ):
        parser.error(f"argument --run-name: expected a new folder's name (no '/', not . or ..), got {args.run_name!r}")
    if args.minutes is not None and not 0 < args.minutes < 10**6:
        parser.error(f"argument --minutes: expected a positive number of minutes, got {args.minutes}")
    if args.checkpoint_freq is None and not args.resume:
        args.checkpoint_freq = DEFAULT_CHECKPOINT_FREQ
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        default_threads()  # the environment's thread cap, before it is blamed on a hyperparameter file
    except ValueError as exc:
        print(f"train.py: error: {exc}", file=sys.stderr)
        return 2
    try:
        if args.tune is not None:
            with sigterm_as_interrupt():
                folder = start_tuning(args)
            print(f"study: {folder} (best.yml, trials.csv, study.json)")
            return 0
        with sigterm_as_interrupt():  # SIGTERM too: train() saves a checkpoint first
            model_path = resume_run(args) if args.resume else start_run(args)
    except ConfigError as exc:
        print(f"train.py: error: {exc}", file=sys.stderr)
        return 2
    except Busy as exc:  # another train.py writes the run folder
        print(exc, file=sys.stderr)
        return 1
    except TrainingDiverged as exc:
        print(f"train.py: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        return interrupted_exit_code(exc)
    print(f"model: {model_path}")
    print(f"tensorboard: tensorboard --logdir {model_path.parent / 'tb'}")
    return 0
