"""The CPG experiments 5 and 6 of [bioloid-webots] with its PSO at its scale (50 particles x 240 iterations x 32 s):
the runs' results, read from their run folders, beside the report's (best scores 7-17 over its six experiments), and the
checks of ``benchmarks/bioloid_cpg_check.py`` on each best policy (is the gait physical, or a simulator exploit?).

Each best policy is then compared with the reference trot (``ik-trot`` at 1.5 Hz) by ``evaluate.py`` (its
episodes: BioloidWalk-v2, 10 s, reset noise 0.1, seeds 1000 on; mean and 95% bootstrap CI, paired differences),
written to ``results/bioloid_cpg_vs_trot.{md,json}``.

The runs themselves are ``python -m agents.optimize`` (the commands below; each resumes from its checkpoint when run
again, about 50 minutes each on this machine); this script summarizes what they have: iterations done, the best eq. 17
score and, for that policy, its signed +x progress and whether it fell, the swarm's falls, the evaluation's wall time,
the best parameters (as the optimizer's [0, 1] vector and as oscillator parameters) and the best score per iteration.
It copies each best policy to ``results/bioloid_cpg_experiment<e>_best.json`` (``evaluate.py --policy cpg:<file>``).

Run: ``python -m benchmarks.bioloid_cpg_experiments`` (about two minutes; ``--no-check`` for the summary alone).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from agents.bioloid.cpg import AMPLITUDE_SCALE, CPG, parse_coupling
from benchmarks.bioloid_cpg_check import check, drop_rebound, markdown
from benchmarks.common import Output, add_output_options, md_table, resolve_output
from envs.common.io import ToolParser, at_least_one, write_text

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = (5, 6)
WALK = "skitter/BioloidWalk-v2"
REFERENCE = "ik-trot:1.5"
SEED_BEST = (7.0, 17.0)  # eq. 17, the report's best scores over its six experiments [bioloid-webots, VI.B.4]


def command(e: int) -> str:
    return (f"python -m agents.optimize --config agents/bioloid/optimize/experiment{e}.json --optimizer pso "
            f"--iterations 240 --particles 50 --seed 0 --out runs/optimize/experiment{e}__pso__0")  # fmt: skip


def oscillator_parameters(policy: dict[str, Any]) -> list[dict[str, Any]]:
    """Each oscillator's parameters in a policy file: offset x0 and amplitude sqrt(E) as angles, and the weights a, b
    it takes from its input's x and v (bidir: its input also takes -a, -b from it), by the report's mapping
    (agents/bioloid/cpg.py)."""
    coupling = parse_coupling(policy["coupling"], "policy")
    p = np.asarray(policy["parameters"], dtype=np.float64)
    cpg = CPG(coupling, p[None])
    w = coupling.ranges["coupling"]
    rows = []
    for i, name in enumerate(coupling.oscillators):
        group = p[4 * coupling.groups[i] : 4 * coupling.groups[i] + 4]
        rows.append({
            "servo": name,
            "input": coupling.oscillators[coupling.inputs[i]],
            "bidir": coupling.bidir[i],
            "group": coupling.groups[i],
            "offset_deg": math.degrees(cpg.offset[0, i]),
            "amplitude_deg": math.degrees(cpg.amplitude[0, i] * AMPLITUDE_SCALE),
            "a": (2.0 * group[2] - 1.0) * w,
            "b": (2.0 * group[3] - 1.0) * w,
            "frequency_hz": float(cpg.rate[0, i] / (2.0 * math.pi)),
        })  # fmt: skip
    return rows


def run_folder(e: int) -> Path:
    return ROOT / "runs" / "optimize" / f"experiment{e}__pso__0"


def runs_missing(output: Output) -> list[str]:
    """The experiments whose runs the results already at ``output`` summarize but whose run folders are gone (a
    fresh checkout holds none): summarizing again would replace those results with "not run yet"."""
    path = output.path(".json")
    if not path.is_file():
        return []
    kept = json.loads(path.read_text()).get("rows", [])
    return [f"experiment {r['experiment']}" for r in kept
            if r.get("iterations_done") and not (run_folder(r["experiment"]) / "history.json").exists()]  # fmt: skip


def summary(e: int, output: Output) -> dict[str, Any]:
    out = run_folder(e)
    row: dict[str, Any] = {"experiment": e, "command": command(e), "run_folder": str(out.relative_to(ROOT))}
    if not (out / "history.json").exists():
        return {**row, "iterations_done": 0}
    history = json.loads((out / "history.json").read_text())
    best = json.loads((out / "best.json").read_text())
    rows = history["history"]
    curve = [h["best_so_far"] for h in rows]
    metrics = best["metrics"]
    row.update({
        "iterations_done": len(curve),
        "best_eq17": metrics.get("distance_travelled", metrics.get("eq17")),  # (earlier runs: "eq17")
        "best_iteration": best["iteration"],
        "best_progress_x": metrics["progress_x"],
        "best_forward": metrics["forward"],
        "best_fallen": bool(metrics["fallen"]),
        "best_fall_time": metrics["fall_time"],
        "swarm_falls_last_iteration": rows[-1]["falls"],
        "swarm_mean_last_iteration": rows[-1]["mean"],
        "wall_seconds": history["wall_seconds"],
        "seconds_per_iteration": history["wall_seconds"] / len(curve),
        "best_so_far": curve,
        "parameters": best["parameters"],
        "oscillators": oscillator_parameters(best),
    })  # fmt: skip
    output.folder.mkdir(parents=True, exist_ok=True)
    write_text(best_policy(output, e), json.dumps(best, indent=2) + "\n")
    return row


def best_policy(output: Output, experiment: int) -> Path:
    """Where a run writes an experiment's best policy (``evaluate.py --policy cpg:<file>``)."""
    return output.file(f"bioloid_cpg_experiment{experiment}_best.json")


