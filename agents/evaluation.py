"""Rollouts of a policy in an env, per-episode metrics, and their statistics.

Every policy is run on the same episode seeds, so two policies can be compared episode by episode (paired).
Confidence intervals are 95% bootstrap intervals (scipy.stats.bootstrap, BCa; percentile when BCa is undefined)
from 10 episodes up, Student's t intervals below that, and none from one episode. A metric that is 1 or 0 an episode
(a fall, a task's success: ``BINARY_METRICS`` and the task's ``binary_metrics``) is a proportion: its interval is
Wilson's score interval, and a paired difference of two policies' is Newcombe's (1998, method 10, from the Wilson
intervals of each and the pairs' correlation), so that 20 successes of 20 read [0.84, 1], not the point 1.

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
BINARY_METRICS = ("falls",)
"""The generic metrics that are 1 or 0 an episode (a task adds its own: ``Task.binary_metrics``)."""


def metric_descriptions(env) -> dict[str, str]:
    """Every metric an episode of ``env`` reports: the generic ones, then the task's."""
    return {**GENERIC_METRICS, **env.unwrapped.task.metrics}


def binary_metrics(env) -> tuple[str, ...]:
    """The metrics of ``env``'s episodes that are 1 or 0 an episode: the generic ones and the task's."""
    return (*BINARY_METRICS, *getattr(env.unwrapped.task, "binary_metrics", ()))


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


Z95 = float(stats.norm.ppf(0.975))


def proportion_ci(values: np.ndarray, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson's score interval of the share of ones among ``values`` (each 1 or 0); none (NaN) from no value."""
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return float("nan"), float("nan")
    _check_binary(x)
    return wilson_interval(int(x.sum()), len(x), confidence)


def wilson_interval(count: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson's score interval of a proportion of ``count`` in ``n`` (scipy's ``binomtest``)."""
    ci = stats.binomtest(int(count), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


def paired_proportion_ci(first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
    """95% interval of the difference of two paired proportions, mean(second) - mean(first), over pairs of 1 or 0
    (the same episode seeds): Newcombe's hybrid score interval (method 10 of Newcombe 1998, Stat. Med. 17:2635),
    from each proportion's Wilson interval and the phi coefficient of the pairs' 2 x 2 table (0 where a margin is
    empty; a positive one corrected as Newcombe gives, ad - bc less n/2). Unlike a bootstrap it has a width where
    every pair agrees: 20 pairs of successes give about +-0.16. Its coverage, simulated on 20 correlated pairs,
    stays at 0.95 or above where the bootstrap's falls to 0.78 (tests/test_evaluate.py)."""
    a_, b_ = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    keep = np.isfinite(a_) & np.isfinite(b_)
    a_, b_ = a_[keep], b_[keep]
    n = len(a_)
    if n == 0:
        return float("nan"), float("nan")
    _check_binary(a_)
    _check_binary(b_)
    p1, p2 = b_.mean(), a_.mean()  # the difference is second - first
    l1, u1 = proportion_ci(b_)
    l2, u2 = proportion_ci(a_)
    both, only_second = float(np.sum((a_ == 1) & (b_ == 1))), float(np.sum((a_ == 0) & (b_ == 1)))
    only_first, neither = float(np.sum((a_ == 1) & (b_ == 0))), float(np.sum((a_ == 0) & (b_ == 0)))
    margins = (both + only_second) * (only_first + neither) * (both + only_first) * (only_second + neither)
    cross = both * neither - only_second * only_first
    if cross > 0:  # Newcombe's correction of a positive correlation, which a few discordant pairs overstate
        cross = max(cross - n / 2, 0.0)
    phi = cross / math.sqrt(margins) if margins > 0 else 0.0
    theta = p1 - p2
    low = theta - math.sqrt(max((p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2) + (u2 - p2) ** 2, 0.0))
    high = theta + math.sqrt(max((u1 - p1) ** 2 - 2 * phi * (u1 - p1) * (p2 - l2) + (p2 - l2) ** 2, 0.0))
    return float(max(low, -1.0)), float(min(high, 1.0))


def _check_binary(x: np.ndarray) -> None:
    if not np.isin(x, (0.0, 1.0)).all():
        raise ValueError(f"a proportion's values are 1 or 0, not {sorted(set(x.tolist()) - {0.0, 1.0})[:3]}")


def summarize(episodes: list[Episode], binary: tuple[str, ...] | frozenset[str] = ()) -> dict[str, dict[str, float]]:
    """Mean, 95% interval and count of each metric: a bootstrap's (:func:`bootstrap_ci`), or for the metrics in
    ``binary`` (1 or 0 an episode) Wilson's (:func:`proportion_ci`)."""
    out = {}
    for name in episodes[0].metrics:
        values = np.array([e.metrics[name] for e in episodes], dtype=float)
        finite = values[np.isfinite(values)]
        low, high = proportion_ci(finite) if name in binary else bootstrap_ci(finite)
        out[name] = {
            "mean": float(finite.mean()) if len(finite) else float("nan"),
            "ci_low": low,
            "ci_high": high,
            "n": len(finite),
        }
    return out


def paired_difference(a: list[Episode], b: list[Episode], metric: str, binary: bool = False) -> dict[str, float]:
    """Mean and 95% interval of metric(b) - metric(a) over the episodes both ran with the same seed: a bootstrap's,
    or where the metric is 1 or 0 an episode (``binary``) Newcombe's (:func:`paired_proportion_ci`)."""
    by_seed = {e.seed: e.metrics[metric] for e in a}
    pairs = np.array([(by_seed[e.seed], e.metrics[metric]) for e in b if e.seed in by_seed], dtype=float)
    pairs = pairs[np.isfinite(pairs).all(axis=1)] if len(pairs) else np.empty((0, 2))
    diffs = pairs[:, 1] - pairs[:, 0]
    low, high = paired_proportion_ci(pairs[:, 0], pairs[:, 1]) if binary else bootstrap_ci(diffs)
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
