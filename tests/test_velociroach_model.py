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


def test_the_battery_voltage_balances_the_cells_power():
    """V = E - R I with P = V I: the larger root, E at no load or with no resistance, E/2 beyond what the cell can
    deliver (E^2 / 4R)."""
    from envs.actuators.battery import loaded_voltage

    e, r = 3.7, 0.2
    power = np.array([0.0, 1.5, 8.0, 20.0])
    v = loaded_voltage(e, r, power)
    np.testing.assert_allclose(v[:3] * (e - v[:3]) / r, power[:3], rtol=1e-12, atol=1e-15)
    assert v[0] == e and v[3] == e / 2 and np.all(np.diff(v) < 0)
    assert 3.6 < v[1] < 3.7, "1.5 W, the tripod's draw at 45 Hz, sags a 0.2-ohm cell by under 0.1 V"
    assert loaded_voltage(e, 0.0, 8.0) == e


@pytest.mark.parametrize("batched", [False, True])
def test_the_battery_sags_under_the_power_drawn_and_the_firmware_follows_it(batched):
    """Each control step holds the voltage the cell sags to under the power the motors drew over the step before:
    the battery sense reads it, and the firmware's torque-space gains carry it, per simulation; a reset starts from
    the open-circuit voltage (and its gains), and an ideal cell (0 ohm) never sags."""
    from envs.actuators.battery import loaded_voltage
    from envs.actuators.dcmotor import SUPPLY_SLOTS

    robot = VelociRoach("gait", num_sims=2, batched=True) if batched else VelociRoach("gait")
    n = robot.num_sims
    ids = np.arange(n)
    m = robot.motors
    compiled = robot.field("actuator_gainprm")[:, m.ids][:, :, SUPPLY_SLOTS].copy()
    np.testing.assert_allclose(m.supply_gains(np.full(n, robot.nominal_battery)), compiled, rtol=1e-14)
    robot.reset(ids, RNG * n)
    assert robot.nominal_battery_resistance == 0.2 and np.all(robot.battery == robot.nominal_battery)
    command = np.array([[45.0, 45.0, np.pi], [30.0, 30.0, np.pi]])[:n]
    drawn = np.zeros(n)
    for _ in range(15):
        robot.command(command)
        expected = loaded_voltage(robot.nominal_battery, 0.2, drawn)
        np.testing.assert_array_equal(robot.battery, expected)
        written = robot.field("actuator_gainprm")[:, m.ids][:, :, SUPPLY_SLOTS]
        np.testing.assert_array_equal(written, m.supply_gains(expected))
        robot.sim.step()
        readings = robot.read(RNG * n)
        np.testing.assert_array_equal(readings["senses"][:, 14], expected)
        drawn = readings["power"]
    sag = robot.nominal_battery - robot.battery
    assert np.all((sag > 0.02) & (sag < 0.3)), sag
    robot.reset(ids, RNG * n)
    assert np.all(robot.battery == robot.nominal_battery)
    np.testing.assert_array_equal(robot.field("actuator_gainprm")[:, m.ids][:, :, SUPPLY_SLOTS],
                                  m.supply_gains(robot.battery))  # fmt: skip
    ideal = VelociRoach("gait", battery_resistance=0.0)
    ideal.reset(np.arange(1), RNG)
    for _ in range(5):
        ideal.command(np.array([[45.0, 45.0, np.pi]]))
        ideal.sim.step()
        ideal.read(RNG)
    assert ideal.battery[0] == ideal.nominal_battery


def test_a_sagged_battery_lets_the_legs_lag_their_clock_more_at_45_hz_only():
    """At 45 Hz the tripod draws about 1.5 W, which sags a 0.2-ohm cell by under 0.1 V: the legs lag the firmware's
    clock a little more than on an ideal cell; at 10 Hz (0.2 W) hardly at all."""
    import gymnasium as gym

    import envs  # noqa: F401

    def lag(resistance: float, hz: float) -> float:
        env = gym.make("skitter/RoachWalk-v4", battery_resistance=resistance, sensor_noise=False)
        env.reset(seed=0)
        robot = env.unwrapped.robot
        action = robot.mode.to_action(np.array([hz, hz, np.pi]))
        lags = []
        for _ in range(50):
            env.step(action)
            lags.append(np.mean(robot.clock[0] - robot.leg_angles()[0]))
        return float(np.degrees(np.mean(lags[25:])))

    fast, slow = lag(0.2, 45.0) - lag(0.0, 45.0), lag(0.2, 10.0) - lag(0.0, 10.0)
    assert 0.3 < fast < 6.0 and abs(slow) < 0.1, (fast, slow)
