"""The commands mode (speed and turn rate through each robot's gait map) and the scripted team."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks.gait_maps import run_on_flat_ground
from envs.bioloid.kick import LEFT, RIGHT, Kick
from envs.common.task import ObservationLayout
from envs.soccer import match
from envs.soccer.robots import ROBOTS
from envs.soccer.scripted import AIM_DEPTH, MEMORY, ScriptedPlayer, ScriptedTeam, scripted_team
from envs.soccer.steering import KICK_THRESHOLD, MAPS, STEERING, BioloidSteering, Commands, GaitMap

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("robot", sorted(STEERING))
def test_every_gait_map_is_the_benchmarks_and_covers_its_grid(robot):
    """envs/soccer/gait_maps/ as ``python -m benchmarks.gait_maps`` wrote it, every grid point measured."""
    data = json.loads((MAPS / f"{robot}.json").read_text())
    steering = STEERING[robot]
    assert data["generated_by"] == "python -m benchmarks.gait_maps"
    grid = {(round(p["drive"], 9), round(p["turn"], 9)) for p in data["points"]}
    assert grid == {(round(d, 9), round(t, 9)) for d in steering.drives for t in steering.turns}
    result = json.loads((ROOT / "benchmarks/results/gait_maps.json").read_text())
    assert any(m["points"] == data["points"] for m in result["maps"].values())


@pytest.mark.parametrize("robot", sorted(STEERING))
def test_a_measured_speed_and_turn_rate_go_back_to_their_own_setting(robot):
    """The inverse is the nearest measured point: asked for exactly what a setting gave, it returns that setting
    (where no other setting gave the same)."""
    gait = GaitMap.read(robot)
    drive, turn = gait.controls(gait.speed, gait.yaw_rate)
    unique = np.array([np.count_nonzero((gait.speed == s) & (gait.yaw_rate == w)) == 1
                       for s, w in zip(gait.speed, gait.yaw_rate, strict=True)])  # fmt: skip
    np.testing.assert_array_equal(drive[unique], gait.drive[unique])
    np.testing.assert_array_equal(turn[unique], gait.turn[unique])
    assert gait.max_speed == gait.speed.max() and gait.max_yaw_rate == np.abs(gait.yaw_rate).max()


def test_the_xjus_walks_at_the_commanded_speed_in_the_commands_mode():
    """Half its fastest straight run, for 4 s from a standstill: within 15%, its heading within 10 deg."""
    env = match.parallel_env(robot="xjus", players_per_team=1, action_mode="commands", reset_noise_scale=0.0)
    speed = 0.5 * env.commands.map.max_speed
    env.reset(seed=0, options={"places": {"home_0": [-3.8, 1.6, 0.0]}})
    action = env.mode.to_action(np.array([[speed, 0.0]]))[0]
    data = env.scene.sim.data
    start, steps = data.qpos[:2].copy(), round(4.0 / env.dt)
    for _ in range(steps):
        env.step({"home_0": action, "away_0": np.array([-1.0, 0.0])})
    moved = (data.qpos[:2] - start) / (steps * env.dt)
    assert moved[0] == pytest.approx(speed, rel=0.15) and abs(moved[1]) < 0.2 * speed
    w, z = data.qpos[3], data.qpos[6]
    assert abs(np.degrees(2 * np.arctan2(z, w))) < 10


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_roach_turns_the_way_it_is_commanded(sign):
    """Differential drive: asked for 1.5 rad/s either way at 0.8 m/s, it turns that way at least at half that rate
    on open ground, over the 2 s after the gait map's first second (its warm-up: from a standstill the settings this
    asks for hold the heading for up to 0.75 s, which on the roach's field runs it into the ball or a wall)."""
    assert sign * turn_rate_on_flat_ground("Roach", 0.8, sign * 1.5, 3.0) > 0.5 * 1.5


