"""Self-play: one shared policy learns soccer against a pool of its own past checkpoints and the scripted team.

    python train.py --soccer bioloid --players 3 --timesteps 3000000 --seed 0 [--scripted-share 0.5]

The learner plays the home team of ``n_envs`` matches at once (its hyperparameters are ``hyperparams/ppo.yml``'s
``soccer/<robot>`` entry; ``n_envs`` there counts matches). Every match's away team is an opponent drawn from the
pool when the match starts: the scripted team (``envs/soccer/scripted.py``) with probability ``scripted_share``,
otherwise one of the learner's last ``pool_size`` snapshots, taken every ``snapshot_freq`` steps (each a frozen
copy of the policy and of its observation normalization, saved in the run folder's ``pool/`` as a model file that
``evaluate.py --soccer --home FILE`` plays). Observations do not depend on the side (envs/soccer/task.py), so one
policy plays either.

With ``residual`` (``train.py --soccer ROBOT --residual scripted``, or the entry's ``residual: {policy: scripted,
scale: S}``) the learner plays on top of the scripted team: each player's action is ``clip(scripted + S * a, -1,
1)``, the scripted player's command for that player (its own memory per match) plus the policy's correction, as
agents/residual.py does for one robot's gait. A new policy's mean correction is near 0, so the team starts from the
scripted team's commands (with PPO's exploration noise, scaled). Its snapshots play on top of the scripted team too.

The learner's reward per player: +1 / -1 for each goal its team scores / concedes, plus the academy's potential-based
shaping (0.1 per body length closed toward the ball, 0.2 per body length the ball moves toward the goal attacked), each
a ``reward_<term>`` in ``info``.

Ratings: Elo, updated after every match (a win 1, a draw 0.5, a loss 0; K = 16), of the learner, of each snapshot
(which starts at the learner's rating when taken) and of the scripted team, which is the anchor: it stays at 1000, so
a rating reads as strength against the scripted team (400 points: 10 to 1 odds). They are logged to TensorBoard
(``selfplay/``) with each opponent's record, and written with the run to ``ratings.json``.
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecNormalize

from agents.residual import parse_residual
from agents.soccer.vec_env import MatchesVecEnv
from envs.common.io import write_json
from envs.soccer.academy import APPROACH_WEIGHT, PROGRESS_WEIGHT
from envs.soccer.match import MATCH_SECONDS, Matches
from envs.soccer.scripted import MEMORY, ScriptedTeam
from envs.soccer.steering import COMMANDS

SCRIPTED = "scripted"
ANCHOR_RATING = 1000.0
ELO_K = 16.0
POOL_SIZE = 10  # the snapshots kept as opponents (the oldest is dropped)
SCRIPTED_SHARE = 0.5
RATINGS_FILE = "ratings.json"
POOL_DIR = "pool"


class ScriptedOpponent:
    """The scripted team of one side (the away team by default): ``act(obs, matches)`` on its players' rows of those
    matches (match-major), each player with its memory of each match (``ScriptedPlayer.predict``'s state), which
    ``restart`` clears."""

    def __init__(self, engine: Matches, team: str = "away"):
        self.team = ScriptedTeam.of(engine, (team,))[0]
        self.memory = np.zeros((engine.num_matches, len(self.team.players), len(MEMORY)))
        self.fresh = np.ones(engine.num_matches, dtype=bool)

    def restart(self, matches: np.ndarray) -> None:
        """Matches that start again: their players' memories start afresh."""
        self.fresh[matches] = True

    def act(self, obs: np.ndarray, matches: np.ndarray) -> np.ndarray:
        by_player = obs.reshape(len(matches), len(self.team.players), obs.shape[-1])
        actions, self.memory[matches] = self.team.act(by_player, self.memory[matches], self.fresh[matches])
        self.fresh[matches] = False
        return actions.reshape(len(obs), -1)


class SnapshotOpponent:
    """A frozen copy of the learner: its policy network and its observation normalization at the time taken; for a
    residual learner also the scripted team it corrects (``base``) and the correction's ``scale``."""

    def __init__(self, policy: Any, normalizer: VecNormalize | None, base: ScriptedOpponent | None = None,
                 scale: float | None = None):  # fmt: skip
        self.policy = policy
        self.policy.set_training_mode(False)
        self.normalizer = normalizer
        self.base, self.scale = base, scale

    @classmethod
    def of(cls, model: Any, base: ScriptedOpponent | None = None, scale: float | None = None) -> SnapshotOpponent:
        stats = model.get_vec_normalize_env()
        normalizer = pickle.loads(pickle.dumps(stats)) if stats is not None else None  # SB3 pickles it without env
        return cls(copy.deepcopy(model.policy), normalizer, base, scale)

    def act(self, obs: np.ndarray, matches: np.ndarray) -> np.ndarray:
        base = None if self.base is None else self.base.act(obs, matches)  # the env's own observations
        if self.normalizer is not None:
            obs = self.normalizer.normalize_obs(obs)
        actions, _ = self.policy.predict(obs, deterministic=False)
        if base is not None:
            actions = base + self.scale * np.asarray(actions, np.float64)
        return np.clip(actions, -1.0, 1.0)


class Pool:
    """The opponents and everyone's Elo rating; the scripted team is the anchor (its rating never moves)."""

    def __init__(self, scripted: ScriptedOpponent, rng: np.random.Generator, scripted_share: float = SCRIPTED_SHARE,
                 pool_size: int = POOL_SIZE, residual: float | None = None):  # fmt: skip
        self.opponents: dict[str, Any] = {SCRIPTED: scripted}
        self.rng, self.scripted_share, self.pool_size = rng, scripted_share, pool_size
        self.residual = residual  # a residual learner's correction scale: its snapshots correct the scripted team
        self.ratings = {"learner": ANCHOR_RATING, SCRIPTED: ANCHOR_RATING}
        self.records: dict[str, list[int]] = {SCRIPTED: [0, 0, 0]}  # the learner's wins, draws, losses against each

    @property
    def base(self) -> ScriptedOpponent | None:
        """What a residual learner's snapshots correct: the scripted away team (a match has one away opponent at a
        time, so the scripted team's memory of a match is its opponent's); None for a plain learner."""
        return None if self.residual is None else self.opponents[SCRIPTED]

    def add(self, name: str, opponent: Any) -> None:
        """A snapshot joins the pool at the learner's current rating; beyond ``pool_size`` the oldest is no longer
        drawn (a match that drew it plays it to its end)."""
        self.opponents[name] = opponent
        self.ratings[name] = self.ratings["learner"]
        self.records.setdefault(name, [0, 0, 0])

    @property
    def drawable(self) -> list[str]:
        """The snapshots a new match may draw: the last ``pool_size``."""
        snapshots = [n for n in self.opponents if n != SCRIPTED]
        return snapshots[max(0, len(snapshots) - self.pool_size) :]

    def release(self, playing: Sequence[str]) -> None:
        """Let go of the snapshots no longer drawn that no match in ``playing`` plays."""
        keep = set(self.drawable) | set(playing) | {SCRIPTED}
        for name in [n for n in self.opponents if n not in keep]:
            del self.opponents[name]

    def draw(self) -> str:
        snapshots = self.drawable
        if not snapshots or self.rng.random() < self.scripted_share:
            return SCRIPTED
        return snapshots[int(self.rng.integers(len(snapshots)))]

    def record(self, opponent: str, goals_for: int, goals_against: int) -> None:
        """One finished match of the learner against ``opponent``: Elo for both (the anchor stays)."""
        score = 1.0 if goals_for > goals_against else 0.5 if goals_for == goals_against else 0.0
        self.records[opponent][0 if score == 1.0 else 1 if score == 0.5 else 2] += 1
        expected = 1.0 / (1.0 + 10.0 ** ((self.ratings[opponent] - self.ratings["learner"]) / 400.0))
        change = ELO_K * (score - expected)
        self.ratings["learner"] += change
        if opponent != SCRIPTED:
            self.ratings[opponent] -= change

    def summary(self) -> dict[str, Any]:
        return {
            "anchor": SCRIPTED,
            "anchor_rating": ANCHOR_RATING,
            "k": ELO_K,
            "ratings": dict(self.ratings),
            "learner_record": {
                n: dict(zip(("wins", "draws", "losses"), r, strict=True)) for n, r in self.records.items()
            },
            "in_pool": [SCRIPTED, *self.drawable],
        }


class SelfPlayVecEnv(MatchesVecEnv):
    """The home team of ``num_matches`` matches as an SB3 VecEnv (``num_matches x players`` envs, match-major), with
    every away team played by an opponent from ``pool`` (drawn as its match starts). Match ``m`` is seeded with its
    first player's env seed, as :class:`agents.soccer.vec_env.SoccerVecEnv` does; the pool draws from its own
    stream. ``residual``: the learner's actions are corrections of this scale to the scripted home team's (the
    module's docstring). Other arguments: :class:`envs.soccer.match.Matches`'s."""

    def __init__(self, num_matches: int, pool_seed: int = 0, scripted_share: float = SCRIPTED_SHARE,
                 match_seconds: float = MATCH_SECONDS, nthread: int | None = None, residual: float | None = None,
                 **kwargs: Any):  # fmt: skip
        engine = Matches(num_matches=num_matches, nthread=nthread, batched=True, **kwargs)
        engine.max_cycles = max(1, round(match_seconds / engine.dt))
        if engine.commands is None:
            raise ValueError(f"self-play draws the scripted team as an opponent: it plays in the {COMMANDS!r} mode")
        self.k = engine.players // 2
        super().__init__(engine, self.k)
        rows = engine.rows_of(np.arange(num_matches)).reshape(num_matches, 2, self.k)
        self.home, self.away = rows[:, 0].reshape(-1), rows[:, 1].reshape(-1)
        try:  # the residual's own check of its scale (agents/residual.py)
            self.residual = None if residual is None else parse_residual({"policy": SCRIPTED, "scale": residual}).scale
        except ValueError as exc:
            raise ValueError(f"residual: a correction scale, {exc}") from None
        self.script = ScriptedOpponent(engine, "home") if residual is not None else None
        self.pool = Pool(ScriptedOpponent(engine), np.random.default_rng(pool_seed), scripted_share,
                         residual=self.residual)  # fmt: skip
        self.opponent_of = [SCRIPTED] * num_matches

    def reset(self) -> np.ndarray:
        self.opponent_of = [self.pool.draw() for _ in range(self.engine.num_matches)]
        self.pool.opponents[SCRIPTED].restart(np.arange(self.engine.num_matches))
        if self.script is not None:
            self.script.restart(np.arange(self.engine.num_matches))
        self._reset_matches()
        return self.engine.obs[self.home].copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float64).reshape(self.num_envs, -1)

    def _opponents_act(self, actions: np.ndarray) -> None:
        obs = self.engine.obs
        names = np.array(self.opponent_of)
        for name in dict.fromkeys(self.opponent_of):
            matches = np.flatnonzero(names == name)
            rows = self.away.reshape(-1, self.k)[matches].reshape(-1)
            actions[rows] = self.pool.opponents[name].act(obs[rows], matches)

    def step_wait(self):
        engine = self.engine
        actions = np.tile(engine.rest, (engine.robot.num_sims, 1))
        if self.script is None:
            actions[self.home] = self._actions
        else:  # the scripted home team's commands, corrected
            base = self.script.act(engine.obs[self.home], np.arange(engine.num_matches))
            actions[self.home] = np.clip(base + self.residual * self._actions, -1.0, 1.0)
        self._opponents_act(actions)
        out = engine.step(actions)
        terms = {
            "goal": out["reward"][self.home],
            "approach": APPROACH_WEIGHT * out["approach"][self.home],
            "ball_progress": PROGRESS_WEIGHT * out["ball_progress"][self.home],
        }
        reward = sum(terms.values())
        match_of = np.arange(self.num_envs) // self.k
        done_match = out["ended"] | out["truncated"]
        obs = engine.obs[self.home].copy()
        infos: list[dict[str, Any]] = [{f"reward_{t}": float(v[i]) for t, v in terms.items()}
                                       for i in range(self.num_envs)]  # fmt: skip
        # a match whose step diverged and held at shorter physics steps, or was lost to it (envs/soccer/match.py),
        # says so in its first learner's info
        for key, flags in (("sim_refined", out["refined"]), ("sim_unstable", out["unstable"])):
            for m in np.flatnonzero(flags):
                infos[m * self.k][key] = True
        finished = np.flatnonzero(done_match)
        for m in finished:
            home, away = (int(g) for g in engine.scores[m])
            self.pool.record(self.opponent_of[m], home, away)
            for i in range(m * self.k, (m + 1) * self.k):
                infos[i]["terminal_observation"] = obs[i].copy()
                infos[i]["TimeLimit.truncated"] = bool(out["truncated"][m])
            infos[m * self.k]["match"] = {"opponent": self.opponent_of[m], "score": [home, away]}
            self.opponent_of[m] = self.pool.draw()
        if len(finished):
            self.pool.release(self.opponent_of)
            engine.reset(finished)
            self.pool.opponents[SCRIPTED].restart(finished)
            if self.script is not None:
                self.script.restart(finished)
            obs = engine.obs[self.home].copy()
        return obs, reward.astype(np.float32), done_match[match_of], infos


