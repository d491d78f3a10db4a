"""The robot contract, run over every robot: the VelociRoACH in both action modes and both bench rigs."""

import copy

import gymnasium as gym
import mujoco
import numpy as np
import pytest

from envs.bench.robot import MotorRig, ServoRig
from envs.common.simulation import CTRL_SPEC, STATE_SPEC
from tests.conftest import ENV_IDS, model_bytes


def _robots_of_registered_envs() -> dict:
    """One robot on its own per (robot, action mode) among the registered envs: a new robot's envs bring it in."""
    found = {}
    for env_id in ENV_IDS:
        spec = gym.spec(env_id)
        robot = gym.make(env_id).unwrapped.robot
        key = f"{robot.name}-{robot.action_mode}"
        if key not in found and not robot.hosted:  # a robot on its own (the academy's share a scene with a field)
            found[key] = lambda spec=spec: gym.make(spec.id).unwrapped.robot
    return found


ROBOTS = {**_robots_of_registered_envs(), "motor-rig": MotorRig, "servo-rig": ServoRig}
REQUIRED_CHANNELS = {"time", "power", *(f"pos_{a}" for a in "xyz"), *(f"quat_{a}" for a in "wxyz")}
READINGS = {"time": (), "position": (3,), "quaternion": (4,), "velocity": (3,), "power": ()}


@pytest.fixture(params=list(ROBOTS))
def robot(request):
    return ROBOTS[request.param]()


def mid_command(robot) -> np.ndarray:
    """The middle of every command's range (a robot-agnostic, in-range command)."""
    return robot.mode.to_command(np.zeros((1, robot.mode.size)))


def test_build_reset_step_and_read(robot):
    assert robot.model.opt.timestep * robot.n_substeps == pytest.approx(robot.control_dt)
    rngs = [np.random.default_rng(1)]
    robot.reset(np.array([0]), rngs, 0.05)
    readings = robot.read(rngs, stepped=False)
    for _ in range(5):
        robot.command(mid_command(robot))
        assert robot.step().tolist() == [True]
        readings = robot.read(rngs)
    for name, shape in READINGS.items():
        assert readings[name].shape == (1, *shape), name
        assert np.isfinite(readings[name]).all(), name
    assert readings["time"][0] == pytest.approx(5 * robot.control_dt)
    assert readings["senses"].shape == (1, sum(robot.sense_structure.values()))
    assert readings["power"][0] >= 0


def test_instability_is_reported(robot):
    rngs = [np.random.default_rng(0)]
    robot.reset(np.array([0]), rngs)
    robot.data.qvel[:] = 1e12  # no physical robot survives this
    robot.command(mid_command(robot))
    assert robot.step().tolist() == [False]


def test_named_sensors(robot):
    assert robot.sensors, "a robot names its sensors"
    for name, where in robot.sensors.items():
        assert robot.sensor(name).shape == (1, where.stop - where.start)
        sensor = robot.model.sensor(name)
        assert (int(sensor.adr[0]), int(sensor.dim[0])) == (where.start, where.stop - where.start)


def test_telemetry_channels_have_units(robot):
    channels = robot.telemetry_channels
    assert REQUIRED_CHANNELS <= set(channels)
    assert all(isinstance(unit, str) and unit for unit in channels.values())
    rngs = [np.random.default_rng(0)]
    robot.reset(np.array([0]), rngs)
    robot.command(mid_command(robot))
    robot.step()
    row = robot.telemetry(robot.read(rngs))
    assert row.shape == (1, len(channels))
    for group in robot.plot_groups:
        assert set(group.channels) | set(group.minus) <= set(channels), group.title


def test_the_velociroach_comes_in_both_action_modes():
    assert {"velociroach-gait", "velociroach-duty", "motor-rig", "servo-rig"} <= set(ROBOTS)


def test_facts(robot):
    facts = robot.facts
    assert facts.mass > 0 and facts.length > 0
    assert len(set(facts.legs)) == len(facts.legs)
    for side in facts.sides:
        assert any(name.endswith(f"_{side}") for name in robot.telemetry_channels), side


