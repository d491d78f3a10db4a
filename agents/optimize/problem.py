"""What an optimizer scores: a controller's parameters rolled out on a robot of a registered env, many at once.

A **run configuration** (JSON) names the env, the controller (from the robot folder's ``CONTROLLERS``: a builder
that takes the configuration's remaining fields and the robot) and how a rollout is scored::

    {
      "env": "skitter/BioloidWalk-v2",     # any registered id; its robot runs the rollouts
      "env_kwargs": {},                    # keyword arguments of the env (e.g. {"knee_wedge": true})
      "controller": "cpg",                 # a name in the robot folder's CONTROLLERS
      "seconds": 32,                       # rollout length (the report: 32 s)
      "objective": "forward",              # "forward" (default) or "distance_travelled"
      "sample_interval": 1.0,              # s between the trajectory samples of eq. 17 (the report: 1 s)
      "max_tilt": 1.0,                     # rad: a body tilted further has fallen
      "coupling": "experiment5"            # ... the controller's own fields
    }

**Scores** of a rollout (all reported; ``objective`` picks the one maximized):

- ``distance_travelled``: the Bioloid report's performance measure [bioloid-webots, eq. 17], ``|p_N - p_1| + sum
  |p_(i+1) - p_i|`` over the body's ground positions sampled every ``sample_interval`` from the start to the end:
  the displacement plus the path length, in any direction, so it rewards walking backward and tumbling too
  (``"eq17"``, its earlier name, is still read in a configuration, with a warning);
- ``forward``: progress along +x from the start to the first fall (or the end): walking forward, upright;
- ``progress_x``: progress along +x at the end, fallen or not (signed); ``fallen``: 1 if the body tilted past
  ``max_tilt`` at any control step, or broke the env's ground rules (anything but the feet on the ground, or the
  body out of its height band, past the grace time: docs/envs.md; not with ``terminate_when_unhealthy: false`` in
  ``env_kwargs``); ``fall_time``: when (s; the rollout's length if never).

A rollout starts from the robot's reset posture without noise, so that the same parameters always score the same,
unless the configuration's ``env_kwargs`` ask otherwise: ``reset_noise_scale`` perturbs each rollout's start as the
env's reset does, and ``randomize`` draws the named physical parameters for each rollout (domain randomization per
particle and iteration). The draws come from the evaluation's ``draw`` key and each row's index in the swarm, so a
run resumed from its checkpoint draws what the uninterrupted run drew.
The whole batch of parameters runs as one ``mujoco.batch`` of simulations (the env's batched robot), the controller
vectorized over them; a control step is the robot's ``command`` and ``step`` (no Python per physics step).
"""

from __future__ import annotations

import functools
import importlib
import json
import math
import pkgutil
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from agents.config import ConfigError
from envs.common.io import not_a_file
from envs.common.locomotion import leaky_count
from envs.common.parameters import sample

OBJECTIVES = ("forward", "distance_travelled")
DEPRECATED_OBJECTIVES = {"eq17": "distance_travelled"}  # an earlier name -> the objective it names now
GENERIC_FIELDS = {"env", "env_kwargs", "controller", "seconds", "objective", "sample_interval", "max_tilt"}


def distance_travelled(positions: np.ndarray, alpha: float = 1.0, beta: float = 1.0) -> np.ndarray:
    """The Bioloid report's performance measure [bioloid-webots, eq. 17] of trajectories sampled at fixed intervals,
    (n, N, 2) ground positions: ``alpha |p_N - p_1| + beta sum_i |p_(i+1) - p_i|``, the displacement plus the path
    length, in any direction (the report: alpha = beta = 1)."""
    p = np.asarray(positions, dtype=np.float64)
    straight = np.linalg.norm(p[:, -1] - p[:, 0], axis=1)
    integrated = np.linalg.norm(np.diff(p, axis=1), axis=2).sum(axis=1)
    return alpha * straight + beta * integrated


class Controller(Protocol):
    """A parameterized controller, vectorized over simulations."""

    dimension: int

    def start(self, parameters: np.ndarray) -> None:
        """Begin rollouts of ``parameters`` (n, dimension) in [0, 1]."""

    def commands(self) -> np.ndarray:
        """Physical commands (n, action size) of the robot's action mode for the next control step."""

    def policy_record(self, parameters: np.ndarray) -> dict[str, Any]:
        """The policy file's content for one parameter vector (loaded by the robot folder's policy)."""


@dataclass(frozen=True)
class RunConfig:
    """A checked run configuration."""

    env: str
    controller: str
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    seconds: float = 32.0
    objective: str = "forward"
    sample_interval: float = 1.0
    max_tilt: float = 1.0
    controller_fields: Mapping[str, Any] = field(default_factory=dict)
    path: str = "<inline>"

    def to_dict(self) -> dict[str, Any]:
        return {"env": self.env, "env_kwargs": dict(self.env_kwargs), "controller": self.controller,
                "seconds": self.seconds, "objective": self.objective, "sample_interval": self.sample_interval,
                "max_tilt": self.max_tilt, **dict(self.controller_fields)}  # fmt: skip


