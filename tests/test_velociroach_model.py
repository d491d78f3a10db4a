"""The VelociRoACH model against the numbers of its sources ([roach-sim], [haldane2013]; docs/references.md)."""

import mujoco
import numpy as np
import pytest

from envs.velociroach import constants, facts
from envs.velociroach.robot import VelociRoach

RNG = [np.random.default_rng(0)]
ONE = np.array([0])


@pytest.fixture(scope="module")
def robot() -> VelociRoach:
    return VelociRoach("gait")


def test_total_mass_is_30_g(robot):
    assert robot.facts.mass == pytest.approx(constants.MASS, rel=0.05)


def test_length_is_10_cm(robot):
    assert facts.overall_length(robot) == pytest.approx(constants.LENGTH, rel=0.05)


def test_centre_of_mass_height_standing():
    assert facts.standing_com_height() == pytest.approx(constants.COM_HEIGHT, rel=0.05)


def test_relative_leg_stiffness_in_a_static_load_test():
    result = facts.relative_leg_stiffness()
    assert result["legs_in_stance"] == 3, "the robot stands on a tripod"
    assert result["k_rel"] == pytest.approx(constants.RELATIVE_LEG_STIFFNESS, rel=0.10)
    assert result["max_relative_compression"] < 0.05, "the load test stays in the small-compression range"


def test_stance_legs_carry_about_0_1_n_each_standing():
    """[roach-sim, Table 1]: about 0.1 N per leg. On a tripod the lone middle leg carries half the weight by statics
    (it faces two legs across the body), the front and back legs a quarter each."""
    robot = VelociRoach("gait", control_freq=100.0)
    robot.reset(ONE, RNG)
    facts.hold(robot, 1.0)
    grf = dict(zip(constants.LEGS, robot.ground_reaction_forces()[0, :, 2], strict=True))
    stance = [grf[leg] for leg in constants.TRIPOD_A]
    assert np.mean(stance) == pytest.approx(constants.GRF_PER_LEG, rel=0.05)
    assert all(0.5 * constants.GRF_PER_LEG < f < 1.5 * constants.GRF_PER_LEG for f in stance), grf
    assert all(abs(grf[leg]) < 1e-9 for leg in constants.LEGS if leg not in constants.TRIPOD_A), (
        "the other tripod is in swing"
    )


def test_leg_inertia_felt_by_the_crank(robot):
    assert facts.reflected_leg_inertia(robot) == pytest.approx(constants.LEG_INERTIA, rel=0.10)


def test_motor_reaches_a_45_hz_stride_with_headroom_and_stalls_at_its_datasheet_torque(robot):
    bench = facts.motor_bench(duty=1.0)
    k, r, v = robot.motors.motor_constant[0, 0], robot.motors.resistance[0, 0], robot.nominal_battery
    assert bench["stall_torque"] == pytest.approx(robot.gear * k * v / r, rel=0.02)
    no_load = v / k / robot.gear / (2 * np.pi)
    assert constants.MAX_STRIDE_FREQUENCY < bench["free_stride_hz"] < no_load


def test_model_sizes_are_pinned(robot):
    m = robot.model
    assert (m.nq, m.nv, m.nu, m.na, m.neq) == (29, 28, 6, 2, 14)  # gait: pos, vel, ff per motor
    duty = VelociRoach("duty").model
    assert (duty.nq, duty.nv, duty.nu, duty.na) == (29, 28, 2, 0)


def test_electrical_power_at_stall_is_v_squared_over_r():
    """Duty mode with the left crank blocked: no back-EMF, so the motor draws (d V)^2 / R."""

    def block(spec):
        spec.delete(spec.joint(constants.ROOT_JOINT))
        spec.body(constants.ROOT_BODY).pos[2] = 0.5
        crank = spec.joint(constants.CRANK_JOINTS["left"])
        crank.range = [-1e-4, 1e-4]
        crank.limited = mujoco.mjtLimited.mjLIMITED_TRUE

    robot = VelociRoach("duty", control_freq=200.0, spec_edits=[block])
    robot.reset(ONE, RNG)
    for _ in range(40):
        robot.command(np.array([[0.5, 0.0]]))
        robot.step()
    r, vb = robot.motors.resistance[0, 0], robot.nominal_battery
    readings = robot.read(RNG)
    assert readings["power"][0] == pytest.approx((0.5 * vb) ** 2 / r, rel=0.01)
    row = dict(zip(robot.telemetry_channels, robot.telemetry(readings)[0], strict=True))
    assert row["duty_left"] == pytest.approx(0.5, abs=1e-3)


