"""What speed and turn rate each robot's steering gait gives over a grid of (drive, turn): the ``commands`` mode's
gait maps (envs/soccer/steering.py).

Every grid point runs on flat ground from the robot's reset pose, ``--seeds`` seeds each, batched; its speed (along
the heading, m/s) and turn rate (rad/s, + to the left) are averaged over the run after its first second. A run that
tips over (the body past 1.4 rad from upright) is a fall; a point with a fall is left out of the map, and so is a
point whose speed or turn rate varies between seeds by more than a quarter of the largest (``usable`` in
envs/soccer/steering.py). The maps are
written to ``envs/soccer/gait_maps/<robot>.json`` (for this configuration only) and the table here.

Run: ``python -m benchmarks.gait_maps`` (about 3 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from collections.abc import Callable

import numpy as np

from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, write_json
from envs.common.robot import Robot
from envs.soccer.robots import BY_NAME, ROBOTS
from envs.soccer.steering import MAPS, STEERING, usable

CONFIGURATIONS: dict[str, list[str]] = {"gait_maps": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
WARMUP = 1.0  # s left out of the averages, while the gait starts
TILT = math.cos(1.4)  # the body's up axis below this z: a fall (the walking tasks' max_tilt)


def measure(robot_key: str, seconds: float, seeds: int) -> dict:
    """The grid of one robot: every (drive, turn) x seeds, batched."""
    robot_class = ROBOTS[robot_key]
    steering_class = STEERING[robot_class.name]
    grid = list(itertools.product(steering_class.drives, steering_class.turns))
    n = len(grid) * seeds
    robot = robot_class(num_sims=n, batched=True)
    steering = steering_class(robot)
    drive = np.repeat([g[0] for g in grid], seeds)
    turn = np.repeat([g[1] for g in grid], seeds)
    rngs = [np.random.default_rng(i % seeds) for i in range(n)]
    robot.reset(np.arange(n), rngs, 0.1, None)
    steering.reset(np.arange(n))
    progress, yaw_travel, fallen, span = run_on_flat_ground(robot, rngs, lambda: steering.commands(drive, turn),
                                                            seconds)  # fmt: skip
    speed, rate = (progress / span).reshape(-1, seeds), (yaw_travel / span).reshape(-1, seeds)
    falls = fallen.reshape(-1, seeds).sum(axis=1)
    points = [
        {"drive": float(d), "turn": float(t), "speed": float(speed[i].mean()), "speed_sd": float(speed[i].std()),
         "yaw_rate": float(rate[i].mean()), "yaw_rate_sd": float(rate[i].std()), "falls": int(falls[i])}
        for i, (d, t) in enumerate(grid)
    ]  # fmt: skip
    safe = usable(points)
    kept = {id(p) for p in safe}
    for p in points:
        p["used"] = id(p) in kept
    return {
        "robot": robot_key,
        "points": points,
        "max_speed": max(p["speed"] for p in safe),
        "max_yaw_rate": max(abs(p["yaw_rate"]) for p in safe),
        "seconds": seconds,
        "seeds": seeds,
    }


def run_on_flat_ground(robot: Robot, rngs: list[np.random.Generator], commands: Callable[[], np.ndarray],
                       seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:  # fmt: skip
    """Run a reset ``robot`` on flat ground for ``seconds`` under ``commands()`` (its command block, asked afresh at
    every control step); returns each simulation's progress along its heading (m) and the angle it turned (rad, +
    to the left) over the run after its first ``WARMUP`` second, whether it tipped past ``TILT`` at any step, and
    the seconds those sums span."""
    n = robot.num_sims
    readings = robot.read(rngs, False)
    steps = round(seconds / robot.control_dt)
    warm = round(WARMUP / robot.control_dt)
    fallen = np.zeros(n, dtype=bool)
    progress, yaw_travel = np.zeros(n), np.zeros(n)
    last_xy, last_yaw = readings["position"][:, :2].copy(), _yaw(readings["quaternion"])
    for step in range(steps):
        robot.command(commands())
        robot.step()
        readings = robot.read(rngs)
        q = readings["quaternion"]
        fallen |= 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2) < TILT
        xy, yaw = readings["position"][:, :2], _yaw(q)
        if step >= warm:
            move = xy - last_xy
            progress += np.cos(yaw) * move[:, 0] + np.sin(yaw) * move[:, 1]
            yaw_travel += np.angle(np.exp(1j * (yaw - last_yaw)))
        last_xy, last_yaw = xy.copy(), yaw
    return progress, yaw_travel, fallen, (steps - warm) * robot.control_dt


def _yaw(q: np.ndarray) -> np.ndarray:
    return np.arctan2(2.0 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]), 1.0 - 2.0 * (q[:, 2] ** 2 + q[:, 3] ** 2))


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument(
        "--robots",
        nargs="+",
        default=list(ROBOTS),
        choices=list(ROBOTS),
        type=lambda name: BY_NAME.get(name.lower(), name),  # lower case, as every other soccer tool takes them
        help="robots to map (roach, xjus, bioloid)",
    )
    parser.add_argument("--seconds", type=float, default=6.0, help="length of each run, s")
    parser.add_argument("--seeds", type=int, default=3, help="runs per grid point")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if not args.seconds > WARMUP or args.seeds < 1:
        parser.error(f"--seconds must be more than {WARMUP} and --seeds at least 1")
    output = resolve_output(parser, args, "gait_maps", CONFIGURATIONS)
    started = time.perf_counter()
    maps = {robot: measure(robot, args.seconds, args.seeds) for robot in args.robots}
    wall = time.perf_counter() - started
    if output.kept:
        for robot, result in maps.items():
            write_json(
                MAPS / f"{ROBOTS[robot].name}.json", {**result, "generated_by": "python -m benchmarks.gait_maps"}
            )
    sections = []
    for robot, result in maps.items():
        rows = [[f"{p['drive']:.3g}", f"{p['turn']:.3g}", f"{p['speed']:.3f} ± {p['speed_sd']:.3f}",
                 f"{p['yaw_rate']:+.3f} ± {p['yaw_rate_sd']:.3f}", p["falls"], "yes" if p["used"] else "no"]
                for p in result["points"]]  # fmt: skip
        sections.append(
            f"## {robot}\n\nFastest straight run {result['max_speed']:.3f} m/s; largest turn rate "
            f"{result['max_yaw_rate']:.3f} rad/s (over the points the map uses).\n\n"
            + md_table(["drive", "turn", "speed, m/s", "turn rate, rad/s", "falls", "in the map"], rows)
        )
    md = (
        "# Gait maps of the commands mode\n\n"
        f"Each (drive, turn) of the robot's steering gait (envs/soccer/steering.py) for {args.seconds:g} s, "
        f"{args.seeds} seeds, averaged after the first {WARMUP:g} s. Wall time {wall:.0f} s.\n\n" + "\n".join(sections)
    )
    output.save({"maps": maps, "wall_seconds": wall}, md)


if __name__ == "__main__":
    main()
