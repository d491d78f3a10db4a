"""xJüs: env speed against raw stepping, real-time factor on one core, and speed and cost of transport on flat ground.

- **env / raw**: the env (``gymnasium.make``, wrappers included) runs the ``buehler`` walk while its control blocks
  are recorded; the same model then steps raw from the same start with those blocks, one native call per control step
  (``mj_step(model, data, nstep)``: the duty is held over a block). Rounds alternate, the ratio is the median of the
  rounds' (as ``benchmarks/env_speed.py`` measures the roach). The batched env is measured the same way against its
  own ``mujoco.batch`` replaying the blocks (as ``benchmarks/batch_speed.py``). Goal: >= 0.9.
- **real-time factor**: simulated seconds per wall-clock second of the env with the ``buehler`` policy, 10 s
  episodes, pinned to one core; the physics step is 2 ms (the report's Blender model used 1.7 ms and ran at 1x). Goal:
  >= 20x.
- **flat ground**: forward speed and cost of transport of the Buehler-clock tripod (60 deg sweep) at several periods,
  10 s episodes over seeded starts, 95% bootstrap intervals, beside Research RHex's 0.55 m/s (7 kg, 0.53 m). The cost
  of transport is battery energy / (m g distance); the report's motor constants cap the motor's efficiency at
  eta N Kt / Ks = 0.37, so it is at least 1/0.37 = 2.7 times the mechanical one.
- **stability**: the stiffest and softest spine offered and a rigid one walk 10 s over 0.05 m RMS ground at the 2 ms
  step; any numerically unstable episode is counted.

Run: ``python -m benchmarks.xjus_speed`` (``--quick`` for fewer rounds and seeds).
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
from agents.evaluation import bootstrap_ci, run_episodes
from benchmarks.batch_speed import time_raw as time_raw_batch
from benchmarks.common import add_output_options, md_table, resolve_output
from benchmarks.env_speed import time_raw
from envs.common.io import ToolParser
from envs.xjus import constants

GOAL_RATIO = 0.9
GOAL_RTF = 20.0
WALK = "skitter/XjusWalk-v1"
ROUGH = "skitter/XjusRough-v1"
EPISODE = 1250  # control steps: 10 s at 125 Hz


def walk_actions(env, steps: int, seed: int = 0) -> np.ndarray:
    """The buehler policy's actions over ``steps`` control steps of ``env`` from ``reset(seed)``."""
    policy = load_policy("buehler", env)
    obs, _ = env.reset(seed=seed)
    actions, state, start = [], None, np.array([True])
    for _ in range(steps):
        action, state = policy.predict(obs, state, start)
        start = np.array([False])
        actions.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            obs, _ = env.reset(seed=seed)
            start = np.array([True])
    return np.array(actions)


def single_ratio(env_id: str, rounds: int, **kwargs) -> dict:
    env = gym.make(env_id, **kwargs)
    base = env.unwrapped
    actions = walk_actions(env, EPISODE)
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
    env_rates, raw_rates, call_rates = [], [], []
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
        call_rates.append(_native_call_rate(env, blocks, resets))
    ratios = np.array(env_rates) / np.array(raw_rates)
    return {
        "env_id": env_id,
        "kwargs": kwargs,
        "num_envs": 1,
        "substeps": base.robot.n_substeps,
        "env_steps_per_s": max(env_rates),
        "raw_steps_per_s": max(raw_rates),
        "ratio": float(np.median(ratios)),
        "native_call_ratio": float(np.median(np.array(call_rates) / np.array(raw_rates))),
        "same_trajectory": bool(np.array_equal(final, raw_final)),
    }


def _native_call_rate(env, blocks: np.ndarray, resets: np.ndarray) -> float:
    """Control steps per second of the env's simulation alone replaying ``blocks``: the one native
    ``mujoco.rollout`` call per step (which records every physics step's sensors), without the env's Python."""
    sim = env.unwrapped.robot.sim
    env.reset(seed=0)
    spent = 0.0
    for block, reset in zip(blocks, resets, strict=True):
        if reset:
            env.reset(seed=0)
        sim.ctrl[0] = block
        t0 = time.perf_counter()
        sim.step()
        spent += time.perf_counter() - t0
    return len(blocks) / spent