def turn_rate_on_flat_ground(robot_key: str, speed: float, yaw_rate: float, seconds: float) -> float:
    """The turn rate (rad/s) of a robot commanded ``(speed, yaw_rate)`` through its commands mode, on flat ground
    from its reset pose as ``benchmarks.gait_maps`` measures: averaged over ``seconds`` after its first second."""
    robot = ROBOTS[robot_key](num_sims=1, batched=True)
    commands = Commands(robot)
    rngs = [np.random.default_rng(0)]
    robot.reset(np.arange(1), rngs, 0.0, None)
    commands.reset(np.arange(1))
    action = commands.mode.to_action(np.array([[speed, yaw_rate]]))
    _, turned, _, span = run_on_flat_ground(robot, rngs, lambda: commands.robot_commands(action), seconds)
    return float(turned[0] / span)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_roach_spins_on_the_spot_its_sides_running_opposite_ways(sign):
    """Asked to turn 3 rad/s either way without walking: one side's clock runs backward, and in 1 s it turns that way
    by at least half the commanded angle."""
    env = match.parallel_env(robot="roach", players_per_team=1, action_mode="commands")
    env.reset(seed=0)
    left, right, _ = env.commands.robot_commands(env.mode.to_action(np.array([[0.0, sign * 3.0]])))[0]
    assert sign * right > 0 > sign * left, "the sides run opposite ways"
    assert sign * turned_by("roach", 0.0, sign * 3.0, 1.0) > 0.5 * 3.0 * 1.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_bioloid_turns_the_way_it_is_commanded(sign):
    """The trot steered by sideways steps: asked for 0.4 rad/s either way while walking, for 8 s from a standstill
    (the gait's first cycle is its lead-in), it turns that way by at least half the commanded angle."""
    assert sign * turned_by("bioloid", 0.04, sign * 0.4, 8.0) > 0.5 * 0.4 * 8.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_xjus_turns_on_the_spot_the_way_it_is_commanded(sign):
    """One side's legs backward: asked for 1 rad/s either way at 0.1 m/s, for 3 s from a standstill, it turns that way
    by at least half the commanded angle, and its legs run forward again once it walks straight."""
    assert sign * turned_by("xjus", 0.1, sign * 1.0, 3.0) > 0.5 * 1.0 * 3.0
    env = match.parallel_env(robot="xjus", players_per_team=1, action_mode="commands")
    env.reset(seed=0)
    env.step({"home_0": env.mode.to_action(np.array([[0.1, sign]]))[0], "away_0": np.array([1.0, 0.0])})
    assert env.robot.backward[0].tolist() == [sign > 0, sign < 0] and not env.robot.backward[1].any()
    env.step({"home_0": np.array([1.0, 0.0]), "away_0": np.array([1.0, 0.0])})
    assert not env.robot.backward.any()


def turned_by(robot: str, speed: float, yaw_rate: float, seconds: float) -> float:
    """How far (rad) a player commanded ``(speed, yaw_rate)`` turns in ``seconds``, from the home half's centre."""
    env = match.parallel_env(robot=robot, players_per_team=1, action_mode="commands", reset_noise_scale=0.0)
    env.reset(seed=0, options={"places": {"home_0": [-0.25 * env.field.length, 0.0, 0.0]}})
    extra = [0.0] * (env.mode.size - 2)  # no kick, for a robot that kicks
    action = env.mode.to_action(np.array([[speed, yaw_rate, *extra]]))[0]
    data = env.scene.sim.data
    steps = round(seconds / env.dt)
    turned = 0.0
    for _ in range(steps):
        before = 2 * np.arctan2(data.qpos[6], data.qpos[3])
        env.step({"home_0": action, "away_0": np.array([-1.0, 0.0, *extra])})
        turned += np.angle(np.exp(1j * (2 * np.arctan2(data.qpos[6], data.qpos[3]) - before)))
    return turned


def test_the_bioloids_commands_run_the_ik_trot_from_its_own_clock():
    env = match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands")
    env.reset(seed=0)
    commands: Commands = env.commands
    first = commands.robot_commands(np.zeros((2, 2)))
    second = commands.robot_commands(np.zeros((2, 2)))
    assert first.shape == (2, 16) and not np.array_equal(first, second), "the trot's clock runs"
    commands.reset(np.array([0, 1]))
    np.testing.assert_array_equal(commands.robot_commands(np.zeros((2, 2))), first)


