"""The ground rules of the walking and turning tasks: what each robot declares (its feet, its height band) against its
own model, scripted crawls that the rules end, and reference gaits that they never end."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import envs  # noqa: F401
from agents import load_policy, reference_policy
from envs.bioloid import constants as bioloid_constants
from envs.common.locomotion import GRACE_TIME
from envs.common.robot import GROUND_SENSOR
from envs.common.terrain import Terrain
from envs.velociroach import constants as roach_constants
from envs.xjus import constants as xjus_constants

RESULTS = Path(__file__).resolve().parents[1] / "benchmarks" / "results" / "ground_rules.json"
WALKS = {
    "skitter/RoachWalk-v4": roach_constants,
    "skitter/XjusWalk-v1": xjus_constants,
    "skitter/BioloidWalk-v2": bioloid_constants,
}


def lowest_point(model: mujoco.MjModel, data: mujoco.MjData, body: int) -> float:
    """The lowest world z of a body's colliding geoms (their bounding boxes)."""
    low = np.inf
    for g in np.flatnonzero(model.geom_bodyid == body):
        if model.geom_contype[g] or model.geom_conaffinity[g]:
            rot = data.geom_xmat[g].reshape(3, 3)
            centre, half = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
            low = min(low, data.geom_xpos[g, 2] + rot[2] @ centre - np.abs(rot[2]) @ half)
    return float(low)


@pytest.mark.parametrize("env_id", WALKS)
def test_standing_height_and_belly_clearance_come_from_the_model(env_id):
    constants = WALKS[env_id]
    env = gym.make(env_id, reset_noise_scale=0.0)
    env.reset(seed=0)
    robot, model, data = env.unwrapped.robot, env.unwrapped.model, env.unwrapped.data
    mujoco.mj_forward(model, data)
    root = model.body(robot.root_body).id
    assert data.xpos[root, 2] == pytest.approx(constants.STANDING_HEIGHT, abs=1e-3)
    assert lowest_point(model, data, root) == pytest.approx(constants.BELLY_CLEARANCE, abs=1e-3)
    low, high = robot.height_band
    assert low < constants.STANDING_HEIGHT - 0.25 * constants.BELLY_CLEARANCE and high > constants.STANDING_HEIGHT
    assert low > constants.STANDING_HEIGHT - constants.BELLY_CLEARANCE  # a body on its belly is out of the band


@pytest.mark.parametrize("env_id", WALKS)
def test_every_colliding_part_but_the_feet_has_a_ground_sensor(env_id):
    """A sensor per colliding body without a foot geom, a sensor per other colliding geom of a body with one."""
    robot = gym.make(env_id).unwrapped.robot
    model = robot.model
    root = model.body(robot.root_body).id
    colliding: dict[str, list[str]] = {}
    for g in range(model.ngeom):
        body = model.geom_bodyid[g]
        if model.body_rootid[body] == root and (model.geom_contype[g] or model.geom_conaffinity[g]):
            colliding.setdefault(model.body(body).name, []).append(model.geom(g).name)
    expected = set()
    for body, geoms in colliding.items():
        if body not in robot.feet:
            feet_here = [g for g in geoms if g in robot.feet]
            expected |= {g for g in geoms if g not in robot.feet} if feet_here else {body}
    sensed = {name.removeprefix(GROUND_SENSOR) for name in robot.sensors if name.startswith(GROUND_SENSOR)}
    assert sensed == expected and set(robot.feet) <= set(colliding) | {g for gs in colliding.values() for g in gs}
    assert not robot.non_foot_contact()[0]  # standing at reset, only its feet touch


def crawl_episode(env_id: str, action, options=None, **kwargs) -> dict:
    env = gym.make(env_id, **kwargs)
    base = env.unwrapped
    env.reset(seed=0, options=options)
    total, steps = 0.0, 0
    while True:
        _, reward, terminated, truncated, info = env.step(action(base, steps))
        total, steps = total + reward, steps + 1
        if terminated or truncated:
            return {"terminated": terminated, "return": total, "steps": steps, **info}


def xjus_belly_crawl(base, step: int) -> np.ndarray:
    """Every leg turning slowly at a quarter duty from pointing up: the body rests on its belly, the legs paddle."""
    return np.full(6, 0.25, dtype=np.float32)


def bioloid_swim(base, step: int) -> np.ndarray:
    """The legs splayed out sideways over the first second (the abduction servos 69 deg off their standing 90), the
    hips paddling at 1.5 Hz in a trot's pairs: "almost swimming" [bioloid-webots]."""
    robot, t = base.robot, step * base.dt
    index = {servo: i for i, servo in enumerate(bioloid_constants.SERVOS)}
    angles = np.array([robot.ready[servo] for servo in bioloid_constants.SERVOS])
    paddle = 0.4 * np.sin(2 * np.pi * 1.5 * t)
    for leg in bioloid_constants.LEGS:
        i = index[bioloid_constants.ABDUCTION[leg]]
        angles[i] -= np.sign(angles[i]) * 1.2 * min(1.0, t)
        angles[index[bioloid_constants.HIP[leg]]] += paddle if leg in ("F_L", "B_R") else -paddle
    return robot.mode.to_action(robot.servo.constants.counts_of(angles))


