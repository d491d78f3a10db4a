"""Yaw rate against left/right phase offset for the tripod gait: the curve of [roach-sim, Figures 16 and 17].

Writes ``benchmarks/results/turn_table.{json,md,png}`` and regenerates ``agents/velociroach/turn_table.json`` (used by
the turning tripod, ``agents.tripod.TripodTurn``); another configuration writes its own folder and leaves the
tripod's table alone. Run: ``python -m benchmarks.turn_table``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from scipy.optimize import isotonic_regression

import envs  # noqa: F401  (registers the envs)
from agents.velociroach.tripod import TURN_TABLE, TripodContext, TripodGait
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, at_least_one, atomic_write, positive_number, write_json

PHASES_DEG = np.arange(90, 271, 10)
# The table spans 130..230 deg: beyond it the model falls into fast spinning modes (about +-150 deg/s near 110 and
# 250 deg at 10 Hz) rather than steady turns. The report's V-REP model responded between 130 and 210 deg (its
# figure 17).
TABLE_WINDOW = (130, 230)
WARMUP = 1.0


def yaw_rate(env, policy: TripodGait, seed: int) -> float:
    """Mean yaw rate (rad/s, counter-clockwise positive) after the first second of an episode."""
    obs, info = env.reset(seed=seed)
    rates = []
    while True:
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        if info["time"] > WARMUP:
            rates.append(info["yaw_rate"])
        if terminated or truncated:
            break
    return float(np.mean(rates))


def fingerprint() -> list[float]:
    """The body's pose after a short turning run: it changes when the model or the firmware changes, so a table
    measured on another model or firmware shows itself (tests/test_tripod.py)."""
    env = gym.make("skitter/RoachWalk-v4", sensor_noise=False, max_episode_steps=25)
    policy = TripodGait(TripodContext.from_env(env), frequency=10.0, phase=np.radians(160.0))
    obs, info = env.reset(seed=0)
    for _ in range(25):
        obs, *_, info = env.step(policy.predict(obs)[0])
    return [round(info[k], 5) for k in ("x_position", "y_position", "yaw")]


def fit_table(phases: np.ndarray, rates: np.ndarray) -> tuple[slice, np.ndarray]:
    """The phases of ``TABLE_WINDOW`` and the non-increasing (isotonic) fit of their yaw rates."""
    first = int(np.searchsorted(phases, TABLE_WINDOW[0]))
    last = int(np.searchsorted(phases, TABLE_WINDOW[1], side="right"))
    window = slice(first, last)
    return window, isotonic_regression(rates[window], increasing=False).x


CONFIGURATIONS: dict[str, list[str]] = {"turn_table": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
FILES = ("{name}.json", "{name}.md", "{name}.png")


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--frequencies", type=positive_number, nargs="+", default=[5.0, 10.0, 20.0])
    parser.add_argument("--table-frequency", type=positive_number, default=10.0)
    parser.add_argument("--seeds", type=at_least_one, default=6)
    parser.add_argument("--seconds", type=positive_number, default=8.0)
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    if args.table_frequency not in args.frequencies:
        parser.error(f"--table-frequency {args.table_frequency:g} must be one of --frequencies {args.frequencies}")
    output = resolve_output(parser, args, "turn_table", CONFIGURATIONS, files=FILES)
    env = gym.make("skitter/RoachWalk-v4", episode_seconds=args.seconds)
    layout = TripodContext.from_env(env)
    curves = {}
    for f in args.frequencies:
        rows = []
        for p in PHASES_DEG:
            policy = TripodGait(layout, frequency=f, phase=np.radians(p))
            rows.append([yaw_rate(env, policy, seed) for seed in range(args.seeds)])
        curves[f] = np.array(rows)
        print(
            f"{f:g} Hz: "
            + " ".join(f"{p}:{np.degrees(r.mean()):.0f}" for p, r in zip(PHASES_DEG, curves[f], strict=False))
        )
    mean = {f: c.mean(axis=1) for f, c in curves.items()}
    sd = {f: c.std(axis=1, ddof=1) for f, c in curves.items()}
    f0 = args.table_frequency
    mono, fit = fit_table(PHASES_DEG, mean[f0])
    residual = float(np.abs(fit - mean[f0][mono]).max())
    table = {
        "frequency_hz": f0,
        "generated_by": "benchmarks/turn_table.py",
        "model_hash": env.unwrapped.robot.model_hash,
        "fingerprint": fingerprint(),
        "seeds": args.seeds,
        "episode_seconds": args.seconds,
        "phase_deg": PHASES_DEG.tolist(),
        "yaw_rate": mean[f0].tolist(),
        "yaw_rate_sd": sd[f0].tolist(),
        "monotonic": {"phase_deg": PHASES_DEG[mono].tolist(), "yaw_rate": fit.tolist()},
        "fit_max_residual": residual,
    }
    if output.kept:  # the kept configuration's table is the turning tripod's
        write_json(TURN_TABLE, table)
    else:
        print(f"{TURN_TABLE} left as it is: this configuration's table is in {output.path('.json')}")
    output.folder.mkdir(parents=True, exist_ok=True)
    plot(mean, sd, output.path(".png"))
    header = ["phase (deg)"] + [f"yaw rate at {f:g} Hz (deg/s, mean ± sd)" for f in args.frequencies]
    rows = [
        [int(p)] + [f"{np.degrees(mean[f][i]):.0f} ± {np.degrees(sd[f][i]):.0f}" for f in args.frequencies]
        for i, p in enumerate(PHASES_DEG)
    ]
    lo, hi = PHASES_DEG[mono][0], PHASES_DEG[mono][-1]
    text = (
        "# Yaw rate against phase offset (tripod gait)\n\n"
        f"{args.seeds} seeds x {args.seconds:g} s per point, first {WARMUP:g} s left out; positive = counter-clockwise."
        f"\nThe turning tripod's table: the {f0:g} Hz rates from {lo} to {hi} deg, fitted non-increasing (scipy's "
        f"isotonic regression; largest residual {np.degrees(residual):.0f} deg/s), spanning "
        f"{np.degrees(fit[0]):.0f} to {np.degrees(fit[-1]):.0f} deg/s.\n\n" + md_table(header, rows)
    )
    output.save({"curves": {str(f): c.tolist() for f, c in curves.items()}, "table": table}, text)


def plot(mean: dict, sd: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for f in mean:
        ax.errorbar(PHASES_DEG, np.degrees(mean[f]), yerr=np.degrees(sd[f]), marker="o", capsize=3, label=f"{f:g} Hz")
    ax.axhline(0, color="k", lw=0.5)
    ax.axvline(180, color="k", lw=0.5, ls=":")
    ax.set_xlabel("phase offset, right behind left (deg)")
    ax.set_ylabel("yaw rate (deg/s, CCW +)")
    ax.set_title("VelociRoACH model: turning rate vs phase offset")
    ax.legend()
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=120))
    plt.close(fig)


if __name__ == "__main__":
    main()
