"""RoachTurn: follow a commanded yaw rate."""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.velociroach import constants as C
from envs.velociroach.base import RoachEnv
from envs.velociroach.robot import ActionMode

YAW_RATE_RANGE = 0.8  # rad/s: commands are drawn from U(-0.8, 0.8), within the turning tripod's reach at 10 Hz


class RoachTurnEnv(RoachEnv):
    """Make a VelociRoACH turn at a commanded yaw rate while it runs.

    Robot, actions, starting state, episode end and the shared observations are those of
    :class:`envs.velociroach.walk.RoachWalkEnv`; this docstring lists what differs.

    ## Command
    A yaw rate ``r`` (rad/s, positive counter-clockwise seen from above), drawn per episode from
    ``U(-yaw_rate_range, yaw_rate_range)`` (default 0.8 rad/s, within what the tripod reaches by phase alone,
    ``benchmarks/results/turn_table.md``), or set with ``reset(options={"yaw_rate": r})``.
    The real robot turns by the phase offset between its sides (seed 000; Haldane and Fearing, ICRA 2014); so does
    this model, once its feet slip (docs/velociroach.md).

    ## Observation Space
    As RoachWalk, with the commanded yaw rate (rad/s) appended after the robot's sensors (before the privileged
    observations): size 20 in gait mode, 16 in duty mode, 7 more with ``privileged_obs``.

    ## Rewards
    ``reward = tracking + speed + energy``, each in ``info["reward_<term>"]``:

    - ``tracking``: ``tracking_reward_weight * exp(-(w - r)^2 / tracking_sigma^2)``, w the yaw rate over the step;
    - ``speed``: ``speed_reward_weight * v / 0.1 m``, v the speed along the body's heading in body lengths/s;
    - ``energy``: ``-energy_cost_weight * P`` as in RoachWalk.

    ## Arguments
    As RoachWalk, less ``forward_reward_weight`` and ``upright_reward_weight``, plus ``yaw_rate_range`` (0.8 rad/s),
    ``tracking_reward_weight`` (1.0), ``tracking_sigma`` (0.5 rad/s), ``speed_reward_weight`` (0.1).

    ## Version History
    - v0: first release.
    """

    def __init__(
        self,
        action_mode: ActionMode = "gait",
        control_freq: float | None = None,
        privileged_obs: bool = False,
        yaw_rate_range: float = YAW_RATE_RANGE,
        tracking_reward_weight: float = 1.0,
        tracking_sigma: float = 0.5,
        speed_reward_weight: float = 0.1,
        energy_cost_weight: float = 0.1,
        max_tilt: float = 1.4,
        reset_noise_scale: float = 0.1,
        battery_voltage: float | None = None,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ):
        if not yaw_rate_range >= 0:
            raise ValueError(f"yaw_rate_range must be >= 0, got {yaw_rate_range}")
        if not tracking_sigma > 0:
            raise ValueError(f"tracking_sigma must be positive, got {tracking_sigma}")
        self.yaw_rate_range = yaw_rate_range
        self.tracking_reward_weight = tracking_reward_weight
        self.tracking_sigma = tracking_sigma
        self.speed_reward_weight = speed_reward_weight
        self.yaw_rate_command = 0.0
        super().__init__(
            action_mode=action_mode,
            control_freq=control_freq,
            privileged_obs=privileged_obs,
            energy_cost_weight=energy_cost_weight,
            max_tilt=max_tilt,
            reset_noise_scale=reset_noise_scale,
            battery_voltage=battery_voltage,
            telemetry=telemetry,
            render_mode=render_mode,
            width=width,
            height=height,
        )

    def _command_size(self) -> int:
        return 1

    def _command_obs(self) -> np.ndarray:
        return np.array([self.yaw_rate_command])

    def _sample_command(self, options: dict[str, Any] | None) -> None:
        if options and "yaw_rate" in options:
            value = options["yaw_rate"]
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"options['yaw_rate'] must be a number, got {value!r}") from None
            if not np.isfinite(value):
                raise ValueError(f"options['yaw_rate'] must be finite, got {value}")
            self.yaw_rate_command = value
        else:
            self.yaw_rate_command = float(self.np_random.uniform(-self.yaw_rate_range, self.yaw_rate_range))

    def _reward_terms(self, state: dict[str, float]) -> dict[str, float]:
        error = state["yaw_rate"] - self.yaw_rate_command
        heading = np.array([np.cos(state["yaw"]), np.sin(state["yaw"])])
        speed = float(heading @ np.array([state["x_velocity"], state["y_velocity"]]))
        return {
            "tracking": self.tracking_reward_weight * float(np.exp(-((error / self.tracking_sigma) ** 2))),
            "speed": self.speed_reward_weight * speed / C.LENGTH,
            "energy": -self.energy_cost_weight * state["power"],
        }

    def _info(self, pose, state, terms=None, fallen=False):
        info = super()._info(pose, state, terms, fallen)
        info["yaw_rate_command"] = self.yaw_rate_command
        return info