class SelfPlayCallback(BaseCallback):
    """Takes a snapshot of the learner into the pool every ``snapshot_freq`` steps (saved as ``pool/<name>.zip`` in
    the run folder), logs the matches and the ratings to TensorBoard, and writes ``ratings.json``. Per rollout it
    also logs the match steps that diverged and held at shorter physics steps (``selfplay/steps_run_again``) and the
    matches lost to instability (``selfplay/matches_lost_unstable``)."""

    def __init__(self, pool: Pool, run_dir: Path, snapshot_freq: int, manifest: dict[str, Any]):
        super().__init__()
        self.pool, self.run_dir, self.snapshot_freq, self.manifest = pool, run_dir, snapshot_freq, manifest

    def _on_training_start(self) -> None:
        self._last = self.num_timesteps
        self._returns = np.zeros(self.training_env.num_envs)
        self._refined = self._lost = 0

    def _on_step(self) -> bool:
        infos, dones = self.locals["infos"], self.locals["dones"]
        self._returns += self.locals["rewards"]
        for i, (info, done) in enumerate(zip(infos, dones, strict=True)):
            self._refined += int(info.get("sim_refined", False))
            self._lost += int(info.get("sim_unstable", False))
            match = info.get("match")
            if match is not None:
                home, away = match["score"]
                against = "scripted" if match["opponent"] == SCRIPTED else "snapshots"
                self.logger.record_mean(f"selfplay/goal_difference_vs_{against}", home - away)
                self.logger.record_mean(f"selfplay/win_rate_vs_{against}", float(home > away))
            if done:
                self.logger.record_mean("selfplay/player_return", float(self._returns[i]))
                self._returns[i] = 0.0
        if self.num_timesteps - self._last >= self.snapshot_freq:
            self.snapshot()
        return True

    def _on_rollout_end(self) -> None:
        self.logger.record("selfplay/elo_learner", self.pool.ratings["learner"])
        snapshots = [self.pool.ratings[n] for n in self.pool.drawable]
        if snapshots:
            self.logger.record("selfplay/elo_best_snapshot", max(snapshots))
        self.logger.record("selfplay/pool_size", len(self.pool.drawable))
        self.logger.record("selfplay/steps_run_again", self._refined)
        self.logger.record("selfplay/matches_lost_unstable", self._lost)
        self._refined = self._lost = 0

    def _on_training_end(self) -> None:
        self.write_ratings()

    def snapshot(self) -> None:
        from agents.sb3 import save_model

        name = f"step_{self.num_timesteps:010d}"  # as the run's checkpoints are named
        self.pool.add(name, SnapshotOpponent.of(self.model, self.pool.base, self.pool.residual))
        save_model(self.model, self.run_dir / POOL_DIR / f"{name}.zip", {**self.manifest, "snapshot": name})
        self._last = self.num_timesteps
        self.write_ratings()

    def write_ratings(self) -> None:
        write_json(self.run_dir / RATINGS_FILE, {**self.pool.summary(), "num_timesteps": int(self.num_timesteps)})
