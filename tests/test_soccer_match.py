"""Multi-robot soccer: PettingZoo's own tests, mirror symmetry, goals and kickoffs, the referee, rendering."""

import functools
import types
from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest
from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test, seed_test

from envs.soccer import match
from envs.soccer.field import BALL, THROW_IN_BACK, THROW_IN_INSET


def pettingzoo_battery(robot: str, k: int, cycles: int) -> None:
    """Every PettingZoo test the suite promises, on one robot and team size."""
    parallel = functools.partial(match.parallel_env, robot=robot, players_per_team=k)
    aec = functools.partial(match.env, robot=robot, players_per_team=k)
    parallel_api_test(parallel(), num_cycles=cycles)
    api_test(aec(), num_cycles=cycles)
    parallel_seed_test(parallel, num_cycles=cycles)
    seed_test(aec, num_cycles=cycles)
    max_cycles_test(types.SimpleNamespace(parallel_env=parallel, env=aec))
    render_test(functools.partial(aec, render_mode="rgb_array"))


def test_pettingzoo_tests_pass_on_a_three_a_side_bioloid_match():
    """The full matrix (every robot, 1 to 3 a side and 4 for the Bioloid) is benchmarks/soccer_api.py's, whose
    results the last test here checks."""
    pettingzoo_battery("bioloid", 3, 40)


def quiet(**kwargs):
    return match.parallel_env(ball_noise=0.0, sensor_noise=False, reset_noise_scale=0.0, **kwargs)


def test_turning_the_field_and_swapping_the_teams_swaps_observations_and_rewards():
    """The kickoff is symmetric by half a turn: a home player and its away counterpart, sent the same actions, see
    the same (to rounding) and are rewarded the same."""
    env = quiet(robot="bioloid", players_per_team=2)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(40):
        for i in range(2):
            np.testing.assert_allclose(obs[f"home_{i}"], obs[f"away_{i}"], atol=1e-9)
        home = {f"home_{i}": rng.uniform(-0.3, 0.3, 16) for i in range(2)}
        obs, rewards, *_ = env.step({**home, **{f"away_{i}": home[f"home_{i}"] for i in range(2)}})
        assert rewards["home_0"] == rewards["away_0"] == 0.0


def roll_ball(env, x: float, speed: float) -> None:
    """The ball at (x, 0), rolling along x (written into the running match)."""
    data = env.scene.sim.data
    q, v = env.scene.objects[BALL]
    data.qpos[q : q + 3] = [x, 0.0, env.field.ball.radius]
    data.qvel[v : v + 6] = [speed, 0, 0, 0, 0, 0]


def test_a_goal_rewards_both_teams_and_the_next_step_kicks_off():
    env = quiet(robot="roach", players_per_team=1)
    env.reset(seed=0)
    hl = env.field.half_length
    still = {a: np.zeros(3) for a in env.possible_agents}
    roll_ball(env, -(hl - 0.03), -3.0)  # into the home team's goal
    for _ in range(10):
        _, rewards, terminations, _, infos = env.step(still)
        if rewards["away_0"]:
            break
    assert (rewards["away_0"], rewards["home_0"]) == (1.0, -1.0)
    assert infos["home_0"]["score"] == {"home": 0, "away": 1} and not any(terminations.values())
    env.step(still)
    ball = env.scene.scene_sensor("ball_pos")[0]
    assert abs(ball[0]) < 1e-3 and abs(ball[1]) < 1e-3, "the kickoff puts the ball on the centre spot"