def test_a_bioloids_kick_runs_to_its_end_whatever_is_commanded_then_the_trot_starts_afresh():
    """The third command kicks: from the goals the trot left the legs at, the kick's own goals (the left leg's for
    a kick above the threshold, the right's below minus it), commands ignored until it ends; then the trot's clock
    starts again at 0. Another player's commands are its own all along. The kick is asked for: off by default, and
    only the Bioloid kicks."""
    assert match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands").mode.size == 2
    for robot, kwargs, message in (("roach", {"action_mode": "commands"}, "has no kick"),
                                   ("bioloid", {}, "give action_mode='commands'")):  # fmt: skip
        with pytest.raises(ValueError, match=message):
            match.parallel_env(robot=robot, players_per_team=1, kick=True, **kwargs)
    env = match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands", kick=True)
    env.reset(seed=0)
    commands: Commands = env.commands
    steering = commands.steering
    assert env.mode.commands == ("speed", "yaw_rate", "kick") and commands.kick_zone is not None
    walk = np.array([[0.5, 0.0, 0.0], [0.5, 0.0, 0.0]])
    for _ in range(10):
        commands.robot_commands(walk)
    trotting = steering.last.copy()
    kick = Kick()
    first = commands.robot_commands(np.array([[0.5, 0.0, -KICK_THRESHOLD], [0.5, 0.0, KICK_THRESHOLD - 0.01]]))
    np.testing.assert_allclose(first[0], trotting[0], atol=1e-9)  # the kick starts where the trot left the legs
    assert steering.kicking().tolist() == [True, False] and steering.kick_side[0] == RIGHT
    steps = math.ceil(kick.duration / env.dt - 1e-9)  # the control steps a kick takes
    for k in range(1, steps):
        goals = commands.robot_commands(np.array([[1.0, 1.0, 1.0], [0.5, 0.0, 0.0]]))  # ignored by the kicker
        if k * env.dt >= kick.shape.lean_time:  # blended into the kick's own goals by then
            np.testing.assert_allclose(goals[0], kick.counts(np.array([k * env.dt]), np.array([RIGHT]))[0])
    assert not steering.kicking()[0] and steering.clock[0] == 0.0 and steering.clock[1] > 1.0
    after = commands.robot_commands(np.array([[0.5, 0.0, 0.0], [0.5, 0.0, 0.0]]))
    np.testing.assert_allclose(after[0], kick.ready, atol=1.0)  # the trot's lead-in: from the ready posture


LAYOUT = ObservationLayout.from_structure({"ball": 2, "goal": 2, "own_goal": 2})


def test_a_scripted_kicker_kicks_with_the_foot_the_ball_lies_before_when_the_goal_is_ahead():
    env = match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands", kick=True)
    zone = env.commands.kick_zone
    player = ScriptedPlayer(LAYOUT, env.mode, 0.3, env.field, kick=zone)
    ahead = np.mean(zone.ahead)
    obs = np.array([[ahead, -zone.side, 2.0, 0.0, -2.0, 0.0],  # before the right foot, the goal ahead
                    [ahead, zone.side, 2.0, 0.5, -2.0, 0.0],  # before the left foot
                    [ahead, -zone.side, -2.0, 0.0, 2.0, 0.0],  # the goal behind: no kick toward its own
                    [zone.ahead[1] + 0.05, -zone.side, 2.0, 0.0, -2.0, 0.0],  # too far
                    [ahead, 0.0, 2.0, 0.0, -2.0, 0.0]])  # between the feet  # fmt: skip
    assert player.kicks(obs).tolist() == [RIGHT, LEFT, 0.0, 0.0, 0.0]
    action, _ = player.predict(obs)
    assert action.shape == (5, 3) and action[0, 2] <= -KICK_THRESHOLD and action[1, 2] >= KICK_THRESHOLD
    assert np.all(np.abs(action[2:, 2]) < KICK_THRESHOLD)
    assert np.all(ScriptedPlayer(LAYOUT, env.mode, 0.3, env.field, keeper=True, kick=zone).kicks(obs) == 0.0)
    with pytest.raises(ValueError, match="needs the robot's kick zone"):
        ScriptedPlayer(LAYOUT, env.mode, 0.3, env.field)
    plain = match.parallel_env(robot="bioloid", players_per_team=1, action_mode="commands")
    pusher = ScriptedPlayer(LAYOUT, plain.mode, 0.3, plain.field, kick=zone)  # pushes with its foot, never kicks
    assert pusher.predict(obs)[0].shape == (5, 2)


