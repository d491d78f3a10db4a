"""The ground rules against the reference gaits: on every registered id, each robot's reference gait runs the
evaluation seeds (0-9, as ``evaluate.py`` uses by default, and 1000-1009, as ``make demo`` does) and the table reports
how often the rules would end its episodes, how close it came (the largest leaky counts, against the grace time), its
fraction of steps with a non-foot ground contact and its body height against its band.

A reference gait that trips a rule means a rule is wrong, not the gait: the benchmark prints ``MISSED`` for it. The
soccer academy's ids are reported apart and do not count toward the verdict: there the walking gait, which heads for
+x and knows no walls, walks into the field's wall and climbs or tips at it, which the rules rightly end.

Run: ``python -m benchmarks.ground_rules`` (a few minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import envs  # noqa: F401 (registers the ids)
from agents import load_policy, reference_policy
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser

SEEDS = [*range(10), *range(1000, 1010)]

CONFIGURATIONS: dict[str, list[str]] = {"ground_rules": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def skitter_ids() -> list[str]:
    """Every registered skitter id, in registration order."""
    return [env_id for env_id in gym.registry if env_id.startswith("skitter/")]


def run(env_id: str, seeds: list[int], yaw_rate: float | None = None) -> dict:
    """The reference gait of ``env_id``'s robot on ``seeds``, one batched env (on a turning task, each episode's
    command drawn, or ``yaw_rate`` for all): per episode, whether the ground rules or a tilt ended it, the largest
    leaky counts and the ground metrics."""
    venv = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point")
    base = venv.unwrapped
    task = base.task
    name = reference_policy(base.robot.name)
    policy = load_policy(name, venv)
    obs, info = venv.reset(seed=seeds, options=None if yaw_rate is None else {"yaw_rate": yaw_rate})
    n = len(seeds)
    running = np.ones(n, dtype=bool)
    most_contact, most_band = np.zeros(n), np.zeros(n)
    contact_steps, height_sum, steps = np.zeros(n), np.zeros(n), np.zeros(n)
    low_height, high_height = np.full(n, np.inf), np.full(n, -np.inf)
    by_rule, by_tilt = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    state, start = None, np.ones(n, dtype=bool)
    while running.any():
        action, state = policy.predict(obs, state=state, episode_start=start, deterministic=True)
        start = np.zeros(n, dtype=bool)
        obs, _, terminated, truncated, info = venv.step(action)
        live = running & ~info["sim_unstable"]
        most_contact = np.where(live, np.maximum(most_contact, info["contact_time"]), most_contact)
        most_band = np.where(live, np.maximum(most_band, info["band_time"]), most_band)
        contact_steps = np.where(live, info["contact_steps"], contact_steps)
        height_sum = np.where(live, info["height_sum"], height_sum)
        steps = np.where(live, info["steps"], steps)
        low_height = np.where(live, np.minimum(low_height, info["body_height"]), low_height)
        high_height = np.where(live, np.maximum(high_height, info["body_height"]), high_height)
        ended = running & terminated
        rule = task.rules_broken(info["contact_time"], info["band_time"])
        by_rule |= ended & rule
        by_tilt |= ended & ~rule & info["fallen"]
        running &= ~(terminated | truncated)
    venv.close()
    return {
        "env_id": env_id,
        "yaw_rate": yaw_rate,
        "policy": name,
        "episodes": n,
        "ended_by_ground_rules": int(by_rule.sum()),
        "ended_by_tilt": int(by_tilt.sum()),
        "max_contact_time": float(most_contact.max()),
        "max_band_time": float(most_band.max()),
        "grace_time": float(task.grace_time),
        "non_foot_contact": float(contact_steps.sum() / steps.sum()),
        "body_height": float(height_sum.sum() / steps.sum()),
        "lowest_height": float(low_height.min()),
        "highest_height": float(high_height.max()),
        "height_band": list(task.height_band),
        "walled_field": hasattr(task, "field"),  # a soccer task: on its robot's walled field
    }


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--ids", nargs="+", default=None, help="env ids (default: every registered skitter id)")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    ids = args.ids or skitter_ids()
    unknown = sorted(set(ids) - set(skitter_ids()))
    if unknown:
        parser.error(f"--ids: not registered skitter ids: {', '.join(unknown)}")
    output = resolve_output(parser, args, "ground_rules", CONFIGURATIONS)
    started = time.perf_counter()
    rows = []
    for env_id in ids:
        rows.append(run(env_id, SEEDS))
        turn = getattr(gym.make(env_id).unwrapped.task, "yaw_rate_range", None)
        if turn:  # a turning task also at its hardest commands, either way
            rows += [run(env_id, SEEDS, sign * turn) for sign in (-1.0, 1.0)]
    wall = time.perf_counter() - started
    missed = [r["env_id"] for r in rows if r["ended_by_ground_rules"] and not r["walled_field"]]
    table = md_table(
        ["env id", "reference", "episodes", "ended by the ground rules", "ended by a tilt",
         "largest contact count / grace, s", "largest band count / grace, s", "non-foot contact, fraction of steps",
         "body height mean (lowest-highest), m", "band, m"],
        [[r["env_id"] + ("" if r["yaw_rate"] is None else f", command {r['yaw_rate']:+g} rad/s"), r["policy"],
          r["episodes"], r["ended_by_ground_rules"], r["ended_by_tilt"],
          f"{r['max_contact_time']:.2f} / {r['grace_time']:g}", f"{r['max_band_time']:.2f} / {r['grace_time']:g}",
          f"{r['non_foot_contact']:.2g}",
          f"{r['body_height']:.4f} ({r['lowest_height']:.4f}-{r['highest_height']:.4f})",
          f"{r['height_band'][0]:.4f}-{r['height_band'][1]:.4f}"] for r in rows],
    )  # fmt: skip
    open_ground = [r for r in rows if not r["walled_field"]]
    walled = [r for r in rows if r["walled_field"]]
    ended = sum(r["ended_by_ground_rules"] for r in open_ground)
    verdict = (
        f"{ended} of {sum(r['episodes'] for r in open_ground)} reference episodes on open ground ended by the ground "
        "rules: " + (f"MISSED (on {', '.join(missed)})" if missed else "met")
    )
    if walled:
        verdict += (
            f". On the soccer fields (not in the verdict; the walking gait walks into the wall): "
            f"{sum(r['ended_by_ground_rules'] for r in walled)} of {sum(r['episodes'] for r in walled)} ended by the "
            f"rules, {sum(r['ended_by_tilt'] for r in walled)} by a tilt"
        )
    md = (
        "# The ground rules against the reference gaits\n\n"
        f"Seeds {SEEDS[0]}-{SEEDS[9]} and {SEEDS[10]}-{SEEDS[-1]} on every id, the robot's reference gait, batched; "
        "turning ids with commands drawn per episode, then at their hardest command either way. "
        "A count is the leaky time (s) a rule was broken; an episode ends when it passes the grace time.\n\n"
        + table
        + f"\n{verdict}. Wall time {wall:.0f} s.\n"
    )
    output.save({"rows": rows, "seeds": SEEDS, "met": not missed, "wall_seconds": wall}, md)


if __name__ == "__main__":
    main()
