"""Soccer: robots sharing a scene, the fields and balls, and the academy tasks."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from envs.bioloid.robot import Bioloid
from envs.common.match import SharedScene
from envs.soccer import ACADEMY, FIELDS, academy
from envs.soccer.field import BALL, FOUR_LEGGED, field_edit, measure_bounce, measure_deceleration
from envs.velociroach.robot import VelociRoach
from envs.xjus.robot import Xjus

ROBOTS = {"Roach": VelociRoach, "Xjus": Xjus, "Bioloid": Bioloid}


def run(robot, actions: np.ndarray, seed: int = 1) -> np.ndarray:
    rngs = [np.random.default_rng(seed + i) for i in range(robot.num_sims)]
    robot.reset(np.arange(robot.num_sims), rngs, 0.1, None)
    for action in actions:
        robot.command(robot.mode.to_command(np.broadcast_to(action, (robot.num_sims, robot.mode.size))))
        robot.step()
        robot.read(rngs)
    return robot.sim.substep_sensordata.copy()


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_a_robot_alone_on_a_shared_scene_is_the_robot_bit_for_bit(name):
    """The scene's view gives the robot its own rows: its firmware, senses and physics run unchanged."""
    robot_class = ROBOTS[name]
    alone = robot_class()
    actions = np.random.default_rng(0).uniform(-1, 1, (25, alone.mode.size))
    scene = SharedScene(robot_class, ["p"])
    np.testing.assert_array_equal(run(alone, actions), run(scene.robot, actions))


def test_players_are_placed_and_the_scene_batches_bit_for_bit():
    """Two players, the second placed turned by 90 degrees, run as a turned copy of the first; two scenes on a batch
    give the same numbers as one scene each."""
    actions = np.random.default_rng(1).uniform(-1, 1, (20, 16))
    scenes = []
    for num_scenes, batched in ((2, True), (1, False)):
        scene = SharedScene(Bioloid, ["a", "b"], num_scenes=num_scenes, batched=batched)
        scene.placement[:] = np.tile([[0.0, 0.0, 0.0], [3.0, 1.0, math.pi / 2]], (num_scenes, 1))
        rngs = [np.random.default_rng(7) for _ in range(scene.num_sims)]
        scene.robot.reset(np.arange(scene.num_sims), rngs, 0.0, None)
        for action in actions:
            scene.robot.command(scene.robot.mode.to_command(np.broadcast_to(action, (scene.num_sims, 16))))
            scene.robot.step()
        scenes.append(scene.robot.read(rngs))
    batched, single = scenes
    np.testing.assert_array_equal(batched["position"][:2], single["position"])
    np.testing.assert_array_equal(batched["position"][:2], batched["position"][2:])
    a, b = single["position"]
    np.testing.assert_allclose(b, [3.0 - a[1], 1.0 + a[0], a[2]], atol=1e-9)


def test_a_player_reset_alone_leaves_the_others_and_the_ball():
    scene = SharedScene(Bioloid, ["a", "b"], [field_edit(FOUR_LEGGED, ["a", "b"], "BODY")])
    scene.placement[:] = [[-1.0, 0.0, 0.0], [1.0, 0.0, math.pi]]
    scene.place_object(np.array([0]), BALL, np.array([[0.0, 0.5, 0.2]]), np.array([[0.3, 0.0, 0.0]]))
    robot = scene.robot
    rngs = [np.random.default_rng(i) for i in range(2)]
    robot.reset(np.arange(2), rngs, 0.1, None)
    for _ in range(10):
        robot.command(np.tile(robot.ready_counts, (2, 1)))
        robot.step()
    data = scene.sim.data
    before = data.qpos.copy()
    scene.placement[1] = [2.0, -1.0, 0.0]
    robot.reset(np.array([1]), rngs[1:], 0.0, None)
    nq = robot.model.nq  # each player's block
    np.testing.assert_array_equal(data.qpos[:nq], before[:nq])  # the other player
    np.testing.assert_array_equal(data.qpos[2 * nq :], before[2 * nq :])  # the ball
    np.testing.assert_allclose(robot.read(rngs, False)["position"][1, :2], [2.0, -1.0])


@pytest.mark.parametrize("name", sorted(FIELDS))
def test_each_ball_bounces_and_rolls_as_its_numbers_say(name):
    """In the robot's own scene and physics options: the restitution (table-tennis rules' drop test) within 0.05
    and the rolling deceleration within 10% of C_rr g / (1 + I / (m r^2))."""
    field = FIELDS[name]
    scene = SharedScene(ROBOTS[name], ["p"], [field_edit(field, ["p"], ROBOTS[name].root_body)])
    ball = field.ball
    at = (-0.25 * field.length, 0.25 * field.width)  # clear of the player at the centre spot
    bounces = [measure_bounce(scene.model, k * ball.radius, BALL, at) for k in (5, 10, 20)]
    assert abs(np.mean(bounces) - ball.restitution) < 0.05, bounces
    rate = measure_deceleration(scene.model, 2.0 * ball.deceleration(), 0.5, BALL, at)
    assert rate == pytest.approx(ball.deceleration(), rel=0.1)