def player(keeper: bool = False) -> ScriptedPlayer:
    env = match.parallel_env(robot="roach", players_per_team=1, action_mode="commands")
    return ScriptedPlayer(LAYOUT, env.mode, 0.1, env.field, keeper)


def obs(ball, goal=(0.9, 0.0), own=(-0.9, 0.0)) -> np.ndarray:
    """A player on the roach's 1.8 m field (at the centre spot, facing the goal it attacks, by default)."""
    return np.array([[*ball, *goal, *own]], dtype=np.float64)


def test_a_scripted_player_behind_the_ball_pushes_it_toward_the_goal():
    target, pushing = player().targets(obs((0.3, 0.0)))
    assert pushing[0] and target[0, 0] > 0.3 and abs(target[0, 1]) < 1e-9
    action, _ = player().predict(obs((0.3, 0.0))[0])
    assert action[0] > -1.0 and abs(action[1]) < 1e-6, "straight at it"


def test_a_scripted_player_pushes_at_its_gaits_share_of_its_cruise():
    lined_up = obs((0.3, 0.0))
    default = player().predict(lined_up)[0]
    env = match.parallel_env(robot="roach", players_per_team=1, action_mode="commands")
    slow = ScriptedPlayer(LAYOUT, env.mode, 0.1, env.field, push=0.25).predict(lined_up)[0]
    speed = env.mode.to_command(np.vstack([default, slow]))[:, 0]
    cruise = player().cruise
    np.testing.assert_allclose(speed, [0.5 * cruise, 0.25 * cruise])  # facing the ball straight ahead
    with pytest.raises(ValueError, match="push"):
        ScriptedPlayer(LAYOUT, env.mode, 0.1, env.field, push=0.0)
    # the scripted team takes its share from the robot's steering: the Bioloid's, the others the default
    for robot, share in (("bioloid", BioloidSteering.push_share), ("roach", 0.5)):
        team = scripted_team(match.parallel_env(robot=robot, players_per_team=1, action_mode="commands"), "home")
        assert [p.push for p in team.values()] == [share]


def test_a_scripted_player_aims_behind_the_goal_where_the_ball_goes_straight_in_else_at_its_line():
    """A ball just short of the goal line in front of the goal is aimed in, not along the line to its centre (where
    the scripted Bioloid pushed it back and forth for minutes); one wide of the goal near the line is brought round
    to the goal line's centre first."""
    p = player()
    goal, own = np.array([[0.9, 0.0]]), np.array([[-0.9, 0.0]])
    depth = AIM_DEPTH * p.goal_half_width * 2.0
    short = p.aim(np.array([[0.87, 0.06]]), goal, own)  # 3 cm short of the line, off the goal's centre
    np.testing.assert_allclose(short, [[0.9 + depth, 0.0]])
    wide = p.aim(np.array([[0.85, 0.5]]), goal, own)
    np.testing.assert_allclose(wide, goal)
    on_line = p.aim(np.array([[0.9, 0.0]]), goal, own)  # on the line, not yet wholly over it: pushed in
    np.testing.assert_allclose(on_line, [[0.9 + depth, 0.0]])
    # seen from a player turned half a turn (the goal behind it), the same ball gets the same aim in its frame
    turned = p.aim(-np.array([[0.87, 0.06]]), -goal, -own)
    np.testing.assert_allclose(turned, -short)


def test_a_scripted_player_in_front_of_the_ball_goes_round_it_on_its_own_side():
    """The ball behind the player and a little to its left, the goal ahead: its target is behind the ball, on the
    player's (right) side of the line from the ball to the goal."""
    target, pushing = player().targets(obs((-0.3, 0.05)))
    assert not pushing[0] and target[0, 0] < -0.3 and target[0, 1] < -0.03


