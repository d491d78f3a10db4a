"""The VelociRoACH model against the numbers of its sources (shared/robots.md section 1, seed 000)."""

import mujoco
import numpy as np
import pytest

from envs.common.mujoco_utils import SensorHistory
from envs.velociroach import constants as C
from envs.velociroach import facts
from envs.velociroach.robot import DC_DYN_IMAX, DC_DYN_SLEW, DC_GAIN_PID, VelociRoach


@pytest.fixture(scope="module")
def robot() -> VelociRoach:
    return VelociRoach("gait", control_dt=0.02)


def test_total_mass_is_30_g(robot):
    assert robot.mass == pytest.approx(C.MASS, rel=0.05)


def test_length_is_10_cm(robot):
    assert facts.overall_length(robot) == pytest.approx(C.LENGTH, rel=0.05)


def test_centre_of_mass_height_standing():
    assert facts.standing_com_height() == pytest.approx(C.COM_HEIGHT, rel=0.05)


def test_relative_leg_stiffness_in_a_static_load_test():
    result = facts.relative_leg_stiffness()
    assert result["legs_in_stance"] == 3, "the robot stands on a tripod"
    assert result["k_rel"] == pytest.approx(C.RELATIVE_LEG_STIFFNESS, rel=0.10)
    assert result["max_relative_compression"] < 0.05, "the load test stays in the small-compression range"


def test_stance_legs_carry_about_0_1_n_each_standing():
    """Seed 000 Table 1: about 0.1 N per leg. On a tripod the lone middle leg carries half the weight by statics
    (it faces two legs across the body), the front and back legs a quarter each."""
    robot = VelociRoach("gait", control_dt=0.01)
    robot.reset()
    facts.hold(robot, 1.0)
    grf = dict(zip(C.LEGS, robot.ground_reaction_forces()[:, 2], strict=True))
    stance = [grf[leg] for leg in C.TRIPOD_A]
    assert np.mean(stance) == pytest.approx(C.GRF_PER_LEG, rel=0.05)
    assert all(0.5 * C.GRF_PER_LEG < f < 1.5 * C.GRF_PER_LEG for f in stance), grf
    assert all(abs(grf[leg]) < 1e-9 for leg in C.LEGS if leg not in C.TRIPOD_A), "the other tripod is in swing"


def test_leg_inertia_felt_by_the_crank(robot):
    assert facts.reflected_leg_inertia(robot) == pytest.approx(C.LEG_INERTIA, rel=0.10)


def test_motor_reaches_a_45_hz_stride_with_headroom_and_stalls_at_its_datasheet_torque(robot):
    bench = facts.motor_bench(duty=1.0)
    k, r, v = robot.motor_constant[0], robot.resistance[0], robot.battery_voltage
    assert bench["stall_torque"] == pytest.approx(robot.gear * k * v / r, rel=0.02)
    no_load = v / k / robot.gear / (2 * np.pi)
    assert C.MAX_STRIDE_FREQUENCY < bench["free_stride_hz"] < no_load


def test_model_sizes_are_pinned(robot):
    m = robot.model
    assert (m.nq, m.nv, m.nu, m.na, m.neq) == (29, 28, 4, 4, 14)
    duty = VelociRoach("duty", control_dt=0.001).model
    assert (duty.nq, duty.nv, duty.nu, duty.na) == (29, 28, 2, 0)


def test_dcmotor_parameter_slots_match_the_compiler():
    xml = """<mujoco><worldbody><body><joint name="j" axis="0 1 0"/><geom size=".01"/></body></worldbody>
    <actuator><dcmotor joint="j" resistance="3" motorconst="0.01" input="pos vel" controller="1 2 3 4 5 6"/>
    </actuator></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    np.testing.assert_array_equal(m.actuator_gainprm[0, DC_GAIN_PID], [1, 2, 3, 6])
    assert m.actuator_dynprm[0, DC_DYN_SLEW] == 4
    assert m.actuator_dynprm[0, DC_DYN_IMAX] == 5


def test_sensor_history_reads_every_substep_in_order():
    robot = VelociRoach("duty", control_dt=0.005)
    robot.reset()
    names = [C.SENSOR_MOTOR_TORQUE["left"], C.SENSOR_MOTOR_VEL["left"]]
    history = SensorHistory(robot.model, names, robot.n_substeps)
    for _ in range(3):
        robot.command_duty(np.array([0.7, -0.3]))
        robot.step()
    samples = history.read(robot.data)
    dt = robot.model.opt.timestep
    for i, name in enumerate(names):
        sid = robot.model.sensor(name).id
        for j in range(robot.n_substeps):
            t = robot.data.time - (robot.n_substeps - j) * dt
            expected = np.empty(1)
            value = mujoco.mj_readSensor(robot.model, robot.data, sid, t, expected, 0)
            expected = expected if value is None else value
            assert samples[j, i] == pytest.approx(expected[0], abs=1e-12)


def test_electrical_power_at_stall_is_v_squared_over_r():
    """Duty mode with the left crank blocked: no back-EMF, so the motor draws (d V)^2 / R."""

    def block(spec):
        spec.delete(spec.joint(C.ROOT_JOINT))
        spec.body(C.ROOT_BODY).pos[2] = 0.5
        crank = spec.joint(C.CRANK_JOINTS["left"])
        crank.range = [-1e-4, 1e-4]
        crank.limited = mujoco.mjtLimited.mjLIMITED_TRUE

    robot = VelociRoach("duty", control_dt=0.005, spec_edit=block)
    robot.reset()
    for _ in range(40):
        robot.command_duty(np.array([0.5, 0.0]))
        robot.step()
    r, vb = robot.resistance[0], robot.battery_voltage
    assert robot.electrical_power() == pytest.approx((0.5 * vb) ** 2 / r, rel=0.01)
    assert robot.duty()[0] == pytest.approx(0.5, abs=1e-3)


def test_braking_energy_is_not_returned_to_the_battery():
    """Duty 0 while the legs still spin: the shorted motor brakes, current flows backward, and the battery supplies
    nothing, so power is zero, not negative."""

    def clamp(spec):
        spec.delete(spec.joint(C.ROOT_JOINT))
        spec.body(C.ROOT_BODY).pos[2] = 0.5

    robot = VelociRoach("duty", control_dt=0.005, spec_edit=clamp)
    robot.reset()
    for _ in range(40):
        robot.command_duty(np.array([1.0, 0.0]))
        robot.step()
    robot.command_duty(np.array([0.0, 0.0]))
    robot.step()
    torque = robot.data.sensordata[robot.sensor_slice[C.SENSOR_MOTOR_TORQUE["left"]]][0]
    assert torque < 0, "the spinning motor brakes"
    assert robot.electrical_power() == pytest.approx(0.0, abs=1e-12)
