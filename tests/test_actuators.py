"""The shared actuator models against their formulas and datasheets, measured on the bench rigs."""

import itertools

import mujoco
import numpy as np
import pytest

from envs.actuators import dcmotor
from envs.actuators.motor import MotorConstants
from envs.actuators.servo import DATASHEET, ServoConstants
from envs.bench.robot import JOINT, MotorRig, ServoRig
from envs.velociroach.robot import VelociRoach

RNG = [np.random.default_rng(0)]
ONE = np.array([0])


def block_shaft(spec: mujoco.MjSpec) -> None:
    joint = spec.joint(JOINT)
    joint.range = [-1e-4, 1e-4]
    joint.limited = mujoco.mjtLimited.mjLIMITED_TRUE


# --- the xJüs report's gearmotor ---------------------------------------------------------------------------------
def test_motor_torque_equals_the_seed_formula_over_a_grid():
    """tau = eta N Kt (d Vs - Ks w) / (Ra + d^2 Ramp), exactly, for held d and any shaft speed."""
    rig = MotorRig()
    m, d = rig.model, rig.data
    c = rig.motor.constants
    for duty, speed in itertools.product(np.linspace(-1, 1, 9), np.linspace(-40, 40, 9)):
        rig.motor.set_duty(rig.sim.ctrl, np.array([[duty]]))
        d.ctrl[:] = rig.sim.ctrl[0, 0]
        d.qvel[0] = speed
        mujoco.mj_forward(m, d)
        expected = (
            c.efficiency * c.gear_ratio * c.torque_constant * (duty * c.supply_voltage - c.speed_constant * speed)
        )
        expected /= c.motor_resistance + duty**2 * c.amplifier_resistance
        assert d.qfrc_actuator[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert c.torque(duty, speed) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_motor_duty_is_the_clipped_voltage_ratio_and_out_of_range_duty_clips():
    c = MotorConstants()
    assert c.duty(np.array([-50.0, 11.1, 50.0])) == pytest.approx([-1.0, 0.5, 1.0])
    rig = MotorRig()
    rig.motor.set_duty(rig.sim.ctrl, np.array([[3.0]]))
    a, b = c.coefficients(np.array(1.0))
    assert rig.sim.ctrl[0, 0, rig.motor.drive_adr[0]] == pytest.approx(float(a))
    assert rig.sim.ctrl[0, 0, rig.motor.emf_adr[0]] == pytest.approx(float(b))


def test_motor_stall_torque_and_no_load_speed_in_simulation():
    """Table 1 gives 2.17 N m at the shaft at d = 1 and rest, and Vs / Ks = 29.6 rad/s without load."""
    assert MotorConstants().stall_torque == pytest.approx(2.17, abs=0.005)
    assert MotorConstants().no_load_speed == pytest.approx(29.6, abs=0.05)
    blocked = MotorRig(spec_edits=[block_shaft])
    blocked.reset(ONE, RNG)
    for _ in range(20):
        blocked.command(np.array([[1.0]]))
        blocked.step()
    torque = blocked.telemetry(blocked.read(RNG))[0][list(blocked.telemetry_channels).index("torque")]
    assert torque == pytest.approx(2.17, abs=0.005)
    free = MotorRig(load_inertia=1e-4)
    free.reset(ONE, RNG)
    for _ in range(100):
        free.command(np.array([[1.0]]))
        free.step()
    assert free.read(RNG)["senses"][0, 1] == pytest.approx(29.6, rel=1e-3)


def test_motor_battery_current_and_power():
    c = MotorConstants()
    d, w = 0.6, 10.0
    i = (d * c.supply_voltage - c.speed_constant * w) / (c.motor_resistance + d * d * c.amplifier_resistance)
    assert c.current(d, w) == pytest.approx(i)
    assert c.battery_power(d, w) == pytest.approx(c.supply_voltage * d * i)
    # the report's constants cap the efficiency at eta N Kt / Ks
    assert c.torque_per_amp / c.speed_constant == pytest.approx(0.37, abs=0.005)


def test_motor_constants_are_checked():
    with pytest.raises(ValueError, match="supply_voltage"):
        MotorConstants(supply_voltage=float("inf"))
    with pytest.raises(ValueError, match="efficiency"):
        MotorConstants(efficiency=1.5)


# --- the AX-12 servo -------------------------------------------------------------------------------------------
def servo_speed(volts: float) -> float:
    """Peak shaft speed of a free servo on a full-range move, rad/s."""
    rig = ServoRig(constants=ServoConstants(supply_voltage=volts), load_inertia=1e-6)
    rig.reset(ONE, RNG, options={"angle": rig.servo.constants.angle(0.0)})
    speeds = []
    for _ in range(60):
        rig.command(np.array([[1023.0]]))
        rig.step()
        speeds.append(rig.read(RNG)["senses"][0, 1])
    return max(speeds)


def servo_stall_torque(volts: float) -> float:
    rig = ServoRig(constants=ServoConstants(supply_voltage=volts), spec_edits=[block_shaft])
    rig.reset(ONE, RNG)
    for _ in range(10):
        rig.command(np.array([[1023.0]]))
        rig.step()
    return float(rig.telemetry(rig.read(RNG))[0][list(rig.telemetry_channels).index("torque")])


@pytest.mark.parametrize(("volts", "torque", "speed"), DATASHEET)
def test_servo_speed_and_torque_limits_match_the_datasheet_within_5_percent(volts, torque, speed):
    """They come out of the motor and the supply (no clamps): [ax12-manual], AX-12 at 7 V and 10 V."""
    assert servo_stall_torque(volts) == pytest.approx(torque, rel=0.05)
    assert servo_speed(volts) == pytest.approx(speed, rel=0.05)


def test_servo_goal_counts_map_onto_300_degrees_and_report_whole_counts():
    c = ServoConstants()
    assert c.angle(512) == 0.0
    assert np.degrees(c.angle(1023) - c.angle(0)) == pytest.approx(300.0)
    rig = ServoRig()
    rig.reset(ONE, RNG)
    for _ in range(50):
        rig.command(np.array([[700.0]]))
        rig.step()
    row = dict(zip(rig.telemetry_channels, rig.telemetry(rig.read(RNG))[0], strict=True))
    assert row["present_position"] == round(row["present_position"])
    assert abs(row["present_position"] - 700) <= 1, "a free servo settles on its goal"
    assert abs(c.counts_of(row["angle"]) - 700) < 1.0


def test_servo_compliance_slope_sets_the_stiffness():
    """Held against a load torque, the softer slope (larger) gives way further, in proportion."""

    def deflection(slope: float) -> float:
        rig = ServoRig(constants=ServoConstants(compliance_slope=slope))
        rig.reset(ONE, RNG)
        rig.data.qfrc_applied[0] = 0.2  # N m, within the holding torque
        for _ in range(100):
            rig.command(np.array([[512.0]]))
            rig.step()
        return float(rig.read(RNG)["senses"][0, 0])

    soft, stiff = deflection(64), deflection(16)
    assert soft > stiff > 0
    assert soft / stiff == pytest.approx(4.0, rel=0.05)


# --- the dcmotor layer, shared with the VelociRoACH ------------------------------------------------------------
def test_dcmotor_parameter_slots_match_the_compiler():
    xml = """<mujoco><worldbody><body><joint name="j" axis="0 1 0"/><geom size=".01"/></body></worldbody>
    <actuator><dcmotor joint="j" resistance="3" motorconst="0.01" input="pos vel" controller="1 2 3 4 5 6"/>
    <dcmotor joint="j" resistance="3" motorconst="0.01"/><dcmotor joint="j" resistance="3" motorconst="0.01"
    input="pos"/></actuator></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    g = m.actuator_gainprm[0]
    assert (g[dcmotor.GAIN_R], g[dcmotor.GAIN_K]) == (3, 0.01)
    assert [g[dcmotor.GAIN_KP], g[dcmotor.GAIN_KI], g[dcmotor.GAIN_KD], g[dcmotor.GAIN_VMAX]] == [1, 2, 3, 6]
    assert m.actuator_dynprm[0, dcmotor.DYN_SLEW] == 4 and m.actuator_dynprm[0, dcmotor.DYN_IMAX] == 5
    assert list(m.actuator_ctrlspec) == [
        dcmotor.INPUT_POS | dcmotor.INPUT_VEL,
        dcmotor.INPUT_VOLTAGE,
        dcmotor.INPUT_POS,
    ]


def test_the_velociroach_motors_go_through_the_shared_layer():
    for mode in ("gait", "duty"):
        robot = VelociRoach(mode)
        assert isinstance(robot.motors, dcmotor.DCMotors)
        assert robot.motors.mode == ("pid" if mode == "gait" else "voltage")


def test_cancelled_back_emf_compensation_is_a_plain_voltage_amplifier():
    """The servo's amplifier: terminal voltage = supply x clip(kp x error), whatever the shaft speed."""
    rig = ServoRig()
    m, d = rig.model, rig.data
    c, motors = rig.servo.constants, rig.servo.motors
    for goal, speed in itertools.product((520.0, 530.0, 900.0), (-3.0, 0.0, 3.0)):
        rig.servo.set_goal(rig.sim.ctrl, np.array([[goal]]))
        d.ctrl[:] = rig.sim.ctrl[0, 0]
        d.qpos[0], d.qvel[0] = 0.0, speed
        mujoco.mj_forward(m, d)
        torque, motor_speed = d.actuator_force[0], d.actuator_velocity[0]
        volts = motors.terminal_voltage(np.array([torque]), np.array([motor_speed]))[0]
        duty = np.clip((goal - c.center) / c.compliance_slope, -1, 1)
        assert volts == pytest.approx(duty * c.supply_voltage, rel=1e-9)


@pytest.mark.parametrize("velocity_setpoint", [True, False])
def test_a_voltage_mode_pid_with_a_derivative_and_feed_forward_is_the_firmwares_duty_law(velocity_setpoint):
    """A firmware's PWM PID, ``v = supply x clip(kp e + kd (v_cmd - w) + ff)``, whatever the shaft speed: MuJoCo's
    back-EMF compensation cancelled through the derivative gain and the feed-forward input."""
    xml = """<mujoco><worldbody><body><joint name="j" axis="0 1 0"/><geom size=".01" mass=".01"/></body></worldbody>
    <actuator><dcmotor name="m" joint="j" resistance="3.3" motorconst="0.00141" gear="7"/></actuator></mujoco>"""
    spec = mujoco.MjSpec.from_string(xml)
    pid = dcmotor.PIDGains(kp=1.2, ki=0.5, kd=0.03, feedforward=0.05, velocity_setpoint=velocity_setpoint,
                           compensate_back_emf=False, max_duty=0.9)  # fmt: skip
    motors = dcmotor.DCMotors(["m"], 3.7, pid)
    motors.configure(spec)
    m = spec.compile()
    d = mujoco.MjData(m)
    motors.bind(m)
    supply = np.array([3.7])
    ctrl = np.zeros((1, 1, m.nu))
    integral = (-0.2, 0.0, 0.3)  # rad s of integrated leg-angle error, as the firmware's integrator holds it
    for target, rate, angle, speed, area in itertools.product((0.0, 0.3), (0.0, 40.0), (-0.1, 0.2), (-30.0, 0.0, 50.0),
                                                              integral):  # fmt: skip
        motors.set_setpoints(ctrl, np.full((1, 1, 1), target), np.full((1, 1, 1), rate), supply)
        d.ctrl[:] = ctrl[0, 0]
        d.qpos[0], d.qvel[0] = angle, speed
        d.act[0] = 7 * area  # MuJoCo's integrator holds the motor shaft's angle error (gear 7)
        mujoco.mj_forward(m, d)
        volts = motors.terminal_voltage(np.array([[d.actuator_force[0]]]), np.array([[d.actuator_velocity[0]]]))
        command = rate if velocity_setpoint else 0.0
        duty = np.clip(1.2 * (target - angle) + 0.5 * area + 0.03 * (command - speed) + 0.05, -0.9, 0.9)
        assert volts[0, 0] == pytest.approx(duty * 3.7, rel=1e-9, abs=1e-12)
