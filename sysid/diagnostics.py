"""Residual diagnostics that point to a cause: lag, dependence on the sign of velocity, on velocity, acceleration,
command and load, drift with time or supply voltage, spectral peaks, constant bias, stance against swing, left against
right, and a residual gathered at one moment of a log (a stall there: an event, not a property of the robot).

Each is a number per channel with a plain reading; the report lists the strongest, and the effect ranking (a score
statistic of each effect's parameters, sysid/select.py) is explained by them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sysid.problem import Problem, Residual


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    denom = float(np.sqrt((a @ a) * (b @ b)))
    return float(a @ b) / denom if denom > 0 else 0.0


def diagnose(problem: Problem, residuals: Sequence[Residual], context: Mapping[str, Any]) -> dict[str, dict]:
    """Diagnostics of normalized residuals per channel.

    ``context`` names the log columns that explain a residual: ``velocity``, ``command``, ``load``, ``supply``, and
    ``phase`` (a crank or joint angle whose cosine is positive in stance). Each is one column for every channel, or
    a dict channel -> column (a robot with sides relates each side's channels to that side's columns). Channels
    named ``..._left`` and ``..._right`` are also compared with each other.
    """
    out: dict[str, dict] = {}
    segs = [problem.segments[i] for i in problem.scored]  # the segments whose residuals are given
    times = np.concatenate([s.data["time"] for s in segs])
    dt = np.gradient(times) if len(times) > 1 else np.ones_like(times)
    dt[dt <= 0] = np.median(dt[dt > 0]) if (dt > 0).any() else 1.0
    logs = np.concatenate([np.full(len(s.data["time"]), s.source) for s in segs])  # each sample's log
    names = {s.source: s.log for s in segs}

    def column(key: str, channel: str) -> np.ndarray | None:
        name = context.get(key)
        name = name.get(channel) if isinstance(name, Mapping) else name
        if name is None or not all(name in s.data for s in segs):
            return None
        return np.concatenate([s.data[name] for s in segs])

    for c, name in enumerate(problem.channels):
        r = np.concatenate([x.data[:, c] for x in residuals])
        rms = float(np.sqrt(np.mean(r * r))) if r.size else 0.0
        entry = {"rms": rms, "bias": float(r.mean()) if r.size else 0.0}
        if r.size < 8:
            out[name] = entry
            continue
        entry["drift_with_time"] = _corr(r, times)
        v = column("velocity", name)
        if v is not None:
            entry["with_sign_of_velocity"] = _corr(r, np.sign(v))
            entry["with_velocity"] = _corr(r, v)
            entry["with_acceleration"] = _corr(r, np.gradient(v) / dt)
        u = column("command", name)
        if u is not None:
            entry["with_command"] = _corr(r, u)
            entry["lag_of_command"] = _best_lag(r, u, times)
        for key in ("load", "supply"):
            x = column(key, name)
            if x is not None:
                entry[f"with_{key}"] = _corr(r, x)
        phase = column("phase", name)
        if phase is not None:
            stance = np.cos(phase) > 0
            if stance.any() and (~stance).any():
                entry["stance_over_swing"] = float(np.sqrt(np.mean(r[stance] ** 2) / max(np.mean(r[~stance] ** 2),
                                                                                          1e-12)))  # fmt: skip
        entry["spectral_peak_hz"], entry["spectral_peak_share"] = _spectral_peak(r, times)
        entry.update(_event(r, times, logs, names, column("velocity", name), column("load", name)))
        out[name] = entry
    for name, entry in out.items():
        if name.endswith("_left") and name[:-5] + "_right" in out:
            right = out[name[:-5] + "_right"]["rms"]
            entry["left_over_right"] = entry["rms"] / right if right > 0 else float("inf")
    return out


EVENT_WINDOW = 0.1  # the moment's window: this share of the residual's time (summed over its logs)
EVENT_SHARE = 0.4  # a moment holds at least this share of a channel's squared residual (4 times a spread one's)
AT_LIMIT = 0.97  # a drive "at its limit": its effort within 3% of the largest the log holds


def _event(r: np.ndarray, t: np.ndarray, logs: np.ndarray, names: Mapping[int, str], velocity: np.ndarray | None,
           load: np.ndarray | None) -> dict[str, Any]:  # fmt: skip
    """Where a channel's squared residual gathers most: the window of a tenth of the residual's time (within one
    log) holding the largest share of it, narrowed to the span between its 5th and 95th percentiles of that share.
    ``event_share`` is the span's share of the whole, ``event_start`` and ``event_end`` its times (s, the log's own
    time), ``event_fraction`` its share of the time tested, ``event_log`` the log, and ``event_stall`` whether the
    drive's effort was at its limit for a quarter of the span or more and the joint, while it was, did not move the
    way it pushed (the robot held or blocked). A residual spread over the run holds about a tenth in the window;
    one growing linearly over the run, about a quarter."""
    energy = r * r
    total = float(energy.sum())
    masks = {k: logs == k for k in np.unique(logs)}  # each log's samples
    spans = {k: float(np.ptp(t[m])) for k, m in masks.items()}
    width = EVENT_WINDOW * sum(spans.values())
    if total <= 0 or width <= 0:
        return {}
    best = (0.0, 0, np.zeros(0, dtype=int))
    for k, mask in masks.items():
        index = np.flatnonzero(mask)
        index = index[np.argsort(t[index], kind="stable")]
        cumulative = np.concatenate([[0.0], np.cumsum(energy[index])])
        end = np.searchsorted(t[index], t[index] + width, side="right")
        held = cumulative[end] - cumulative[:-1]
        i = int(np.argmax(held))
        if held[i] > best[0]:
            best = (float(held[i]), k, index[i : end[i]])
    held, k, window = best
    inner = np.cumsum(energy[window]) / held
    span = window[int(np.searchsorted(inner, 0.05)) : int(np.searchsorted(inner, 0.95)) + 1]
    in_log = masks[k]
    step = float(np.median(np.diff(np.sort(t[in_log])))) if in_log.sum() > 1 else 0.0
    out: dict[str, Any] = {"event_share": float(energy[span].sum()) / total, "event_start": float(t[span[0]]),
                           "event_end": float(t[span[-1]]), "event_log": str(names.get(k, k)),
                           "event_fraction": len(span) * step / sum(spans.values())}  # fmt: skip
    if velocity is not None and load is not None:
        limit = float(np.max(np.abs(load[in_log])))
        at_limit = np.abs(load[span]) >= AT_LIMIT * limit
        pushed = (np.sign(load[span]) * velocity[span])[at_limit]
        typical = float(np.mean(np.abs(velocity[in_log])))
        out["event_stall"] = bool(limit > 0 and at_limit.mean() >= 0.25 and pushed.mean() < 0.1 * typical)
    return out


def _best_lag(r: np.ndarray, u: np.ndarray, t: np.ndarray) -> float:
    """The lag (s) at which the command's change best correlates with the residual."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    du = np.diff(u, prepend=u[0])
    best, best_lag = 0.0, 0.0
    for k in range(0, min(50, len(r) // 4)):
        c = abs(_corr(r[k:], du[: len(du) - k])) if k else abs(_corr(r, du))
        if c > best:
            best, best_lag = c, k * dt
    return best_lag


def _spectral_peak(r: np.ndarray, t: np.ndarray) -> tuple[float, float]:
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    spectrum = np.abs(np.fft.rfft(r - r.mean())) ** 2
    if len(spectrum) < 3 or spectrum.sum() <= 0:
        return 0.0, 0.0
    k = int(np.argmax(spectrum[1:])) + 1
    return float(k / (len(r) * dt)), float(spectrum[k] / spectrum.sum())


@dataclass(frozen=True)
class Finding:
    """One diagnostic that stands out: on ``channel``, of kind ``key`` (a key of :data:`MECHANISMS`), weighing
    ``weight`` (its correlation or ratio times the channel's RMS, in noise levels; a moment's, the root of its share
    of the squared residual beyond a spread residual's), read as ``text``."""

    weight: float
    channel: str
    key: str
    text: str


# what each kind of finding points to, and the catalog effects (envs/common/effects.py) that make a residual of that
# kind: the mechanism a report names when what remains is unexplained, and the effects it asks the outcome about
MECHANISMS: dict[str, tuple[str, tuple[str, ...]]] = {
    "bias": ("a constant offset (a sensor's zero, or an output the model holds too low or too high throughout)",
             ("sensor_bias", "sensor_running_offset", "com_offset", "coulomb_friction")),
    "with_sign_of_velocity": ("dry friction, backlash or a deadband",
                              ("coulomb_friction", "asymmetric_friction", "stribeck_friction", "load_friction",
                               "backlash", "deadband")),
    "with_velocity": ("speed-proportional losses or the back-EMF",
                      ("viscous_friction", "back_emf_constant", "torque_constant", "pwm_decay", "sensor_gain")),
    "with_acceleration": ("inertia or lag", ("armature", "delay", "mass", "servo_gain")),
    "with_command": ("the drive's strength", ("torque_constant", "supply_voltage", "gearbox_efficiency", "deadband",
                                              "servo_gain", "sensor_coupling")),
    "drift_with_time": ("a slow change over the run (the supply sagging, the motor heating)",
                        ("supply_sag", "supply_voltage")),
    "with_supply": ("the supply", ("supply_voltage", "supply_sag")),
    "with_load": ("what the drive carries: its losses, the legs' compliance, the body and the ground they move",
                  ("gearbox_efficiency", "load_friction", "coulomb_friction", "viscous_friction", "torque_constant",
                   "supply_sag", "sensor_coupling", "periodic_load", "leg_stiffness", "spine_stiffness",
                   "ground_contact", "foot_friction", "mass", "com_offset", "terrain_bump")),
    "stance": ("the contacts: legs, feet and ground",
               ("foot_friction", "ground_contact", "leg_stiffness", "spine_stiffness", "mass", "com_offset",
                "terrain_bump")),
    "swing": ("the legs' own motion in the air: inertia, lag, friction",
              ("armature", "delay", "viscous_friction", "coulomb_friction")),
    "sides": ("a difference between the sides", ()),
    # a moment is often the response to a change of the command, which the drive's effects make; a stall is not
    "moment": ("a residual gathered at one moment of a log: the response to a change of the command that the model "
               "makes differently (a step's transient: lag, inertia, friction), a start the replay does not "
               "reproduce, something the robot met, or a glitch in the logging; a window of the log without it "
               "(FILE@START:END) tests the model on the rest", ("delay", "armature", "coulomb_friction",
                                                                 "terrain_bump")),
    "stall": ("an event at one moment of a log, not a property of the robot: held or blocked by something outside it "
              "(an obstacle, a hand, a leg caught), which no effect acting throughout a run makes; a window of the "
              "log that leaves it out (FILE@START:END) tests the model on the rest", ("terrain_bump",)),
    "spectral": ("a periodic disturbance, or a mode of the body on its legs",
                 ("disturbance", "terrain_bump", "ground_contact", "leg_stiffness", "spine_stiffness")),
}  # fmt: skip
# the kinds that act on a body standing on the ground: a robot with none in its catalog (a bench rig) lacks them by
# nature, and a trace does not name them as missing
BODY_KINDS = frozenset({"leg_stiffness", "spine_stiffness", "ground_contact", "foot_friction", "mass", "com_offset",
                        "terrain_bump"})  # fmt: skip
_CORRELATIONS = (
    ("with_sign_of_velocity", "follows the sign of velocity (dry friction, backlash, deadband)"),
    ("with_velocity", "grows with velocity (viscous friction, back-EMF)"),
    ("with_acceleration", "follows acceleration (inertia, armature, delay)"),
    ("with_command", "follows the command (torque constant, supply, deadband)"),
    ("drift_with_time", "drifts over time (supply sag, heating)"),
    ("with_supply", "follows the supply voltage"),
    ("with_load", "follows the load (compliance, current limit)"),
)


def findings(diagnostics: Mapping[str, dict]) -> list[Finding]:
    """The diagnostics that stand out, strongest first."""
    found: list[Finding] = []
    for channel, d in diagnostics.items():
        if d.get("rms", 0.0) <= 1.2:
            continue
        if abs(d.get("bias", 0.0)) > 0.5 * d["rms"]:
            found.append(Finding(abs(d["bias"]), channel, "bias", f"{channel}: a constant offset ({d['bias']:+.2f} "
                                 "noise levels)"))  # fmt: skip
        for key, text in _CORRELATIONS:
            c = d.get(key)
            if c is not None and abs(c) > 0.3:
                found.append(Finding(abs(c) * d["rms"], channel, key, f"{channel}: the residual {text}, correlation "
                                     f"{c:+.2f}"))  # fmt: skip
        ratio = d.get("stance_over_swing")
        if ratio is not None and (ratio > 1.5 or ratio < 1 / 1.5):
            where = "stance" if ratio > 1 else "swing"
            times = max(ratio, 1 / ratio)
            text = f"{channel}: the residual is larger in {where} ({times:.1f} times; contacts, legs, feet)"
            found.append(Finding(abs(math.log(ratio)) * d["rms"] / 2, channel, where, text))
        ratio = d.get("left_over_right")
        if ratio is not None and (ratio > 2 or ratio < 0.5):
            side, other = ("left", "right") if ratio > 1 else ("right", "left")
            larger = channel if ratio > 1 else channel[:-5] + "_right"
            found.append(Finding(abs(math.log(ratio)) * d["rms"] / 2, larger, "sides", f"{channel[:-5]}: the {side} "
                                 f"side's residual is {max(ratio, 1 / ratio):.1f} times the {other}'s (a per-side "
                                 "effect)"))  # fmt: skip
        share = d.get("event_share", 0.0)
        if share >= EVENT_SHARE:
            stall = bool(d.get("event_stall"))
            text = (f"{channel}: {share:.0%} of the residual lies in {d['event_log']} between {d['event_start']:.2f} "
                    f"and {d['event_end']:.2f} s, {d['event_fraction']:.0%} of the time tested")  # fmt: skip
            if stall:
                text += (", with the drive at its limit and the joint not moving the way it pushes (a stall: the "
                         "robot held or blocked)")  # fmt: skip
            weight = math.sqrt((share - EVENT_WINDOW) / (1 - EVENT_WINDOW)) * d["rms"]
            found.append(Finding(weight, channel, "stall" if stall else "moment", text))
        if d.get("spectral_peak_share", 0.0) > 0.2:
            found.append(Finding(d["spectral_peak_share"] * d["rms"], channel, "spectral",
                                 f"{channel}: a spectral peak at {d['spectral_peak_hz']:.2f} Hz holds "
                                 f"{d['spectral_peak_share']:.0%} of the residual's power"))  # fmt: skip
    found.sort(key=lambda f: -f.weight)
    return found


def summarize(diagnostics: Mapping[str, dict], limit: int = 3) -> list[str]:
    """The strongest findings, as sentences."""
    return [f.text for f in findings(diagnostics)[:limit]]
