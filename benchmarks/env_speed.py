"""Env steps per second against the same physics stepped raw with ``mujoco.mj_step``, in one run.

For every registered env: the env (made with ``gymnasium.make``, wrappers included) runs N control steps with
random actions while the controls it writes are recorded; then the same model steps raw from the same start, with
those controls, ``mj_step(model, data, nstep=substeps)`` per control step. The ratio env/raw is the cost of
everything we add in Python (actions, firmware, observation, reward, telemetry hooks, wrappers). Rounds alternate
env and raw and the best of each is kept, since these machines are shared. Gymnasium's Ant-v5 is measured the same
way for comparison. Goal: ratio >= 0.9 (Ant-v5 reaches about 0.75 on these machines).

Run: ``python -m benchmarks.env_speed``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np

import envs  # noqa: F401
from benchmarks.common import md_table, save
from envs.velociroach.robot import DC_DYN_SLEW

GOAL = 0.9


def time_env(env, actions: np.ndarray) -> float:
    env.reset(seed=0)
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return len(actions) / (time.perf_counter() - start)


def record_controls(env, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The controls and firmware slew limits the env writes at each step, where it reset, and its final qpos."""
    robot = env.unwrapped.robot
    env.reset(seed=0)
    ctrls, slews, resets = [], [], []
    reset = False
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        ctrls.append(robot.data.ctrl.copy())
        slews.append(robot.model.actuator_dynprm[:, DC_DYN_SLEW].copy())
        resets.append(reset)
        final = robot.data.qpos.copy()
        reset = terminated or truncated
        if reset:
            env.reset(seed=0)
    return np.array(ctrls), np.array(slews), np.array(resets), final


def time_raw(model, start: mujoco.MjData, ctrls, nstep: int, slews=None, resets=None) -> tuple[float, np.ndarray]:
    """Raw physics: the recorded controls (and slew limits), stepped natively; no Python per physics step."""
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, start)
    dynprm = model.actuator_dynprm
    t0 = time.perf_counter()
    for i, c in enumerate(ctrls):
        if resets is not None and resets[i]:
            mujoco.mj_copyData(data, model, start)
        data.ctrl[:] = c
        if slews is not None:
            dynprm[:, DC_DYN_SLEW] = slews[i]
        mujoco.mj_step(model, data, nstep=nstep)
    return len(ctrls) / (time.perf_counter() - t0), data.qpos.copy()


def measure_skitter(env_id: str, steps: int, rounds: int) -> dict:
    env = gym.make(env_id)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, *env.action_space.shape)).astype(np.float32)
    # straight-ish random actions keep the robot running rather than tumbling, like a policy would
    if env.unwrapped.action_mode == "gait":
        actions[:, 1] = actions[:, 0]
    robot = env.unwrapped.robot
    env.reset(seed=0)
    start = mujoco.MjData(robot.model)
    mujoco.mj_copyData(start, robot.model, robot.data)
    ctrls, slews, resets, final = record_controls(env, actions)
    env_sps, raw_sps = [], []
    for _ in range(rounds):
        env_sps.append(time_env(env, actions))
        sps, raw_final = time_raw(robot.model, start, ctrls, robot.n_substeps, slews, resets)
        raw_sps.append(sps)
    # the raw loop must have simulated exactly what the env did, or the comparison means nothing
    identical = bool(np.array_equal(final, raw_final))
    best_env, best_raw = max(env_sps), max(raw_sps)
    return {
        "same_trajectory": identical,
        "env_id": env_id,
        "substeps": robot.n_substeps,
        "env_steps_per_s": best_env,
        "raw_steps_per_s": best_raw,
        "ratio": best_env / best_raw,
        "physics_steps_per_s_raw": best_raw * robot.n_substeps,
    }


def measure_ant(steps: int, rounds: int) -> dict | None:
    try:
        env = gym.make("Ant-v5")
    except Exception as exc:  # gymnasium's MuJoCo envs may be unavailable; say so, do not fail the benchmark
        print(f"Ant-v5 not measured: {exc}")
        return None
    u = env.unwrapped
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, *env.action_space.shape)).astype(np.float32)
    env.reset(seed=0)
    start = mujoco.MjData(u.model)
    mujoco.mj_copyData(start, u.model, u.data)
    env_sps, raw_sps = [], []
    for _ in range(rounds):
        env_sps.append(time_env(env, actions))
        raw_sps.append(time_raw(u.model, start, actions, u.frame_skip)[0])
    return {
        "env_id": "Ant-v5 (Gymnasium)",
        "substeps": u.frame_skip,
        "env_steps_per_s": max(env_sps),
        "raw_steps_per_s": max(raw_sps),
        "ratio": max(env_sps) / max(raw_sps),
        "physics_steps_per_s_raw": max(raw_sps) * u.frame_skip,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="control steps per timing (duty envs: x10)")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    ids = sorted(k for k in gym.registry if k.startswith("skitter/"))
    rows = []
    for env_id in ids:
        steps = args.steps * (10 if "Duty" in env_id else 1)
        rows.append(measure_skitter(env_id, steps, args.rounds))
        print(rows[-1])
    ant = measure_ant(args.steps, args.rounds)
    if ant:
        rows.append(ant)
    table = md_table(
        ["env", "physics steps per step", "env steps/s", "raw mj_step steps/s", "ratio", "goal >= 0.9", "same run?"],
        [
            [
                r["env_id"],
                r["substeps"],
                round(r["env_steps_per_s"]),
                round(r["raw_steps_per_s"]),
                round(r["ratio"], 3),
                "met" if r["ratio"] >= GOAL else "MISSED",
                {True: "identical", False: "DIFFERENT"}.get(r.get("same_trajectory"), "n/a"),
            ]
            for r in rows
        ],
    )
    text = (
        "# Env speed against raw mj_step (same model, same run)\n\n"
        "'same run?': whether the raw loop, replaying the env's controls, ended in exactly the env's state.\n\n" + table
    )
    save("env_speed", {"goal": GOAL, "rows": rows}, text)


if __name__ == "__main__":
    main()
