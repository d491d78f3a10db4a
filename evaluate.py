"""Evaluate policies (scripted gaits and trained models) on the same episode seeds, with honest statistics.

    python evaluate.py --env skitter/RoachWalk-v0 --policy tripod --policy runs/.../model.zip \
        --episodes 10 --seed 0 --out results/walk [--video] [--telemetry]

Prints a side-by-side table (mean and 95% bootstrap CI per metric), and writes DIR/results.json (every episode and
the summaries), DIR/results.md, plots of one episode per policy (trajectory, leg angles, body angles, torques, ground
reaction forces; like seed 000 figures 6 to 8) and, with --video, an mp4 per policy; with --telemetry, the
telemetry of every episode as Parquet.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the envs)
from agents import SCRIPTED, load_policy
from agents.evaluation import METRICS, Episode, episode_record, paired_difference, run_episode, summarize
from envs.common.io import atomic_write, write_json, write_text
from envs.common.telemetry import read_telemetry


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description="Compare policies on the same seeds.")
    p.add_argument("--env", required=True, help="env id, e.g. skitter/RoachWalk-v0")
    p.add_argument(
        "--policy",
        action="append",
        required=True,
        help="scripted gait (" + "; ".join(f"{k}: {v}" for k, v in SCRIPTED.items()) + ") or a model.zip; repeat",
    )
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=0, help="episode i runs with seed SEED + i, for every policy")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--video", action="store_true", help="write an mp4 of the first episode of each policy")
    p.add_argument("--telemetry", action="store_true", help="write the telemetry of every episode as Parquet")
    p.add_argument("--stochastic", action="store_true", help="sample actions instead of taking the mode")
    p.add_argument("--overwrite", action="store_true", help="replace the results of an earlier run in --out")
    p.add_argument("--max-episode-steps", type=int, help="cut episodes short (default: the env's time limit)")
    args = p.parse_args(argv)
    if (args.out / "results.json").exists() and not args.overwrite:
        p.error(f"--out {args.out} already holds results.json; choose another directory or pass --overwrite")
    if args.episodes < 1:
        p.error(f"--episodes must be at least 1, got {args.episodes}")
    if args.env not in gym.registry:
        known = ", ".join(sorted(k for k in gym.registry if k.startswith("skitter/")))
        p.error(f"--env {args.env!r} is not registered; known: {known}")
    return args


def slug(spec: str) -> str:
    """A file-name-safe name for a policy spec."""
    path = Path(spec)
    name = f"{path.parent.name}_{path.stem}" if spec.endswith(".zip") else spec
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_")


def evaluate_policy(args, spec: str, out: Path) -> list[Episode]:
    limit = {"max_episode_steps": args.max_episode_steps} if args.max_episode_steps else {}
    env = gym.make(args.env, telemetry=True, render_mode="rgb_array" if args.video else None, **limit)
    policy = load_policy(spec, env)
    episodes = []
    for i in range(args.episodes):
        episodes.append(
            run_episode(
                env, policy, seed=args.seed + i, deterministic=not args.stochastic, render=args.video and i == 0
            )
        )
    recorder = env.unwrapped.recorder
    name = slug(spec)
    with tempfile.TemporaryDirectory() as scratch:
        telemetry_dir = out / "telemetry" if args.telemetry else Path(scratch)
        telemetry_path = telemetry_dir / f"{name}.parquet"
        meta = {"controller": spec, "env_id": args.env, "seeds": [e.seed for e in episodes]}
        recorder.save(telemetry_path, overwrite=args.overwrite, **meta)
        plot_episode(telemetry_path, out / "plots" / f"{name}.png", title=f"{spec} on {args.env}, seed {args.seed}")
    if args.video:
        write_video(episodes[0].frames, out / "videos" / f"{name}.mp4", fps=env.metadata["render_fps"])
    env.close()
    return episodes


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> None:
    import imageio.v2 as imageio

    stride = max(1, round(fps / 50))  # at most 50 frames/s of video

    def write(tmp: Path) -> None:
        with imageio.get_writer(tmp, format="FFMPEG", fps=fps / stride, codec="libx264", macro_block_size=8) as w:
            for frame in frames[::stride]:
                w.append_data(frame)

    atomic_write(path, write)


def plot_episode(telemetry: Path, path: Path, title: str) -> None:
    """Trajectory, leg angles, body angles, crank torques and vertical ground reaction forces of episode 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df, meta = read_telemetry(telemetry)
    df = df[df.episode == 0]
    t = df.time.to_numpy()
    w, x, y, z = (df[f"quat_{a}"].to_numpy() for a in "wxyz")
    roll = np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)))
    pitch = np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1, 1)))
    yaw = np.degrees(np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))))
    fig, ax = plt.subplots(3, 2, figsize=(11, 9))
    ax[0, 0].plot(df.pos_x, df.pos_y)
    ax[0, 0].set(xlabel="x (m)", ylabel="y (m)", title="trajectory")
    ax[0, 0].axis("equal")
    for side, colour in (("left", "C0"), ("right", "C1")):
        angle = np.degrees(np.mod(df[f"leg_angle_{side}"], 2 * np.pi))
        ax[0, 1].plot(t, angle, colour + ".", ms=2, label=f"{side} (mod 360)")
        if df[f"leg_angle_cmd_{side}"].notna().any():
            error = np.degrees(df[f"leg_angle_{side}"] - df[f"leg_angle_cmd_{side}"])
            ax[0, 1].plot(t, error, colour + "-", lw=0.8, label=f"{side} minus firmware clock")
        ax[2, 0].plot(t, df[f"torque_{side}"] * 1e3, colour, label=side)
    ax[0, 1].set(xlabel="time (s)", ylabel="deg", title="leg angles and tracking error")
    ax[0, 1].legend(fontsize=7)
    for series, label in ((roll, "roll"), (pitch, "pitch"), (yaw, "yaw")):
        ax[1, 0].plot(t, series, label=label)
    ax[1, 0].set(xlabel="time (s)", ylabel="deg", title="body angles")
    ax[1, 0].legend(fontsize=7)
    ax[1, 1].plot(t, df.duty_left, label="left")
    ax[1, 1].plot(t, df.duty_right, label="right")
    ax[1, 1].set(xlabel="time (s)", ylabel="duty", title="PWM duty")
    ax[1, 1].legend(fontsize=7)
    ax[2, 0].set(xlabel="time (s)", ylabel="mN m", title="crank torques")
    ax[2, 0].legend(fontsize=7)
    left = df[[f"grf_{leg}_z" for leg in ("FL", "ML", "BL")]].sum(axis=1)
    right = df[[f"grf_{leg}_z" for leg in ("FR", "MR", "BR")]].sum(axis=1)
    ax[2, 1].plot(t, left, label="left legs")
    ax[2, 1].plot(t, right, label="right legs")
    ax[2, 1].set(xlabel="time (s)", ylabel="N", title="vertical ground reaction force")
    ax[2, 1].legend(fontsize=7)
    fig.suptitle(f"{title}\n(sampled at the control rate, {meta['rate_hz']:.0f} Hz)", fontsize=10)
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=100))
    plt.close(fig)


