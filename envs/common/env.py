"""The single Gymnasium env over a robot and a task: a batch of one.

Robots and tasks compute with a leading simulation axis; this env runs one simulation and takes element 0. Like
Gymnasium's ``MujocoEnv`` it exposes ``model`` and ``data`` (the live ``MjData``), ``dt``, ``observation_structure``,
``render()`` and ``close()``.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.wrappers import TimeLimit

from envs.common.io import nearest
from envs.common.parameters import check_randomize, sample
from envs.common.rendering import FrameRenderer, tracking_camera
from envs.common.robot import Robot, check_number
from envs.common.task import Task
from envs.common.telemetry import TelemetryRecorder

MAX_FRAME = (4096, 4096)  # largest width, height of a rendered frame
EPISODE_SECONDS = 10.0  # an episode's length, whatever the control rate


class SkitterEnv(gym.Env):
    """A robot doing a task, one simulation. The user's manual of each env is its subclass's docstring.

    Args:
        robot: the robot (built with ``num_sims=1``).
        task: the task over that robot.
        reset_noise_scale: how much the robot's reset pose and velocity are perturbed (see the robot's ``reset``).
        randomize: physical parameters to draw at every reset, name -> (low, high), uniform; names from
            ``robot.parameters`` (off by default).
        telemetry: record the robot's telemetry channels (``env.unwrapped.recorder``): True or ``"control"`` at every
            control step, ``"physics"`` at every physics step (its sensor channels then resolve what happens within
            a control step, such as a stride faster than half the control rate; see ``Robot.physics_telemetry``).
        render_mode: ``"human"`` or ``"rgb_array"``.
        width, height: size of rendered frames, pixels.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    def __init__(
        self,
        robot: Robot,
        task: Task,
        reset_noise_scale: float = 0.1,
        randomize: Mapping[str, Sequence[float]] | None = None,
        telemetry: bool | str = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        for name, value, most in (("width", width, MAX_FRAME[0]), ("height", height, MAX_FRAME[1])):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= most:
                raise ValueError(f"{name} must be a whole number of pixels in [1, {most}], got {value!r}")
        self.reset_noise_scale = check_number("reset_noise_scale", reset_noise_scale, 0)
        self.telemetry_rate = telemetry_rate(telemetry)
        self.robot = robot
        self.task = task
        self.randomize = check_randomize(randomize, robot.parameters)
        self.parameter_values: dict[str, float] = {}
        self.dt = robot.control_dt
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.dt)}
        self._width, self._height = int(width), int(height)
        self._renderer = None
        self.action_space = spaces.Box(-1.0, 1.0, shape=(robot.mode.size,), dtype=np.float32)
        # an action mode of the env's own over the robot's (the soccer envs' speed and turn rate): it turns actions
        # (n, size) into the robot's commands (``robot_commands``) and restarts for reset simulations (``reset``)
        self.commands: Any = None
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(task.layout.size,), dtype=np.float64)
        self.recorder = (
            TelemetryRecorder(self.telemetry_metadata(), robot.telemetry_channels) if self.telemetry_rate else None
        )
        self._ids = np.array([0])
        self._last_obs = np.zeros(task.layout.size)
        self._last_info: dict[str, Any] = {}

    # --- like MujocoEnv -------------------------------------------------------------------------------------------
    @property
    def model(self) -> mujoco.MjModel:
        return self.robot.model

    @property
    def data(self) -> mujoco.MjData:
        return self.robot.data

    @property
    def observation_structure(self) -> dict[str, int]:
        return self.task.observation_structure

    # --- gymnasium API --------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        check_options(options)
        super().reset(seed=seed)
        rngs = [self.np_random]
        if self.randomize:
            self.parameter_values = sample(self.randomize, self.np_random)
            self.robot.set_parameters(self._ids, self.parameter_values)
        self.task.prepare_reset(self._ids, rngs, options)
        self.robot.reset(self._ids, rngs, self.reset_noise_scale, options)
        if self.commands is not None:
            self.commands.reset(self._ids)
        readings = self.robot.read(rngs, stepped=False)
        self.task.reset(self._ids, rngs, options, readings)
        obs = self.task.observe(readings)[0]
        self._last_obs = obs
        if self.recorder is not None:
            self.recorder.start_episode()
            self.recorder.record(self.robot.telemetry(readings)[0])
        if self.render_mode == "human":
            self.render()
        info = self._info(readings, {}, {}, fallen=False)
        self._last_info = info.copy()
        return obs.copy(), info

    def step(self, action: np.ndarray):
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {action.shape}")
        if not math.isfinite(sum(action.tolist())) and not np.isfinite(action).all():  # the first test is the cheapest
            raise ValueError(f"action must be finite, got {action}")
        if self.commands is None:
            self.robot.command(
                self.robot.mode.to_command(action)[None]
            )  # mapped in the action's shape: no broadcasting
        else:
            self.robot.command(self.commands.robot_commands(action[None]))
        if not self.robot.step()[0]:
            # MuJoCo has reset the data; end the episode with the last good observation and info, and no reward
            info = {
                key: value.copy() if isinstance(value, np.ndarray) else value for key, value in self._last_info.items()
            }
            info.update({key: 0.0 for key in info if key.startswith("reward_")}, sim_unstable=True, fallen=False)
            return self._last_obs.copy(), 0.0, True, False, info
        rngs = [self.np_random]
        readings = self.robot.read(rngs)
        state = self.task.update(readings)
        terms = {name: value.item() for name, value in self.task.reward_terms(state).items()}
        reward = sum(terms.values())
        terminated = self.task.terminated(state).item()
        obs = self.task.observe(readings)[0]
        self._last_obs = obs
        if self.recorder is not None:
            if self.telemetry_rate == PHYSICS:
                for row in self.robot.physics_telemetry(readings)[0]:
                    self.recorder.record(row)
            else:
                self.recorder.record(self.robot.telemetry(readings)[0])
        if self.render_mode == "human":
            self.render()
        fallen = bool(self.task.fell(state, np.array([terminated]))[0]) if terminated else False
        info = self._info(readings, self.task.info(readings, state), terms, fallen)
        self._last_info = info.copy()
        return obs.copy(), reward, terminated, False, info

    def _info(self, readings: dict, state: dict, terms: dict[str, float], fallen: bool) -> dict[str, Any]:
        x, y, z = readings["position"][0].tolist()
        info: dict[str, Any] = {
            "x_position": x,
            "y_position": y,
            "z_position": z,
            "quaternion": readings["quaternion"][0].copy(),
            "sim_unstable": False,
            "fallen": fallen,
            "time": readings["time"].item(),
        }
        for key, value in state.items():
            info[key] = value.item()
        for key, value in terms.items():
            info[f"reward_{key}"] = value
        return info

    # --- rendering ------------------------------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        body = self.model.body(self.tracked_body()).id
        if self._renderer is None and self.render_mode == "human":
            from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

            camera = {**self.camera_config(), "trackbodyid": body}
            self._renderer = MujocoRenderer(self.model, self.data, camera, self._width, self._height)
        elif self._renderer is None:
            camera = tracking_camera(self.model, self.camera_config(), body)
            self._renderer = FrameRenderer(self.model, camera, self._width, self._height)
        if self.render_mode == "human":
            return self._renderer.render(self.render_mode)
        return self._renderer.render(self.data)

    def tracked_body(self) -> str:
        """The body the camera follows: the robot's root."""
        return self.robot.root_body

    def camera_config(self) -> dict[str, Any]:
        """The tracking camera, scaled to the robot's length (``MjvCamera`` fields)."""
        return {
            "type": mujoco.mjtCamera.mjCAMERA_TRACKING,
            "distance": 3.5 * self.robot.facts.length,
            "elevation": -25.0,
        }

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state

    # --- metadata ---------------------------------------------------------------------------------------------------
    def telemetry_metadata(self) -> dict[str, Any]:
        return {
            **self.robot.metadata(),
            "task": self.task.name,
            "controller": f"{self.robot.action_mode} mode",
            "rate_hz": 1.0 / (self.model.opt.timestep if self.telemetry_rate == PHYSICS else self.dt),
        }

    def metrics_context(self) -> dict[str, Any]:
        """What evaluation needs to turn an episode's last ``info`` into metrics: the robot's mass and length, the
        task's own metrics."""
        return {"mass": self.robot.facts.mass, "length": self.robot.facts.length, "task": self.task}


