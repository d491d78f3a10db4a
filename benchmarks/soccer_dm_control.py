"""Our soccer against dm_control's, side by side in one run on one core: agent-steps per second, the share of a step
spent in raw physics, and the time of a reset.

dm_control's ``locomotion.soccer`` (BoxHead walkers, 2 vs 2, its default 40 Hz control on 200 Hz physics) runs in a
virtualenv of its own, which this benchmark makes once in ``--venv`` (default ``runs/dm_control_venv``):
dm_control 1.0.50 needs a MuJoCo 3 (3.17.0), and skitter runs on MuJoCo 4. Its raw physics is ``physics.step()``
for as many physics steps as the env took, from random actions. Ours: two-a-side matches of each robot in its own
action mode, one match (the PettingZoo env, as dm_control's one env) and 32 batched (``SoccerVecEnv``), each against
raw stepping of the same model through the same control blocks (benchmarks/soccer_speed.py).

Run: ``python -m benchmarks.soccer_dm_control`` (about 3 minutes, and a minute more to make the virtualenv once).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.common import add_output_options, md_table, resolve_output
from benchmarks.soccer_speed import batched
from envs.common.io import ToolParser
from envs.soccer import match

CONFIGURATIONS: dict[str, list[str]] = {"soccer_dm_control": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
RUN_OPTIONS = ("venv",)
DM_CONTROL = ("dm_control==1.0.50", "mujoco==3.17.0", "pillow")
# measured in dm_control's virtualenv: BoxHead 2 vs 2, random actions, one core
PROBE = r"""
import json, os, sys, time
import numpy as np
from dm_control.locomotion import soccer
steps, seed = int(sys.argv[1]), int(sys.argv[2])
env = soccer.load(team_size=2, time_limit=1e6, walker_type=soccer.WalkerType.BOXHEAD,
                  random_state=np.random.RandomState(seed))
specs = env.action_spec()
resets = []
for _ in range(5):
    began = time.perf_counter(); env.reset(); resets.append(time.perf_counter() - began)
rng = np.random.default_rng(seed)
actions = [[rng.uniform(s.minimum, s.maximum) for s in specs] for _ in range(steps)]
substeps = round(env.control_timestep() / env.physics.timestep())
began = time.perf_counter()
for a in actions:
    env.step(a)
wall = time.perf_counter() - began
physics = env.physics
began = time.perf_counter()
for a in actions:
    physics.data.ctrl[:] = np.concatenate(a)
    for _ in range(substeps):
        physics.step()
raw = time.perf_counter() - began
import mujoco, dm_control
print(json.dumps({"agents": len(specs), "steps": steps, "substeps": substeps, "timestep": env.physics.timestep(),
                  "agent_steps_per_second": steps * len(specs) / wall,
                  "raw_agent_steps_per_second": steps * len(specs) / raw, "raw_share": raw / wall,
                  "reset_ms": 1e3 * float(np.median(resets)), "mujoco": mujoco.__version__}))
