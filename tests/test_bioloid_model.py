"""The Bioloid quadruped's model against its sources: masses, geometry, the knee wedge, the AX-12 servos in the robot
(holding a pose within their compliance, saturating at their torque limit), telemetry and argument checks."""

import math

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import envs  # noqa: F401
from envs.actuators.servo import KGF_CM, ServoConstants
from envs.bioloid import constants
from envs.bioloid.kinematics import LegGeometry
from envs.bioloid.robot import Bioloid

RNG = [np.random.default_rng(0)]
ONE = np.array([0])


def test_total_mass_is_the_seeds_within_two_percent_and_every_part_is_table_3():
    robot = Bioloid(imu_noise=None)
    m = robot.model
    assert robot.facts.mass == pytest.approx(constants.MASS, rel=constants.MASS_TOLERANCE)
    for part, grams in constants.PARTS_G.items():
        assert m.body(part).mass[0] == pytest.approx(grams / 1000.0), part
    assert sum(constants.PARTS_G.values()) == 1760


def test_hip_anchor_segments_and_servo_names_follow_the_sources():
    robot = Bioloid(imu_noise=None)
    m = robot.model
    assert [m.actuator(i).name for i in range(m.nu)] == [f"{s}_servo" for s in constants.SERVOS]
    np.testing.assert_allclose(m.body("F_L_1").pos, constants.HIP_ANCHOR_FRONT)
    np.testing.assert_allclose(m.body("F_R_1").pos, np.array(constants.HIP_ANCHOR_FRONT) * [1, -1, 1])
    assert m.body("F_L_3").pos[1] == pytest.approx(constants.THIGH)
    assert m.site("F_L_sole").pos[1] == pytest.approx(constants.SHANK)


def test_standing_posture_puts_the_legs_down_and_forward_kinematics_matches_the_model():
    for wedge in (False, True):
        robot = Bioloid(knee_wedge=wedge, imu_noise=None)
        m, d = robot.model, mujoco.MjData(robot.model)
        rng = np.random.default_rng(1)
        angles = np.array([constants.STAND_ANGLES[s] for s in constants.SERVOS])
        for leg in constants.LEGS:
            angles[constants.SERVO_INDEX[constants.HIP[leg]]] = rng.uniform(-0.5, 0.5)
            angles[constants.SERVO_INDEX[constants.KNEE[leg]]] = rng.uniform(0.0, 1.2)
        d.qpos[robot._servo_qpos] = angles
        d.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
        mujoco.mj_kinematics(m, d)
        for leg in constants.LEGS:
            hip = d.body(constants.HIP[leg]).xpos
            sole = d.site(constants.SOLE_SITE[leg]).xpos
            x, z = LegGeometry.of(leg, robot.wedge).forward(
                angles[constants.SERVO_INDEX[constants.HIP[leg]]], angles[constants.SERVO_INDEX[constants.KNEE[leg]]]
            )
            assert sole[0] - hip[0] == pytest.approx(x, abs=1e-9), (wedge, leg)
            assert sole[2] - hip[2] == pytest.approx(z, abs=1e-9), (wedge, leg)
            assert abs(sole[1] - hip[1]) < 0.01, "the leg points down, not sideways"


def test_knee_wedge_turns_every_shank_by_18_degrees_and_changes_nothing_else():
    plain, wedged = Bioloid(imu_noise=None), Bioloid(knee_wedge=True, imu_noise=None)
    assert wedged.facts.mass == pytest.approx(plain.facts.mass)
    for leg in constants.LEGS:
        q = wedged.model.body(constants.KNEE[leg]).quat
        assert 2 * math.degrees(math.atan2(q[3], q[0])) == pytest.approx(18.0)
        np.testing.assert_array_equal(plain.model.body(constants.KNEE[leg]).quat, [1, 0, 0, 0])
    assert wedged.model_hash != plain.model_hash


def test_body_length_constant_matches_the_model_within_a_centimetre():
    robot = Bioloid(imu_noise=None)
    robot.reset(ONE, RNG)
    m, d = robot.model, robot.data
    xs = []
    for name in ("cm5", "head", "pelvis", "PELVIS_case"):
        g = m.geom(name).id
        half = np.abs(d.geom_xmat[g].reshape(3, 3)[0]) @ m.geom_size[g]  # half-extent along world x
        xs += [d.geom_xpos[g, 0] - half, d.geom_xpos[g, 0] + half]
    assert max(xs) - min(xs) == pytest.approx(constants.LENGTH, abs=0.01)