def test_a_ball_that_leaves_the_field_is_put_back_as_a_referee_would():
    """Rolled over a touch line, the ball is put back at rest a metre (scaled) nearer the halfway line (nobody has
    touched it since the kickoff), a body length inside the line; the step's info says so, and the shaping terms
    do not count the jump."""
    env = quiet(robot="roach", players_per_team=1)
    env.reset(seed=0)
    f = env.field
    data = env.scene.sim.data
    q, v = env.scene.objects[BALL]
    x_out = 0.5 * f.half_length
    data.qpos[q : q + 3] = [x_out, f.half_width - 0.01, f.ball.radius]
    data.qvel[v : v + 6] = [0.0, 1.0, 0, 0, 0, 0]
    still = {a: np.zeros(3) for a in env.possible_agents}
    for _ in range(20):
        _, rewards, _, _, infos = env.step(still)
        if infos["home_0"]["throw_in"]:
            break
    assert infos["home_0"]["throw_in"] and infos["away_0"]["throw_in"] and rewards["home_0"] == 0.0
    ball = env.scene.scene_sensor("ball_pos")[0]
    expected = f.throw_in(x_out, f.half_width + 0.05, 0, np.zeros((0, 2)), 0.0)
    assert ball[0] == pytest.approx(max(x_out - THROW_IN_BACK * f.scale, 0.0)) == pytest.approx(expected[0])
    assert ball[1] == pytest.approx(f.half_width - THROW_IN_INSET * f.scale)
    assert np.allclose(env.scene.scene_sensor("ball_vel")[0], 0.0)
    _, _, _, _, infos = env.step(still)
    assert not infos["home_0"]["throw_in"]
    assert abs(infos["home_0"]["approach"]) < 0.05 and abs(infos["home_0"]["ball_progress"]) < 0.05
    assert np.allclose(env.scene.scene_sensor("ball_pos")[0][:2], ball[:2], atol=2e-3), "it stays where it was put"


def test_the_throw_in_goes_toward_the_goal_of_the_team_that_touched_the_ball_last_and_is_symmetric():
    f = match.FIELDS["Bioloid"]
    back, inset = THROW_IN_BACK * f.scale, THROW_IN_INSET * f.scale
    x = np.array([0.5, 0.5, 1.2, 0.4, f.half_length + 0.1, -(f.half_length + 0.1)])
    y = np.array([f.half_width + 0.1, f.half_width + 0.1, -(f.half_width + 0.1), f.half_width + 0.1, 0.9, -0.9])
    last = np.array([1, -1, 0, 0, -1, 1])  # home's goal is at -x: a home touch sends the ball toward -x
    none = np.zeros((0, 2))

    def throw(xs, ys, lasts):
        return np.array([f.throw_in(*a, none, 0.0) for a in zip(xs, ys, lasts, strict=True)]).T

    px, py = throw(x, y, last)
    limit = f.half_length - back
    np.testing.assert_allclose(px, [0.5 - back, 0.5 + back, 1.2 - back, 0.0, limit, -limit])
    np.testing.assert_allclose(py, [*[f.half_width - inset] * 2, inset - f.half_width, f.half_width - inset, 0.9, -0.9])
    mx, my = throw(-x, -y, -last)  # the field turned by half a turn, the teams swapped
    np.testing.assert_allclose(mx, -px)
    np.testing.assert_allclose(my, -py)
    assert list(f.left_field(x, y)) == [True] * 6
    inside = f.left_field(np.array([f.half_length + 0.1, 0.0, f.half_length]), np.array([0.0, f.half_width, 1.0]))
    assert not inside.any(), "past the goal line between the posts is a goal; on a line is still in"


def test_a_throw_in_spot_taken_by_a_player_moves_along_the_line_clear_of_it():
    """A player standing on the throw-in spot: the ball goes a body length on along the touch line, the way it was
    sent, not into the robot (which would shoot it out)."""
    env = quiet(robot="roach", players_per_team=1)
    f = env.field
    spot = (0.0, -(f.half_width - THROW_IN_INSET * f.scale))  # where a ball out at x = 0.3 m, untouched, goes
    env.reset(seed=0, options={"ball": (0.3, -(f.half_width + 1.5 * f.ball.radius)),
                               "places": {"home_0": (*spot, 0.0)}})  # fmt: skip
    _, _, _, _, infos = env.step({a: np.zeros(3) for a in env.possible_agents})
    assert infos["home_0"]["throw_in"]
    ball = env.scene.scene_sensor("ball_pos")[0]
    length = env.task.length
    assert ball[1] == pytest.approx(spot[1]) and ball[0] == pytest.approx(-length), "one body length on, toward -x"
    robot = env.robot.read([None, None], False)["position"][0]
    assert np.hypot(*(ball[:2] - robot[:2])) > length
    _, _, _, _, infos = env.step({a: np.zeros(3) for a in env.possible_agents})
    assert np.linalg.norm(env.scene.scene_sensor("ball_vel")[0]) < 0.05 and not infos["home_0"]["touched"]


