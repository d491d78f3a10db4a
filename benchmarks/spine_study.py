"""The spine study the xJüs report asked for and never ran: does a compliant spine beat a rigid chassis over rough
ground and obstacles? ([xjus-report, section 2.6]: "power usage over stochastically generated terrain ... for various
joint stiffnesses")

Every setting walks the same seeded terrains: ``skitter/XjusRough-v1``'s height field, lane ``k`` of field
``terrain_seed`` for every setting, started with the same reset perturbation (seed ``1000 + k``). Settings: the spine
stiffness log-spaced from 0.3x to 10x the report's design stiffness (19.4 N m/rad, 60 lbf in at 20 deg), on all four
spine axes, and a rigid chassis. The gait is the reference Buehler-clock tripod (T = 0.5 s, 60 deg sweep, gait mode),
10 s per episode. Terrains: level ground and random ground at two RMS roughness levels (0.02 and 0.04 m), and a
0.05 m step, a 0.1 m step and 0.05 m stairs on lightly rough ground (0.01 m RMS, so that lanes differ).

The spine's damping scales with the square root of its stiffness, so that every setting has the damping ratio of
the default (about 0.1); ``--damping constant`` keeps 0.1 N m s/rad instead (the stiff settings then ring).

Per setting and terrain, over the lanes, with 95% bootstrap intervals (``agents.evaluation.bootstrap_ci``): forward
speed (progress along +x / time), cost of transport (battery energy / (m g distance along the heading); the report's
motor constants cap the motor's efficiency at 0.37), the variance of the middle segment's roll and pitch after the
first second, how often the robot flips, and on the obstacle terrains how far it got and whether it got past.
Paired differences against the rigid chassis on the same lanes. The compliant settings of a terrain run as one
``mujoco.batch`` (stiffness per simulation), the rigid one as another (its model has no spine joints).

Run: ``python -m benchmarks.spine_study`` (``--lanes``, ``--roughness``, ``--stiffnesses``, ``--obstacles``,
``--seconds`` to shrink it; the run states its size).
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import envs  # noqa: F401
from agents.evaluation import bootstrap_ci
from benchmarks.common import add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, atomic_write
from envs.xjus import constants

ENV_ID = "skitter/XjusRough-v1"
PERIOD, SWEEP = 0.5, constants.WALK_SWEEP
WARMUP = 1.0  # s left out of the roll and pitch variance
DEFAULT_ROUGHNESS = [0.0, 0.02, 0.04]  # m RMS: level ground (lanes differ by the reset perturbation only), two rough
DEFAULT_OBSTACLES = ["step:0.05", "step:0.1", "stairs:0.05"]
GRAVITY = 9.81
METRICS = {
    "speed": "forward speed, m/s",
    "cot": "cost of transport",
    "roll_var": "roll variance, deg^2",
    "pitch_var": "pitch variance, deg^2",
    "flipped": "flipped (fraction)",
    "progress": "progress along +x, m",
    "cleared": "got past the obstacle (fraction)",
}


@dataclass(frozen=True)
class TerrainSpec:
    name: str
    roughness: float
    obstacle: str = "none"
    step_height: float = 0.05

    def kwargs(self) -> dict:
        return {"roughness": self.roughness, "obstacle": self.obstacle, "step_height": self.step_height}


def roll_pitch(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad) of unit quaternions (n, 4), (w, x, y, z)."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return roll, pitch


def run_batch(terrain: TerrainSpec, scales: list[float | None], lanes: int, seconds: float, threads: int,
              terrain_seed: int, damping: str = "ratio") -> list[dict]:  # fmt: skip
    """One episode per (setting, lane) on one batch; a scale of None is the rigid chassis (all of ``scales`` must
    then be None). ``damping="ratio"`` scales the spine's damping with the square root of its stiffness (the same
    damping ratio at every stiffness), ``"constant"`` keeps 0.1 N m s/rad. Returns a record per episode."""
    rigid = scales[0] is None
    n = len(scales) * lanes
    steps = round(seconds * constants.CONTROL_FREQ)
    kwargs = {**terrain.kwargs(), "terrain_seed": terrain_seed, "spine": "rigid" if rigid else "compliant"}
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", nthread=threads,
                        max_episode_steps=steps, episode_seconds=None, **kwargs)  # fmt: skip
    base = venv.unwrapped
    robot = base.robot
    setting = np.repeat(np.arange(len(scales)), lanes)
    lane = np.tile(np.arange(lanes), len(scales))
    if not rigid:
        for i in range(n):
            scale = scales[setting[i]]
            damping_scale = np.sqrt(scale) if damping == "ratio" else 1.0
            robot.set_parameters(np.array([i]), {"spine_stiffness_scale": scale, "spine_damping_scale": damping_scale})
    seeds = [1000 + int(k) for k in lane]
    for k in range(lanes):
        venv.reset(seed=seeds, options={"reset_mask": lane == k, "start": k})
    action = np.tile(robot.mode.to_action(np.array([PERIOD, SWEEP, SWEEP])), (n, 1))
    running = np.ones(n, dtype=bool)
    last: list[dict] = [{} for _ in range(n)]
    fallen, unstable = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    rolls, pitches = [], []
    for _ in range(steps):
        _, _, terminated, truncated, info = venv.step(action)
        roll, pitch = roll_pitch(info["quaternion"])
        keep = running & (info["time"] > WARMUP)
        rolls.append(np.where(keep, roll, np.nan))
        pitches.append(np.where(keep, pitch, np.nan))
        for i in np.flatnonzero(running):
            if info["sim_unstable"][i]:
                unstable[i] = True
            else:
                last[i] = {k: info[k][i] for k in ("progress_x", "distance", "energy", "elapsed")}
                fallen[i] = bool(info["fallen"][i])
        running &= ~(terminated | truncated)
        if not running.any():
            break
    roll_var = np.degrees(np.degrees(np.nanvar(np.array(rolls), axis=0)))  # deg^2
    pitch_var = np.degrees(np.degrees(np.nanvar(np.array(pitches), axis=0)))
    end = base.task.terrain.obstacle_end()
    mass = robot.facts.mass
    records = []
    nan = float("nan")
    for i in range(n):
        rec = last[i] or {"progress_x": nan, "distance": nan, "energy": nan, "elapsed": nan}  # unstable at once
        distance = float(rec["distance"])
        records.append({
            "terrain": terrain.name,
            "setting": "rigid" if rigid else f"{scales[setting[i]]:.3g}x",
            "scale": None if rigid else float(scales[setting[i]]),
            "lane": int(lane[i]),
            "speed": float(rec["progress_x"]) / float(rec["elapsed"]),
            "cot": float(rec["energy"]) / (mass * GRAVITY * distance) if distance > 1e-3 else float("nan"),
            "roll_var": float(roll_var[i]),
            "pitch_var": float(pitch_var[i]),
            "flipped": float(fallen[i]),
            "unstable": bool(unstable[i]),
            "progress": float(rec["progress_x"]),
            "cleared": float(rec["progress_x"] >= end) if np.isfinite(end) else float("nan"),
        })  # fmt: skip
    return records


def summarize(records: list[dict], settings: list[str], terrains: list[str]) -> dict:
    """Mean and 95% CI per terrain, setting and metric; paired differences against rigid on the same lanes."""
    out: dict = {}
    for terrain in terrains:
        rows = [r for r in records if r["terrain"] == terrain]
        rigid = {r["lane"]: r for r in rows if r["setting"] == "rigid"}
        out[terrain] = {}
        for setting in settings:
            mine = sorted((r for r in rows if r["setting"] == setting), key=lambda r: r["lane"])
            entry = {}
            for metric in METRICS:
                values = np.array([r[metric] for r in mine], dtype=float)
                if not np.isfinite(values).any():
                    continue
                low, high = bootstrap_ci(values)
                entry[metric] = {
                    "mean": float(np.nanmean(values)),
                    "ci": [low, high],
                    "n": int(np.isfinite(values).sum()),
                }
                if setting != "rigid":
                    diffs = np.array([r[metric] - rigid[r["lane"]][metric] for r in mine], dtype=float)
                    dlow, dhigh = bootstrap_ci(diffs)
                    entry[metric]["paired_vs_rigid"] = {"mean": float(np.nanmean(diffs)), "ci": [dlow, dhigh]}
            out[terrain][setting] = entry
    return out


def findings(summary: dict, settings: list[str]) -> list[str]:
    """Plain statements: where a paired difference's 95% CI excludes zero, and which way."""
    lines = []
    for terrain, by_setting in summary.items():
        said = []
        for metric, label in METRICS.items():
            better, worse = [], []
            for setting in settings:
                d = by_setting[setting].get(metric, {}).get("paired_vs_rigid")
                if d is None or not np.all(np.isfinite(d["ci"])):
                    continue
                if d["ci"][0] > 0:
                    better.append(setting)
                elif d["ci"][1] < 0:
                    worse.append(setting)
            if better or worse:
                parts = []
                if better:
                    parts.append(f"higher at {', '.join(better)}")
                if worse:
                    parts.append(f"lower at {', '.join(worse)}")
                said.append(f"{label}: {'; '.join(parts)} than rigid")
        statement = "; ".join(said) if said else "no difference from the rigid chassis in any metric (every CI spans 0)"
        lines.append(f"- **{terrain}**: {statement}.")
    return lines