def test_a_scripted_player_is_never_sent_beyond_a_wall():
    """The ball against the wall at +y, the player ahead of it on the wall's side: the way round is on the field's
    side, and every target lies inside the walls."""
    env = match.parallel_env(robot="roach", players_per_team=1, action_mode="commands")
    wall = 0.5 * env.field.width + env.field.side_border
    scripted = player()
    for ball_y in np.linspace(0.0, wall - 0.02, 7):
        for ball_x in (-0.5, 0.0, 0.4):
            target, _ = scripted.targets(obs((ball_x, ball_y)))
            assert abs(target[0, 1]) <= wall - 0.1 + 1e-9 and abs(target[0, 0]) < 0.9 + env.field.end_border
    target, pushing = scripted.targets(obs((-0.2, wall - 0.03), own=(-0.9, 0.0)))
    assert not pushing[0] and target[0, 1] < wall - 0.03, "round the ball on the field's side"


def test_a_scripted_player_that_cannot_move_escapes_toward_the_centre_spot():
    """Pressed into the wall beside its own goal (its view never changes): after stuck_seconds (2 s for the roach)
    of wanting to walk to the ball behind it, it turns to the centre spot and walks there for the escape's length,
    then plays on; without its memory it never escapes, and a new match (episode_start) clears the memory."""
    scripted = player()
    # at (-0.95, 0.15) facing -x (toward the end wall); the ball at (-0.6, 0.4): behind it and to its right
    seen = obs((-0.35, -0.25), goal=(-1.85, 0.15), own=(-0.05, 0.15))
    place, heading = scripted.pose(seen)
    np.testing.assert_allclose(place[0], [-0.95, 0.15], atol=1e-12)
    assert abs(abs(heading[0]) - np.pi) < 1e-12
    steps = round(scripted.stuck_seconds * scripted.mode.control_freq)
    memory, plays = None, []
    for _ in range(steps):
        action, memory = scripted.predict(seen[0], memory)
        plays.append(action)
    assert all(np.array_equal(a, plays[0]) for a in plays[:-1]), "plays on while it waits"
    centre = scripted.mode.to_action(np.column_stack(scripted.steer(0.5 * (seen[:, 2:4] + seen[:, 4:6]),
                                                                      np.zeros(1, bool))))[0]  # fmt: skip
    np.testing.assert_array_equal(plays[-1], centre)
    assert plays[-1][1] < plays[0][1] or np.sign(plays[-1][1]) != np.sign(plays[0][1]), "turns to the centre"
    escape = math.ceil(scripted.escape_seconds * scripted.mode.control_freq)
    for _ in range(escape - 1):
        action, memory = scripted.predict(seen[0], memory)
        np.testing.assert_array_equal(action, centre)
    action, memory = scripted.predict(seen[0], memory)
    np.testing.assert_array_equal(action, plays[0])
    assert all(np.array_equal(scripted.predict(seen[0])[0], plays[0]) for _ in range(steps + 2)), "no memory"
    stuck = memory
    for _ in range(steps - 1):
        _, stuck = scripted.predict(seen[0], stuck)
    action, _ = scripted.predict(seen[0], stuck, np.array([True]))
    np.testing.assert_array_equal(action, plays[0])


def test_a_scripted_player_that_moves_or_is_placed_starts_its_watch_again():
    """Moving a third of a body length, turning half a radian or being placed (a kickoff) resets the time it has
    waited; a wrongly shaped memory is refused."""
    scripted = player()
    steps = round(scripted.stuck_seconds * scripted.mode.control_freq)
    memory = None
    for step in range(3 * steps):
        x = 0.04 * (step // (steps // 2))  # 0.4 body lengths every half of the stuck time
        _, memory = scripted.predict(obs((0.3, 0.0), goal=(0.9 - x, 0.0), own=(-0.9 - x, 0.0))[0], memory)
        assert memory[MEMORY.index("escape")] == 0.0
    assert memory[MEMORY.index("waiting")] < scripted.stuck_seconds
    far = obs((0.3, 0.0), goal=(0.4, 0.0), own=(-1.4, 0.0))[0]  # half a metre on: placed
    _, placed = scripted.predict(far, memory)
    assert placed[MEMORY.index("waiting")] == pytest.approx(1.0 / scripted.mode.control_freq)
    assert placed[MEMORY.index("anchor_x")] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="state"):
        scripted.predict(far, np.zeros(3))


