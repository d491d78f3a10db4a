"""An optimization run: iterations of ask, evaluate the whole swarm, tell; a checkpoint after every iteration; the
best parameters so far as a policy file.

Files in the run folder (each written atomically, a temporary file renamed over the last):

- ``checkpoint.pkl``: the settings, the optimizer (its whole state, random generators included), the best so far and
  the history; a run started again with the same settings resumes from it and gives what an uninterrupted run gives;
- ``best.json``: the best parameters as a policy file (the robot folder's policy loads it: ``cpg:<path>``);
- ``history.json``: per iteration, the best score so far and the iteration's scores (objective, distance
  travelled, +x progress, falls);
- ``.lock``: held while a run writes the folder, so that a second run into it at once is refused
  (:func:`envs.common.io.folder_lock`).
"""

from __future__ import annotations

import pickle
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from agents.optimize.optimizers import OPTIMIZERS
from agents.optimize.problem import DEPRECATED_OBJECTIVES, Evaluator, RunConfig
from envs.common.cluster import ensure_ray
from envs.common.io import Busy, ProgressLines, atomic_write, folder_lock, write_json

CHECKPOINT, BEST, HISTORY, LOCK = "checkpoint.pkl", "best.json", "history.json", ".lock"
TOOL = "python -m agents.optimize"
VERSION = 1


class RunError(ValueError):
    """A run that cannot start or resume; the message names the file and the setting."""


@dataclass(frozen=True)
class Settings:
    """What identifies a run: a checkpoint resumes only under the same settings."""

    config: dict[str, Any]
    optimizer: str
    iterations: int
    particles: int
    seed: int

    def as_dict(self) -> dict[str, Any]:
        return {"config": self.config, "optimizer": self.optimizer, "iterations": self.iterations,
                "particles": self.particles, "seed": self.seed}  # fmt: skip


class LocalBackend:
    """The whole swarm as one batch on this machine (``threads`` threads)."""

    def __init__(self, config: RunConfig, particles: int, threads: int | None = None):
        self.evaluator = Evaluator(config, particles, threads)
        self.controller = self.evaluator.controller

    @property
    def dimension(self) -> int:
        return self.evaluator.dimension

    def evaluate(self, parameters: np.ndarray, draw: tuple[int, ...] = ()) -> dict[str, np.ndarray]:
        return self.evaluator.evaluate(parameters, draw)

    def close(self) -> None:
        pass


class RayBackend:
    """The swarm split into ``workers`` batches, each on a Ray actor (one CPU, one thread) of a cluster.

    Args:
        address: a running cluster's address (``ray start --head`` prints it), or None: join the Ray instance this
            process already runs, or start a local one.
    """

    def __init__(self, config: RunConfig, particles: int, workers: int, address: str | None = None):
        # built here first: a bad config fails in one line before Ray starts (it also writes the policy files)
        self.controller = Evaluator(config, 1, nthread=1).controller
        ray = ensure_ray(address)
        sizes = [len(part) for part in np.array_split(np.arange(particles), workers)]
        remote = ray.remote(num_cpus=1)(_Worker)
        self._ray = ray
        self._bounds = np.cumsum([0, *sizes])
        self._workers = [remote.remote(config, size) for size in sizes]
        self.dimension = ray.get(self._workers[0].dimension.remote())

    def evaluate(self, parameters: np.ndarray, draw: tuple[int, ...] = ()) -> dict[str, np.ndarray]:
        b = self._bounds
        futures = [w.evaluate.remote(parameters[b[i] : b[i + 1]], draw, int(b[i])) for i, w in enumerate(self._workers)]
        parts = self._ray.get(futures)
        return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}

    def close(self) -> None:
        for worker in self._workers:
            self._ray.kill(worker)


class _Worker:
    """A Ray actor: an evaluator of its share of the swarm (one thread)."""

    def __init__(self, config: RunConfig, num_sims: int):
        self.evaluator = Evaluator(config, num_sims, nthread=1)

    def dimension(self) -> int:
        return self.evaluator.dimension

    def evaluate(self, parameters: np.ndarray, draw: tuple[int, ...] = (), first: int = 0) -> dict[str, np.ndarray]:
        return self.evaluator.evaluate(parameters, draw, first)


