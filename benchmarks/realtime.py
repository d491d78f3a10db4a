"""Real-time factor of RoachWalk under the tripod gait at a 45 Hz stride, on one core.

The env (gait mode, 50 Hz control, 2 kHz physics) runs the scripted tripod for a 10 s episode from seed 0; the
real-time factor is simulated seconds per wall-clock second, the tripod's own moves included. Goal: at least 10x.
The report's V-REP model ran at 0.1x real time and failed above 5 Hz [roach-sim]. Beside it, the same episode's
physics stepped raw: the control blocks and motor gains the env gave the physics, replayed on the same model from
the same start, one native call per control step (``benchmarks.env_speed.time_raw``; checked to end where the env
ended). The host's speed drifts, so the episode and its replay alternate in ``--rounds`` rounds; the env's share
of the raw speed is the median round's, the real-time factors the best rounds'.

Run: ``python -m benchmarks.realtime``.
"""

from __future__ import annotations

import argparse
import os

import gymnasium as gym
import numpy as np

import envs  # noqa: F401
from agents import load_policy
from benchmarks.common import add_output_options, md_table, resolve_output
from benchmarks.env_speed import alternate_with_replay
from envs.common.io import ToolParser, at_least_one

GOAL = 10.0
ENV_ID = "skitter/RoachWalk-v4"


CONFIGURATIONS: dict[str, list[str]] = {"realtime": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--rounds", type=at_least_one, default=3, help="rounds of the episode and its replay, in turn")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "realtime", CONFIGURATIONS)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    env = gym.make(ENV_ID)
    policy = load_policy("tripod:45", env)
    run = alternate_with_replay(env, policy, args.rounds)
    recorded, env_rtfs, raw_rtfs, same = run["recorded"], run["env_rtfs"], run["raw_rtfs"], run["same"]
    best = max(env_rtfs)
    rows = [
        ["env + tripod, best round", round(best, 1), "met" if best >= GOAL else "MISSED"],
        ["env + tripod, median round", round(float(np.median(env_rtfs)), 1), ""],
        ["the same physics raw, best round", round(max(raw_rtfs), 1), ""],
        ["[roach-sim] V-REP model", 0.1, ""],
    ]
    text = (
        f"# Real-time factor, {ENV_ID}, tripod at 45 Hz, one core\n\n"
        + md_table(["what", "real-time factor (x)", f"goal >= {GOAL:g}x"], rows)
        + f"\nThe env's share of the raw speed: {run['share']:.3f} (median of {args.rounds} alternating rounds; "
        f"the replay {'ends where the env ended' if same else 'DID NOT end where the env ended'}). Forward speed in "
        f"the episode: {recorded['speed']:.2f} m/s.\n"
    )
    output.save({"goal": GOAL, "rtf_rounds": env_rtfs, "rtf_raw_rounds": raw_rtfs, "share": run["share"],
                 "replay_matches": same, "speed": float(recorded["speed"])}, text)  # fmt: skip


if __name__ == "__main__":
    main()
