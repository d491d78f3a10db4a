"""How fast soccer runs: batched matches against raw ``mujoco.batch`` on the same controls, a match's reset, and the
real-time factor of a three-a-side Bioloid match with the scripted team on both sides.

For each robot, ``--matches`` (8, then 32) two-a-side matches in the robot's own action mode run as one
:class:`~agents.soccer.vec_env.SoccerVecEnv` on one thread, from random actions, for ``--steps`` control steps:

- agent-steps per second (players x steps / wall time, one core);
- the same physics replayed raw: one ``mujoco.batch.Batch`` of the same model, run through the very control block
  the env gave the physics right after each control step (``Batch.rollout``, one call per control step), from the
  state and with the per-simulation parameters the env started that block with; the ratio of the two times is the
  share of a step that is physics (goal: 0.9 or more). Interleaved step by step, the host's drift falls on both
  alike; the replay is checked to give the env's sensor values bit for bit. ``--rounds`` rounds (3), each from the
  same seed (checked to give the same control blocks); the share is the median round's, the rates the best rounds';
- a reset of every match at once, per match (goal: under 1 ms).

Then a three-a-side Bioloid match in the ``commands`` mode, the scripted team on both sides, one PettingZoo env on
one thread: simulated seconds per wall second, the scripted team's moves included (its players acting in one call
per role, :class:`~envs.soccer.scripted.ScriptedTeam`; goal: 5 or more).

Run: ``python -m benchmarks.soccer_speed`` (about 5 minutes).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from mujoco import batch

from agents.soccer.vec_env import SoccerVecEnv
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser
from envs.common.simulation import CTRL_SPEC
from envs.soccer import match
from envs.soccer.scripted import ScriptedTeam

CONFIGURATIONS: dict[str, list[str]] = {"soccer_speed": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
GOALS = {"raw_share": 0.9, "reset_ms": 1.0, "realtime": 5.0}


def mirror_parameters(source: batch.Batch, target: batch.Batch) -> None:
    """Give ``target`` the per-simulation model parameters ``source`` holds (those it expanded, such as the gains a
    robot's motors are driven through, set for each block)."""
    for name in batch.MODEL_FIELDS:
        values = source.expanded(name)
        if values is not None:
            target.expand(name)[:] = values


def batched(robot: str, matches: int, steps: int, seed: int, rounds: int) -> dict:
    """The batched matches and their raw replay, one thread. Each control step of the matches is followed at once by
    the raw replay of the very block it gave the physics, from the state the matches started it in and with the model
    parameters the robot set for it (a motor's gains; both copied over untimed), and each is timed on its own: the
    two interleave every few milliseconds, so a shared host's drift and its other jobs' bursts fall on both alike,
    and the replay runs exactly the matches' physics (checked: the same sensor values after every block). Each round
    runs the matches from the same seed (the rounds are checked to give the same control blocks); the share is the
    median round's."""
    vec = SoccerVecEnv(matches, nthread=1, robot=robot, players_per_team=2, max_cycles=10 * steps)
    engine = vec.engine
    sim = engine.scene.sim
    model = engine.scene.model
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1, 1, (steps, vec.num_envs, vec.action_space.shape[0])).astype(np.float32)
    blocks = np.empty((steps, *sim.ctrl.shape))
    # the same physics, raw: the same model, start and control blocks, one Batch.rollout call a step, recording the
    # sensor values the env needs (and reads its players' senses, the ball and the goals from)
    raw = batch.Batch(model, matches, 1)
    record = {"sensordata": np.empty((matches, sim.n_substeps, model.nsensordata))}
    env_times, raw_times, same, tracks = [], [], True, True
    clock = time.perf_counter
    # the replay starts where the matches' block starts, after what the referee wrote before it (a player back from
    # a penalty): the state is copied then, its time taken off the matches'. A scene the referee moved after its
    # block (a goal's kickoff, a throw-in) records the new state, not the block's: the bit-for-bit check leaves it
    # out, as it does a block run again at shorter steps
    step, reset, write = sim.step, sim.reset, sim.write
    written, copying = np.zeros(matches, dtype=bool), [0.0]

    def step_from_here(ids: np.ndarray | None = None) -> np.ndarray:
        began = clock()
        raw.state[:] = sim.batch.state  # the integration state a block's physics starts from (warmstart included)
        written[:] = False
        copying[0] += clock() - began
        return step(ids)

    def noting_reset(ids: np.ndarray, values: dict[str, np.ndarray]) -> None:
        written[ids] = True
        reset(ids, values)

    def noting_write(ids: np.ndarray, columns: dict) -> np.ndarray:
        written[ids] = True
        return write(ids, columns)

    sim.step, sim.reset, sim.write = step_from_here, noting_reset, noting_write
    for r in range(rounds):
        vec.seed(seed)
        vec.reset()
        first = blocks.copy() if r else None
        env_time = raw_time = 0.0
        for t in range(steps):
            copying[0] = 0.0
            began = clock()
            vec.step(actions[t])
            stepped = clock()
            mirror_parameters(sim.batch, raw)
            resumed = clock()
            raw.rollout(sim.n_substeps, sim.ctrl, CTRL_SPEC, record=("sensordata",), out=record)
            env_time += stepped - began - copying[0]
            raw_time += clock() - resumed
            blocks[t] = sim.ctrl
            kept = ~(written | sim.refined)
            tracks &= bool(np.array_equal(record["sensordata"][kept], sim.substep_sensordata[kept]))
        env_times.append(env_time)
        raw_times.append(raw_time)
        same &= first is None or np.array_equal(first, blocks)
    del sim.step, sim.reset, sim.write  # the simulation's own methods again
    shares = np.array(raw_times) / np.array(env_times)
    env_seconds, raw_seconds = min(env_times), min(raw_times)
    resets = []
    for _ in range(5):
        began = time.perf_counter()
        engine.reset(np.arange(matches))
        resets.append((time.perf_counter() - began) / matches)
    agent_steps = vec.num_envs * steps
    return {
        "robot": robot,
        "matches": matches,
        "players": engine.players,
        "steps": steps,
        "substeps": sim.n_substeps,
        "physics_timestep": float(model.opt.timestep),
        "agent_steps_per_second": agent_steps / env_seconds,
        "raw_agent_steps_per_second": agent_steps / raw_seconds,
        "raw_share": float(np.median(shares)),
        "raw_shares": shares.tolist(),
        "rounds_repeat": bool(same),
        "replay_tracks": tracks,
        "reset_ms_per_match": 1e3 * float(np.median(resets)),
        "simulated_seconds_per_wall_second": steps * engine.dt / env_seconds * matches,
    }