def load_checkpoint(out: Path) -> dict[str, Any] | None:
    """The run folder's checkpoint, None if it has none, or a one-line :class:`RunError` naming the file and why it
    cannot be resumed from."""
    path = out / CHECKPOINT
    if not path.exists():
        return None
    try:
        with path.open("rb") as f:
            state = pickle.load(f)
    except Exception as error:  # unpickling damaged bytes can raise almost anything (OSError for a folder, too)
        raise RunError(
            f"cannot resume from {path}: not a readable checkpoint ({type(error).__name__}: {error})"
        ) from None
    problem = _checkpoint_problem(state)
    if problem is not None:
        raise RunError(f"cannot resume from {path}: {problem}")
    return state


def _checkpoint_problem(state: Any) -> str | None:
    """What makes an unpickled checkpoint unusable (the fields :func:`run` and :func:`check_resumable` read), or
    None."""
    if not isinstance(state, dict) or state.get("version") != VERSION:
        return "not a checkpoint of this version of agents.optimize"
    missing = [key for key in ("settings", "optimizer", "best", "history", "wall_seconds") if key not in state]
    if missing:
        return f"it has no {', '.join(map(repr, missing))}"
    settings, keys = state["settings"], {f.name for f in fields(Settings)}
    if not isinstance(settings, dict) or set(settings) != keys or not isinstance(settings["config"], dict):
        return f"its 'settings' are not a dict of {', '.join(sorted(keys))} with a dict 'config'"
    optimizer = state["optimizer"]
    if not any(settings["optimizer"] == name and isinstance(optimizer, cls) for name, cls in OPTIMIZERS.items()):
        return f"its 'optimizer' is a {type(optimizer).__name__}, not the {settings['optimizer']!r} of its settings"
    best = state["best"]
    if best is not None and not (
        isinstance(best, dict) and set(best) >= {"score", "parameters", "iteration", "metrics"}
    ):
        return "its 'best' is not None nor a dict of score, parameters, iteration and metrics"
    if not isinstance(state["history"], list):
        return f"its 'history' is a {type(state['history']).__name__}, not a list"
    wall = state["wall_seconds"]
    if isinstance(wall, bool) or not isinstance(wall, int | float):
        return f"its 'wall_seconds' is {wall!r}, not a number"
    return None


def check_resumable(state: dict[str, Any], settings: Settings, path: Path) -> None:
    """The checkpoint's settings equal these, or a one-line error naming the first that differs."""
    old, new = dict(state["settings"]), settings.as_dict()
    objective = old["config"].get("objective")
    if isinstance(objective, str) and objective in DEPRECATED_OBJECTIVES:  # a run from before the objective's rename
        old["config"] = {**old["config"], "objective": DEPRECATED_OBJECTIVES[objective]}
    for key in new:
        if key == "config":
            for field in sorted(set(old[key]) | set(new[key])):
                if old[key].get(field) != new[key].get(field):
                    was, now = old[key].get(field), new[key].get(field)
                    raise RunError(
                        f"{path}: the checkpoint's run has config field {field!r} = {was!r}, not {now!r}; "
                        "use another --out"
                    )
        elif old[key] != new[key]:
            raise RunError(
                f"{path}: the checkpoint's run has {key} = {old[key]!r}, not {new[key]!r}; use another --out"
            )


def run(
    config: RunConfig,
    settings: Settings,
    out: Path,
    backend_factory: Callable[[], Any],
    progress: bool = True,
    command: str = "",
    stop_after: int | None = None,
) -> dict[str, Any]:
    """Run (or resume) the optimization; returns the record so far (best score, parameters, history).
    ``stop_after``: run at most this many iterations in this call, then stop (the checkpoint resumes it). The run
    holds the folder's lock while it writes: a second run into the same folder at once gets :class:`RunError`. A run
    found finished writes its ``best.json`` and ``history.json`` again (one lost since is back)."""
    out = Path(out)
    state = load_checkpoint(out)  # refused before the backend is built (a checkpoint of other settings)
    if state is not None:
        check_resumable(state, settings, out / CHECKPOINT)
    backend = backend_factory()  # first: building it checks the env's arguments before the folder is made
    try:
        with folder_lock(out, TOOL, LOCK):
            return _run_locked(config, settings, out, backend, progress, command, stop_after)
    except Busy as error:
        raise RunError(str(error).removeprefix(f"{TOOL}: ")) from None
    finally:
        backend.close()


