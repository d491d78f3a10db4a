"""The xJüs model against the numbers of its sources ([xjus-report], [saranli2001]; docs/references.md)."""

import mujoco
import numpy as np
import pytest

from envs.actuators.motor import MotorConstants
from envs.xjus import constants, facts
from envs.xjus.controller import MotorArrays, buehler_clock
from envs.xjus.robot import COMPLIANT, DUTY, GAIT, RIGID, Xjus, efficiency_cap

RNG = [np.random.default_rng(0)]
ONE = np.array([0])


@pytest.fixture(scope="module")
def robot() -> Xjus:
    return Xjus(GAIT)


def test_total_mass_is_4_467_kg_with_the_battery(robot):
    assert robot.facts.mass == pytest.approx(constants.MASS, rel=0.02)
    battery = robot.model.geom("battery")
    assert robot.model.geom_bodyid[battery.id] == robot.model.body(constants.ROOT_BODY).id
    assert float(robot.model.body_mass[robot.model.body(constants.ROOT_BODY).id]) > constants.BATTERY_MASS


def test_body_is_research_rhex_long_and_the_legs_are_7_inch_semicircles(robot):
    assert facts.body_length(robot) == pytest.approx(constants.LENGTH, rel=0.01)
    tip = robot.model.site("FL_tip").pos
    assert np.linalg.norm(tip) == pytest.approx(constants.LEG_DIAMETER, rel=1e-3)


def test_leg_compliance_in_a_static_load_test():
    """[xjus-report] FEA: 29.2 N on a leg deflects it 0.30 in (7.6 mm)."""
    result = facts.leg_load_test()
    np.testing.assert_allclose(result["toe"], constants.LEG_TEST_DEFLECTION, rtol=0.03)
    np.testing.assert_allclose(result["spring"], constants.LEG_TEST_DEFLECTION, rtol=0.03)


def test_each_leg_motor_stalls_at_2_17_n_m_and_runs_free_at_29_6_rad_s_in_the_assembled_robot():
    bench = facts.motor_bench(duty=1.0)
    np.testing.assert_allclose(bench["stall_torque"], constants.STALL_TORQUE, rtol=0.01)
    np.testing.assert_allclose(bench["no_load_speed"], constants.NO_LOAD_SPEED, rtol=0.01)


def test_motor_constants_are_the_seeds_table_1(robot):
    assert robot.constants == MotorConstants()
    assert efficiency_cap() == pytest.approx(constants.EFFICIENCY_CAP, abs=0.005)
    assert robot.facts.extra["efficiency_cap"] == pytest.approx(0.37, abs=0.005)


def test_native_motor_torque_is_the_seed_formula_at_held_duties():
    """Duty mode on a blocked and a spinning leg: the hip torque MuJoCo applies equals the shared formula."""
    c = MotorConstants()
    spinning = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[facts.clamp(quat=facts.HIPS_VERTICAL)])
    spinning.reset(ONE, RNG, options={"leg_angles": np.zeros(6)})
    for duty in (0.3, -0.7, 1.0, 0.05):
        facts.hold(spinning, duty, 0.05)
        speed, torque = spinning.leg_speeds()[0], spinning.hip_torques()[0]
        # sensors at a block's end are computed before its last physics step, at the speed shown
        np.testing.assert_allclose(torque, c.torque(np.float64(duty), speed), rtol=1e-9, atol=1e-12)


def test_duty_for_torque_inverts_the_motor_model():
    motors = MotorArrays(*(np.array([v]) for v in (22.2, 2.36, 0.5, MotorConstants().torque_per_amp, 0.75)))
    rng = np.random.default_rng(0)
    duty = rng.uniform(-1, 1, (1, 200))
    speed = rng.uniform(-25, 25, (1, 200))
    a, b = motors.coefficients(duty)
    torque = a - b * speed
    np.testing.assert_allclose(torque, MotorConstants().torque(duty, speed), rtol=1e-12)
    np.testing.assert_allclose(motors.duty_for_torque(torque, speed), duty, atol=1e-9)
    assert motors.duty_for_torque(np.array([[50.0]]), np.array([[0.0]]))[0, 0] == 1.0, "beyond reach: full duty"