def controllers() -> dict[str, tuple[str, str]]:
    """Every robot folder's optimizable controllers: name -> (robot folder, "module:builder")."""
    import agents

    found = {}
    for module in pkgutil.iter_modules(agents.__path__):
        if module.ispkg:
            package = importlib.import_module(f"agents.{module.name}")
            for name, target in getattr(package, "CONTROLLERS", {}).items():
                found[name] = (module.name, target)
    return found


def parse_config(raw: Any, path: str = "<inline>") -> RunConfig:
    """Check a run configuration; :class:`ConfigError` names the file and the field."""
    import envs  # noqa: F401  (registers the envs)

    if not isinstance(raw, Mapping):
        raise ConfigError(f"{path}: a run configuration is a JSON object, got {type(raw).__name__}")
    env = raw.get("env")
    if not isinstance(env, str) or env not in gym.registry:
        known = ", ".join(sorted(k for k in gym.registry if k.startswith("skitter/")))
        raise ConfigError(f"{path}: field 'env': {env!r} is not a registered env ({known})")
    kwargs = raw.get("env_kwargs", {})
    if not isinstance(kwargs, Mapping):
        raise ConfigError(f"{path}: field 'env_kwargs' must be an object of keyword arguments, got {kwargs!r}")
    name = raw.get("controller")
    known_controllers = controllers()
    if name not in known_controllers:
        raise ConfigError(f"{path}: field 'controller': {name!r} is not one of {sorted(known_controllers)}")

    def number(key: str, default: float, low: float, high: float) -> float:
        value = raw.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ConfigError(f"{path}: field {key!r} must be a finite number, got {value!r}")
        if not low < value <= high:
            raise ConfigError(f"{path}: field {key!r} must be in ({low}, {high}], got {value!r}")
        return float(value)

    seconds = number("seconds", 32.0, 0.0, 3600.0)
    interval = number("sample_interval", 1.0, 0.0, seconds)
    objective = raw.get("objective", "forward")
    if isinstance(objective, str) and objective in DEPRECATED_OBJECTIVES:
        renamed = DEPRECATED_OBJECTIVES[objective]
        warnings.warn(f"{path}: field 'objective': {objective!r} is a deprecated name of {renamed!r}; write "
                      f"{renamed!r}", FutureWarning, stacklevel=2)  # fmt: skip
        objective = renamed
    if objective not in OBJECTIVES:
        raise ConfigError(f"{path}: field 'objective' must be one of {OBJECTIVES}, got {objective!r}")
    return RunConfig(
        env=env,
        controller=name,
        env_kwargs=dict(kwargs),
        seconds=seconds,
        objective=objective,
        sample_interval=interval,
        max_tilt=number("max_tilt", 1.0, 0.0, math.pi),
        controller_fields={k: v for k, v in raw.items() if k not in GENERIC_FIELDS},
        path=path,
    )


def read_config(path: str | Path) -> RunConfig:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: {not_a_file(p, 'run configuration')}")
    try:
        raw = json.loads(p.read_text(), object_pairs_hook=functools.partial(_unique_keys, p))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ConfigError(f"{p}: not valid JSON ({error})") from None
    return parse_config(raw, str(p))


def _unique_keys(path: Path, pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's pairs as a dict, or a :class:`ConfigError` naming the file and a key given twice (JSON keeps
    the last silently, and a setting written twice is one of them lost)."""
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise ConfigError(f"{path}: key {key!r} is given twice; give each field once")
        seen[key] = value
    return seen


def build_controller(config: RunConfig, robot) -> Controller:
    """The configuration's controller for ``robot`` (its builder checks its own fields)."""
    folder, target = controllers()[config.controller]
    if robot.name != folder:
        raise ConfigError(f"{config.path}: field 'controller': {config.controller!r} drives a {folder}, "
                          f"but {config.env} runs a {robot.name}")  # fmt: skip
    module, _, attribute = target.partition(":")
    builder = getattr(importlib.import_module(module), attribute)
    try:
        return builder(dict(config.controller_fields), robot)
    except (TypeError, ValueError) as error:
        raise ConfigError(f"{config.path}: {error}") from None


