"""Matches between two teams' policies (``evaluate.py --soccer``): statistics, results, bad input."""

import json

import numpy as np
import pytest

import evaluate
from agents.soccer.play import play, statistics
from envs.soccer import match


def test_the_record_and_its_intervals():
    result = statistics(np.array([[2, 0], [1, 1], [0, 1], [3, 0]]))
    assert (result["wins"]["count"], result["draws"]["count"], result["losses"]["count"]) == (2, 1, 1)
    assert result["wins"]["ci_low"] < 0.5 < result["wins"]["ci_high"]
    gd = result["goal_difference"]
    assert gd["mean"] == pytest.approx(1.0) and gd["ci_low"] <= 1.0 <= gd["ci_high"] and gd["ci_low"] < gd["ci_high"]
    assert result["goals"] == {"home": 6, "away": 2}
    even = statistics(np.zeros((5, 2), dtype=int))
    assert even["draws"]["count"] == 5 and even["goal_difference"] == {"mean": 0.0, "ci_low": 0.0, "ci_high": 0.0}


def test_matches_played_together_are_the_pettingzoo_matches_of_their_seeds():
    """Match i of a batch is the PettingZoo match reset with seed SEED + i, the same teams playing."""
    from envs.soccer.scripted import scripted_team

    played = play("bioloid", 1, "scripted", "scripted", 2, 5, 0.4)
    for i in range(2):
        env = match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands")
        obs, _ = env.reset(seed=5 + i)
        team = {**scripted_team(env, "home"), **scripted_team(env, "away")}
        memory = dict.fromkeys(team)
        for _ in range(round(0.4 / env.dt)):
            moves = {}
            for a, p in team.items():
                moves[a], memory[a] = p.predict(obs[a], memory[a])
            obs, *_ = env.step(moves)
        assert played["scores"][i] == [env.score["home"], env.score["away"]]


def test_a_match_against_the_random_team_replays_alone_from_its_seed():
    """The random team draws each match's actions from that match's seed: match 1 of seed 5 is match 0 of seed 6,
    so ``--seed 6 --matches 1 --video`` shows it."""
    from agents.soccer.play import prepare

    runs = []
    for seed, matches in ((5, 2), (6, 1)):
        engine, teams = prepare("bioloid", 1, "scripted", "random", matches, seed, 0.2)
        actions = np.zeros((engine.robot.num_sims, engine.mode.size))
        for _ in range(engine.max_cycles):
            for team in teams:
                team.act(engine.obs, actions)
            engine.step(actions)
        runs.append(engine.obs[engine.rows_of(np.array([matches - 1]))].copy())
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_match_that_goes_unstable_is_stopped_there_and_said_so(monkeypatch):
    """A scene MuJoCo had to reset ends its match at that step: later goals there do not count, the others' do, and
    the record and report name the match and when."""
    import argparse

    from agents.soccer.play import report

    step, calls = match.Matches.step, []

    def step_with_trouble(self, actions):
        out = step(self, actions)
        calls.append(None)
        if len(calls) == 2:  # match 1's scene blows up at the second step
            out["unstable"][1] = True
        if len(calls) in (1, 3):  # match 0's first and third steps diverged and held at shorter steps
            out["refined"][0] = True
        if len(calls) == 4:  # a goal in each match afterwards: only match 0's counts
            self.scores[:, 0] += 1
        return out

    monkeypatch.setattr(match.Matches, "step", step_with_trouble)
    result = play("roach", 1, "random", "random", 2, 3, 0.2)
    dt = 0.2 / len(calls)
    assert result["scores"] == [[1, 0], [0, 0]]
    assert result["stopped_unstable"] == [{"match": 1, "seed": 4, "seconds": pytest.approx(2 * dt), "score": [0, 0]}]
    assert result["wins"]["count"] == 1 and result["draws"]["count"] == 1
    args = argparse.Namespace(soccer="roach", players=1, home="random", away="random", match_seconds=0.2, seed=3,
                              matches=2)  # fmt: skip
    assert "1 of 2 matches went numerically unstable" in report(args, result) and "seed 4 at" in report(args, result)
    assert result["refined_steps"] == [2, 0]
    assert "2 control steps in 1 match diverged and held" in report(args, result)


def test_evaluate_plays_matches_and_writes_one_folder(tmp_path, capsys):
    out = tmp_path / "m"
    assert evaluate.main(["--soccer", "bioloid", "--players", "1", "--home", "scripted", "--away", "random",
                          "--matches", "2", "--match-seconds", "0.4", "--out", str(out)]) == 0  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    assert record["seeds"] == [0, 1] and len(record["scores"]) == 2 and record["home"] == "scripted"
    assert "| wins | draws | losses |" in (out / "results.md").read_text() and "wins" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["results.json", "results.md"]


@pytest.mark.parametrize(
    ("args", "word"),
    [(["--soccer", "aibo"], "--soccer"), (["--players", "5"], "--players"), (["--home", "ppo"], "--home"),
     (["--matches", "0"], "--matches"), (["--match-seconds", "-1"], "--match-seconds"),
     (["--action-mode", "goal"], "commands"), (["--action-mode", "bogus"], "--action-mode must be one of")],
)  # fmt: skip
def test_bad_arguments_are_one_line_errors_before_any_match(args, word, tmp_path, capsys):
    base = {"--soccer": "bioloid", "--home": "scripted", "--away": "random", "--out": str(tmp_path / "x")}
    for flag, value in zip(args[::2], args[1::2], strict=True):
        base[flag] = value
    with pytest.raises(SystemExit) as stop:
        evaluate.main([item for pair in base.items() for item in pair])
    assert stop.value.code == 2 and word in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    ("args", "words"),
    [(["--kick"], "the robot's own mode (give --action-mode commands)")],
)  # fmt: skip
def test_teams_that_cannot_play_are_refused_before_any_folder_is_made(args, words, tmp_path, capsys):
    out = tmp_path / "deep" / "x"
    code = evaluate.main(["--soccer", "roach", "--players", "1", "--home", "random", "--away", "random", *args,
                          "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("evaluate.py --soccer: error: ") and words in err and "Traceback" not in err
    assert not (tmp_path / "deep").exists()


def test_a_team_given_as_a_run_or_checkpoint_folder_is_its_model(tmp_path):
    from agents.soccer.play import model_in

    checkpoint = tmp_path / "run" / "checkpoints" / "step_0000001024"
    checkpoint.mkdir(parents=True)
    (checkpoint / "model.zip").write_bytes(b"")
    assert model_in(str(checkpoint)) == str(checkpoint / "model.zip")
    assert model_in(str(tmp_path / "run")) == str(tmp_path / "run")  # no final model yet: refused as not a model
    assert model_in("scripted") == "scripted"


def test_the_soccer_options_are_listed_before_a_robot_is_named(capsys):
    with pytest.raises(SystemExit) as stop:
        evaluate.main(["--soccer", "--help"])
    assert stop.value.code == 0 and "--match-seconds" in capsys.readouterr().out