def test_without_the_throw_in_a_ball_past_the_touch_line_stays_in_play():
    env = quiet(robot="roach", players_per_team=1, throw_in=False)
    env.reset(seed=0)
    f = env.field
    data = env.scene.sim.data
    q, v = env.scene.objects[BALL]
    data.qpos[q : q + 3] = [0.0, f.half_width + 2 * f.ball.radius, f.ball.radius]
    data.qvel[v : v + 6] = 0.0
    for _ in range(5):
        _, _, _, _, infos = env.step({a: np.zeros(3) for a in env.possible_agents})
        assert not infos["home_0"]["throw_in"]
    assert env.scene.scene_sensor("ball_pos")[0][1] > f.half_width


def test_a_match_to_one_goal_ends_by_rule():
    env = quiet(robot="roach", players_per_team=1, max_goals=1)
    env.reset(seed=0)
    roll_ball(env, env.field.half_length - 0.03, 3.0)
    for _ in range(10):
        _, rewards, terminations, truncations, _ = env.step({a: np.zeros(3) for a in env.agents})
        if any(terminations.values()):
            break
    assert all(terminations.values()) and not any(truncations.values()) and rewards["home_0"] == 1.0
    assert env.agents == []


def test_a_fallen_player_is_taken_off_and_put_back_at_its_own_half():
    env = match.parallel_env(robot="bioloid", players_per_team=1, penalty_seconds=0.5)
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    seen = []
    for _ in range(400):
        _, _, _, _, infos = env.step({a: rng.uniform(-1, 1, 16) for a in env.agents})
        where = env.scene.sim.data.qpos[:2].copy()  # home_0's root: the first block of the scene's qpos
        seen.append((infos["home_0"]["fallen"], infos["home_0"]["off"], where))
        if len(seen) > 2 and seen[-2][1] and not seen[-1][1]:
            break
    fell = next(i for i, s in enumerate(seen) if s[0])
    off = seen[fell + 2][2]
    assert off[1] < -(env.field.half_width + env.field.side_border), "off the field, beyond the wall"
    back = seen[-1][2]
    assert back[0] < 0 and abs(back[1]) < env.field.half_width, "back on its own half, inside the touch line"


@pytest.mark.parametrize(("robot", "k", "back"), [("bioloid", 3, [3, 4]), ("roach", 4, [0, 1, 2, 3])])
def test_players_put_back_together_are_put_apart_and_clear_of_the_others(robot, k, back):
    """Players of a team whose penalties end in the same step (two of a Bioloid three, a whole roach four) come back
    on their side of the field, each a ``RETURN_CLEARANCE`` of body lengths from everyone else and from the ball (one
    spot for all of them put one inside the other, and the scene blew up)."""
    engine = match.Matches(robot=robot, players_per_team=k, num_matches=1)
    engine.seed(0, 7)
    engine.reset(np.arange(1))
    rest = np.tile(engine.rest, (engine.players, 1))
    engine.step(rest)
    back = np.array(back)  # due back now (standing where they are, as if waiting outside)
    engine.off_until[back] = engine.scene.time[0]
    side = 1.0 if back[0] < k else -1.0
    blocker = 2 * k - 1 if side > 0 else 0  # a player of the other team read standing on the first spot
    engine._where[blocker] = engine._return_spots(side)[0]
    before = engine._where.copy()
    engine.step(rest)
    places = engine.scene.placement[back]
    length, f = engine.robot.facts.length, engine.field
    assert np.all(side * places[:, 0] < 0) and np.all(side * places[:, 1] < 0), "its own half, its own touch side"
    assert np.all(np.abs(places[:, 1]) <= f.half_width - 0.5 * length + 1e-12), "inside the touch line"
    assert np.all(np.abs(places[:, 2] - side * np.pi / 2) < 1e-12), "facing into the field"
    others = np.vstack([np.delete(before, back, axis=0), engine.scene.scene_sensor(match.BALL_POS)[0, :2]])
    clearance = match.RETURN_CLEARANCE * length - 1e-9
    for i, place in enumerate(places):
        assert np.linalg.norm(others - place[:2], axis=1).min() >= clearance
        assert all(np.linalg.norm(place[:2] - q[:2]) >= clearance for q in places[i + 1 :])


