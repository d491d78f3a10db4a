"""Self-play (agents/soccer/selfplay.py, ``train.py --soccer``) and trained teams in ``evaluate.py --soccer``."""

import json

import numpy as np
import pytest

from agents.soccer.play import play
from agents.soccer.selfplay import ANCHOR_RATING, ELO_K, SCRIPTED, Pool, SelfPlayVecEnv
from envs.soccer import match
from envs.soccer.scripted import scripted_team
from tests.conftest import ENV_IDS  # noqa: F401  (registers the envs)
from tests.test_train import scalars, train_in_process


class Dummy:
    def act(self, obs, matches):
        return np.zeros((len(obs), 2))


def test_elo_moves_the_learner_and_its_snapshots_but_not_the_anchor():
    pool = Pool(Dummy(), np.random.default_rng(0), scripted_share=0.0, pool_size=2)
    pool.record(SCRIPTED, 2, 0)  # a win against an equal rating: K / 2
    assert pool.ratings["learner"] == pytest.approx(ANCHOR_RATING + ELO_K / 2)
    assert pool.ratings[SCRIPTED] == ANCHOR_RATING
    pool.add("a", Dummy())
    assert pool.ratings["a"] == pool.ratings["learner"]
    before = pool.ratings["learner"]
    pool.record("a", 0, 0)  # a draw between equals moves nothing
    assert pool.ratings["learner"] == before and pool.ratings["a"] == before
    pool.record("a", 0, 1)
    assert pool.ratings["learner"] + pool.ratings["a"] == pytest.approx(2 * before), "zero-sum between snapshots"
    assert pool.records["a"] == [0, 1, 1] and pool.records[SCRIPTED] == [1, 0, 0]
    pool.add("b", Dummy())
    pool.add("c", Dummy())
    assert pool.drawable == ["b", "c"], "beyond pool_size the oldest snapshot is no longer drawn"
    assert {pool.draw() for _ in range(50)} == {"b", "c"}, "scripted_share 0: snapshots only"
    pool.release(["a", "b"])
    assert "a" in pool.opponents, "a match still plays it"
    pool.release(["b"])
    assert list(pool.opponents) == [SCRIPTED, "b", "c"]


def test_a_pool_with_no_snapshot_draws_the_scripted_team():
    pool = Pool(Dummy(), np.random.default_rng(0), scripted_share=0.0)
    assert {pool.draw() for _ in range(10)} == {SCRIPTED}


def test_the_learners_matches_are_the_pettingzoo_matches_against_the_scripted_team():
    """Scripted share 1: each learner match is, bit for bit, the PettingZoo match seeded alike in which the home team
    takes the learner's actions and the away team is the scripted team; a finished match reports its score and
    starts again."""
    venv = SelfPlayVecEnv(2, robot="roach", players_per_team=1, action_mode="commands", scripted_share=1.0,
                          match_seconds=0.3)  # fmt: skip
    venv.seed(5)
    obs = venv.reset()
    envs = [match.parallel_env(robot="roach", players_per_team=1, action_mode="commands", max_cycles=10**6)
            for _ in range(2)]  # fmt: skip
    away = [scripted_team(e, "away")["away_0"] for e in envs]
    memory = [None, None]
    firsts = [e.reset(seed=5 + i)[0] for i, e in enumerate(envs)]
    np.testing.assert_array_equal(obs, [f["home_0"] for f in firsts])
    seen = list(firsts)
    rng = np.random.default_rng(1)
    steps = round(0.3 / envs[0].engine.dt)
    for step in range(steps):
        actions = rng.uniform(-1, 1, (2, 2))
        obs, _, done, infos = venv.step(actions)
        for i, e in enumerate(envs):
            scripted, memory[i] = away[i].predict(seen[i]["away_0"], memory[i])
            moves = {"home_0": actions[i], "away_0": scripted}
            seen[i], rewards, *_ = e.step(moves)
            if step < steps - 1:
                np.testing.assert_array_equal(obs[i], seen[i]["home_0"])
            else:
                np.testing.assert_array_equal(infos[i]["terminal_observation"], seen[i]["home_0"])
            assert infos[i]["reward_goal"] == rewards["home_0"]
    assert done.all() and all(info["match"]["opponent"] == SCRIPTED for info in infos)
    assert all(info["match"]["score"] == [0, 0] for info in infos)


def test_a_match_step_run_again_or_lost_is_said_in_its_first_learners_info(monkeypatch):
    """What self-play's TensorBoard counts (selfplay/steps_run_again, selfplay/matches_lost_unstable): a match's step
    that diverged and held at shorter physics steps, or was lost, flagged once, on its first learner's info."""
    step = match.Matches.step

    def flagged(self, actions):
        out = step(self, actions)
        out["refined"][1] = True
        out["unstable"][0] = True
        return out

    monkeypatch.setattr(match.Matches, "step", flagged)
    venv = SelfPlayVecEnv(2, robot="roach", players_per_team=2, action_mode="commands", scripted_share=1.0,
                          match_seconds=0.3)  # fmt: skip
    venv.seed(0)
    venv.reset()
    _, _, _, infos = venv.step(np.zeros((venv.num_envs, 2)))
    assert [bool(i.get("sim_refined")) for i in infos] == [False, False, True, False]
    assert [bool(i.get("sim_unstable")) for i in infos] == [True, False, False, False]