def _shown(path: Path) -> str:
    """A path as the repository's commands give it: relative to the repository."""
    return os.path.relpath(path.resolve(), ROOT)


def _parameter_table(r: dict[str, Any]) -> str:
    return md_table(
        ["servo", "input", "bidir", "offset x0 (deg)", "amplitude (deg)", "a", "b"],
        [[o["servo"], o["input"], "yes" if o["bidir"] else "", f"{o['offset_deg']:+.1f}", f"{o['amplitude_deg']:.1f}",
          f"{o['a']:+.2f}", f"{o['b']:+.2f}"] for o in r["oscillators"]],
    )  # fmt: skip


def compare_with_trot(done: list[dict[str, Any]], episodes: int, output: Output) -> str:
    """``evaluate.py`` on the reference trot and each best policy; its results.md and results.json copied to
    ``results/bioloid_cpg_vs_trot.*``. Returns the command it ran."""
    from agents import compare

    policies = [best_policy(output, r["experiment"]) for r in done]
    specs = [REFERENCE] + [f"cpg:{_shown(p)}" for p in policies]
    argv = ["--env", WALK, *[a for s in specs for a in ("--policy", s)], "--episodes", str(episodes), "--seed", "1000"]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "evaluation"
        with contextlib.chdir(ROOT):  # the policy paths are relative to the repository
            if compare.main([*argv, "--out", str(out)]) != 0:
                raise RuntimeError("evaluate.py failed on the best policies")
        for suffix in ("md", "json"):
            write_text(output.file(f"bioloid_cpg_vs_trot.{suffix}"), (out / f"results.{suffix}").read_text())
    return "python evaluate.py " + " ".join(argv) + " --out <folder>"


