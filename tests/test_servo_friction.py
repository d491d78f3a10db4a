"""The AX-12 rig's friction forms and gearbox efficiency (sysid/adapters/bench.py, envs/actuators/servo.py), each
applied as its effect says: natively (the joint's frictionloss, the dcmotor's LuGre friction and cogging term, its
resistance and controller gains), never by Python per physics step. The loop finding each on synthetic data is in
tests/test_calibration.py (``RECOVERY``, the null cases), as for the rig's other effects."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from envs.actuators.dcmotor import GAIN_K, GAIN_R, GAIN_VMAX
from envs.actuators.servo import (
    BIAS_COGGING_AMPLITUDE,
    BIAS_COGGING_PHASE,
    BIAS_COGGING_POLES,
    BIAS_LUGRE_COULOMB,
    BIAS_LUGRE_STATIC,
    BIAS_LUGRE_STRIBECK,
    DYN_LUGRE_DAMPING,
    DYN_LUGRE_STIFFNESS,
    GEARBOX_EFFICIENCY,
    WINDING_RESISTANCE,
)
from envs.bench.robot import JOINT
from sysid import synth
from sysid.adapters.bench import LOAD_INERTIA, LOADED_INERTIA, ServoAdapter
from sysid.logs import Log, LogError
from tests.conftest import model_bytes

NEW = ("load_friction", "stribeck_friction", "asymmetric_friction", "gearbox_efficiency")


def shaft_run(model: mujoco.MjModel, goals: np.ndarray, start: float, friction=None) -> np.ndarray:
    """The shaft's angle and speed (steps, 2) of the servo driven to ``goals`` (counts, one per physics step) from
    rest at ``start`` counts. ``friction(model, data)``, if given, runs before every step: a reference computed in
    Python per step, for comparison only."""
    adapter = ServoAdapter()
    data = mujoco.MjData(model)
    joint = model.joint(JOINT)
    servo = model.actuator(adapter._servo).id
    data.qpos[joint.qposadr[0]] = adapter.servo_constants.angle(start)
    out = np.empty((len(goals), 2))
    for i, goal in enumerate(goals):
        data.ctrl[model.actuator_ctrladr[servo]] = model.actuator_gear[servo, 0] * adapter.servo_constants.angle(goal)
        if friction is not None:
            friction(model, data)
        mujoco.mj_step(model, data)
        out[i] = data.qpos[joint.qposadr[0]], data.qvel[joint.dofadr[0]]
    return out


def saturated_torque(model: mujoco.MjModel, speed: float) -> float:
    """The servo's torque at the output at full duty toward its speed ``speed`` (> 0): N (K/R) (Vmax - K N w)."""
    servo = model.actuator(ServoAdapter()._servo).id
    r, k, vmax = (model.actuator_gainprm[servo, i] for i in (GAIN_R, GAIN_K, GAIN_VMAX))
    gear = model.actuator_gear[servo, 0]
    return float(gear * k / r * (vmax - k * gear * speed))


def test_the_dcmotor_keeps_cogging_and_lugre_where_the_servo_model_writes_them():
    """The slots envs/actuators/servo.py writes are those MuJoCo's compiler fills from ``set_to_dcmotor``."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="b")
    body.add_joint(name="j", type=mujoco.mjtJoint.mjJNT_HINGE)
    body.add_geom(size=[0.1, 0, 0])
    a = spec.add_actuator(name="a", target="j", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    a.set_to_dcmotor(motorconst=[0.01, 0.01], resistance=10.0, cogging=[1.0, 2.0, 3.0], lugre=[4.0, 5.0, 6.0, 7.0, 8.0])
    m = spec.compile()
    bias, dyn = m.actuator_biasprm[0], m.actuator_dynprm[0]
    assert [bias[BIAS_COGGING_AMPLITUDE], bias[BIAS_COGGING_POLES], bias[BIAS_COGGING_PHASE]] == [1.0, 2.0, 3.0]
    assert [dyn[DYN_LUGRE_STIFFNESS], dyn[DYN_LUGRE_DAMPING]] == [4.0, 5.0]
    assert [bias[BIAS_LUGRE_COULOMB], bias[BIAS_LUGRE_STATIC], bias[BIAS_LUGRE_STRIBECK]] == [6.0, 7.0, 8.0]
    assert m.actuator_actnum[0] == 1  # the bristle state


def test_at_their_nominal_values_the_new_effects_leave_the_model_as_it_was():
    """Byte for byte: the rig's earlier cases replay as they did."""
    adapter = ServoAdapter()
    nominal = adapter.catalog_nominal()
    assert all(name in adapter.catalog() for name in NEW)
    assert model_bytes(adapter.model_for(nominal)) == model_bytes(adapter.nominal_robot.model)


