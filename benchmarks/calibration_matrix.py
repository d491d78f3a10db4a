"""The calibration loop on synthetic data, every robot and every catalogued effect.

For each robot and each catalogued effect its channels observe, a case (sysid/cases.py): a 10 s training log with the
effect at a value the generator draws with the seed, a test log of the same truth under other commands; calibrate on
the one and judge on the other: is the first pick in the injected effect's alias group, is the value recovered
(within the larger of twice the reported half-width and 5% of the range), does the held-out error's excess over the
noise floor at least halve. Each robot runs SEEDS such cases (``--seeds``, default 20): every observable effect at the
first draw, then again at the next draws (effect k of the catalog at draw d: seed 1000 d + k + 1) until SEEDS cases,
so that every effect is judged at one random value or more, and the coverage of the reported 95% intervals is
measured over those SEEDS cases (goal: >= 80%), pooled over the robot's effects. Effects a robot declares weak on
its channels (``Effect.weak``) are not drawn: each is set at the far end of its range and the nominal model's error
checked to stay under the generator's threshold of 3, measured as the generator measures it (against the true and the
nominal model's replay floors, on the robot's recording protocol): the declaration held to the data. Then, per robot,
the null case (noise only: nothing should be chosen), the out-of-catalog cases (a periodic disturbance torque, and for
the roach a terrain bump: the report should say "unexplained").

Not in the default matrix (``--kinds coverage``): the coverage over SEEDS seeds of one effect at a time (seeds
100, 101, ...; the effects in COVERAGE): each effect's interval coverage over many values of it.

Not in the default matrix (``--kinds pairs``, ``--pairs N``): cases with two hidden effects of different alias
groups at once, drawn with seed PAIR_SEED + k: is an effect kept from each one's group and nothing else, is each
recovered where it was the one kept, does the held-out excess halve.

Every case that ran is reported; a budget (``--minutes``, default 45) stops new cases from starting, and the cases
left out are listed as not run, never counted as passes.

Run: ``python -m benchmarks.calibration_matrix [--robots motor servo roach] [--seeds 20] [--minutes 45]``; a part
of it: ``--kinds null ooc --robots roach`` (written to ``--out FOLDER`` or a folder named by its options,
benchmarks/common.py). The cases are independent: ``--workers K`` runs K at a time as Ray tasks, each with its share
of the machine's cores (a local Ray instance), or, with ``--address HEAD:PORT``, on a running Ray cluster whose nodes
hold this checkout at the same path (one core per case there unless ``--threads`` says more). Same seeds, same cases:
a case's result does not depend on where it ran.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Iterator, Mapping
from pathlib import Path

import mujoco
import numpy as np

from benchmarks.common import Output, add_output_options, md_table, resolve_output
from envs.common.batch import THREADS_VARIABLE, default_threads
from envs.common.cluster import ClusterError, check_address, ensure_ray
from envs.common.io import ToolParser
from sysid import synth
from sysid.cases import Case, run_case
from sysid.report import format_interval
from sysid.robots import adapter as make_adapter
from sysid.robots import adapters

COVERAGE = {"motor": ["viscous_friction", "delay"], "servo": ["delay", "servo_gain"],
            "roach": ["viscous_friction_left"], "xjus": ["viscous_friction_left"],
            "bioloid": ["servo_gain"]}  # fmt: skip
# the order in which cases start (longest kinds first, so that no long case starts near the end and sets the wall
# time; the report keeps the plan's order)
START_ORDER = ("ooc", "pairs", "effect", "coverage", "null", "weak")
COVERAGE_GOAL = 0.8  # the goal: the reported 95% intervals cover the truth at least this often
PAIR_SEED = 500  # pair k of a robot: its two effects and their values drawn with seed PAIR_SEED + k
OUT_OF_CATALOG = {"motor": ["disturbance"], "servo": ["disturbance"], "roach": ["disturbance", "terrain_bump"],
                  "xjus": ["disturbance", "terrain_bump"], "bioloid": ["disturbance", "terrain_bump"]}  # fmt: skip


def _safe_case(robot: str, effects: Mapping, seed: int) -> tuple[Case | None, str]:
    try:
        return run_case(robot, effects, seed), ""
    except ValueError as exc:  # the generator cannot make the effect visible: reported, not hidden
        return None, str(exc)


Job = tuple[str, str, str | None, int]  # (kind, robot, effect, seed)


def run_job(job: Job) -> tuple[dict, str]:
    """One case of the matrix: its result row and the line printed for it."""
    kind, robot, name, seed = job
    if kind == "weak":  # the declaration that the channels barely see it, held to the data
        row = _weak(robot, name)
        return row, (f"{robot:6s} weak     {name:28s} nominal error at the range's far end "
                     f"{row['nominal_error']:.2f}")  # fmt: skip
    effects = {} if kind == "null" else dict.fromkeys(name.split("+")) if kind == "pairs" else {name: None}
    case, error = _safe_case(robot, effects, seed)
    tag = f"{robot:6s} {kind:8s} {name or '-':28s} seed {seed:3d}"
    if case is None:
        return {"robot": robot, "effect": name, "seed": seed, "error": error}, f"{tag} could not be generated: {error}"
    return {"kind": kind, "effect": name, **case.row()}, (
        f"{tag} first {case.first} before {case.result.before.error:.2f} after {case.result.after.error:.2f}"
        f" ({case.seconds:.0f} s)"
    )


def _run_in(job: Job, threads: int) -> tuple[dict, str]:
    """``run_job`` in a process that shares the machine: its rollouts on ``threads`` threads."""
    os.environ[THREADS_VARIABLE] = str(threads)
    return run_job(job)


def _serial(plan: list[Job], left) -> Iterator[tuple[Job, dict | None, str]]:
    for job in plan:
        if not left():
            yield job, None, ""
            continue
        row, line = run_job(job)
        yield job, row, line


def _on_ray(plan: list[Job], left, workers: int, threads: int, address: str | None):
    """The plan as Ray tasks, at most ``workers`` at a time; no task is submitted after the budget. Yields each job
    with its row as it finishes (None: not run)."""
    root = str(Path(__file__).resolve().parent.parent)
    ray = ensure_ray(address, num_cpus=None if address else workers * threads,
                     runtime_env={"env_vars": {"PYTHONPATH": root}})  # fmt: skip
    task = ray.remote(num_cpus=threads)(_run_in)
    queue, running = list(plan), {}
    try:
        while queue or running:
            while queue and len(running) < workers and left():
                job = queue.pop(0)
                running[task.remote(job, threads)] = job
            if not running:  # the budget is spent: the rest is not run
                for job in queue:
                    yield job, None, ""
                return
            done, _ = ray.wait(list(running), num_returns=1)
            job = running.pop(done[0])
            row, line = ray.get(done[0])
            yield job, row, line
    finally:
        for ref in running:
            ray.cancel(ref, force=True)
        if address is None:
            ray.shutdown()


_EACH_ONCE = ["--seeds", "1", "--coverage-seeds", *map(str, range(100, 120))]  # one case per effect, 20 coverage seeds
_ALL_KINDS = ["--kinds", "effect", "weak", "null", "ooc", "coverage"]
CONFIGURATIONS: dict[str, list[str]] = {
    "calibration_matrix_roach_motor_servo": ["--robots", "roach", "motor", "servo"],
    "calibration_matrix_roach_motor_servo_coverage": ["--robots", "roach", "motor", "servo", *_ALL_KINDS, *_EACH_ONCE],
    "calibration_matrix_motor_servo": ["--robots", "motor", "servo", *_ALL_KINDS, "pairs", *_EACH_ONCE],
    "calibration_matrix_motor_servo_bioloid_draw1": ["--robots", "motor", "servo", "bioloid", "--kinds", "effect",
                                                     "--draw", "1", "--seeds", "1"],
    "calibration_matrix_bioloid": ["--robots", "bioloid", *_ALL_KINDS, "pairs", "--pairs", "4", *_EACH_ONCE],
    "calibration_matrix_xjus": ["--robots", "xjus", *_ALL_KINDS, *_EACH_ONCE],
    "calibration_matrix_xjus_draw1": ["--robots", "xjus", "--kinds", "effect", "--draw", "1", "--seeds", "1"],
    "calibration_matrix_xjus_draw1_com": ["--robots", "xjus", "--kinds", "effect", "--draw", "1", "--seeds", "1",
                                          "--effects", "com_offset"],
    "calibration_matrix_roach_draw1": ["--robots", "roach", "--kinds", "effect", "--draw", "1", "--seeds", "1"],
    "calibration_matrix_roach_draw1_rest": ["--robots", "roach", "--kinds", "effect", "--draw", "1", "--seeds", "1",
                                            "--effects", "torque_constant_right", "sensor_bias_bemf_right"],
    "calibration_matrix_roach_drive": ["--robots", "roach", "--kinds", "effect", "weak", "--seeds", "4", "--effects",
                                       "gearbox_efficiency_left", "gearbox_efficiency_right", "sensor_gain_bemf_left",
                                       "sensor_gain_bemf_right", "sensor_coupling_bemf_left",
                                       "sensor_coupling_bemf_right"],
    "calibration_matrix_roach_leg_phase": ["--robots", "roach", "--kinds", "effect", "weak", "--seeds", "2",
                                           "--effects", "leg_phase_left", "leg_phase_right"],
    "calibration_matrix_roach_periodic_load": ["--robots", "roach", "--kinds", "effect", "weak", "--seeds", "2",
                                               "--effects", "periodic_load_left", "periodic_load_right"],
    "calibration_matrix_roach_running_offset": ["--robots", "roach", "--kinds", "effect", "weak", "--seeds", "2",
                                                "--effects", "sensor_running_offset_bemf_left",
                                                "sensor_running_offset_bemf_right"],
    "calibration_matrix_servo": ["--robots", "servo"],
}  # fmt: skip
"""The configurations whose results benchmarks/results/ keeps: name -> arguments (benchmarks/common.py). The budget,
workers, threads and cluster address say how a matrix runs, not what it measures (a case cut by the budget is listed
as not run)."""
RUN_OPTIONS = ("minutes", "workers", "threads", "address")


def make_parser() -> argparse.ArgumentParser:
    p = ToolParser(description=__doc__)
    p.add_argument("--robots", nargs="+", default=sorted(adapters()), help="default: every robot with an adapter")
    p.add_argument("--seeds", type=int, default=20, help="effect cases per robot (every observable effect, then "
                   "again at the next draws; coverage pooled over them), and the seeds of --kinds coverage "
                   "(100, 101, ...)")  # fmt: skip
    p.add_argument("--coverage-seeds", type=int, nargs="+", metavar="SEED",
                   help="these coverage seeds instead (to rerun a few)")  # fmt: skip
    p.add_argument("--minutes", type=float, default=45.0, help="no case starts after this budget")
    p.add_argument("--kinds", nargs="+", default=["effect", "weak", "null", "ooc"],
                   choices=["effect", "weak", "null", "ooc", "coverage", "pairs"],
                   help="which cases to run (not in the default matrix: coverage, over seeds of one effect at a "
                   "time; pairs, two effects at once)")  # fmt: skip
    p.add_argument("--pairs", type=int, default=6, help="pairs of effects per robot (kind pairs)")
    p.add_argument("--effects", nargs="+", help="only these effects (default: every catalogued one)")
    p.add_argument("--draw", type=int, default=0, help="the effect cases' first draw: effect k of a catalog takes "
                   "seed 1000 DRAW + k + 1, and the cases past the catalog's length the next draws (default 0: the "
                   "seeds reported in docs/calibration.md); another draw checks the loop on values nobody has "
                   "looked at")  # fmt: skip
    p.add_argument("--workers", type=int, default=1, help="cases run at a time, as Ray tasks (default 1: in turn)")
    p.add_argument("--threads", type=int, help="rollout threads per case (default: the cores shared by the workers "
                   "locally, 1 on a cluster)")  # fmt: skip
    p.add_argument("--address", help="a running Ray cluster (HEAD:PORT) to run the cases on")
    add_output_options(p)
    return p


def main(argv: list[str] | None = None) -> int:
    p = make_parser()
    args = p.parse_args(argv)
    for flag in ("workers", "threads", "seeds", "pairs"):
        value = getattr(args, flag)
        if value is not None and value < 1:
            p.error(f"--{flag} {value}: expected at least 1")
    if args.draw < 0:
        p.error(f"--draw {args.draw}: expected 0 or more")
    if args.coverage_seeds and min(args.coverage_seeds) < 0:
        p.error(f"--coverage-seeds {min(args.coverage_seeds)}: seeds are non-negative")
    if not args.minutes > 0:
        p.error(f"--minutes {args.minutes:g}: expected a positive budget")
    unknown = sorted(set(args.robots) - set(adapters()))
    if unknown:
        p.error(f"--robots {unknown[0]!r}: no calibration adapter (known: {', '.join(sorted(adapters()))})")
    if args.address:
        try:
            check_address(args.address)
        except ClusterError as exc:
            p.error(str(exc))
    output = resolve_output(p, args, "calibration_matrix", CONFIGURATIONS, run_options=RUN_OPTIONS)
    threads = args.threads or (1 if args.address else max(1, default_threads() // args.workers))
    start = time.perf_counter()

    def left() -> bool:
        return (time.perf_counter() - start) / 60 < args.minutes

    plan: list[Job] = []
    models = {}
    for robot in args.robots:
        adapter = make_adapter(robot)
        models[robot] = adapter.nominal_robot.model
        catalogued = list(adapter.catalog())
        observable = [name for name in catalogued if adapter.effects()[name].observable]
        plan += [("effect", robot, name, seed) for name, seed in effect_cases(catalogued, observable, args)]
        plan += [("weak", robot, name, 0) for name in catalogued if name not in observable]
        plan += [("null", robot, None, 2)]
        plan += [("ooc", robot, name, 3) for name in OUT_OF_CATALOG.get(robot, [])]
        seeds = args.coverage_seeds or [100 + s for s in range(args.seeds)]
        plan += [("coverage", robot, name, s) for name in COVERAGE.get(robot, []) for s in seeds]
        plan += [("pairs", robot, "+".join(pair), PAIR_SEED + k)
                 for k, pair in enumerate(pairs(adapter, observable, args.pairs))]  # fmt: skip
    plan = [c for c in plan if c[0] in args.kinds
            and (args.effects is None or c[0] == "null" or set(c[2].split("+")) <= set(args.effects))]  # fmt: skip
    parallel = args.workers > 1 or args.address
    host = host_speed(models)
    schedule = sorted(plan, key=lambda job: START_ORDER.index(job[0]))
    results = _on_ray(schedule, left, args.workers, threads, args.address) if parallel else _serial(schedule, left)
    done: dict[Job, dict] = {}
    not_run: list[Job] = []
    for job, row, line in results:
        if row is None:
            not_run.append(job)
            continue
        print(line, flush=True)
        done[job] = row
        # the results so far, after every case: a run cut short keeps what it measured (marked partial)
        report(args, output, (time.perf_counter() - start) / 60, plan, done, [j for j in plan if j not in done],
               partial=True, host=host)  # fmt: skip
    report(args, output, (time.perf_counter() - start) / 60, plan, done, not_run, workers=args.workers,
           threads=threads, host=host)  # fmt: skip
    return 0


WEAK_SEEDS = (0, 1, 2)


def effect_cases(catalogued: list[str], observable: list[str], args) -> list[tuple[str, int]]:
    """A robot's effect cases, (effect, seed): ``args.seeds`` of them (at least one per effect), the observable
    effects (those of ``args.effects`` if given) in catalog order at draw ``args.draw``, then again at the next
    draws; effect k of the catalog at draw d takes seed 1000 d + k + 1, whatever else is run beside it."""
    names = [n for n in observable if args.effects is None or n in args.effects]
    cases = []
    for j in range(max(args.seeds, len(names)) if names else 0):
        draw, k = divmod(j, len(names))
        cases.append((names[k], 1000 * (args.draw + draw) + 1 + catalogued.index(names[k])))
    return cases


def pairs(adapter, observable: list[str], count: int) -> list[tuple[str, str]]:
    """``count`` pairs of a robot's observable effects from two different alias groups (the data could not tell
    two of one group apart), drawn with seed PAIR_SEED: every pair once before any repeats, in a seeded order."""
    effects = adapter.effects()
    every = [(a, b) for i, a in enumerate(observable) for b in observable[i + 1 :]
             if effects[a].alias != effects[b].alias]  # fmt: skip
    order = np.random.default_rng(PAIR_SEED).permutation(len(every))
    return [every[int(k)] for k in order[:count]]


def host_speed(models: Mapping[str, mujoco.MjModel], steps: int = 4000) -> dict[str, float]:
    """Microseconds per raw ``mj_step`` of each robot's nominal model (robot -> model) from its rest state, on
    this process's core, measured once before the cases start: the host's speed, against which the matrix's wall
    time reads (it has varied by about three times between days on the project's shared machine)."""
    out = {}
    for robot, model in models.items():
        data = mujoco.MjData(model)
        tic = time.perf_counter()
        mujoco.mj_step(model, data, steps)
        out[robot] = (time.perf_counter() - tic) / steps * 1e6
    return out


def report(args, output: Output, minutes: float, plan: list[Job], done: Mapping[Job, dict], not_run: list[Job],
           partial=False, workers: int = 1, threads: int | None = None,
           host: Mapping[str, float] | None = None) -> None:  # fmt: skip
    """Write the matrix's results (``output``: <name>.md and .json): every case run so far, in the plan's
    order, and the cases not run (``partial``: still to come, in a run under way or cut short)."""
    rows, null_rows, ooc_rows, coverage_rows, weak_rows, pair_rows = [], [], [], [], [], []
    for job in plan:
        if job in done:
            {"effect": rows, "null": null_rows, "ooc": ooc_rows, "coverage": coverage_rows,
             "weak": weak_rows, "pairs": pair_rows}[job[0]].append(done[job])  # fmt: skip
    not_run = [f"{k} {r} {n or ''} seed {s}" for k, r, n, s in not_run]
    pair_section = _pairs_section(args, pair_rows)
    state = "**partial: the run was still going or was cut short**; " if partial else ""
    how = f" ({workers} cases at a time, {threads} rollout threads each)" if workers > 1 else ""
    md = [f"# Calibration matrix\n\n{state}{minutes:.1f} min on this machine{how}; budget {args.minutes:g} min.\n"]
    if host:
        speeds = ", ".join(f"{robot} {us:.1f}" for robot, us in host.items())
        md.append(f"\nThe host's speed before the run (us per raw physics step of each nominal model): {speeds}.\n")
    if done:
        md.append(f"\n{_time_spent(plan, done)}\n")
    ok = [r for r in rows if "error" not in r]
    md.append(
        "\n## Each catalogued effect, drawn by the generator (effect k of a robot's catalog at draw d: seed "
        f"1000 d + k + 1, from draw {args.draw}; {args.seeds} cases per robot)\n\n"
    )
    md.append(md_table(
        ["robot", "effect", "seed", "truth", "first pick", "alias ok", "estimate +- 95%", "recovered", "before",
         "after", "excess after/before", "halved", "s"],
        [[r["robot"], r["effect"], r["seed"], _values(r, 0), r["first"] or "none", _yn(r["first_in_alias_group"]),
          _values(r, 1), _yn(r["recovered"]), r["error_before"], r["error_after"], r["excess_ratio"],
          _yn(r["halved"]), round(r["seconds"])] for r in ok]
        + [[r["robot"], r["effect"], r["seed"], "-", "not generated: " + r["error"], "", "", "", "", "", "", "", ""]
           for r in rows if "error" in r],
    ))  # fmt: skip
    for robot in args.robots:
        mine = [r for r in ok if r["robot"] == robot]
        if mine:
            md.append(f"\n{robot}: alias group right in {sum(r['first_in_alias_group'] for r in mine)}/{len(mine)}, "
                      f"value recovered in {sum(r['recovered'] for r in mine)}/{len(mine)}, excess halved in "
                      f"{sum(r['halved'] for r in mine)}/{len(mine)}, over {len(set(r['effect'] for r in mine))} "
                      "effects.")  # fmt: skip
            failed = [f"{r['effect']} (seed {r['seed']})" for r in mine
                      if not (r["first_in_alias_group"] and r["recovered"] and r["halved"])]  # fmt: skip
            md.append(f" Not all three in: {', '.join(failed)}.\n" if failed else " Every case all three.\n")
    if weak_rows:
        md.append(
            "\n## Effects declared weak on a robot's channels (`Effect.weak`)\n\nEach set at the far end of its "
            "range (the bound farther from nominal; a phase at the strongest of its quarter and half turns); the "
            "declaration holds if the nominal model's error on its "
            "synthetic log stays under 3 noise levels (the generator's threshold for a visible effect).\n\n"
        )
        md.append(md_table(["robot", "effect", "value", "nominal error (median)", f"on seeds {WEAK_SEEDS}",
                            "declaration holds", "why weak"],
                           [[r["robot"], r["effect"], r["value"], r["nominal_error"],
                             ", ".join(f"{e:.2f}" for e in r["errors"]), _yn(r["holds"]), r["why"]]
                            for r in weak_rows]))  # fmt: skip
    md.append("\n## Null (noise only) and out of catalog\n\n")
    md.append(md_table(
        ["robot", "case", "chosen", "before", "after", "unexplained", "as expected"],
        [[r["robot"], "null", ", ".join(r["chosen"]) or "none", r["error_before"], r["error_after"],
          _yn(r["unexplained"]), _yn(not r["chosen"] and r["error_after"] < r["threshold"])] for r in null_rows
         if "error" not in r]
        + [[r["robot"], r["effect"], ", ".join(r["chosen"]) or "none", r["error_before"], r["error_after"],
            _yn(r["unexplained"]), _yn(r["unexplained"] and r["excess_ratio"] > 0.5)] for r in ooc_rows
           if "error" not in r]
        + [[r["robot"], r["effect"] or "null", f"not generated at seed {r['seed']}: {r['error']}", "", "", "",
            "not run"] for r in null_rows + ooc_rows if "error" in r],
    ))  # fmt: skip
    goal = f"goal >= {COVERAGE_GOAL:.0%}"
    pooled = []
    for robot in args.robots:
        mine = [r for r in ok if r["robot"] == robot]
        if mine:
            hits = [r for r in mine if _covers(r)]
            share = len(hits) / len(mine)
            misses = [f"{r['effect']} (seed {r['seed']})" for r in mine if r not in hits]
            pooled.append([robot, len(mine), len({r["effect"] for r in mine}),
                           sum(r["first"] == r["effect"] for r in mine), len(hits), share,
                           _goal(share), ", ".join(misses) or "-"])  # fmt: skip
    if pooled:  # (a run without effect cases has no pooled coverage to show)
        md.append(
            f"\n## Coverage of the 95% intervals over each robot's effect cases ({goal})\n\nPooled over the "
            "robot's effects: a case counts as covered if its first pick is the injected effect and every "
            "parameter's interval holds the truth.\n\n"
        )
        md.append(md_table(["robot", "cases", "effects", "effect picked", "intervals cover truth", "coverage",
                            "goal", "not covered"], pooled))  # fmt: skip
    if coverage_rows:
        md.append(f"\n## Coverage over {args.seeds} seeds of one effect (`--kinds coverage`; {goal})\n\n")
        cov_table = []
        for robot in args.robots:
            for name in COVERAGE.get(robot, []):
                mine = [r for r in coverage_rows if r["robot"] == robot and r["effect"] == name and "error" not in r]
                if mine:
                    hits = sum(_covers(r) for r in mine)
                    share = hits / len(mine)
                    cov_table.append([robot, name, len(mine), sum(r["first"] == name for r in mine), hits, share,
                                      _goal(share)])  # fmt: skip
        md.append(md_table(["robot", "effect", "cases run", "effect picked", "interval covers truth", "coverage",
                            "goal"], cov_table))  # fmt: skip
        md.append("\n(coverage counts a case whose first pick was another effect as not covered)\n")
    md += pair_section
    if not_run:
        title = "Not run yet" if partial else "Not run within the budget"
        md.append(f"\n## {title} ({len(not_run)} cases)\n\n" + "\n".join(f"- {x}" for x in not_run))
        md.append("\n")
    output.save({"minutes": minutes, "budget_minutes": args.minutes, "workers": workers, "threads": threads,
                     "host_us_per_step": dict(host or {}), "seeds": args.seeds, "draw": args.draw,
                     "effects": rows, "null": null_rows, "out_of_catalog": ooc_rows, "coverage": coverage_rows,
                     "weak": weak_rows, "pairs": pair_rows, "partial": partial, "not_run": not_run},
         "".join(md), echo=not partial)  # fmt: skip


def _pairs_section(args, pair_rows: list[dict]) -> list[str]:
    """The two-effect cases: is an effect kept from each injected effect's alias group and nothing else, is each
    injected effect's value recovered and covered where it was the one kept, does the held-out excess halve."""
    if not pair_rows:
        return []
    md = ["\n## Two effects at once (`--kinds pairs`: two effects of different alias groups, drawn with seed "
          f"{PAIR_SEED} + k)\n\n"]  # fmt: skip
    table = []
    for r in pair_rows:
        if "error" in r:
            table.append([r["robot"], r["seed"], r["effect"], "not generated: " + r["error"], *[""] * 8])
            continue
        truth = "; ".join(f"{n} {' '.join(f'{v:.3g}' for v in vals.values())}" for n, vals in r["injected"].items())
        found = list(r["found"].values())
        estimates = "; ".join(
            f"{n} " + ", ".join(f"{got:.3g} {format_interval(got, *f['intervals'][k])}"
                                for k, (_, got, _) in f["values"].items())
            for n, f in r["found"].items() if f["values"]
        )  # fmt: skip
        table.append([r["robot"], r["seed"], truth, ", ".join(r["chosen"]) or "none", _yn(r["all_found"]),
                      estimates or "-", _yn(all(f["recovered"] for f in found)),
                      _yn(all(all(f["covered"].values()) and f["covered"] for f in found)), r["error_before"],
                      r["error_after"], _yn(r["halved"]), round(r["seconds"])])  # fmt: skip
    md.append(md_table(["robot", "seed", "truth", "chosen", "both found, nothing else", "estimates +- 95%",
                        "both recovered", "both covered", "before", "after", "halved", "s"], table))  # fmt: skip
    for robot in args.robots:
        mine = [r for r in pair_rows if r["robot"] == robot and "error" not in r]
        if mine:
            md.append(f"\n{robot}: both found and nothing else in {sum(r['all_found'] for r in mine)}/{len(mine)}, "
                      f"both recovered in {sum(all(f['recovered'] for f in r['found'].values()) for r in mine)}/"
                      f"{len(mine)}, excess halved in {sum(r['halved'] for r in mine)}/{len(mine)}.\n")  # fmt: skip
    return md


def _weak(robot: str, name: str) -> dict:
    """The nominal model's error on synthetic logs (seeds WEAK_SEEDS; the robot's runs where it records several) with
    a weak effect at the far end of its range (a phase at a quarter turn either way and at half a turn, the
    strongest), against both replay floors as the generator measures it; the declaration holds if the median stays
    under the generator's threshold."""
    adapter = make_adapter(robot)
    effect = adapter.effects()[name]
    runs, seconds = synth.protocol(adapter)
    far = {p.name: p.high if p.high - p.nominal >= p.nominal - p.low else p.low for p in effect.params}
    # a phase (Param.periodic) has no far end: the quarter turns either side of nominal and the half turn, the
    # strongest of them held to the threshold
    turns = [0.25, 0.5, -0.25] if any(p.periodic for p in effect.params) else [None]
    start = time.perf_counter()
    best = None
    for turn in turns:
        values = far if turn is None else {p.name: p.nominal + turn * p.span for p in effect.params}
        errors = [float(synth.record(robot, {name: values}, s, seconds, runs)[1]["nominal_error"]) for s in WEAK_SEEDS]
        if best is None or np.median(errors) > np.median(best[1]):
            best = (values, errors)
    values, errors = best
    median = float(np.median(errors))
    return {"robot": robot, "effect": name, "value": "; ".join(f"{k} {v:g}" for k, v in values.items()),
            "nominal_error": median, "errors": errors, "holds": median < synth.MIN_NOMINAL_ERROR,
            "why": effect.weak, "seconds": time.perf_counter() - start}  # fmt: skip


def _time_spent(plan: list[Job], done: Mapping[Job, dict]) -> str:
    """Where the time went: each case's own wall time (``seconds``), summed per robot and kind, in minutes."""
    minutes: dict[str, dict[str, float]] = {}
    for job in plan:
        if job in done:
            kind, robot = job[0], job[1]
            per = minutes.setdefault(robot, {})
            per[kind] = per.get(kind, 0.0) + done[job].get("seconds", 0.0) / 60
    parts = "; ".join(f"{robot} " + ", ".join(f"{kind} {m:.1f}" for kind, m in kinds.items())
                      for robot, kinds in minutes.items())  # fmt: skip
    total = sum(m for kinds in minutes.values() for m in kinds.values())
    return f"Case-minutes (each case's own wall time, summed): {total:.1f} in all; {parts}."


def _goal(share: float) -> str:
    return "met" if share >= COVERAGE_GOAL else "MISSED"


def _covers(row: dict) -> bool:
    """A case's intervals cover the truth: its first pick is the injected effect (``covered`` is filled only then)
    and every parameter's 95% interval holds the true value."""
    return bool(row["covered"]) and all(row["covered"].values())


def _yn(x: bool) -> str:
    return "yes" if x else "no"


def _values(row: dict, which: int) -> str:
    parts = []
    for name, (true, got, half) in row["values"].items():
        low, high = row.get("intervals", {}).get(name, (got - half, got + half))  # rows of earlier stops: symmetric
        parts.append(f"{name} {true:.3g}" if which == 0 else f"{got:.3g} {format_interval(got, low, high)}")
    if which == 0 and not parts:
        parts = [f"{k} {v:.3g}" for e in row["injected"].values() for k, v in e.items()]
    return "; ".join(parts) or "-"


if __name__ == "__main__":
    raise SystemExit(main())