def fmt(stat: dict | None, digits: int = 2) -> str:
    if stat is None:
        return ""
    return f"{stat['mean']:.{digits}f} [{stat['ci'][0]:.{digits}f}, {stat['ci'][1]:.{digits}f}]"


def plot(summary: dict, settings: list[str], scales: list[float], path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = ["speed", "cot", "roll_var", "pitch_var", "flipped", "progress"]
    fig, axes = plt.subplots(2, 3, figsize=(15, 8))
    stiffness = np.array(scales) * constants.SPINE_DESIGN_STIFFNESS
    for ax, metric in zip(axes.ravel(), panels, strict=True):
        for j, (terrain, by_setting) in enumerate(summary.items()):
            color = f"C{j}"
            stats = [by_setting[s].get(metric) for s in settings if s != "rigid"]
            if any(s is None for s in stats):
                continue
            mean = np.array([s["mean"] for s in stats])
            err = np.abs(np.array([s["ci"] for s in stats]).T - mean)
            ax.errorbar(stiffness, mean, yerr=err, marker="o", capsize=3, color=color, label=terrain)
            rigid = by_setting["rigid"].get(metric)
            if rigid is not None:
                ax.axhline(rigid["mean"], color=color, linestyle="--", linewidth=1)
                ax.axhspan(*rigid["ci"], color=color, alpha=0.08)
        ax.set_xscale("log")
        ax.set_xlabel("spine stiffness per axis, N m/rad (dashed: rigid, band: its 95% CI)")
        ax.set_title(METRICS[metric])
        ax.axvline(constants.SPINE_DESIGN_STIFFNESS, color="grey", linewidth=0.5)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("xJüs spine study: mean and 95% CI over seeded lanes, Buehler tripod T = 0.5 s")
    fig.tight_layout()
    atomic_write(path, lambda p: fig.savefig(p, format="png", dpi=90))
    plt.close(fig)


RUN_OPTIONS = ("threads",)  # options that do not change the results (benchmarks/common.py)
CONFIGURATIONS: dict[str, list[str]] = {"spine_study": [], "spine_study_constant_damping": ["--damping", "constant"]}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
FILES = ("{name}.json", "{name}.md", "{name}.png")


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--lanes", type=int, default=20,
                        help="seeded terrains (lanes) per terrain kind (default 20, the issue's least; fewer for a "
                             "quick look)")  # fmt: skip
    parser.add_argument("--roughness", type=float, nargs="+", default=DEFAULT_ROUGHNESS, help="RMS heights, m")
    parser.add_argument("--stiffnesses", type=int, default=6, help="log-spaced settings from 0.3x to 10x")
    parser.add_argument("--obstacles", nargs="*", default=DEFAULT_OBSTACLES, help="KIND:HEIGHT (m), e.g. step:0.05")
    parser.add_argument("--obstacle-roughness", type=float, default=0.01)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--terrain-seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument(
        "--damping",
        choices=["ratio", "constant"],
        default="ratio",
        help="spine damping: the same damping ratio at every stiffness, or 0.1 N m s/rad throughout",
    )
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "spine_study", CONFIGURATIONS, files=FILES, run_options=RUN_OPTIONS)
    if args.lanes < 1 or args.stiffnesses < 1 or args.threads < 1 or not args.roughness:
        parser.error("--lanes, --stiffnesses, --threads and --roughness need at least one")
    if not (np.isfinite(args.seconds) and args.seconds > 0):
        parser.error(f"--seconds must be a positive number of seconds, got {args.seconds!r}")
    scales = np.geomspace(0.3, 10.0, args.stiffnesses).tolist() if args.stiffnesses > 1 else [1.0]
    terrains = [TerrainSpec(f"rough {r:g} m RMS", r) for r in args.roughness]
    for item in args.obstacles:
        kind, _, height = item.partition(":")
        try:
            terrains.append(TerrainSpec(f"{kind} {float(height):g} m", args.obstacle_roughness, kind, float(height)))
        except ValueError:
            parser.error(f"--obstacles: {item!r} is not KIND:HEIGHT in m (e.g. step:0.05)")
    for terrain in terrains:  # the env's own checks, before any episode runs
        try:
            gym.make(ENV_ID, **terrain.kwargs(), terrain_seed=args.terrain_seed).close()
        except ValueError as exc:
            parser.error(f"{terrain.name}: {exc}")
    settings = [f"{s:.3g}x" for s in scales] + ["rigid"]
    started = time.perf_counter()
    records, timings = [], []
    for terrain in terrains:
        for batch in (scales, [None]):
            t0 = time.perf_counter()
            records += run_batch(
                terrain, batch, args.lanes, args.seconds, args.threads, args.terrain_seed, args.damping
            )
            timings.append({"terrain": terrain.name, "episodes": len(batch) * args.lanes,
                            "seconds": time.perf_counter() - t0})  # fmt: skip
            print(timings[-1], flush=True)
    wall = time.perf_counter() - started
    episodes = len(records)
    summary = summarize(records, settings, [t.name for t in terrains])
    plot_path = output.path(".png")
    output.folder.mkdir(parents=True, exist_ok=True)
    plot(summary, settings, scales, plot_path)
    size = (f"{args.lanes} lanes x {len(settings)} settings ({len(scales)} stiffnesses + rigid) x {len(terrains)} "
            f"terrains, {args.seconds:g} s episodes: {episodes} episodes")  # fmt: skip
    full = 20 * 7 * (len(DEFAULT_ROUGHNESS) + len(DEFAULT_OBSTACLES)) * 10.0  # the default study: episode-seconds
    per_episode_second = wall / (episodes * args.seconds)
    text = [
        "# xJüs spine study: compliant spine against a rigid chassis\n",
        f"Size: {size}, terrain seed {args.terrain_seed}. Wall time {wall:.0f} s on {args.threads} threads "
        f"({os.cpu_count()} cores, shared); the default study (20 lanes, 6 stiffnesses + rigid, 6 terrains, 10 s) "
        f"takes about {full * per_episode_second / 60:.1f} min at this rate.\n",
        "Gait: Buehler-clock tripod, T = 0.5 s, 60 deg sweep (gait mode). Stiffness per spine axis = scale x 19.4 "
        "N m/rad (the report's 60 lbf in at 20 deg); damping "
        + (
            "0.1 x sqrt(scale) N m s/rad, the same damping ratio (about 0.1) at every stiffness. "
            if args.damping == "ratio"
            else "0.1 N m s/rad at every stiffness. "
        )
        + "Speed: progress along +x over the episode's time (to a flip). "
        "Cost of transport: battery energy / (m g distance along the heading); the report's motor constants cap the "
        "motor's efficiency at 0.37. Roll and pitch: the middle segment's, variance after the first second.\n",
        "## Findings (95% CIs of paired differences against rigid on the same lanes)\n",
        *findings(summary, settings),
        "",
    ]
    for terrain in terrains:
        by_setting = summary[terrain.name]
        obstacle = terrain.obstacle != "none"
        header = ["setting", "speed, m/s", "CoT", "roll var, deg^2", "pitch var, deg^2", "flipped"]
        header += ["progress, m", "cleared"] if obstacle else []
        rows = []
        for setting in settings:
            e = by_setting[setting]
            row = [setting, fmt(e.get("speed")), fmt(e.get("cot")), fmt(e.get("roll_var"), 1),
                   fmt(e.get("pitch_var"), 1), fmt(e.get("flipped"))]  # fmt: skip
            row += [fmt(e.get("progress")), fmt(e.get("cleared"))] if obstacle else []
            rows.append(row)
        diffs = []
        for setting in settings[:-1]:
            e = by_setting[setting]
            keys = ["speed", "cot", "roll_var", "pitch_var", "flipped"] + (["progress", "cleared"] if obstacle else [])
            diffs.append([setting] + [fmt(e.get(k, {}).get("paired_vs_rigid"), 2) for k in keys])
        text += [f"## {terrain.name}\n", "Mean [95% CI] over lanes:\n", md_table(header, rows),
                 "Paired difference, setting minus rigid, same lanes:\n", md_table(header, diffs)]  # fmt: skip
    text.append(f"Plot: {plot_path.name}\n")
    output.save({"size": size, "wall_seconds": wall, "timings": timings, "settings": settings, "scales": scales,
                     "terrains": [t.__dict__ for t in terrains], "summary": summary, "records": records,
                     "args": vars(args)}, "\n".join(text))  # fmt: skip


if __name__ == "__main__":
    main()
