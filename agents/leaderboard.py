"""The leaderboard: learning on every task against its reference, in one command that anyone can rerun.

    python -m agents.leaderboard --tasks skitter/RoachWalk-v4 skitter/XjusWalk-v1 skitter/BioloidWalk-v2 \\
        --algos ppo --seeds 0 1 2 --timesteps skitter/RoachWalk-v4=4000000 skitter/XjusWalk-v1=10000000 \\
        skitter/BioloidWalk-v2=7000000 --out results/leaderboard --records docs/results/records \\
        --docs docs/results.md

**Rows.** A row is one task, algorithm and seed. ``train.py`` trains it into ``OUT/runs/<row>/`` with the
hyperparameter file's entry (``--hyperparams``, default ``hyperparams/<algo>.yml``); ``evaluate.py`` then plays the
trained model and the task's reference on the evaluation seeds (``--eval-seed``, the same for every row of a task)
into ``OUT/rows/<row>/``: the robot's reference gait, or on a soccer academy task the scripted player, where the
task is trained and evaluated in the commands mode (:func:`task_kwargs`). For each task, ``evaluate.py`` also plays
a random policy and the reference once (``OUT/tasks/<task>/``). A row is done when its record, ``row.json`` with its
numbers and its learning curve, is written into ``--records`` (default ``OUT``): another command skips it. ``make
leaderboard`` keeps the records in ``docs/results/records/``, part of the repository, and the runs in ``results/``
outside it, so that a table built over several sessions or machines keeps its finished rows on a fresh checkout. A
row whose training was killed continues from its last checkpoint (``train.py --resume``). ``--rerun`` computes the
named rows again from nothing, and ``--table-only`` trains nothing: it writes the table of the rows done so far (a
table built over several runs can be published between them). Rows run in a local pool of ``--workers`` processes
(each with an equal share of the cores), or as Ray tasks on the cluster at ``--address``.

**Budget.** Every row trains ``--timesteps`` env steps: one number for every task, or ``TASK=N`` for each, so that
a budget of time on a given machine becomes a number of steps per task that any machine can train again. A row
records its wall time. ``--minutes`` adds a cap of wall time; the row says when it bit, since a row cut short by
the cap trained fewer steps than another machine would. The command prints its plan before it starts.

**Scores.** A row's score is its model's mean return over the evaluation episodes, normalized per task so that the
random policy scores 0 and the reference 1. For each task and algorithm: the interquartile mean (IQM) over
seeds, with a 95% stratified-bootstrap interval (``rliable``). Over all tasks: the same across tasks and seeds, and
performance profiles; until every row is done, the same over the seeds every task has for every algorithm.
Learning curves are each run's TensorBoard episode return, averaged over seeds. The model's metric and energy
(:func:`energy_metric`) beside the reference's come from ``evaluate.py``'s paired comparison.

Writes ``OUT/results.md``, ``OUT/results.json`` and ``OUT/plots/`` (each file whole, or not at all); with ``--docs
PATH``, the page also goes to ``PATH``.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from agents.config import skitter_env_problem
from agents.evaluation import GENERIC_METRICS, LOWER_IS_BETTER
from envs.common.batch import THREADS_VARIABLE
from envs.common.cluster import ClusterError, check_address, ensure_ray, init_ray
from envs.common.host import numerics
from envs.common.io import ToolParser, atomic_write, current_folder_problem, parent_problem, write_json, write_text

ROOT = Path(__file__).resolve().parents[1]
RETURN = "return"
NARROW_MARGIN = 0.25  # a reference that beats random by less than this share of its return: say normalizing magnifies
RESIDUAL = "+residual"  # an algorithm's suffix: learn a correction on top of the task's reference gait
CURVE_POINTS = 200  # a row's learning curve as kept in its record
CURVE_TAG = "rollout/ep_rew_mean"  # SB3's mean training-episode return (the raw reward: VecMonitor is innermost)
BOOTSTRAP_REPS = 2000
CHILD_GRACE = 120.0  # s a stopped train.py or evaluate.py may take to save its checkpoint and end
SOCCER = "soccer/"  # a task ``soccer/<robot>``: self-play (train.py --soccer), one a side, rated against the script
SELFPLAY_ALGOS = ("ppo",)  # what self-play trains a soccer task with (a plan's other algorithms skip its soccer tasks)
SOCCER_PLAYERS = 1
SCRIPTED_ELO = 1000.0  # the scripted team: the anchor of every rating (agents/soccer/selfplay.py)
MATCH_SECONDS = 60.0  # a soccer task's matches, in training and evaluation, unless the plan says otherwise (--match-
# seconds): train.py's and evaluate.py's default (envs.soccer.match.MATCH_SECONDS; a test holds them equal)


def is_soccer(task: str) -> bool:
    """Whether a task is a robot's self-play soccer (``soccer/<robot>``), not a gym id."""
    return task.startswith(SOCCER)


# each kind of task's own metric, by the metric only its kind reports (the first a row has): an academy task's
# success (1 or 0 an episode), a turn's yaw-rate error (rad/s; lower is better), else a walk's speed (m/s)
TASK_METRICS = (("success", ""), ("yaw_rate_error", " rad/s"), ("speed", " m/s"))


def task_metric(paired_differences: dict) -> tuple[str, str]:
    """The task's own metric of a row (from the metrics its paired comparison holds) and its unit: what the row's
    model is judged on beside the reference, with its energy (:func:`energy_metric`)."""
    return next(((m, unit) for m, unit in TASK_METRICS if m in paired_differences), TASK_METRICS[-1])


def energy_metric(paired_differences: dict) -> tuple[str, str]:
    """The energy a row's model is judged on beside the reference, and its unit: on a turn, which asks for a yaw
    rate and no travel, the mean electrical power (W; energy per metre is undefined for a robot that turns on the
    spot); on an academy task, whose episode ends when the task is done, the energy of the episode (J: what the
    touch or the goal took; a player that walks sideways or turns on its way travels little along its heading, so
    its energy per metre of that is no measure of it); elsewhere the cost of transport (energy per metre). A record
    from before evaluate.py reported the power or the energy keeps the cost of transport."""
    metric = task_metric(paired_differences)[0]
    if metric == "yaw_rate_error" and "power" in paired_differences:
        return "power", " W"
    if metric == "success" and "energy" in paired_differences:
        return "energy", " J"
    return "cost_of_transport", ""


def _energy_cell(diff: dict[str, Any]) -> str:
    """A row's energy against the reference, named: ``power -1.230 [..] W`` or ``cost of transport +0.5 [..]``."""
    metric, unit = energy_metric(diff)
    return f"{metric.replace('_', ' ')} {_paired(diff, metric)}{unit}"


def task_kwargs(task: str) -> dict[str, Any]:
    """The env keyword arguments a task is trained and evaluated with: the commands mode (speed and turn rate, run
    by the robot's gait) on a soccer academy task, where the reference is the scripted player; none elsewhere."""
    from agents.soccer import ACADEMY_KWARGS
    from envs.soccer import ACADEMY

    return dict(ACADEMY_KWARGS) if any(spec["id"] == task for spec in ACADEMY) else {}


def _env(task: str) -> list[str]:
    """train.py's and evaluate.py's options that make a task's env: ``--env`` and its ``--env-kwargs``."""
    kwargs = task_kwargs(task)
    return ["--env", task, *(["--env-kwargs", json.dumps(kwargs)] if kwargs else [])]


def elo_against(wins: int, draws: int, losses: int) -> dict[str, float]:
    """A team's Elo from its record against a team rated :data:`SCRIPTED_ELO`: the rating difference at which Elo
    expects its score, ``400 log10(s / (1 - s))``, with the score's 95% Wilson interval carried through (a score of 0
    or 1 has an open end: that side of the rating is unbounded, written as infinite)."""
    from scipy import stats

    n = wins + draws + losses
    points = wins + 0.5 * draws

    def rating(score: float) -> float:
        if score <= 0.0:
            return -np.inf
        if score >= 1.0:
            return np.inf
        return SCRIPTED_ELO + 400.0 * np.log10(score / (1.0 - score))

    # the Wilson interval of a score with half points: of the wins and draws counted in half matches
    interval = stats.binomtest(round(2 * points), 2 * n).proportion_ci(confidence_level=0.95, method="wilson")
    return {"elo": rating(points / n), "low": rating(interval.low), "high": rating(interval.high), "matches": n,
            "score": points / n}  # fmt: skip


@dataclass(frozen=True)
class Row:
    task: str
    algo: str
    seed: int

    @property
    def name(self) -> str:
        return f"{self.task.replace('/', '_')}__{self.algo}__{self.seed}"


@dataclass(frozen=True)
class Plan:
    tasks: tuple[str, ...]
    algos: tuple[str, ...]
    seeds: tuple[int, ...]
    timesteps: tuple[tuple[str, int], ...]  # (task, env steps a row of it trains)
    minutes: float | None
    episodes: int
    eval_seed: int
    hyperparams: str | None
    max_episode_steps: int | None = None  # cut evaluation episodes short (a smoke test's budget), else the task's
    match_seconds: tuple[tuple[str, float], ...] = ()  # (soccer task, its matches' length, s) where not MATCH_SECONDS

    @property
    def rows(self) -> list[Row]:
        return [Row(t, a, s) for t in self.tasks for a in self.algos_of(t) for s in self.seeds]

    def algos_of(self, task: str) -> tuple[str, ...]:
        """The plan's algorithms that train ``task``: all of them on a gym task; on a soccer task those self-play
        trains (:data:`SELFPLAY_ALGOS`), so that one plan holds the gym tasks' residual rows and the soccer rows."""
        return tuple(a for a in self.algos if a in SELFPLAY_ALGOS) if is_soccer(task) else self.algos

    def steps(self, task: str) -> int:
        """The env steps a row of ``task`` trains."""
        return dict(self.timesteps)[task]

    def match_length(self, task: str) -> float:
        """How long a soccer task's matches last, in training and evaluation (s)."""
        return dict(self.match_seconds).get(task, MATCH_SECONDS)

    def row_settings(self, task: str) -> dict[str, Any]:
        """What a row's numbers depend on besides its task, algorithm and seed."""
        return {"timesteps": self.steps(task), "minutes": self.minutes, "hyperparams": self.hyperparams,
                **self.task_settings(task)}  # fmt: skip

    def task_settings(self, task: str) -> dict[str, Any]:
        """What a task's evaluation episodes depend on: :attr:`eval_settings`, and the env kwargs it is made with
        (a soccer academy task's commands mode)."""
        kwargs = task_kwargs(task)
        # a record without a match length holds MATCH_SECONDS matches (it was made before the length could change)
        length = self.match_length(task) if is_soccer(task) else MATCH_SECONDS
        return {**self.eval_settings, **({"env_kwargs": kwargs} if kwargs else {}),
                **({"match_seconds": length} if length != MATCH_SECONDS else {})}  # fmt: skip

    @property
    def eval_settings(self) -> dict[str, Any]:
        """What a task's evaluation episodes depend on."""
        return {"episodes": self.episodes, "eval_seed": self.eval_seed, "max_episode_steps": self.max_episode_steps}


class StaleResult(RuntimeError):
    """A finished row or task in the folder was made with other settings than the command's."""


def _load_done(path: Path, settings: dict[str, Any], what: str) -> dict[str, Any] | None:
    """A finished record, if it was made with ``settings`` (StaleResult otherwise); None if there is none."""
    if not path.is_file():
        return None
    record = json.loads(path.read_text())
    if record.get("settings") != settings:
        # a row can be computed again (--rerun TASK:ALGO:SEED); a task's baselines belong to the plan's settings
        remedy = "give --rerun for it, or another --out" if what.startswith("row ") else (
            "its rows and baselines were made under those settings: give another --out (and --records), or the "
            "settings they were made with")  # fmt: skip
        raise StaleResult(f"{path}: {what} was made with {record.get('settings')}, not {settings}: {remedy}")
    return record


def _tool(script: str, *args: Any) -> list[str]:
    return [sys.executable, str(ROOT / script), *map(str, args)]


def _run(command: list[str], threads: int, log: Path) -> None:
    """Run a tool with ``threads`` threads of simulation, its output in ``log``; RuntimeError naming the log if it
    fails."""
    env = {**os.environ, THREADS_VARIABLE: str(threads), "PYTHONPATH": str(ROOT)}
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as out:
        out.write(f"$ {shlex.join(command)}\n")
        out.flush()
        child = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, env=env)
        try:
            code = child.wait()
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the child stops as on its own Ctrl-C (train.py checkpoints)
            child.send_signal(signal.SIGINT)
            try:
                child.wait(timeout=CHILD_GRACE)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()
            raise
    if code != 0:
        raise RuntimeError(f"{shlex.join(command[1:3])} ... failed (exit {code}); see {log}")


@functools.cache
def reference_name(task: str) -> str:
    """The policy a task's rows are compared with: its robot's reference gait (agents: each robot's ``REFERENCE``),
    or on a soccer academy task the scripted player (:func:`agents.env_reference`)."""
    import gymnasium as gym

    import envs  # noqa: F401  (registers the ids)
    from agents import env_reference

    env = gym.make(task, **task_kwargs(task))
    try:
        return env_reference(env)
    finally:
        env.close()


