"""[bioloid-webots, Figure 30] on our Bioloid: the IK library's seven gaits at 0.5, 1, 1.5 and 2 Hz, each scored by
eq. 17 over 32 s (positions every 1 s), beside the report's Webots values.

All 28 rollouts run as one batch (agents.optimize's evaluator, the gaits as ``ik-<gait>:<Hz>`` drive them, lead-in
included), from the ready posture without noise, as the report's single Webots run per cell; ``--seeds K`` adds K
rollouts per cell from perturbed starts (the envs' reset noise 0.1) for the spread. Beside eq. 17: the signed +x
progress (eq. 17 counts walking backward and tumbling too) and whether the robot fell (the body tilted past 1 rad),
the report's four outcomes: forward, backward, fallen, on the spot (|progress| < 0.1 m).

Run: ``python -m benchmarks.bioloid_figure30`` (about a minute on one core).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from agents.bioloid.ik import IKRollouts
from agents.optimize.problem import Evaluator, parse_config
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, non_negative

FREQUENCIES = (0.5, 1.0, 1.5, 2.0)
ORDER = ("trot", "walk", "gallop", "canter", "pace", "bound", "pronk")
SEED = {  # [bioloid-webots, Figure 30]: phi by frequency, gaits in ORDER
    0.5: (8.68, 2.63, 1.25, 1.11, 0.93, 1.19, 2.98),
    1.0: (11.29, 3.16, 0.33, 0.27, 2.88, 0.39, 0.68),
    1.5: (11.06, 4.17, 0.84, 0.83, 2.81, 0.58, 2.43),
    2.0: (12.41, 3.80, 6.32, 1.70, 3.55, 0.26, 1.41),
}
CONFIG = {"env": "skitter/BioloidWalk-v2", "controller": "cpg", "seconds": 32.0, "objective": "distance_travelled",
          "sample_interval": 1.0, "max_tilt": 1.0}  # fmt: skip


def outcome(progress: float, fallen: bool) -> str:
    if fallen:
        return "fallen"
    if abs(progress) < 0.1:
        return "on the spot"
    return "forward" if progress > 0 else "backward"


def figure30(knee_wedge: bool = False, noisy_seeds: int = 0) -> list[dict]:
    cells = [(g, f) for f in FREQUENCIES for g in ORDER]
    config = parse_config({**CONFIG, "env_kwargs": {"knee_wedge": knee_wedge}})
    gaits, frequencies = [g for g, _ in cells], [f for _, f in cells]
    evaluator = Evaluator(config, len(cells), nthread=1, controller=lambda robot: IKRollouts(robot, gaits, frequencies))
    scores = evaluator.evaluate(np.zeros((len(cells), 0)))
    spread = {}
    if noisy_seeds:
        spread = noisy(cells, noisy_seeds, knee_wedge)
    rows = []
    for i, (g, f) in enumerate(cells):
        row = {
            "gait": g,
            "frequency": f,
            "seed_eq17": SEED[f][ORDER.index(g)],
            **{k: float(v[i]) for k, v in scores.items()},
        }
        row["outcome"] = outcome(row["progress_x"], bool(row["fallen"]))
        if spread:
            row["noisy_eq17"] = spread[(g, f)]["distance_travelled"]
            row["noisy_progress_x"] = spread[(g, f)]["progress_x"]
        rows.append(row)
    return rows


def noisy(cells, seeds: int, knee_wedge: bool) -> dict:
    """eq. 17 and progress of every cell from ``seeds`` perturbed starts (reset noise 0.1, seeds 0..K-1)."""
    import gymnasium as gym

    from agents import load_policy

    out = {}
    for g, f in cells:
        # the report's measure, whatever touches the ground: the ground rules end nothing
        venv = gym.make_vec("skitter/BioloidWalk-v2", num_envs=seeds, vectorization_mode="vector_entry_point",
                            nthread=1, max_episode_steps=10**6, episode_seconds=None, max_tilt=np.pi,
                            knee_wedge=knee_wedge, sensor_noise=False,
                            terminate_when_unhealthy=False)  # fmt: skip
        policy = load_policy(f"ik-{g}:{f}", venv)
        obs, info = venv.reset(seed=0)
        positions = [np.column_stack([info["x_position"], info["y_position"]])]
        state, start = None, np.ones(seeds, dtype=bool)
        steps = round(32.0 / venv.unwrapped.dt)
        every = round(1.0 / venv.unwrapped.dt)
        for k in range(1, steps + 1):
            action, state = policy.predict(obs, state, start)
            start[:] = False
            obs, _, _, _, info = venv.step(action)
            if k % every == 0:
                positions.append(np.column_stack([info["x_position"], info["y_position"]]))
        from agents.optimize.problem import distance_travelled

        p = np.stack(positions, axis=1)
        out[(g, f)] = {
            "distance_travelled": distance_travelled(p).tolist(),
            "progress_x": (p[:, -1, 0] - p[:, 0, 0]).tolist(),
        }
    return out


CONFIGURATIONS: dict[str, list[str]] = {"bioloid_figure30": [], "bioloid_figure30_wedge": ["--knee-wedge"]}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--seeds", type=non_negative, default=4, help="perturbed starts per cell beside the nominal")
    parser.add_argument("--knee-wedge", action="store_true", help="the 18 deg wedge variant ([bioloid-webots] IV.A)")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_figure30", CONFIGURATIONS)
    started = time.perf_counter()
    rows = figure30(args.knee_wedge, args.seeds)
    wall = time.perf_counter() - started
    table_rows = []
    for f in FREQUENCIES:
        cells = [r for r in rows if r["frequency"] == f]
        table_rows.append([f"{f:g}"] + [f"{r['distance_travelled']:.2f} ({r['seed_eq17']:.2f})" for r in cells])
    progress_rows = []
    for f in FREQUENCIES:
        cells = [r for r in rows if r["frequency"] == f]
        progress_rows.append([f"{f:g}"] + [f"{r['progress_x']:+.2f} {r['outcome']}" for r in cells])
    best = {
        f: max((r for r in rows if r["frequency"] == f), key=lambda r: r["distance_travelled"])["gait"]
        for f in FREQUENCIES
    }
    spread_rows = []
    if args.seeds:
        for f in FREQUENCIES:
            cells = [r for r in rows if r["frequency"] == f]
            spread_rows.append([f"{f:g}"] + [f"{np.mean(r['noisy_eq17']):.2f} [{min(r['noisy_eq17']):.2f}, "
                                             f"{max(r['noisy_eq17']):.2f}]" for r in cells])  # fmt: skip
    md = (
        f"# [bioloid-webots, Figure 30] on the MuJoCo Bioloid{' (18 deg knee wedges)' if args.knee_wedge else ''}\n\n"
        "eq. 17 over 32 s (positions every 1 s), nominal start; in brackets the report's Webots value:\n\n"
        + md_table(["f (Hz)", *ORDER], table_rows)
        + "\nSigned +x progress (m) over the 32 s and the report's outcome classes (fallen: tilted past 1 rad):\n\n"
        + md_table(["f (Hz)", *ORDER], progress_rows)
        + (f"\neq. 17 from {args.seeds} perturbed starts (reset noise 0.1): mean [min, max]:\n\n"
           + md_table(["f (Hz)", *ORDER], spread_rows) if spread_rows else "")
        + "\nBest gait by eq. 17 per frequency: " + ", ".join(f"{f:g} Hz {g}" for f, g in best.items())
        + " (the report: trot at every frequency).\n"
        + f"\nWall time {wall:.0f} s (28 nominal rollouts as one batch on one thread"
        + (f", then {args.seeds} perturbed per cell)" if args.seeds else ")") + ".\n"
    )  # fmt: skip
    output.save({"rows": rows, "best_by_frequency": best, "wall_seconds": wall, "seeds": args.seeds,
                "knee_wedge": args.knee_wedge}, md)  # fmt: skip


if __name__ == "__main__":
    main()