def test_the_fields_scale_with_the_robots():
    bioloid, xjus, roach = FIELDS["Bioloid"], FIELDS["Xjus"], FIELDS["Roach"]
    assert (bioloid.length, bioloid.width, bioloid.goal_width) == (5.4, 3.6, 0.8)
    assert xjus.length == pytest.approx(5.4 * 0.53 / 0.30) and roach.goal_width == pytest.approx(0.8 / 3)
    assert roach.ball.radius == 0.020 and roach.ball.mass == 0.0027


def make(env_id: str, **kwargs):
    (entry,) = [e for e in ACADEMY if e["id"] == env_id]
    name = entry["entry_point"].split(":")[1]
    return getattr(academy, name)(**kwargs)


def test_a_goal_is_seen_between_control_steps_and_ends_the_episode():
    """The ball rolled fast at the goal: a goal at the physics rate, +1, success and no fall; the other way an own
    goal, -1."""
    env = make("skitter/RoachScoreEmptyGoal-v4")
    field = FIELDS["Roach"]
    hl = field.half_length
    for side, key, reward in ((1, "scored", 1.0), (-1, "conceded", -1.0)):
        env.reset(seed=0, options={"robot": [0.0, 0.3, 0.0], "ball": [side * (hl - 0.05), 0.0]})
        env.unwrapped.scene.sim.data.qvel[env.unwrapped.scene.objects[BALL][1]] = side * 3.0
        ended = None
        for _ in range(20):
            *_, terminated, _, info = env.step(np.zeros(env.action_space.shape))
            if terminated:
                ended = info
                break
        assert ended is not None and ended[key] == 1.0 and ended["reward_goal"] == reward
        assert ended["fallen"] is False and ended["success"] == (1.0 if side > 0 else 0.0)


@pytest.mark.parametrize(
    ("options", "word"),
    [({"ball": [99.0, 0.0]}, "ball"), ({"robot": [0.0, 0.0]}, "robot"), ({"robot": "here"}, "robot")],
)
def test_bad_places_are_refused_by_name(options, word):
    env = make("skitter/BioloidGoToBall-v4")
    with pytest.raises(ValueError, match=f"options\\['{word}'\\]"):
        env.reset(seed=0, options=options)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_go_to_ball_starts_the_robot_2_to_8_body_lengths_from_the_ball_inside_the_lines(name):
    """Both places are drawn again until they hold, not moved inside the lines: moving the robot's put 8.5% of the
    starts within a body length of the ball, some touching it before the first step."""
    (env_id,) = [e["id"] for e in ACADEMY if e["id"].startswith(f"skitter/{name}GoToBall-")]
    env = make(env_id)
    task, length = env.unwrapped.task, env.unwrapped.robot.facts.length
    inner = np.array([task.field.half_length, task.field.half_width]) - 2.0 * length
    rng = np.random.default_rng(0)
    distances = []
    for _ in range(2000):
        robot, ball = task.draw_places(rng, length)
        distances.append(np.hypot(*(robot[:2] - ball)) / length)
        assert (np.abs(robot[:2]) <= inner).all() and (np.abs(ball) <= inner).all()
    assert 2.0 <= min(distances) and max(distances) <= 8.0
    for seed in range(1000, 1020):  # the evaluation seeds: the old placement put the xJüs on its ball at 1004
        env.reset(seed=seed)
        *_, terminated, _, info = env.step(np.zeros(env.action_space.shape))
        assert not terminated and info["ball_distance"] > 1.5, (seed, info["ball_distance"])


def test_robots_on_a_shared_scene_refuse_per_robot_parameters():
    scene = SharedScene(Bioloid, ["a"])
    with pytest.raises(ValueError, match="shared scene"):
        scene.robot.set_parameters(np.array([0]), {"foot_friction": 0.5})
    assert mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_BODY, "a/BODY") >= 0
    assert {e["id"] for e in ACADEMY} <= gym.registry.keys(), "the academy is registered"