CRAWLS = {
    "skitter/XjusWalk-v1": (xjus_belly_crawl, {"leg_angles": [np.pi] * 6}, {"action_mode": "duty"}),
    "skitter/BioloidWalk-v2": (bioloid_swim, None, {}),
}


@pytest.mark.parametrize("env_id", CRAWLS)
def test_a_scripted_crawl_ends_its_episode(env_id):
    policy, options, kwargs = CRAWLS[env_id]
    ended = crawl_episode(env_id, policy, options, episode_seconds=5.0, **kwargs)
    assert ended["terminated"] and ended["steps"] * gym.make(env_id, **kwargs).unwrapped.dt < 3.0
    assert max(ended["contact_time"], ended["band_time"]) > GRACE_TIME  # a ground rule ended it, not a tilt
    assert ended["body_height"] < gym.make(env_id).unwrapped.task.height_band[0] or ended["non_foot_touch"]
    # without the rules the same crawl stays upright to the time limit: nothing but the rules stops it
    free = crawl_episode(env_id, policy, options, episode_seconds=5.0, terminate_when_unhealthy=False, **kwargs)
    assert not free["terminated"] and free["up_z"] > 0.9
    # a shorter grace ends it sooner
    sooner = crawl_episode(env_id, policy, options, episode_seconds=5.0, grace_time=0.3, **kwargs)
    assert sooner["terminated"] and sooner["steps"] < ended["steps"]


def test_the_roach_cannot_crawl_and_its_paddling_scores_below_the_tripod():
    """The C-legs hold the chassis clear at any crank angle (its belly never reaches the floor): a crawl with the
    legs set level fore and aft and rocking back and forth stays in the band and loses to the tripod."""

    def paddle(base, step: int) -> np.ndarray:
        swing = 0.3 * np.sin(2 * np.pi * 3.0 * step * base.dt)
        return np.array([swing, swing], dtype=np.float32)

    env_id = "skitter/RoachWalkDuty-v3"
    crawl = crawl_episode(env_id, paddle, {"crank_left": np.pi / 2, "phase": 0.0}, episode_seconds=2.0)
    env = gym.make(env_id, episode_seconds=2.0)
    tripod = load_policy("tripod", env)
    obs, _ = env.reset(seed=0)
    total, done = 0.0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(
            tripod.predict(obs, episode_start=np.array([total == 0]))[0]
        )
        total, done = total + reward, terminated or truncated
    assert not terminated and crawl["return"] < total and crawl["x_position"] < 0.1 * info["x_position"]


@pytest.mark.parametrize("env_id", WALKS)
def test_the_reference_gait_keeps_the_rules(env_id):
    seeds = [0, 1, 1000, 1001]
    venv = gym.make_vec(env_id, num_envs=len(seeds), vectorization_mode="vector_entry_point", episode_seconds=4.0)
    policy = load_policy(reference_policy(venv.unwrapped.robot.name), venv)
    obs, _ = venv.reset(seed=seeds)
    state, start, running = None, np.ones(len(seeds), dtype=bool), np.ones(len(seeds), dtype=bool)
    while running.any():
        action, state = policy.predict(obs, state=state, episode_start=start)
        start[:] = False
        obs, _, terminated, truncated, info = venv.step(action)
        assert not (running & terminated).any(), info
        assert (info["contact_time"][running] < 0.5 * GRACE_TIME).all()
        assert (info["band_time"][running] == 0.0).all()
        running &= ~truncated


def test_the_benchmark_covers_every_id_and_no_reference_episode_ended_by_the_rules():
    """benchmarks/results/ground_rules.json (``python -m benchmarks.ground_rules``): every registered id, 20 seeds;
    no reference episode on open ground ended by the rules (the academy's walled fields are reported apart)."""
    result = json.loads(RESULTS.read_text())
    rows = {row["env_id"]: row for row in result["rows"]}
    assert sorted(rows) == sorted(k for k in gym.registry if k.startswith("skitter/"))
    assert all(row["episodes"] == 20 for row in rows.values())
    open_ground = [row for row in rows.values() if not row["walled_field"]]
    assert result["met"] and all(row["ended_by_ground_rules"] == 0 for row in open_ground)
    assert {row["env_id"] for row in rows.values() if row["walled_field"]} == {
        k for k in gym.registry if k.startswith("skitter/") and any(t in k for t in ("GoToBall", "Score"))
    }, "only the soccer academy's ids are on a walled field"


