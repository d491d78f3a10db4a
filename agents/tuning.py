"""Hyperparameter tuning with Optuna: ``python train.py --tune N --env ID --algo ppo|sac --timesteps T``.

Each trial draws hyperparameters (:data:`SPACES`) on top of the id's entry in the hyperparameter file (its ``n_envs``,
``normalize``, ``env_kwargs`` and ``policy`` stay), trains a model for ``--timesteps`` env steps with a run's own code
(agents/training.py: the same envs, normalization and model building), and evaluates it ``--evaluations`` times on the
way, each time on the next ``--eval-episodes`` deterministic episodes of an env of its own (seeded :data:`EVAL_SEED`: a
trial's k-th evaluation plays the same episodes in every trial). Each evaluation's score goes to Optuna, whose median
pruner stops a trial that scores worse than the median of the earlier trials at the same step (after
:data:`STARTUP_TRIALS` trials and the first third of a trial's steps). A trial's value is its last evaluation's score.
The score is the mean return by default; ``--tune-metric NAME`` makes it the mean of an episode metric instead
(``evaluate.py``'s: ``speed``, ``cost_of_transport``, the task's own such as ``yaw_rate_error`` or ``success``),
minimized where smaller is better (:data:`agents.evaluation.LOWER_IS_BETTER`), else maximized. A return pays for what
its terms pay for, which on some tasks is standing still; the task's metric is what its leaderboard row is judged on.

Storage: an SQLite file by default (``sqlite:///<runs-dir>/tuning.db``) or any database URL that SQLAlchemy takes,
such as ``postgresql://user@host:5432/db`` (the ``psycopg`` driver ships with skitter): every process that names the
same ``--study`` there shares the study, each running its own trials (on several machines at once). A study is
resumable: run the command again and it adds its trials to those done (a trial cut short by Ctrl-C is recorded as
failed and not counted). The sampler is Optuna's TPE, seeded with ``--seed`` plus the number of trials the study
already holds (a command run again draws anew; processes sharing a study should use different seeds). A study is
one env's, algorithm's, env kwargs', budget's and metric's: a command with another is refused.

Writes ``<runs-dir>/tuning/<study>/`` (each file written whole, or not at all): ``best.yml``, the id's
hyperparameter entry with the best trial's values, ready to go into ``hyperparams/<algo>.yml`` (its header says how
the entry's own values scored: a new study's first trial plays them, :func:`shipped_params`); ``trials.csv``,
every trial of the study with its values, state and score; ``study.json``, the best trial, the counts and the
command. Nothing in ``hyperparams/`` is changed.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from stable_baselines3.common.callbacks import EvalCallback
from stable_baselines3.common.utils import set_random_seed
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from agents.config import ConfigError
from agents.evaluation import LOWER_IS_BETTER, episode_metrics, metric_descriptions
from agents.sb3 import diverged_cause
from envs.common.io import write_json, write_text

if TYPE_CHECKING:
    import optuna


@dataclasses.dataclass(frozen=True)
class RunCode:
    """What a trial trains with: a run's own functions (agents/training.py's ``RUN_CODE``), so that a trial builds its
    hyperparameters, envs and model exactly as ``train.py`` does."""

    resolve_hyperparams: Callable[..., Any]
    make_env: Callable[..., VecEnv]
    build_model: Callable[..., Any]
    torch_threads: int
    algo_defaults: Callable[[str], dict[str, Any]]  # an algorithm's constructor arguments and their defaults


class Diverged(RuntimeError):
    """A trial whose training broke down (NaN in the policy): recorded as failed, and the study goes on."""


EVAL_SEED = 10**6  # the evaluation episodes' seed: away from the training seeds (0, 1, ...) of any run
STARTUP_TRIALS = 5  # trials that run to the end before the pruner compares
TUNABLE = ("ppo", "sac")
GAMMAS = (0.98, 0.99, 0.995, 0.998, 0.999)
WIDTHS = (64, 128, 256)  # hidden units of the two layers of the policy and value networks
LOG_STDS = (-3.0, -2.0, -1.0, 0.0)  # PPO's initial log standard deviation of its actions (0: SB3's default)


def _net(trial: optuna.Trial, exploring: bool = False) -> str:
    """The policy's network, and with ``exploring`` the initial standard deviation of its Gaussian (``log_std_init``):
    a legged robot that falls under PPO's default of 1 may learn from a smaller one, as RL Zoo's sampler also draws."""
    width = trial.suggest_categorical("net_width", WIDTHS)
    if not exploring:
        return f"dict(net_arch=[{width}, {width}])"
    return f"dict(net_arch=[{width}, {width}], log_std_init={trial.suggest_categorical('log_std_init', LOG_STDS)})"


def sample_ppo(trial: optuna.Trial, n_envs: int, timesteps: int, exploring: bool = True) -> dict[str, Any]:
    """PPO's hyperparameters for a trial: a rollout cut to the trial's budget (at least 128 steps an env), a minibatch
    no larger than a rollout, and the policy's initial exploration unless the entry's residual sets it
    (``exploring`` False). The draws' choices are fixed (a study keeps them whatever the budget); the values used
    are in each trial's ``hyperparams``."""
    drawn = trial.suggest_categorical("n_steps", (128, 256, 512, 1024, 2048))
    n_steps = max(128, min(drawn, timesteps // n_envs))
    batch = trial.suggest_categorical("batch_size", (64, 128, 256, 512))
    return {
        "n_steps": n_steps,
        "batch_size": min(batch, n_steps * n_envs),
        "n_epochs": trial.suggest_categorical("n_epochs", (5, 10, 20)),
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 3e-3, log=True),
        "gamma": trial.suggest_categorical("gamma", GAMMAS),
        "gae_lambda": trial.suggest_categorical("gae_lambda", (0.9, 0.95, 0.98, 0.99)),
        "clip_range": trial.suggest_categorical("clip_range", (0.1, 0.2, 0.3)),
        "ent_coef": trial.suggest_float("ent_coef", 1e-8, 1e-2, log=True),
        "max_grad_norm": trial.suggest_categorical("max_grad_norm", (0.3, 0.5, 1.0, 2.0)),
        "policy_kwargs": _net(trial, exploring),
    }


def sample_sac(trial: optuna.Trial, n_envs: int, timesteps: int, exploring: bool = True) -> dict[str, Any]:
    """SAC's hyperparameters for a trial: learning starts within the first quarter of the trial's budget."""
    train_freq = trial.suggest_categorical("train_freq", (1, 4, 8))
    return {
        "learning_rate": trial.suggest_float("learning_rate", 1e-5, 3e-3, log=True),
        "batch_size": trial.suggest_categorical("batch_size", (64, 128, 256, 512)),
        "buffer_size": trial.suggest_categorical("buffer_size", (100_000, 300_000, 1_000_000)),
        "learning_starts": min(trial.suggest_categorical("learning_starts", (1000, 5000, 10000)), timesteps // 4),
        "tau": trial.suggest_categorical("tau", (0.005, 0.01, 0.02)),
        "gamma": trial.suggest_categorical("gamma", GAMMAS),
        "train_freq": train_freq,
        "gradient_steps": train_freq,
        "policy_kwargs": _net(trial),
    }


SPACES: dict[str, Callable[[Any, int, int, bool], dict[str, Any]]] = {"ppo": sample_ppo, "sac": sample_sac}
SHIPPED = "shipped"  # the user attribute of the trial that plays the entry's own values


def _entry_value(algo: str, name: str, model_kwargs: dict[str, Any], defaults: dict[str, Any]) -> Any:
    """The entry's value of the search space's parameter ``name`` (the algorithm's default where the entry has none);
    None where it is not a plain value (a schedule, an uneven network)."""
    policy = model_kwargs.get("policy_kwargs") or {}
    if name == "net_width":
        arch = policy.get("net_arch", [64, 64] if algo == "ppo" else [256, 256])  # SB3's MlpPolicy defaults
        arch = arch.get("pi") if isinstance(arch, dict) else arch
        return arch[0] if isinstance(arch, list) and arch and len(set(arch)) == 1 else None
    if name == "log_std_init":
        return policy.get("log_std_init", 0.0)
    value = model_kwargs.get(name, defaults.get(name))
    if name == "train_freq" and isinstance(value, tuple | list) and len(value) == 2 and value[1] == "step":
        value = value[0]
    return value if isinstance(value, int | float) and not isinstance(value, bool) else None


def shipped_params(algo: str, hp: Any, timesteps: int, exploring: bool,
                   defaults: dict[str, Any]) -> tuple[dict[str, Any], list[str]]:  # fmt: skip
    """The entry's own values as the search space's draws, for a trial that plays them (the study's yardstick), and
    what could not be played as written: a choice the space lacks takes the nearest one, a number outside a range
    the nearest end, a value that is no plain number (a schedule) a draw. ``defaults``: the algorithm's constructor
    arguments and their defaults, for what the entry leaves out."""
    import optuna

    probe = optuna.create_study().ask()
    SPACES[algo](probe, hp.n_envs, timesteps, exploring)
    params, moved = {}, []
    for name, dist in probe.distributions.items():
        value = _entry_value(algo, name, hp.model_kwargs, defaults)
        if value is None:
            moved.append(f"{name}: drawn (the entry's is not a plain number)")
            continue
        if isinstance(dist, optuna.distributions.CategoricalDistribution):
            played = min(dist.choices, key=lambda c: (abs(math.log(c / value)) if c > 0 and value > 0
                                                      else abs(c - value)))  # fmt: skip
        else:
            played = min(max(value, dist.low), dist.high)
        if played != value:
            moved.append(f"{name}: {played:g} for the entry's {value:g}")
        params[name] = played
    # what the trial then uses against the entry, field by field (a rollout cut to the budget, SAC's gradient steps
    # tied to its training frequency)
    used = SPACES[algo](optuna.trial.FixedTrial({**probe.params, **params}), hp.n_envs, timesteps, exploring)
    for key, value in used.items():
        entry = hp.model_kwargs.get(key, defaults.get(key))
        if key in probe.params and key not in params:
            continue  # drawn, and said so
        if key != "policy_kwargs" and key not in params and entry != value:
            moved.append(f"{key}: {value} for the entry's {entry}")
        elif key in params and value != params[key]:
            moved.append(f"{key}: {value} (the draw {params[key]} cut to the budget)")
    return params, moved


class TrialEvalCallback(EvalCallback):
    """SB3's evaluation every ``eval_freq`` calls, each score reported to the trial (``last_score``: the mean return,
    or the mean of episode metric ``metric`` over the evaluation's episodes); a trial the pruner stops ends its
    training (``pruned``)."""

    def __init__(self, trial: optuna.Trial, eval_env: VecEnv, eval_freq: int, n_eval_episodes: int,
                 metric: str = "return"):  # fmt: skip
        super().__init__(eval_env, n_eval_episodes=n_eval_episodes, eval_freq=eval_freq, deterministic=True,
                         verbose=0, warn=False)  # fmt: skip
        self.trial = trial
        self.metric = metric
        self.pruned = False
        self.reported = 0
        self.last_score = float("nan")
        self._ended: list[dict[str, Any]] = []  # the last info of each episode of the evaluation under way

    def _log_success_callback(self, locals_: dict[str, Any], globals_: dict[str, Any]) -> None:
        super()._log_success_callback(locals_, globals_)
        if locals_["done"]:
            self._ended.append(locals_["info"])

    def _score(self) -> float:
        if self.metric == "return":
            return float(self.last_mean_reward)
        env = self.eval_env.get_attr("unwrapped", [0])[0]
        values = [episode_metrics(env, 0.0, info, bool(info.get("fallen", False)))[self.metric]
                  for info in self._ended if not info.get("sim_unstable", False)]  # fmt: skip
        finite = [v for v in values if math.isfinite(v)]
        return sum(finite) / len(finite) if finite else float("nan")

    def _on_step(self) -> bool:
        evaluating = self.eval_freq > 0 and self.n_calls % self.eval_freq == 0  # SB3's evaluation runs in this step
        if evaluating:
            self._ended = []
        going = super()._on_step()
        if evaluating:
            self.reported += 1
            self.last_score = self._score()
            if math.isfinite(self.last_score):
                self.trial.report(self.last_score, self.num_timesteps)
            if self.trial.should_prune():
                self.pruned = True
                return False
        return going


def eval_env(env_id: str, hp: Any, code: RunCode) -> VecEnv:
    """One env of ``env_id`` made as the training envs are (the same wrappers, ``env_kwargs`` and normalization, whose
    statistics SB3 copies from training at each evaluation, frozen here), seeded :data:`EVAL_SEED`."""
    venv = code.make_env(env_id, dataclasses.replace(hp, n_envs=1), EVAL_SEED)
    if isinstance(venv, VecNormalize):
        venv.training, venv.norm_reward = False, False
    return venv


def storage_url(storage: str | None, runs_dir: Path) -> str:
    """The study's database: ``storage`` as given, or an SQLite file in ``runs_dir``."""
    if storage is None:
        return f"sqlite:///{(runs_dir / 'tuning.db').resolve()}"
    if not storage.strip() or "://" not in storage:
        raise ConfigError(f"--storage {storage!r}: expected a database URL (sqlite:///file.db, postgresql://...)")
    return storage


def _shown(url: str) -> str:
    """A database URL as messages and files show it: without its password."""
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:  # not a URL SQLAlchemy parses: shown as given (it holds no password to hide)
        return url


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else ""


def study_name(env_id: str, algo: str) -> str:
    return f"{env_id.replace('/', '_')}__{algo}"


def tune(code: RunCode, env_id: str, algo: str, base: dict[str, Any], where: str, trials: int, timesteps: int,
         runs_dir: Path, storage: str | None = None, study: str | None = None, seed: int = 0, evaluations: int = 4,
         eval_episodes: int = 5, minutes: float | None = None, command: str = "", metric: str = "return",
         ) -> Path:  # fmt: skip
    """Run ``trials`` trials of the study (see the module docstring) and write its files; returns their folder.

    Args:
        code: the run's functions the trials train with.
        base: the id's entry in the hyperparameter file (``where`` names it in messages); each trial's draws
            replace its fields.
        minutes: stop starting trials after this much wall time (a running trial finishes).
        metric: what a trial scores: ``return``, or an episode metric of the env (minimized if in
            :data:`~agents.evaluation.LOWER_IS_BETTER`).
    """
    import optuna
    import torch

    if algo not in TUNABLE:
        raise ConfigError(f"--tune tunes {' and '.join(TUNABLE)}, not {algo}")
    if evaluations < 1 or eval_episodes < 1:
        raise ConfigError("--evaluations and --eval-episodes must be at least 1")
    torch.set_num_threads(code.torch_threads)  # as a run trains
    hp0 = code.resolve_hyperparams(base, algo, where)  # the entry itself must hold before any trial runs
    if evaluations > max(1, timesteps // hp0.n_envs):  # else an evaluation at every step, and the same ones again
        raise ConfigError(f"--evaluations {evaluations}: a trial of {timesteps} steps on {hp0.n_envs} envs takes "
                          f"{timesteps // hp0.n_envs} steps in each; evaluate at most that often")  # fmt: skip
    venv = code.make_env(env_id, hp0, seed)  # and its env_kwargs
    try:
        known = metric_descriptions(venv.get_attr("unwrapped", [0])[0])
    finally:
        venv.close()
    if metric not in known:
        raise ConfigError(f"--tune-metric {metric!r}: {env_id} reports {', '.join(known)}")
    direction = "minimize" if metric in LOWER_IS_BETTER else "maximize"
    name = study or study_name(env_id, algo)
    url = storage_url(storage, runs_dir)
    made_dir = next((p for p in reversed([runs_dir, *runs_dir.parents]) if not p.exists()), None)
    runs_dir.mkdir(parents=True, exist_ok=True)  # the default storage's file lives there
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    pruner = optuna.pruners.MedianPruner(n_startup_trials=STARTUP_TRIALS, n_warmup_steps=timesteps // 3)
    try:  # its sampler is set below, seeded by how many trials the study holds
        the_study = optuna.create_study(storage=url, study_name=name, direction=direction, pruner=pruner,
                                        load_if_exists=True)  # fmt: skip
    except Exception as exc:  # SQLAlchemy's errors: a server that does not answer, a bad URL, a locked file
        if made_dir is not None:  # a refused study leaves nothing behind: not the folders made for it
            shutil.rmtree(made_dir, ignore_errors=True)
        if isinstance(exc, ImportError):
            raise ConfigError(f"--storage {_shown(url)}: {_first_line(exc)}") from None
        raise ConfigError(f"--storage {_shown(url)}: cannot open the study ({type(exc).__name__}: "
                          f"{_first_line(exc)})") from None  # fmt: skip
    # a study is one env's: a process that shares it with another env id, algorithm or env kwargs (another action
    # space, say) is refused before it adds a trial
    made = {"env_id": env_id, "algo": algo, "env_kwargs": hp0.env_kwargs, "timesteps": timesteps, "metric": metric}
    held = dict(the_study.user_attrs)
    if held and "metric" not in held:  # a study made before metrics could be tuned scored the return
        held["metric"] = "return"
    clash = {k: held[k] for k, v in made.items() if held.get(k, v) != v}
    if clash:
        raise ConfigError(f"--study {name} in {_shown(url)} was made with {clash}, not "
                          f"{ {k: made[k] for k in clash} }: give another --study")  # fmt: skip
    for key, value in made.items():
        the_study.set_user_attr(key, value)
    # a command run again continues the study with new draws: seeded with --seed alone, its first (random) trials
    # would repeat the earlier command's
    the_study.sampler = optuna.samplers.TPESampler(seed=seed + len(the_study.trials), n_startup_trials=STARTUP_TRIALS)

    exploring = hp0.residual is None or hp0.residual.exploration is None  # else the entry's residual sets it
    # the entry's own values are the study's first trial, the yardstick of its draws: queued once a study (Optuna
    # skips a trial whose values the study holds already, also when workers that share it each queue it)
    params, moved = shipped_params(algo, hp0, timesteps, exploring, code.algo_defaults(algo))
    the_study.enqueue_trial(params, user_attrs={SHIPPED: True, "moved": moved}, skip_if_exists=True)

    def objective(trial: optuna.Trial) -> float:
        drawn = SPACES[algo](trial, hp0.n_envs, timesteps, exploring)
        hp = code.resolve_hyperparams({**base, **drawn}, algo, f"{where} (trial {trial.number})")
        trial.set_user_attr("hyperparams", drawn)
        trial.set_user_attr("command", command)
        set_random_seed(seed + trial.number)
        venv = code.make_env(env_id, hp, seed + 1000 * trial.number)
        evaluation = eval_env(env_id, hp, code)
        try:
            model = code.build_model(algo, hp, venv, seed + trial.number)
            every = max(1, timesteps // (evaluations * hp.n_envs))
            callback = TrialEvalCallback(trial, evaluation, every, eval_episodes, metric)
            try:
                model.learn(timesteps, callback=callback)
            except ConfigError:
                raise
            except ValueError as exc:  # torch's distributions refuse NaN parameters: the trial diverged
                cause = diverged_cause(exc)
                if cause is None:  # any other ValueError is a fault to show, not a trial's bad luck
                    raise
                raise Diverged(cause) from None
            if callback.pruned:
                raise optuna.TrialPruned()
            value = callback.last_score
            if not math.isfinite(value):  # diverged, or no episode gave the metric a value
                if metric != "return":
                    trial.set_user_attr("unscored", f"no evaluation episode gave {metric} a finite value (an "
                                                    "episode shorter than the metric's warm-up has none)")  # fmt: skip
                raise optuna.TrialPruned()
            return value
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: said below in one line, not in Optuna's failed-trial warnings
            quiet.active = True
            raise
        finally:
            venv.close()
            evaluation.close()

    quiet = _QuietWhileStopping()
    optuna_logger = logging.getLogger("optuna.study._optimize")
    optuna_logger.addFilter(quiet)
    interrupted = False
    try:
        the_study.optimize(
            objective, n_trials=trials, timeout=None if minutes is None else 60.0 * minutes, catch=(Diverged,)
        )
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        optuna_logger.removeFilter(quiet)
        folder = write_study(the_study, env_id, algo, base, runs_dir / "tuning" / name, url, command)
        if interrupted:
            print(f"\ninterrupted: study {name} in {_shown(url)} keeps its finished trials (the one stopped "
                  f"counts as failed), and {folder} holds them; run the same command again to go on",
                  file=sys.stderr)  # fmt: skip
    return folder


class _QuietWhileStopping(logging.Filter):
    """Drops Optuna's warnings of a trial stopped by Ctrl-C (its traceback): the tuner says it in one line."""

    active = False

    def filter(self, record: logging.LogRecord) -> bool:
        return not self.active


def _as_entry(base: dict[str, Any], hyperparams: dict[str, Any]) -> dict[str, Any]:
    """The id's entry with a trial's drawn values, as the YAML file holds them (plain numbers and strings)."""
    entry = {**base, **hyperparams}
    return {k: (float(v) if isinstance(v, float) else v) for k, v in entry.items()}


def write_study(study: Any, env_id: str, algo: str, base: dict[str, Any], folder: Path, url: str,
                command: str) -> Path:  # fmt: skip
    """The study's files (see the module docstring) in ``folder``."""
    import optuna

    metric = study.user_attrs["metric"]

    folder.mkdir(parents=True, exist_ok=True)
    frame = study.trials_dataframe(attrs=("number", "value", "state", "params", "duration", "user_attrs"))
    write_text(folder / "trials.csv", frame.to_csv(index=False))
    states = [t.state for t in study.trials]
    counts = {s.name.lower(): states.count(s) for s in optuna.trial.TrialState}
    summary: dict[str, Any] = {"study": study.study_name, "env_id": env_id, "algo": algo, "storage": _shown(url),
                               "metric": metric, "direction": study.direction.name.lower(), "trials": counts,
                               "command": command}  # fmt: skip
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    if complete:
        best = study.best_trial
        entry = _as_entry(base, best.user_attrs.get("hyperparams", {}))
        summary["best"] = {"trial": best.number, "value": best.value, "hyperparams": entry}
        header = (f"# {algo} for {env_id}: the best of {len(complete)} complete trials of study {study.study_name} "
                  f"(trial {best.number}, mean {metric} {best.value:.4g}).\n# Its trial was run by: "
                  f"{best.user_attrs.get('command', command)}\n")  # fmt: skip
        shipped = next((t for t in study.trials if t.user_attrs.get(SHIPPED)), None)
        if shipped is not None:
            value = shipped.value if shipped.state == optuna.trial.TrialState.COMPLETE else None
            summary["shipped"] = {"trial": shipped.number, "state": shipped.state.name.lower(), "value": value,
                                  "moved": shipped.user_attrs.get("moved", [])}  # fmt: skip
            said = ("is the best" if shipped.number == best.number else
                    f"scored {value:.4g}" if value is not None else f"was {shipped.state.name.lower()}")  # fmt: skip
            header += f"# The entry's own values (trial {shipped.number}) {said}.\n"
        write_text(folder / "best.yml", header + yaml.safe_dump({env_id: entry}, sort_keys=False))
    write_json(folder / "study.json", summary)
    return folder
