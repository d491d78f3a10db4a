"""Seed 002's CPG experiments 5 and 6 with its PSO at its scale (50 particles x 240 iterations x 32 s): the runs'
results, read from their run folders, beside the seed's (best scores 7-17 over its six experiments).

The runs themselves are ``python -m agents.optimize`` (the commands below; each resumes from its checkpoint when run
again); this script summarizes what they have so far: iterations done, the best eq. 17 score and, for that policy,
its signed +x progress and whether it fell, the evaluation's wall time, and the best score per iteration.

Run: ``python -m benchmarks.bioloid_cpg_experiments`` (seconds; the PSO runs take about half an hour each on this
machine, benchmarks/results/bioloid_speed.md).
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.common import RESULTS, md_table, save

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = (5, 6)


def command(e: int) -> str:
    return (f"python -m agents.optimize --config agents/bioloid/optimize/experiment{e}.json --optimizer pso "
            f"--iterations 240 --particles 50 --seed 0 --out runs/optimize/experiment{e}__pso__0")  # fmt: skip


def summary(e: int) -> dict:
    out = ROOT / "runs" / "optimize" / f"experiment{e}__pso__0"
    row: dict = {"experiment": e, "command": command(e), "run_folder": str(out.relative_to(ROOT))}
    if not (out / "history.json").exists():
        return {**row, "iterations_done": 0}
    history = json.loads((out / "history.json").read_text())
    best = json.loads((out / "best.json").read_text())
    curve = [h["best_so_far"] for h in history["history"]]
    row.update({
        "iterations_done": len(curve),
        "best_eq17": best["score"],
        "best_iteration": best["iteration"],
        "best_progress_x": best["metrics"]["progress_x"],
        "best_forward": best["metrics"]["forward"],
        "best_fallen": bool(best["metrics"]["fallen"]),
        "wall_seconds": history["wall_seconds"],
        "best_so_far": curve,
        "parameters": best["parameters"],
    })  # fmt: skip
    (RESULTS / f"bioloid_cpg_experiment{e}_best.json").write_text(json.dumps(best, indent=2) + "\n")
    return row


def main() -> None:
    rows = [summary(e) for e in EXPERIMENTS]
    table = md_table(
        ["experiment", "iterations done", "best eq. 17", "at iteration", "its +x progress (m)", "fell",
         "evaluation wall time"],
        [[r["experiment"], f"{r['iterations_done']} of 240", round(r.get("best_eq17", float("nan")), 2),
          r.get("best_iteration", "-"), round(r.get("best_progress_x", float("nan")), 2),
          r.get("best_fallen", "-"), f"{r.get('wall_seconds', 0) / 60:.0f} min"] for r in rows],
    )  # fmt: skip
    curves = "\n".join(
        f"- experiment {r['experiment']}: best so far every 20 iterations: "
        + ", ".join(f"{v:.2f}" for v in r.get("best_so_far", [])[::20])
        for r in rows
    )
    md = (
        "# Seed 002 CPG experiments 5 and 6, PSO at the seed's scale\n\n"
        "50 particles x 240 iterations x 32 s each (107 h simulated per run), the seed's PSO (decreasing inertia, "
        "geometric neighbourhood), eq. 17 maximized as the seed did; the seed's best scores over its six "
        "experiments: 7-17.\n\n" + table + "\n" + curves + "\n\nCommands (each resumes its run when run again):\n\n"
        + "\n".join(f"    {r['command']}" for r in rows) + "\n\nThe best policies: "
        + ", ".join(f"`evaluate.py --policy cpg:benchmarks/results/bioloid_cpg_experiment{e}_best.json`"
                    for e in EXPERIMENTS) + ".\n"
    )  # fmt: skip
    save("bioloid_cpg_experiments", {"rows": rows}, md)


if __name__ == "__main__":
    main()
