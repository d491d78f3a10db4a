"""Calibrated envs, every robot: ``gym.make(id, calibration=PATH)`` adds a calibration file's effects to the nominal
model (which stays as it was), batched envs take the same file, bad files are refused with the file, field and value
named, and ``evaluate.py --calibration`` runs the calibrated model."""

from __future__ import annotations

import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import envs  # noqa: F401 (registers the ids)
import evaluate
from envs.actuators.dcmotor import GAIN_K, GAIN_KP, GAIN_VMAX
from envs.bioloid import constants as BIOLOID
from envs.velociroach import constants
from envs.xjus import constants as XJUS

EFFECTS = {
    "coulomb_friction_left": {"torque": 0.004},
    "viscous_friction_right": {"damping": 3e-5},
    "torque_constant_right": {"scale": 2.0},
    "supply_voltage": {"scale": 0.9},
    "delay": {"seconds": 0.003},
    "mass": {"scale": 1.2},
}
XJUS_EFFECTS = {
    "coulomb_friction_left": {"torque": 0.1},
    "viscous_friction_right": {"damping": 0.02},
    "torque_constant": {"scale": 1.2},
    "supply_voltage": {"scale": 0.9},
    "delay": {"seconds": 0.01},
    "backlash": {"gap": 0.05},
    "deadband": {"duty": 0.05},
    "mass": {"scale": 1.1},
}
BIOLOID_EFFECTS = {
    "coulomb_friction_left": {"torque": 0.05},
    "viscous_friction_right": {"damping": 0.02},
    "servo_gain": {"scale": 0.5},
    "supply_voltage": {"scale": 0.9},
    "delay": {"seconds": 0.01},
    "backlash": {"gap": 0.02},
    "mass": {"scale": 1.1},
    "foot_friction": {"mu": 0.5},
}


def _write(path, effects=EFFECTS, robot="velociroach", **extra):
    path.write_text(json.dumps({"format": "skitter calibration", "version": 1, "robot": robot, "effects": effects,
                                **extra}))  # fmt: skip
    return path


def test_calibration_adds_its_effects_and_leaves_the_nominal_model(tmp_path):
    path = _write(tmp_path / "cal.json")
    before = path.read_bytes()
    nominal = gym.make("skitter/RoachWalk-v4").unwrapped.robot
    robot = gym.make("skitter/RoachWalk-v4", calibration=str(path)).unwrapped.robot
    m0, m = nominal.model, robot.model
    left = m.joint(constants.CRANK_JOINTS["left"]).dofadr[0]
    right = m.joint(constants.CRANK_JOINTS["right"]).dofadr[0]
    assert m.dof_frictionloss[left] == pytest.approx(m0.dof_frictionloss[left] + 0.004)
    assert m.dof_damping[right] == pytest.approx(m0.dof_damping[right] + 3e-5)
    a_right, a_left = (m.actuator(constants.MOTORS[s]).id for s in ("right", "left"))
    assert m.actuator_gainprm[a_right, GAIN_K] == pytest.approx(2 * m0.actuator_gainprm[a_right, GAIN_K])
    assert m.actuator_gainprm[a_left, GAIN_K] == pytest.approx(m0.actuator_gainprm[a_left, GAIN_K])
    # the firmware's duty gains are the same; its torque-space gains carry the motor constant and the battery
    assert m.actuator_gainprm[a_right, GAIN_KP] == pytest.approx(2 * 0.9 * m0.actuator_gainprm[a_right, GAIN_KP])
    assert robot.nominal_battery == pytest.approx(0.9 * nominal.nominal_battery)
    np.testing.assert_allclose(m.actuator_delay, 0.003)
    chassis = m.body(constants.ROOT_BODY).id
    assert m.body_mass[chassis] == pytest.approx(1.2 * m0.body_mass[chassis])
    assert m.body_subtreemass[0] > m0.body_subtreemass[0]  # mj_setConst ran
    assert robot.model_hash != nominal.model_hash and robot.metadata()["calibration"] == str(path)
    # nothing written to the file; a new nominal env is still nominal
    assert path.read_bytes() == before
    again = gym.make("skitter/RoachWalk-v4").unwrapped.robot.model
    assert again.dof_frictionloss[left] == m0.dof_frictionloss[left] and again.actuator_delay[a_left] == 0