def _run_locked(
    config: RunConfig,
    settings: Settings,
    out: Path,
    backend: Any,
    progress: bool,
    command: str,
    stop_after: int | None,
) -> dict[str, Any]:
    state = load_checkpoint(out)  # again, under the lock: another run may have written it since
    if state is not None:
        check_resumable(state, settings, out / CHECKPOINT)
    if state is None:
        optimizer = OPTIMIZERS[settings.optimizer](backend.dimension, settings.particles, settings.iterations,
                                                   settings.seed)  # fmt: skip
        state = {"version": VERSION, "settings": settings.as_dict(), "optimizer": optimizer, "best": None,
                 "history": [], "wall_seconds": 0.0, "command": command}  # fmt: skip
    optimizer = state["optimizer"]
    bar, lines = None, None
    if not progress:  # a line a minute, for a log file
        lines = ProgressLines(settings.iterations, "iteration")
        lines.start(optimizer.iteration)
    else:
        from tqdm import tqdm

        bar = tqdm(total=settings.iterations, initial=optimizer.iteration, desc=f"{settings.optimizer}",
                   unit="it", dynamic_ncols=True)  # fmt: skip
        if state["best"] is not None:
            bar.set_postfix(best=f"{state['best']['score']:.3f}")
    budget = settings.iterations if stop_after is None else min(settings.iterations,
                                                                  optimizer.iteration + stop_after)  # fmt: skip
    while optimizer.iteration < budget:
        started = time.perf_counter()
        draw = (settings.seed, optimizer.iteration)  # the randomized rollouts' key: the same when resumed
        parameters = optimizer.ask()
        scores = backend.evaluate(parameters, draw)
        optimizer.tell(scores["score"])
        i = int(np.argmax(scores["score"]))
        if state["best"] is None or scores["score"][i] > state["best"]["score"]:
            state["best"] = {"score": float(scores["score"][i]), "parameters": parameters[i].tolist(),
                             "iteration": optimizer.iteration - 1,
                             "metrics": {k: float(v[i]) for k, v in scores.items()}}  # fmt: skip
        state["history"].append(_history_row(optimizer.iteration - 1, scores, state["best"]["score"]))
        state["wall_seconds"] += time.perf_counter() - started
        _save(out, state, config, backend)
        if bar is not None:
            bar.update(1)
            bar.set_postfix(best=f"{state['best']['score']:.3f}")
        if lines is not None:
            lines.update(optimizer.iteration, f"best score {state['best']['score']:.4g}")
    if bar is not None:
        bar.close()
    if state["best"] is not None and not all((out / name).is_file() for name in (BEST, HISTORY)):
        _save(out, state, config, backend)  # a finished (or paused) run whose files were lost: written again
    return {"best": state["best"], "history": state["history"], "wall_seconds": state["wall_seconds"],
            "finished": optimizer.iteration >= settings.iterations}  # fmt: skip


def _history_row(iteration: int, scores: dict[str, np.ndarray], best: float) -> dict[str, Any]:
    i = int(np.argmax(scores["score"]))
    return {
        "iteration": iteration,
        "best_so_far": best,
        "max": float(scores["score"][i]),
        "mean": float(np.mean(scores["score"])),
        "at_max": {k: float(v[i]) for k, v in scores.items()},
        "falls": int(np.sum(scores["fallen"])),
    }


def _save(out: Path, state: dict[str, Any], config: RunConfig, backend) -> None:
    out.mkdir(parents=True, exist_ok=True)
    atomic_write(out / CHECKPOINT, lambda p: p.write_bytes(pickle.dumps(state)))
    best = state["best"]
    record = backend.controller.policy_record(np.asarray(best["parameters"]))
    record.update({
        "score": best["score"],
        "objective": config.objective,
        "metrics": best["metrics"],
        "iteration": best["iteration"],
        "run": {**state["settings"], "command": state.get("command", "")},
    })  # fmt: skip
    write_json(out / BEST, record, strict=True)
    write_json(out / HISTORY, {"settings": state["settings"], "history": state["history"],
                               "wall_seconds": state["wall_seconds"]}, strict=True)  # fmt: skip