def test_players_collide_with_each_other_but_not_with_themselves():
    """Each player has a contact bit of its own: two Bioloids set down overlapping push each other apart, and no
    contact is ever between two parts of one robot (as alone)."""
    scene = SharedScene(Bioloid, ["a", "b"])
    scene.placement[:] = [[0.0, 0.0, 0.0], [0.12, 0.0, np.pi]]
    robot = scene.robot
    rngs = [np.random.default_rng(i) for i in range(2)]
    robot.reset(np.arange(2), rngs, 0.0, None)
    model, data = scene.model, scene.sim.data
    owner = np.array([model.body(model.geom_bodyid[g]).name.split("/")[0] for g in range(model.ngeom)])
    between = 0
    for _ in range(5):
        robot.command(np.tile(robot.ready_counts, (2, 1)))
        robot.step()
        pairs = data.contact.geom[: data.ncon]
        mine = owner[pairs]
        assert not any(a == b and a in ("a", "b") for a, b in mine), "a robot touched itself"
        between += sum({a, b} == {"a", "b"} for a, b in mine)
    assert between > 0


@pytest.mark.parametrize(
    "env_id",
    ["skitter/BioloidGoToBall-v4", "skitter/RoachScoreEmptyGoal-v4", "skitter/XjusScoreVsKeeper-v1",
     "skitter/BioloidScoreVsKeeper-v2"],
)  # fmt: skip
def test_the_academy_in_the_commands_mode_is_batched_like_single_across_resets(env_id):
    """Speed and turn rate through the gait map (and the Bioloid's kick): the same results single and batched, the
    Bioloid's trot clock and kicks restarting with each episode (the keeper's and the learner's, each on its own
    rows)."""
    kicks = "Bioloid" in env_id  # speed, turn rate and the Bioloid's kick
    kwargs = {"action_mode": "commands", "max_episode_steps": 12, **({"kick": True} if kicks else {})}
    singles = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", **kwargs)
    batched = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
    size = 3 if kicks else 2
    assert singles.single_action_space.shape == batched.single_action_space.shape == (size,)
    actions = np.random.default_rng(3).uniform(-1, 1, (30, 2, size))
    outs = []
    for venv in (singles, batched):
        obs, _ = venv.reset(seed=9)
        steps = [obs]
        for a in actions:
            obs, reward, terminated, truncated, _ = venv.step(a)
            steps += [obs, reward, terminated, truncated]
        outs.append(steps)
    for a, b in zip(*outs, strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_bioloids_field_of_view_follows_its_neck():
    """A 60 deg field of view on the Bioloid's head: the ball straight ahead is seen with the head forward and lost
    with the head panned 0.8 rad either way by the neck's roll servo (N_2, about the raised neck)."""
    from envs.bioloid import constants as bc

    env = gym.make("skitter/BioloidGoToBall-v4", field_of_view=np.radians(60), reset_noise_scale=0.0)
    layout = env.unwrapped.task.layout
    stand = bc.CENTER + np.array([bc.STAND_ANGLES[s] for s in bc.SERVOS]) / bc.RAD_PER_COUNT
    for pan, seen in ((0.0, 1.0), (0.8, 0.0), (-0.8, 0.0)):
        counts = stand.copy()
        counts[bc.SERVO_INDEX["N_2"]] += pan / bc.RAD_PER_COUNT
        action = env.unwrapped.robot.mode.to_action(counts[None])[0]
        obs, _ = env.reset(seed=0, options={"robot": [0.0, 0.0, 0.0], "ball": [0.5, 0.0]})
        assert layout.get(obs[None], "ball_visible")[0, 0] == 1.0, "at reset the head looks ahead"
        for _ in range(40):
            obs, *_ = env.step(action)
        assert layout.get(obs[None], "ball_visible")[0, 0] == seen, pan


def keeper_pose(env) -> np.ndarray:
    """The scripted keeper's (x, y, up_z) in a single ScoreVsKeeper env."""
    base = env.unwrapped
    data = base.data
    body = data.body(f"{academy.KEEPER}/{base.robot.root_body}")
    return np.array([*body.xpos[:2], body.xmat[8]])


@pytest.mark.parametrize("robot", ["Roach", "Xjus", "Bioloid"])
def test_the_keeper_stands_between_the_ball_and_its_goal(robot):
    """Placed off its line at a post, the scripted keeper walks to its place between the ball and its goal's centre
    (``KEEP`` body lengths out) while the learner stands still; the learner sees it as an opponent."""
    env = gym.make(f"skitter/{robot}ScoreVsKeeper-v{academy.version(robot, academy.ScoreVsKeeperTask)}",
                   action_mode="commands")  # fmt: skip
    base = env.unwrapped
    field, length = base.field, base.robot.facts.length
    ball = np.array([field.half_length - 5.0 * length, 0.4 * field.goal_width])
    post = [field.half_length - 0.5 * length, -0.5 * field.goal_width, math.pi]
    obs, _ = env.reset(seed=0, options={"ball": ball, "keeper": post, "robot": [0.0, 0.0, 0.0]})
    start = keeper_pose(env)
    goal = np.array([field.half_length, 0.0])
    wanted = goal + (ball - goal) / np.linalg.norm(ball - goal) * academy.KEEP * length
    assert np.linalg.norm(start[:2] - wanted) > 1.0 * length
    still = np.zeros(env.action_space.shape)  # no speed, no turn (and no kick)
    still[0] = -1.0
    # long enough for each to walk there and stand still for the last 3 s (the Bioloid walks at 5 cm/s)
    seconds = {"Roach": 12.0, "Xjus": 9.0, "Bioloid": 19.0}[robot]
    steps, last = round(seconds / base.dt), round(3.0 / base.dt)
    off = []
    for step in range(steps):
        obs, _, terminated, truncated, _ = env.step(still)
        assert not (terminated or truncated)
        if step >= steps - last:
            off.append(np.linalg.norm(keeper_pose(env)[:2] - wanted) / length)
    end = keeper_pose(env)
    # within a body length of its place over the last 3 s (the Bioloid walks there at 5 cm/s; the xJus's turns on
    # the spot shift it a little)
    assert np.mean(off) < 0.9, (robot, off, wanted)
    assert end[2] > 0.8, "the keeper stays upright"
    seen = base.task.layout.get(obs[None], "opponents")[0]
    assert np.linalg.norm(seen) == pytest.approx(np.linalg.norm(end[:2] - base.data.body(
        f"home_0/{base.robot.root_body}").xpos[:2]), rel=0.3)  # fmt: skip


@pytest.mark.parametrize("on_a_spot", [False, True])
def test_a_fallen_keeper_is_put_back_beside_its_goal_and_the_episode_goes_on(on_a_spot):
    """Flipped over, the keeper stands again beside its goal in the next step, away from the learner even when the
    learner stands on one of its places; the learner's episode goes on and ``info`` counts the put-back."""
    env = gym.make("skitter/XjusScoreVsKeeper-v1")
    base = env.unwrapped
    field, length = base.field, base.robot.facts.length
    spot = [field.half_length - 0.5 * length, 0.5 * field.goal_width + length, math.pi]
    env.reset(seed=1, options={"robot": spot, "ball": [field.half_length - 4 * length, 0.3]} if on_a_spot else None)
    action = np.zeros(env.action_space.shape, dtype=np.float32)
    env.step(action)
    qadr = base.model.jnt_qposadr[base.model.body(f"{academy.KEEPER}/{base.robot.root_body}").jntadr[0]]
    base.data.qpos[qadr + 2] += 0.3  # lifted and turned upside down
    base.data.qpos[qadr + 3 : qadr + 7] = [0.0, 1.0, 0.0, 0.0]
    ended = False
    put_back = None
    for _ in range(round(2.0 / base.dt)):
        _, _, terminated, truncated, _ = env.step(action)
        ended |= terminated or truncated
        pose = keeper_pose(env)
        if pose[2] > 0.9 and abs(pose[0] - (base.field.half_length - 0.5 * base.robot.facts.length)) < 0.05:
            put_back = pose
            break
    assert not ended, "the learner's episode goes on"
    assert put_back is not None, "the keeper stands again beside its goal"
    assert abs(put_back[1]) >= 0.5 * base.field.goal_width
    learner = base.data.body(f"home_0/{base.robot.root_body}").xpos[:2]
    assert np.linalg.norm(put_back[:2] - learner) > 1.5 * length
    _, _, _, _, info = env.step(action)
    assert info["keeper_put_back"] == 1.0 and info["keeper_x"] == pytest.approx(put_back[0], abs=0.05)


def test_a_scripted_keeper_takes_only_the_gaits_mode_or_commands():
    with pytest.raises(ValueError, match="action_mode must be 'gait' or 'commands'"):
        gym.make("skitter/RoachScoreVsKeeper-v3", action_mode="duty")
    env = gym.make("skitter/RoachScoreVsKeeper-v3")
    for bad in ([0.0, 0.0], {"x": 1.0}, [1.0, "a", 0.0]):
        with pytest.raises(ValueError, match=r"options\['keeper'\]"):
            env.reset(seed=0, options={"keeper": bad})
    with pytest.raises(ValueError, match="a body length"):
        env.reset(seed=0, options={"robot": [0.0, 0.0, 0.0], "keeper": [0.05, 0.0, 0.0]})
    with pytest.raises(ValueError, match="options must be a dict"):
        env.reset(seed=0, options=[1, 2])
