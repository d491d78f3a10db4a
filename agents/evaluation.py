"""Rollouts of a policy in an env, per-episode metrics, and their statistics.

Every policy is run on the same episode seeds, so two policies can be compared episode by episode (paired).
Confidence intervals are 95% bootstrap intervals (scipy.stats.bootstrap, BCa; percentile when BCa is undefined)
from 10 episodes up, Student's t intervals below that, and none from one episode.

Metrics come from the env's own metadata (the robot's mass and length, the task's metrics), never from one robot's
constants: the generic ones below from the running sums every task reports in ``info``, the task's own from
``task.episode_metrics``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from agents import Policy
from envs.common.io import atomic_write

GRAVITY = 9.81
GENERIC_METRICS = {
    "return": "episode return",
    "speed": "mean speed along the body's heading, m/s",
    "speed_bl": "the same in body lengths per second",
    "cost_of_transport": "electrical energy / (m g distance travelled)",
    "power": "mean electrical power, W (energy / time: defined where the robot travels nowhere, as on a turn)",
    "energy": "electrical energy over the episode, J (an academy episode ends when its task is done: what it took)",
    "falls": "1 if the task ended the episode: the robot fell (tilted past its limit) or broke a ground rule",
}
LOWER_IS_BETTER = ("yaw_rate_error", "cost_of_transport", "power", "energy", "falls")
"""The metrics (generic or a task's) where a smaller value is the better one; every other is better larger."""


def metric_descriptions(env) -> dict[str, str]:
    """Every metric an episode of ``env`` reports: the generic ones, then the task's."""
    return {**GENERIC_METRICS, **env.unwrapped.task.metrics}


def episode_metrics(env, total_reward: float, info: Mapping[str, Any], fallen: bool) -> dict[str, float]:
    """Metrics of an episode from its return and its last complete ``info`` (the running sums)."""
    context = env.unwrapped.metrics_context()
    elapsed = float(info.get("elapsed", 0.0))
    distance = float(info.get("distance", 0.0))
    speed = distance / elapsed if elapsed > 0 else 0.0
    energy = float(info.get("energy", 0.0))
    metrics = {
        "return": float(total_reward),
        "speed": speed,
        "speed_bl": speed / context["length"],
        "cost_of_transport": energy / (context["mass"] * GRAVITY * distance) if distance > 1e-6 else float("nan"),
        "power": energy / elapsed if elapsed > 0 else float("nan"),
        "energy": energy,
        "falls": float(fallen),
    }
    if elapsed > 0:
        metrics.update(context["task"].episode_metrics(info))
    else:
        metrics.update(dict.fromkeys(context["task"].metrics, float("nan")))
    return metrics


@dataclass
class Episode:
    seed: int
    length: int
    duration: float
    metrics: dict[str, float]
    unstable: bool = False
    frames: list[np.ndarray] = field(default_factory=list, repr=False)


def run_episode(env, policy: Policy, seed: int, deterministic: bool = True, render: bool = False) -> Episode:
    """Run one episode; the metrics come from the env's ``info``."""
    obs, info = env.reset(seed=seed)
    state, start = None, np.array([True])
    total, steps = 0.0, 0
    last = info  # the last info with the running sums (an unstable step's info has none)
    unstable = fallen = False
    frames = [env.render()] if render else []
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
        last = info
        fallen = bool(info.get("fallen", False))
        if terminated or truncated:
            break
    metrics = episode_metrics(env, total, last, fallen)
    return Episode(seed, steps, steps * env.unwrapped.dt, metrics, unstable, frames)


def run_episodes(
    venv,
    policy: Policy,
    seeds: list[int],
    deterministic: bool = True,
    render_first: bool = False,
    render_every: int = 1,
) -> list[Episode]:
    """Run one episode per seed at once, simulation i with seed ``seeds[i]``, on a batched env of ``len(seeds)``
    simulations; the same episodes :func:`run_episode` runs one after another (a batched env gives each simulation
    a single env's results). Each simulation's first episode counts; what it does after it ends is not used.
    ``render_first``: frames of simulation 0's episode, at its start and after every ``render_every``-th step."""
    base = venv.unwrapped
    n = base.num_envs
    if n != len(seeds):
        raise ValueError(f"{len(seeds)} seeds for {n} simulations")
    obs, info = venv.reset(seed=list(seeds))
    state, start = None, np.ones(n, dtype=bool)
    running = np.ones(n, dtype=bool)
    totals, steps = np.zeros(n), np.zeros(n, dtype=np.int64)
    last: list[dict[str, Any]] = [_row(info, i) for i in range(n)]
    fallen, unstable = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    frames = [venv.render()] if render_first else []
    while running.any():
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=deterministic)
        start = np.zeros(n, dtype=bool)
        obs, reward, terminated, truncated, info = venv.step(action)
        totals[running] += reward[running]
        steps[running] += 1
        if render_first and running[0] and steps[0] % render_every == 0:
            frames.append(venv.render())
        for i in np.flatnonzero(running):
            if info["sim_unstable"][i]:
                unstable[i] = True
            else:
                last[i] = _row(info, i)
                fallen[i] = bool(info["fallen"][i])
        running &= ~(terminated | truncated)
    return [
        Episode(seed, int(steps[i]), int(steps[i]) * base.dt, episode_metrics(venv, totals[i], last[i], fallen[i]),
                bool(unstable[i]), frames if i == 0 else [])
        for i, seed in enumerate(seeds)
    ]  # fmt: skip


def _row(info: Mapping[str, Any], i: int) -> dict[str, Any]:
    """Simulation i's entries of a vector info."""
    return {k: v[i] for k, v in info.items() if not k.startswith("_") and info[f"_{k}"][i]}


MIN_BOOTSTRAP = 10  # fewer values, and a bootstrap interval is too narrow (with 3, BCa spans their min to max)


def bootstrap_ci(values: np.ndarray, confidence: float = 0.95, seed: int = 0) -> tuple[float, float]:
    """95% interval of the mean: bootstrap (BCa; percentile if BCa is undefined) from :data:`MIN_BOOTSTRAP` values;
    below that, Student's t interval, which a bootstrap undercuts on so few; none (NaN) from one value, where no
    interval can be had, and a point where every value is the same."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return float("nan"), float("nan")
    if np.ptp(x) == 0:
        return float(x.mean()), float(x.mean())
    if len(x) < MIN_BOOTSTRAP:
        half = stats.t.ppf(0.5 + confidence / 2, len(x) - 1) * x.std(ddof=1) / math.sqrt(len(x))
        return float(x.mean() - half), float(x.mean() + half)
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


def write_video(frames: list[np.ndarray], path: Path, fps: float) -> None:
    """An mp4 of ``frames`` at ``fps``, written atomically (evaluate.py's videos, walking and soccer)."""
    import imageio.v2 as imageio

    def write(tmp: Path) -> None:
        with imageio.get_writer(tmp, format="FFMPEG", fps=fps, codec="libx264", macro_block_size=8) as w:
            for frame in frames:
                w.append_data(frame)

    atomic_write(path, write)
