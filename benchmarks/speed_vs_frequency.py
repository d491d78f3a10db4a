"""The tripod gait's speed against stride frequency, 5 to 45 Hz, beside the real robot's 2.7 m/s top speed.

Gait mode (the firmware's clock and PID), straight tripod, several seeds per frequency, 6 s episodes with the first
second left out. Also reports leg tracking (the firmware clock's lead over the legs), power and cost of transport.
Writes ``benchmarks/results/speed_vs_frequency.{json,md,png}``. Run: ``python -m benchmarks.speed_vs_frequency``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np

import envs  # noqa: F401
from agents.velociroach.tripod import TripodContext, TripodGait
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, at_least_one, atomic_write, positive_number
from envs.velociroach import constants

WARMUP = 1.0
FAILED = dict.fromkeys(
    ("speed", "heading_drift_deg_per_s", "lag_deg", "power", "cost_of_transport", "fell", "unstable"), np.nan
)


def episode(env, policy, seed: int) -> dict[str, float]:
    obs, info = env.reset(seed=seed)
    robot = env.unwrapped.robot
    x0 = y0 = t0 = None
    lags, powers = [], []
    fell = False
    while True:
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        if info.get("sim_unstable"):
            return {**FAILED, "unstable": 1.0}
        fell |= info["fallen"]
        if info["time"] > WARMUP:
            if x0 is None:
                x0, y0, t0 = info["x_position"], info["y_position"], info["time"]
            lags.append(np.degrees(np.abs(robot.clock[0] - robot.leg_angles()[0])).mean())
            powers.append(info["power"])
        if terminated or truncated:
            break
    if t0 is None:  # fell within the warm-up
        return {**FAILED, "fell": 1.0}
    duration = info["time"] - t0
    distance = np.hypot(info["x_position"] - x0, info["y_position"] - y0)
    power = float(np.mean(powers))
    return {
        "speed": distance / duration,
        "heading_drift_deg_per_s": float(np.degrees(info["yaw"]) / info["time"]),
        "lag_deg": float(np.mean(lags)),
        "power": power,
        "cost_of_transport": power / (robot.facts.mass * 9.81 * distance / duration),
        "fell": float(fell),
        "unstable": 0.0,
    }


CONFIGURATIONS: dict[str, list[str]] = {"speed_vs_frequency": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
FILES = ("{name}.json", "{name}.md", "{name}.png")


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--seeds", type=at_least_one, default=5)
    parser.add_argument("--seconds", type=positive_number, default=6.0)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "speed_vs_frequency", CONFIGURATIONS, files=FILES)
    freqs = np.arange(5.0, 46.0, 5.0)
    env = gym.make("skitter/RoachWalk-v4", episode_seconds=args.seconds)
    layout = TripodContext.from_env(env)
    results = {}
    for f in freqs:
        runs = [episode(env, TripodGait(layout, frequency=f), seed) for seed in range(args.seeds)]
        results[float(f)] = runs
        print(f"{f:g} Hz:", {k: round(float(np.nanmean([r[k] for r in runs])), 3) for k in runs[0]})
    rows = []
    for f, runs in results.items():
        sp = np.array([r["speed"] for r in runs])

        def mean(key: str, runs=runs) -> float:
            return float(np.nanmean([abs(r[key]) for r in runs]))

        rows.append(
            [
                f,
                f"{np.nanmean(sp):.2f} ± {np.nanstd(sp, ddof=1):.2f}",
                round(np.nanmean(sp) / constants.LENGTH, 1),
                round(np.nanmean(sp) / f * 1000, 1),
                round(mean("lag_deg"), 1),
                round(mean("power"), 2),
                round(mean("cost_of_transport"), 2),
                round(mean("heading_drift_deg_per_s"), 1),
                int(sum(np.nan_to_num(r["fell"]) + np.nan_to_num(r["unstable"]) for r in runs)),
            ]
        )
    output.folder.mkdir(parents=True, exist_ok=True)
    plot(results, args.seeds, output.path(".png"))
    header = [
        "stride (Hz)",
        "speed (m/s, mean ± sd)",
        "body lengths/s",
        "mm per stride",
        "clock lead (deg)",
        "power (W)",
        "cost of transport",
        "|heading drift| (deg/s)",
        "falls",
    ]
    top = results[45.0]
    text = (
        "# Tripod speed against stride frequency (RoachWalk-v4, gait mode)\n\n"
        f"{args.seeds} seeds x {args.seconds:g} s per frequency, first {WARMUP:g} s left out. Real robot: "
        f"{constants.TOP_SPEED} m/s at up to {constants.MAX_STRIDE_FREQUENCY:g} Hz (ICRA 2013); model at 45 Hz: "
        f"{np.nanmean([r['speed'] for r in top]):.2f} m/s. Falls: episodes that tipped over (speed and other columns "
        "average the rest).\n\n" + md_table(header, rows)
    )
    output.save({"results": {str(k): v for k, v in results.items()}}, text)


def plot(results: dict, seeds: int, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = np.array(list(results))
    speed = np.array([[r["speed"] for r in runs] for runs in results.values()])
    fig, ax = plt.subplots(figsize=(6, 4))
    mean, sd = np.nanmean(speed, axis=1), np.nanstd(speed, axis=1, ddof=1)
    ax.errorbar(f, mean, yerr=sd, marker="o", capsize=3, label="model, tripod (mean ± sd over seeds)")
    ax.axhline(constants.TOP_SPEED, color="C3", ls="--", label=f"real robot top speed, {constants.TOP_SPEED} m/s")
    ax.set(xlabel="stride frequency (Hz)", ylabel="speed (m/s)", title=f"VelociRoACH tripod, {seeds} seeds")
    ax.legend()
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=120))
    plt.close(fig)


if __name__ == "__main__":
    main()