CONTROL, PHYSICS = "control", "physics"  # the rates telemetry is recorded at


def telemetry_rate(value: Any) -> str | None:
    """``telemetry``: False (None: not recorded), True or ``"control"`` (every control step), ``"physics"``."""
    if value is True or value == CONTROL:
        return CONTROL
    if value is False or value is None:
        return None
    if value == PHYSICS:
        return PHYSICS
    raise ValueError(f"telemetry must be True, False, {CONTROL!r} or {PHYSICS!r}, got {value!r}")


def check_options(options: Any) -> None:
    """A reset's ``options``: None or a mapping of names (ValueError otherwise)."""
    if options is not None and not isinstance(options, Mapping):
        raise ValueError(f"options must be a dict of named options or None, got {type(options).__name__} {options!r}")


def episode_steps(seconds: float | None, dt: float) -> int | None:
    """The control steps of an episode of ``seconds`` (None: no limit) at a control step of ``dt`` seconds."""
    if seconds is None:
        return None
    return max(1, round(check_number("episode_seconds", seconds, 0, strict=True) / dt))


def keywords_taken(env_class: Callable[..., SkitterEnv], kwargs: Mapping[str, Any], also: Sequence[str] = ()) -> None:
    """TypeError naming a keyword the env does not take, the one it may have meant and those it takes (its class's,
    ``episode_seconds`` and ``also``: the entry point's own)."""
    params = inspect.signature(env_class).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    taken = sorted({*params, "episode_seconds", *also})
    for key in kwargs:
        if key not in params:
            close = nearest(key, taken)
            hint = f" (did you mean {close!r}?)" if close else ""
            raise TypeError(f"{env_class.__name__} takes no keyword {key!r}{hint}; it takes {', '.join(taken)}")