def fmt(s: dict[str, float]) -> str:
    if not np.isfinite(s["mean"]):
        return "n/a"
    return f"{s['mean']:.3g} [{s['ci_low']:.3g}, {s['ci_high']:.3g}]"


def report(env_id: str, results: dict[str, list[Episode]], summaries: dict, comparisons: dict, seeds) -> str:
    specs = list(results)
    metrics = [m for m in METRICS if m in summaries[specs[0]]]
    lines = [
        f"# {env_id}: {len(seeds)} episodes per policy, seeds {seeds[0]}..{seeds[-1]} (the same for every policy)",
        "",
        "Mean [95% bootstrap CI] per episode.",
        "",
        "| metric | " + " | ".join(specs) + " |",
        "|---|" + "---|" * len(specs),
    ]
    for m in metrics:
        lines.append(f"| {m} | " + " | ".join(fmt(summaries[s][m]) for s in specs) + " |")
    unstable = {s: sum(e.unstable for e in eps) for s, eps in results.items()}
    lines.append("| unstable episodes | " + " | ".join(str(unstable[s]) for s in specs) + " |")
    if comparisons:
        lines += ["", f"Paired differences against {specs[0]} (same seeds), mean [95% CI]:", ""]
        lines += ["| policy | " + " | ".join(metrics) + " |", "|---|" + "---|" * len(metrics)]
        for s, diffs in comparisons.items():
            lines.append(f"| {s} | " + " | ".join(fmt(diffs[m]) for m in metrics) + " |")
    lines += ["", "Metrics: " + "; ".join(f"{k}: {v}" for k, v in METRICS.items() if k in metrics) + "."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    out: Path = args.out
    results = {}
    for spec in args.policy:
        try:
            results[spec] = evaluate_policy(args, spec, out)
        except (ValueError, FileNotFoundError) as exc:
            print(f"evaluate.py: policy {spec!r}: {exc}", file=sys.stderr)
            return 2
    summaries = {s: summarize(eps) for s, eps in results.items()}
    reference = args.policy[0]
    comparisons = {
        s: {m: paired_difference(results[reference], eps, m) for m in summaries[s]}
        for s, eps in results.items()
        if s != reference
    }
    seeds = [args.seed + i for i in range(args.episodes)]
    text = report(args.env, results, summaries, comparisons, seeds)
    write_json(
        out / "results.json",
        {
            "env": args.env,
            "seeds": seeds,
            "deterministic": not args.stochastic,
            "metrics": METRICS,
            "policies": {
                s: {"summary": summaries[s], "episodes": [episode_record(e) for e in eps]} for s, eps in results.items()
            },
            "paired_differences": {"reference": reference, "policies": comparisons},
        },
    )
    write_text(out / "results.md", text)
    print(text)
    print(f"results in {out}/ (results.json, results.md, plots/{' videos/' if args.video else ''})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