def test_without_a_referee_a_fallen_player_stays():
    env = match.parallel_env(robot="bioloid", players_per_team=1, referee=False)
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    for _ in range(200):
        _, _, _, _, infos = env.step({a: rng.uniform(-1, 1, 16) for a in env.agents})
        assert not infos["home_0"]["off"] and not infos["away_0"]["off"]


def test_a_three_a_side_bioloid_match_renders_to_mp4_headless(tmp_path):
    env = match.parallel_env(robot="bioloid", players_per_team=3, render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    path = tmp_path / "match.mp4"
    with imageio.get_writer(path, fps=env.metadata["render_fps"]) as writer:
        for _ in range(6):
            env.step({a: env.action_space(a).sample() for a in env.agents})
            frame = env.render()
            assert frame.shape == (120, 160, 3) and frame.std() > 5
            writer.append_data(frame)
    with imageio.get_reader(path) as reader:
        assert reader.count_frames() == 6


def test_supersuits_path_gives_an_sb3_vec_env_of_every_player():
    import supersuit as ss

    vec = ss.concat_vec_envs_v1(ss.pettingzoo_env_to_vec_env_v1(match.parallel_env(players_per_team=2)), 2,
                                base_class="stable_baselines3")  # fmt: skip
    obs = vec.reset()
    assert obs.shape[0] == 8
    obs, *_ = vec.step(np.zeros((8, 16), dtype=np.float32))
    assert obs.shape[0] == 8 and np.isfinite(obs).all()


@pytest.mark.parametrize(
    ("kwargs", "word"),
    [({"robot": "aibo"}, "robot"), ({"players_per_team": 5}, "players_per_team"), ({"camera": "away_9"}, "camera"),
     ({"max_goals": 0}, "max_goals"), ({"render_mode": "ansi"}, "render_mode"), ({"penalty_seconds": -1}, "penalty"),
     ({"max_cycles": 0}, "max_cycles"), ({"action_mode": "kick"}, "action_mode"), ({"robot": ["roach"]}, "robot"),
     ({"players_per_team": 2.0}, "players_per_team"), ({"max_cycles": 2.5}, "max_cycles")],
)  # fmt: skip
def test_bad_arguments_are_refused_by_name(kwargs, word):
    with pytest.raises(ValueError, match=word):
        match.parallel_env(**kwargs)


def test_a_bad_action_is_refused_by_agent():
    env = match.parallel_env(robot="roach", players_per_team=1)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="away_0"):
        env.step({"home_0": np.zeros(3), "away_0": np.array([np.nan, 0.0, 0.0])})
    with pytest.raises(ValueError, match=r"agents not in this match: \['home0'\]"):  # a typo is not "no action"
        env.step({"home0": np.zeros(3), "away_0": np.zeros(3)})
    with pytest.raises(ValueError, match="actions must be a dict of agent name -> action, got list"):
        env.step([np.zeros(3), np.zeros(3)])
    with pytest.raises(ValueError, match="seed must be a whole number >= 0"):
        env.reset(seed=-1)
    with pytest.raises(ValueError, match="max_cycles"):
        env.max_cycles = -5
    with pytest.raises(TypeError, match="sparse"):  # a match's reward is the goal alone: no flag to pretend otherwise
        match.parallel_env(robot="roach", sparse=True)


def test_numpy_whole_numbers_are_whole_numbers():
    env = match.parallel_env(robot="bioloid", players_per_team=np.int64(1), max_cycles=np.int64(10))
    env.max_cycles = np.int64(12)
    assert env.max_cycles == 12 and env.possible_agents == ["home_0", "away_0"]
    env.reset(seed=np.int64(3))