def test_braking_energy_is_not_returned_to_the_battery():
    """Duty 0 while the legs still spin: the shorted motor brakes, current flows backward, and the battery supplies
    nothing, so power is zero, not negative."""

    def clamp(spec):
        spec.delete(spec.joint(constants.ROOT_JOINT))
        spec.body(constants.ROOT_BODY).pos[2] = 0.5

    robot = VelociRoach("duty", control_freq=200.0, spec_edits=[clamp])
    robot.reset(ONE, RNG)
    for _ in range(40):
        robot.command(np.array([[1.0, 0.0]]))
        robot.step()
    robot.command(np.array([[0.0, 0.0]]))
    robot.step()
    torque = robot.sensor(constants.SENSOR_MOTOR_TORQUE["left"])[0, 0]
    assert torque < 0, "the spinning motor brakes"
    assert robot.read(RNG)["power"][0] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("batched", [False, True])
def test_the_firmwares_gains_follow_the_battery_and_the_motor_per_simulation(batched):
    """The voltage-mode PID's motor-shaft gains are the firmware's duty gains times battery x K / (R gear), and its
    derivative gain also holds the K^2/R that cancels MuJoCo's back-EMF compensation: per simulation, after
    randomized parameters, and back at nominal."""
    from envs.actuators.dcmotor import GAIN_KD, GAIN_KI, GAIN_KP
    from envs.velociroach.robot import FIRMWARE_PID

    robot = VelociRoach("gait", num_sims=2 if batched else 1, batched=batched)
    robot.reset(np.arange(robot.num_sims), RNG * robot.num_sims)
    m = robot.motors
    r0, k0 = float(m.resistance[0, 0]), float(m.motor_constant[0, 0])
    changed = {"battery_voltage": 3.2, "motor_constant": 1.3 * k0, "motor_resistance": 0.8 * r0}
    last = robot.num_sims - 1
    for values in (changed, {}):
        robot.set_parameters(np.array([last]), values)
        vb = values.get("battery_voltage", robot.nominal_battery)
        k, r = values.get("motor_constant", k0), values.get("motor_resistance", r0)
        gains = robot.field("actuator_gainprm")[last][m.ids]
        to_torque = vb * k / (r * m.gear)
        np.testing.assert_allclose(gains[:, GAIN_KP], FIRMWARE_PID.kp * to_torque, rtol=1e-12)
        np.testing.assert_allclose(gains[:, GAIN_KI], FIRMWARE_PID.ki * to_torque, rtol=1e-12)
        np.testing.assert_allclose(gains[:, GAIN_KD], FIRMWARE_PID.kd * to_torque + k * k / r, rtol=1e-12)
        if batched:  # the other simulation keeps the nominal gains
            nominal = robot.field("actuator_gainprm")[0][m.ids, GAIN_KD]
            np.testing.assert_allclose(nominal, m.derivative_gain(robot.nominal_battery, r0, k0, m.gear), rtol=1e-12)


def test_the_parameter_map_alone_writes_the_firmwares_derivative_gain():
    """The D gain is no product of battery, R and K, so it is a derived entry of the parameter map: applying the map
    to a copy of the compiled model (as a replay would) writes it, with no robot hook after."""
    import copy

    from envs.actuators.dcmotor import GAIN_KD

    robot = VelociRoach("gait")
    m = robot.motors
    r0, k0 = float(m.resistance[0, 0]), float(m.motor_constant[0, 0])
    values = {"battery_voltage": 3.3, "motor_constant": 1.2 * k0, "motor_resistance": 1.5 * r0}
    model = copy.copy(robot.model)
    robot.parameters.apply(lambda name: getattr(model, name), values)
    expected = m.derivative_gain(3.3, 1.5 * r0, 1.2 * k0, m.gear)
    np.testing.assert_allclose(model.actuator_gainprm[m.ids, GAIN_KD], expected, rtol=1e-12)
    assert robot.model.actuator_gainprm[m.ids[0], GAIN_KD] != model.actuator_gainprm[m.ids[0], GAIN_KD]
