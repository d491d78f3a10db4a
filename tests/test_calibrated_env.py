"""Calibrated envs: ``gym.make(id, calibration=PATH)`` adds a calibration file's effects to the nominal model (which
stays as it was), batched envs take the same file, bad files are refused with the file, field and value named, and
``evaluate.py --calibration`` runs the calibrated model."""

from __future__ import annotations

import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import envs  # noqa: F401 (registers the ids)
import evaluate
from envs.actuators.dcmotor import GAIN_K, GAIN_KP
from envs.velociroach import constants

EFFECTS = {
    "coulomb_friction_left": {"torque": 0.004},
    "viscous_friction_right": {"damping": 3e-5},
    "torque_constant_right": {"scale": 2.0},
    "supply_voltage": {"scale": 0.9},
    "delay": {"seconds": 0.003},
    "mass": {"scale": 1.2},
}


def _write(path, effects=EFFECTS, robot="velociroach", **extra):
    path.write_text(json.dumps({"format": "skitter calibration", "version": 1, "robot": robot, "effects": effects,
                                **extra}))  # fmt: skip
    return path


def test_calibration_adds_its_effects_and_leaves_the_nominal_model(tmp_path):
    path = _write(tmp_path / "cal.json")
    before = path.read_bytes()
    nominal = gym.make("skitter/RoachWalk-v1").unwrapped.robot
    robot = gym.make("skitter/RoachWalk-v1", calibration=str(path)).unwrapped.robot
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
    again = gym.make("skitter/RoachWalk-v1").unwrapped.robot.model
    assert again.dof_frictionloss[left] == m0.dof_frictionloss[left] and again.actuator_delay[a_left] == 0


def test_calibrated_env_changes_the_gait_and_batches_alike(tmp_path):
    path = _write(tmp_path / "cal.json")
    action = np.array([0.5, 0.5, 0.0], dtype=np.float32)

    def run(env, n=50):
        env.reset(seed=3)
        for _ in range(n):
            *_, info = env.step(action if env.action_space.shape == action.shape else np.tile(action, (1, 1)))
        return info

    plain = run(gym.make("skitter/RoachWalk-v1"))
    calibrated = run(gym.make("skitter/RoachWalk-v1", calibration=str(path)))
    assert abs(calibrated["yaw"] - plain["yaw"]) > 0.05  # the right side is stronger: it turns
    vec = gym.make_vec("skitter/RoachWalk-v1", num_envs=1, vectorization_mode="vector_entry_point",
                       calibration=str(path))  # fmt: skip
    batched = run(vec)
    assert batched["yaw"][0] == pytest.approx(calibrated["yaw"], abs=1e-9)


@pytest.mark.parametrize(
    "change, field",
    [
        ({"robot": "servo"}, "'robot'"),
        ({"effects": {"warp_drive": {"level": 1.0}}}, "'effects.warp_drive'"),
        ({"effects": {"delay": {"seconds": 5.0}}}, "'effects.delay.seconds'"),
        ({"effects": {"delay": {"minutes": 0.0}}}, "'effects.delay.minutes'"),
        ({"version": 7}, "'version'"),
    ],
)
def test_bad_calibration_files_are_refused_naming_file_and_field(tmp_path, change, field):
    data = {"format": "skitter calibration", "version": 1, "robot": "velociroach", "effects": EFFECTS, **change}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError) as info:
        gym.make("skitter/RoachWalk-v1", calibration=str(path))
    assert str(path) in str(info.value) and field in str(info.value)


def test_a_calibration_that_is_not_a_file_is_refused():
    with pytest.raises(ValueError, match="calibration must be the path of a calibration file, got 3"):
        gym.make("skitter/RoachWalk-v1", calibration=3)
    with pytest.raises(ValueError, match="no such calibration file"):
        gym.make("skitter/RoachWalk-v1", calibration="nowhere.json")


def test_evaluate_refuses_a_bad_calibration_before_writing(tmp_path, capsys):
    bad = _write(tmp_path / "bad.json", robot="motor", effects={"viscous_friction": {"damping": 1e-4}})
    out = tmp_path / "results"
    argv = ["--env", "skitter/RoachWalk-v1", "--policy", "tripod", "--episodes", "1", "--out", str(out),
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
        argv = ["--env", "skitter/RoachWalk-v1", "--policy", "tripod", "--episodes", "2", "--out", str(out),
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