def test_the_benchmark_ran_every_robot_and_team_size_and_every_test_passed():
    """benchmarks/results/soccer_api.json (``python -m benchmarks.soccer_api``)."""
    import json
    from pathlib import Path

    from benchmarks.soccer_api import TESTS, matrix

    result = json.loads((Path(__file__).resolve().parents[1] / "benchmarks/results/soccer_api.json").read_text())
    assert sorted((r["robot"], r["players_per_team"], r["action_mode"]) for r in result["rows"]) == sorted(matrix())
    assert result["passed"] and all(r["errors"] == dict.fromkeys(TESTS) for r in result["rows"])


def test_a_set_piece_places_players_and_ball_and_refuses_places_outside_the_walls():
    env = quiet(robot="roach", players_per_team=1)
    env.reset(seed=0, options={"places": {"away_0": [0.5, -0.2, 1.0]}, "ball": [0.3, 0.1]})
    data = env.scene.sim.data
    nq = env.robot.model.nq
    np.testing.assert_allclose(data.qpos[nq : nq + 2], [0.5, -0.2], atol=1e-9)
    np.testing.assert_allclose(env.scene.scene_sensor("ball_pos")[0, :2], [0.3, 0.1], atol=1e-9)
    for options, word in (({"ball": [5.0, 0.0]}, "ball"), ({"places": {"home_9": [0, 0, 0]}}, "places"),
                          ({"places": {"home_0": [0.0, 0.0]}}, "home_0")):  # fmt: skip
        with pytest.raises(ValueError, match=word):
            env.reset(seed=0, options=options)


@pytest.mark.parametrize("robot", ["bioloid", "roach"])
def test_batched_matches_are_the_pettingzoo_matches_bit_for_bit(robot):
    """Two matches (2 a side) on one mujoco.batch, as an SB3 VecEnv of 8 players, against two PettingZoo matches
    seeded as SB3 seeds them: the same observations and rewards at every step, across the time limit (SB3 starts a
    match again in the same step, with its last observation in the info). The roach's firmware gains follow each
    player's own sagging battery, written into its own actuators of the shared scene."""
    from agents.soccer.vec_env import SoccerVecEnv

    vec = SoccerVecEnv(2, robot=robot, players_per_team=2, max_cycles=8)
    vec.seed(10)
    singles = [match.parallel_env(robot=robot, players_per_team=2, max_cycles=8) for _ in range(2)]
    width = vec.action_space.shape[0]

    def rows(observations, env):
        return [observations[a] for a in env.possible_agents]

    obs = vec.reset()
    np.testing.assert_array_equal(obs, np.vstack([rows(env.reset(seed=10 + 4 * m)[0], env)
                                                  for m, env in enumerate(singles)]))  # fmt: skip
    rng = np.random.default_rng(0)
    for _ in range(12):
        actions = rng.uniform(-1, 1, (8, width)).astype(np.float32)
        obs, rewards, dones, infos = vec.step(actions)
        for m, env in enumerate(singles):
            o, r, term, trunc, _ = env.step({a: actions[4 * m + i] for i, a in enumerate(env.possible_agents)})
            mine = slice(4 * m, 4 * m + 4)
            np.testing.assert_array_equal(rewards[mine], [r[a] for a in env.possible_agents])
            assert dones[4 * m] == (term["home_0"] or trunc["home_0"])
            if dones[4 * m]:
                np.testing.assert_array_equal([info["terminal_observation"] for info in infos[mine]], rows(o, env))
                o = env.reset()[0]
            np.testing.assert_array_equal(obs[mine], rows(o, env))
    with pytest.raises(ValueError, match=rf"actions must be \(8, {width}\) \(an action per player of every match\)"):
        vec.step(np.zeros((3, width)))
    if robot == "roach":  # each player's actuators of the scene hold the gains of its own sagging battery
        from envs.actuators.dcmotor import SUPPLY_SLOTS

        players, scene = vec.engine.robot, vec.engine.scene
        assert np.ptp(players.battery) > 0, "each player's battery sags under its own load"
        per_scene = scene.sim.batch.expanded("actuator_gainprm")
        ids = players.sim._actuators[:, players.motors.ids]  # (players, motors): the scene's actuators
        written = per_scene[:, ids][..., SUPPLY_SLOTS].reshape(players.num_sims, len(players.motors.ids), -1)
        np.testing.assert_array_equal(written, players.motors.supply_gains(players.battery))