def settle(robot: Bioloid, seconds: float) -> None:
    for _ in range(round(seconds / robot.control_dt)):
        robot.command(robot.goal.copy())
        robot.step()


def test_servos_hold_the_standing_pose_under_gravity_within_their_compliance():
    """Standing at the ready posture, every servo holds its goal: the error stays below the compliance slope (the
    servo is not saturated) and equals torque / stiffness, the proportional law; the body holds its height."""
    robot = Bioloid(imu_noise=None)
    robot.reset(ONE, RNG)
    settle(robot, 1.0)
    z0 = robot.data.qpos[2]
    settle(robot, 2.0)
    assert abs(robot.data.qpos[2] - z0) < 0.002, "the pose holds"
    c = robot.servo.constants
    stiffness = c.stall_torque / c.compliance_slope  # N m per count of error
    error = robot.servo.constants.counts_of(robot.servo_angles()[0]) - robot.goal[0]
    torque = robot.servo.output_torque(robot.sim.sensordata)[0]
    assert np.abs(error).max() < c.compliance_slope, "within compliance, not saturated"
    assert np.abs(error).max() > 1.0, "the knees carry the robot: they sag a little"
    loaded = np.abs(torque) > 0.05
    np.testing.assert_allclose(-torque[loaded] / stiffness, error[loaded], atol=0.5)  # 0.5 count: velocity, noise


def clamped_servo(supply: float, torque_limit: float = 1023.0, servo: str = "F_L_3") -> Bioloid:
    """The body fixed in the air and one servo (the front-left knee) blocked at 0 rad by its joint limits."""

    def edit(spec: mujoco.MjSpec) -> None:
        spec.delete(spec.joint(constants.ROOT_JOINT))
        spec.body(constants.ROOT_BODY).pos = [0.0, 0.0, 0.5]

    robot = Bioloid(servo=ServoConstants(supply_voltage=supply, torque_limit=torque_limit), imu_noise=None,
                    spec_edits=[edit])  # fmt: skip
    i = robot.model.joint(servo).id
    robot.model.jnt_range[i] = [-1e-4, 1e-4]
    return robot


@pytest.mark.parametrize(("supply", "kgf_cm"), [(7.0, 12.0), (10.0, 16.5)])
def test_a_blocked_servo_saturates_at_its_holding_torque(supply, kgf_cm):
    # a hip pitch servo (the knee's allowed range is one-sided: straight to bent 90 deg)
    robot = clamped_servo(supply, servo="F_L_1")
    robot.reset(ONE, RNG, options={"angles": [constants.STAND_ANGLES[s] for s in constants.SERVOS]})
    servo = constants.SERVO_INDEX["F_L_1"]
    for goal in (constants.CENTER + 200, constants.CENTER - 200):  # 59 deg away from where the stop holds it, both ways
        robot.goal[0, servo] = goal
        settle(robot, 0.3)
        torque = robot.servo.output_torque(robot.sim.sensordata)[0, servo]
        assert abs(torque) == pytest.approx(kgf_cm * KGF_CM, rel=0.03), goal  # datasheet, [bioloid-webots, Table 2]
        assert np.sign(torque) == np.sign(goal - constants.CENTER)
        readings = robot.read(RNG)
        row = dict(zip(robot.telemetry_channels, robot.telemetry(readings)[0], strict=True))
        assert abs(row["load_F_L_1"]) == 1023, "the servo reports full load"


def test_the_torque_limit_register_caps_the_torque():
    robot = clamped_servo(10.0, torque_limit=512)
    robot.reset(ONE, RNG, options={"angles": [constants.STAND_ANGLES[s] for s in constants.SERVOS]})
    knee = constants.SERVO_INDEX["F_L_3"]
    robot.goal[0, knee] = constants.CENTER + 200
    settle(robot, 0.3)
    torque = robot.servo.output_torque(robot.sim.sensordata)[0, knee]
    assert torque == pytest.approx(16.5 * KGF_CM * 512 / 1023, rel=0.03)