def realtime(seconds: float, seed: int) -> dict:
    """A three-a-side Bioloid match, commands mode, the scripted team on both sides, one thread."""
    env = match.parallel_env(robot="bioloid", players_per_team=3, action_mode="commands")
    obs, _ = env.reset(seed=seed)
    teams, agents = ScriptedTeam.of(env)  # both teams' players, one call per role (field player, keeper)
    memory = None
    steps = round(seconds / env.dt)
    began = time.perf_counter()
    for _ in range(steps):
        actions, memory = teams.act(np.stack([obs[agent] for agent in agents])[None], memory)
        obs, *_ = env.step(dict(zip(agents, actions[0], strict=True)))
    wall = time.perf_counter() - began
    return {"seconds": seconds, "wall": wall, "realtime": seconds / wall, "score": env.score}


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--matches", type=int, nargs="+", default=[8, 32], help="two-a-side matches per robot, batched")
    parser.add_argument("--steps", type=int, default=200, help="control steps of the batched matches")
    parser.add_argument("--match-seconds", type=float, default=20.0, help="simulated seconds of the Bioloid match")
    parser.add_argument("--rounds", type=int, default=3, help="rounds of the matches, each with its replay")
    parser.add_argument("--seed", type=int, default=0)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if min(args.matches) < 1 or args.steps < 1 or args.rounds < 1 or not args.match_seconds > 0:
        parser.error("--matches, --steps and --rounds must be at least 1, --match-seconds more than 0")
    output = resolve_output(parser, args, "soccer_speed", CONFIGURATIONS)
    os.environ.setdefault("SKITTER_THREADS", "1")
    rows = [batched(robot, n, args.steps, args.seed, args.rounds)
            for robot in ("roach", "xjus", "bioloid") for n in args.matches]  # fmt: skip
    match_run = realtime(args.match_seconds, args.seed)
    missed = [f"{r['robot']} raw share at {r['matches']} matches" for r in rows if r["raw_share"] < GOALS["raw_share"]]
    missed += [f"{r['robot']} at {r['matches']} matches: its rounds differ" for r in rows if not r["rounds_repeat"]]
    missed += [f"{r['robot']} at {r['matches']} matches: the replay left the matches' physics" for r in rows
               if not r["replay_tracks"]]  # fmt: skip
    missed += [
        f"{r['robot']} reset at {r['matches']} matches" for r in rows if r["reset_ms_per_match"] > GOALS["reset_ms"]
    ]
    if match_run["realtime"] < GOALS["realtime"]:
        missed.append("Bioloid 3 vs 3 real time")
    table = md_table(
        ["robot", "matches x players", "agent-steps/s (one core)", "raw batch, agent-steps/s", "env / raw",
         "reset per match, ms", "simulated s per wall s"],
        [[r["robot"], f"{r['matches']} x {r['players']}", f"{r['agent_steps_per_second']:.0f}",
          f"{r['raw_agent_steps_per_second']:.0f}", f"{r['raw_share']:.3f}", f"{r['reset_ms_per_match']:.3f}",
          f"{r['simulated_seconds_per_wall_second']:.1f}"] for r in rows],
    )  # fmt: skip
    verdict = "all goals met" if not missed else "MISSED: " + ", ".join(missed)
    md = (
        "# Soccer speed\n\n"
        f"Two-a-side matches of each robot in its own action mode, {' and '.join(map(str, args.matches))} batched "
        "on one thread, "
        f"{args.steps} control steps of random actions; after each control step the raw replay runs the same model "
        "through the very block the matches ran, from their state and parameters (the same sensor values, bit for "
        f"bit), each timed on its own; {args.rounds} rounds (env / raw: the median round's; rates: the best "
        "rounds'). Goals: env / raw at least "
        f"{GOALS['raw_share']}, a reset under {GOALS['reset_ms']:g} ms a match.\n\n"
        + table
        + f"\nA three-a-side Bioloid match in the commands mode, the scripted team on both sides, one thread: "
        f"{match_run['realtime']:.1f} simulated seconds per wall second over {args.match_seconds:g} s "
        f"(goal {GOALS['realtime']:g}).\n\n{verdict}.\n"
    )
    output.save({"rows": rows, "bioloid_3v3": match_run, "goals": GOALS, "met": not missed}, md)


if __name__ == "__main__":
    main()
