"""Batched environments: N simulations of one robot and task in one process, on ``mujoco.batch.Batch``.

:class:`SkitterVectorEnv` is Gymnasium's ``VectorEnv`` (next-step autoreset, as Gymnasium 1.x defines it; info as a
dict of arrays with ``_key`` masks) over a robot built with ``num_sims = N``. It runs the same robot and task code as
the single env, whose arrays simply have N rows: one implementation of observations, rewards and termination. Each
simulation has its own random generator, seeded as Gymnasium's ``SyncVectorEnv`` seeds its sub-envs (``seed + i``),
so N single envs and one batched env of N give identical results (tests/test_batch.py). A simulation that goes
unstable ends its own episode (``info["sim_unstable"]``) and the others go on.

``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", nthread=...)`` makes one; every
registered id has it as its ``vector_entry_point``. :class:`agents.vec_env.SkitterVecEnv` adapts it to
Stable-Baselines3.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from envs.common.env import EPISODE_SECONDS, PHYSICS, SkitterEnv, check_options, episode_steps, keywords_taken
from envs.common.parameters import sample
from envs.common.rendering import FrameRenderer, tracking_camera
from envs.common.robot import batched_robots
from envs.common.telemetry import TelemetryRecorder


class SkitterVectorEnv(VectorEnv):
    """N copies of a skitter env stepped together.

    Args:
        env: a :class:`SkitterEnv` whose robot was built batched (see :func:`vector_entry_point`); its task,
            settings and spaces are taken over.
        max_episode_steps: the time limit in control steps (see :func:`vector_entry_point`); episodes are truncated
            after it.
        render_sim: which simulation ``render()`` shows.
    """

    metadata: ClassVar[dict[str, Any]] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"]}

    def __init__(self, env: SkitterEnv, max_episode_steps: int | None = None, render_sim: int = 0):
        robot = env.robot
        if not robot.batched:
            raise ValueError("SkitterVectorEnv needs a robot built batched (see vector_entry_point)")
        self.env = env
        self.robot, self.task = robot, env.task
        n = self.num_envs = robot.num_sims
        if max_episode_steps is not None and (isinstance(max_episode_steps, bool) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be a whole number >= 1, got {max_episode_steps!r}")
        if not 0 <= render_sim < n:
            raise ValueError(f"render_sim must be in [0, {n}), got {render_sim}")
        self.max_episode_steps = max_episode_steps
        self.render_sim = render_sim
        self.render_mode = "rgb_array" if env.render_mode is not None else None
        self.metadata = {**self.metadata, "render_fps": env.metadata["render_fps"]}
        self.dt = env.dt
        self.single_action_space = env.action_space
        self.single_observation_space = env.observation_space
        self.action_space = batch_space(env.action_space, n)
        self.observation_space = batch_space(env.observation_space, n)
        self.rngs: list[np.random.Generator] = [seeding.np_random()[0] for _ in range(n)]
        self.parameter_values: list[dict[str, float]] = [{} for _ in range(n)]
        self.recorders = (
            [
                TelemetryRecorder({**env.telemetry_metadata(), "simulation": i}, robot.telemetry_channels)
                for i in range(n)
            ]
            if env.recorder is not None
            else None
        )
        self._steps = np.zeros(n, dtype=np.int64)
        self._needs_reset = np.zeros(n, dtype=bool)
        self._no_ids = np.zeros(0, dtype=np.int64)
        self._obs = np.zeros((n, env.observation_space.shape[0]))
        # each simulation's last good pose and time, which an unstable step's info reports
        self._pose = {key: np.zeros(n) for key in ("x_position", "y_position", "z_position", "time")}
        self._pose["quaternion"] = np.zeros((n, 4))
        self._render_model: mujoco.MjModel | None = None
        self._renderer = None

    @property
    def observation_structure(self) -> dict[str, int]:
        return self.task.observation_structure

    # --- reset and step -------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None):
        check_options(options)
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        ids = np.arange(self.num_envs) if mask is None else np.flatnonzero(self._check_mask(mask))
        seeds = self._seeds(seed)
        for i in ids:
            if seeds[i] is not None or mask is None:
                self.rngs[i] = seeding.np_random(seeds[i])[0]
        readings = self._reset(ids, options or None)
        infos = self._infos(readings, {}, {}, np.zeros(self.num_envs, dtype=bool), ids)
        for key, last in self._pose.items():
            last[ids] = infos[key][ids]
        if mask is not None:  # the others' entries describe nothing new
            for key in [k for k in infos if not k.startswith("_")]:
                infos[f"_{key}"] = infos[f"_{key}"] & mask
        return self._obs.copy(), infos

    def step(self, actions: np.ndarray):
        n, a = self.num_envs, self.single_action_space.shape[0]
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (n, a):
            raise ValueError(f"actions must have shape {(n, a)}, got {actions.shape}")
        if not np.isfinite(actions).all():
            bad = int(np.flatnonzero(~np.isfinite(actions).all(axis=1))[0])
            raise ValueError(f"actions must be finite; simulation {bad} got {actions[bad]}")
        resetting = self._needs_reset.copy()
        any_reset = bool(resetting.any())
        stepped = ~resetting
        commands = self.env.commands
        self.robot.command(
            self.robot.mode.to_command(actions) if commands is None else commands.robot_commands(actions)
        )
        stable = self.robot.step(np.flatnonzero(stepped) if any_reset else None)
        reset_ids = np.flatnonzero(resetting) if any_reset else self._no_ids
        if any_reset:
            self._reset_robot(reset_ids, None)
        readings = self.robot.read(self.rngs, stepped if any_reset else True)
        if any_reset:
            self.task.reset(reset_ids, [self.rngs[i] for i in reset_ids], None, readings)
        state = self.task.update(readings, stepped if any_reset else None)
        terms = self.task.reward_terms(state)
        reward = sum(terms.values())
        terminated = self.task.terminated(state)
        unstable = ~stable
        obs = self.task.observe(readings)
        # an unstable simulation ends its episode with its last good observation and no reward
        obs[unstable] = self._obs[unstable]
        reward = np.where(stepped & stable, reward, 0.0)
        terminated = (terminated | unstable) & stepped
        self._steps += stepped
        self._steps[reset_ids] = 0
        truncated = np.zeros(n, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = stepped & (self._steps >= self.max_episode_steps)
        self._needs_reset = terminated | truncated
        self._obs = obs
        if self.recorders is not None:
            self._record(readings, unstable, reset_ids)
        fallen = self.task.fell(state, terminated & stable) & terminated & stable
        infos = self._infos(readings, self.task.info(readings, state), terms, fallen, reset_ids, unstable)
        if unstable.any():  # MuJoCo has reset those simulations: their pose is the last good one
            for key, last in self._pose.items():
                infos[key] = np.where(unstable.reshape(-1, *[1] * (last.ndim - 1)), last, infos[key])
        for key, last in self._pose.items():
            last[...] = infos[key]
        return obs.copy(), reward, terminated, truncated, infos

    def _reset(self, ids: np.ndarray, options: Mapping | None) -> dict[str, np.ndarray]:
        self._reset_robot(ids, options)
        # the simulations not reset keep their state and their random streams (None: draw nothing); their readings
        # here are not used
        rngs = [self.rngs[i] if reset else None for i, reset in enumerate(self._mask(ids, True))]
        readings = self.robot.read(rngs, False)
        self.task.reset(ids, [self.rngs[i] for i in ids], options, readings)
        self._obs[ids] = self.task.observe(readings)[ids]
        self._steps[ids] = 0
        self._needs_reset[ids] = False
        if self.recorders is not None:
            rows = self.robot.telemetry(readings)
            for i in ids:
                self.recorders[i].start_episode()
                self.recorders[i].record(rows[i])
        return readings

    def _reset_robot(self, ids: np.ndarray, options: Mapping | None) -> None:
        """Draw each simulation's parameters (with randomize) and reset the robot, in the single env's order."""
        if self.env.randomize:
            for i in ids:
                self.parameter_values[i] = sample(self.env.randomize, self.rngs[i])
                self.robot.set_parameters(np.array([i]), self.parameter_values[i])
        self.task.prepare_reset(ids, [self.rngs[i] for i in ids], options)
        self.robot.reset(ids, [self.rngs[i] for i in ids], self.env.reset_noise_scale, options)
        if self.env.commands is not None:
            self.env.commands.reset(ids)

    def _mask(self, ids: np.ndarray, value: bool) -> np.ndarray:
        mask = np.full(self.num_envs, not value)
        mask[ids] = value
        return mask

    def _record(self, readings: dict[str, np.ndarray], unstable: np.ndarray, reset_ids: np.ndarray) -> None:
        """A step's telemetry: a row per simulation, or one per physics step (``telemetry="physics"``) of those that
        stepped (one that reset in this step records its reset state once, as at every reset)."""
        rows = self.robot.telemetry(readings)
        physics = self.robot.physics_telemetry(readings) if self.env.telemetry_rate == PHYSICS else None
        for i in range(self.num_envs):
            reset = i in reset_ids
            if reset:
                self.recorders[i].start_episode()
            if unstable[i]:
                continue
            if physics is None or reset:
                self.recorders[i].record(rows[i])
            else:
                for row in physics[i]:
                    self.recorders[i].record(row)

    def _infos(self, readings, state, terms, fallen, reset_ids, unstable=None) -> dict[str, np.ndarray]:
        """Gymnasium's vector info: an array per key, and ``_key`` marking the simulations that have it. The step's
        quantities and reward terms are absent for simulations that reset in this call (and unstable ones, whose pose
        and time are their last good ones)."""
        n = self.num_envs
        everyone = np.ones(n, dtype=bool)
        unstable = np.zeros(n, dtype=bool) if unstable is None else unstable
        pos = readings["position"]
        infos: dict[str, np.ndarray] = {
            "x_position": pos[:, 0],
            "y_position": pos[:, 1],
            "z_position": pos[:, 2],
            "quaternion": readings["quaternion"],
            "time": readings["time"],
            "sim_unstable": unstable,
            "fallen": np.asarray(fallen, dtype=bool),
        }
        masks = {f"_{key}": everyone for key in infos}
        if state:
            good = ~unstable
            if len(reset_ids):
                good = good & self._mask(reset_ids, False)
            for key, value in state.items():
                infos[key], masks[f"_{key}"] = value, good
            for key, value in terms.items():
                infos[f"reward_{key}"], masks[f"_reward_{key}"] = value, good
        infos.update(masks)
        return infos

    # --- seeding, rendering, metadata ------------------------------------------------------------------------------
    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(n)]
        seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"seed must be an int or {n} seeds, got {len(seeds)}")
        return seeds

    def _check_mask(self, mask: Any) -> np.ndarray:
        mask = np.asarray(mask)
        if mask.shape != (self.num_envs,) or mask.dtype != np.bool_ or not mask.any():
            raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},) with a True")
        return mask

    @property
    def np_random(self) -> tuple[np.random.Generator, ...]:
        return tuple(self.rngs)

    def render(self) -> np.ndarray | None:
        """A frame of simulation ``render_sim``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without render_mode='rgb_array'")
            return None
        sim = self.robot.sim
        if self._renderer is None:
            model = self._render_model = sim.batch.get_model(self.render_sim)
            self._render_data = mujoco.MjData(model)
            camera = tracking_camera(model, self.env.camera_config(), model.body(self.env.tracked_body()).id)
            self._renderer = FrameRenderer(model, camera, self.env._width, self.env._height)
        sim.batch.get_data(self.render_sim, self._render_data)
        mujoco.mj_forward(self._render_model, self._render_data)
        return self._renderer.render(self._render_data)

    def metrics_context(self) -> dict[str, Any]:
        return self.env.metrics_context()

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        raise TypeError(
            "a batched env holds a MuJoCo thread pool and cannot be pickled; make it again with gymnasium.make_vec"
        )


