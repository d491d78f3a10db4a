"""Env steps per second against the same physics stepped raw, in one run.

For every registered walking, turning and rough-ground env (the soccer academy's are
``benchmarks.soccer_speed``'s): the env (made with ``gymnasium.make``, wrappers included) runs N control steps with
random actions while the control blocks it gives the physics are recorded; then the same model steps raw from the
same start with those controls, one native call per control step: ``mj_step(model, data, nstep)`` where the block's
controls are constant (duty mode), ``mujoco.rollout`` of the block where they change within it (gait mode: the
firmware's clock ramps). The ratio env/raw is the cost of everything we add in Python (actions, firmware, sensors,
observation, reward, info, wrappers). The whole recorded run in one ``mujoco.rollout`` call (no Python between
control steps at all) is reported beside it. These machines are shared and their speed drifts, so the env and the
raw loop alternate in short rounds and the ratio is the median of the rounds' ratios (the rates shown are the best
rounds'). Gymnasium's Ant-v5 is measured the same way for comparison. Goal: ratio >= 0.9.

Run: ``python -m benchmarks.env_speed``.
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import mujoco
import numpy as np
from mujoco import rollout

import envs  # noqa: F401
from benchmarks.common import add_output_options, md_table, resolve_output, robot_task_ids
from envs.common.io import ToolParser, at_least_one
from envs.common.simulation import CTRL_SPEC, STATE_SPEC

GOAL = 0.9


def time_env(env, actions: np.ndarray) -> float:
    env.reset(seed=0)
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset(seed=0)
    return len(actions) / (time.perf_counter() - start)


def record_blocks(env, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The control block of every step, whether the env reset before it, the env's final qpos, and the actuator
    gains of every block where the robot writes them between blocks (the roach's gait mode; else None)."""
    sim = env.unwrapped.robot.sim
    model = env.unwrapped.model
    env.reset(seed=0)
    blocks, resets, gains, reset = [], [], [], False
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        blocks.append(sim.ctrl[0].copy())
        gains.append(model.actuator_gainprm.copy())
        resets.append(reset)
        final = sim.data.qpos.copy()
        reset = terminated or truncated
        if reset:
            env.reset(seed=0)
    written = any(not np.array_equal(g, gains[0]) for g in gains)
    return np.array(blocks), np.array(resets), final, np.array(gains) if written else None


def policy_episode(env, policy, seed: int = 0, record: bool = False) -> dict:
    """One episode of ``policy`` from ``seed``, timed with the policy's moves: the real-time factor, the simulated
    seconds, the forward speed and the final qpos; with ``record``, the control block of every step and the actuator
    gains of every block where the robot writes them between blocks (the roach's gait mode; else None), for
    :func:`time_raw` to replay the very physics the episode ran."""
    base = env.unwrapped
    sim, model = base.robot.sim, base.model
    obs, _ = env.reset(seed=seed)
    blocks, gains, state, start = [], [], None, np.array([True])
    began = time.perf_counter()
    while True:
        action, state = policy.predict(obs, state, start)
        start = np.array([False])
        obs, _, terminated, truncated, info = env.step(action)
        if record:
            blocks.append(sim.ctrl[0].copy())
            gains.append(model.actuator_gainprm.copy())
        if terminated or truncated:
            break
    wall = time.perf_counter() - began
    out = {"rtf": info["time"] / wall, "seconds": float(info["time"]), "speed": info["x_position"] / info["time"],
           "final_qpos": sim.data.qpos.copy()}  # fmt: skip
    if record:
        written = any(not np.array_equal(g, gains[0]) for g in gains)
        out["blocks"], out["gains"] = np.array(blocks), np.array(gains) if written else None
    return out


def alternate_with_replay(env, policy, rounds: int) -> dict:
    """``policy``'s episode from seed 0 and its physics replayed raw (:func:`time_raw`: its control blocks and gains
    from its start), alternating in ``rounds`` rounds so that a shared host's drift falls on both: the recorded
    episode, each round's real-time factors (``env_rtfs``, ``raw_rtfs``), the env's share of the raw speed (the
    median round's) and whether every replay and episode ended where the recorded one did (``same``)."""
    base = env.unwrapped
    recorded = policy_episode(env, policy, record=True)
    env.reset(seed=0)
    start = mujoco.MjData(base.model)
    mujoco.mj_copyData(start, base.model, base.data)
    nominal_gains = base.model.actuator_gainprm.copy()
    blocks = recorded["blocks"]
    resets = np.zeros(len(blocks), dtype=bool)
    env_rtfs, raw_rtfs, same = [], [], True
    for _ in range(rounds):
        run = policy_episode(env, policy)
        env_rtfs.append(run["rtf"])
        same &= bool(np.array_equal(run["final_qpos"], recorded["final_qpos"]))
        rate, final = time_raw(base.model, start, blocks, resets, recorded["gains"])
        base.model.actuator_gainprm[:] = nominal_gains  # the replay wrote the blocks' gains into the env's model
        raw_rtfs.append(rate * recorded["seconds"] / len(blocks))
        same &= bool(np.allclose(final, recorded["final_qpos"], atol=1e-6))
    share = float(np.median(np.array(env_rtfs) / np.array(raw_rtfs)))
    return {"recorded": recorded, "env_rtfs": env_rtfs, "raw_rtfs": raw_rtfs, "share": share, "same": same}