def test_action_spans_each_servos_allowed_range_and_knees_go_from_straight_to_bent_90_degrees():
    env = gym.make("skitter/BioloidWalk-v2")
    robot = env.unwrapped.robot
    low, high = robot.mode.to_command(-np.ones(16)), robot.mode.to_command(np.ones(16))
    for name, (lo, hi) in constants.SERVO_RANGE.items():
        i = constants.SERVO_INDEX[name]
        assert (low[i], high[i]) == (lo, hi), name
    for leg in (
        constants.LEGS
    ):  # [bioloid-webots, VI.A.2] (bent at most 90 deg) and Table 4 (straight knees); no backward bend
        i = constants.SERVO_INDEX[constants.KNEE[leg]]
        assert (low[i], high[i]) == pytest.approx(
            (constants.CENTER, constants.CENTER + math.radians(90) / constants.RAD_PER_COUNT)
        )
        assert robot.model.joint(constants.KNEE[leg]).range == pytest.approx([0.0, math.radians(90)])
    assert (low[0], high[0]) == (0.0, 1023.0)


def test_telemetry_has_goal_present_position_load_and_battery_per_servo():
    env = gym.make("skitter/BioloidWalk-v2", telemetry=True)
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample())
    frame = env.unwrapped.recorder.frame()
    for servo in constants.SERVOS:
        for channel in ("goal", "present_position", "torque", "load"):
            assert f"{channel}_{servo}" in frame.columns
    assert (frame["vbatt"] == 10.0).all()
    assert ((frame["present_position_F_L_1"] % 1) == 0).all(), "positions reported in whole counts"


def test_parameters_reach_the_model():
    robot = Bioloid(imu_noise=None)
    body = robot.model.body("BODY").id
    robot.set_parameters(ONE, {"body_com_x": 0.01, "battery_voltage": 7.0, "compliance_slope": 64.0})
    assert robot.model.body_ipos[body, 0] == 0.01
    assert robot.battery[0] == 7.0
    assert sorted(robot.parameters.names()) == sorted([
        "battery_voltage", "compliance_slope", "servo_armature", "joint_friction", "joint_damping",
        "foot_friction", "body_friction", "body_mass", "body_com_x", "body_com_y", "body_com_z",
    ])  # fmt: skip


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"knee_wedge": "yes"}, "knee_wedge"),
        ({"battery_voltage": 0.0}, "battery_voltage"),
        ({"servo": 10.0}, "servo"),
        ({"control_freq": 333.0}, "control_freq"),
        ({"max_tilt": -1.0}, "max_tilt"),
    ],
)
def test_nonsense_constructor_arguments_are_refused_at_once(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gym.make("skitter/BioloidWalk-v2", **kwargs)


def test_the_offset_mode_centres_every_servo_on_the_ready_posture_with_half_a_radian_each_way():
    from envs.bioloid.robot import OFFSET_SCALE, ready_angles

    for wedge in (False, True):
        robot = Bioloid(action_mode="offset", knee_wedge=wedge)
        ready = ready_angles(robot.wedge)
        centre = np.array([constants.CENTER + ready[s] / constants.RAD_PER_COUNT for s in constants.SERVOS])
        assert robot.mode.to_command(np.zeros(16)) == pytest.approx(centre)
        reach = (robot.mode.to_command(np.ones(16)) - robot.mode.to_command(-np.ones(16))) / 2
        assert reach * constants.RAD_PER_COUNT == pytest.approx(np.full(16, OFFSET_SCALE))
    env = gym.make("skitter/BioloidTurn-v5")
    robot = env.unwrapped.robot
    env.reset(seed=0)
    env.step(np.ones(16, dtype=np.float32))  # past the knees' bend limit: clipped to the servos' allowed range
    high = np.minimum(robot.mode.to_command(np.ones(16)), constants.RANGE_HIGH)
    assert robot.goal[0] == pytest.approx(high)
    assert (robot.goal[0] <= constants.RANGE_HIGH).all()


@pytest.mark.parametrize("seed", [0, 1])
def test_under_random_actions_the_robot_stands_in_the_offset_mode_and_falls_in_the_goal_mode(seed):
    """What BioloidTurn-v5 changed: in the goal mode an action of 0 puts the legs out sideways and random actions
    fall within about 2 s; in the offset mode they wobble around the ready posture and stay up (measured on seeds
    1000-1009: 100 steps on average against the whole 500)."""
    lengths = {}
    for mode in ("offset", "goal"):
        env = gym.make("skitter/BioloidTurn-v5", action_mode=mode)
        env.reset(seed=seed)
        env.action_space.seed(seed)
        steps, ended = 0, False
        while steps < 300 and not ended:
            *_, terminated, truncated, info = env.step(env.action_space.sample())
            steps, ended = steps + 1, terminated or truncated
        lengths[mode] = (steps, info["fallen"])
    assert lengths["offset"] == (300, False) and lengths["goal"][0] < 250 and lengths["goal"][1], lengths