def test_the_terrain_height_is_the_height_field_mujoco_collides_with():
    terrain = Terrain(roughness=0.03, obstacle="course", seed=3)
    spec = mujoco.MjSpec.from_string('<mujoco><worldbody><geom name="floor" type="plane" size="0 0 1"/></worldbody>'
                                     "</mujoco>")  # fmt: skip
    terrain(spec)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(0)
    x, y = terrain.grid()
    points = np.column_stack([rng.uniform(x[0], x[-1], 200), rng.uniform(y[0], y[-1], 200)])
    geomid = np.zeros(1, dtype=np.int32)
    hit = [1.0 - mujoco.mj_ray(model, data, np.array([px, py, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
           for px, py in points]  # fmt: skip
    # MuJoCo splits each grid cell into two triangles, the interpolation is bilinear: they differ inside a cell by
    # at most a quarter of the cell's twist
    assert np.abs(terrain.height_at(points) - np.array(hit)).max() < 0.01
    beyond = terrain.height_at(np.array([[x[-1] + 5.0, 0.0]]))[0]
    assert beyond == pytest.approx(terrain.heights().min() - 0.05)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"height_band": (0.2, 0.1)},
        {"height_band": "low"},
        {"height_band": np.array(0.1)},
        {"height_band": {"low": 0.05, "high": 0.3}},
        {"height_band": {0.05, 0.3}},
        {"height_band": (float("nan"), 0.3)},
        {"height_band": [0.1]},
        {"grace_time": -1.0},
        {"grace_time": True},
        {"terminate_when_unhealthy": "no"},
    ],
)
def test_bad_ground_rule_arguments_are_refused_by_name(kwargs):
    name = next(iter(kwargs))
    with pytest.raises(ValueError, match=name):
        gym.make("skitter/BioloidWalk-v2", **kwargs)


def test_a_band_may_be_open_above_and_a_robot_without_feet_or_band_has_no_rules(monkeypatch):
    env = gym.make("skitter/BioloidWalk-v2", height_band=(0.05, float("inf")))
    assert env.unwrapped.task.height_band == (0.05, float("inf"))
    from envs.bioloid.robot import Bioloid

    monkeypatch.setattr(Bioloid, "feet", None)
    monkeypatch.setattr(Bioloid, "height_band", None)
    env = gym.make("skitter/BioloidWalk-v2", episode_seconds=1.0)
    robot = env.unwrapped.robot
    assert not [name for name in robot.sensors if name.startswith(GROUND_SENSOR)]
    env.reset(seed=0, options={"height": 0.03})  # dropped onto its belly: no rule to break
    *_, info = env.step(env.action_space.sample())
    assert not robot.non_foot_contact()[0] and info["band_time"] == 0.0 and env.unwrapped.task.height_band[0] < 0


def test_the_optimizer_scores_a_rule_break_as_a_fall():
    """The optimizer's rollouts keep their env's ground rules: with a band the Bioloid's body cannot be in, every
    rollout falls once the grace has passed; without the rules the same rollouts run on until this CPG tips over."""
    from agents.optimize.problem import Evaluator, parse_config

    def scores(env_kwargs: dict) -> dict:
        config = {"env": "skitter/BioloidWalk-v2", "controller": "cpg", "coupling": "experiment5", "seconds": 2.0,
                  "env_kwargs": {"height_band": [0.2, 0.3], "grace_time": 0.1, **env_kwargs}}  # fmt: skip
        return Evaluator(parse_config(config), 2, nthread=1).evaluate(np.full((2, 16), 0.5))

    ruled, free = scores({}), scores({"terminate_when_unhealthy": False})
    assert ruled["fallen"].all() and ruled["fall_time"] == pytest.approx([0.12, 0.12])  # 0.1 s grace, 50 Hz steps
    assert (free["fall_time"] > 0.3).all() and (free["forward"] > ruled["forward"]).all()


def test_a_foot_geom_leaves_the_other_geoms_of_its_body_sensed():
    """Feet may be geoms: a body that carries one gets a sensor per other colliding geom (named), not one for the
    body; an unknown foot or an unnamed geom beside a foot is refused by name."""
    from envs.common.robot import add_ground_contact_sensors

    def spec(knee_name: str = ' name="knee"') -> mujoco.MjSpec:
        return mujoco.MjSpec.from_string(
            '<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>'
            '<body name="torso" pos="0 0 .3"><freejoint/><geom type="box" size=".1 .05 .02"/>'
            f'<body name="leg"><geom name="shin" type="capsule" fromto="0 0 0 0 0 -.25" size=".01"/>'
            f'<geom{knee_name} type="sphere" size=".02"/><geom name="visual" type="sphere" size=".01" contype="0" '
            'conaffinity="0"/></body></body></worldbody></mujoco>'
        )

    model_spec = spec()
    names = add_ground_contact_sensors(model_spec, "torso", ("shin",))
    assert names == [GROUND_SENSOR + "torso", GROUND_SENSOR + "knee"]
    model = model_spec.compile()
    data = mujoco.MjData(model)
    data.qpos[2] = 0.02  # the leg through the floor, the torso just above it: the knee and the torso touch
    mujoco.mj_forward(model, data)
    assert (data.sensordata > 0).all()  # "found": how many contacts (the box corners: four)
    with pytest.raises(ValueError, match="toe"):
        add_ground_contact_sensors(spec(), "torso", ("toe",))
    with pytest.raises(ValueError, match="unnamed"):
        add_ground_contact_sensors(spec(""), "torso", ("shin",))
