"""Batched env speed: against raw ``mujoco.batch`` stepping of the same blocks, and against the single env.

For every registered id of a robot's own task (the soccer academy's are ``benchmarks.soccer_speed``'s), with N
simulations on T threads:

- **batched / raw**: the batched env (``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``)
  runs random actions while its control blocks are recorded; the same batch model then replays them raw, one native
  call per control step: ``Batch.step`` where a block's controls are constant (duty mode), ``Batch.rollout`` where
  they ramp within it (gait mode). Goal: >= 0.9, the 1 kHz duty ids included.
- **batched / single**: simulation steps per second of the batched env (2 threads) against one single Gymnasium env
  (which uses one core), and against two single envs in two processes (SB3's ``SubprocVecEnv``, both cores). Goal:
  1.6x in gait mode, 2.5x in duty mode, against the single env.

Rounds alternate and the best of each is kept (shared machines). Run: ``python -m benchmarks.batch_speed``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np

import envs  # noqa: F401
from benchmarks.common import add_output_options, md_table, resolve_output, robot_task_ids
from envs.common.batch import default_threads
from envs.common.io import ToolParser, at_least_one
from envs.common.simulation import CTRL_SPEC

GOAL_RAW = 0.9
GOAL_SINGLE = {"gait": 1.6, "duty": 2.5}


def random_actions(space: gym.Space, steps: int, n: int, gait: bool) -> np.ndarray:
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, n, space.shape[0])).astype(np.float32)
    if gait:
        actions[..., 1] = actions[..., 0]  # straight-ish gaits keep the robots running, as a policy would
    return actions


def time_batched(venv, actions: np.ndarray) -> float:
    """Simulation steps per second (control steps x simulations)."""
    venv.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        venv.step(a)
    return actions.shape[0] * actions.shape[1] / (time.perf_counter() - t0)


def record(venv, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The start state rows and every step's control blocks (the run must not reset: long episodes)."""
    sim = venv.unwrapped.robot.sim
    venv.reset(seed=0)
    start = sim.batch.state.copy()
    blocks = []
    for a in actions:
        _, _, terminated, truncated, _ = venv.step(a)
        blocks.append(sim.ctrl.copy())
        if (terminated | truncated).any():
            raise RuntimeError("a simulation ended its episode during the speed run: shorten it")
    return start, np.array(blocks)


def time_raw(venv, start: np.ndarray, blocks: np.ndarray) -> float:
    """The recorded blocks on the env's own batch, one native call per control step."""
    sim = venv.unwrapped.robot.sim
    b = sim.batch
    b.state[:] = start
    constant = bool((blocks == blocks[:, :, :1]).all())
    ctrl = b.bind("ctrl")
    nstep = blocks.shape[2]
    t0 = time.perf_counter()
    for block in blocks:
        if constant:
            ctrl[:] = block[:, 0]
            b.step(nstep=nstep)
        else:
            b.rollout(nstep, block, CTRL_SPEC, record=())
    return blocks.shape[0] * blocks.shape[1] / (time.perf_counter() - t0)


def time_single(env_id: str, actions: np.ndarray) -> float:
    env = gym.make(env_id, episode_seconds=None, max_tilt=np.pi, terminate_when_unhealthy=False)  # no time limit
    env.reset(seed=0)
    t0 = time.perf_counter()
    for a in actions:
        env.step(a)
    return len(actions) / (time.perf_counter() - t0)


def time_subproc(env_id: str, actions: np.ndarray) -> float:
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    vec = make_vec_env(
        env_id,
        n_envs=2,
        vec_env_cls=SubprocVecEnv,
        env_kwargs={"episode_seconds": None, "max_tilt": np.pi, "terminate_when_unhealthy": False},
    )
    vec.reset()
    t0 = time.perf_counter()
    for a in actions:
        vec.step(a[:2])
    rate = len(actions) * 2 / (time.perf_counter() - t0)
    vec.close()
    return rate