def test_a_roach_leg_phase_puts_its_legs_ahead_of_the_cranks_reading(tmp_path):
    """``leg_phase_<side>``: the legs of that side stand, at a reading of the crank, where the nominal model's stand
    that much further on; the reading (the crank joint the firmware and the telemetry read) starts from the clock,
    the linkage's equalities hold at the reset, and the other side is unchanged."""
    offset = 1.0
    path = _write(tmp_path / "cal.json", {"leg_phase_left": {"offset": offset}})
    nominal = gym.make("skitter/RoachWalk-v4").unwrapped
    shifted = gym.make("skitter/RoachWalk-v4", calibration=str(path)).unwrapped
    for env in (nominal, shifted):
        env.reset(seed=0, options={"crank_left": 0.3, "phase": np.pi})
    crank = shifted.robot.model.joint(constants.CRANK_JOINTS["left"]).qposadr[0]
    assert shifted.robot.model.qpos0[crank] == pytest.approx(-offset)
    assert shifted.robot.leg_angles()[0, 0] == pytest.approx(0.3)  # the reading: the clock's start

    def legs(env, crank_left: float) -> np.ndarray:
        """Each leg's place in the chassis' frame, the cranks at (crank_left, crank_left - pi) by their readings."""
        robot = env.robot
        data = mujoco.MjData(robot.model)
        data.qpos[:] = robot.linkage_qpos(crank_left, crank_left - np.pi)
        mujoco.mj_kinematics(robot.model, data)
        chassis = robot.model.body(constants.ROOT_BODY).id
        rot = data.xmat[chassis].reshape(3, 3)
        return np.array([rot.T @ (data.xpos[robot.model.body(f"{leg}_leg").id] - data.xpos[chassis])
                         for leg in constants.LEGS])  # fmt: skip

    left = [i for i, leg in enumerate(constants.LEGS) if leg.endswith("L")]
    right = [i for i in range(len(constants.LEGS)) if i not in left]
    ahead = legs(shifted, 0.3)
    np.testing.assert_allclose(ahead[left], legs(nominal, 0.3 + offset)[left], atol=1e-9)
    np.testing.assert_allclose(ahead[right], legs(nominal, 0.3)[right], atol=1e-9)
    assert np.abs(ahead[left] - legs(nominal, 0.3)[left]).max() > 1e-3, "the legs moved"
    data = shifted.robot.sim.get_data(0)
    mujoco.mj_forward(shifted.robot.model, data)
    rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert np.abs(data.efc_pos[rows]).max() < 1e-6, "the linkage's equalities hold at the reset"


def test_a_roach_periodic_load_is_the_torque_its_coefficients_give(tmp_path):
    """``periodic_load_<side>``: at every reading q of that crank (a leg phase moving its reference), the passive
    torque reaching it is sin1 sin q + cos1 cos q + sin2 sin 2q + cos2 cos 2q, the second harmonic's through the
    joint geared 2:1 to the crank; the reset puts that joint where its equality holds it; the other crank feels
    nothing, and a setting without the effect compiles the nominal model's sizes."""
    coef = {"sin1": 1e-3, "cos1": 2e-3, "sin2": 5e-4, "cos2": -1e-3}
    path = _write(tmp_path / "cal.json", {"periodic_load_left": coef, "leg_phase_left": {"offset": 0.7}})
    env = gym.make("skitter/RoachWalk-v4", calibration=str(path)).unwrapped
    nominal = gym.make("skitter/RoachWalk-v4").unwrapped.robot.model
    m = env.robot.model
    assert m.nq == nominal.nq + 1 and m.ntendon == nominal.ntendon + 2
    crank = {s: m.joint(constants.CRANK_JOINTS[s]) for s in constants.SIDES}
    geared = m.joint(f"{constants.CRANK_JOINTS['left']}_h2").dofadr[0]
    data = mujoco.MjData(m)
    for q in np.linspace(-3.0, 3.0, 9):
        data.qpos[:] = env.robot.linkage_qpos(q, q + 1.0)
        mujoco.mj_forward(m, data)
        torque = data.qfrc_passive[crank["left"].dofadr[0]] + 2.0 * data.qfrc_passive[geared]
        want = sum(coef[f"sin{h}"] * np.sin(h * q) + coef[f"cos{h}"] * np.cos(h * q) for h in (1, 2))
        assert torque == pytest.approx(want, abs=1e-12)
        assert data.qfrc_passive[crank["right"].dofadr[0]] == 0.0
    env.reset(seed=0)
    data = env.robot.sim.get_data(0)
    mujoco.mj_forward(m, data)
    rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert np.abs(data.efc_pos[rows]).max() < 1e-6, "the geared joint starts where its equality holds it"
    zero = _write(tmp_path / "zero.json", {"periodic_load_left": dict.fromkeys(coef, 0.0)})
    assert gym.make("skitter/RoachWalk-v4", calibration=str(zero)).unwrapped.robot.model.nq == nominal.nq


