"""Real-time factor of RoachWalk under the tripod gait at a 45 Hz stride, on one core.

The env (gait mode, 50 Hz control, 2 kHz physics) runs the scripted tripod for a 10 s episode; the real-time factor
is simulated seconds per wall-clock second. Goal: at least 10x. The seed's V-REP model ran at 0.1x real time and
failed above 5 Hz [roach-sim]. The raw physics rate (``mj_step``) is measured on the same model for reference.

Run: ``python -m benchmarks.realtime``.
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import mujoco
import numpy as np

import envs  # noqa: F401
from agents import load_policy
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser

GOAL = 10.0


CONFIGURATIONS: dict[str, list[str]] = {"realtime": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--episodes", type=int, default=3)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "realtime", CONFIGURATIONS)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core
    env = gym.make("skitter/RoachWalk-v4")
    policy = load_policy("tripod:45", env)
    rtfs, speeds = [], []
    for seed in range(args.episodes):
        obs, info = env.reset(seed=seed)
        start = time.perf_counter()
        while True:
            obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
            if terminated or truncated:
                break
        rtfs.append(info["time"] / (time.perf_counter() - start))
        speeds.append(info["x_position"] / info["time"])
    robot = env.unwrapped.robot
    data = mujoco.MjData(robot.model)
    mujoco.mj_copyData(data, robot.model, robot.data)
    start = time.perf_counter()
    mujoco.mj_step(robot.model, data, nstep=10000)
    raw = 10000 * robot.model.opt.timestep / (time.perf_counter() - start)
    best = max(rtfs)
    rows = [
        ["env + tripod, best of episodes", round(best, 1), "met" if best >= GOAL else "MISSED"],
        ["env + tripod, mean", round(float(np.mean(rtfs)), 1), ""],
        ["raw mj_step, same model", round(raw, 1), ""],
        ["[roach-sim] V-REP model", 0.1, ""],
    ]
    text = (
        "# Real-time factor, RoachWalk-v4, tripod at 45 Hz, one core\n\n"
        + md_table(["what", "real-time factor (x)", "goal >= 10x"], rows)
        + f"\nMean forward speed in these episodes: {np.mean(speeds):.2f} m/s.\n"
    )
    output.save({"goal": GOAL, "rtf_episodes": rtfs, "rtf_raw_physics": raw, "speeds": speeds}, text)


if __name__ == "__main__":
    main()
