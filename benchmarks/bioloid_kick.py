"""The Bioloid's kick (envs/bioloid/kick.py), measured: the ball's speed and direction after a kick from the ready
posture, by where the ball lay, with either front leg, and whether the robot stayed up.

On ``skitter/BioloidScoreEmptyGoal`` (the Four-Legged League field and ball) in the robot's own mode: the robot
starts at the centre spot facing the goal, stands in the ready posture for 0.5 s, the ball is then put at rest at
each place of a grid (m ahead of the body's centre, and to the kicking leg's side), and the kick runs to its end.
Reported per place: the ball's largest forward speed, its direction of travel (deg, 0 straight ahead), and falls,
over seeds 0-2.

Run: ``python -m benchmarks.bioloid_kick`` (about a minute).
"""

from __future__ import annotations

import argparse
import time

import gymnasium as gym
import numpy as np

import envs  # noqa: F401 (registers the ids)
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.bioloid.kick import KICK_AHEAD, KICK_SIDE, KICK_WIDTH, LEFT, RIGHT, Kick
from envs.common.io import ToolParser
from envs.soccer.academy import PLAYER, version
from envs.soccer.field import BALL

CONFIGURATIONS: dict[str, list[str]] = {"bioloid_kick": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
SEEDS = (0, 1, 2)
AHEAD = (0.13, 0.14, 0.15, 0.16, 0.17)  # m ahead of the body's centre
SIDE = (0.05, 0.07, 0.09, 0.11, 0.12, 0.13)  # m to the kicking leg's side
STAND_SECONDS = 0.5
FAST = 2.0  # m/s: a kick that sends the ball at least this fast (the trot pushes it at 0.04-0.07 m/s)
STRAIGHT = 15.0  # deg: and within this of straight ahead


def kick_once(env: gym.Env, kick: Kick, side: float, ahead: float, across: float, seed: int) -> dict:
    """One kick with the leg on ``side`` at a ball ``ahead`` m in front of the body's centre and ``across`` m to that
    leg's side of it, on ``seed``."""
    base = env.unwrapped
    env.reset(seed=seed, options={"robot": [0.0, 0.0, 0.0], "ball": [1.5, 0.0]})
    ready = base.robot.mode.to_action(kick.ready[None])[0]
    for _ in range(round(STAND_SECONDS / base.dt)):
        env.step(ready)
    data = base.data
    qadr, vadr = base.scene.objects[BALL]
    body = data.body(f"{PLAYER}/{base.robot.root_body}").xpos
    start = np.array([body[0] + ahead, body[1] + side * across])
    radius = base.field.ball.radius
    data.qpos[qadr : qadr + 7] = [*start, radius, 1.0, 0.0, 0.0, 0.0]
    data.qvel[vadr : vadr + 6] = 0.0
    fastest, fell, goal = 0.0, False, False
    for step in range(round((kick.duration + 0.3) / base.dt)):
        goals = kick.counts(np.array([step * base.dt]), np.array([side]))
        _, _, terminated, _, info = env.step(base.robot.mode.to_action(goals)[0])
        fastest = max(fastest, float(data.qvel[vadr]))
        if terminated:
            goal = bool(info.get("success", 0.0) > 0.0)
            fell = not goal
            break
    moved = data.qpos[qadr : qadr + 2] - start
    direction = float(np.degrees(np.arctan2(moved[1], moved[0]))) if np.linalg.norm(moved) > 0.01 else float("nan")
    return {"speed": fastest, "direction": direction, "fell": fell, "goal": goal}


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_kick", CONFIGURATIONS)
    started = time.perf_counter()
    env_id = f"skitter/BioloidScoreEmptyGoal-v{version('Bioloid')}"
    env = gym.make(env_id)
    kick = Kick()
    places = []
    for name, side in (("right", RIGHT), ("left", LEFT)):
        for ahead in AHEAD:
            for across in SIDE:
                runs = [kick_once(env, kick, side, ahead, across, seed) for seed in SEEDS]
                moved = [r["direction"] for r in runs if np.isfinite(r["direction"])]
                places.append({"leg": name, "ahead": ahead, "side": across,
                               "speed": float(np.mean([r["speed"] for r in runs])),
                               "direction": float(np.mean(moved)) if moved else None,
                               "falls": sum(r["fell"] for r in runs),
                               "goals": sum(r["goal"] for r in runs)})  # fmt: skip
    env.close()
    zone = [p for p in places if KICK_AHEAD[0] - 1e-9 <= p["ahead"] <= KICK_AHEAD[1] + 1e-9
            and abs(p["side"] - KICK_SIDE) <= KICK_WIDTH + 1e-9]  # fmt: skip
    good = [p for p in zone if p["speed"] >= FAST and p["direction"] is not None
            and abs(p["direction"]) <= STRAIGHT and p["falls"] == 0]  # fmt: skip
    falls = sum(p["falls"] for p in places)
    verdict = (f"in the kick zone (ball {KICK_AHEAD[0]:g}-{KICK_AHEAD[1]:g} m ahead, {KICK_SIDE:g} +- {KICK_WIDTH:g} "
               f"m to the leg's side): {len(good)} of {len(zone)} places send the ball at {FAST:g} m/s or more "
               f"within {STRAIGHT:g} deg of straight, with no fall "
               + ("(met)" if len(good) == len(zone) else "(MISSED)"))  # fmt: skip
    wall = time.perf_counter() - started

    def cell(p: dict) -> str:
        if p["direction"] is None:
            return "no contact" + (f", {p['falls']} falls" if p["falls"] else "")
        return f"{p['speed']:.2f} m/s, {p['direction']:+.0f} deg" + (f", {p['falls']} falls" if p["falls"] else "")

    tables = []
    for leg in ("right", "left"):
        rows = [[f"{a:.2f}"] + [cell(next(p for p in places if p["leg"] == leg and p["ahead"] == a and p["side"] == s))
                                for s in SIDE] for a in AHEAD]  # fmt: skip
        tables.append(f"\n### The {leg} front leg\n\n" + md_table(
            ["ball ahead, m \\ to the leg's side, m", *[f"{s:.2f}" for s in SIDE]], rows))  # fmt: skip
    md = (
        "# The Bioloid's kick\n\n"
        f"`{env_id}`, the robot's own mode; the kick of envs/bioloid/kick.py from the ready posture, the ball put at "
        f"rest at each place after {STAND_SECONDS:g} s of standing; each cell the ball's largest forward speed and "
        f"its direction of travel (+ to the robot's left), mean over seeds {SEEDS[0]}-{SEEDS[-1]}, and the robot's "
        f"falls (of {len(SEEDS)}).\n" + "".join(tables) + f"\n- {verdict}\n- falls over all places: {falls}\n"
        f"\nWall time {wall:.0f} s.\n"
    )
    output.save({"env_id": env_id, "places": places, "zone": zone, "verdict": verdict, "met": len(good) == len(zone),
                 "falls": falls, "wall_seconds": wall}, md)  # fmt: skip


if __name__ == "__main__":
    main()