def test_asymmetric_friction_slows_each_direction_by_its_own_level():
    """At full duty the servo runs where its torque-speed line meets the friction: the friction read off the line
    at each direction's top speed is that direction's level (the mean a frictionloss, half the difference a
    constant torque from the dcmotor's cogging term with no poles)."""
    adapter = ServoAdapter()
    model = adapter.model_for({"asymmetric_friction.positive": 0.2, "asymmetric_friction.negative": 0.05})
    steps = 1200  # 0.6 s: the servo crosses 200 counts and runs at its top speed
    up = shaft_run(model, np.full(steps, 1000.0), 100.0)[steps // 2, 1]
    down = shaft_run(model, np.full(steps, 24.0), 924.0)[steps // 2, 1]
    assert up > 0 > down
    assert saturated_torque(model, up) == pytest.approx(0.2, rel=0.02)
    assert saturated_torque(model, -down) == pytest.approx(0.05, rel=0.02)


def test_stribeck_friction_holds_a_small_step_and_decays_with_speed_as_its_gaussian():
    """MuJoCo's LuGre friction with the static level above the Coulomb one: in steady sliding it is ``static
    exp(-(w / velocity)^2)`` (read off the torque-speed line at supplies that set slow top speeds); at rest it
    holds a step whose servo torque (stall / 32 per count) is below it; stable at the servo's top speed, where it
    has decayed to nothing."""
    adapter = ServoAdapter()
    stribeck = {"stribeck_friction.static": 0.15, "stribeck_friction.velocity": 0.5}
    speeds = []
    for supply in (0.1, 0.12, 0.14):  # stall torques 0.16 to 0.23 N m: the friction met on its falling side
        model = adapter.model_for({**stribeck, "supply_voltage.scale": supply})
        speeds.append(shaft_run(model, np.full(2000, 1000.0), 100.0)[-1, 1])
        assert saturated_torque(model, speeds[-1]) == pytest.approx(0.15 * math.exp(-((speeds[-1] / 0.5) ** 2)))
    assert 0.03 < speeds[0] and speeds[-1] > 0.5  # from a twentieth of the Stribeck velocity to past it
    # a 2-count step: 0.10 N m of servo torque against 0.15 N m of static friction
    c = adapter.servo_constants
    free = shaft_run(adapter.model_for({}), np.full(600, 514.0), 512.0)[-1, 0]
    held = shaft_run(adapter.model_for(stribeck), np.full(600, 514.0), 512.0)[-1, 0]
    assert c.counts_of(free) == pytest.approx(514.0, abs=0.3)
    assert abs(c.counts_of(held) - 512.0) < 0.2
    fast = shaft_run(adapter.model_for(stribeck), np.full(1200, 1000.0), 100.0)
    assert np.isfinite(fast).all() and fast[600, 1] > 5.0


def test_load_friction_follows_bams_friction_where_the_native_form_can():
    """BAM's load-dependent friction (a friction budget of coefficient x |motor torque| against the motion, here
    set in Python before every physics step as the reference) cannot run natively: MuJoCo's friction levels are
    constants. Its native form scales the torque out by 1 - k while the amplifier is saturated (the motor drives the
    load) and by 1 + k within the compliance slope (it brakes the load onto the goal): on the loaded bench, over goal
    steps, it leaves under a third of the reference's effect on the shaft angle; the same torque scale in both
    regimes (an efficiency) would leave over half."""
    adapter = ServoAdapter(load_inertia=LOADED_INERTIA)
    commands = adapter.excite(3.0, np.random.default_rng(0))
    times = np.arange(0.0, 3.0, adapter.physics_dt)
    goals = commands["goal"].to_numpy()[np.searchsorted(commands["time"].to_numpy(), times, side="right") - 1]
    k = 0.3
    servo = adapter.nominal_robot.model.actuator(adapter._servo).id

    def budget(model, data):
        model.dof_frictionloss[0] = k * abs(data.actuator_force[servo] * model.actuator_gear[servo, 0])

    nominal = shaft_run(adapter.model_for({}), goals, 512.0)[:, 0]
    reference = shaft_run(adapter.build([]), goals, 512.0, friction=budget)[:, 0]
    native = shaft_run(adapter.model_for({"load_friction.coefficient": k}), goals, 512.0)[:, 0]
    scaled = shaft_run(adapter.model_for({"gearbox_efficiency.efficiency": (1 - k) * GEARBOX_EFFICIENCY}), goals,
                       512.0)[:, 0]  # fmt: skip

    def rms(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.sqrt(np.mean((a - b) ** 2)))

    effect = rms(reference, nominal)
    assert effect > 3 * adapter.servo_constants.rad_per_count  # counts: the loaded bench shows it
    assert rms(reference, native) < effect / 3
    assert rms(reference, scaled) > effect / 2


def test_gearbox_efficiency_is_the_winding_resistance_over_it_and_keeps_the_top_speed():
    """The model lumps the gearbox's losses into its resistance: with efficiency e the dcmotor's resistance is the
    winding's (8 ohm from the AX-12A's stall current) over e, the controller's gains scaled to keep the duty law; the
    stall torque scales with e, the no-load speed does not."""
    adapter = ServoAdapter()
    servo = adapter.nominal_robot.model.actuator(adapter._servo).id
    for efficiency in (0.5, GEARBOX_EFFICIENCY, 0.9):
        model = adapter.model_for({"gearbox_efficiency.efficiency": efficiency})
        assert model.actuator_gainprm[servo, GAIN_R] == pytest.approx(WINDING_RESISTANCE / efficiency)
        assert saturated_torque(model, 0.0) == pytest.approx(
            saturated_torque(adapter.model_for({}), 0.0) * efficiency / GEARBOX_EFFICIENCY
        )
        top = shaft_run(model, np.full(1200, 1000.0), 100.0)[600, 1]
        assert top == pytest.approx(adapter.servo_constants.no_load_speed, rel=0.02)


def test_a_servo_log_replays_the_load_its_record_declares():
    """The effects that need load torque are recorded on the loaded bench, declared in the log's record, which the
    replay takes; other logs keep the rig's load, and a declared load that is no inertia is refused."""
    adapter = ServoAdapter()
    (loaded,), _ = synth.record("servo", {"load_friction": 0.2}, 0, seconds=2.0)
    (plain,), _ = synth.record("servo", {"delay": 0.01}, 0, seconds=2.0)
    assert loaded.meta[LOAD_INERTIA] == LOADED_INERTIA and LOAD_INERTIA not in plain.meta
    load = adapter.nominal_robot.model.body("load").id
    for log, inertia in ((loaded, LOADED_INERTIA), (plain, adapter.nominal_robot.load_inertia)):
        segment = adapter.segments(log)[0]
        assert adapter.model_for({}, segment).body_inertia[load, 2] == pytest.approx(inertia)
    for bad in (0.0, -1e-3, float("nan"), "heavy"):
        with pytest.raises(LogError, match=LOAD_INERTIA):
            adapter.check_logs([Log("bench.parquet", plain.df, {**plain.meta, LOAD_INERTIA: bad})])