def _cut(plan: Plan) -> list[Any]:
    """evaluate.py's option that cuts evaluation episodes short, if the plan does."""
    return [] if plan.max_episode_steps is None else ["--max-episode-steps", plan.max_episode_steps]


def _episodes(plan: Plan) -> list[Any]:
    """evaluate.py's options that choose the evaluation episodes (the same for every policy of a task)."""
    return ["--episodes", plan.episodes, "--seed", plan.eval_seed, *_cut(plan)]


def _soccer(task: str, *args: Any) -> list[Any]:
    """evaluate.py's options of a soccer task's matches (its robot, one a side)."""
    return ["--soccer", task.removeprefix(SOCCER), "--players", SOCCER_PLAYERS, *args]


def _matches(plan: Plan, task: str) -> list[Any]:
    """evaluate.py --soccer's options that choose the evaluation matches (the same for every row of a task)."""
    return ["--matches", plan.episodes, "--seed", plan.eval_seed, *_match_length(plan, task)]


def _match_length(plan: Plan, task: str) -> list[Any]:
    """train.py's and evaluate.py's ``--match-seconds`` for a soccer task whose matches are not MATCH_SECONDS long."""
    length = plan.match_length(task)
    return [] if length == MATCH_SECONDS else ["--match-seconds", f"{length:g}"]


def task_file(records: Path, task: str) -> Path:
    """Where a task's finished baselines are kept."""
    return records / "tasks" / task.replace("/", "_") / "baselines.json"


def row_file(records: Path, row: Row) -> Path:
    """Where a finished row's record is kept."""
    return records / "rows" / row.name / "row.json"


def task_baselines(plan: Plan, task: str, out: Path, threads: int, records: Path | None = None) -> dict[str, Any]:
    """The task's reference gait and a random policy on the evaluation seeds (once per task); for a soccer task,
    the scripted team against a random one. Worked out in ``out``, kept in ``records`` (default ``out``)."""
    from envs.common.io import folder_lock

    folder = out / "tasks" / task.replace("/", "_")
    record = task_file(records or out, task)
    with folder_lock(folder, "leaderboard", wait=True):  # another command on the task: its baselines, once
        done = _load_done(record, plan.task_settings(task), f"the baselines of {task}")
        return done if done is not None else _work_out_baselines(plan, task, folder, record, threads)


def _work_out_baselines(plan: Plan, task: str, folder: Path, record: Path, threads: int) -> dict[str, Any]:
    if is_soccer(task):
        evaluation = folder / "eval"
        _run(_tool("evaluate.py", *_soccer(task, "--home", "scripted", "--away", "random"), *_matches(plan, task),
                   "--out", evaluation, "--overwrite"), threads, folder / "log.txt")  # fmt: skip
        result = json.loads((evaluation / "results.json").read_text())
        counts = [result[k]["count"] for k in ("wins", "draws", "losses")]
        random_elo = elo_against(*reversed(counts))  # the random team's record against the scripted one
        baselines = {"task": task, "soccer": True, "reference": "scripted", "scripted_vs_random": result,
                     "random_elo": random_elo, "settings": plan.task_settings(task), "host": numerics()}  # fmt: skip
        write_json(record, baselines)
        return baselines
    reference = reference_name(task)
    evaluation = folder / "eval"
    _run(_tool("evaluate.py", *_env(task), "--policy", reference, "--policy", "random", *_episodes(plan), "--out",
               evaluation, "--overwrite"), threads, folder / "log.txt")  # fmt: skip
    results = json.loads((evaluation / "results.json").read_text())
    returns = {spec: _returns(results, spec) for spec in (reference, "random")}
    baselines = {"task": task, "reference": reference, "reference_return": float(np.mean(returns[reference])),
                 "random_return": float(np.mean(returns["random"])), "returns": returns,
                 "reference_summary": results["policies"][reference]["summary"],
                 "settings": plan.task_settings(task), "host": numerics()}  # fmt: skip
    write_json(record, baselines)
    return baselines


def video_marker(records: Path, task: str) -> Path:
    """The name of the row whose model a task's published video shows."""
    return records / "videos" / task.replace("/", "_") / "row.txt"


def task_video(plan: Plan, task: str, out: Path, rows: dict[Row, dict | None], threads: int,
               records: Path | None = None) -> Path | None:  # fmt: skip
    """A side-by-side video of the task's reference gait and its best row's model, on the first evaluation seed
    (``OUT/videos/<task>/``); made again when the best row changes and its model is in ``OUT/runs/`` (a checkout
    keeps the records, not the runs: there the published video stays). The best row is the best of all the
    task's finished rows under the plan's settings, this command's and those recorded before it: a command that
    computes one row does not take the video from a better row it did not plan."""
    if is_soccer(task):  # a soccer row is rated in matches, and has no return to pick a best row by
        return None
    done = [(rec["mean_return"], row) for row, rec in rows.items() if rec is not None and row.task == task]
    planned = {row.name for row in rows}
    for path in sorted(((records or out) / "rows").glob(f"{task.replace('/', '_')}__*/row.json")):
        try:
            record = _load_done(path, plan.row_settings(task), f"row {path.parent.name}")
        except (StaleResult, ValueError):  # another budget's row, or a record being written: not this table's
            continue
        if record is not None and record.get("task") == task and path.parent.name not in planned:
            done.append((record["mean_return"], Row(task, record["algo"], int(record["seed"]))))
    if not done:
        return None
    _, best = max(done, key=lambda pair: pair[0])
    folder = out / "videos" / task.replace("/", "_")
    marker = video_marker(records or out, task)
    if marker.is_file() and marker.read_text().strip() == best.name:
        return folder
    if not (out / "runs" / best.name / "model.zip").is_file():
        return None
    _run(_tool("evaluate.py", *_env(task), "--policy", reference_name(task), "--policy",
               out / "runs" / best.name / "model.zip", "--episodes", 2, "--seed", plan.eval_seed, *_cut(plan),
               "--video", "--out", folder / "eval", "--overwrite"), threads, folder / "log.txt")  # fmt: skip
    write_text(marker, best.name + "\n")
    return folder


def _returns(results: dict[str, Any], spec: str) -> list[float]:
    return [float(e["metrics"][RETURN]) for e in results["policies"][spec]["episodes"]]


def _judge(plan: Plan, row: Row, model: Path, evaluation: Path, threads: int) -> dict[str, Any]:
    """A model of a row played against the task's reference on the plan's evaluation seeds (evaluate.py, into
    ``evaluation``): its returns, their mean, its metrics' summary and its paired differences from the reference."""
    reference = reference_name(row.task)
    _run(_tool("evaluate.py", *_env(row.task), "--policy", reference, "--policy", model, *_episodes(plan), "--out",
               evaluation, "--overwrite"), threads, evaluation.parent / "log.txt")  # fmt: skip
    results = json.loads((evaluation / "results.json").read_text())
    spec = next(s for s in results["policies"] if s != reference)
    returns = _returns(results, spec)
    return {"returns": returns, "mean_return": float(np.mean(returns)),
            "summary": results["policies"][spec]["summary"],
            "paired_differences": results["paired_differences"]["policies"][spec]}  # fmt: skip


def run_row(plan: Plan, row: Row, out: Path, threads: int, records: Path | None = None,
            again: bool = False) -> dict[str, Any]:  # fmt: skip
    """Train and evaluate one row in ``out`` (resuming a killed training); returns its record, also written as
    ``row.json`` in ``records`` (default ``out``) with the run's learning curve. ``again``: compute it even where a
    record exists (``--rerun``), which the new record replaces only when it is done."""
    folder = out / "rows" / row.name
    record_path = row_file(records or out, row)
    done = None if again else _load_done(record_path, plan.row_settings(row.task), f"row {row.name}")
    if done is not None:
        return done
    runs = out / "runs"
    run_dir = runs / row.name
    log = folder / "log.txt"
    started = time.time()  # less the training behind a resumed checkpoint: the row's wall time is all its training
    trained_before = (run_dir / "model.zip").is_file()
    resuming = (run_dir / "config.json").is_file() and any((run_dir / "checkpoints").glob("step_*"))
    if (run_dir / "config.json").is_file() and (trained_before or resuming):
        _check_run_plan(run_dir, plan, row)  # a run left by an earlier command goes on under this plan only
    if not trained_before:
        if not resuming and run_dir.exists():  # killed before its first checkpoint: nothing to continue
            _remove_run(run_dir)
            (folder / ATTEMPTS).unlink(missing_ok=True)
        credit = _begin_attempt(folder, run_dir)
        started -= credit
        budget = [] if plan.minutes is None else ["--minutes", f"{max(plan.minutes - credit / 60.0, 0.01):.4f}"]
        if resuming:
            command = _tool("train.py", "--resume", run_dir, "--no-progress", *budget)
        elif is_soccer(row.task):
            command = _tool("train.py", "--soccer", row.task.removeprefix(SOCCER), "--players", SOCCER_PLAYERS,
                            *_match_length(plan, row.task), *_algo_options(plan, row.algo), "--seed", row.seed,
                            "--timesteps",
                            plan.steps(row.task), "--runs-dir", runs, "--run-name", row.name, "--no-progress",
                            *budget)  # fmt: skip
        else:
            command = _tool("train.py", *_env(row.task), *_algo_options(plan, row.algo), "--seed", row.seed,
                            "--timesteps", plan.steps(row.task), "--runs-dir", runs, "--run-name", row.name,
                            "--no-progress", *budget)  # fmt: skip
        start = "resuming from its last checkpoint" if resuming else "training"
        print(f"leaderboard: {row.name}: {start}, to {plan.steps(row.task):,} steps; its progress is in {log}",
              flush=True)  # fmt: skip
        _run(command, threads, log)
    trained = _trained_steps(run_dir)
    if is_soccer(row.task):
        return _soccer_row(plan, row, out, threads, started, trained, records or out)
    reference = reference_name(row.task)
    judged = _judge(plan, row, run_dir / "model.zip", folder / "eval", threads)
    record = {**_row_record(plan, row, trained, started, run_dir, out, records or out), **judged,
              "reference": reference, "reproduce": reproduce(plan, row, trained, reference)}  # fmt: skip
    try:
        record["one_hour"] = one_hour(plan, row, out, threads, trained)
    except RuntimeError as exc:  # the row is done without it; a later command judges its hour again
        print(f"leaderboard: {row.name}: its policy after an hour not judged: {exc}", file=sys.stderr)
    write_json(record_path, record)
    return record


def backfill_judgment(plan: Plan, row: Row, record: dict[str, Any], out: Path, records: Path,
                      threads: int) -> dict[str, Any]:  # fmt: skip
    """A finished row's record brought up to what a row's judgment holds today, where its run is still in
    ``OUT/runs/`` (:func:`_record_of_run`): its policy after an hour (:func:`one_hour`) added where it has none, and
    its final and hour policies judged again where ``evaluate.py`` now reports metrics its record lacks (the mean
    power). A judgment again must give the record's returns (evaluation is seeded), or the record stays as it was;
    so does a record whose run is gone."""
    lacking = [m for m in GENERIC_METRICS if m not in record.get("paired_differences", {})]
    if is_soccer(row.task) or ("one_hour" in record and not lacking) or not _record_of_run(record, out, row):
        return record
    folder = out / "rows" / row.name
    updated = dict(record)
    if lacking:
        judged = _judge(plan, row, out / "runs" / row.name / "model.zip", folder / "eval", threads)
        if judged["returns"] != record["returns"]:
            print(f"leaderboard: {row.name}: judged again, its model gave other returns than its record's; the record "
                  "is kept as it was", file=sys.stderr)  # fmt: skip
            return record
        updated.update(judged)
    if lacking or "one_hour" not in record:
        try:
            hour = one_hour(plan, row, out, threads, record["timesteps"])
        except RuntimeError as exc:
            print(f"leaderboard: {row.name}: its policy after an hour not judged: {exc}", file=sys.stderr)
            hour = record.get("one_hour")
        if hour is not None:
            updated["one_hour"] = hour
    write_json(row_file(records, row), updated)
    added = f"judged again for {', '.join(lacking)}" if lacking else "its policy after an hour of training judged"
    print(f"leaderboard: {row.name}: {added}")
    return updated


def _sha256(path: Path) -> str:
    import hashlib

    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _record_of_run(record: dict[str, Any], out: Path, row: Row) -> bool:
    """Whether ``OUT/runs/<row>/`` holds the run a record was made from: its model's digest where the record keeps
    one, else (a record from before it did) the row's evaluation in ``OUT/rows/<row>/eval/`` played that model and
    gave the record's returns (a rerun killed after its training left another run with as many steps)."""
    model = out / "runs" / row.name / "model.zip"
    if not model.is_file():
        return False
    if "model_sha256" in record:
        return record["model_sha256"] == _sha256(model)
    results = out / "rows" / row.name / "eval" / "results.json"
    if not results.is_file():
        return False
    results = json.loads(results.read_text())
    return str(model) in results.get("policies", {}) and _returns(results, str(model)) == record.get("returns")