CONFIGURATIONS: dict[str, list[str]] = {"bioloid_cpg_experiments": []}
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py)."""
FILES = ("{name}.json", "{name}.md", "bioloid_cpg_vs_trot.json", "bioloid_cpg_vs_trot.md",
         "bioloid_cpg_experiment[0-9]*_best.json", "bioloid_cpg_experiment[0-9]*_frames.png")  # fmt: skip
"""The files it writes for the results name ``name`` (``fnmatch`` patterns): its own, the evaluation against the
reference trot, and per experiment the best policy and its frames."""


def make_parser() -> argparse.ArgumentParser:
    parser = ToolParser(description=__doc__)
    parser.add_argument("--no-check", action="store_true", help="skip the physical checks and the evaluation")
    parser.add_argument("--episodes", type=at_least_one, default=20, help="evaluate.py episodes per policy")
    add_output_options(parser)
    return parser


def main(argv: list[str] | None = None) -> None:
    parser = make_parser()
    args = parser.parse_args(argv)
    output = resolve_output(parser, args, "bioloid_cpg_experiments", CONFIGURATIONS, files=FILES)
    lost = runs_missing(output)
    if lost:
        parser.exit(1, f"{parser.prog}: the kept results in {output.path('.json')} summarize "
                       f"{', '.join(lost)}, whose run folders are not here: nothing written (run the commands "
                       "in that file first, or give --out)\n")  # fmt: skip
    rows = [summary(e, output) for e in EXPERIMENTS]
    done = [r for r in rows if r["iterations_done"]]
    table = md_table(
        ["experiment", "parameters", "iterations done", "best eq. 17 (seed: 7-17)", "at iteration",
         "its +x progress in 32 s", "fell", "swarm falls, last iteration", "evaluation wall time"],
        [[r["experiment"], len(r["parameters"]), f"{r['iterations_done']} of 240", f"{r['best_eq17']:.2f}",
          r["best_iteration"], f"{r['best_progress_x']:+.2f} m ({r['best_progress_x'] / 32:.2f} m/s)",
          "yes" if r["best_fallen"] else "no", f"{r['swarm_falls_last_iteration']} of 50",
          f"{r['wall_seconds']:.0f} s ({r['wall_seconds'] / 60:.1f} min, {r['seconds_per_iteration']:.1f} s per "
          "iteration)"] for r in done],
    )  # fmt: skip
    missing = "".join(f"- experiment {r['experiment']}: not run yet\n" for r in rows if not r["iterations_done"])
    curves = "\n".join(
        f"- experiment {r['experiment']}: best so far every 20 iterations: "
        + ", ".join(f"{v:.2f}" for v in r["best_so_far"][::20])
        + f", final {r['best_so_far'][-1]:.2f}"
        for r in done
    )
    parameters = "\n".join(
        f"Experiment {r['experiment']}, best parameters (the optimizer's [0, 1] vector: "
        + ", ".join(f"{p:.3f}" for p in r["parameters"])
        + "), as oscillators (1 Hz; a, b: the weights it takes from its input's x and v):\n\n"
        + _parameter_table(r)
        for r in done
    )
    checks, evaluation = [], ""
    drop: dict[str, float] | None = None
    if not args.no_check and done:
        ran = compare_with_trot(done, args.episodes, output)
        evaluation = (
            "\n## Against the reference trot (`evaluate.py`, `results/bioloid_cpg_vs_trot.md`)\n\n"
            f"    {ran}\n\n" + output.file("bioloid_cpg_vs_trot.md").read_text().split("\n", 1)[1]
        )
        for r in done:
            policy = best_policy(output, r["experiment"])
            frames = output.file(f"bioloid_cpg_experiment{r['experiment']}_frames.png")
            result = check(policy, frames)
            r["check"] = result
            checks.append(markdown(result, f"Experiment {r['experiment']}'s best policy"))
        drop = drop_rebound()
        checks.insert(0, f"The contacts are not elastic: the robot dropped {drop['height'] * 100:.0f} cm in its ready "
                         f"posture sinks {drop['sink_below_rest'] * 1000:.1f} mm below where it comes to rest and "
                         f"rebounds {drop['rebound_above_rest'] * 1000:.1f} mm above it.\n")  # fmt: skip
    md = (
        "# CPG experiments 5 and 6 of [bioloid-webots], PSO at its scale\n\n"
        "50 particles x 240 iterations x 32 s each (107 h simulated per run), the report's PSO (decreasing inertia, "
        "geometric neighbourhood), eq. 17 maximized as the report did, on both cores of this machine (the swarm as one "
        "batch); the report's best scores over its six experiments: 7-17.\n\n" + table + missing + "\n" + curves
        + "\n\nCommands (each resumes its run when run again):\n\n" + "\n".join(f"    {r['command']}" for r in rows)
        + "\n\nThe best policies: "
        + ", ".join(f"`evaluate.py --policy cpg:{_shown(best_policy(output, r['experiment']))}`" for r in done)
        + ".\n\n" + parameters
        + evaluation
        + ("\n## Is the gait physical? (`benchmarks/bioloid_cpg_check.py`)\n\n" + "\n".join(checks) if checks else "")
    )  # fmt: skip
    output.save({"rows": rows, "drop": drop if checks else None}, md)


if __name__ == "__main__":
    main()