def test_calibrated_xjus_adds_its_effects_and_leaves_the_nominal_model(tmp_path):
    path = _write(tmp_path / "cal.json", XJUS_EFFECTS, "xjus")
    nominal = gym.make("skitter/XjusWalk-v1").unwrapped.robot
    robot = gym.make("skitter/XjusWalk-v1", calibration=str(path)).unwrapped.robot
    m0, m = nominal.model, robot.model
    for leg in XJUS.LEGS:
        dof0, dof = (x.joint(XJUS.HIP_JOINTS[leg]).dofadr[0] for x in (m0, m))
        left = leg in XJUS.LEFT_LEGS
        assert m.dof_frictionloss[dof] == pytest.approx(m0.dof_frictionloss[dof0] + (0.1 if left else 0.0))
        assert m.dof_damping[dof] == pytest.approx(m0.dof_damping[dof0] + (0.0 if left else 0.02))
        assert m.joint(f"{leg}_play").range[1] == pytest.approx(0.025)  # the gearbox's play: +-gap/2
    # the motor numerics the robot reads its motor arrays from: Kt and Ks scale together, the supply by 0.9
    assert robot.motors.torque_per_amp[0] == pytest.approx(1.2 * nominal.motors.torque_per_amp[0])
    assert robot.motors.speed_constant[0] == pytest.approx(1.2 * nominal.motors.speed_constant[0])
    assert robot.battery[0] == pytest.approx(0.9 * nominal.battery[0])
    drives = [a for a in range(m.nu) if m.actuator(a).name.endswith(("_drive", "_emf"))]
    np.testing.assert_allclose(m.actuator_delay[drives], 0.01)
    segments = sum(m0.body_mass[m0.body(name).id] for name in XJUS.SEGMENTS)  # plates, housings, motors, battery
    assert m.body_subtreemass[0] == pytest.approx(m0.body_subtreemass[0] + 0.1 * segments, rel=1e-9)
    # the driver's deadband on every duty the robot holds
    robot.hold_duty(np.full((1, 6), 0.04))
    assert np.all(robot.last_duty == 0.0)
    # the nominal model stays nominal
    again = gym.make("skitter/XjusWalk-v1").unwrapped.robot.model
    assert again.nq == m0.nq and again.dof_frictionloss.sum() == m0.dof_frictionloss.sum()