def row_command(plan: Plan, row: Row, out: Path, records: Path) -> str:
    """The command that computes ``row`` alone again, into the folders it was made in (its record replaced when
    done, with the verdict of :func:`reproduction`)."""
    alone = replace(plan, tasks=(row.task,), algos=(row.algo,), seeds=(row.seed,),
                    timesteps=((row.task, plan.steps(row.task)),))  # fmt: skip
    folders = ["--out", str(out)] + ([] if Path(records) == Path(out) else ["--records", str(records)])
    return shlex.join(["python", "-m", "agents.leaderboard", *plan_arguments(alone), *folders, "--rerun",
                       f"{row.task}:{row.algo}:{row.seed}"])  # fmt: skip


def _row_record(plan: Plan, row: Row, trained: int, started: float, run_dir: Path, out: Path,
                records: Path) -> dict[str, Any]:  # fmt: skip
    """What every row's record holds: the row, the steps it trained against its plan's, its wall time, its learning
    curve, the command that computes it again and the settings it was made with."""
    steps, values = learning_curve(run_dir)
    keep = np.unique(np.linspace(0, len(steps) - 1, min(len(steps), CURVE_POINTS)).round().astype(int))
    attempts = out / "rows" / row.name / ATTEMPTS
    return {**asdict(row), "row": row.name, "timesteps": trained, "timesteps_planned": plan.steps(row.task),
            # training processes it took: more than one when killed and resumed from a checkpoint (a resumed PPO
            # run does not continue bit for bit: the row's commands then give a close, not the same, result)
            "training_attempts": len(json.loads(attempts.read_text())) if attempts.is_file() else 1,
            "curve": {"steps": steps[keep].tolist(), "values": values[keep].tolist()} if len(steps) else None,
            "capped": trained < plan.steps(row.task), "wall_seconds": time.time() - started,
            "model_sha256": _sha256(run_dir / "model.zip"), "software": software(run_dir),
            "command": row_command(plan, row, out, records), "settings": plan.row_settings(row.task),
            "intervals": INTERVALS}  # fmt: skip


LIBRARIES = ("python", "stable-baselines3", "torch", "mujoco", "gymnasium", "numpy")
"""What a row's training ran on that decides its numbers besides the code (train.py's config.json ``versions``)."""


def software(run_dir: Path) -> dict[str, str] | None:
    """The Python, library versions and commit a row's training ran on, from its run's ``config.json``; None where
    the run keeps none."""
    try:
        versions = json.loads((run_dir / "config.json").read_text()).get("versions")
    except (OSError, ValueError, AttributeError):
        return None
    return {k: str(v) for k, v in versions.items()} if isinstance(versions, dict) else None


def libraries(found: dict[str, str] | None) -> str | None:
    """A record's library versions in words (``python 3.11.7, torch 2.13.0+cpu, ...``), None where it has none."""
    return ", ".join(f"{k} {found.get(k, '?')}" for k in LIBRARIES) if found else None


CODE_PATHS = ("numpy_simd", "torch_cpu")
"""The CPU code paths a row's training ran (envs/common/host.py): numpy's SIMD targets and torch's CPU capability,
which change the last bits of a result on the same library versions."""


def code_paths(found: dict[str, str] | None) -> str | None:
    """A record's CPU code paths in words (``numpy X86_V3 X86_V4 baseline(X86_V2), torch AVX512``), None where the
    record does not keep them (rows trained before runs recorded them)."""
    if not found or not any(k in found for k in CODE_PATHS):
        return None
    return f"numpy {found.get('numpy_simd', '?')}, torch {found.get('torch_cpu', '?')}"


def backfill_software(row: Row, record: dict[str, Any], out: Path, records: Path) -> dict[str, Any]:
    """A finished row's record with the versions its training ran on added, where it has none and its run is still
    in ``OUT/runs/`` (:func:`_record_of_run`); the record as it was otherwise."""
    if "software" in record or not _record_of_run(record, out, row):
        return record
    found = software(out / "runs" / row.name)
    if found is None:
        return record
    record = {**record, "software": found}
    write_json(row_file(records, row), record)
    return record


INTERVALS = "1-or-0 metrics: Wilson, paired Newcombe"
"""What a record's intervals of metrics that are 1 or 0 an episode are (evaluate.py's; agents/evaluation.py)."""


@functools.cache
def task_binary_metrics(task: str) -> tuple[str, ...]:
    """The metrics of a task's episodes that are 1 or 0 an episode (:func:`agents.evaluation.binary_metrics`)."""
    import gymnasium as gym

    import envs  # noqa: F401  (registers the ids)
    from agents.evaluation import binary_metrics

    try:
        env = gym.make(task, **task_kwargs(task))
    except gym.error.Error:  # an id no longer registered (an earlier version's record): none known
        return ()
    try:
        return binary_metrics(env)
    finally:
        env.close()


def backfill_intervals(row: Row, record: dict[str, Any], out: Path, records: Path) -> dict[str, Any]:
    """A record judged before evaluate.py gave a 1-or-0 metric (a fall, a success) a proportion's intervals, brought
    to them (:data:`INTERVALS`) where its numbers determine them: a summary's Wilson interval from its mean and
    count; a paired difference's Newcombe interval from the evaluation's episodes where they are kept
    (``OUT/rows/<row>/eval``, ``one_hour``: the same returns as the record's), or else from the record alone where
    every pair agreed (a bootstrap's point: then the pairs are known from the mean). A paired difference whose
    pairs disagreed and whose episodes are gone keeps its bootstrap interval, named in
    ``bootstrap_intervals_kept``."""
    from agents.evaluation import paired_proportion_ci, wilson_interval

    if is_soccer(row.task) or record.get("intervals") == INTERVALS:
        return record
    binary = task_binary_metrics(row.task)
    updated = json.loads(json.dumps(record))
    kept = []
    for part, folder in ((updated, "eval"), (updated.get("one_hour") or {}, "one_hour")):
        summary, paired = part.get("summary") or {}, part.get("paired_differences") or {}
        episodes = _kept_episodes(out / "rows" / row.name / folder, part.get("returns"))
        for metric in binary:
            s = summary.get(metric)
            if s and s.get("n"):
                s["ci_low"], s["ci_high"] = wilson_interval(round(s["mean"] * s["n"]), s["n"])
            d = paired.get(metric)
            if not (d and d.get("n")):
                continue
            if episodes is not None:
                first, second = (np.array([np.nan if e.get(metric) is None else e[metric] for e in side], dtype=float)
                                 for side in episodes)  # fmt: skip
                keep = np.isfinite(first) & np.isfinite(second)
                d["ci_low"], d["ci_high"] = paired_proportion_ci(first[keep], second[keep])
            elif d["ci_low"] == d["ci_high"] and s and s.get("n") == d["n"]:  # every pair agreed, or every pair
                k = round(s["mean"] * s["n"])  # differed alike: the model's values and the difference give both
                second = np.r_[np.ones(k), np.zeros(d["n"] - k)]
                d["ci_low"], d["ci_high"] = paired_proportion_ci(second - d["mean"], second)
            else:
                kept.append(f"{folder}:{metric}")
    updated["intervals"] = INTERVALS
    if kept:
        updated["bootstrap_intervals_kept"] = kept
    write_json(row_file(records, row), updated)
    print(f"leaderboard: {row.name}: intervals of {', '.join(binary)} made a proportion's"
          + (f" (a bootstrap's kept: {', '.join(kept)})" if kept else ""))  # fmt: skip
    return updated


def _bootstrap_note(rows: dict[Row, dict | None]) -> str:
    """The rows whose paired intervals of a 1-or-0 metric are still a bootstrap's (:func:`backfill_intervals`)."""
    old = sorted(row.name for row, rec in rows.items() if rec and rec.get("bootstrap_intervals_kept"))
    return f"; in {', '.join(old)}, judged before it and its episodes not kept, a bootstrap's" if old else ""


def _kept_episodes(evaluation: Path, returns: list[float] | None) -> tuple[list[dict], list[dict]] | None:
    """The reference's and the model's episode metrics, paired by seed, from an evaluation kept in ``evaluation``
    that gave ``returns``; None where there is none, or it is another."""
    try:
        result = json.loads((evaluation / "results.json").read_text())
        reference, model = list(result["policies"])[:2]
        by_seed = {e["seed"]: e["metrics"] for e in result["policies"][reference]["episodes"]}
        ours = result["policies"][model]["episodes"]
    except (OSError, ValueError, KeyError):
        return None
    if returns is None or [e["metrics"].get(RETURN) for e in ours] != returns:
        return None
    pairs = [(by_seed[e["seed"]], e["metrics"]) for e in ours if e["seed"] in by_seed]
    return [a for a, _ in pairs], [b for _, b in pairs]


def _soccer_row(plan: Plan, row: Row, out: Path, threads: int, started: float, trained: int,
                records: Path) -> dict[str, Any]:  # fmt: skip
    """A soccer row's evaluation and record: its model as the home team against the scripted one on the
    evaluation matches, the Elo that record gives it, and the rating self-play ended with (ratings.json)."""
    from agents.soccer.selfplay import RATINGS_FILE

    folder = out / "rows" / row.name
    run_dir = out / "runs" / row.name
    evaluation = folder / "eval"
    _run(_tool("evaluate.py", *_soccer(row.task, "--home", run_dir / "model.zip", "--away", "scripted"),
               *_matches(plan, row.task), "--out", evaluation, "--overwrite"), threads, folder / "log.txt")  # fmt: skip
    result = json.loads((evaluation / "results.json").read_text())
    counts = [result[k]["count"] for k in ("wins", "draws", "losses")]
    ratings = json.loads((run_dir / RATINGS_FILE).read_text()) if (run_dir / RATINGS_FILE).is_file() else {}
    record = {**_row_record(plan, row, trained, started, run_dir, out, records), "soccer": True,
              "against_scripted": result,
              "elo": elo_against(*counts), "selfplay_elo": ratings.get("ratings", {}).get("learner"),
              "reproduce": [
                  shlex.join(["python", "train.py", "--soccer", row.task.removeprefix(SOCCER), "--players",
                              str(SOCCER_PLAYERS), "--seed", str(row.seed), "--timesteps", str(trained),
                              *map(str, _match_length(plan, row.task)), "--run-name", row.name]),
                  shlex.join(["python", "evaluate.py", *map(str, _soccer(row.task, "--home",
                              f"runs/{row.name}/model.zip", "--away", "scripted")), *map(str, _matches(plan, row.task)),
                              "--out", f"results/{row.name}"])]}  # fmt: skip
    write_json(row_file(records, row), record)
    return record


def _check_run_plan(run_dir: Path, plan: Plan, row: Row) -> None:
    """A killed row's run goes on only under the plan it started with (StaleResult otherwise)."""
    from agents.residual import names_a_gait

    config = json.loads((run_dir / "config.json").read_text())
    algo, residual = row.algo.removesuffix(RESIDUAL), row.algo.endswith(RESIDUAL)
    made_with = config.get("hyperparams", {}).get("env_kwargs") or {}
    started = {"timesteps": config.get("timesteps"), "algo": config.get("algo"),
               "residual": names_a_gait(config.get("hyperparams", {}).get("residual", {})),
               "env_kwargs": {k: made_with[k] for k in task_kwargs(row.task) if k in made_with}}  # fmt: skip
    wanted = {
        "timesteps": plan.steps(row.task),
        "algo": algo,
        "residual": residual,
        "env_kwargs": task_kwargs(row.task),
    }
    if is_soccer(row.task):  # a self-play run's matches
        started["match_seconds"] = (config.get("soccer") or {}).get("match_seconds", MATCH_SECONDS)
        wanted["match_seconds"] = plan.match_length(row.task)
    if started != wanted:
        raise StaleResult(f"{run_dir}: a killed row's run started with {started}, not {wanted}: give --rerun for it, "
                          "or another --out")  # fmt: skip


def _remove_run(run_dir: Path) -> None:
    """Remove a row's run folder, unless a train.py still writes it (a leaderboard killed without its child)."""
    from agents.training import RUN_LOCK
    from envs.common.io import folder_lock

    if (run_dir / RUN_LOCK).is_file():
        with folder_lock(run_dir, "train.py", RUN_LOCK):  # Busy if one still runs
            pass
    shutil.rmtree(run_dir)


ATTEMPTS = "attempts.json"  # in a row's folder: when each training process started, and the time it was credited


def _begin_attempt(folder: Path, run_dir: Path) -> float:
    """Record a training process starting now; returns the training time (s) already behind the checkpoint it
    resumes from, so that a row killed and resumed trains ``--minutes`` in all. That is the time of the attempt that
    wrote the newest checkpoint, from its start to the checkpoint, plus what that attempt was credited itself; what
    a killed process did after its last checkpoint is lost, and not counted."""
    path = folder / ATTEMPTS
    attempts = json.loads(path.read_text()) if path.is_file() else []
    saved = [_written(p) for p in (run_dir / "checkpoints").glob("step_*")]
    credit = (training_seconds(folder, max(saved)) or 0.0) if saved else 0.0
    folder.mkdir(parents=True, exist_ok=True)
    write_json(path, [*attempts, {"start": time.time(), "credit": credit}])
    return credit


