"""Bioloid: env speed against raw stepping, real-time factor on one core, and the wall time of one PSO run at the
seed's scale (50 particles x 240 iterations x 32 s = 107 h simulated).

- **env / raw**: the env (``gymnasium.make``, wrappers included) runs ``ik-trot`` while its control blocks are
  recorded; the same model then steps raw from the same start with those blocks, one native call per control step
  (``mj_step(model, data, nstep)``: a goal is held over a block). Rounds alternate; the ratio is the median of the
  rounds' (as ``benchmarks/env_speed.py`` measures the roach). The batched env of 50 is measured the same way against
  its own ``mujoco.batch``. Goal >= 0.9.
- **real-time factor**: simulated seconds per wall-clock second of the env with the ``ik-trot`` policy (a 10 s
  episode from seed 0, the policy's moves included), pinned to one core; beside it the same episode's physics raw
  (its control blocks replayed from its start, one native call per control step, checked to end where the env
  ended), the two alternating in rounds. The physics step is 2 ms. Goal >= 50x (the report's Webots: 1.5x).
- **PSO at the report's scale**: ``--pso-iterations`` iterations (default 4) of the report's PSO on experiment 5's
  coupling, 50 particles x 32 s, the swarm as one batch on both cores (agents.optimize's local backend: the CPG
  integrated for all particles at once, the robot's batched command and step); the measured time per iteration x
  240 is the run's wall time, extrapolated (stated as such). Goal: under 1 hour.

Run: ``python -m benchmarks.bioloid_speed`` (``--quick`` for fewer rounds).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np

import envs  # noqa: F401
from agents import load_policy
from agents.optimize.problem import read_config
from agents.optimize.run import LocalBackend, Settings, run
from benchmarks.batch_speed import time_raw as time_raw_batch
from benchmarks.common import add_output_options, md_table, resolve_output
from benchmarks.env_speed import alternate_with_replay, time_raw
from envs.common.io import ToolParser, at_least_one

WALK = "skitter/BioloidWalk-v2"
EPISODE = 500  # control steps: 10 s at 50 Hz
GOAL_RATIO, GOAL_RTF, GOAL_PSO_HOURS = 0.9, 50.0, 1.0
SEED_SCALE = {"particles": 50, "iterations": 240, "seconds": 32.0}
CONFIG = Path(__file__).resolve().parents[1] / "agents" / "bioloid" / "optimize" / "experiment5.json"


def trot_actions(env, steps: int) -> np.ndarray:
    policy = load_policy("ik-trot", env)
    obs, _ = env.reset(seed=0)
    actions, state, start = [], None, np.array([True])
    for _ in range(steps):
        action, state = policy.predict(obs, state, start)
        start = np.array([False])
        actions.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset(seed=0)
            start = np.array([True])
    return np.array(actions)


def single_ratio(rounds: int) -> dict:
    env = gym.make(WALK)
    base = env.unwrapped
    actions = trot_actions(env, EPISODE)
    env.reset(seed=0)
    start = mujoco.MjData(base.model)
    mujoco.mj_copyData(start, base.model, base.data)
    blocks, resets, reset = [], [], False
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        blocks.append(base.robot.sim.ctrl[0].copy())
        resets.append(reset)
        final = base.data.qpos.copy()
        reset = terminated or truncated
        if reset:
            env.reset(seed=0)
    blocks, resets = np.array(blocks), np.array(resets)
    env_rates, raw_rates = [], []
    for _ in range(rounds):
        env.reset(seed=0)
        t0 = time.perf_counter()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset(seed=0)
        env_rates.append(len(actions) / (time.perf_counter() - t0))
        rate, raw_final = time_raw(base.model, start, blocks, resets)
        raw_rates.append(rate)
    return {"env_id": WALK, "num_envs": 1, "substeps": base.robot.n_substeps, "env_steps_per_s": max(env_rates),
            "raw_steps_per_s": max(raw_rates), "ratio": float(np.median(np.array(env_rates) / np.array(raw_rates))),
            "same_trajectory": bool(np.array_equal(final, raw_final))}  # fmt: skip


def batched_ratio(n: int, threads: int, rounds: int) -> dict:
    venv = gym.make_vec(WALK, num_envs=n, vectorization_mode="vector_entry_point", nthread=threads,
                        max_episode_steps=10**9, episode_seconds=None, max_tilt=np.pi,
                        terminate_when_unhealthy=False)  # fmt: skip
    single = gym.make(WALK)
    actions = np.repeat(trot_actions(single, EPISODE // 2)[:, None, :], n, axis=1)
    sim = venv.unwrapped.robot.sim
    venv.reset(seed=0)
    start = sim.batch.state.copy()
    blocks = []
    for a in actions:
        venv.step(a)
        blocks.append(sim.ctrl.copy())
    blocks = np.array(blocks)
    env_rates, raw_rates = [], []
    for _ in range(rounds):
        venv.reset(seed=0)
        t0 = time.perf_counter()
        for a in actions:
            venv.step(a)
        env_rates.append(actions.shape[0] * n / (time.perf_counter() - t0))
        raw_rates.append(time_raw_batch(venv, start, blocks))
    return {"env_id": WALK, "num_envs": n, "threads": threads, "substeps": venv.unwrapped.robot.n_substeps,
            "env_steps_per_s": max(env_rates), "raw_steps_per_s": max(raw_rates),
            "ratio": float(np.median(np.array(env_rates) / np.array(raw_rates)))}  # fmt: skip


def real_time_factor(rounds: int) -> dict:
    """On one core: the env and the ik-trot policy for a 10 s episode from seed 0, and the same episode's physics
    raw (its control blocks, replayed from the same start with one native call per control step, checked to end where
    the env ended), alternating in ``rounds`` rounds; the env's share of the raw speed is the median round's."""
    env = gym.make(WALK)
    policy = load_policy("ik-trot", env)
    base = env.unwrapped
    run = alternate_with_replay(env, policy, rounds)
    env_rtfs = run["env_rtfs"]
    return {"physics_dt": float(base.model.opt.timestep), "rtf_best": max(env_rtfs),
            "rtf_mean": float(np.mean(env_rtfs)), "rtf_raw_physics": max(run["raw_rtfs"]), "share": run["share"],
            "replay_matches": run["same"]}  # fmt: skip


def pso_fraction(iterations: int, threads: int) -> dict:
    """``iterations`` of the seed-scale PSO on both cores; per-iteration wall time, extrapolated to 240."""
    config = read_config(CONFIG)
    settings = Settings(config.to_dict(), "pso", SEED_SCALE["iterations"], SEED_SCALE["particles"], 0)
    backend = LocalBackend(config, SEED_SCALE["particles"], threads)
    times = []
    with tempfile.TemporaryDirectory() as out:
        state_backend = _Timed(backend, times)
        run(config, settings, Path(out), lambda: state_backend, progress=False, stop_after=iterations)
    per_iteration = float(np.median(times))
    simulated = SEED_SCALE["particles"] * SEED_SCALE["seconds"]
    return {"iterations_measured": iterations, "threads": threads, "seconds_per_iteration": times,
            "median_seconds_per_iteration": per_iteration, "simulated_per_iteration_s": simulated,
            "rtf_machine": simulated / per_iteration, "rtf_per_core": simulated / per_iteration / threads,
            "extrapolated_run_hours": per_iteration * SEED_SCALE["iterations"] / 3600.0}  # fmt: skip


class _Timed:
    """A backend that records the wall time of each evaluation (the swarm's rollouts)."""

    def __init__(self, backend, times: list[float]):
        self.backend, self.times = backend, times
        self.dimension, self.controller = backend.dimension, backend.controller

    def evaluate(self, parameters, draw: tuple[int, ...] = ()):
        t0 = time.perf_counter()
        out = self.backend.evaluate(parameters, draw)
        self.times.append(time.perf_counter() - t0)
        return out

    def close(self) -> None:
        self.backend.close()


CONFIGURATIONS: dict[str, list[str]] = {"bioloid_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer rounds and PSO iterations")
    parser.add_argument("--pso-iterations", type=at_least_one, default=None, help="seed-scale PSO iterations to time")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_speed", CONFIGURATIONS)
    rounds, episodes = (3, 2) if args.quick else (7, 3)
    pso_iterations = args.pso_iterations or (2 if args.quick else 4)
    ratios = [single_ratio(rounds), batched_ratio(50, 2, rounds), batched_ratio(100, 2, rounds)]
    for r in ratios:
        print(r)
    pso = pso_fraction(pso_iterations, 2)
    print(pso)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core from here on
    # the "on one core": the batched env with one rollout thread against raw mujoco.batch with one
    one_core = [batched_ratio(n, 1, rounds) | {"one_core": True} for n in (16, 50, 100)]
    for r in one_core:
        print(r)
    ratios += one_core
    rtf = real_time_factor(episodes)
    print(rtf)
    ratio_table = md_table(
        ["env", "N", "threads", "physics steps per step", "env steps/s", "raw steps/s", "env / raw", "goal >= 0.9"],
        [[r["env_id"], r["num_envs"], f"{r.get('threads', 1)}" + (" (pinned to one core)" if r.get("one_core") else ""),
          r["substeps"], round(r["env_steps_per_s"]), round(r["raw_steps_per_s"]), round(r["ratio"], 3),
          "met" if r["ratio"] >= GOAL_RATIO else "MISSED"] for r in ratios],
    )  # fmt: skip
    rtf_table = md_table(
        ["what", "physics step", "real-time factor, best", "mean", "goal >= 50x"],
        [["env + ik-trot, one core", "2 ms", round(rtf["rtf_best"], 1), round(rtf["rtf_mean"], 1),
          "met" if rtf["rtf_best"] >= GOAL_RTF else "MISSED"],
         ["the same episode's physics raw, one core", "2 ms", round(rtf["rtf_raw_physics"], 1), "", ""],
         ["[bioloid-webots] Webots", "", 1.5, "", ""]],
    )  # fmt: skip
    hours = pso["extrapolated_run_hours"]
    verdict = "met" if hours < GOAL_PSO_HOURS else "MISSED"
    pso_table = md_table(
        ["PSO, 50 particles x 32 s per iteration, both cores", "value"],
        [["iterations timed", pso_iterations],
         ["wall time per iteration, median", f"{pso['median_seconds_per_iteration']:.1f} s"],
         ["real-time factor of the whole path (CPG, robot, physics)", f"{pso['rtf_machine']:.0f}x on 2 cores, "
                                                                      f"{pso['rtf_per_core']:.0f}x per core"],
         ["240 iterations (107 h simulated), extrapolated", f"{hours * 60:.0f} min ({verdict}: goal < 60 min)"],
         ["the report: 50 computers at 1.5x", "about 2 h"]],
    )  # fmt: skip
    md = (
        "# Bioloid: env speed, real-time factor, seed-scale PSO\n\n"
        + ratio_table
        + "\n"
        + rtf_table
        + f"\nThe env's share of the raw speed in that episode: {rtf['share']:.3f} (median of {episodes} alternating "
        f"rounds; the replay {'ends' if rtf['replay_matches'] else 'DID NOT end'} where the env ended).\n\n" + pso_table
    )
    output.save({"ratios": ratios, "real_time_factor": rtf, "pso": pso}, md)


if __name__ == "__main__":
    main()