"""


def dm_control_python(venv: Path) -> Path:
    """dm_control's virtualenv's python, made (once) with :data:`DM_CONTROL`."""
    python = venv / "bin" / "python"
    marker = venv / ".skitter-dm-control"
    if not marker.is_file() or marker.read_text() != " ".join(DM_CONTROL):
        subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "--quiet", *DM_CONTROL], check=True)
        marker.write_text(" ".join(DM_CONTROL))
    return python


def ours_single(robot: str, steps: int, seed: int) -> dict:
    """One PettingZoo match, two a side, random actions, one core; its reset."""
    env = match.parallel_env(robot=robot, players_per_team=2, max_cycles=10 * steps)
    resets = []
    for i in range(5):
        began = time.perf_counter()
        env.reset(seed=seed + i)
        resets.append(time.perf_counter() - began)
    rng = np.random.default_rng(seed)
    size = env.action_space("home_0").shape[0]
    actions = rng.uniform(-1, 1, (steps, len(env.possible_agents), size)).astype(np.float32)
    began = time.perf_counter()
    for a in actions:
        env.step(dict(zip(env.possible_agents, a, strict=True)))
    wall = time.perf_counter() - began
    return {
        "agent_steps_per_second": steps * len(env.possible_agents) / wall,
        "reset_ms": 1e3 * float(np.median(resets)),
    }


def our_rows(steps: int, seed: int, rounds: int, matches: int = 32) -> list[dict]:
    """Each robot's two-a-side soccer, one match and ``matches`` batched, random actions, one core."""
    return [{"robot": robot, "single": ours_single(robot, steps, seed),
             "batched": batched(robot, matches, steps, seed, rounds)}
            for robot in ("roach", "xjus", "bioloid")]  # fmt: skip


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--steps", type=int, default=200, help="control steps of each measurement")
    parser.add_argument("--rounds", type=int, default=3,
                        help="rounds of the batched matches, each with its raw replay interleaved")  # fmt: skip
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--venv", type=Path, default=Path("runs") / "dm_control_venv",
                        help="dm_control's virtualenv (made if missing)")  # fmt: skip
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.steps < 1 or args.rounds < 1:
        parser.error(f"--steps and --rounds must be at least 1, got {args.steps} and {args.rounds}")
    output = resolve_output(parser, args, "soccer_dm_control", CONFIGURATIONS, run_options=RUN_OPTIONS)
    os.environ.setdefault("SKITTER_THREADS", "1")
    python = dm_control_python(args.venv)
    probe = subprocess.run([str(python), "-c", PROBE, str(args.steps), str(args.seed)], capture_output=True,
                           text=True, check=True, env={**os.environ, "MUJOCO_GL": "egl"})  # fmt: skip
    dm = json.loads(probe.stdout.strip().splitlines()[-1])
    rows = our_rows(args.steps, args.seed, args.rounds)
    behind = [r["robot"] for r in rows if r["batched"]["agent_steps_per_second"] < dm["agent_steps_per_second"]]
    table = md_table(
        ["env, 2 vs 2, one core", "physics steps a control step", "agent-steps/s, one match",
         "agent-steps/s, 32 batched", "raw physics share", "reset per match, ms"],
        [["dm_control BoxHead", f"{dm['substeps']} of {1e3 * dm['timestep']:g} ms",
          f"{dm['agent_steps_per_second']:.0f}", "(no batching)", f"{dm['raw_share']:.3f}", f"{dm['reset_ms']:.1f}"]]
        + [[f"skitter {r['robot']}", f"{r['batched']['substeps']} of {1e3 * r['batched']['physics_timestep']:g} ms",
            f"{r['single']['agent_steps_per_second']:.0f}",
            f"{r['batched']['agent_steps_per_second']:.0f}", f"{r['batched']['raw_share']:.3f} (batched)",
            f"{r['single']['reset_ms']:.2f} (one), {r['batched']['reset_ms_per_match']:.2f} (batched)"]
           for r in rows],
    )  # fmt: skip
    verdict = ("ahead of dm_control's agent-steps/s batched for every robot" if not behind
               else f"MISSED: behind dm_control's agent-steps/s on {', '.join(behind)}")  # fmt: skip
    md = (
        "# Soccer against dm_control's\n\n"
        f"dm_control {DM_CONTROL[0].split('==')[1]} on MuJoCo {dm['mujoco']} in its own virtualenv; skitter on "
        f"MuJoCo 4. {args.steps} control steps of random actions each, one core. dm_control's raw share is "
        f"physics.step() for its {dm['substeps']} physics steps a control step; ours the batched matches against "
        "raw mujoco.batch on the same control blocks.\n\n" + table + f"\n{verdict}.\n"
    )
    output.save({"dm_control": dm, "rows": rows, "met": not behind}, md)


if __name__ == "__main__":
    main()
