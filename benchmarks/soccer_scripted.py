"""The scripted soccer team, measured: what one scripted player does on the academy's tasks in the commands mode,
and its record in one-a-side matches against a random team (the goal: 18 wins in 20 for every robot) and against
itself (even within the interval).

Academy: ``skitter/<Robot>{GoToBall,ScoreEmptyGoal,ScoreVsKeeper}`` at their current versions,
``action_mode="commands"``, seeds 1000-1019 (one batched env of 20), the scripted field player
(envs/soccer/scripted.py) on each episode (against the scripted keeper on ScoreVsKeeper): successes, falls and the
mean time of a success. ``--academy-only`` runs this part alone (a few minutes, under
``runs/benchmarks/``). Matches: ``evaluate.py --soccer ROBOT --players 1`` as a library
call, 20 matches of 10 minutes (one half of a Four-Legged League match, RoboCup 2005 rules) on seeds 0-19, home
scripted against away random and against away scripted, two robots' sets at a time (one process per core). The
Bioloid plays again with its kick (``kick=True``: both teams have the action, the scripted team kicks), in the
academy and against random.

Run: ``python -m benchmarks.soccer_scripted`` (41 minutes on 2 idle cores, 2026-12-03; 82 beside a training job).
``--robots bioloid`` runs one robot's sets (13 minutes for the Bioloid), under ``runs/benchmarks/``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor

import gymnasium as gym
import numpy as np

import envs  # noqa: F401 (registers the ids)
from agents.soccer.play import play
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser
from envs.soccer import TASKS as ACADEMY_TASKS
from envs.soccer.academy import version
from envs.soccer.scripted import scripted_player

CONFIGURATIONS: dict[str, list[str]] = {
    "soccer_scripted": [],
}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
ROBOTS = {"roach": "Roach", "xjus": "Xjus", "bioloid": "Bioloid"}
TASKS = ("GoToBall", "ScoreEmptyGoal", "ScoreVsKeeper")
EPISODE_SEEDS = list(range(1000, 1020))
MATCHES = 20
MATCH_SECONDS = 600.0  # one half of a Four-Legged League match (two halves of 10 minutes, RoboCup 2005 rules)
WINS_WANTED = 18  # of 20, against a random team


KICKERS = ("bioloid",)  # robots whose sets run again with the kick action


def academy(robot: str, task: str, kick: bool = False) -> dict:
    """The scripted player on one academy task in the commands mode (with the kick action), one episode per
    seed."""
    env_id = f"skitter/{ROBOTS[robot]}{task}-v{version(ROBOTS[robot], ACADEMY_TASKS[task])}"
    venv = gym.make_vec(env_id, num_envs=len(EPISODE_SEEDS), vectorization_mode="vector_entry_point",
                        action_mode="commands", kick=kick)  # fmt: skip
    base = venv.unwrapped
    commands = base.env.commands
    player = scripted_player(base.task.layout, commands.mode, base.robot.facts.length, base.task.field, commands)
    obs, _ = venv.reset(seed=EPISODE_SEEDS)
    n = len(EPISODE_SEEDS)
    done, success, fell, ended_at = np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, bool), np.zeros(n)
    memory = None
    for step in range(base.max_episode_steps):
        action, memory = player.predict(obs, memory)
        obs, _, terminated, truncated, info = venv.step(action)
        new = (terminated | truncated) & ~done
        success[new], fell[new] = info["success"][new] > 0, info["fallen"][new]
        ended_at[new] = (step + 1) * base.dt
        done |= new
        if done.all():
            break
    venv.close()
    return {"env_id": env_id, "kick": kick, "episodes": n, "successes": int(success.sum()), "falls": int(fell.sum()),
            "mean_success_seconds": float(ended_at[success].mean()) if success.any() else None}  # fmt: skip


def match_set(job: tuple[str, str, bool]) -> dict:
    """The scripted team's record in one-a-side matches against ``away`` on ``robot`` (with the kick action)."""
    robot, away, kick = job
    return play(robot, 1, "scripted", away, MATCHES, 0, MATCH_SECONDS, kick=kick)


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--academy-only", action="store_true", help="run the academy's episodes, not the matches")
    parser.add_argument("--robots", nargs="+", choices=tuple(ROBOTS), default=list(ROBOTS),
                        help="the robots whose academy and matches to run (default: all three)")  # fmt: skip
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "soccer_scripted", CONFIGURATIONS)
    started = time.perf_counter()
    robots = [r for r in ROBOTS if r in args.robots]
    kickers = [r for r in KICKERS if r in args.robots]
    episodes = [academy(robot, task) for robot in robots for task in TASKS]
    episodes += [academy(robot, task, kick=True) for robot in kickers for task in TASKS]
    jobs = [] if args.academy_only else [(robot, away, False) for robot in robots for away in ("random", "scripted")]
    jobs += [] if args.academy_only else [(robot, "random", True) for robot in kickers]
    # each set is seeded on its own (the same numbers serially); fresh interpreters, not forks of this one, whose
    # simulations' worker threads a fork would not carry over
    with ProcessPoolExecutor(max_workers=2, mp_context=multiprocessing.get_context("spawn")) as pool:
        results = list(pool.map(match_set, jobs))
    matches = [{"robot": robot + (" (kick)" if kick else ""), "away": away, "kick": kick, **result}
               for (robot, away, kick), result in zip(jobs, results, strict=True)]  # fmt: skip
    wall = time.perf_counter() - started
    academy_table = md_table(
        ["env id (commands mode)", "episodes", "successes", "falls", "mean time of a success, s"],
        [[e["env_id"] + (", kick" if e["kick"] else ""), e["episodes"], e["successes"], e["falls"],
          "-" if e["mean_success_seconds"] is None else f"{e['mean_success_seconds']:.1f}"] for e in episodes],
    )  # fmt: skip

    def record(m: dict) -> list:
        gd = m["goal_difference"]
        return [m["robot"], m["away"], m["wins"]["count"], m["draws"]["count"], m["losses"]["count"],
                f"{gd['mean']:+.2f} [{gd['ci_low']:+.2f}, {gd['ci_high']:+.2f}]",
                f"{m['goals']['home']}-{m['goals']['away']}"]  # fmt: skip

    match_table = md_table(["robot", "away team", "wins", "draws", "losses", "goal difference [95% CI]", "goals"],
                           [record(m) for m in matches])  # fmt: skip
    verdicts = []
    for m in matches:
        if m["away"] == "random":
            wins = m["wins"]["count"]
            verdicts.append(f"{m['robot']} against random: {wins} wins of {MATCHES} "
                            + ("(met)" if wins >= WINS_WANTED else f"(MISSED: the goal is {WINS_WANTED})"))  # fmt: skip
        else:
            gd = m["goal_difference"]
            even = gd["ci_low"] <= 0.0 <= gd["ci_high"]
            verdicts.append(f"{m['robot']} against itself: {'even (met)' if even else 'NOT even (MISSED)'}")
    met = all(v.endswith("(met)") for v in verdicts) if jobs else None  # the academy alone has no goal
    match_part = (
        "\n## One-a-side matches\n\n"
        f"{MATCHES} matches of {MATCH_SECONDS:g} s (a Four-Legged League half) on seeds 0-{MATCHES - 1}, home "
        "scripted; the home team's record.\n\n" + match_table + "\n" + "\n".join(f"- {v}" for v in verdicts) + "\n"
        if jobs
        else "\nThe matches were not run (``--academy-only``).\n"
    )
    md = (
        "# The scripted soccer team\n\n"
        f"## The academy in the commands mode\n\nSeeds {EPISODE_SEEDS[0]}-{EPISODE_SEEDS[-1]}, one scripted field "
        "player per episode (against the scripted keeper on ScoreVsKeeper).\n\n"
        + academy_table
        + match_part
        + f"\nWall time {wall:.0f} s.\n"
    )
    output.save({"academy": episodes, "matches": matches, "verdicts": verdicts, "met": met, "wall_seconds": wall}, md)


if __name__ == "__main__":
    main()