def _written(checkpoint: Path) -> float:
    """When a checkpoint was written: its checkpoint.json's time (the folder's own changes when train.py later
    drops an off-policy checkpoint's replay buffer from it)."""
    marker = checkpoint / "checkpoint.json"
    return (marker if marker.is_file() else checkpoint).stat().st_mtime


def training_seconds(folder: Path, when: float) -> float | None:
    """The training time (s) a row had put in at the moment ``when`` (a checkpoint's or its model's time of
    writing): the time of the attempt running then, from its start, plus what that attempt was credited; None
    where the row's folder keeps no record of its attempts (:data:`ATTEMPTS`)."""
    path = folder / ATTEMPTS
    attempts = json.loads(path.read_text()) if path.is_file() else []
    mine = [a for a in attempts if a["start"] <= when]
    return mine[-1]["credit"] + when - mine[-1]["start"] if mine else None


HOUR = 3600.0  # s of training: the suite's goal, a policy trained within an hour on 2 cores that matches its reference


def hour_checkpoint(folder: Path, run_dir: Path, limit: float = HOUR) -> tuple[Path, int, float] | None:
    """The newest checkpoint a row's training had written within ``limit`` s of training time: its model, its env
    steps and its training time; None if it wrote none so soon (or keeps no record of its attempts)."""
    found = None
    for checkpoint in (run_dir / "checkpoints").glob("step_*"):
        seconds = training_seconds(folder, _written(checkpoint))
        steps = int(checkpoint.name.removeprefix("step_"))
        if seconds is not None and seconds <= limit and (found is None or steps > found[1]):
            found = (checkpoint / "model.zip", steps, seconds)
    return found


def one_hour(plan: Plan, row: Row, out: Path, threads: int, trained: int) -> dict[str, Any] | None:
    """The policy a row had after an hour of training, judged as the row is (its reference on the same evaluation
    seeds): the final model where the training took an hour or less (``final``), else the newest checkpoint written
    within the hour, evaluated into ``OUT/rows/<row>/one_hour/``. None where the row's run keeps no record of its
    training time."""
    folder, run_dir = out / "rows" / row.name, out / "runs" / row.name
    final = training_seconds(folder, (run_dir / "model.zip").stat().st_mtime)
    if final is None:
        return None
    if final <= HOUR:
        return {"timesteps": trained, "training_minutes": final / 60.0, "final": True}
    found = hour_checkpoint(folder, run_dir)
    if found is None:
        return {"timesteps": 0, "training_minutes": 0.0, "final": False, "mean_return": None}
    model, steps, seconds = found
    return {"timesteps": steps, "training_minutes": seconds / 60.0, "final": False,
            **_judge(plan, row, model, folder / "one_hour", threads)}  # fmt: skip


def _algo_options(plan: Plan, algo: str) -> list[str]:
    """train.py's options for a row's algorithm: ``--algo``, its hyperparameter file, and ``--residual`` for a
    residual variant."""
    base, residual = algo.removesuffix(RESIDUAL), algo.endswith(RESIDUAL)
    hyper = [] if plan.hyperparams is None else ["--hyperparams", _hyperparams(plan.hyperparams, base)]
    return ["--algo", base, *hyper, *(["--residual", "reference"] if residual else [])]


def reproduce(plan: Plan, row: Row, trained: int, reference: str) -> list[str]:
    """The two commands that give a row's numbers again on any machine: its training for the steps it took (no
    time cap), then its evaluation."""
    run = f"runs/{row.name}"
    return [
        shlex.join(["python", "train.py", *_env(row.task), *_algo_options(plan, row.algo), "--seed", str(row.seed),
                    "--timesteps", str(trained), "--run-name", row.name]),
        shlex.join(["python", "evaluate.py", *_env(row.task), "--policy", reference, "--policy", f"{run}/model.zip",
                    "--episodes", str(plan.episodes), "--seed", str(plan.eval_seed), *map(str, _cut(plan)), "--out",
                    f"results/{row.name}"]),
    ]  # fmt: skip


def _hyperparams(given: str, algo: str) -> str:
    """``--hyperparams``: a file, or a folder of ``<algo>.yml`` files."""
    path = Path(given)
    return str(path / f"{algo}.yml" if path.is_dir() else path)


def _trained_steps(run_dir: Path) -> int:
    """The env steps the run's final model took (SB3's record of the model, the ``data`` entry of model.zip)."""
    import zipfile

    with zipfile.ZipFile(run_dir / "model.zip") as archive:
        return int(json.loads(archive.read("data"))["num_timesteps"])


def plan_arguments(plan: Plan) -> list[str]:
    """The command-line options that reproduce ``plan``."""
    budgets = {n for _, n in plan.timesteps}
    steps = [str(*budgets)] if len(budgets) == 1 else [f"{t}={n}" for t, n in plan.timesteps]
    args = ["--tasks", *plan.tasks, "--algos", *plan.algos, "--seeds", *map(str, plan.seeds), "--timesteps", *steps,
            "--episodes", str(plan.episodes), "--eval-seed", str(plan.eval_seed)]  # fmt: skip
    if plan.minutes is not None:
        args += ["--minutes", f"{plan.minutes:g}"]
    if plan.hyperparams is not None:
        args += ["--hyperparams", plan.hyperparams]
    if plan.max_episode_steps is not None:
        args += ["--max-episode-steps", str(plan.max_episode_steps)]
    if plan.match_seconds:
        args += ["--match-seconds", *(f"{t}={n:g}" for t, n in plan.match_seconds)]
    return args


# --- the table --------------------------------------------------------------------------------------------------
def normalized(score: np.ndarray, baselines: dict[str, Any]) -> np.ndarray:
    """Scores with the random policy at 0 and the reference at 1; NaN where the task's reference scores no better
    than random (no scale to normalize by: :func:`comparable`)."""
    low, high = baselines["random_return"], baselines["reference_return"]
    if not comparable(baselines):
        return np.full(np.shape(score), np.nan)
    return (np.asarray(score, dtype=np.float64) - low) / (high - low)


def comparable(baselines: dict[str, Any]) -> bool:
    """Whether a task's reference beats its random policy, so that its scores can be normalized (a soccer task
    is rated, not normalized)."""
    if baselines.get("soccer"):
        return False
    low, high = baselines["random_return"], baselines["reference_return"]
    return bool(np.isfinite(low) and np.isfinite(high) and high > low)


@contextlib.contextmanager
def numpy_global_seed(seed: int) -> Iterator[None]:
    """numpy's global generator seeded for the block, and put back as it was after it: rliable's stratified bootstrap
    draws its resamples from it (``np.random.choice``), whatever generator it is handed, as do its profiles."""
    state = np.random.get_state()  # noqa: NPY002
    np.random.seed(seed)  # noqa: NPY002
    try:
        yield
    finally:
        np.random.set_state(state)  # noqa: NPY002


def aggregate(scores: dict[str, np.ndarray], seed: int = 0, over_tasks: bool = False) -> dict[str, dict[str, float]]:
    """IQM and its 95% stratified-bootstrap interval per algorithm, ``scores[algo]`` (runs, tasks) (rliable);
    ``over_tasks``: the tasks resampled too (rliable's task bootstrap), for one run a task, where resampling the
    runs within each task alone moves nothing."""
    from rliable import library, metrics

    def iqm(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x)])

    with warnings.catch_warnings(), numpy_global_seed(seed):  # rliable hands arch a RandomState, which arch now
        warnings.filterwarnings("ignore", "random_state is deprecated", FutureWarning)  # warns of in several lines
        points, intervals = library.get_interval_estimates(scores, iqm, reps=BOOTSTRAP_REPS, task_bootstrap=over_tasks,
                                                           random_state=np.random.RandomState(seed))  # fmt: skip
    return {a: {"iqm": float(points[a][0]), "low": float(intervals[a][0, 0]), "high": float(intervals[a][1, 0])}
            for a in scores}  # fmt: skip


