"""Tune a controller's parameters by particle swarm or CMA-ES: ``python -m agents.optimize``.

Examples::

    python -m agents.optimize --config agents/bioloid/optimize/experiment5.json --optimizer pso \\
        --iterations 240 --particles 50                       # [bioloid-webots]'s experiment 5 at its scale
    python -m agents.optimize --config ... --backend ray --address HEAD:6379 --workers 50   # split over a cluster

The run folder (``--out``, default ``runs/optimize/<config>__<optimizer>__<seed>`` under the working folder) holds
the checkpoint, the best parameters as a policy file (``best.json``: ``evaluate.py --policy cpg:<run>/best.json``)
and the history. Running the same command again resumes an interrupted run from its last checkpoint (a finished run
just reports, and writes its ``best.json`` again if it was lost). One run at a time writes a run folder: a second one
into it is refused.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import warnings
from pathlib import Path

from agents.optimize.optimizers import OPTIMIZERS
from agents.optimize.problem import ConfigError, read_config
from agents.optimize.run import CHECKPOINT, LOCK, RunError, Settings, run
from envs.common.cluster import ClusterError, check_address
from envs.common.io import (
    ToolParser,
    interrupted_exit_code,
    parent_problem,
    progress_bar_wanted,
    sigterm_as_interrupt,
)

PROG = "python -m agents.optimize"
# one batch holds a simulation per particle (the local backend: all of them in this process): the Bioloid report's
# swarm is 50 [bioloid-webots, sec. VI.B]; twenty times that is far past any population it or CMA-ES's defaults use
MAX_PARTICLES = 1024
MAX_ITERATIONS = 100_000  # the report's PSO runs 240; more than this is a typo, not a run
MAX_THREADS = 1024


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = ToolParser(prog=PROG, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                epilog=__doc__)  # fmt: skip
    p.add_argument("--config", required=True, help="a run configuration (JSON; agents/optimize/problem.py)")
    p.add_argument("--optimizer", choices=sorted(OPTIMIZERS), default="pso")
    p.add_argument("--iterations", type=int, default=240, help="iterations ([bioloid-webots]'s PSO: 240)")
    p.add_argument("--particles", type=int, default=50, help="swarm or population size (the report: 50)")
    p.add_argument("--workers", type=int, default=None,
                   help="local: the batch's threads (default: the machine's cores); ray: the batches the swarm is "
                        "split into, one actor each (default: 2)")  # fmt: skip
    p.add_argument("--backend", choices=("local", "ray"), default="local")
    p.add_argument("--address", default=None, help="ray: the cluster's address (default: start a local instance)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None,
                   help="run folder (default runs/optimize/<config>__<opt>__<seed> in the working folder)")  # fmt: skip
    p.add_argument("--stop-after", type=int, default=None,
                   help="run at most this many iterations now, then stop (the same command resumes)")  # fmt: skip
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar: a line of progress a minute instead (as when the output is not a terminal)",
    )
    return p.parse_args(argv)


MAX_SEED = 2**32 - 1  # CMA-ES seeds numpy's RandomState, which takes [0, 2**32)


def check(args: argparse.Namespace) -> None:
    """One-line errors for settings that cannot run, before anything is created."""
    if not 0 <= args.seed <= MAX_SEED:
        raise RunError(f"--seed must be in [0, {MAX_SEED}], got {args.seed}")
    if not 1 <= args.iterations <= MAX_ITERATIONS:
        raise RunError(f"--iterations must be in [1, {MAX_ITERATIONS}], got {args.iterations}")
    if not 2 <= args.particles <= MAX_PARTICLES:
        raise RunError(f"--particles must be in [2, {MAX_PARTICLES}] (one simulation each), got {args.particles}")
    if args.workers is not None and not 1 <= args.workers <= (args.particles if args.backend == "ray" else MAX_THREADS):
        most = args.particles if args.backend == "ray" else MAX_THREADS
        raise RunError(f"--workers must be in [1, {most}] for the {args.backend} backend, got {args.workers}")
    if args.stop_after is not None and not 1 <= args.stop_after <= MAX_ITERATIONS:
        raise RunError(f"--stop-after must be in [1, {MAX_ITERATIONS}], got {args.stop_after}")
    if args.address is not None and args.backend != "ray":
        raise RunError("--address is for --backend ray")
    if args.address is not None:
        try:
            check_address(args.address)
        except ClusterError as exc:
            raise RunError(str(exc)) from None
    problem = parent_problem(args.out / CHECKPOINT)  # the run folder's own file: can it be made?
    if problem:
        raise RunError(f"--out {args.out}: {problem}; choose another folder")
    if (
        args.out.exists() and not (args.out / CHECKPOINT).exists() and any(f.name != LOCK for f in args.out.iterdir())
    ):  # (a run stopped before its first checkpoint leaves its lock file alone)
        raise RunError(f"--out {args.out} holds files but no checkpoint; choose another folder")


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FutureWarning)
            config = read_config(args.config)
        for warning in caught:  # a deprecated name: one line, as the errors are
            print(f"{PROG}: warning: {warning.message}", file=sys.stderr)
        if args.out is None:  # relative to the working folder, as every other path on the command line
            args.out = Path("runs") / "optimize" / f"{Path(args.config).stem}__{args.optimizer}__{args.seed}"
        check(args)  # a bad env_kwargs or controller fails when the backend builds them, before anything is written
        settings = Settings(config.to_dict(), args.optimizer, args.iterations, args.particles, args.seed)

        def backend():
            from agents.optimize.run import LocalBackend, RayBackend

            if args.backend == "ray":
                return RayBackend(config, args.particles, args.workers or 2, args.address)
            return LocalBackend(config, args.particles, args.workers)

        command = f"{PROG} " + " ".join(shlex.quote(a) for a in (argv or sys.argv[1:]))
        progress = progress_bar_wanted(args.no_progress)
        with sigterm_as_interrupt():  # SIGTERM as Ctrl-C: the checkpoint of the last whole iteration stays
            result = run(config, settings, args.out, backend, progress=progress, command=command,
                         stop_after=args.stop_after)  # fmt: skip
    except (ConfigError, RunError, ClusterError) as error:
        print(f"{PROG}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        kept = "its last checkpoint is kept" if (args.out / CHECKPOINT).exists() else "no iteration was finished"
        print(f"\n{PROG}: interrupted; {kept} in {args.out}: run the same command again to resume", file=sys.stderr)
        return interrupted_exit_code(exc)
    best = result["best"]
    if best is None:
        print("no iteration run")
        return 0
    m = {"distance_travelled": best["metrics"].get("eq17", math.nan), **best["metrics"]}  # (runs before the rename)
    status = "" if result["finished"] else f"; stopped at iteration {len(result['history'])}: run again to resume"
    print(f"best {config.objective} = {best['score']:.4f} (iteration {best['iteration']}): distance travelled "
          f"{m['distance_travelled']:.3f} m, +x progress {m['progress_x']:.3f} m, fallen {int(m['fallen'])}; "
          f"{result['wall_seconds']:.1f} s of evaluation; policy {args.out / 'best.json'}{status}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