def measure(env_id: str, n: int, threads: int, steps: int, rounds: int, compare_single: bool) -> dict:
    # no episode ends during the run (max_tilt pi: a fallen robot runs on; the ground rules are computed but end
    # nothing), so the raw replay needs no resets
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", nthread=threads,
                        max_episode_steps=10**9, episode_seconds=None, max_tilt=np.pi,
                        terminate_when_unhealthy=False)  # fmt: skip
    gait = venv.unwrapped.robot.action_mode == "gait"
    actions = random_actions(venv.single_action_space, steps, n, gait)
    start, blocks = record(venv, actions)
    batched, raw, single, subproc = [], [], [], []
    for _ in range(rounds):
        batched.append(time_batched(venv, actions))
        raw.append(time_raw(venv, start, blocks))
        if compare_single:
            single.append(time_single(env_id, actions[: steps // 2, 0]))
            subproc.append(time_subproc(env_id, actions[: steps // 2]))
    row = {
        "env_id": env_id,
        "mode": "gait" if gait else "duty",
        "num_envs": n,
        "threads": threads,
        "batched_sim_steps_per_s": max(batched),
        "raw_sim_steps_per_s": max(raw),
        "ratio_raw": max(batched) / max(raw),
    }
    if compare_single:
        row.update(
            single_steps_per_s=max(single),
            subproc2_steps_per_s=max(subproc),
            speedup_vs_single=max(batched) / max(single),
            speedup_vs_subproc2=max(batched) / max(subproc),
        )
    return row


def verdict(row: dict) -> str:
    goal = GOAL_SINGLE[row["mode"]]
    return ("met" if row["speedup_vs_single"] >= goal else "MISSED") + f" (>= {goal})"


CONFIGURATIONS: dict[str, list[str]] = {"batch_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--num-envs", type=at_least_one, nargs="+", default=[4, 16, 64, 128])
    parser.add_argument("--steps", type=at_least_one, default=150, help="control steps per timing (duty ids: x10)")
    parser.add_argument("--rounds", type=at_least_one, default=3)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "batch_speed", CONFIGURATIONS)
    threads = default_threads()
    ids = robot_task_ids()
    rows = []
    for env_id in ids:
        steps = args.steps * (10 if "Duty" in env_id else 1)
        for n in args.num_envs:
            rows.append(measure(env_id, n, threads, steps, args.rounds, compare_single=n == max(args.num_envs)))
            print(rows[-1])
    table = md_table(
        ["env", "N", "threads", "batched sim-steps/s", "raw batch sim-steps/s", "batched / raw", "goal >= 0.9",
         "single env steps/s", "batched / single", "goal", "2 processes steps/s", "batched / 2 processes"],
        [
            [r["env_id"], r["num_envs"], r["threads"], round(r["batched_sim_steps_per_s"]),
             round(r["raw_sim_steps_per_s"]), round(r["ratio_raw"], 3),
             "met" if r["ratio_raw"] >= GOAL_RAW else "MISSED",
             round(r["single_steps_per_s"]) if "single_steps_per_s" in r else "",
             round(r["speedup_vs_single"], 2) if "speedup_vs_single" in r else "",
             verdict(r) if "speedup_vs_single" in r else "",
             round(r["subproc2_steps_per_s"]) if "subproc2_steps_per_s" in r else "",
             round(r["speedup_vs_subproc2"], 2) if "speedup_vs_subproc2" in r else ""]
            for r in rows
        ],
    )  # fmt: skip
    text = (
        "# Batched envs: against raw mujoco.batch stepping and against single envs\n\n"
        f"Machine: {threads} cores. Simulation steps per second (control steps x simulations). raw: the batched "
        "env's recorded control blocks replayed on its own batch, one native call per control step.\n\n" + table
    )
    output.save({"goals": {"raw": GOAL_RAW, "single": GOAL_SINGLE}, "rows": rows, "mujoco": mujoco.__version__},
         text)  # fmt: skip


if __name__ == "__main__":
    main()
