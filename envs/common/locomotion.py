"""Walking and turning tasks for any legged robot of the contract.

Both observe what the robot senses, its heading error and (optionally, privileged) the body's velocity and orientation.
Both end the episode when the robot fails as a walker: when its body tilts past ``max_tilt``, and, as Gymnasium's Ant-v5
does with its healthy z range, when anything of it but its feet has touched the ground or its body has left its height
band (the robot's :attr:`~envs.common.robot.Robot.feet` and :attr:`~envs.common.robot.Robot.height_band`) for longer
than a grace time. The grace is a leaky count: each control step that breaks a rule adds its duration, each that keeps
it takes a quarter of its duration away (down to zero), and the episode ends when the count passes ``grace_time``; a
part that brushes the floor now and then costs nothing, a body that rests on the ground more than a fifth of the time
ends its episode however it alternates. The heading error is the robot's own estimate of its heading (integrating its
gyro, as firmware can, so that it drifts with the gyro's bias) against the commanded heading: +x for walking, a heading
that turns at the commanded rate for turning. Running sums of distance, progress, energy and yaw give the episode
metrics.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from envs.common.robot import Robot, check_flag, check_number
from envs.common.task import Task

GRAVITY = 9.81
METRIC_WARMUP = 1.0  # s: left out of rate metrics, while the gait settles
# s: how long in all a walker may break its ground rules before its episode ends: sized by the reference gait that
# breaks them most, ik-trot turning hardest (its front knees set down in 16% of its steps, bursts whose largest count
# is 1.14 s over 20 seeds at -0.2 rad/s; benchmarks/results/ground_rules.md)
GRACE_TIME = 1.5
# how fast a ground rule's count drains while the rule is kept, per second of its filling: a gait that breaks a rule
# more than DRAIN / (1 + DRAIN) of the time (a fifth) fills it for good. With an even drain (1) PPO learned to crawl
# on BioloidWalk with something other than its feet on the ground in about half of its steps (48-51%)
DRAIN = 0.25
_TWO_PI = 2.0 * np.pi
# the keys of LocomotionTask.update's state, in its order
_STATE_KEYS = ("x_velocity", "y_velocity", "speed", "yaw", "yaw_rate", "up_z", "power", "heading_error", "distance",
               "energy", "progress_x", "elapsed", "yaw_travel", "yaw_travel_warmup", "body_height", "non_foot_touch",
               "contact_time", "band_time", "contact_steps", "height_sum", "steps")  # fmt: skip


def wrap(x: np.ndarray) -> np.ndarray:
    """Wrap angles to [-pi, pi] by subtracting whole turns (as cheap as arctan2 of sin and cos on one simulation,
    a tenth of its cost on 128)."""
    return x - _TWO_PI * np.rint(x * (1.0 / _TWO_PI))


def wrap_one(x: float) -> float:
    """:func:`wrap` of one float (``round`` rounds half to even, as ``np.rint``; it takes no NaN)."""
    return x - _TWO_PI * round(x * (1.0 / _TWO_PI))


def quat_yaw(q: np.ndarray) -> np.ndarray:
    """Heading about world z of unit quaternions (n, 4) (w, x, y, z)."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quat_up(q: np.ndarray) -> np.ndarray:
    """World-z component of the body's z axis (n,): 1 upright, 0 on its side, -1 upside down."""
    return 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)


def check_band(band: Any) -> tuple[float, float]:
    """``band`` as (low, high) heights, m, 0 <= low < high (high may be infinite: no upper bound); ValueError naming
    the value otherwise."""
    message = f"height_band must be (low, high) in metres with 0 <= low < high, got {band!r}"
    if isinstance(band, str | bytes | Mapping | set | frozenset):
        raise ValueError(message)
    try:
        low, high = tuple(band)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    try:
        low = check_number("height_band", low, 0)
        high = math.inf if high == math.inf else check_number("height_band", high, low, strict=True)
    except (TypeError, ValueError):
        raise ValueError(message) from None
    return low, high


