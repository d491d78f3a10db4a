"""The held-out test's leave-a-fold-out refits, recorded for one synthetic calibration case (docs/calibration.md,
"a jackknife over the held-out folds").

For every candidate that reaches the held-out test it prints, as one JSON line: the full fit's values and 95%
intervals, each fold's refit (the others' segments, searched locally from the full fit, as the test does), a
reference refit the same way on all the decision segments, the test's verdict, and the delete-a-group jackknife's
bias-corrected estimate and t (bias over the folds' own standard error) against the full fit and against the
reference. The loop's decisions are the loop's own: the recording wraps ``sysid.select._held_out_test`` and changes
nothing it returns.

Run: ``python -m benchmarks.calibration_folds --robot roach --effect disturbance --seed 3`` (2-6 min a case).
"""

from __future__ import annotations

import json
import math

import numpy as np

import sysid.select as select
from envs.common.io import ToolParser
from sysid.cases import run_case


def jackknife(reference: float, refits: np.ndarray) -> tuple[float, float]:
    """Equal folds: the bias-corrected estimate ``g theta - (g - 1) mean(theta_(j))`` and |bias| / jackknife SE."""
    g = len(refits)
    corrected = g * reference - (g - 1) * float(refits.mean())
    se = math.sqrt((g - 1) / g * float(np.sum(np.square(refits - refits.mean()))))
    bias = abs(reference - corrected)
    return corrected, (bias / se if se > 0 else (0.0 if bias == 0 else math.inf))


CONFIGURATIONS: dict[str, list[str]] = {}
"""None kept in benchmarks/results/: this prints its records (JSON lines) and writes no file."""


def main(argv: list[str] | None = None) -> int:
    p = ToolParser(description=__doc__)
    p.add_argument("--robot", required=True)
    p.add_argument("--effect", required=True, help="an effect the generator can inject (sysid.synth --list)")
    p.add_argument("--seed", type=int, required=True)
    args = p.parse_args(argv)
    original_test, original_fit = select._held_out_test, select.fit

    def recorded(problem, current, effects, nuisance, fitting, folds, trial):
        params = {k: q for e in effects for k, q in select._params(e).items()}
        refits: list[dict[str, float]] = []

        def fit(*a, **kw):
            result = original_fit(*a, **kw)
            refits.append({k: result.values[k] for k in params})
            return result

        select.fit = fit
        try:
            verdict = original_test(problem, current, effects, nuisance, fitting, folds, trial)
        finally:
            select.fit = original_fit
        segments = list(fitting if fitting is not None else problem.scored)
        reference = original_fit(problem, current, {**params, **nuisance}, segments, start=trial.values, local=True,
                                 intervals=False)  # fmt: skip
        row = {"effects": [e.name for e in effects], "verdict": verdict, "params": {}}
        for k in params:
            values = np.array([r[k] for r in refits])
            full, ref = trial.values[k], reference.values[k]
            row["params"][k] = {
                "full": full, "ci95": trial.bounds95.get(k), "refits": values.tolist(), "reference": ref,
                "against_full": dict(zip(("corrected", "t"), jackknife(full, values), strict=True)),
                "against_reference": dict(zip(("corrected", "t"), jackknife(ref, values), strict=True)),
            }  # fmt: skip
        print(json.dumps(row), flush=True)
        return verdict

    select._held_out_test = recorded
    try:
        case = run_case(args.robot, {args.effect: None}, args.seed, say=print)
    finally:
        select._held_out_test = original_test
    print(json.dumps({"first": case.first, "truth": case.injected, "before": case.result.before.error,
                      "after": case.result.after.error}))  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