class Evaluator:
    """Rollouts of a run configuration, ``num_sims`` at a time on one ``mujoco.batch``.

    Args:
        config: the run configuration.
        num_sims: simulations per batch (an optimizer's swarm or population, or a worker's share of it).
        nthread: the batch's threads (default: the machine's cores).
        controller: a controller to use instead of the configuration's (benchmarks of scripted gaits), built for
            ``num_sims`` rows; called with the robot.
    """

    def __init__(self, config: RunConfig, num_sims: int, nthread: int | None = None, controller=None):
        import envs  # noqa: F401

        self.config = config
        kwargs = {"sensor_noise": False, **dict(config.env_kwargs)}  # the scores do not read the IMU
        try:
            venv = gym.make_vec(config.env, num_envs=num_sims, vectorization_mode="vector_entry_point",
                                nthread=nthread, **kwargs)  # fmt: skip
        except (TypeError, ValueError) as error:  # the env's own checks (values, calibration files, names)
            raise ConfigError(f"{config.path}: field 'env_kwargs' = {dict(config.env_kwargs)!r}: {error}") from None
        self.robot = venv.unwrapped.robot
        self.task = venv.unwrapped.task
        env = venv.unwrapped.env  # the env's own checked values of its keyword arguments
        self.randomize = dict(env.randomize or {})
        # without one in the configuration, no reset noise: the same parameters always score the same
        self.reset_noise_scale = env.reset_noise_scale if "reset_noise_scale" in config.env_kwargs else 0.0
        self.num_sims = num_sims
        self.controller = build_controller(config, self.robot) if controller is None else controller(self.robot)
        self.steps = max(1, round(config.seconds / self.robot.control_dt))
        self.sample_every = max(1, round(config.sample_interval / self.robot.control_dt))
        self._ids = np.arange(num_sims)
        self._rngs = [np.random.default_rng(0) for _ in range(num_sims)]
        self._min_up = math.cos(config.max_tilt)

    @property
    def dimension(self) -> int:
        return self.controller.dimension

    def evaluate(self, parameters: np.ndarray, draw: Sequence[int] = (), first: int = 0) -> dict[str, np.ndarray]:
        """Scores of every row of ``parameters`` (n <= num_sims, dimension): a dict of (n,) arrays. With
        ``randomize`` or ``reset_noise_scale`` in the configuration's ``env_kwargs``, row ``j``'s physical parameters
        and start are drawn from the generator seeded with ``(*draw, first + j)``: ``draw`` names the evaluation (a
        run's seed and iteration), ``first`` the row's place in the whole swarm (a worker's share starts there)."""
        params = np.atleast_2d(np.asarray(parameters, dtype=np.float64))
        n = len(params)
        if n > self.num_sims or params.shape[1] != self.dimension:
            raise ValueError(f"parameters must be (<= {self.num_sims}, {self.dimension}), got {params.shape}")
        if n < self.num_sims:  # pad with copies: the batch always runs whole
            params = np.concatenate([params, np.repeat(params[-1:], self.num_sims - n, axis=0)])
        robot = self.robot
        if self.randomize or self.reset_noise_scale:
            self._rngs = [np.random.default_rng([*map(int, draw), first + j]) for j in range(self.num_sims)]
            for j, rng in enumerate(self._rngs):
                if self.randomize:
                    robot.set_parameters(self._ids[j : j + 1], sample(self.randomize, rng))
        robot.reset(self._ids, self._rngs, self.reset_noise_scale, None)
        self.controller.start(params)
        readings = robot.read(self._rngs, stepped=False)
        samples = [readings["position"][:, :2].copy()]
        x0 = readings["position"][:, 0].copy()
        fallen = np.zeros(self.num_sims, dtype=bool)
        fall_x = np.zeros(self.num_sims)
        fall_time = np.full(self.num_sims, self.steps * robot.control_dt)
        rules = getattr(self.task, "terminate_when_unhealthy", False)  # a walking task's ground rules
        contact_time, band_time = np.zeros(self.num_sims), np.zeros(self.num_sims)
        for k in range(1, self.steps + 1):
            robot.command(self.controller.commands())
            stable = robot.step()
            readings = robot.read(self._rngs)
            q = readings["quaternion"]
            up = 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)
            down = (up < self._min_up) | ~stable
            if rules:  # the same leaky counts as the task's (envs/common/locomotion.py)
                low, high = self.task.height_band
                height = readings["position"][:, 2] - self.task.ground_height(readings["position"])
                contact_time = leaky_count(contact_time, robot.non_foot_contact(), robot.control_dt)
                band_time = leaky_count(band_time, (height < low) | (height > high), robot.control_dt)
                down |= self.task.rules_broken(contact_time, band_time)
            down &= ~fallen
            if down.any():
                fall_x[down] = readings["position"][down, 0]
                fall_time[down] = k * robot.control_dt
                fallen |= down
            if k % self.sample_every == 0 or k == self.steps:
                samples.append(readings["position"][:, :2].copy())
        p = np.stack(samples, axis=1)  # (n, N, 2)
        x_end = p[:, -1, 0]
        forward = np.where(fallen, fall_x, x_end) - x0
        scores = {
            "distance_travelled": distance_travelled(p),
            "forward": forward,
            "progress_x": x_end - x0,
            "fallen": fallen.astype(np.float64),
            "fall_time": fall_time,
        }
        scores["score"] = scores[self.config.objective]
        return {k: v[:n].copy() for k, v in scores.items()}