def test_calibrated_bioloid_adds_its_effects_and_leaves_the_nominal_model(tmp_path):
    path = _write(tmp_path / "cal.json", BIOLOID_EFFECTS, "bioloid")
    m0 = gym.make("skitter/BioloidWalk-v2").unwrapped.robot.model
    m = gym.make("skitter/BioloidWalk-v2", calibration=str(path)).unwrapped.robot.model
    for servo in BIOLOID.SERVOS:
        dof0, dof = (x.joint(servo).dofadr[0] for x in (m0, m))
        sides = {BIOLOID.LEG_SIDE[leg] for leg in BIOLOID.LEGS if servo in (f"{leg}_{k}" for k in (1, 2, 3))}
        left, right = "left" in sides, "right" in sides
        assert m.dof_frictionloss[dof] == pytest.approx(m0.dof_frictionloss[dof0] + (0.05 if left else 0.0))
        assert m.dof_damping[dof] == pytest.approx(m0.dof_damping[dof0] + (0.02 if right else 0.0))
        assert m.joint(f"{servo}_play").range[1] == pytest.approx(0.01)  # the gear train's play: +-gap/2
        a0, a = m0.actuator(f"{servo}_servo"), m.actuator(f"{servo}_servo")
        # the compliance slope halved (gain x 0.5) at 0.9 of the supply; the duty bound at 0.9 of the supply
        assert a.gainprm[GAIN_KP] == pytest.approx(0.5 * 0.9 * a0.gainprm[GAIN_KP])
        assert a.gainprm[GAIN_VMAX] == pytest.approx(0.9 * a0.gainprm[GAIN_VMAX])
        assert m.actuator_delay[a.id] == pytest.approx(0.01)
    body = m0.body(BIOLOID.ROOT_BODY).id
    assert m.body_subtreemass[0] == pytest.approx(m0.body_subtreemass[0] + 0.1 * m0.body_mass[body], rel=1e-9)
    assert m.geom_friction[m.geom(BIOLOID.FOOT_GEOM["F_L"]).id, 0] == pytest.approx(0.5)
    again = gym.make("skitter/BioloidWalk-v2").unwrapped.robot.model  # the nominal model stays nominal
    assert again.nq == m0.nq and again.dof_frictionloss.sum() == m0.dof_frictionloss.sum()


# one walk per robot: its env, its calibration file's robot and effects, a constant action (None: zeros), the reset
# seed and steps, and the info entry the effects move, by at least how much
MOTIONS = {
    # the right side is stronger: it turns
    "velociroach": ("skitter/RoachWalk-v4", EFFECTS, np.array([0.5, 0.5, 0.0], dtype=np.float32), 3, 50, "yaw", 0.05),
    "xjus": ("skitter/XjusWalk-v1", XJUS_EFFECTS, np.array([0.0, 0.3, 0.3]), 5, 60, "x_position", 1e-3),
    # a softer servo under a heavier body sags
    "bioloid": ("skitter/BioloidWalk-v2", BIOLOID_EFFECTS, None, 5, 50, "z_position", 1e-4),
}


@pytest.mark.parametrize("robot", list(MOTIONS))
def test_calibrated_env_changes_the_motion_and_batches_alike(tmp_path, robot):
    env_id, effects, action, seed, steps, key, moved = MOTIONS[robot]
    path = _write(tmp_path / "cal.json", effects, robot)

    def run(env):
        env.reset(seed=seed)
        act = np.zeros(env.action_space.shape[-1], dtype=np.float32) if action is None else action
        for _ in range(steps):
            *_, info = env.step(act if env.action_space.shape == act.shape else act[None])
        return info

    plain = run(gym.make(env_id))
    calibrated = run(gym.make(env_id, calibration=str(path)))
    assert abs(calibrated[key] - plain[key]) > moved
    vec = gym.make_vec(env_id, num_envs=1, vectorization_mode="vector_entry_point", calibration=str(path))
    batched = run(vec)
    assert batched[key][0] == pytest.approx(calibrated[key], abs=1e-9)