def learning_curve(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(env steps, mean episode return) from a run's TensorBoard log."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    if not (run_dir / "tb").is_dir():  # a row whose run folder is gone: no curve
        return np.zeros(0), np.zeros(0)
    acc = EventAccumulator(str(run_dir / "tb"), size_guidance={"scalars": 0})
    acc.Reload()
    if CURVE_TAG not in acc.Tags().get("scalars", []):
        return np.zeros(0), np.zeros(0)
    events = acc.Scalars(CURVE_TAG)
    return np.array([e.step for e in events], dtype=np.float64), np.array([e.value for e in events])


def _curve(record: dict[str, Any], run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """A row's learning curve: from its record, or from its run's TensorBoard log (a record written before records
    held their curve)."""
    if record.get("curve"):
        return np.array(record["curve"]["steps"], dtype=np.float64), np.array(record["curve"]["values"])
    return learning_curve(run_dir)


def score_matrix(by_seed: dict[tuple[str, str], dict[int, float]], algo: str, tasks: list[str],
                 seeds: list[int]) -> np.ndarray:  # fmt: skip
    """(seeds, tasks) normalized scores of ``algo``, each seed's row its own across the tasks."""
    return np.array([[by_seed[algo, t][s] for t in tasks] for s in seeds], dtype=np.float64)


def interim_scores(plan: Plan, ranked: list[str], by_seed: dict[tuple[str, str], dict[int, float]]) -> dict | None:
    """The score over all tasks before every row is done: each algorithm's IQM over the seeds that every normalized
    task has for every algorithm (so that each task weighs the same and every algorithm is scored on the same
    seeds), with its 95% interval. Over one seed a task the stratified bootstrap has no run to resample, so the
    tasks are resampled instead (rliable's task bootstrap): the interval then says how much the score depends on
    which tasks the suite holds. None where no seed is common to every task and algorithm."""
    if not ranked:
        return None
    seeds = sorted(set(plan.seeds).intersection(*(scored.keys() for scored in by_seed.values())))
    if not seeds:
        return None
    over_tasks = len(seeds) == 1
    matrix = {a: score_matrix(by_seed, a, ranked, seeds) for a in plan.algos}
    return {"seeds": seeds, "tasks": len(ranked), "over_tasks": over_tasks,
            "scores": aggregate(matrix, over_tasks=over_tasks)}  # fmt: skip


def build_table(plan: Plan, out: Path, baselines: dict[str, dict], rows: dict[Row, dict | None],
                docs: Path | None, records: Path | None = None) -> dict[str, Any]:  # fmt: skip
    """results.md, results.json and the plots from the rows done (rows not done are listed as such)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    done = {row: rec for row, rec in rows.items() if rec is not None}
    per_task: dict[str, dict[str, dict[str, float]]] = {}
    matrix: dict[str, np.ndarray] = {}
    ranked = [t for t in plan.tasks if comparable(baselines[t])]  # tasks whose scores normalize
    by_seed: dict[tuple[str, str], dict[int, float]] = {}  # (algo, task) -> seed -> normalized score
    for algo in plan.algos:
        for task in ranked:
            scored = {r.seed: float(normalized(done[r]["mean_return"], baselines[task])) for r in done if
                      r.task == task and r.algo == algo}  # fmt: skip
            scored = by_seed[algo, task] = {s: x for s, x in scored.items() if np.isfinite(x)}  # no finite return
            if scored:
                cell = aggregate({algo: np.array(list(scored.values()))[:, None]})[algo]
                per_task.setdefault(task, {})[algo] = {**cell, "seeds": len(scored)}
        if ranked and all(len(by_seed[algo, t]) == len(plan.seeds) for t in ranked):  # every row of it scored
            matrix[algo] = score_matrix(by_seed, algo, ranked, list(plan.seeds))
    overall = aggregate(matrix) if matrix else {}
    interim = interim_scores(plan, ranked, by_seed) if len(overall) < len(plan.algos) else None
    plots = out / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    profiled = matrix  # every algorithm on the same rows: all of them, or until then those they all share
    if interim:
        profiled = {a: score_matrix(by_seed, a, ranked, interim["seeds"]) for a in plan.algos}
    if profiled:
        from rliable import library, plot_utils

        taus = np.linspace(-0.5, 2.0, 101)
        with numpy_global_seed(0):  # rliable's profiles take no generator: they draw from numpy's global one
            profiles, cis = library.create_performance_profile(
                profiled, taus, reps=BOOTSTRAP_REPS, task_bootstrap=bool(interim and interim["over_tasks"])
            )
        fig, ax = plt.subplots(figsize=(6, 4))
        plot_utils.plot_performance_profiles(profiles, taus, performance_profile_cis=cis, ax=ax,
                                             xlabel=r"normalized score $\tau$ (random 0, reference 1)")  # fmt: skip
        ax.legend(loc="lower left")
        if interim:
            ax.set_title(f"{len(ranked)} tasks, {_seeds_named(interim['seeds'])} (the rows all share)")
        _save(fig, plots / "performance_profiles.png")
    for task in plan.tasks:
        fig, ax = plt.subplots(figsize=(6, 4))
        for algo in plan.algos:
            curves = [
                _curve(rec, out / "runs" / r.name) for r, rec in done.items() if r.task == task and r.algo == algo
            ]
            curves = [c for c in curves if len(c[0])]
            if curves:
                grid = np.linspace(0, max(c[0][-1] for c in curves), 50)
                mean = np.mean([np.interp(grid, s, v) for s, v in curves], axis=0)
                ax.plot(grid, mean, label=f"{algo} ({len(curves)} seeds)")
        if not is_soccer(task):  # a soccer task's training return is against its pool, not the script
            ax.axhline(baselines[task]["reference_return"], color="k", ls="--", label=baselines[task]["reference"])
            ax.axhline(baselines[task]["random_return"], color="grey", ls=":", label="random")
        ax.set_xlabel("env steps")
        ax.set_ylabel("episode return (training)")
        ax.set_title(task)
        if ax.get_legend_handles_labels()[0]:
            ax.legend()
        _save(fig, plots / f"curve_{task.replace('/', '_')}.png")
    summary = {"plan": asdict(plan), "baselines": baselines, "per_task": per_task, "overall": overall,
               "interim": interim,
               "rows": {r.name: rec for r, rec in rows.items()}, "command": shlex.join(
                   ["python", "-m", "agents.leaderboard", *plan_arguments(plan)])}  # fmt: skip
    table = (plan, baselines, done, rows, per_task, overall, interim, summary["command"], records or out)
    write_json(out / "results.json", summary, strict=True)
    write_text(out / "results.md", render(*table))
    if docs is not None:  # the page beside the guides links each task to the one that discusses its rows
        write_text(docs, publish_media(render(*table, guides=docs.parent), out, docs, records or out))
    return summary


# where the guides discuss a task's rows, and why a row falls short of its reference where it does: the guide and
# the start of its section's heading, by the kind of task (the first that holds)
DISCUSSED = (
    (is_soccer, "soccer.md", "Self-play"),
    (lambda t: any(k in t for k in ("GoToBall", "ScoreEmptyGoal", "ScoreVsKeeper")), "soccer.md", "Learning on"),
    (lambda t: t.startswith("skitter/Roach"), "velociroach.md", "Policies, real logs"),
    (lambda t: t.startswith("skitter/Xjus"), "xjus.md", "Walking, measured"),
    (lambda t: t.startswith("skitter/BioloidTurn"), "bioloid.md", "Steering, and BioloidTurn"),
    (lambda t: t.startswith("skitter/Bioloid"), "bioloid.md", "PPO against"),
)


def _anchor(guide: Path, heading: str) -> str:
    """The link to the section of ``guide`` whose heading starts with ``heading`` (GitHub's anchor of it), or to the
    guide alone where no heading does."""
    for line in guide.read_text(encoding="utf-8").splitlines():
        title = line.lstrip("#").strip()
        if line.startswith("#") and title.startswith(heading):
            slug = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
            return f"{guide.name}#{slug}"
    return guide.name


def discussion(tasks: list[str], folder: Path) -> str:
    """A paragraph linking each task to the guide (in ``folder``, beside the page) that discusses its rows (each
    section's link found once); empty where no guide is there."""
    by_section: dict[tuple[str, str], list[str]] = {}
    for task in tasks:
        found = next(((name, heading) for holds, name, heading in DISCUSSED if holds(task)), None)
        if found is not None and (folder / found[0]).is_file():
            by_section.setdefault(found, []).append(f"`{task}`")
    parts = [f"[{name}]({_anchor(folder / name, heading)}) ({', '.join(named)})"
             for (name, heading), named in by_section.items()]  # fmt: skip
    if not parts:
        return ""
    return ("What each row learnt, and why a row falls short of its reference where it does, is discussed with the "
            "robot: " + "; ".join(parts) + ".")  # fmt: skip


def publish_media(text: str, out: Path, docs: Path, records: Path | None = None) -> str:
    """The page for ``docs``, its plots and videos copied beside it into a folder of its name (``docs/results/``:
    the leaderboard's own folder is a run's output, not part of a checkout), its links pointing there; a video made
    by an earlier run and published there stays while its row is the task's best (``records``' marker)."""
    media = docs.with_suffix("")
    for png in sorted((out / "plots").glob("*.png")):
        if f"](plots/{png.name})" not in text:  # a plot of an earlier plan's task: not the page's
            continue
        target = media / "plots" / png.name
        target.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(target, lambda tmp, png=png: shutil.copyfile(png, tmp))
        text = text.replace(f"](plots/{png.name})", f"]({media.name}/plots/{png.name})")
    for video in sorted((out / "videos").glob("*/eval/videos/side_by_side.mp4")):
        task = video.parents[2].name
        if f"](videos/{task}/eval/videos/side_by_side.mp4)" not in text:  # an earlier plan's task: not the page's
            continue
        target = media / "videos" / f"{task}.mp4"
        target.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(target, lambda tmp, video=video: shutil.copyfile(video, tmp))
    for marker in sorted((records or out).glob("videos/*/row.txt")):
        task = marker.parent.name
        if (media / "videos" / f"{task}.mp4").is_file():
            text = text.replace(f"](videos/{task}/eval/videos/side_by_side.mp4)",
                                f"]({media.name}/videos/{task}.mp4)")  # fmt: skip
    # a link still into the run folder: the row's run that makes the video is not kept here (a fresh checkout's
    # records name the row, its mp4 was never published); say so rather than link to nothing
    return re.sub(
        r"\[the reference and ([^\]]+)\]\(videos/[^)]+/eval/videos/side_by_side\.mp4\)",
        r"no video: \1's run, which makes it, is not kept here (`--videos` on a `--rerun` of the row makes it again)",
        text,
    )


PAGE_START = "# Results\n\nLearning against each task's reference"  # how every page :func:`render` writes begins
# what the leaderboard writes in --out and in --records: name -> whether it is a folder
OUT_ENTRIES = {"results.json": False, "results.md": False, ".table.lock": False, "plots": True, "rows": True,
               "runs": True, "tasks": True, "videos": True}  # fmt: skip
RECORDS_ENTRIES = {"rows": True, "tasks": True, "videos": True}


def _page_problem(page: Path) -> str | None:
    """Why an existing file is not a page :func:`render` wrote (which the command may replace), or None."""
    try:
        with page.open(encoding="utf-8") as text:
            begins = text.read(len(PAGE_START))
    except (OSError, UnicodeDecodeError) as exc:
        return f"exists and cannot be read as this command's page ({exc})"
    if begins != PAGE_START:
        return "exists and is not a page this command wrote (it would be replaced); give another path"
    return None


def foreign_problem(folder: Path, entries: dict[str, bool]) -> str | None:
    """Why the leaderboard cannot work in ``folder`` (``--out`` or ``--records``, which it adds to and rewrites the
    table of), or None: the folder holds what the leaderboard does not write (a name not in ``entries``, a file
    where it writes a folder or the reverse), or a ``results.json`` or ``results.md`` that is not its own, which it
    would replace."""
    if not folder.is_dir():
        return None
    others = [e.name + "/" * e.is_dir() for e in sorted(folder.iterdir()) if entries.get(e.name) is not e.is_dir()]
    summary, page = folder / "results.json", folder / "results.md"
    if "results.json" in entries and summary.is_file():
        try:
            held = json.loads(summary.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError):
            held = None
        if not (isinstance(held, dict) and {"plan", "rows", "command"} <= held.keys()):
            others.append("results.json")
    if "results.md" in entries and page.is_file() and _page_problem(page) is not None:
        others.append("results.md")
    if not others:
        return None
    shown = ", ".join(others[:5]) + (f" and {len(others) - 5} more" if len(others) > 5 else "")
    return (f"holds what the leaderboard does not write ({shown}), which it would add to or replace; give a folder "
            "of its own (a new one, or one an earlier leaderboard command wrote)")  # fmt: skip


def docs_problem(docs: Path) -> str | None:
    """Why ``--docs`` cannot take the page, or None: it must be a Markdown file whose folder can hold it, and an
    existing file there must be a page this command wrote (it is replaced), never a user's own file. Its media go
    into the folder of its name beside it (``docs/results/``), which may hold only a page's ``plots/`` and
    ``videos/``."""
    if docs.suffix != ".md":
        return "the page is Markdown: give a path ending in .md"
    if docs.is_dir():
        return "is a folder; give the page's file name (e.g. results.md)"
    media = docs.with_suffix("")
    problem = parent_problem(docs)  # a file on the path: nothing below can be read or made
    if problem:
        return problem
    if media.exists() and not media.is_dir():
        return f"its media folder {media} is a file"
    if docs.exists():
        problem = _page_problem(docs)
        if problem:
            return problem
    elif media.is_dir() and any(e.name not in ("plots", "videos") or not e.is_dir() for e in media.iterdir()):
        return f"{media} holds other files than a page's plots and videos; give another path"
    return None


def _save(fig: Any, path: Path) -> None:
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=100, bbox_inches="tight"))
    import matplotlib.pyplot as plt

    plt.close(fig)


def _cell(cell: dict[str, float] | None, seeds: int, comparable: bool) -> str:
    """A task's cell: the IQM and interval, and how many seeds if not all; "not run", or "-" where no score
    normalizes."""
    if cell is None:
        return "not run" if comparable else "-"
    if cell["seeds"] == 1 and seeds > 1:
        return f"{_interval(cell)} (1 of {seeds} seeds: no interval)"
    return _interval(cell) + ("" if cell["seeds"] == seeds else f" ({cell['seeds']} of {seeds} seeds)")


def _rating(r: dict[str, float]) -> str:
    """An Elo with its 95% interval; a record of one way only (every match lost, or won) has no finite estimate, and
    is given by the interval's one finite end."""
    if r["elo"] == -np.inf:
        return f"at most {r['high']:.0f} (no point scored)"
    if r["elo"] == np.inf:
        return f"at least {r['low']:.0f} (every match won)"
    return f"{r['elo']:.0f} [{r['low']:.0f}, {r['high']:.0f}]"


def _soccer_section(plan: Plan, baselines: dict, rows: dict[Row, dict | None]) -> list[str]:
    """The soccer tasks' ratings: each row's team against the scripted one (the anchor, Elo 1000) on the evaluation
    matches, the random team's from the scripted team's record against it, and the rating self-play ended with."""
    tasks = [t for t in plan.tasks if is_soccer(t)]
    if not tasks:
        return []
    lines = ["", "## Soccer", "", f"Self-play (`train.py --soccer`, {SOCCER_PLAYERS} a side) rated against the "
             f"scripted team, the anchor at Elo {SCRIPTED_ELO:.0f}: a team's Elo is the rating at which Elo expects "
             f"its score over the {plan.episodes} evaluation matches (wins 1, draws 1/2) against the scripted team, "
             "with the score's 95% Wilson interval carried through (an open end where every match went one way). "
             "The random team is rated from the scripted team's record against it. Self-play's own rating is "
             "against its pool. Matches last " + ", ".join(f"{plan.match_length(t):g} s ({t})" for t in tasks)
             + ", in training and evaluation.",
             "", "| row | steps trained | wall time (min) | wins-draws-losses vs scripted | goal difference | Elo "
             "(95%) | Elo in self-play |", "|---" * 7 + "|"]  # fmt: skip
    for task in tasks:
        b = baselines[task]
        vs = b["scripted_vs_random"]
        lines.append(f"| `{task}` scripted | - | - | {vs['wins']['count']}-{vs['draws']['count']}-"
                     f"{vs['losses']['count']} vs random | {vs['goal_difference']['mean']:+.2f} | "
                     f"{SCRIPTED_ELO:.0f} (anchor); random {_rating(b['random_elo'])} | - |")  # fmt: skip
        for row, rec in rows.items():
            if row.task != task:
                continue
            if rec is None:
                lines.append(f"| {row.name} | not run | | | | | |")
                continue
            r, gd = rec["against_scripted"], rec["against_scripted"]["goal_difference"]
            selfplay = "-" if rec.get("selfplay_elo") is None else f"{rec['selfplay_elo']:.0f}"
            record = f"{r['wins']['count']}-{r['draws']['count']}-{r['losses']['count']}"
            lines.append(f"| {row.name} | {rec['timesteps']:,} | {rec['wall_seconds'] / 60:.0f} | {record} | "
                         f"{gd['mean']:+.2f} [{gd['ci_low']:+.2f}, {gd['ci_high']:+.2f}] | {_rating(rec['elo'])} | "
                         f"{selfplay} |")  # fmt: skip
    return lines


def _paired(diff: dict[str, Any], metric: str) -> str:
    """A paired difference and its 95% interval, as the rows' tables show it ("-" where there is none)."""
    d = diff.get(metric)
    if not d or d.get("mean") is None or d.get("ci_low") is None:
        return "-"
    return f"{d['mean']:+.3f} [{d['ci_low']:+.3f}, {d['ci_high']:+.3f}]"


def at_least_as_good(diff: dict[str, Any], metric: str) -> bool | None:
    """Whether a model is not shown worse than its reference on ``metric`` by their paired difference (the model's
    less the reference's): its 95% interval reaches zero or the better side of it. None where it has no interval."""
    d = diff.get(metric)
    if not d or d.get("ci_low") is None or d.get("ci_high") is None:
        return None
    return d["ci_low"] <= 0.0 if metric in LOWER_IS_BETTER else d["ci_high"] >= 0.0


def _hour_section(baselines: dict, rows: dict[Row, dict | None]) -> list[str]:
    """Each finished row's policy after an hour of training (:func:`one_hour`) against its reference: whether it
    matches or beats it on the task's metric at no worse energy (:func:`energy_metric`)."""
    done = [(row, rec) for row, rec in rows.items() if rec is not None and not is_soccer(row.task)]
    if not done:
        return []
    lines = ["", "## After an hour of training", "",
             f"The goal: a policy trained within {HOUR / 3600:g} hour on 2 cores, from the shipped hyperparameters, "
             "matches or beats its reference on the task's metric at no worse energy: the cost of transport (energy "
             "per metre); on a turn, which asks for no travel, the mean electrical power; on an academy task, whose "
             "episode ends when its task is done, the energy of the episode (a record from before evaluate.py "
             "reported these keeps the cost of transport). Each row's policy "
             "after an hour is the newest checkpoint its training had written within 60 minutes of training time "
             "(the final model if it took less), on the host it ran on and as busy as that host was: a row trained "
             "beside other work reaches fewer steps in its hour than on an idle host. It is judged as the row is, "
             "against the reference on the same evaluation seeds. \"Not shown worse\" means the paired "
             "difference's 95% interval reaches zero or the better side of it: a wide interval passes easily, so read "
             "the intervals.", "",
             "| row | steps after 1 h | training time (min) | normalized | the task's metric vs reference | "
             "energy vs reference | not shown worse than the reference |",
             "|---" * 7 + "|"]  # fmt: skip
    for row, rec in done:
        hour = rec.get("one_hour")
        if hour is None:
            lines.append(f"| {row.name} | not judged: its record is older than this table, or its run is not kept "
                         "| | | | | |")  # fmt: skip
            continue
        source = rec if hour["final"] else hour
        if source.get("mean_return") is None:
            lines.append(f"| {row.name} | no checkpoint within the hour | | | | | no |")
            continue
        diff = source["paired_differences"]
        metric, unit = task_metric(diff)
        judged = {m: at_least_as_good(diff, m) for m in (metric, energy_metric(diff)[0])}
        worse = [m.replace("_", " ") for m, ok in judged.items() if ok is False]
        answer = "yes" if all(judged.values()) else ("no: " + " and ".join(worse) + " worse" if worse else "-")
        score = float(normalized(source["mean_return"], baselines[row.task]))
        final = " (its final model)" if hour["final"] else ""
        lines.append(f"| {row.name} | {hour['timesteps']:,}{final} | {hour['training_minutes']:.0f} | {score:.2f} | "
                     f"{metric} {_paired(diff, metric)}{unit} | {_energy_cell(diff)} | {answer} |")  # fmt: skip
    return lines


def _share(record: dict[str, Any], baselines: dict[str, Any], metric: str) -> str:
    """A row's share of ``metric`` (falls: of its episodes; contact: of its time), the reference's in brackets."""

    def mean(summary: dict[str, Any] | None) -> float | None:
        value = (summary or {}).get(metric)
        return value.get("mean") if isinstance(value, dict) else None

    mine, reference = mean(record.get("summary")), mean(baselines.get("reference_summary"))
    if mine is None:
        return "-"
    return f"{mine:.0%}" + ("" if reference is None else f" ({reference:.0%})")


def _rows(count: int) -> str:
    return f"{count} row" if count == 1 else f"{count} rows"


def _budget(plan: Plan) -> str:
    """The steps a row trains, in words: one number, or one per task."""
    budgets = {n for _, n in plan.timesteps}
    if len(budgets) == 1:
        return f"{budgets.pop():,} env steps a row"
    return "env steps a row: " + ", ".join(f"{t} {n:,}" for t, n in plan.timesteps)


def _seeds_named(seeds: list[int]) -> str:
    return f"seed {seeds[0]}" if len(seeds) == 1 else "seeds " + ", ".join(map(str, seeds))


def _interval(a: dict[str, float]) -> str:
    """An IQM and its interval; over one seed, the score alone (a bootstrap of one run has no spread to show)."""
    if a.get("seeds") == 1:
        return f"{a['iqm']:.2f}"
    return f"{a['iqm']:.2f} [{a['low']:.2f}, {a['high']:.2f}]"


def residual_comparison(plan: Plan, baselines: dict, per_task: dict) -> list[str]:
    """The page's lines comparing each residual variant with its plain algorithm, task by task where both have rows:
    their normalized IQMs with intervals and whether the intervals tell them apart (two seeds or more on each)."""
    lines = []
    tasks = [t for t in plan.tasks if not is_soccer(t) and comparable(baselines[t])]
    for base in [a for a in plan.algos if not a.endswith(RESIDUAL) and a + RESIDUAL in plan.algos]:
        residual = base + RESIDUAL
        both = [t for t in tasks if {base, residual} <= set(per_task.get(t, {}))]
        lines += ["", f"{residual} against {base}, on the {len(both)} of {len(tasks)} tasks with rows of both "
                  "(normalized IQM over seeds, 95% interval; told apart only where the intervals of two seeds or more "
                  "on each side do not overlap)" + (":" if both else "."), ""]  # fmt: skip
        for task in both:
            r, b = per_task[task][residual], per_task[task][base]
            if min(r["seeds"], b["seeds"]) < 2:
                verdict = "not told apart: one seed on a side"
            elif r["low"] > b["high"]:
                verdict = "the residual ahead"
            elif r["high"] < b["low"]:
                verdict = "the residual behind"
            else:
                verdict = "not told apart: the intervals overlap"
            n = r["seeds"]
            lines.append(f"- `{task}`: {residual} {_interval(r)} ({n} seed{'s' * (n != 1)}) against {base} "
                         f"{_interval(b)} ({b['seeds']}): {verdict}")  # fmt: skip
        if not both:
            lines.pop()
    return lines


def render(plan: Plan, baselines: dict, done: dict[Row, dict], rows: dict[Row, dict | None], per_task: dict,
           overall: dict, interim: dict | None, command: str, records: Path,
           guides: Path | None = None) -> str:  # fmt: skip
    budget = _budget(plan) + ("" if plan.minutes is None else f", at most {plan.minutes:g} min")
    lines = [
        "# Results",
        "",
        f"Learning against each task's reference: {', '.join(plan.algos)} on {len(plan.tasks)} tasks, seeds "
        f"{', '.join(map(str, plan.seeds))}; {budget}; {plan.episodes} evaluation episodes per row on seeds "
        f"{plan.eval_seed}-{plan.eval_seed + plan.episodes - 1}. Scores are normalized per task: a random policy 0, "
        "the reference 1. IQM over seeds with 95% stratified-bootstrap intervals (rliable). Soccer academy tasks "
        "are learnt in the commands mode, against the scripted player.",
        "",
        f"Reproduce the table: `{command}`; each row's own command is in results.json.",
        "",
        "| task | reference | reference return | random return | " + " | ".join(plan.algos) + " |",
        "|---|---|---|---|" + "---|" * len(plan.algos),
    ]
    seeds = len(plan.seeds)
    for task in [t for t in plan.tasks if not is_soccer(t)]:
        b = baselines[task]
        cells = [_cell(per_task.get(task, {}).get(a), seeds, comparable(b)) for a in plan.algos]
        lines.append(f"| `{task}` | {b['reference']} | {b['reference_return']:.1f} | {b['random_return']:.1f} | "
                     + " | ".join(cells) + " |")  # fmt: skip
    unranked = [t for t in plan.tasks if not comparable(baselines[t]) and not is_soccer(t)]
    if unranked:
        lines += ["", "Not normalized (the reference scores no better than random there): "
                  + ", ".join(f"`{t}`" for t in unranked) + "."]  # fmt: skip
    narrow = [t for t in plan.tasks if not is_soccer(t) and comparable(baselines[t])
              and baselines[t]["reference_return"] - baselines[t]["random_return"]
              < NARROW_MARGIN * abs(baselines[t]["reference_return"])]  # fmt: skip
    if narrow:
        lines += ["", "The reference beats a random policy by little on "
                  + ", ".join(f"`{t}` ({baselines[t]['reference_return'] - baselines[t]['random_return']:.0f} of "
                              f"{baselines[t]['reference_return']:.0f})" for t in narrow)
                  + ": a normalized score there magnifies a lead in return; read the returns beside it."]  # fmt: skip
    if seeds < 4:
        lines += ["", f"Over {seeds} seeds or fewer the interquartile mean trims nothing: it is the mean."]
    lines += residual_comparison(plan, baselines, per_task)
    missing = [a for a in plan.algos if a not in overall]
    if overall:
        lines += ["", "Over all tasks: " + "; ".join(f"{a} {_interval(v)}" for a, v in overall.items()) + ".", "",
                  "![performance profiles](plots/performance_profiles.png)"]  # fmt: skip
    if missing:
        lines += ["", "No score over all tasks for " + ", ".join(missing) + ": some of their rows are not done."]
    if interim:
        named = _seeds_named(interim["seeds"])
        how = ("one seed a task: the interval resamples the tasks (rliable's task bootstrap), so it says how much "
               "the score depends on which tasks are in the suite, not on training's chance" if interim["over_tasks"]
               else "the interval resamples the seeds within each task (stratified bootstrap)")  # fmt: skip
        lines += ["", f"Until then, over the {interim['tasks']} normalized tasks on the rows every task has for every "
                  f"algorithm ({named}; the other rows left out, so that each task weighs the same): "
                  + "; ".join(f"{a} {_interval(v)}" for a, v in interim["scores"].items())
                  + f". IQM of the normalized scores, 95% interval; {how}. Performance profiles on the same rows "
                  "(the share of runs scoring above each normalized score):", "",
                  "![performance profiles](plots/performance_profiles.png)"]  # fmt: skip
    paragraph = "" if guides is None else discussion(list(plan.tasks), guides)
    if paragraph:
        lines += ["", paragraph]
    lines += ["", "## Rows", "", "The task's metric is a walk's speed, a turn's yaw-rate error (lower is better) or an "
              "academy task's success (1 or 0 an episode); it and the energy (the cost of transport, a turn's "
              "mean electrical power or an academy episode's energy) are the model's less the reference's, paired "
              "over the evaluation seeds, with 95% intervals (of a success, Newcombe's for paired proportions"
              + _bootstrap_note(rows) + "). A row's falls and the time its "
              "body touched the ground with more than its feet are its model's over the evaluation episodes; the "
              "reference's are in brackets.", "",
              "| row | steps trained | wall time (min) | mean return | normalized | the task's metric vs reference | "
              "energy vs reference | falls | time touching with more than feet |",
              "|---" * 9 + "|"]  # fmt: skip
    for row, rec in rows.items():
        if is_soccer(row.task):
            continue
        if rec is None:
            lines.append(f"| {row.name} | not run | | | | | | | |")
            continue
        diff = rec["paired_differences"]
        metric, unit = task_metric(diff)
        capped = " (capped by --minutes)" if rec["capped"] else ""
        score = float(normalized(rec["mean_return"], baselines[row.task]))
        wall = f"{rec['wall_seconds'] / 60:.0f}" if "wall_seconds" in rec else "-"
        lines.append(f"| {row.name} | {rec['timesteps']:,}{capped} | {wall} | {rec['mean_return']:.1f} | {score:.2f} | "
                     f"{metric} {_paired(diff, metric)}{unit} | {_energy_cell(diff)} | "
                     f"{_share(rec, baselines[row.task], 'falls')} | "
                     f"{_share(rec, baselines[row.task], 'non_foot_contact')} |")  # fmt: skip
    resumed = [f"{row.name} ({rec['training_attempts']})" for row, rec in rows.items()
               if rec and rec.get("training_attempts", 1) > 1]  # fmt: skip
    if resumed:
        lines += ["", "Rows trained in several attempts (killed and resumed from a checkpoint; a resumed run does not "
                  "continue bit for bit, so its commands give a close result, not the same): "
                  + ", ".join(resumed) + "."]  # fmt: skip
    again = [(row, rec["reproduction"]) for row, rec in rows.items() if rec and "reproduction" in rec]
    if again:
        lines += ["", "Rows computed again with their own command (`--rerun`), against their earlier record. A row's "
                  "interval spans its evaluation episodes of one trained policy, not the training's own chance: a "
                  "row computed again gives the same number only if it trains bit for bit (the same code, library "
                  "versions and threads, in one sitting); otherwise it is another draw of the training, which can "
                  "fall outside, as the spread over seeds shows:", ""]  # fmt: skip
        lines += [f"- {row.name}: {verdict(r)}." for row, r in again]
    lines += _software_lines(rows)
    lines += _baseline_host_lines(plan, baselines)
    lines += _hour_section(baselines, rows)
    lines += _soccer_section(plan, baselines, rows)
    lines += ["", "## Learning curves", ""]
    lines += [f"![{t}](plots/curve_{t.replace('/', '_')}.png)" for t in plan.tasks]
    videos = {t: video_marker(records, t) for t in plan.tasks}
    videos = {t: m.read_text().strip() for t, m in videos.items() if m.is_file()}
    if videos:
        lines += ["", "## Videos", "", "The reference and a row's model side by side, on the first evaluation "
                  "seed:", ""]  # fmt: skip
        lines += [
            f"- `{t}`: [the reference and {name}](videos/{t.replace('/', '_')}/eval/videos/side_by_side.mp4)"
            for t, name in videos.items()
        ]
    return "\n".join(lines) + "\n"


# --- command line -----------------------------------------------------------------------------------------------
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = ToolParser(prog="python -m agents.leaderboard", description=__doc__)
    parser.add_argument("--tasks", nargs="+", required=True, help="env ids")
    parser.add_argument("--algos", nargs="+", default=["ppo"], metavar="ALGO",
                        choices=[f"{a}{v}" for a in ("ppo", "sac", "td3") for v in ("", RESIDUAL)],
                        help=f"ppo, sac, td3, or one of them with {RESIDUAL} (a residual policy on the task's "
                             "reference gait, agents/residual.py): ppo+residual")  # fmt: skip
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument(
        "--timesteps",
        nargs="+",
        required=True,
        metavar="N|TASK=N",
        help="env steps a row trains: one number for every task, or TASK=N for each task",
    )
    parser.add_argument("--minutes", type=float, help="wall-time cap of a row's training")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes per row (default 20)")
    parser.add_argument("--eval-seed", type=int, default=1000, help="the first evaluation seed (default 1000)")
    parser.add_argument("--max-episode-steps", type=int, help="cut evaluation episodes short (default: the task's)")
    parser.add_argument("--hyperparams", help="a hyperparameter file, or a folder of <algo>.yml (default hyperparams/)")
    parser.add_argument("--out", default="results/leaderboard", help="the leaderboard's working folder: runs, "
                        "evaluations, plots and the table")  # fmt: skip
    parser.add_argument("--records", help="keep the finished rows' and tasks' records here (default: --out); "
                        "make leaderboard keeps them in docs/results/records/, part of a checkout, so that "
                        "a table built over several machines' runs keeps every row")  # fmt: skip
    parser.add_argument("--docs", help="also write the page here (docs/results.md)")
    parser.add_argument("--workers", type=int, default=1, help="rows at a time in the local pool (default 1)")
    parser.add_argument("--address", help="run rows as Ray tasks on the cluster at HOST:PORT")
    parser.add_argument("--videos", action="store_true",
                        help="a video per task: its reference and its best row side by side")  # fmt: skip
    parser.add_argument("--rerun", nargs="+", default=[], metavar="TASK:ALGO:SEED", help="compute these rows again")
    parser.add_argument("--match-seconds", nargs="+", default=[], metavar="TASK=S",
                        help=f"a soccer task's matches in training and evaluation, s (default {MATCH_SECONDS:g}): "
                             "as long as its robot needs to score")  # fmt: skip
    parser.add_argument(
        "--table-only",
        action="store_true",
        help="train nothing: write the table of the rows done so far (the others listed as not run; a task's reference "
        "is evaluated where no earlier run has)",
    )
    args = parser.parse_args(argv)
    import gymnasium as gym

    import envs  # noqa: F401
    from agents.training import SOCCER_ROBOTS

    def robot_soccer(task: str) -> bool:  # soccer/ROBOT of a robot that plays
        return is_soccer(task) and task.removeprefix(SOCCER) in SOCCER_ROBOTS

    if len(set(args.tasks)) != len(args.tasks):
        parser.error(f"--tasks must not repeat a task: {' '.join(args.tasks)}")
    for task in args.tasks:
        if is_soccer(task):
            if not robot_soccer(task):
                parser.error(f"--tasks {task!r}: soccer/ROBOT takes one of {', '.join(SOCCER_ROBOTS)}")
            if not any(a in SELFPLAY_ALGOS for a in args.algos):
                parser.error(f"--tasks {task!r}: self-play trains with {' or '.join(SELFPLAY_ALGOS)} alone, and "
                             f"--algos has none of it ({', '.join(args.algos)}); the plan's other algorithms train "
                             "its gym tasks only")  # fmt: skip
        elif (problem := skitter_env_problem(task)) is not None:
            parser.error(f"--tasks: {problem} (or soccer/ROBOT)")
    args.timesteps = _task_budgets(parser, args.tasks, args.timesteps, lambda t: t in gym.registry or robot_soccer(t))
    args.match_seconds = _match_lengths(parser, args.tasks, args.match_seconds, robot_soccer)
    checks = (
        ("--episodes", args.episodes, 2),
        ("--workers", args.workers, 1),
        ("--max-episode-steps", args.max_episode_steps, 1),
    )
    for name, value, least in checks:
        if value is not None and value < least:
            parser.error(f"{name} must be at least {least}, got {value}")
    cores = os.cpu_count() or 1
    if args.address is None and args.workers > cores:  # each row in the local pool takes a core at least
        parser.error(f"--workers {args.workers}: this machine has {cores} cores and each row runs on one at least; "
                     f"give at most {cores}")  # fmt: skip
    if args.minutes is not None and not 0 < args.minutes < 10**6:  # train.py's own bound: finite
        parser.error(f"--minutes must be a positive number of minutes under 10**6, got {args.minutes}")
    negative = [s for s in (*args.seeds, args.eval_seed) if s < 0]
    if negative:
        parser.error(f"seeds must be whole numbers >= 0, got {negative[0]}")
    if len(set(args.seeds)) != len(args.seeds) or len(set(args.algos)) != len(args.algos):
        parser.error("--seeds and --algos must not repeat themselves")
    if args.hyperparams is not None and not Path(args.hyperparams).exists():
        parser.error(f"--hyperparams {args.hyperparams}: no such file or folder")
    if args.hyperparams is not None and Path(args.hyperparams).resolve() == (ROOT / "hyperparams").resolve():
        args.hyperparams = None  # the shipped files, however named: the same rows as without the option
    for name in ("out", "records"):
        value = getattr(args, name)
        problem = None if value is None else current_folder_problem(value, f"--{name}")
        if problem:
            parser.error(problem)
        if value is not None and Path(value).exists() and not Path(value).is_dir():
            parser.error(f"--{name} {value}: exists and is not a folder")
        shared = name == "records" and value is not None and Path(value).resolve() == Path(args.out).resolve()
        entries = OUT_ENTRIES if name == "out" or shared else RECORDS_ENTRIES
        problem = None if value is None else foreign_problem(Path(value), entries)
        if problem:
            parser.error(f"--{name} {value}: {problem}")
        problem = None if value is None else parent_problem(Path(value) / "row")  # in it, or where it is made
        if problem:
            parser.error(f"--{name} {value}: {problem}")
    if args.docs is not None:
        problem = docs_problem(Path(args.docs))
        if problem:
            parser.error(f"--docs {args.docs}: {problem}")
    reruns = []
    for text in args.rerun:
        parts = text.rsplit(":", 2)
        if len(parts) != 3 or not parts[2].isdigit():
            parser.error(f"--rerun {text!r}: expected TASK:ALGO:SEED")
        reruns.append(Row(parts[0], parts[1], int(parts[2])))
    args.rerun = reruns
    if args.table_only and args.rerun:
        parser.error("--table-only trains nothing: it cannot --rerun rows")
    if args.table_only and args.address is not None:
        parser.error(f"--table-only trains nothing: it runs nothing on Ray (--address {args.address})")
    return args


def _task_budgets(
    parser: argparse.ArgumentParser, tasks: list[str], given: list[str], known: Callable[[str], bool]
) -> tuple[tuple[str, int], ...]:
    """``--timesteps``: N for every task, or TASK=N for each; errors name the item at fault.

    A budget for a known task outside ``--tasks`` is ignored, so one list of budgets (the Makefile's) serves a run of
    any of its tasks; an unknown name is refused as a typo.
    """

    def count(text: str, item: str) -> int:
        try:
            value = int(text.replace("_", ""))
        except ValueError:
            parser.error(f"--timesteps {item!r}: expected a whole number of env steps")
        if value < 1:
            parser.error(f"--timesteps {item!r}: must be at least 1, got {value}")
        return value

    if len(given) == 1 and "=" not in given[0]:
        return tuple((t, count(given[0], given[0])) for t in tasks)
    budgets: dict[str, int] = {}
    for item in given:
        task, sep, steps = item.rpartition("=")
        if not sep:
            parser.error(f"--timesteps {item!r}: give one number, or TASK=N for every task")
        if task not in tasks and not known(task):
            parser.error(f"--timesteps {item!r}: unknown task {task!r} (an env id, or soccer/ROBOT)")
        if task in budgets:
            parser.error(f"--timesteps {item!r}: {task} is given twice")
        budgets[task] = count(steps, item)
    missing = [t for t in tasks if t not in budgets]
    if missing:
        parser.error(f"--timesteps: no budget for {', '.join(missing)}")
    return tuple((t, budgets[t]) for t in tasks)


def _match_lengths(parser, tasks: list[str], given: list[str],
                   robot_soccer: Callable[[str], bool]) -> tuple[tuple[str, float], ...]:  # fmt: skip
    """``--match-seconds TASK=S ...``: each a soccer task (soccer/ROBOT), once, in (0, 3600] s; those equal to
    MATCH_SECONDS are left out (a plan's settings hold only a length that is not the default). As with
    ``--timesteps``, a length for a soccer task outside ``--tasks`` is ignored, so that the Makefile's one list
    serves a run of any of its tasks; ``robot_soccer`` says which names are soccer tasks."""
    lengths: dict[str, float] = {}
    for item in given:
        task, sep, text = item.rpartition("=")
        if not sep or not robot_soccer(task):
            parser.error(f"--match-seconds {item!r}: expected TASK=S for a soccer task (soccer/ROBOT)")
        if task in lengths:
            parser.error(f"--match-seconds {item!r}: {task} is given twice")
        try:
            seconds = float(text)
        except ValueError:
            parser.error(f"--match-seconds {item!r}: {text!r} is not a number of seconds")
        if not 0 < seconds <= 3600:
            parser.error(f"--match-seconds {item!r}: must be in (0, 3600] s, got {text}")
        lengths[task] = seconds
    return tuple((t, lengths[t]) for t in tasks if t in lengths and lengths[t] != MATCH_SECONDS)


def main(argv: list[str] | None = None) -> int:
    from envs.common.io import Busy, interrupted_exit_code, sigterm_as_interrupt

    args = parse_args(argv)
    plan = Plan(tuple(args.tasks), tuple(args.algos), tuple(args.seeds), args.timesteps, args.minutes,
                args.episodes, args.eval_seed, args.hyperparams, args.max_episode_steps,
                args.match_seconds)  # fmt: skip
    out = Path(args.out)
    records = Path(args.records) if args.records else out
    try:
        _check_plan(plan, args.rerun, records)
        if args.address is not None and not args.table_only:  # joined before anything runs or is removed
            check_address(args.address)
            init_ray(args.address)
    except (StaleResult, ValueError, ClusterError) as exc:
        print(f"leaderboard: error: {exc}", file=sys.stderr)
        return 2
    try:
        with sigterm_as_interrupt():
            return _run_plan(plan, args, out, records)
    except Busy as exc:
        print(exc, file=sys.stderr)
        return 1
    except StaleResult as exc:  # baselines another command on the folder wrote with other settings meanwhile
        print(f"leaderboard: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(f"leaderboard: interrupted; finished rows are kept in {records}, and a killed row's training resumes "
              "from its last checkpoint when the command runs again", file=sys.stderr)  # fmt: skip
        return interrupted_exit_code(exc)


def _check_plan(plan: Plan, reruns: list[Row], records: Path) -> None:
    """Everything a command can be refused for, before anything runs or is removed: rows to rerun that are not in
    the plan, hyperparameter files without an entry for a task, finished rows and baselines of other settings."""
    from agents.training import entry_key, load_hyperparams, read_yaml

    for row in reruns:
        if row not in plan.rows:
            raise ValueError(f"--rerun {row.task}:{row.algo}:{row.seed}: not a row of this plan")

    def file_of(base: str) -> Path:
        return Path(_hyperparams(plan.hyperparams, base)) if plan.hyperparams else ROOT / "hyperparams" / f"{base}.yml"

    for base in {a.removesuffix(RESIDUAL) for a in plan.algos}:
        table = read_yaml(file_of(base))
        missing = [t for t in plan.tasks if not isinstance(table, dict) or not isinstance(table.get(t), dict)]
        if missing:
            raise ValueError(f"{file_of(base)}: no entry for {', '.join(missing)}")
    for algo in plan.algos:  # every entry a row's train.py takes, checked as train.py checks it (ConfigError)
        base, path = algo.removesuffix(RESIDUAL), file_of(algo.removesuffix(RESIDUAL))
        for task in (t for t in plan.tasks if not is_soccer(t)):  # a soccer entry: checked by self-play's start
            load_hyperparams(path, entry_key(path, task, algo.endswith(RESIDUAL)), base)
    for task in plan.tasks:
        _load_done(task_file(records, task), plan.task_settings(task), task)
    for row in plan.rows:
        if row not in reruns:
            _load_done(row_file(records, row), plan.row_settings(row.task), f"row {row.name}")


def _software_lines(rows: dict[Row, dict | None]) -> list[str]:
    """The library versions the done rows trained on, grouped, and the rows whose records do not say."""
    groups: dict[str, list[str]] = {}
    for row, rec in rows.items():
        if rec:
            found = rec.get("software")
            words, paths = libraries(found), code_paths(found)
            key = (words or "") + (f"; CPU code paths {paths}" if words and paths else "")
            groups.setdefault(key, []).append(row.name)
    if not groups:
        return []
    intro = ("Library versions the rows trained on (train.py's config.json), and the CPU code paths where the record "
             "keeps them (numpy's SIMD targets and torch's CPU capability: the same seed gives the same bits only on "
             "the same versions and paths):")  # fmt: skip
    return _grouped(intro, groups, "rows trained before records kept them")


def _grouped(intro: str, groups: dict[str, list[str]], unrecorded: str) -> list[str]:
    """A paragraph ``intro`` and a bullet per group (what they share: their names), the group without a key (its
    records do not say) last, as ``unrecorded``."""
    lines = ["", intro, ""]
    lines += [f"- {key}: {', '.join(names)}." for key, names in groups.items() if key]
    if "" in groups:
        lines.append(f"- not recorded ({unrecorded}): {', '.join(groups[''])}.")
    return lines


def _baseline_host_lines(plan: Plan, baselines: dict[str, dict]) -> list[str]:
    """Where each task's reference and random returns (the normalization's 1 and 0) were played: numpy's code paths
    on that host, grouped, and the tasks whose records do not say. A row's paired comparison plays the reference
    again on the row's own host, so its reference return there can differ from the task's where the paths do."""
    groups: dict[str, list[str]] = {}
    for task in plan.tasks:
        host = baselines[task].get("host")
        key = f"numpy {host.get('numpy_simd', '?')}" if isinstance(host, dict) else ""
        groups.setdefault(key, []).append(f"`{task}`")
    intro = ("The tasks' reference and random returns (a normalized 1 and 0) are played once per task; a row's "
             "paired comparison plays the reference again, on the row's host. Where the two hosts' numpy code paths "
             "differ, the last bits of a long episode differ, and the reference's return in a row's evaluation may "
             "differ from the task's. The tasks' own, by the code paths they were played on:")  # fmt: skip
    return _grouped(intro, groups, "played before the records kept them")


def reproduction(previous: dict[str, Any], record: dict[str, Any]) -> dict[str, Any]:
    """Whether a row computed again reproduces its earlier record: each one's number and 95% interval (the mean
    evaluation return, bootstrap over its episodes; a soccer row's goal difference against the scripted team) and
    whether the new number lies within the earlier interval."""

    def number(rec: dict[str, Any]) -> dict[str, float]:
        if rec.get("soccer"):
            gd = rec["against_scripted"]["goal_difference"]
            return {"metric": "goal difference", "value": gd["mean"], "ci_low": gd["ci_low"], "ci_high": gd["ci_high"]}
        r = rec["summary"]["return"]
        return {"metric": "mean return", "value": rec["mean_return"], "ci_low": r["ci_low"], "ci_high": r["ci_high"]}

    before, now, evaluated = number(previous), number(record), _evaluated(previous)
    libraries_before, libraries_now = libraries(previous.get("software")), libraries(record.get("software"))
    return {"metric": now["metric"], "before": before, "again": now, "timesteps_before": previous.get("timesteps"),
            "settings_before": previous.get("settings"), "same_settings": previous.get("settings") == record.get(
                "settings"), "libraries_before": libraries_before, "libraries_again": libraries_now,
            "code_paths_before": code_paths(previous.get("software")),
            "code_paths_again": code_paths(record.get("software")),
            "within": bool(before["ci_low"] <= now["value"] <= before["ci_high"]),
            "identical": evaluated is not None and evaluated == _evaluated(record)}  # fmt: skip


def _evaluated(record: dict[str, Any]) -> Any:
    """What a row's evaluation gave, episode by episode: its returns, or a soccer row's matches against the
    scripted team; None where the record does not keep them."""
    return record.get("against_scripted") if record.get("soccer") else record.get("returns")


def verdict(r: dict[str, Any]) -> str:
    """A :func:`reproduction` in words: the new number against the earlier one and its interval, within or not."""
    b = r["before"]
    other = "" if r.get("same_settings", True) else f" (made with other settings: {r['settings_before']})"
    if "libraries_before" in r and r["libraries_before"] is None:
        other += "; the earlier record does not say which library versions it ran on"
    elif r.get("libraries_before") != r.get("libraries_again"):
        again = r.get("libraries_again")
        other += f"; the earlier one ran on {r['libraries_before']}, " + (
            f"this one on {again}" if again else "this one does not say on which library versions"
        )
    paths_before, paths_again = r.get("code_paths_before"), r.get("code_paths_again")
    if paths_again and r.get("libraries_before") is not None and paths_before != paths_again:
        other += ("; the earlier record does not say which CPU code paths it ran" if paths_before is None else
                  f"; the earlier one ran the CPU code paths {paths_before}, this one {paths_again}")  # fmt: skip
    return (
        f"{r['metric']} {r['again']['value']:.2f} against {b['value']:.2f} [{b['ci_low']:.2f}, {b['ci_high']:.2f}]"
        f" before: {'within' if r['within'] else 'OUTSIDE'} its 95% interval"
        + (", the same in every evaluation episode, bit for bit" if r.get("identical") else "")
        + other
    )


def _run_plan(plan: Plan, args: argparse.Namespace, out: Path, records: Path) -> int:
    from envs.common.io import folder_lock

    cores = os.cpu_count() or 1
    threads = max(1, cores // args.workers)
    # a row computed again keeps its published record until the new one replaces it, then says if it reproduced it
    again = {row: json.loads(row_file(records, row).read_text()) if row_file(records, row).is_file() else None
             for row in args.rerun}  # fmt: skip
    with contextlib.ExitStack() as held:  # refused (Busy) before anything goes if another command computes one
        for row in args.rerun:
            held.enter_context(row_lock(out, row))
    # seed by seed, so that a table built over several runs has every task and algorithm early
    todo = sorted((r for r in plan.rows if r in args.rerun or not row_file(records, r).is_file()),
                  key=lambda r: plan.seeds.index(r.seed))  # fmt: skip
    if args.table_only:
        print(f"leaderboard: --table-only: not run, so listed as such: {_rows(len(todo))}")
        todo = []
    worst = "" if plan.minutes is None else f"; at most {len(todo) * plan.minutes / args.workers:.1f} min of training"
    print(f"leaderboard: {_rows(len(plan.rows))} ({len(todo)} to run), {_budget(plan)}{worst}, "
          f"{args.workers} at a time on {threads} threads each" + (f" on Ray at {args.address}" if args.address
                                                                    else ""))  # fmt: skip
    baselines = {task: task_baselines(plan, task, out, cores, records) for task in plan.tasks}
    results: dict[Row, dict | None] = {r: None for r in plan.rows}
    failures = []
    for row, record, error in _run_rows(plan, todo, out, records, threads, args.workers, args.address, again):
        if record is not None and "reproduction" in record:
            print(f"leaderboard: {row.name} again: {verdict(record['reproduction'])}")
        results[row] = record
        if record is None and error is None:
            print(f"leaderboard: {row.name}: another command computes it in {out} (it holds "
                  f"{out / 'rows' / row.name / ROW_LOCK}); left to it")  # fmt: skip
        elif error:
            failures.append(error)
            print(f"leaderboard: {row.name}: {error}", file=sys.stderr)
        else:
            print(
                f"leaderboard: {row.name}: "
                + (
                    f"Elo {record['elo']['elo']:.0f} against the scripted team's {SCRIPTED_ELO:.0f}"
                    if record.get("soccer")
                    else f"mean return {record['mean_return']:.1f}"
                )
            )
    replaced = [row for row in again if results[row] is not None]  # a video of the model a rerun replaced goes
    for row in plan.rows:  # each under its own lock: judging one again takes minutes, and holds no other row
        results[row] = _finished(plan, row, out, records, threads, results[row], not args.table_only)
    with folder_lock(out, "leaderboard", TABLE_LOCK, wait=True):  # the table, plots and videos two commands share
        for row in replaced:
            marker = video_marker(records, row.task)
            if marker.is_file() and marker.read_text().strip() == row.name:
                marker.unlink()
        if args.videos:
            for task in plan.tasks:
                try:
                    task_video(plan, task, out, results, cores, records)
                except RuntimeError as exc:  # a video is a picture of the table, not part of it
                    print(f"leaderboard: {task}: no video ({exc})", file=sys.stderr)
        build_table(plan, out, baselines, results, Path(args.docs) if args.docs else None, records)
    print(f"leaderboard: {out / 'results.md'}" + (f" and {args.docs}" if args.docs else ""))
    return 1 if failures else 0


def _finished(plan: Plan, row: Row, out: Path, records: Path, threads: int, record: dict | None,
              judge: bool) -> dict | None:  # fmt: skip
    """A row's record for the table: this command's, or one another command wrote in the meantime (unless made with
    other settings, which is said and left out); given its software and its hour where its run is kept (``judge``),
    unless another command computes the row again now."""
    from envs.common.io import Busy

    path = row_file(records, row)
    if record is None and path.is_file():
        try:
            record = _load_done(path, plan.row_settings(row.task), f"row {row.name}")
        except StaleResult as exc:  # written by another command on the same folder since this one was checked
            print(f"leaderboard: {exc}; not in this command's table", file=sys.stderr)
            return None
    if record is None:
        return None
    try:
        with row_lock(out, row):
            record = json.loads(path.read_text()) if path.is_file() else record  # as written last
            record = backfill_software(row, record, out, records)
            record = backfill_intervals(row, record, out, records)
            return backfill_judgment(plan, row, record, out, records, threads) if judge else record
    except Busy:
        return record


ROW_LOCK = ".row.lock"  # in a row's folder: held by the command that computes the row
TABLE_LOCK = ".table.lock"  # in --out: held while a command writes the table, its plots and videos


def row_lock(out: Path, row: Row) -> contextlib.AbstractContextManager[Path]:
    """The lock a command holds on a row while it computes it (:class:`~envs.common.io.Busy` if another holds it),
    so that two commands share one ``--out``, each computing its own rows."""
    from envs.common.io import folder_lock

    return folder_lock(out / "rows" / row.name, "leaderboard", ROW_LOCK)


def _row_job(plan: Plan, row: Row, out: Path, records: Path, threads: int, again: bool = False,
             before: dict | None = None) -> tuple[Row, dict | None, str | None]:  # fmt: skip
    """(row, its record, None) when computed; (row, None, why) when it failed; (row, None, None) when another command
    computes it (it holds the row's lock), which this one leaves to it. ``again`` (``--rerun``): the row's work goes
    first, under the same lock, but not its record, which the new one replaces when done, saying whether it
    reproduced ``before`` (the record it replaces)."""
    from envs.common.io import Busy

    with contextlib.ExitStack() as held:
        try:
            lock = held.enter_context(row_lock(out, row))
        except Busy as exc:
            return row, None, str(exc) if again else None
        try:
            if again:
                _clear_row(out, records, row, lock)
            record = run_row(plan, row, out, threads, records, again)
            if before is not None:
                record = {**record, "reproduction": reproduction(before, record)}
                write_json(row_file(records, row), record)
            return row, record, None
        except KeyboardInterrupt:
            raise
        except Exception as exc:  # a failed tool, a stale run, a busy folder: the row fails, the others go on
            return row, None, f"{type(exc).__name__}: {exc}" if not isinstance(exc, RuntimeError) else str(exc)


def _clear_row(out: Path, records: Path, row: Row, lock: Path) -> None:
    """A row's work and run, before it is computed again: not its record (where records = out) or its lock."""
    for item in (out / "rows" / row.name).iterdir():
        if item not in (row_file(records, row), lock):
            shutil.rmtree(item) if item.is_dir() else item.unlink()
    if (out / "runs" / row.name).exists():
        _remove_run(out / "runs" / row.name)


def _run_rows(plan: Plan, rows: list[Row], out: Path, records: Path, threads: int, workers: int,
              address: str | None, again: dict[Row, dict | None] | None = None):  # fmt: skip
    """Each row's (row, record, error), as they finish: in this process, a local pool or Ray. Rows in ``again`` are
    computed even where their record exists, and say whether they reproduced the record given with them."""
    again = again or {}
    if not rows:
        return
    if address is not None:
        ray = ensure_ray(address)  # main joined the cluster before anything ran
        job = ray.remote(num_cpus=threads)(_row_job)
        pending = [job.remote(plan, row, out.resolve(), records.resolve(), threads, row in again, again.get(row))
                   for row in rows]  # fmt: skip
        while pending:
            ready, pending = ray.wait(pending)
            yield ray.get(ready[0])
        return
    if workers == 1:
        for row in rows:
            yield _row_job(plan, row, out, records, threads, row in again, again.get(row))
        return
    import multiprocessing
    from concurrent.futures import as_completed

    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(_row_job, plan, row, out, records, threads, row in again, again.get(row))
                   for row in rows]  # fmt: skip
        for future in as_completed(futures):
            yield future.result()


if __name__ == "__main__":
    # the importable module's main, not this copy's: Ray sends a row's job and its plan to a cluster's workers by
    # reference to their module, and a worker has no ``__main__`` of ours to find them in
    from agents.leaderboard import main as leaderboard_main

    sys.exit(leaderboard_main())