def test_buehler_clock_is_the_seeds_fourier_series():
    """[xjus-report, section 2.5]: theta_d(0) = 0, a full turn per cycle, theta_g swept in the first half (exactly for
    the infinite series; the M = 10 terms reach 98% of the way from pi to theta_g, 2.4 deg short at 60 deg), ground
    speed about 2 theta_g / T in mid-stance."""
    sweep = np.radians(60.0)
    s = np.array([0.0, 0.25, 0.5, 1.0])
    angle, rate, _ = buehler_clock(s, sweep)
    odd = 2 * np.arange(1, 11) - 1
    reach = 8 / np.pi**2 * np.sum(1.0 / odd**2)  # 1 for the infinite series
    assert reach == pytest.approx(0.98, abs=0.005)
    assert angle[0] == pytest.approx(0.0, abs=1e-12)
    assert angle[3] == pytest.approx(2 * np.pi, abs=1e-9)
    assert angle[2] == pytest.approx(np.pi + reach * (sweep - np.pi), rel=1e-12)
    assert angle[2] == pytest.approx(sweep, abs=np.radians(2.5))
    assert angle[1] == pytest.approx(sweep / 2, abs=np.radians(1.5))
    assert rate[1] == pytest.approx(2 * sweep, rel=0.1)  # per cycle: 2 theta_g / T with T = 1
    m = np.arange(1, 11)
    t = 0.3
    series = 2 * np.pi * t + np.sum(
        4 * (sweep - np.pi) / ((2 * m - 1) ** 2 * np.pi**2) * (1 - np.cos(2 * np.pi * (2 * m - 1) * t))
    )
    assert buehler_clock(np.array([t]), sweep)[0][0] == pytest.approx(series, rel=1e-12)


def test_spine_stiffness_and_damping_per_joint_and_axis_through_the_spec():
    stiff = {"front_pitch": 5.0, "front_roll": 10.0, "rear_pitch": 40.0}
    robot = Xjus(GAIT, spine_stiffness=stiff, spine_damping=0.3)
    m = robot.model
    for joint in constants.SPINE_JOINTS:
        expected = stiff.get(joint, constants.SPINE_DESIGN_STIFFNESS)
        assert m.jnt_stiffness[m.joint(joint).id] == pytest.approx(expected)
        assert m.dof_damping[m.jnt_dofadr[m.joint(joint).id]] == pytest.approx(0.3)
    assert constants.SPINE_DESIGN_STIFFNESS == pytest.approx(19.4, abs=0.05)


def test_a_rigid_spine_has_no_spine_joints_and_the_model_sizes_are_pinned():
    compliant, rigid = Xjus(GAIT), Xjus(GAIT, spine=RIGID)
    m, r = compliant.model, rigid.model
    assert (m.nq, m.nv, m.nu) == (23, 22, 12)
    assert (r.nq, r.nv, r.nu) == (19, 18, 12)
    for joint in constants.SPINE_JOINTS:
        assert mujoco.mj_name2id(r, mujoco.mjtObj.mjOBJ_JOINT, joint) == -1
    assert compliant.facts.extra["spine"] == COMPLIANT and rigid.facts.extra["spine"] == RIGID
    assert "spine_stiffness_scale" in compliant.parameters and "spine_stiffness_scale" not in rigid.parameters


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"spine": "floppy"}, "spine"),
        ({"spine_stiffness": -1.0}, "spine_stiffness"),
        ({"spine_stiffness": {"front_yaw": 3.0}}, "front_yaw"),
        ({"spine_damping": float("nan")}, "spine_damping"),
        ({"spine": RIGID, "spine_stiffness": 10.0}, "spine_stiffness"),
        ({"control_freq": 100.0}, "control_freq"),
        ({"current_limit": 0.0}, "current_limit"),
        ({"current_limit": True}, "current_limit must be a number, got True"),
        ({"current_limit": "1.08"}, "current_limit must be a number, got '1.08'"),
        ({"spine_stiffness": 1e12}, r"spine_stiffness\['front_pitch'\] must be <= 971 N m/rad"),
        ({"spine_stiffness": {"rear_roll": 2000.0}}, r"spine_stiffness\['rear_roll'\] must be <= 971"),
        ({"battery_voltage": -22.2}, "battery_voltage"),
        ({"starts": [[0.0, 1.0, 2.0]]}, "starts"),
    ],
)
def test_bad_robot_arguments_are_refused_in_one_line(kwargs, message):
    with pytest.raises(ValueError, match=message) as error:
        Xjus(GAIT, **kwargs)
    assert "\n" not in str(error.value)


