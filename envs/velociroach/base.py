"""What the VelociRoACH tasks share: actions, observations, termination, rendering and telemetry."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from envs.common.mujoco_utils import quat_to_yaw, quat_up_z
from envs.common.telemetry import TelemetryRecorder
from envs.velociroach import constants as C
from envs.velociroach.robot import TELEMETRY_COLUMNS, ActionMode, VelociRoach, wrap_angle

DEFAULT_CONTROL_FREQ = {"gait": 50.0, "duty": 1000.0}  # Hz
CAMERA = {"type": mujoco.mjtCamera.mjCAMERA_TRACKING, "distance": 0.35, "elevation": -25.0}  # tracks the body


class RoachEnv(gym.Env, ABC):
    """Base of the VelociRoACH tasks; see :class:`envs.velociroach.walk.RoachWalkEnv` for the user's manual.

    Subclasses define ``_reward_terms`` (a dict of weighted terms whose sum is the reward), ``_command_obs`` and,
    when they have a command, ``_sample_command``.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    def __init__(
        self,
        action_mode: ActionMode = "gait",
        control_freq: float | None = None,
        privileged_obs: bool = False,
        energy_cost_weight: float = 0.1,
        max_tilt: float = 1.4,
        reset_noise_scale: float = 0.1,
        battery_voltage: float | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        freq = DEFAULT_CONTROL_FREQ[action_mode] if control_freq is None else float(control_freq)
        if not freq > 0:
            raise ValueError(f"control_freq must be positive, got {control_freq}")
        self.robot = VelociRoach(action_mode, control_dt=1.0 / freq, battery_voltage=battery_voltage)
        self.action_mode = action_mode
        self.dt = self.robot.control_dt
        self.privileged_obs = privileged_obs
        self.energy_cost_weight = energy_cost_weight
        self.max_tilt = max_tilt
        self.reset_noise_scale = reset_noise_scale
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.dt)}
        self._width, self._height = width, height
        self._renderer = None
        self.action_space = spaces.Box(-1.0, 1.0, shape=(3 if action_mode == "gait" else 2,), dtype=np.float32)
        n_obs = 15 + (4 if action_mode == "gait" else 0) + self._command_size() + (7 if privileged_obs else 0)
        self.observation_space = spaces.Box(-np.inf, np.inf, shape=(n_obs,), dtype=np.float64)
        self.recorder = TelemetryRecorder(self._telemetry_meta(), TELEMETRY_COLUMNS) if telemetry else None
        self._last_obs = np.zeros(n_obs)
        self._obs_buffer = np.zeros(n_obs)
        self._planar = (0.0, 0.0, 0.0)  # x, y, yaw at the end of the last step
        self._min_up_z = float(np.cos(max_tilt))

    # --- the parts a task fills in ----------------------------------------------------------------------------
    def _command_size(self) -> int:
        return 0

    def _command_obs(self) -> np.ndarray:
        return np.zeros(0)

    def _sample_command(self, options: dict[str, Any] | None) -> None:
        """Draw (or take from ``options``) the episode's command."""

    @abstractmethod
    def _reward_terms(self, state: dict[str, float]) -> dict[str, float]:
        """The task's weighted reward terms for one step; the reward is their sum."""

    # --- actions ----------------------------------------------------------------------------------------------
    def action_to_command(self, action: np.ndarray) -> np.ndarray:
        """Physical command of a normalized action: duty per side, or (f_left Hz, f_right Hz, phase rad)."""
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        if self.action_mode == "duty":
            return a
        return np.array([a[0] * C.MAX_COMMAND_FREQUENCY, a[1] * C.MAX_COMMAND_FREQUENCY, np.pi * (1.0 + a[2])])

    @staticmethod
    def gait_action(freq_left: float, freq_right: float, phase: float) -> np.ndarray:
        """The normalized gait action for stride frequencies (Hz) and a left/right phase (rad, in [0, 2 pi])."""
        f = C.MAX_COMMAND_FREQUENCY
        return np.array([freq_left / f, freq_right / f, phase / np.pi - 1.0], dtype=np.float32)

    def _apply_action(self, action: np.ndarray) -> None:
        action = np.asarray(action, dtype=np.float64).reshape(-1)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {action.shape}")
        if not np.isfinite(action).all():
            raise ValueError(f"action must be finite, got {action}")
        command = self.action_to_command(action)
        if self.action_mode == "duty":
            self.robot.command_duty(command)
        else:
            self.robot.command_gait(*command)

    # --- observation ------------------------------------------------------------------------------------------
    def _get_obs(self) -> np.ndarray:
        r = self.robot
        obs = self._obs_buffer
        senses = r.senses()
        obs[0:2] = np.cos(senses[0:2])
        obs[2:4] = np.sin(senses[0:2])
        obs[4:12] = senses[2:10]
        obs[12:14] = r.motor_constant * senses[10:12]  # back-EMF
        obs[14] = r.battery_voltage
        i = 15
        if self.action_mode == "gait":
            clock = r.commanded_leg_angles()
            obs[15:17] = np.cos(clock)
            obs[17:19] = np.sin(clock)
            i = 19
        n = self._command_size()
        obs[i : i + n] = self._command_obs()
        if self.privileged_obs:
            obs[i + n : i + n + 3] = r.body_velocity()
            obs[i + n + 3 : i + n + 7] = r.body_pose()[3:]
        return obs.copy()

    # --- gymnasium API ----------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        noise = self.reset_noise_scale
        rng = self.np_random
        self.robot.reset(crank_left=rng.uniform(-noise, noise), phase=C.STRAIGHT_PHASE + rng.uniform(-noise, noise))
        self.robot.set_body_velocity(rng.normal(0.0, noise * 0.1, 3), rng.normal(0.0, noise, 3))
        self._sample_command(options)
        pose = self.robot.body_pose()
        self._planar = (pose[0], pose[1], quat_to_yaw(pose[3:]))
        obs = self._get_obs()
        self._last_obs = obs
        if self.recorder is not None:
            self.recorder.start_episode()
            self.recorder.record(self.robot, 0.0)
        if self.render_mode == "human":
            self.render()
        return obs, self._info(pose, {})

    def step(self, action: np.ndarray):
        self._apply_action(action)
        stable = self.robot.step()
        if not stable:
            # MuJoCo has reset the data; end the episode with the last good observation
            info = {"sim_unstable": True, "fallen": False, "time": float(self.robot.data.time)}
            return self._last_obs.copy(), 0.0, True, False, info
        pose = self.robot.body_pose()
        x, y, yaw = pose[0], pose[1], quat_to_yaw(pose[3:])
        x_before, y_before, yaw_before = self._planar
        state = {
            "x_velocity": (x - x_before) / self.dt,
            "y_velocity": (y - y_before) / self.dt,
            "yaw_rate": float(wrap_angle(yaw - yaw_before)) / self.dt,
            "yaw": yaw,
            "up_z": quat_up_z(pose[3:]),
            "power": self.robot.electrical_power(),
        }
        self._planar = (x, y, yaw)
        terms = self._reward_terms(state)
        reward = float(sum(terms.values()))
        terminated = bool(state["up_z"] < self._min_up_z)
        obs = self._get_obs()
        self._last_obs = obs
        if self.recorder is not None:
            self.recorder.record(self.robot, state["power"])
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, False, self._info(pose, state, terms, fallen=terminated)

    def _info(self, pose: np.ndarray, state: dict[str, float], terms: dict | None = None, fallen: bool = False):
        info: dict[str, Any] = {
            "x_position": float(pose[0]),
            "y_position": float(pose[1]),
            "z_position": float(pose[2]),
            "quaternion": pose[3:].copy(),
            "sim_unstable": False,
            "fallen": fallen,
            "time": float(self.robot.data.time),
        }
        info.update({k: float(v) for k, v in state.items()})
        for name, value in (terms or {}).items():
            info[f"reward_{name}"] = float(value)
        return info

    # --- rendering and telemetry ------------------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

            camera = {**CAMERA, "trackbodyid": self.robot.model.body(C.ROOT_BODY).id}
            self._renderer = MujocoRenderer(self.robot.model, self.robot.data, camera, self._width, self._height)
        return self._renderer.render(self.render_mode)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _telemetry_meta(self) -> dict[str, Any]:
        return {
            "robot": "velociroach",
            "model_hash": self.robot.model_hash,
            "controller": f"{self.action_mode} mode",
            "rate_hz": 1.0 / self.dt,
            "battery_voltage": self.robot.battery_voltage,
        }

    def __getstate__(self):
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state