def vector_entry_point(env_class: Callable[..., SkitterEnv]) -> Callable[..., SkitterVectorEnv]:
    """The ``vector_entry_point`` of an env class: builds the class's own robot and task batched.

    The returned function takes ``num_envs``, ``episode_seconds`` (the time limit as a duration, as the single env's
    entry point: 10 s at any control rate; None for none), ``max_episode_steps`` (a limit in steps given to
    ``gymnasium.make_vec``: the episode ends at whichever limit comes first, as in a single env made with
    ``gymnasium.make(id, max_episode_steps=n)``; for longer episodes pass ``episode_seconds`` too, or None),
    ``nthread`` (default: the machine's cores), ``render_sim`` and the env's own keyword arguments.
    """

    def make(
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        episode_seconds: float | None = EPISODE_SECONDS,
        nthread: int | None = None,
        render_sim: int = 0,
        **kwargs: Any,
    ) -> SkitterVectorEnv:
        if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
            raise ValueError(f"num_envs must be a whole number >= 1, got {num_envs!r}")
        episode_steps(episode_seconds, 1.0)  # refused before anything is built
        keywords_taken(env_class, kwargs, also=("num_envs", "max_episode_steps", "nthread", "render_sim"))
        with batched_robots(int(num_envs), nthread):
            env = env_class(**kwargs)
        duration = episode_steps(episode_seconds, env.dt)
        if max_episode_steps is None or (duration is not None and duration < max_episode_steps):
            max_episode_steps = duration
        return SkitterVectorEnv(env, max_episode_steps, render_sim)

    make.__doc__ = f"Batched {env_class.__name__} (see envs/common/vector.py)."
    return make
