"""Rollouts of a policy in an env, per-episode task metrics, and their statistics.

Every policy is run on the same episode seeds, so two policies can be compared episode by episode (paired).
Confidence intervals are 95% bootstrap intervals (scipy.stats.bootstrap, BCa; percentile when BCa is undefined).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from agents import Policy
from envs.velociroach import constants as C

WARMUP_SECONDS = 1.0  # left out of the yaw-rate error: the gait settles in the first second
METRICS = {
    "return": "episode return",
    "speed": "mean speed along the body's heading, m/s",
    "forward_speed": "progress along +x (RoachWalk's direction) over the episode, m/s",
    "speed_bl": "the same in body lengths per second",
    "cost_of_transport": "electrical energy / (m g distance travelled)",
    "falls": "1 if the episode ended with the robot fallen",
    "yaw_rate_error": "|mean yaw rate after the first second - command|, rad/s (RoachTurn)",
}


@dataclass
class Episode:
    seed: int
    length: int
    duration: float
    metrics: dict[str, float]
    unstable: bool = False
    frames: list[np.ndarray] = field(default_factory=list, repr=False)


def run_episode(env, policy: Policy, seed: int, deterministic: bool = True, render: bool = False) -> Episode:
    """Run one episode; the metrics come from the env's ``info`` at every step."""
    obs, info = env.reset(seed=seed)
    state, start = None, np.array([True])
    total, steps, energy, distance = 0.0, 0, 0.0, 0.0
    x_end = info["x_position"]
    yaw_rates: list[float] = []
    fallen = unstable = False
    frames = [env.render()] if render else []
    dt = env.unwrapped.dt
    command = info.get("yaw_rate_command")
    x_start = info["x_position"]
    while True:
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=deterministic)
        start = np.array([False])
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        steps += 1
        if render:
            frames.append(env.render())
        if info.get("sim_unstable"):
            unstable = True
            break
        heading = np.array([np.cos(info["yaw"]), np.sin(info["yaw"])])
        distance += float(heading @ np.array([info["x_velocity"], info["y_velocity"]])) * dt
        energy += info["power"] * dt
        if info["time"] > WARMUP_SECONDS:
            yaw_rates.append(info["yaw_rate"])
        fallen = bool(info.get("fallen", False))
        x_end = info["x_position"]
        if terminated or truncated:
            break
    duration = steps * dt
    robot = env.unwrapped.robot
    speed = distance / duration if duration > 0 else 0.0
    metrics = {
        "return": total,
        "speed": speed,
        "speed_bl": speed / C.LENGTH,
        "cost_of_transport": energy / (robot.mass * 9.81 * distance) if distance > 1e-6 else float("nan"),
        "falls": float(fallen),
    }
    if hasattr(env.unwrapped, "forward_reward_weight"):  # a task that runs along +x (RoachWalk)
        metrics["forward_speed"] = (x_end - x_start) / duration if duration > 0 else 0.0
    if command is not None:
        metrics["yaw_rate_error"] = abs(float(np.mean(yaw_rates)) - command) if yaw_rates else float("nan")
    return Episode(seed=seed, length=steps, duration=duration, metrics=metrics, unstable=unstable, frames=frames)


def bootstrap_ci(values: np.ndarray, confidence: float = 0.95, seed: int = 0) -> tuple[float, float]:
    """95% bootstrap interval of the mean (BCa; percentile if BCa is undefined, e.g. all values equal)."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return float("nan"), float("nan")
    if len(x) == 1 or np.ptp(x) == 0:
        return float(x.mean()), float(x.mean())
    rng = np.random.default_rng(seed)
    for method in ("BCa", "percentile"):
        res = stats.bootstrap((x,), np.mean, confidence_level=confidence, method=method, random_state=rng)
        low, high = res.confidence_interval
        if np.isfinite(low) and np.isfinite(high):
            return float(low), float(high)
    return float("nan"), float("nan")


def summarize(episodes: list[Episode]) -> dict[str, dict[str, float]]:
    """Mean, 95% bootstrap CI and count of each metric."""
    out = {}
    for name in episodes[0].metrics:
        values = np.array([e.metrics[name] for e in episodes], dtype=float)
        finite = values[np.isfinite(values)]
        low, high = bootstrap_ci(finite)
        out[name] = {
            "mean": float(finite.mean()) if len(finite) else float("nan"),
            "ci_low": low,
            "ci_high": high,
            "n": len(finite),
        }
    return out


def paired_difference(a: list[Episode], b: list[Episode], metric: str) -> dict[str, float]:
    """Mean and 95% bootstrap CI of metric(b) - metric(a) over the episodes both ran with the same seed."""
    by_seed = {e.seed: e.metrics[metric] for e in a}
    diffs = np.array([e.metrics[metric] - by_seed[e.seed] for e in b if e.seed in by_seed], dtype=float)
    diffs = diffs[np.isfinite(diffs)]
    low, high = bootstrap_ci(diffs)
    return {"mean": float(diffs.mean()) if len(diffs) else float("nan"), "ci_low": low, "ci_high": high,
            "n": len(diffs)}  # fmt: skip


def episode_record(e: Episode) -> dict[str, Any]:
    d = asdict(e)
    d.pop("frames")
    return d
