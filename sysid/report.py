"""What ``calibrate.py`` writes: ``report.json``, ``report.md``, the residual plots and ``calibration.json``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from envs.common.calibration import calibration_record
from envs.common.effects import Effect
from sysid import diagnostics
from sysid.pipeline import STALL_ADVICE, STALL_SIGN, Result


def _round(x: float, digits: int = 6) -> float:
    return float(f"{x:.{digits}g}") if math.isfinite(x) else x


def _params(
    effect: Effect,
    values: Mapping[str, float],
    ci95: Mapping[str, float],
    bounds95: Mapping[str, tuple[float, float]],
) -> dict[str, dict[str, Any]]:
    """Each parameter's value, its 95% interval as a half-width (``ci95``, the larger side) and as (low, high)
    (``interval95``: one-sided where the data bound the value on one side only), unit, nominal value and range."""
    nan = (math.nan, math.nan)
    return {
        p.name: {
            "value": _round(values[effect.key(p.name)]),
            "ci95": _round(ci95.get(effect.key(p.name), math.nan)),
            "interval95": [_round(x) for x in bounds95.get(effect.key(p.name), nan)],
            "unit": p.unit,
            "nominal": p.nominal,
            "range": [p.low, p.high],
        }
        for p in effect.params
    }


INTERNAL = ("start", "measured")  # a ranking entry's keys for the loop's own use: where each fit starts


def report_dict(result: Result, seconds: float, start: str | None = None) -> dict[str, Any]:
    """The content of report.json."""
    out = result.outcome
    adapter = result.adapter
    chosen = []
    for choice, step in zip(out.chosen, result.steps, strict=True):
        chosen.append(
            {
                "name": choice.effect.name,
                "alias_group": choice.effect.alias,
                "params": _params(choice.effect, choice.values, choice.ci95, choice.bounds95),
                "error_after": _round(step.error, 4),
                "per_channel_after": {k: _round(v, 4) for k, v in step.per_channel.items()},
                "training_error_after": _round(choice.training_error, 4),
                "score": _round(choice.score, 4),
            }
        )
    test_diag = result.diagnostics_after()
    before_diag = diagnostics.diagnose(result.test_problem, result.before.residuals, adapter.context)
    return {
        "robot": adapter.name,
        "train": [log.path for log in result.train],
        "test": [log.path for log in result.test],
        "start": start,
        "error_before": _round(result.before.error, 4),
        "error_after": _round(result.after.error, 4),
        "per_channel": {
            c: {"before": _round(result.before.per_channel[c], 4), "after": _round(result.after.per_channel[c], 4)}
            for c in adapter.channels
        },
        "per_log": {
            log: {"before": _round(result.before.per_log[log], 4), "after": _round(result.after.per_log[log], 4)}
            for log in result.before.per_log
        },
        "mode": out.mode,
        "chosen": chosen,
        "rejected": list(out.rejected),
        "unexplained": result.unexplained,
        "unexplained_reason": result.where(),
        # the held-out error with the span of a stall found after calibration left out (None: no stall)
        "without_stall": _stall_errors(result.without_stall()) if result.unexplained else None,
        # a stall in the training logs, found in the starting model's residual before the fit (None: none)
        "train_stall": _stall_errors(result.train_stall),
        # what the remaining residual points to, and what became of each catalog effect of that kind
        "trace": result.trace() if result.unexplained else None,
        # the effects kept on the training logs leave the held-out error above the starting model's (the nominal
        # one, or the calibration started from), by more than the reported precision
        "worse_on_test": bool(result.after.error > result.before.error * (1.0 + WORSE_BY)),
        "noise": {
            "threshold_unexplained": result.threshold,
            "sigma": result.test_problem.sigma,
            "units": dict(adapter.channels),
        },
        "nuisance": {k: _round(v) for k, v in out.nuisance.items()},
        "ranking": [
            [
                {k: (_round(v, 4) if isinstance(v, float) else v) for k, v in entry.items() if k not in INTERNAL}
                for entry in round_
            ]
            for round_ in out.rounds
        ],
        "diagnostics": {
            "before": before_diag,
            "after": test_diag,
            "findings_before": diagnostics.summarize(before_diag),
            "findings_after": diagnostics.summarize(test_diag),
        },
        "extra": report_extra(adapter, result),
        "segments": {
            "train": len(result.train_problem.scored),
            "test": len(result.test_problem.scored),
            "seconds_each": adapter.segment_seconds,
        },
        "rollouts": result.train_problem.rollouts + result.test_problem.rollouts,
        "wall_seconds": round(seconds, 1),
    }


def calibration_dict(result: Result, report: Mapping[str, Any], base: Mapping[str, Any] | None = None) -> dict:
    """The content of calibration.json: the chosen effects (and those of a starting calibration)."""
    effects: dict[str, dict] = {k: dict(v) for k, v in (base or {}).items()}
    for entry in report["chosen"]:
        effects[entry["name"]] = {p: {k: v[k] for k in ("value", "ci95", "unit")} for p, v in entry["params"].items()}
    provenance = {k: report[k] for k in ("train", "test", "start", "error_before", "error_after", "unexplained")}
    return calibration_record(result.adapter.robot, effects, provenance)


def format_interval(value: float, low: float, high: float) -> str:
    """A 95% interval for reading: +- the half-width where it is symmetric (within 5%), else [low, high]."""
    if math.isfinite(low) and math.isfinite(high) and not math.isclose(value - low, high - value, rel_tol=0.05):
        return f"[{low:.3g}, {high:.3g}]"
    return f"+-{max(value - low, high - value):.2g}"


WORSE_BY = 1e-3  # a relative rise of the held-out error under this is no rise: errors are reported to 3 digits
WORSE = (
    "**The calibrated model is worse on the held-out logs than the {baseline}** ({after:.3g} against "
    "{before:.3g}): what the training logs chose does not carry over to the test logs. calibration.json holds it "
    "as chosen; before using it, calibrate on logs more like those it is meant for."
)


def baseline(report: dict[str, Any]) -> str:
    """What the calibrated model is compared with: the nominal model, or the calibration the run started from."""
    return f"calibration it started from ({report['start']})" if report.get("start") else "nominal model"


def report_extra(adapter, result) -> dict[str, Any]:
    """The adapter's own additions to the report, and what each log measures by itself (``Adapter.measure_log``): its
    records and a section, with the logs too short for it named."""
    from dataclasses import asdict

    from sysid.measurement import compare_conditions, conditions_table, table

    extra = dict(adapter.report_extra(result))
    measured: dict[str, list] = {"train": [], "test": []}
    skipped = []
    for which, logs in (("train", result.train), ("test", result.test)):
        for log in logs:
            try:
                measured[which] += adapter.measure_log(log)
            except ValueError as exc:
                skipped.append(f"- {exc}")
    found = measured["train"] + measured["test"]
    if found or skipped:
        extra["measured"] = [asdict(m) for m in found]
        extra["sections"] = {**extra.get("sections", {}), "Measured directly (no simulator)": (
            "What the logs measure by themselves, beside the nominal model's values (`python -m sysid.measure`).\n\n"
            + (table(found) if found else "") + ("\n" + "\n".join(skipped) + "\n" if skipped else ""))}  # fmt: skip
    checks = compare_conditions(measured["train"], measured["test"], adapter.condition_quantities)
    if checks:
        extra["conditions"] = [{"quantity": c.quantity, "side": c.side, "log": c.held_out.log, "outside": c.outside,
                                "held_out": [c.held_out.value, c.held_out.low, c.held_out.high],
                                "training": [[m.log, m.value, m.low, m.high] for m in c.training]}
                               for c in checks]  # fmt: skip
        extra["sections"][CONDITIONS] = (
            "What each held-out log measures by itself of the conditions it ran under (the robot's "
            f"{', '.join(adapter.condition_quantities)}), against the training logs' (`python -m sysid.measure`).\n\n"
            + conditions_table(checks))  # fmt: skip
    return extra


CONDITIONS = "Held-out logs against the training logs' conditions"


def _stall_errors(found: Mapping[str, Any] | None) -> dict[str, Any] | None:
    if found is None:
        return None
    return {k: (_round(v, 4) if isinstance(v, float) else v) for k, v in found.items()}


def report_markdown(report: Mapping[str, Any]) -> str:
    r = report
    lines = [
        f"# Calibration of {r['robot']}",
        "",
        f"Trained on {', '.join(map(str, r['train']))}; tested on {', '.join(map(str, r['test']))}"
        + (f"; started from {r['start']}" if r.get("start") else "")
        + ".",
        "",
        "Errors are the RMS of the held-out residual over each channel's noise level: 1 is the noise floor.",
        "",
        f"**Held-out error: {r['error_before']:.3g} before, {r['error_after']:.3g} after.** "
        + ("Unexplained: " if r["unexplained"] else "")
        + r["unexplained_reason"],
        "",
    ]
    if r.get("without_stall"):
        w = r["without_stall"]
        lines += [f"Without the stall's span ({w['log']}, {w['start']:.2f} to {w['end']:.2f} s, every channel): "
                  f"{w['before']:.3g} before, {w['after']:.3g} after.", ""]  # fmt: skip
    if r.get("train_stall"):
        w = r["train_stall"]
        lines += [f"**A training log holds a stall**: {w['log']}, {w['start']:.2f} to {w['end']:.2f} s on "
                  f"{w['channel']} ({STALL_SIGN}). {STALL_ADVICE[0].upper()}{STALL_ADVICE[1:]}.", ""]  # fmt: skip
    if r.get("worse_on_test"):
        lines += [WORSE.format(after=r["error_after"], before=r["error_before"], baseline=baseline(r)), ""]
    lines += [
        "| channel | before | after |",
        "|---|---|---|",
    ]
    lines += [f"| {c} | {v['before']:.3g} | {v['after']:.3g} |" for c, v in r["per_channel"].items()]
    if len(r.get("per_log") or {}) > 1:
        lines += ["", "| held-out log | before | after |", "|---|---|---|"]
        lines += [f"| {log} | {v['before']:.3g} | {v['after']:.3g} |" for log, v in r["per_log"].items()]
    lines += ["", "## Effects kept, in order" if r["mode"] == "select" else "## Effects fitted (named with --fit)", ""]
    if r["chosen"]:
        lines += [
            "| effect | alias group | parameter | value | 95% interval | held-out error after |",
            "|---|---|---|---|---|---|",
        ]
        for c in r["chosen"]:
            for name, p in c["params"].items():
                lines.append(
                    f"| {c['name']} | {c['alias_group']} | {name} | {p['value']:.4g} {p['unit']} | "
                    f"{format_interval(p['value'], *p['interval95'])} | {c['error_after']:.3g} |"
                )
    else:
        lines.append("None: no catalog effect earned its place.")
    if r["rejected"]:
        lines += ["", "## Tried and rejected", ""]
        lines += [f"- **{x['name']}**: {x['reason']}" for x in r["rejected"]]
    if r.get("trace"):
        t = r["trace"]
        lines += ["", "## What the remaining residual points to", "",
                  f"The strongest finding on the held-out residual after calibration, `{t['text']}`, points to "
                  f"{t['mechanism']}. The catalog's effects of that kind acting on {t['channel']}:", ""]  # fmt: skip
        lines += [f"- **{name}**: {e['words']}" for name, e in t["effects"].items()] or ["- none"]
        if t.get("out_of_catalog"):
            lines += ["", f"Declared for this robot but kept out of its catalog: {', '.join(t['out_of_catalog'])}."]
        if t["missing"]:
            lines += ["", f"Kinds of effect not declared for this robot: {', '.join(t['missing'])}."]
        outside = [c for c in (r.get("extra") or {}).get("conditions", []) if c["outside"]]
        if outside:
            named = ", ".join(sorted({f"{c['quantity']} {c['side']}".strip() for c in outside}))
            lines += ["", f"The held-out logs ran under conditions no training log holds ({named}; section "
                      f"\"{CONDITIONS}\"): a residual there may be the conditions', not the model's."]  # fmt: skip
    if r["diagnostics"]["findings_before"]:
        lines += ["", "## What the residual pointed to (held-out, before)", ""]
        lines += [f"- {x}" for x in r["diagnostics"]["findings_before"]]
    if r["ranking"]:
        lines += ["", "## First ranking (score statistic of each effect at the nominal model)", ""]
        lines += ["| effect | alias group | score | p | share of residual explained |", "|---|---|---|---|---|"]
        for e in r["ranking"][0][:10]:
            lines.append(
                f"| {e['effect']} | {e['alias_group']} | {e['score']:.4g} | {e['p_value']:.2g} | "
                f"{e['explained_fraction']:.1%} |"
            )
    for title, text in (r.get("extra") or {}).get("sections", {}).items():
        lines += ["", f"## {title}", "", text]
    lines += [
        "",
        f"{r['segments']['train']} training and {r['segments']['test']} test segments of "
        f"{r['segments']['seconds_each']:g} s; {r['rollouts']} segment rollouts; {r['wall_seconds']} s.",
    ]
    return "\n".join(lines) + "\n"


def plot_residuals(result: Result, path: Path, which: str) -> None:
    """The held-out residual per channel over time (``which``: before or after)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    held = result.before if which == "before" else result.after
    problem = result.test_problem
    channels = problem.channels
    height = 2.2 * len(channels) + 0.6
    fig, axes = plt.subplots(len(channels), 1, figsize=(10, height), sharex=True, squeeze=False)
    # margins in inches for the titles and labels: tight_layout measured every tick label, a fifth of the plot's time
    fig.subplots_adjust(left=0.1, right=0.98, bottom=0.55 / height, top=1 - 0.8 / height, hspace=0.4)
    for c, ax in enumerate(axes[:, 0]):
        for seg, res in zip([problem.segments[i] for i in problem.scored], held.residuals, strict=True):
            t = seg.data["time"]
            ax.plot(t, res.data[:, c], lw=0.6, color="C0" if which == "before" else "C2")
        ax.axhline(1, color="0.6", lw=0.5, ls="--")
        ax.axhline(-1, color="0.6", lw=0.5, ls="--")
        ax.set_ylabel(f"{channels[c]}\n(noise levels)")
        ax.set_title(f"{channels[c]}: RMS {held.per_channel[channels[c]]:.3g}", fontsize=9)
    axes[-1, 0].set_xlabel("time in the test log, s")
    fig.suptitle(
        f"{result.adapter.name}: held-out residual {which} calibration (error {held.error:.3g})",
        y=1 - 0.2 / height,
        va="top",
    )
    fig.savefig(path, dpi=110)
    plt.close(fig)