def creator_error(exc: Exception) -> str:
    """The first line of an error from making an env, without what ``gymnasium.make`` appends to a TypeError (the
    env's id and every keyword it was made with)."""
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text.split(" was raised from the environment creator for ")[0]


def entry_point(env_class: Callable[..., SkitterEnv]) -> Callable[..., gym.Env]:
    """The registration's ``entry_point`` of an env class: the env in a ``TimeLimit`` of ``episode_seconds``.

    The limit is a duration: its steps follow the env's own control rate (``control_freq``), so the spec that
    ``gymnasium.make`` returns has ``max_episode_steps`` of 10 s at any rate. ``gymnasium.make(id,
    max_episode_steps=n)`` truncates at ``n`` steps when that comes first; for longer episodes pass ``episode_seconds``
    (None: no limit of the env's own).
    """

    def make(episode_seconds: float | None = EPISODE_SECONDS, **kwargs: Any) -> gym.Env:
        episode_steps(episode_seconds, 1.0)  # refused before anything is built
        keywords_taken(env_class, kwargs)
        env = env_class(**kwargs)
        steps = episode_steps(episode_seconds, env.dt)
        return env if steps is None else TimeLimit(env, steps)

    make.metadata = env_class.metadata  # what gymnasium.make reads of an entry point (render modes)
    make.__doc__ = f"{env_class.__name__} with its time limit (see envs/common/env.py)."
    return make