def test_train_soccer_runs_self_play_and_evaluate_plays_the_team(tmp_path):
    """A short self-play run: checkpoints, snapshots in pool/, ratings.json, the self-play scalars in TensorBoard;
    then evaluate.py's matches take the trained model as a team, and refuse it for another team size (the Bioloid:
    its physics is the fastest at a 20 ms step)."""
    done = train_in_process("--soccer", "bioloid", "--players", "1", "--timesteps", "2048", "--n-envs", "4",
                            "--match-seconds", "2", "--checkpoint-freq", "1024", "--runs-dir", tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    (run_dir,) = tmp_path.iterdir()
    config = json.loads((run_dir / "config.json").read_text())
    assert config["soccer"]["robot"] == "bioloid" and config["env_id"] == "soccer/bioloid"
    ratings = json.loads((run_dir / "ratings.json").read_text())
    assert ratings["ratings"][SCRIPTED] == ANCHOR_RATING and ratings["num_timesteps"] >= 2048
    played = sum(sum(r.values()) for r in ratings["learner_record"].values())
    assert played == 4 * (2048 // 4 // 100), "every finished 2 s match (100 steps) of the 4 counted"
    assert sorted(p.name for p in (run_dir / "pool").iterdir()) == ["step_0000001024.zip", "step_0000002048.zip"]
    tags = scalars(run_dir / "tb")
    assert {"selfplay/elo_learner", "selfplay/win_rate_vs_scripted", "selfplay/player_return"} <= set(tags)
    result = play("bioloid", 1, str(run_dir / "model.zip"), "scripted", 2, 0, 1.0)
    assert result["matches"] == 2
    with pytest.raises(ValueError, match="players_per_team"):
        play("bioloid", 2, str(run_dir / "pool" / "step_0000001024.zip"), "random", 1, 0, 1.0)
    # resumed from its last checkpoint: the pool and the ratings carry on
    (run_dir / "pool" / "step_0000009999.zip").write_bytes(b"left by a killed run, after its checkpoint")
    resumed = train_in_process("--resume", run_dir, "--timesteps", "3072")
    assert resumed.returncode == 0, resumed.stderr
    assert sorted(p.name for p in (run_dir / "pool").iterdir()) == [
        "step_0000001024.zip", "step_0000002048.zip", "step_0000003072.zip"]  # fmt: skip
    again = json.loads((run_dir / "ratings.json").read_text())
    assert again["num_timesteps"] == 3072
    assert sum(sum(r.values()) for r in again["learner_record"].values()) == played + 4 * (1024 // 4 // 100)


def test_train_soccer_offers_every_robot_that_plays_soccer():
    # train.py keeps its own list, so that starting it does not load every robot's soccer scene
    from agents.training import SOCCER_ROBOTS
    from envs.soccer.robots import BY_NAME

    assert sorted(SOCCER_ROBOTS) == sorted(BY_NAME)


def test_train_soccer_refuses_nonsense_before_making_anything(tmp_path):
    for args, word in ((("--env", "skitter/RoachWalk-v4"), "not both"), (("--algo", "sac"), "PPO"),
                       (("--players", "5"), "--players"), (("--scripted-share", "2"), "--scripted-share"),
                       (("--resume", "x"), "without --soccer"),
                       (("--players", "3", "--n-envs", "1"), "(matches) x players = 256 x 1 x 3")):  # fmt: skip
        done = train_in_process("--soccer", "roach", "--timesteps", "10", "--runs-dir", tmp_path, *args)
        assert done.returncode == 2 and word in done.stderr, (args, done.stderr)
    for flag in ("--players", "--match-seconds", "--scripted-share", "--snapshot-freq"):  # not ignored without it
        done = train_in_process("--env", "skitter/RoachWalk-v4", "--timesteps", "10", "--runs-dir", tmp_path, flag, "2")
        assert done.returncode == 2 and f"{flag} is a self-play option: give --soccer" in done.stderr, done.stderr
        done = train_in_process("--resume", tmp_path / "a_run", flag, "2")  # a run keeps its own, self-play or not
        assert done.returncode == 2 and "--resume takes the run's settings from its folder" in done.stderr
    assert not any(tmp_path.iterdir())


def test_a_residual_learner_that_corrects_nothing_plays_the_scripted_team():
    """With ``residual``, the learner's actions correct the scripted home team's commands: actions of 0 play, bit for
    bit, the PettingZoo match of the scripted team against itself; a scale beyond (0, 2] is refused."""
    venv = SelfPlayVecEnv(2, robot="roach", players_per_team=1, action_mode="commands", scripted_share=1.0,
                          match_seconds=0.3, residual=0.5)  # fmt: skip
    venv.seed(5)
    obs = venv.reset()
    envs = [match.parallel_env(robot="roach", players_per_team=1, action_mode="commands", max_cycles=10**6)
            for _ in range(2)]  # fmt: skip
    teams = [{**scripted_team(e, "home"), **scripted_team(e, "away")} for e in envs]
    memory = [{}, {}]
    seen = [e.reset(seed=5 + i)[0] for i, e in enumerate(envs)]
    np.testing.assert_array_equal(obs, [s["home_0"] for s in seen])
    for _ in range(5):
        obs, *_ = venv.step(np.zeros((2, 2)))
        for i, e in enumerate(envs):
            moves = {}
            for agent, player in teams[i].items():
                moves[agent], memory[i][agent] = player.predict(seen[i][agent], memory[i].get(agent))
            seen[i], *_ = e.step(moves)
            np.testing.assert_array_equal(obs[i], seen[i]["home_0"])
    for bad in (3.0, 0.0, True):
        with pytest.raises(ValueError, match="correction scale"):
            SelfPlayVecEnv(1, robot="roach", players_per_team=1, action_mode="commands", residual=bad)


def test_train_soccer_residual_on_the_scripted_team(tmp_path):
    """``train.py --soccer ROBOT --residual scripted``: the model records its residual, its snapshots play on top of
    the scripted away team, and evaluate.py's matches play it on top of the scripted team; another gait is refused."""
    done = train_in_process("--soccer", "bioloid", "--players", "1", "--timesteps", "512", "--n-envs", "4",
                            "--match-seconds", "1", "--checkpoint-freq", "256", "--residual", "scripted",
                            "--runs-dir", tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    (run_dir,) = tmp_path.iterdir()
    config = json.loads((run_dir / "config.json").read_text())
    assert config["soccer"]["residual"] == 0.25 and config["hyperparams"]["residual"] == {"policy": SCRIPTED}
    from agents.sb3 import read_model_file

    manifest, _ = read_model_file(run_dir / "model.zip")
    assert manifest["residual"] == {"policy": SCRIPTED, "scale": 0.25}
    ratings = json.loads((run_dir / "ratings.json").read_text())
    steps = ratings["num_timesteps"]  # whole rollouts of PPO's n_steps x 4
    assert sum(sum(r.values()) for r in ratings["learner_record"].values()) == 4 * (steps // 4 // 50)
    snapshots = {n: r for n, r in ratings["learner_record"].items() if n != SCRIPTED}
    assert sum(sum(r.values()) for r in snapshots.values()) > 0, "snapshots (on the scripted team) played matches"
    result = play("bioloid", 1, str(run_dir / "model.zip"), "scripted", 2, 0, 1.0)
    assert result["matches"] == 2
    refused = train_in_process("--soccer", "roach", "--timesteps", "10", "--residual", "tripod",
                               "--runs-dir", tmp_path / "other")  # fmt: skip
    assert refused.returncode == 2 and "--residual tripod" in refused.stderr, refused.stderr
    assert not (tmp_path / "other").exists()


def test_evaluate_plays_a_residual_team_on_top_of_the_scripted_team(monkeypatch):
    """evaluate.py's team of a residual model: the scripted team's commands plus the model's correction at the scale
    its file records, clipped; a correction of 0 is the scripted team, step by step."""
    from types import SimpleNamespace

    from agents.soccer import play as play_module
    from envs.soccer.match import Matches

    correction = {"value": 0.0}

    def predict(obs, deterministic):
        return np.full((len(obs), 2), correction["value"]), None

    stub = SimpleNamespace(manifest={"residual": {"policy": SCRIPTED, "scale": 0.25}}, predict=predict)
    monkeypatch.setattr(play_module, "trained_team", lambda spec, engine: stub)
    engine = Matches(robot="roach", players_per_team=2, action_mode="commands", num_matches=2, batched=True,
                     max_cycles=10**6)  # fmt: skip
    for m in range(2):
        engine.seed(m, 7 + m)
    engine.reset(np.arange(2))
    residual = play_module.TeamPolicy("team.zip", engine, "home", 0)
    scripted = play_module.TeamPolicy("scripted", engine, "home", 0)
    away = play_module.TeamPolicy("scripted", engine, "away", 0)
    rows = np.concatenate(scripted.rows)
    for step in range(6):
        correction["value"] = 0.0 if step < 3 else 1.0
        actions, expected = np.zeros((engine.robot.num_sims, 2)), np.zeros((engine.robot.num_sims, 2))
        scripted.act(engine.obs, expected)
        residual.act(engine.obs, actions)
        np.testing.assert_array_equal(actions[rows], np.clip(expected[rows] + 0.25 * correction["value"], -1, 1))
        away.act(engine.obs, actions)
        engine.step(actions)
    stub.manifest["residual"] = {"policy": "tripod"}
    with pytest.raises(ValueError, match="tripod"):
        play_module.TeamPolicy("team.zip", engine, "home", 0)