def leaky_count(count: np.ndarray, broken: np.ndarray, dt: float) -> np.ndarray:
    """A ground rule's leaky count after a step of ``dt`` seconds: up by ``dt`` where the rule was ``broken``, down
    by ``DRAIN * dt`` where it was kept, never below zero."""
    return np.maximum(count + np.where(broken, dt, -DRAIN * dt), 0.0)


class LocomotionTask(Task):
    """What walking and turning share. Subclasses give ``_command_structure``, ``_draw_command``,
    ``_target_heading`` and ``reward_terms``."""

    metrics: ClassVar[dict[str, str]] = {
        "non_foot_contact": "fraction of steps in which anything but the feet touched the ground",
        "body_height": "mean height of the body's origin above the ground under it, m",
    }

    def __init__(
        self,
        robot: Robot,
        privileged_obs: bool = False,
        energy_cost_weight: float = 0.1,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.privileged_obs = check_flag("privileged_obs", privileged_obs)
        self.energy_cost_weight = check_number("energy_cost_weight", energy_cost_weight, 0)
        self.max_tilt = check_number("max_tilt", max_tilt, 0, np.pi, strict=True)
        self._min_up = float(np.cos(self.max_tilt))
        self.terminate_when_unhealthy = check_flag("terminate_when_unhealthy", terminate_when_unhealthy)
        band = robot.height_band if height_band is None else height_band
        # a robot that declares no band (and no band given) has none: the band rule never fires
        self.height_band = (-math.inf, math.inf) if band is None else check_band(band)
        self.grace_time = check_number("grace_time", grace_time, 0)
        self._count_limit = self.grace_time + 1e-9  # a count past it ends the episode (the sum of steps may round)
        self._ground_height = ground_height
        n = robot.num_sims
        self.length = robot.facts.length
        # per simulation: x, y, yaw at the end of the last step; x and time at reset; the episode's running sums
        self._xy = np.zeros((n, 2))
        self._yaw, self._x0, self._t0 = (np.zeros(n) for _ in range(3))
        self._distance, self._energy_used, self._yaw_travel, self._yaw_warmup = (np.zeros(n) for _ in range(4))
        self._heading_error = np.zeros(n)
        # the ground rules' leaky counts (s) and the running sums of the ground metrics
        self._contact_time, self._band_time = np.zeros(n), np.zeros(n)
        self._contact_steps, self._height_sum, self._steps = np.zeros(n), np.zeros(n), np.zeros(n)
        self._dt = robot.control_dt
        self._drain_step = -DRAIN * robot.control_dt  # what a step that keeps a rule takes from its count
        self._rate = 1.0 / robot.control_dt
        self._single = n == 1
        super().__init__(robot)

    # --- layout -------------------------------------------------------------------------------------------------
    @property
    def observation_structure(self) -> dict[str, int]:
        structure = {**self.robot.sense_structure, "heading_error": 2, **self._command_structure()}
        if self.privileged_obs:
            structure.update({"body_velocity": 3, "body_quaternion": 4})
        return structure

    def _command_structure(self) -> dict[str, int]:
        return {}

    def _command_obs(self) -> list[np.ndarray]:
        return []

    def _draw_command(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None) -> None:
        """Draw (or take from ``options``) the commands of simulations ``ids``."""

    def _target_heading(self, elapsed: np.ndarray) -> np.ndarray | float:
        """The commanded heading of every simulation (n,) at its time since reset (0 at reset: the heading then)."""
        return 0.0

    # --- the contract -------------------------------------------------------------------------------------------
    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None, readings) -> None:
        self._draw_command(ids, rngs, options)
        pos, quat = readings["position"][ids], readings["quaternion"][ids]
        target = np.broadcast_to(self._target_heading(np.zeros(self.robot.num_sims)), (self.robot.num_sims,))[ids]
        for name, value in (
            ("_xy", pos[:, :2]),
            ("_yaw", quat_yaw(quat)),
            ("_x0", pos[:, 0]),
            ("_t0", readings["time"][ids]),
            ("_distance", 0.0),
            ("_energy_used", 0.0),
            ("_yaw_travel", 0.0),
            ("_yaw_warmup", 0.0),
            ("_heading_error", wrap(readings["heading"][ids] - target)),
            ("_contact_time", 0.0),
            ("_band_time", 0.0),
            ("_contact_steps", 0.0),
            ("_height_sum", 0.0),
            ("_steps", 0.0),
        ):
            array = getattr(self, name).copy()
            array[ids] = value
            setattr(self, name, array)

    def update(self, readings: dict[str, np.ndarray], stepped: np.ndarray | None = None) -> dict[str, np.ndarray]:
        if self._single and stepped is None and (state := self._update_one(readings)) is not None:
            return state
        dt = self._dt
        pos, quat, time = readings["position"], readings["quaternion"], readings["time"]
        w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
        px = pos[:, 0]
        yy = y * y  # in the yaw and in up_z
        yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (yy + z * z))
        velocity = (pos[:, :2] - self._xy) * self._rate
        x_velocity, y_velocity = velocity[:, 0], velocity[:, 1]
        yaw_step = wrap(yaw - self._yaw)
        self._xy, self._yaw = pos[:, :2], yaw
        speed = np.cos(yaw) * x_velocity + np.sin(yaw) * y_velocity
        elapsed = time - self._t0
        # running sums, rebound (not updated in place) so that a state handed out keeps its values
        self._distance = self._distance + speed * dt
        self._energy_used = self._energy_used + readings["power"] * dt
        self._yaw_travel = self._yaw_travel + yaw_step
        if elapsed.min() <= METRIC_WARMUP + 1e-9:
            self._yaw_warmup = np.where(elapsed <= METRIC_WARMUP + 1e-9, self._yaw_travel, self._yaw_warmup)
        self._heading_error = wrap(readings["heading"] - self._target_heading(elapsed))
        height = pos[:, 2] - self.ground_height(pos)
        contact = self.robot.non_foot_contact()
        low, high = self.height_band
        counts = (
            leaky_count(self._contact_time, contact, dt),
            leaky_count(self._band_time, (height < low) | (height > high), dt),
            self._contact_steps + contact,
            self._height_sum + height,
            self._steps + 1.0,
        )
        if stepped is not None:  # a simulation reset in this step took no step: its counts stay as the reset left them
            old = (self._contact_time, self._band_time, self._contact_steps, self._height_sum, self._steps)
            counts = tuple(np.where(stepped, new, was) for new, was in zip(counts, old, strict=True))
        self._contact_time, self._band_time, self._contact_steps, self._height_sum, self._steps = counts
        return {
            "x_velocity": x_velocity,
            "y_velocity": y_velocity,
            "speed": speed,
            "yaw": yaw,
            "yaw_rate": yaw_step / dt,
            "up_z": 1.0 - 2.0 * (x * x + yy),
            "power": readings["power"],
            "heading_error": self._heading_error,
            "distance": self._distance,
            "energy": self._energy_used,
            "progress_x": px - self._x0,
            "elapsed": elapsed,
            "yaw_travel": self._yaw_travel,
            "yaw_travel_warmup": self._yaw_warmup,
            "body_height": height,
            "non_foot_touch": contact.astype(np.float64),
            "contact_time": self._contact_time,
            "band_time": self._band_time,
            "contact_steps": self._contact_steps,
            "height_sum": self._height_sum,
            "steps": self._steps,
        }

    def ground_height(self, pos: np.ndarray) -> np.ndarray | float:
        """The ground's height under positions (n, 3): 0 on level ground, the terrain's where the task has one."""
        return 0.0 if self._ground_height is None else self._ground_height(pos[:, :2])

    def _update_one(self, readings: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
        """:meth:`update` of a single simulation on Python floats: the same operations in the same order, arctan2, cos
        and sin by numpy on arrays of one element as there (bitwise the same numbers; numpy's cost per call on such
        arrays is that of some twenty float operations). None, having changed nothing, if an angle to wrap is not
        finite (``round`` takes no NaN): :meth:`update` takes those."""
        dt = self._dt
        pos = readings["position"]
        px, py, pz = pos[0].tolist()
        w, x, y, z = readings["quaternion"][0].tolist()
        yy = y * y
        yaw = np.arctan2(np.array([2.0 * (w * z + x * y)]), np.array([1.0 - 2.0 * (yy + z * z)]))
        yaw_change = yaw.item() - self._yaw.item()
        elapsed = readings["time"].item() - self._t0.item()
        target = self._target_heading(np.array([elapsed]))
        heading_change = readings["heading"].item() - (target.item() if isinstance(target, np.ndarray) else target)
        if not math.isfinite(yaw_change + heading_change):
            return None
        x_last, y_last = self._xy[0].tolist()
        x_velocity = (px - x_last) * self._rate
        y_velocity = (py - y_last) * self._rate
        yaw_step = wrap_one(yaw_change)
        speed = np.cos(yaw).item() * x_velocity + np.sin(yaw).item() * y_velocity
        yaw_travel = self._yaw_travel.item() + yaw_step
        yaw_warmup = yaw_travel if elapsed <= METRIC_WARMUP + 1e-9 else self._yaw_warmup.item()
        height = pz - (0.0 if self._ground_height is None else self._ground_height(pos[:, :2]).item())
        contact = self.robot.non_foot_contact_of(0)
        low, high = self.height_band
        drain = self._drain_step
        contact_time = max(self._contact_time.item() + (dt if contact else drain), 0.0)
        band_time = max(self._band_time.item() + (dt if height < low or height > high else drain), 0.0)
        values = [
            x_velocity,
            y_velocity,
            speed,
            yaw.item(),
            yaw_step / dt,
            1.0 - 2.0 * (x * x + yy),
            readings["power"].item(),
            wrap_one(heading_change),
            self._distance.item() + speed * dt,
            self._energy_used.item() + readings["power"].item() * dt,
            px - self._x0.item(),
            elapsed,
            yaw_travel,
            yaw_warmup,
            height,
            float(contact),
            contact_time,
            band_time,
            self._contact_steps.item() + contact,
            self._height_sum.item() + height,
            self._steps.item() + 1.0,
        ]
        # the arrays update returns, as (1,) views of one array (one call, not one per key)
        state = dict(zip(_STATE_KEYS, np.array(values)[:, None], strict=True))
        self._xy, self._yaw, self._heading_error = pos[:, :2], state["yaw"], state["heading_error"]
        self._distance, self._energy_used = state["distance"], state["energy"]
        self._yaw_travel, self._yaw_warmup = state["yaw_travel"], state["yaw_travel_warmup"]
        self._contact_time, self._band_time = state["contact_time"], state["band_time"]
        self._contact_steps, self._height_sum, self._steps = state["contact_steps"], state["height_sum"], state["steps"]
        return state

    def observe(self, readings: dict[str, np.ndarray]) -> np.ndarray:
        error = self._heading_error[:, None]
        parts = [readings["senses"], np.sin(error), np.cos(error), *self._command_obs()]
        if self.privileged_obs:
            parts += [readings["velocity"], readings["quaternion"]]
        return np.concatenate(parts, axis=1)

    def terminated(self, state: dict[str, np.ndarray]) -> np.ndarray:
        """The body tilted past ``max_tilt``; or, unless ``terminate_when_unhealthy`` is off, the leaky count of
        steps with a non-foot ground contact, or of steps with the body outside its height band, passed
        ``grace_time``."""
        if self._single:  # the same comparisons on Python floats (a tenth of the cost on arrays of one)
            ended = state["up_z"].item() < self._min_up
            if self.terminate_when_unhealthy:
                limit = self._count_limit
                ended = ended or state["contact_time"].item() > limit or state["band_time"].item() > limit
            return np.array([ended])
        tilted = state["up_z"] < self._min_up
        if not self.terminate_when_unhealthy:
            return tilted
        return tilted | self.rules_broken(state["contact_time"], state["band_time"])

    def rules_broken(self, contact_time: np.ndarray, band_time: np.ndarray) -> np.ndarray:
        """Where a ground rule's leaky count has passed the grace (whether or not the rules end episodes)."""
        return (contact_time > self._count_limit) | (band_time > self._count_limit)

    def ground_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        """The episode's fraction of steps with a non-foot ground contact and mean body height (NaN before a step)."""
        steps = info.get("steps", 0.0)
        if steps <= 0:
            return dict.fromkeys(LocomotionTask.metrics, float("nan"))
        return {"non_foot_contact": info["contact_steps"] / steps, "body_height": info["height_sum"] / steps}

    def _energy(self, state: dict[str, np.ndarray]) -> np.ndarray:
        return -self.energy_cost_weight * state["power"]


class WalkTask(LocomotionTask):
    """Walk along +x (the heading at reset): reward = forward + energy + upright (see the robot's env docstring)."""

    name = "walk"
    metrics: ClassVar[dict[str, str]] = {
        **LocomotionTask.metrics,
        "forward_speed": "progress along +x over the episode, m/s",
        "heading_drift": "mean yaw rate after the first second (signed; + is to the left), rad/s",
    }

    def __init__(
        self,
        robot: Robot,
        privileged_obs: bool = False,
        forward_reward_weight: float = 1.0,
        energy_cost_weight: float = 0.1,
        upright_reward_weight: float = 1.0,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        self.forward_reward_weight = check_number("forward_reward_weight", forward_reward_weight)
        self.upright_reward_weight = check_number("upright_reward_weight", upright_reward_weight)
        super().__init__(
            robot,
            privileged_obs,
            energy_cost_weight,
            max_tilt,
            terminate_when_unhealthy,
            height_band,
            grace_time,
            ground_height,
        )

    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {
            "forward": self.forward_reward_weight * state["x_velocity"] / self.length,
            "energy": self._energy(state),
            "upright": self.upright_reward_weight * state["up_z"],
        }

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        elapsed = info["elapsed"]
        after = elapsed - METRIC_WARMUP
        drift = (info["yaw_travel"] - info["yaw_travel_warmup"]) / after if after > 1e-9 else float("nan")
        return {
            **self.ground_metrics(info),
            "forward_speed": info["progress_x"] / elapsed if elapsed > 0 else float("nan"),
            "heading_drift": drift,
        }


class TurnTask(LocomotionTask):
    """Turn at a commanded yaw rate while running: reward = tracking + speed + energy + upright.

    ``tracking_window`` (s): the yaw rate tracked is the mean over that long (the body's yaw travel over the window,
    or since the reset within the first window), so that a gait whose body swings from side to side within a stride
    is judged by the rate it turns at, not by its swing; 0 (the default) tracks the rate over each control step.
    ``upright_reward_weight``: pay per step for the body's uprightness, as on :class:`WalkTask` (default 0): a robot
    that falls unless its legs hold it up needs it, or its learner gains by ending its episodes early.
    """

    name = "turn"
    metrics: ClassVar[dict[str, str]] = {
        **LocomotionTask.metrics,
        "yaw_rate_error": "|mean yaw rate after the first second - command|, rad/s",
    }

    def __init__(
        self,
        robot: Robot,
        privileged_obs: bool = False,
        yaw_rate_range: float = 0.8,
        tracking_reward_weight: float = 1.0,
        tracking_sigma: float = 0.5,
        speed_reward_weight: float = 0.1,
        energy_cost_weight: float = 0.1,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        ground_height: Callable[[np.ndarray], np.ndarray] | None = None,
        tracking_window: float = 0.0,
        upright_reward_weight: float = 0.0,
    ):
        self.yaw_rate_range = check_number("yaw_rate_range", yaw_rate_range, 0)
        self.upright_reward_weight = check_number("upright_reward_weight", upright_reward_weight)
        self.tracking_reward_weight = check_number("tracking_reward_weight", tracking_reward_weight)
        self.tracking_sigma = check_number("tracking_sigma", tracking_sigma, 0, strict=True)
        self.speed_reward_weight = check_number("speed_reward_weight", speed_reward_weight)
        self.tracking_window = check_number("tracking_window", tracking_window, 0, 60)
        self.yaw_rate_command = np.zeros(robot.num_sims)
        # the yaw travel of the last ``_window`` steps, per simulation (a ring; zeros back to the reset)
        self._window = max(1, round(self.tracking_window / robot.control_dt))
        self._travel_ring = np.zeros((robot.num_sims, self._window))
        self._ring_at = 0
        super().__init__(
            robot,
            privileged_obs,
            energy_cost_weight,
            max_tilt,
            terminate_when_unhealthy,
            height_band,
            grace_time,
            ground_height,
        )

    def _command_structure(self) -> dict[str, int]:
        return {"yaw_rate_command": 1}

    def _command_obs(self) -> list[np.ndarray]:
        return [self.yaw_rate_command[:, None]]

    def _draw_command(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None) -> None:
        for i, rng in zip(ids, rngs, strict=True):
            drawn = rng.uniform(-self.yaw_rate_range, self.yaw_rate_range)
            if options and "yaw_rate" in options:
                drawn = check_number("options['yaw_rate']", options["yaw_rate"])
            self.yaw_rate_command[i] = drawn

    def _target_heading(self, elapsed: np.ndarray) -> np.ndarray:
        return self.yaw_rate_command * elapsed

    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None, readings) -> None:
        super().reset(ids, rngs, options, readings)
        self._travel_ring[ids] = 0.0

    def update(self, readings: dict[str, np.ndarray], stepped: np.ndarray | None = None) -> dict[str, np.ndarray]:
        state = super().update(readings, stepped)
        if self._window > 1:  # the mean rate over the window: travel now less travel then (0 before the reset)
            travel, steps = state["yaw_travel"], state["steps"]
            then = self._travel_ring[:, self._ring_at].copy()
            if stepped is None:
                self._travel_ring[:, self._ring_at] = travel
            else:  # a simulation reset in this step took no step: its ring stays as the reset left it
                self._travel_ring[:, self._ring_at] = np.where(stepped, travel, self._travel_ring[:, self._ring_at])
            self._ring_at = (self._ring_at + 1) % self._window
            state["yaw_rate_window"] = (travel - then) / (np.clip(steps, 1.0, self._window) * self._dt)
        return state

    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        rate = state["yaw_rate_window"] if self._window > 1 else state["yaw_rate"]
        error = (rate - self.yaw_rate_command) / self.tracking_sigma
        return {
            "tracking": self.tracking_reward_weight * np.exp(-np.square(error)),
            "speed": self.speed_reward_weight * state["speed"] / self.length,
            "energy": self._energy(state),
            "upright": self.upright_reward_weight * state["up_z"],
        }

    def info(self, readings: dict[str, np.ndarray], state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {**state, "yaw_rate_command": self.yaw_rate_command.copy()}

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        after = info["elapsed"] - METRIC_WARMUP
        if after <= 1e-9:
            return {**self.ground_metrics(info), "yaw_rate_error": float("nan")}
        mean_rate = (info["yaw_travel"] - info["yaw_travel_warmup"]) / after
        return {**self.ground_metrics(info), "yaw_rate_error": abs(mean_rate - info["yaw_rate_command"])}