def batched_ratio(env_id: str, n: int, threads: int, rounds: int, **kwargs) -> dict:
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", nthread=threads,
                        max_episode_steps=10**9, episode_seconds=None, max_tilt=np.pi,
                        terminate_when_unhealthy=False, **kwargs)  # fmt: skip
    single = gym.make(env_id, **kwargs)
    action = walk_actions(single, 1)[0]  # the walk's gait-mode action is constant
    actions = np.broadcast_to(action, (EPISODE // 2, n, action.shape[0])).copy()
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
    return {
        "env_id": env_id,
        "kwargs": kwargs,
        "num_envs": n,
        "threads": threads,
        "substeps": venv.unwrapped.robot.n_substeps,
        "env_steps_per_s": max(env_rates),
        "raw_steps_per_s": max(raw_rates),
        "ratio": float(np.median(np.array(env_rates) / np.array(raw_rates))),
    }


def real_time_factor(env_id: str, episodes: int, **kwargs) -> dict:
    """On one core: the env and the buehler policy, and raw mj_step on the same model."""
    env = gym.make(env_id, **kwargs)
    policy = load_policy("buehler", env)
    rtfs = []
    for seed in range(episodes):
        obs, _ = env.reset(seed=seed)
        t0 = time.perf_counter()
        while True:
            obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
            if terminated or truncated:
                break
        rtfs.append(info["time"] / (time.perf_counter() - t0))
    robot = env.unwrapped.robot
    data = mujoco.MjData(robot.model)
    mujoco.mj_copyData(data, robot.model, robot.data)
    data.ctrl[:] = robot.sim.ctrl[0, 0]
    t0 = time.perf_counter()
    mujoco.mj_step(robot.model, data, nstep=5000)
    raw = 5000 * robot.model.opt.timestep / (time.perf_counter() - t0)
    return {"env_id": env_id, "kwargs": kwargs, "physics_dt": float(robot.model.opt.timestep),
            "rtf_best": max(rtfs), "rtf_mean": float(np.mean(rtfs)), "rtf_raw_physics": raw}  # fmt: skip


def flat_ground(period: float, seeds: list[int], threads: int, **kwargs) -> dict:
    venv = gym.make_vec(WALK, num_envs=len(seeds), vectorization_mode="vector_entry_point", nthread=threads,
                        max_episode_steps=EPISODE, **kwargs)  # fmt: skip
    episodes = run_episodes(venv, load_policy(f"buehler:{period}", venv), seeds)
    row: dict = {"period": period, "kwargs": kwargs, "episodes": len(seeds)}
    for metric in ("forward_speed", "cost_of_transport", "heading_drift", "falls"):
        values = np.array([e.metrics[metric] for e in episodes])
        low, high = bootstrap_ci(values)
        row[metric] = {"mean": float(np.mean(values)), "ci_low": low, "ci_high": high, "values": values.tolist()}
    energy = [e.metrics["cost_of_transport"] * constants.MASS * 9.81 * e.metrics["speed"] for e in episodes]
    row["mean_power_w"] = float(np.mean(energy))
    return row


def turning(seeds: list[int], threads: int) -> dict:
    """Yaw rate against the sweep difference (right minus left, around 60 deg) at T = 0.5 s, and the turn routine's
    tracking of commanded yaw rates (XjusTurn-v2, 10 s episodes)."""
    differences = np.radians([-60.0, -30.0, 0.0, 30.0, 60.0])
    open_loop = []
    for diff in differences:
        venv = gym.make_vec(WALK, num_envs=len(seeds), vectorization_mode="vector_entry_point", nthread=threads,
                            max_episode_steps=EPISODE)  # fmt: skip
        command = np.array([0.5, constants.WALK_SWEEP - diff / 2, constants.WALK_SWEEP + diff / 2])
        action = np.tile(venv.unwrapped.robot.mode.to_action(command), (len(seeds), 1))
        venv.reset(seed=seeds)
        for _ in range(EPISODE):
            *_, info = venv.step(action)
        rates = (info["yaw_travel"] - info["yaw_travel_warmup"]) / (info["elapsed"] - 1.0)
        open_loop.append({"difference_deg": float(np.degrees(diff)), "yaw_rate": rates.tolist()})
    tracking = []
    for command in (-0.4, -0.2, 0.2, 0.4):
        env = gym.make("skitter/XjusTurn-v2")
        policy = load_policy("buehler", env)
        errors = []
        for seed in seeds:
            obs, _ = env.reset(seed=seed, options={"yaw_rate": command})
            for _ in range(EPISODE):
                obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
                if terminated or truncated:
                    break
            errors.append(env.unwrapped.task.episode_metrics(info)["yaw_rate_error"])
        tracking.append({"command": command, "yaw_rate_error": errors})
    return {"open_loop": open_loop, "tracking": tracking}


def stability(seconds_episodes: int, threads: int) -> list[dict]:
    rows = []
    low, high = (scale * constants.SPINE_DESIGN_STIFFNESS for scale in constants.SPINE_STIFFNESS_RANGE)
    for spine, stiffness in (("compliant", low), ("compliant", high), ("rigid", None)):
        kwargs = {"spine": spine, "roughness": 0.05}
        if stiffness is not None:
            kwargs["spine_stiffness"] = stiffness
        venv = gym.make_vec(ROUGH, num_envs=seconds_episodes, vectorization_mode="vector_entry_point",
                            nthread=threads, max_episode_steps=EPISODE, **kwargs)  # fmt: skip
        episodes = run_episodes(venv, load_policy("buehler", venv), list(range(seconds_episodes)))
        unstable = sum(e.unstable for e in episodes)
        falls = sum(e.metrics["falls"] for e in episodes)
        rows.append({"spine": spine, "stiffness": stiffness, "episodes": len(episodes), "unstable": unstable,
                     "falls": falls})  # fmt: skip
    return rows


def fmt_ci(stat: dict, digits: int = 2) -> str:
    return f"{stat['mean']:.{digits}f} [{stat['ci_low']:.{digits}f}, {stat['ci_high']:.{digits}f}]"


CONFIGURATIONS: dict[str, list[str]] = {"xjus_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer rounds, seeds and episodes")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "xjus_speed", CONFIGURATIONS)
    rounds, seeds, rtf_episodes = (3, list(range(6)), 2) if args.quick else (7, list(range(12)), 3)
    started = time.perf_counter()
    ratios = [single_ratio(WALK, rounds), single_ratio(ROUGH, rounds, roughness=0.04)]
    ratios += [batched_ratio(WALK, n, 2, rounds) for n in (16, 64, 128, 256, 512)]
    for r in ratios:
        print(r)
    flat = [flat_ground(p, seeds, 2) for p in (0.5, 0.75, 1.0)]
    flat += [flat_ground(p, seeds, 2, current_limit=constants.MOTOR_CONTINUOUS_CURRENT) for p in (0.5, 1.0)]
    stable = stability(4 if args.quick else 8, 2)
    turn = turning(seeds[:3], 2)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # one core from here on
    # the "on one core": the batched env with one rollout thread against raw mujoco.batch with one
    one_core = [batched_ratio(WALK, n, 1, rounds) | {"one_core": True} for n in (16, 64, 128, 512)]
    for r in one_core:
        print(r)
    ratios += one_core
    rtf = [real_time_factor(WALK, rtf_episodes), real_time_factor(ROUGH, rtf_episodes, roughness=0.04)]
    ratio_table = md_table(
        ["env", "N", "threads", "physics steps per step", "env steps/s", "raw steps/s", "env / raw", "goal >= 0.9"],
        [[r["env_id"] + (" (0.04 m RMS)" if r["kwargs"] else ""), r["num_envs"],
          f"{r.get('threads', 1)}" + (" (pinned to one core)" if r.get("one_core") else ""), r["substeps"],
          round(r["env_steps_per_s"]), round(r["raw_steps_per_s"]), round(r["ratio"], 3),
          "met" if r["ratio"] >= GOAL_RATIO else "MISSED"] for r in ratios],
    )  # fmt: skip
    rtf_table = md_table(
        ["env", "physics step", "env + buehler, best", "mean", "raw mj_step", "goal >= 20x"],
        [[r["env_id"] + (" (0.04 m RMS)" if r["kwargs"] else ""), f"{r['physics_dt'] * 1e3:g} ms",
          round(r["rtf_best"], 1), round(r["rtf_mean"], 1), round(r["rtf_raw_physics"], 1),
          "met" if r["rtf_best"] >= GOAL_RTF else "MISSED"] for r in rtf]
        + [["[xjus-report] Blender model", "1.7 ms", 1.0, "", "", ""]],
    )  # fmt: skip
    flat_table = md_table(
        ["clock period T", "current limit", "forward speed, m/s [95% CI]", "cost of transport [95% CI]",
         "mean battery power, W", "heading drift, rad/s [95% CI]", "falls"],
        [[f"{r['period']:g} s", f"{r['kwargs']['current_limit']:g} A" if r["kwargs"] else "none",
          fmt_ci(r["forward_speed"]), fmt_ci(r["cost_of_transport"]), round(r["mean_power_w"], 1),
          fmt_ci(r["heading_drift"], 3), f"{sum(r['falls']['values']):g}/{r['episodes']}"] for r in flat]
        + [["Research RHex (7 kg, 0.53 m)", "", "0.55", "", "", "", ""]],
    )  # fmt: skip
    stable_table = md_table(
        ["spine", "stiffness, N m/rad", "episodes (10 s, 0.05 m RMS)", "numerically unstable", "flipped"],
        [[r["spine"], "" if r["stiffness"] is None else round(r["stiffness"], 1), r["episodes"], r["unstable"],
          r["falls"]] for r in stable],
    )  # fmt: skip
    turn_table = md_table(
        ["right minus left sweep", "yaw rate, rad/s (mean over seeds)", "per seed"],
        [[f"{r['difference_deg']:+.0f} deg", round(float(np.mean(r["yaw_rate"])), 3),
          ", ".join(f"{v:.3f}" for v in r["yaw_rate"])] for r in turn["open_loop"]],
    ) + "\n" + md_table(
        ["commanded yaw rate, rad/s", "turn routine's error, abs(mean rate - command), rad/s, per seed"],
        [[r["command"], ", ".join(f"{v:.3f}" for v in r["yaw_rate_error"])] for r in turn["tracking"]],
    )  # fmt: skip
    text = (
        "# xJüs speed: env against raw, real time, flat-ground speed and cost of transport\n\n"
        f"Machine: {os.cpu_count()} cores, shared. Gait mode, control at 125 Hz (8 ms, 4 physics steps of 2 ms).\n\n"
        "## Env against raw stepping of the same control blocks\n\n"
        + ratio_table
        + "\nThe single env's ceiling: its simulation alone (the one native `mujoco.rollout` call a step, which "
        "records every physics step's sensors, and no Python) against the same raw stepping: "
        + ", ".join(
            f"{r['native_call_ratio']:.3f} ({r['env_id'].split('/')[1]})" for r in ratios if "native_call_ratio" in r
        )
        + ". The env's Python comes on top of that.\n"
        + "\n## Real-time factor, one core\n\n"
        + rtf_table
        + "\n## Flat ground, Buehler-clock tripod (60 deg sweep), 10 s episodes\n\n"
        "Cost of transport = battery energy / (m g distance). The report's motor constants cap the motor's efficiency "
        "at eta N Kt / Ks = 0.37: every cost of transport here is at least 2.7 times the mechanical one.\n\n"
        + flat_table
        + "\n## Turning by a different sweep per side (T = 0.5 s, sweeps centred on 60 deg)\n\n"
        + turn_table
        + "\n## Stability at the 2 ms physics step\n\n"
        + stable_table
        + f"\nWall time of this benchmark: {time.perf_counter() - started:.0f} s.\n"
    )
    output.save({"goal_ratio": GOAL_RATIO, "goal_rtf": GOAL_RTF, "ratios": ratios, "rtf": rtf,
                        "flat": flat, "stability": stable, "turning": turn, "quick": args.quick}, text)  # fmt: skip


if __name__ == "__main__":
    main()