def test_matches_reset_in_any_order_give_each_player_its_own_noisy_view():
    """Every match reset at once, its rows listed in another order: each player still sees with its own noise
    stream, so the views are those of the ordered reset, then and after a step."""
    engines = [match.Matches(robot="roach", players_per_team=2, num_matches=2, batched=True, nthread=1,
                             max_cycles=10) for _ in range(2)]  # fmt: skip
    assert engines[0].task.ball_noise > 0
    for engine, order in zip(engines, ([0, 1], [1, 0]), strict=True):
        for m in range(2):
            engine.seed(m, 20 + m)
        engine.reset(np.array(order))
    np.testing.assert_array_equal(engines[0].obs, engines[1].obs)
    actions = np.random.default_rng(0).uniform(-1, 1, (8, engines[0].mode.size))
    for engine in engines:
        engine.step(actions)
    np.testing.assert_array_equal(engines[0].obs, engines[1].obs)


def test_a_throw_in_in_batched_matches_is_the_pettingzoo_matchs_bit_for_bit():
    """Two batched roach matches whose balls start beyond a touch line and a goal line: put back in the first step,
    each exactly as in a PettingZoo match of the same seed, the other match untouched by the placement."""
    engine = match.Matches(robot="roach", players_per_team=1, num_matches=2, batched=True, max_cycles=50)
    f = engine.field
    balls = (
        (0.3 * f.half_length, -(f.half_width + 1.5 * f.ball.radius)),
        (f.half_length + 2 * f.ball.radius, 0.6 * f.half_width),
    )
    singles = [match.parallel_env(robot="roach", players_per_team=1, max_cycles=50) for _ in range(2)]
    for m, ball in enumerate(balls):
        engine.seed(m, 7 + m)
        engine.reset(np.array([m]), {"ball": ball})
        singles[m].reset(seed=7 + m, options={"ball": ball})
    rng = np.random.default_rng(1)
    for step in range(6):
        actions = rng.uniform(-1, 1, (4, 3))
        out = engine.step(actions)
        assert out["throw_in"].tolist() == [step == 0] * 2
        for m, env in enumerate(singles):
            o, r, *_, infos = env.step({a: actions[2 * m + i] for i, a in enumerate(env.possible_agents)})
            assert infos["home_0"]["throw_in"] == (step == 0)
            assert out["reward"][2 * m : 2 * m + 2].tolist() == [r[a] for a in env.possible_agents]
            np.testing.assert_array_equal(engine.obs[2 * m : 2 * m + 2], [o[a] for a in env.possible_agents])
            np.testing.assert_array_equal(
                engine.scene.scene_sensor("ball_pos")[m], env.scene.scene_sensor("ball_pos")[0]
            )


def test_a_scene_that_goes_unstable_ends_its_match_with_nothing_counted():
    """The ball sent off at an absurd speed: MuJoCo resets the scene's data, and the match is truncated for every
    player, with no reward and no goal; the next reset starts it again."""
    env = match.parallel_env(robot="roach", players_per_team=1)
    env.reset(seed=0)
    ball = env.engine.scene.objects["ball"][1]
    env.engine.scene.sim.data.qvel[ball : ball + 3] = 1e200
    _, rewards, terminations, truncations, infos = env.step({a: np.zeros(3) for a in env.agents})
    assert all(truncations.values()) and not any(terminations.values())
    assert all(info["sim_unstable"] for info in infos.values()) and set(rewards.values()) == {0.0}
    assert env.score == {"home": 0, "away": 0} and env.agents == []
    obs, _ = env.reset(seed=1)
    assert all(np.isfinite(o).all() for o in obs.values())