def test_parameters_apply_and_return_to_nominal(robot):
    before = {name: np.array(getattr(robot.model, name), copy=True) for name in robot.parameters._nominal_fields}
    ids = np.array([0])
    for p in robot.parameters:
        value = p.low + 0.75 * (p.high - p.low)
        if value == p.nominal:
            continue
        robot.set_parameters(ids, {p.name: value})
        changed = [
            ref.field for ref in p.fields if not np.array_equal(getattr(robot.model, ref.field), before[ref.field])
        ]
        assert changed or p.attribute, f"{p.name} changed nothing"
        if p.attribute:
            assert getattr(robot, p.attribute)[0] == pytest.approx(value)
        robot.set_parameters(ids, {})
        for name, values in before.items():
            np.testing.assert_array_equal(getattr(robot.model, name), values, err_msg=f"{p.name} left {name} changed")
    with pytest.raises(ValueError, match="unknown parameters"):
        robot.set_parameters(ids, {"no_such_parameter": 1.0})


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_an_episode_replays_exactly_from_its_controls_through_mujoco_rollout(env_id):
    """Every input to the physics is a ctrl value, and the controller gains a robot writes between control blocks
    (the roach's, which follow its sagging battery in gait mode): the recorded control blocks, rolled out natively
    from the reset state (block by block with the recorded gains where they change), give the env's states
    exactly."""
    env = gym.make(env_id)
    base = env.unwrapped
    env.reset(seed=3)
    model, data = base.model, base.data
    start = np.empty(mujoco.mj_stateSize(model, STATE_SPEC))
    mujoco.mj_getState(model, data, start, STATE_SPEC)
    warmstart = data.qacc_warmstart.copy()
    # the model's simulation: a soccer env's scene (every player's controls), else the robot's
    sim = base.scene.sim if hasattr(base, "scene") else base.robot.sim
    env.action_space.seed(3)
    blocks, gains, qpos = [], [], []
    for _ in range(40 if "Duty" not in env_id else 400):
        env.step(env.action_space.sample())
        blocks.append(sim.ctrl[0].copy())
        gains.append(model.actuator_gainprm.copy())  # as the block ran
        qpos.append(data.qpos.copy())
    n = base.robot.n_substeps
    writes = any(not np.array_equal(g, gains[0]) for g in gains)
    assert writes == (env_id.startswith("skitter/Roach") and "Duty" not in env_id), "only the roach's gait writes"
    replay = copy.copy(model)
    if not writes:  # one native rollout of every block
        control = np.concatenate(blocks)[None]
        state, _ = mujoco.rollout.rollout(replay, mujoco.MjData(replay), start[None], control,
                                          control_spec=CTRL_SPEC, initial_warmstart=warmstart[None])  # fmt: skip
        replayed = state[0, n - 1 :: n, 1 : 1 + model.nq]  # the state after each control step: time, qpos, ...
    else:  # each block with its gains, the physics native within it
        d = mujoco.MjData(replay)
        mujoco.mj_setState(replay, d, start, STATE_SPEC)
        d.qacc_warmstart[:] = warmstart
        replayed = []
        for block, g in zip(blocks, gains, strict=True):
            replay.actuator_gainprm[:] = g
            for row in block:
                mujoco.mj_setState(replay, d, row, CTRL_SPEC)
                mujoco.mj_step(replay, d)
            replayed.append(d.qpos.copy())
    np.testing.assert_array_equal(np.array(replayed), np.array(qpos))


def test_compile_with_compiles_a_copy_of_the_robots_own_spec(robot):
    """With no edits, the model the robot holds, byte for byte; an edit lands in the copy only (the robot's kept
    spec is not edited); a pickled robot keeps its model hash but not its spec, and says so."""
    import pickle

    assert model_bytes(robot.compile_with([])) == model_bytes(robot.model)
    light = robot.compile_with([lambda spec: setattr(spec.option, "gravity", [0.0, 0.0, -1.0])])
    assert light.opt.gravity.tolist() == [0.0, 0.0, -1.0]
    assert robot.model.opt.gravity[2] == pytest.approx(-9.81)
    assert model_bytes(robot.compile_with([])) == model_bytes(robot.model)
    back = pickle.loads(pickle.dumps(robot))
    assert back.model_hash == robot.model_hash and len(robot.model_hash) == 16
    with pytest.raises(RuntimeError, match="does not keep its spec"):
        back.compile_with([])