@pytest.mark.parametrize(
    "env_id, robot, change, needles",
    [
        ("skitter/RoachWalk-v4", "velociroach", {"robot": "servo"}, ["'robot'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"effects": {"warp_drive": {"level": 1.0}}}, ["'effects.warp_drive'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"effects": {"delay": {"seconds": 5.0}}}, ["'effects.delay.seconds'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"effects": {"delay": {"minutes": 0.0}}}, ["'effects.delay.minutes'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"version": 7}, ["'version'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"effects": {"delay": {"seconds": {"ci95": 0.01}}}},
         ["'effects.delay.seconds': no 'value'"]),
        ("skitter/RoachWalk-v4", "velociroach", {"version": "1"}, ["'version': '1' (a string, not a number)"]),
        ("skitter/XjusWalk-v1", "xjus", {"effects": {"viscous_friction_left": {"damping": 5.0}}},
         ["viscous_friction_left.damping", "outside its range"]),
        ("skitter/BioloidWalk-v2", "bioloid", {"effects": {"servo_gain": {"scale": 9.0}}},
         ["servo_gain.scale", "outside its range"]),
        ("skitter/RoachWalk-v4", "velociroach", {"effects": {"delay": {"seconds": {"value": 3.0, "unit": "ms"}}}},
         ["'effects.delay.seconds.unit': 'ms' is not the unit", "write the value in s"]),
        ("skitter/XjusWalk-v1", "xjus", {"effects": {"delay": {"seconds": {"value": 0.01, "unit": 7}}}},
         ["'effects.delay.seconds.unit': 7 is not a unit's name"]),
        ("skitter/XjusWalk-v1", "xjus", {"effects": {"delay": {"seconds": {"value": 0.01, "unti": "s"}}}},
         ["'effects.delay.seconds': unknown field 'unti' (did you mean 'unit'?)"]),
    ],
)  # fmt: skip
def test_bad_calibration_files_are_refused_naming_file_and_field(tmp_path, env_id, robot, change, needles):
    data = {"format": "skitter calibration", "version": 1, "robot": robot, "effects": EFFECTS, **change}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError) as info:
        gym.make(env_id, calibration=str(path))
    assert str(path) in str(info.value)
    assert all(needle in str(info.value) for needle in needles), (needles, str(info.value))


def test_a_calibration_file_may_name_the_roach_as_calibrate_py_does(tmp_path):
    from envs.common.calibration import read_calibration

    path = tmp_path / "roach.json"
    path.write_text(json.dumps({"format": "skitter calibration", "version": 1, "robot": "roach", "effects": EFFECTS}))
    assert read_calibration(path, "velociroach").robot == "velociroach"


def test_a_calibration_file_in_the_catalogs_units_is_taken_however_the_product_is_written(tmp_path):
    """A unit is compared blind to spacing, the product's sign and a ratio's spelling; a sensor's offset is in its
    channel's unit, whatever it is."""
    effects = {
        "viscous_friction_right": {"damping": {"value": 3e-5, "unit": "N\u00b7m\u00b7s/rad"}},
        "delay": {"seconds": {"value": 0.003, "unit": "s"}},
        "sensor_bias_bemf_left": {"offset": {"value": 0.01, "unit": "V"}},
        "mass": {"scale": {"value": 1.1, "unit": "dimensionless"}},
    }
    env = gym.make("skitter/RoachWalk-v4", calibration=str(_write(tmp_path / "units.json", effects)))
    assert env.unwrapped.robot.calibration.units["viscous_friction_right"]["damping"] == "N\u00b7m\u00b7s/rad"
    env.close()


def test_a_calibration_that_is_not_a_file_is_refused():
    with pytest.raises(ValueError, match="calibration must be the path of a calibration file, got 3"):
        gym.make("skitter/RoachWalk-v4", calibration=3)
    with pytest.raises(ValueError, match="no such calibration file"):
        gym.make("skitter/RoachWalk-v4", calibration="nowhere.json")


def test_evaluate_refuses_a_bad_calibration_before_writing(tmp_path, capsys):
    bad = _write(tmp_path / "bad.json", robot="motor", effects={"viscous_friction": {"damping": 1e-4}})
    out = tmp_path / "results"
    argv = ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "1", "--out", str(out),
            "--max-episode-steps", "5", "--calibration", str(bad)]  # fmt: skip
    assert evaluate.main(argv) == 2
    err = capsys.readouterr().err
    assert "--calibration" in err and str(bad) in err and "'robot'" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    with pytest.raises(SystemExit) as exit_info:
        evaluate.main([*argv[:-1], str(tmp_path / "missing.json")])
    assert exit_info.value.code == 2 and not out.exists()


