"""Evaluate policies (scripted gaits and trained models) on the same episode seeds, with honest statistics: the code
of the ``evaluate.py`` command.

    python evaluate.py --env skitter/RoachWalk-v4 --policy tripod --policy runs/.../model.zip \
        --episodes 10 --seed 0 --out results/walk [--video] [--telemetry]

With ``--soccer ROBOT`` it plays matches between two teams' policies instead (agents/soccer/play.py).

Prints a side-by-side table (mean and 95% CI per metric: bootstrap from 10 episodes, Student's t below), and writes
DIR/results.json (every episode and the summaries), DIR/results.md, a plot of one episode per policy (trajectory, body
angles and the robot's own channel groups) and, with --video, an mp4 of each policy's first episode and one of them
all side by side; with --telemetry, the telemetry of every episode as Parquet.

Everything is checked before the first episode runs, and the results are written as one unit: into a temporary folder
beside DIR, which then takes DIR's place. A trained model must fit --env: one whose record from train.py (the manifest
in model.zip, its run's config.json) names another env id is refused, naming both, and any model whose observation
shape or action space differs from the env's is refused (agents/sb3.py).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import tempfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pandas as pd

import envs  # noqa: F401  (registers the envs)
from agents import describe_policies, load_policy
from agents.config import skitter_env_problem
from agents.evaluation import (
    MIN_BOOTSTRAP,
    Episode,
    binary_metrics,
    episode_record,
    metric_descriptions,
    paired_difference,
    run_episodes,
    summarize,
    write_video,
)
from envs.common.calibration import CalibrationError, read_calibration
from envs.common.env import creator_error
from envs.common.io import (
    ToolParser,
    atomic_write,
    json_object,
    publish_folder,
    published_exit_code,
    replace_problem,
    results_folder_problem,
    results_foreign,
    run_interruptibly,
    unpublished_exit_code,
    write_json,
    write_text,
)
from envs.common.telemetry import read_telemetry, write_telemetry


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ToolParser(prog="evaluate.py", description="Compare policies on the same seeds.",
                   epilog="With --soccer ROBOT, evaluate.py plays matches between two teams' policies instead: "
                   "evaluate.py --soccer ROBOT --help lists that mode's options.")  # fmt: skip
    p.add_argument("--env", required=True, help="env id, e.g. skitter/RoachWalk-v4")
    p.add_argument(
        "--policy", action="append", required=True, help=f"scripted gait ({describe_policies()}) or a model.zip; repeat"
    )
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=0, help="episode i runs with seed SEED + i, for every policy")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument(
        "--video",
        action="store_true",
        help="write an mp4 of the first episode of each policy, and one of them side by side",
    )
    p.add_argument("--telemetry", action="store_true", help="write the telemetry of every episode as Parquet")
    p.add_argument("--telemetry-rate", choices=("control", "physics"), default="control",
                   help="the rate of the telemetry behind the plots and --telemetry's files: every control step "
                        "(default) or every physics step, whose leg angles resolve a stride faster than half the "
                        "control rate")  # fmt: skip
    p.add_argument("--stochastic", action="store_true", help="sample actions instead of taking the mode")
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results of an earlier run in --out (a folder holding other files is refused)",
    )
    p.add_argument("--max-episode-steps", type=int, help="cut episodes short (default: the env's time limit)")
    p.add_argument(
        "--calibration",
        type=Path,
        help="a calibration file from calibrate.py: episodes run on the calibrated model (docs/calibration.md)",
    )
    p.add_argument(
        "--unnormalized", action="store_true", help="accept a foreign SB3 model without normalization statistics"
    )
    p.add_argument(
        "--env-kwargs",
        default="{}",
        help="the env's keyword arguments as a JSON object, e.g. '{\"sensor_noise\": false}' (a model trained with "
        "env_kwargs is evaluated with the same ones; others are warned of)",
    )
    args = p.parse_args(argv)
    try:
        args.env_kwargs = json_object(args.env_kwargs, "--env-kwargs")
    except ValueError as exc:
        p.error(str(exc))
    if args.episodes < 1:
        p.error(f"--episodes must be at least 1, got {args.episodes}")
    if args.seed < 0:
        p.error(f"--seed must be >= 0 (numpy seeds are non-negative), got {args.seed}")
    if args.max_episode_steps is not None and args.max_episode_steps < 1:
        p.error(f"--max-episode-steps must be at least 1, got {args.max_episode_steps}")
    problem = skitter_env_problem(args.env)
    if problem is not None:
        p.error(f"--env: {problem}")
    if args.calibration is not None:
        try:
            read_calibration(args.calibration)
        except CalibrationError as exc:
            p.error(f"--calibration: {exc}")
    # evaluate.py sets these itself (from its own options): the same key in --env-kwargs would be given twice
    owned = {"telemetry": "--telemetry or --telemetry-rate", "render_mode": "--video", "calibration": "--calibration",
             "num_envs": "--episodes"}  # fmt: skip
    if args.max_episode_steps:
        owned |= {"max_episode_steps": "--max-episode-steps", "episode_seconds": "--max-episode-steps"}
    taken = [key for key in args.env_kwargs if key in owned]
    if taken:
        p.error(f"--env-kwargs {taken[0]!r}: evaluate.py sets it from {owned[taken[0]]}; give that option instead")
    if args.env_kwargs:
        try:  # made once, so that a bad argument is one line here, before anything else
            gym.make(args.env, **args.env_kwargs).close()
        except (TypeError, ValueError) as exc:
            p.error(f"--env-kwargs: {creator_error(exc)}")
    repeated = sorted({s for s in args.policy if args.policy.count(s) > 1})
    if repeated:
        p.error(f"--policy {repeated[0]!r} is given twice")
    problem = results_folder_problem(args.out, args.overwrite, "evaluate.py", _foreign(args.out))
    problem = problem or replace_problem(args.out)
    if problem:
        p.error(problem)
    args.out_existed = args.out.exists()  # publishing checks again: a folder that appeared meanwhile is not replaced
    return args


# what evaluate.py writes into --out: these files, and these folders of files of one kind
RESULT_FILES = ("results.json", "results.md")
RESULT_FOLDERS = {"plots": ".png", "videos": ".mp4", "telemetry": ".parquet"}


def _foreign(out: Path):
    """What in an entry of ``out`` evaluate.py does not write."""
    return results_foreign(out, RESULT_FILES, RESULT_FOLDERS)


def slugs(specs: list[str]) -> dict[str, str]:
    """A distinct file-name-safe name per policy spec (two runs' step_N/model.zip must not share a plot)."""
    out: dict[str, str] = {}
    for spec in specs:
        path = Path(spec)
        name = "_".join(path.with_suffix("").parts[-3:]) if spec.endswith(".zip") else spec
        base = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "policy"
        slug, k = base, 1
        while slug in out.values():
            k += 1
            slug = f"{base}-{k}"
        out[spec] = slug
    return out


def make_env(args, render: bool):
    """All the episodes of a policy at once: a batched env of one simulation per episode (the same results as single
    envs run one after another, tests/test_batch.py)."""
    limit = {"max_episode_steps": args.max_episode_steps, "episode_seconds": None} if args.max_episode_steps else {}
    if args.calibration is not None:
        limit["calibration"] = str(args.calibration)
    return gym.make_vec(
        args.env,
        num_envs=args.episodes,
        vectorization_mode="vector_entry_point",
        telemetry=args.telemetry_rate,
        render_mode="rgb_array" if render else None,
        **limit,
        **args.env_kwargs,
    )


def evaluate_policy(args, spec: str, policy, env, name: str, out: Path, scratch: Path) -> list[Episode]:
    seeds = [args.seed + i for i in range(args.episodes)]
    stride = video_stride(env.metadata["render_fps"])
    episodes = run_episodes(
        env, policy, seeds, deterministic=not args.stochastic, render_first=args.video, render_every=stride
    )
    base = env.unwrapped
    # each simulation's first episode is the evaluation's episode i
    frames = [rec.frame().query("episode == 0").assign(episode=i) for i, rec in enumerate(base.recorders)]
    telemetry_path = (out / "telemetry" if args.telemetry else scratch) / f"{name}.parquet"
    meta = {**base.recorders[0].meta, "controller": spec, "env_id": args.env, "seeds": seeds}
    meta.pop("simulation", None)
    write_telemetry(telemetry_path, pd.concat(frames, ignore_index=True), meta)
    plot_episode(
        env.unwrapped.robot, telemetry_path, out / "plots" / f"{name}.png", f"{spec} on {args.env}, seed {args.seed}"
    )
    if args.video:
        write_video(episodes[0].frames, out / "videos" / f"{name}.mp4", fps=env.metadata["render_fps"] / stride)
    env.close()
    return episodes


VIDEO_FPS = 30  # at most this many frames a second of simulated time are rendered: rendering is the slow part


def video_stride(control_fps: float) -> int:
    """Render every this many control steps for a video of at most :data:`VIDEO_FPS` frames per second."""
    return max(1, math.ceil(control_fps / VIDEO_FPS - 1e-9))


SIDE_BY_SIDE = "side_by_side"  # videos/side_by_side.mp4: every policy's first episode, left to right in --policy order


def side_by_side(episodes: list[list[np.ndarray]]) -> list[np.ndarray]:
    """The frames of several episodes next to each other, left to right; one that ended sooner holds its last
    frame (the robot stays where its episode ended)."""
    length = max(len(frames) for frames in episodes)
    return [np.concatenate([f[min(i, len(f) - 1)] for f in episodes], axis=1) for i in range(length)]


def plot_episode(robot, telemetry: Path, path: Path, title: str) -> None:
    """Trajectory, body angles and the robot's own channel groups (``robot.plot_groups``) of episode 0."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df, meta = read_telemetry(telemetry)
    df = df[df.episode == 0]
    t = df.time.to_numpy()
    w, x, y, z = (df[f"quat_{a}"].to_numpy() for a in "wxyz")
    angles = {
        "roll": np.degrees(np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))),
        "pitch": np.degrees(np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))),
        "yaw": np.degrees(np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))),
    }
    groups = robot.plot_groups
    rows = (2 + len(groups) + 1) // 2
    fig, axes = plt.subplots(rows, 2, figsize=(11, 3 * rows), squeeze=False)
    # margins in inches for the title and labels: tight_layout measured every tick label, half of the plot's time
    height = 3 * rows
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.5 / height, top=1 - 0.75 / height, wspace=0.22, hspace=0.55)
    ax = axes.ravel()
    ax[0].plot(df.pos_x, df.pos_y)
    ax[0].set(xlabel="x (m)", ylabel="y (m)", title="trajectory")
    ax[0].axis("equal")
    for label, series in angles.items():
        ax[1].plot(t, series, label=label)
    ax[1].set(xlabel="time (s)", ylabel="deg", title="body angles")
    ax[1].legend(fontsize=7)
    for panel, group in zip(ax[2:], groups, strict=False):
        for i, channel in enumerate(group.channels):
            values = df[channel].to_numpy()
            if group.minus:
                values = values - df[group.minus[i]].to_numpy()
            if np.isfinite(values).any():
                label = channel if not group.minus else f"{channel} - {group.minus[i]}"
                panel.plot(t, values * group.scale, lw=0.8, label=label)
        panel.set(xlabel="time (s)", ylabel=group.unit, title=group.title)
        if panel.lines:
            panel.legend(fontsize=7)
        else:  # e.g. the gait clock of a robot run in duty mode: recorded as NaN
            panel.text(0.5, 0.5, "not recorded in this run", ha="center", va="center", transform=panel.transAxes)
    for panel in ax[2 + len(groups) :]:
        panel.axis("off")
    fig.suptitle(f"{title}\n(sampled at the control rate, {meta['rate_hz']:.0f} Hz)", fontsize=10)
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=100))
    plt.close(fig)


def fmt(s: dict[str, float], total: int) -> str:
    """Mean [95% CI] of a summary; "(n of N episodes)" when the mean is over fewer than all ``total`` episodes (a
    metric an episode does not have, such as the cost of transport of one that travelled no distance, is left out)."""
    subset = f" ({s['n']} of {total} episodes)" if s["n"] < total else ""
    if not np.isfinite(s["mean"]):
        return "n/a" + subset
    if not np.isfinite(s["ci_low"]):  # one episode: no interval
        return f"{s['mean']:.3g}{subset}"
    return f"{s['mean']:.3g} [{s['ci_low']:.3g}, {s['ci_high']:.3g}]{subset}"


def report(
    env_id: str,
    results: dict[str, list[Episode]],
    summaries,
    comparisons,
    seeds,
    metrics: dict[str, str],
    binary: tuple[str, ...] = (),
) -> str:
    specs = list(results)
    names = [m for m in metrics if m in summaries[specs[0]]]
    total = len(seeds)
    lines = [
        f"# {env_id}: {total} episodes per policy, seeds {seeds[0]}..{seeds[-1]} (the same for every policy)",
        "",
        "Mean [95% CI] per episode: "
        + (
            "no interval from one episode."
            if total < 2
            else f"Student's t intervals (fewer than {MIN_BOOTSTRAP} episodes: a bootstrap would be too narrow)."
            if total < MIN_BOOTSTRAP
            else "bootstrap (BCa)."
        )
        + (
            f" {', '.join(n for n in binary if n in names)}: 1 or 0 an episode, Wilson's interval of the proportion, "
            "and Newcombe's of a paired difference."
            if total >= 2 and any(n in names for n in binary)
            else ""
        ),
        "",
        "| metric | " + " | ".join(specs) + " |",
        "|---|" + "---|" * len(specs),
    ]
    for m in names:
        lines.append(f"| {m} | " + " | ".join(fmt(summaries[s][m], total) for s in specs) + " |")
    unstable = {s: sum(e.unstable for e in eps) for s, eps in results.items()}
    lines.append("| unstable episodes | " + " | ".join(str(unstable[s]) for s in specs) + " |")
    if comparisons:
        lines += ["", f"Paired differences against {specs[0]} (same seeds), mean [95% CI]:", ""]
        lines += ["| policy | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
        for s, diffs in comparisons.items():
            lines.append(f"| {s} | " + " | ".join(fmt(diffs[m], total) for m in names) + " |")
    subsets = any(
        summary["n"] < total for table in (summaries, comparisons) for row in table.values() for summary in row.values()
    )
    if subsets:
        note = (
            f"A value marked (n of {total} episodes) is the mean over the n episodes that have the metric (a cost of "
            "transport needs a distance travelled; a paired difference needs both episodes of a seed)."
        )
        lines += ["", note]
    lines += ["", "Metrics: " + "; ".join(f"{k}: {v}" for k, v in metrics.items() if k in names) + "."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    given = sys.argv[1:] if argv is None else list(argv)
    if any(a == "--soccer" or a.startswith("--soccer=") for a in given):  # matches between two teams' policies
        from agents.soccer.play import main as play_matches

        return play_matches(given)
    args = parse_args(argv)
    return run_interruptibly("evaluate.py", args.out, lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    from agents.sb3 import trained_env_kwargs  # SB3 and torch, once the arguments are good

    out: Path = args.out
    names = slugs(args.policy)
    # every policy is loaded and checked against its env before any episode runs
    prepared = {}
    for spec in args.policy:
        try:
            env = make_env(args, render=args.video)
        except CalibrationError as exc:
            print(f"evaluate.py: error: --calibration: {exc}", file=sys.stderr)
            return 2
        try:
            prepared[spec] = (load_policy(spec, env) if not args.unnormalized else _load_unnormalized(spec, env), env)
        except (ValueError, FileNotFoundError) as exc:
            trained = trained_env_kwargs(spec) if spec.endswith(".zip") else None
            hint = f" (it was trained with env_kwargs {trained}: pass them with --env-kwargs)" if trained else ""
            print(f"evaluate.py: error: --policy {spec!r}: {exc}{hint}", file=sys.stderr)
            return 2
        trained = trained_env_kwargs(spec) if spec.endswith(".zip") else None
        if trained is not None and trained != args.env_kwargs:
            print(f"evaluate.py: warning: --policy {spec!r} was trained with env_kwargs {trained}; it is evaluated "
                  f"with {args.env_kwargs} (--env-kwargs)", file=sys.stderr)  # fmt: skip
    metrics = metric_descriptions(next(iter(prepared.values()))[1])
    out.parent.mkdir(parents=True, exist_ok=True)
    with (
        tempfile.TemporaryDirectory(prefix=f".{out.name}.", dir=out.parent) as tmp,
        tempfile.TemporaryDirectory() as scratch,
    ):
        staging = Path(tmp) / "results"
        results = {
            spec: evaluate_policy(args, spec, policy, env, names[spec], staging, Path(scratch))
            for spec, (policy, env) in prepared.items()
        }
        if args.video and len(results) > 1:
            fps = next(iter(prepared.values()))[1].metadata["render_fps"]
            write_video(
                side_by_side([eps[0].frames for eps in results.values()]),
                staging / "videos" / f"{SIDE_BY_SIDE}.mp4",
                fps=fps / video_stride(fps),
            )
        binary = binary_metrics(next(iter(prepared.values()))[1])  # proportions: Wilson's and Newcombe's intervals
        summaries = {s: summarize(eps, binary) for s, eps in results.items()}
        reference = args.policy[0]
        comparisons = {
            s: {m: paired_difference(results[reference], eps, m, m in binary) for m in summaries[s]}
            for s, eps in results.items()
            if s != reference
        }
        seeds = [args.seed + i for i in range(args.episodes)]
        text = report(args.env, results, summaries, comparisons, seeds, metrics, binary)
        record = {
            "env": args.env,
            "calibration": None if args.calibration is None else str(args.calibration),
            "env_kwargs": args.env_kwargs,
            "seeds": seeds,
            "deterministic": not args.stochastic,
            "metrics": metrics,
            "files": names,
            "policies": {
                s: {"summary": summaries[s], "episodes": [episode_record(e) for e in eps]} for s, eps in results.items()
            },
            "paired_differences": {"reference": reference, "policies": comparisons},
        }
        write_json(staging / "results.json", record, strict=True)  # a metric an episode does not have (NaN): null
        write_text(staging / "results.md", text)
        try:
            where = publish_folder(staging, out, args.out_existed, _foreign(out))
        except OSError as exc:  # checked before the run, yet the file system may change meanwhile
            return unpublished_exit_code("evaluate.py", staging, out, exc)
    print(text)
    extra = (" videos/" if args.video else "") + (" telemetry/" if args.telemetry else "")
    print(f"results in {where}/ (results.json, results.md, plots/{extra})")
    return published_exit_code("evaluate.py", out, where)


def _load_unnormalized(spec: str, env):
    if spec.endswith(".zip") or Path(spec).is_file():
        from agents.sb3 import SB3Policy

        return SB3Policy(spec, env, allow_unnormalized=True)
    return load_policy(spec, env)
