"""How often a soccer scene goes numerically unstable: batched two-a-side matches of random play, every robot.

For each robot, ``--matches`` (32) two-a-side matches in the robot's own action mode run as one
:class:`~agents.soccer.vec_env.SoccerVecEnv` from uniform random actions, for ``--steps`` control steps (1250) from
each of ``--seeds`` (0 1). A control step whose scene goes unstable (MuJoCo's bad-acceleration warning: it resets
that scene's data) or ends with a joint faster than 1,000 rad/s is run again at physics steps 8 times shorter (32
where those diverge too); where that holds, the match goes on (counted as refined), else it ends, truncated, with
nothing of that step counted (docs/soccer.md). The matches that end are started again, so that every match plays
the whole time. Reported: the scenes lost to instability per hour of match
play, with the exact Poisson 95% interval of that rate, and the steps run again. Goal: none lost.

Random play is the hardest case a learner's first updates meet: players run into each other at every heading. It
is not a match between trained or scripted teams, whose rates are those of their own runs (docs/soccer.md).

Run: ``python -m benchmarks.soccer_stability`` (about 10 minutes; the roach's physics is most of it).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy import stats

from agents.soccer.vec_env import SoccerVecEnv
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, non_negative
from envs.common.simulation import DIVERGED_SPEED, REFINE_AGAIN
from envs.soccer.match import REFINE_UNSTABLE

CONFIGURATIONS: dict[str, list[str]] = {"soccer_stability": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
ROBOTS = ("roach", "xjus", "bioloid")


def random_play(robot: str, matches: int, steps: int, seed: int) -> dict:
    """``matches`` two-a-side matches of random actions for ``steps`` control steps: the scenes that went unstable,
    each with the match time it happened at."""
    vec = SoccerVecEnv(matches, nthread=1, robot=robot, players_per_team=2, max_cycles=steps + 1)
    vec.seed(seed)
    vec.reset()
    engine = vec.engine
    rng = np.random.default_rng(seed)
    events, refined = [], []
    began = time.perf_counter()
    for t in range(steps):
        out = engine.step(rng.uniform(-1, 1, (vec.num_envs, vec.action_space.shape[0])).astype(np.float32))
        events += [{"match": int(m), "step": t} for m in np.flatnonzero(out["unstable"])]
        refined += [{"match": int(m), "step": t} for m in np.flatnonzero(out["refined"])]
        ended = np.flatnonzero(out["ended"] | out["truncated"])
        if len(ended):
            engine.reset(ended)
    vec.close()
    return {"robot": robot, "seed": seed, "matches": matches, "steps": steps, "dt": engine.dt,
            "match_seconds": matches * steps * engine.dt, "unstable": events, "refined": refined,
            "wall_seconds": time.perf_counter() - began}  # fmt: skip


def rate_per_hour(count: int, seconds: float) -> tuple[float, float, float]:
    """A count of events in ``seconds`` as a rate per hour, with its exact (Garwood) Poisson 95% interval."""
    hours = seconds / 3600.0
    low = 0.0 if count == 0 else stats.chi2.ppf(0.025, 2 * count) / 2
    high = stats.chi2.ppf(0.975, 2 * count + 2) / 2
    return count / hours, low / hours, high / hours


def summarize(runs: list[dict]) -> list[dict]:
    rows = []
    for robot in dict.fromkeys(r["robot"] for r in runs):
        mine = [r for r in runs if r["robot"] == robot]
        count = sum(len(r["unstable"]) for r in mine)
        seconds = sum(r["match_seconds"] for r in mine)
        rate, low, high = rate_per_hour(count, seconds)
        refined = sum(len(r.get("refined", [])) for r in mine)
        rows.append({"robot": robot, "match_seconds": seconds, "unstable": count, "per_hour": rate,
                     "per_hour_ci": [low, high], "refined": refined, "seeds": [r["seed"] for r in mine]})  # fmt: skip
    return rows


def report(rows: list[dict], matches: int, steps: int, seeds: list[int]) -> str:
    """The benchmark's page: a row per robot, and the verdict."""
    missed = [r["robot"] for r in rows if r["unstable"]]
    table = md_table(
        ["robot", "match time, s", "steps run again at shorter steps (held)", "scenes lost to instability",
         "lost per hour of match play [95% CI]"],
        [[r["robot"], f"{r['match_seconds']:.0f}", r["refined"], r["unstable"],
          f"{r['per_hour']:.1f} [{r['per_hour_ci'][0]:.1f}, {r['per_hour_ci'][1]:.1f}]"] for r in rows],
    )  # fmt: skip
    verdict = "goal met: no scene lost to instability" if not missed else "MISSED (goal: none): " + ", ".join(missed)
    return (
        "# Soccer stability\n\n"
        f"{matches} two-a-side matches of each robot in its own action mode, uniform random actions, "
        f"{steps} control steps from each of seeds {', '.join(map(str, seeds))}; a match that ends is "
        "started again. A step whose scene diverges (MuJoCo resets it, or a joint ends it faster than "
        f"{DIVERGED_SPEED:,.0f} rad/s) is run again at physics steps {REFINE_UNSTABLE} times shorter "
        f"({REFINE_UNSTABLE * REFINE_AGAIN} where those diverge too); where every run diverges, the scene is lost: its "
        "match ends with nothing of that step counted.\n\n" + table + f"\n{verdict}.\n"
    )


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--robots", nargs="+", choices=ROBOTS, default=list(ROBOTS))
    parser.add_argument("--matches", type=int, default=32, help="two-a-side matches per robot, batched")
    parser.add_argument("--steps", type=int, default=1250, help="control steps from each seed")
    parser.add_argument("--seeds", type=non_negative, nargs="+", default=[0, 1])
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.matches < 1 or args.steps < 1:
        parser.error("--matches and --steps must be at least 1")
    output = resolve_output(parser, args, "soccer_stability", CONFIGURATIONS)
    os.environ.setdefault("SKITTER_THREADS", "1")
    runs = [random_play(robot, args.matches, args.steps, seed) for robot in args.robots for seed in args.seeds]
    rows = summarize(runs)
    missed = [r["robot"] for r in rows if r["unstable"]]
    md = report(rows, args.matches, args.steps, args.seeds)
    output.save({"runs": runs, "rows": rows, "met": not missed}, md)


if __name__ == "__main__":
    main()