def test_current_limit_clamps_each_motor_at_its_rating():
    """The report's 1.08 A continuous rating as a driver limit: the blocked hip's torque stops at 1.08 A x eta N Kt."""
    limit = constants.MOTOR_CONTINUOUS_CURRENT
    robot = Xjus(DUTY, spine=RIGID, imu_noise=None, current_limit=limit,
                 spec_edits=[facts.clamp(quat=facts.HIPS_VERTICAL, lock_hips=True)])  # fmt: skip
    robot.reset(ONE, RNG, options={"leg_angles": np.zeros(6)})
    facts.hold(robot, 1.0, 0.1)
    np.testing.assert_allclose(robot.hip_torques()[0], limit * robot.constants.torque_per_amp, rtol=1e-6)
    readings = robot.read(RNG)
    row = dict(zip(robot.telemetry_channels, robot.telemetry(readings)[0], strict=True))
    assert row["current_FL"] == pytest.approx(limit, rel=1e-6)
    # the driver cuts its duty to hold the current: at rest d Vs = i (Ra + d^2 Ramp), far below full duty
    c = robot.constants
    duty = np.roots([limit * c.amplifier_resistance, -c.supply_voltage, limit * c.motor_resistance])
    duty = duty[np.abs(duty) <= 1][0]
    # (the locked hips give a little: their speed is not quite zero)
    assert readings["power"][0] == pytest.approx(6 * duty * c.supply_voltage * limit, rel=2e-3)


def test_battery_power_at_stall_is_the_seed_formula_and_braking_returns_nothing():
    robot = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[facts.clamp(quat=facts.HIPS_VERTICAL, lock_hips=True)])
    robot.reset(ONE, RNG, options={"leg_angles": np.zeros(6)})
    facts.hold(robot, 0.5, 0.05)
    c = robot.constants
    stall = 0.5 * c.supply_voltage * c.current(np.float64(0.5), np.float64(0.0))
    assert robot.read(RNG)["power"][0] == pytest.approx(6 * stall, rel=1e-4)  # the locked hips give a little
    free = Xjus(DUTY, spine=RIGID, imu_noise=None, spec_edits=[facts.clamp(quat=facts.HIPS_VERTICAL)])
    free.reset(ONE, RNG, options={"leg_angles": np.zeros(6)})
    facts.hold(free, 1.0, 0.5)
    facts.hold(free, -0.05, free.control_dt)  # reversed duty on spinning legs: the motors brake
    assert (free.hip_torques()[0] < 0).all()
    assert free.read(RNG)["power"][0] > 0, "plugging draws from the battery (d and i both negative)"
    facts.hold(free, 0.0, 0.2)
    facts.hold(free, 0.0, free.control_dt)
    assert free.read(RNG)["power"][0] == pytest.approx(0.0, abs=1e-12), "a shorted motor brakes for free"