def time_raw(model, start: mujoco.MjData, blocks: np.ndarray, resets: np.ndarray,
             gains: np.ndarray | None = None) -> tuple[float, np.ndarray]:  # fmt: skip
    """One native call per control step, as a hand-written loop would make it (writing each block's actuator gains
    first where the robot does)."""
    data = mujoco.MjData(model)
    mujoco.mj_copyData(data, model, start)
    nstep = blocks.shape[1]
    constant = bool((blocks == blocks[:, :1]).all())
    runner = rollout.Rollout(nthread=0)
    state = np.empty((1, mujoco.mj_stateSize(model, STATE_SPEC)))
    warm = np.empty((1, model.nv))
    t0 = time.perf_counter()
    for i, block in enumerate(blocks):
        if resets[i]:
            mujoco.mj_copyData(data, model, start)
        if gains is not None:
            model.actuator_gainprm[:] = gains[i]
        if constant:
            data.ctrl[:] = block[0]
            mujoco.mj_step(model, data, nstep=nstep)
        else:
            mujoco.mj_getState(model, data, state[0], STATE_SPEC)
            warm[0] = data.qacc_warmstart
            runner.rollout([model], [data], state, block[None], control_spec=CTRL_SPEC, skip_checks=True,
                           nstep=nstep, initial_warmstart=warm, state=None, sensordata=None, chunk_size=1)  # fmt: skip
    return len(blocks) / (time.perf_counter() - t0), data.qpos.copy()


def time_one_call(model, start: mujoco.MjData, blocks: np.ndarray) -> float:
    """The whole run (without its resets) in one rollout call, control steps per second."""
    state = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, start, state, STATE_SPEC)
    control = blocks.reshape(1, -1, blocks.shape[2])
    data = mujoco.MjData(model)
    t0 = time.perf_counter()
    rollout.rollout(model, data, state[None], control, initial_warmstart=start.qacc_warmstart[None])
    return len(blocks) / (time.perf_counter() - t0)


def measure_skitter(env_id: str, steps: int, rounds: int) -> dict:
    env = gym.make(env_id)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, *env.action_space.shape)).astype(np.float32)
    base = env.unwrapped
    if base.robot.action_mode == "gait":
        actions[:, 1] = actions[:, 0]  # straight-ish random gaits keep the robot running, as a policy would
    model = base.model
    env.reset(seed=0)
    start = mujoco.MjData(model)
    mujoco.mj_copyData(start, model, base.data)
    blocks, resets, final, gains = record_blocks(env, actions)
    env_sps, raw_sps, one_sps = [], [], []
    for _ in range(rounds):
        env_sps.append(time_env(env, actions))
        sps, raw_final = time_raw(model, start, blocks, resets, gains)
        raw_sps.append(sps)
        one_sps.append(time_one_call(model, start, blocks))
    ratios = np.array(env_sps) / np.array(raw_sps)
    return {
        "same_trajectory": bool(np.array_equal(final, raw_final)),
        "env_id": env_id,
        "substeps": base.robot.n_substeps,
        "env_steps_per_s": max(env_sps),
        "raw_steps_per_s": max(raw_sps),
        "ratio": float(np.median(ratios)),
        "ratio_rounds": ratios.tolist(),
        "one_call_steps_per_s": max(one_sps),
        "ratio_to_one_call": float(np.median(np.array(env_sps) / np.array(one_sps))),
        "physics_steps_per_s_raw": max(raw_sps) * base.robot.n_substeps,
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
    blocks = np.repeat(actions[:, None, :], u.frame_skip, axis=1).astype(np.float64)
    env_sps, raw_sps = [], []
    for _ in range(rounds):
        env_sps.append(time_env(env, actions))
        raw_sps.append(time_raw(u.model, start, blocks, np.zeros(len(blocks), dtype=bool))[0])
    return {
        "env_id": "Ant-v5 (Gymnasium)",
        "substeps": u.frame_skip,
        "env_steps_per_s": max(env_sps),
        "raw_steps_per_s": max(raw_sps),
        "ratio": float(np.median(np.array(env_sps) / np.array(raw_sps))),
        "physics_steps_per_s_raw": max(raw_sps) * u.frame_skip,
    }


CONFIGURATIONS: dict[str, list[str]] = {"env_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--steps", type=at_least_one, default=600, help="control steps per round (duty envs: x10)")
    parser.add_argument("--rounds", type=at_least_one, default=9)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "env_speed", CONFIGURATIONS)
    ids = robot_task_ids()
    rows = []
    for env_id in ids:
        steps = args.steps * (10 if "Duty" in env_id else 1)
        rows.append(measure_skitter(env_id, steps, args.rounds))
        print(rows[-1])
    ant = measure_ant(args.steps, args.rounds)
    if ant:
        rows.append(ant)
    table = md_table(
        [
            "env",
            "physics steps per step",
            "env steps/s",
            "raw steps/s",
            "ratio",
            "goal >= 0.9",
            "same run?",
            "ratio to one rollout call",
        ],
        [
            [
                r["env_id"],
                r["substeps"],
                round(r["env_steps_per_s"]),
                round(r["raw_steps_per_s"]),
                round(r["ratio"], 3),
                "met" if r["ratio"] >= GOAL else "MISSED",
                {True: "identical", False: "DIFFERENT"}.get(r.get("same_trajectory"), "n/a"),
                round(r["ratio_to_one_call"], 3) if "ratio_to_one_call" in r else "n/a",
            ]
            for r in rows
        ],
    )
    text = (
        "# Env speed against raw stepping (same model, same controls, same run)\n\n"
        "ratio: the median over alternating rounds of env/raw steps per second.\n"
        "raw: one native call per control step (mj_step with constant controls, mujoco.rollout of the block when the "
        "controls ramp within it). 'same run?': whether the raw loop ended in exactly the env's state. Last column: "
        "against the whole run in a single rollout call.\n\n" + table
    )
    output.save({"goal": GOAL, "rows": rows}, text)


if __name__ == "__main__":
    main()