def test_evaluate_runs_the_calibrated_model(tmp_path):
    path = _write(tmp_path / "cal.json")
    runs = {}
    for name, extra in (("nominal", []), ("calibrated", ["--calibration", str(path)])):
        out = tmp_path / name
        argv = ["--env", "skitter/RoachWalk-v4", "--policy", "tripod", "--episodes", "2", "--out", str(out),
                "--max-episode-steps", "100", *extra]  # fmt: skip
        assert evaluate.main(argv) == 0
        runs[name] = json.loads((out / "results.json").read_text())
    assert runs["calibrated"]["calibration"] == str(path) and runs["nominal"]["calibration"] is None
    drift = {k: r["policies"]["tripod"]["summary"]["heading_drift"]["mean"] for k, r in runs.items()}
    assert drift["calibrated"] != pytest.approx(drift["nominal"], abs=1e-3)


def test_calibration_delay_uses_mujocos_actuator_history(tmp_path):
    """The delay effect is MuJoCo's own actuator delay: a voltage step reaches the motor 3 ms late."""
    from envs.velociroach.robot import VelociRoach

    path = _write(tmp_path / "cal.json", effects={"delay": {"seconds": 0.003}})
    forces = {}
    for name, cal in (("nominal", None), ("delayed", str(path))):
        m = VelociRoach("duty", calibration=cal).model
        d = mujoco.MjData(m)
        a = m.actuator(constants.MOTORS["left"]).id
        d.ctrl[m.actuator_ctrladr[a]] = 3.0  # volts
        trace = []
        for _ in range(12):
            mujoco.mj_step(m, d)
            trace.append(abs(d.actuator_force[a]))
        forces[name] = np.array(trace)
    steps = round(0.003 / 0.0005)
    step = forces["nominal"][0]  # the voltage's torque at once (the rest is back-EMF of the body settling)
    assert step > 1e-4 and np.all(forces["delayed"][: steps - 1] < 1e-3 * step)
    assert forces["delayed"][steps + 1] > 0.5 * step


def test_a_calibrated_roach_keeps_its_sides_and_its_firmware_law_under_drawn_parameters(tmp_path):
    """A calibration that makes the right motor twice as strong: a drawn motor constant, resistance and battery scale
    both sides alike, so the right motor stays twice the left, and each side's torque-space gains stay the
    firmware's duty gains times battery x K / (R gear) (its derivative gain with the K^2/R that cancels MuJoCo's
    back-EMF compensation)."""
    from envs.actuators.dcmotor import GAIN_KD, GAIN_KI, GAIN_R
    from envs.velociroach.robot import FIRMWARE_PID

    robot = gym.make("skitter/RoachWalk-v4", calibration=str(_write(tmp_path / "cal.json"))).unwrapped.robot
    m = robot.model
    left, right = (m.actuator(constants.MOTORS[s]).id for s in ("left", "right"))
    k0 = float(m.actuator_gainprm[left, GAIN_K])
    ratio = m.actuator_gainprm[right, GAIN_K] / k0
    robot.set_parameters(np.array([0]), {"motor_constant": 1.25 * k0, "motor_resistance": 4.0, "battery_voltage": 3.3})
    g = m.actuator_gainprm
    assert g[right, GAIN_K] / g[left, GAIN_K] == pytest.approx(ratio, rel=1e-12) and g[left, GAIN_K] == 1.25 * k0
    assert g[left, GAIN_R] == g[right, GAIN_R] == 4.0
    for a in (left, right):
        k, r = g[a, GAIN_K], g[a, GAIN_R]
        to_torque = 3.3 * k / (r * m.actuator_gear[a, 0])
        assert g[a, GAIN_KP] == pytest.approx(FIRMWARE_PID.kp * to_torque, rel=1e-12)
        assert g[a, GAIN_KI] == pytest.approx(FIRMWARE_PID.ki * to_torque, rel=1e-12)
        assert g[a, GAIN_KD] == pytest.approx(FIRMWARE_PID.kd * to_torque + k * k / r, rel=1e-12)
        assert g[a, GAIN_VMAX] == pytest.approx(3.3 * FIRMWARE_PID.max_duty, rel=1e-12)