def test_the_xjus_wedge_that_blew_a_scene_up_holds_at_shorter_steps():
    """A control block recorded from random two-a-side xJüs play (seed 0, match 28 of 32, step 426), where a leg
    wedged between two robots throws a joint to 5,000 rad/s within the 2 ms steps: run again from its start at the
    match's shorter steps, it holds, and a match's scene runs such blocks again by itself. The file holds the
    block's start (``Batch.state`` row, mjSTATE_INTEGRATION) and controls, taken in ``soccer_stability.random_play``'s
    play with the scene's ``refine`` set to 1; a change to the xJüs's scene means taking them again."""
    from envs.common.simulation import diverged, refined_block, run_at_shorter_steps

    recorded = np.load(Path(__file__).parent / "data" / "xjus_wedge_block.npz")
    env = match.parallel_env(robot="xjus", players_per_team=2)
    model = env.engine.scene.model
    assert (model.nq, model.nv, model.nu) == (recorded["nq"], recorded["nv"], recorded["nu"]), "the scene changed"
    assert env.engine.scene.sim.refine == match.REFINE_UNSTABLE > 1
    start = mujoco.MjData(model)
    mujoco.mj_setState(model, start, recorded["state"], mujoco.mjtState.mjSTATE_INTEGRATION)
    assert not diverged(start.qvel)
    assert run_at_shorter_steps(model, start, recorded["ctrl"], 1) is None, "at the model's own step it diverges"
    held = refined_block(model, start, recorded["ctrl"], match.REFINE_UNSTABLE)
    assert held is not None
    end = mujoco.MjData(model)
    mujoco.mj_setState(model, end, held[0], mujoco.mjtState.mjSTATE_INTEGRATION)
    assert np.abs(end.qvel).max() < 200 and end.time == pytest.approx(start.time + len(recorded["ctrl"]) * 0.002)
    env.reset(seed=0)
    _, _, _, _, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    assert all(info["sim_refined"] is False and info["sim_unstable"] is False for info in infos.values())


def test_the_soccer_benchmark_measures_each_robot_against_its_raw_physics():
    """benchmarks/soccer_dm_control.py's side of the comparison, tiny: each robot's one match and its batched matches,
    whose rounds repeat the same control blocks bit for bit, whose raw replay runs the matches' very physics (the same
    sensor values after every block), and whose physics steps make up the robot's control step."""
    from benchmarks.soccer_dm_control import our_rows

    rows = our_rows(steps=2, seed=0, rounds=2, matches=2)
    assert [r["robot"] for r in rows] == ["roach", "xjus", "bioloid"]
    for r in rows:
        many = r["batched"]
        assert many["rounds_repeat"] and many["replay_tracks"] and many["matches"] == 2 and many["players"] == 4
        assert many["agent_steps_per_second"] > 0 and many["raw_share"] > 0 and r["single"]["reset_ms"] > 0
        dt = match.parallel_env(robot=r["robot"], players_per_team=1).dt
        assert many["substeps"] * many["physics_timestep"] == pytest.approx(dt)


def test_the_stability_benchmark_counts_each_unstable_scene_once_and_gives_its_rate_an_exact_interval(monkeypatch):
    """benchmarks/soccer_stability.py, tiny: a scene made to go unstable is counted at its step, its match starts
    again, and the rate's interval is the exact Poisson one."""
    from benchmarks import soccer_stability
    from envs.soccer.match import Matches

    step = Matches.step

    def blow_up_match_one_at_step_three(self, actions):
        if self.cycles.max() == 2:  # the third step: match 1's scene is given a velocity no solver survives
            self.scene.sim.qvel[1] = 1e12
        return step(self, actions)

    monkeypatch.setattr(Matches, "step", blow_up_match_one_at_step_three)
    run = soccer_stability.random_play("xjus", matches=2, steps=5, seed=0)
    assert run["unstable"] == [{"match": 1, "step": 2}], "once, at its step: the match is started again after it"
    assert run["match_seconds"] == pytest.approx(2 * 5 * run["dt"])
    rate, low, high = soccer_stability.rate_per_hour(0, 3600.0)
    assert (rate, low, high) == (0.0, 0.0, pytest.approx(3.689, abs=1e-3))  # Garwood's upper bound for none seen
    rate, low, high = soccer_stability.rate_per_hour(14, 7200.0)
    assert rate == 7.0 and (low, high) == (pytest.approx(7.654 / 2, abs=1e-3), pytest.approx(23.49 / 2, abs=1e-2))