def test_the_scripted_keeper_stands_between_the_ball_and_its_goal():
    target, _ = player(keeper=True).targets(obs((0.2, 0.3), (0.9, 0.0), own=(-0.5, 0.0)))
    ball, own = np.array([0.2, 0.3]), np.array([-0.5, 0.0])
    along = (target[0] - own) / np.linalg.norm(target[0] - own)
    np.testing.assert_allclose(along, (ball - own) / np.linalg.norm(ball - own))
    assert np.linalg.norm(target[0] - own) == pytest.approx(0.15)


def test_the_scripted_team_plays_in_the_commands_mode_only():
    env = match.parallel_env(robot="bioloid", players_per_team=3, action_mode="commands")
    team = scripted_team(env, "away")
    assert [p.keeper for p in team.values()] == [False, False, True]
    with pytest.raises(ValueError, match="commands mode"):
        scripted_team(match.parallel_env(robot="bioloid", players_per_team=1), "home")


def test_a_scripted_team_acting_together_moves_each_player_as_its_own_predict_would():
    """ScriptedTeam calls each role once on its players' observations stacked (both teams' field players in one
    call, their keepers in another): every action and memory bit for bit those of the players' own calls."""
    env = match.parallel_env(robot="bioloid", players_per_team=3, action_mode="commands")
    obs, _ = env.reset(seed=4)
    team, agents = ScriptedTeam.of(env)
    assert agents == env.possible_agents and [len(c) for _, c in team.roles] == [4, 2]
    players = {**scripted_team(env, "home"), **scripted_team(env, "away")}
    memory, alone = None, dict.fromkeys(agents)
    for _ in range(40):
        actions, memory = team.act(np.stack([obs[a] for a in agents])[None], memory)
        for i, agent in enumerate(agents):
            action, alone[agent] = players[agent].predict(obs[agent], alone[agent])
            assert np.array_equal(action, actions[0, i]) and np.array_equal(alone[agent], memory[0, i])
        obs, *_ = env.step(dict(zip(agents, actions[0], strict=True)))
    with pytest.raises(ValueError, match="expected 6 players"):
        team.act(np.zeros((1, 5, env.task.layout.size)))
    with pytest.raises(ValueError, match="memory: expected"):
        team.act(np.stack([obs[a] for a in agents])[None], memory[:, :3])


def test_the_scripted_player_is_a_policy_by_name_on_academy_tasks_in_the_commands_mode_only():
    """``scripted`` (agents/soccer) plays an academy env made in the commands mode, single or batched, and is then
    that env's reference; elsewhere it is refused, saying where it plays."""
    import gymnasium as gym

    from agents import env_reference, load_policy

    single = gym.make("skitter/RoachGoToBall-v5", action_mode="commands")
    batched = gym.make_vec("skitter/XjusScoreVsKeeper-v1", num_envs=2, vectorization_mode="vector_entry_point",
                           action_mode="commands", nthread=1)  # fmt: skip
    for env, shape in ((single, (2,)), (batched, (2, 2))):
        obs, _ = env.reset(seed=0)
        action, state = load_policy("scripted", env).predict(obs)
        assert action.shape == shape and np.isfinite(action).all() and state.shape[-1] == len(MEMORY)
        assert env_reference(env) == "scripted"
    joints = gym.make("skitter/RoachGoToBall-v5")
    assert env_reference(joints) == "tripod"
    for env, message in ((joints, "commands mode"), (gym.make("skitter/RoachWalk-v4"), "academy")):
        with pytest.raises(ValueError, match=message):
            load_policy("scripted", env)
    with pytest.raises(ValueError, match="no argument"):
        load_policy("scripted:3", single)
