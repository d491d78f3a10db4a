"""The report's CPG (eq. 14) on the Bioloid: the coupling files' parameter counts, the oscillator's limit cycle, the
coupling matrix (bidir, sharing, mirroring), row independence, bad files, and the policy files."""

import json
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents import load_policy
from agents.bioloid.cpg import AMPLITUDE_SCALE, CPG, CouplingError, parse_coupling, read_coupling, read_policy_file
from envs.bioloid import constants

SEED_COUNTS = {1: 64, 2: 33, 3: 32, 4: 24, 5: 16, 6: 24}  # [bioloid-webots, VI.B.3]: experiments 1-6


@pytest.mark.parametrize("experiment", sorted(SEED_COUNTS))
def test_coupling_files_have_the_seeds_parameter_counts(experiment):
    assert read_coupling(f"experiment{experiment}").dimension == SEED_COUNTS[experiment]


def uncoupled(amplitude: float, frequency: float = 1.0):
    return parse_coupling({
        "frequency": frequency,
        "oscillators": {"F_L_1": {"input": "F_R_1"}, "F_R_1": {"input": "F_L_1"}},
        "ranges": {"amplitude": [amplitude, amplitude]},
    })  # fmt: skip


@pytest.mark.parametrize(("amplitude", "frequency"), [(0.5, 1.0), (0.2, 1.7)])
def test_an_uncoupled_oscillator_settles_on_amplitude_sqrt_e_and_period_tau(amplitude, frequency):
    coupling = uncoupled(amplitude, frequency)
    params = np.array([[0.5, 0.0, 0.5, 0.5] * 2])  # zero offset, zero coupling weights
    cpg = CPG(coupling, params)
    xs = []
    for _ in range(round(6.0 / 0.005)):
        cpg.advance(0.005)
        xs.append(cpg.x[0, 0])
    xs = np.array(xs[len(xs) // 2 :])
    assert np.abs(xs).max() == pytest.approx(amplitude, rel=0.01)
    up = np.flatnonzero((xs[1:] > 0) & (xs[:-1] <= 0))
    assert np.diff(up).mean() * 0.005 == pytest.approx(1.0 / frequency, rel=0.01)


def test_bidir_mirrors_a_weight_with_opposite_sign_and_shared_groups_share():
    coupling = read_coupling("experiment5")
    rng = np.random.default_rng(0)
    cpg = CPG(coupling, rng.uniform(0, 1, (1, coupling.dimension)))
    names = coupling.oscillators
    i, j = names.index("F_L_1"), names.index("B_L_1")  # F_L_1 listens to B_L_1, bidir
    assert coupling.inputs[j] != i, "B_L_1 listens to another hip: its weight from F_L_1 is the mirror alone"
    assert cpg.A[0, i, j] != 0 and cpg.A[0, j, i] == -cpg.A[0, i, j]
    assert cpg.B[0, j, i] == -cpg.B[0, i, j]
    k, m = names.index("F_L_3"), names.index("F_L_1")  # the knee listens to its hip, one way
    assert cpg.A[0, k, m] != 0 and cpg.A[0, m, k] == 0
    for a, b in (("F_L_1", "F_R_1"), ("B_L_3", "B_R_3")):  # shared pairs
        ia, ib = names.index(a), names.index(b)
        assert cpg.offset[0, ia] == cpg.offset[0, ib] and cpg.amplitude[0, ia] == cpg.amplitude[0, ib]


def test_goals_are_the_standing_posture_plus_offset_and_state_and_mirror_the_right_abduction():
    coupling = read_coupling("experiment2")
    cpg = CPG(coupling, np.full((1, coupling.dimension), 0.75))
    goal = cpg.goals()[0]
    names = coupling.oscillators
    for servo in ("F_L_2", "F_R_2", "F_L_1", "F_R_1"):
        i = names.index(servo)
        sign = -1.0 if servo == "F_R_2" else 1.0
        angle = constants.STAND_ANGLES[servo] + sign * (cpg.offset[0, i] + AMPLITUDE_SCALE * cpg.x[0, i])
        assert goal[constants.SERVO_INDEX[servo]] == pytest.approx(constants.counts(angle))
    assert goal[constants.SERVO_INDEX["HEAD"]] == 512.0, "a fixed servo holds its count"


def test_a_rows_trajectory_does_not_depend_on_the_batch_it_is_in():
    coupling = read_coupling("experiment1")
    rng = np.random.default_rng(3)
    params = rng.uniform(0, 1, (7, coupling.dimension))
    together, alone = CPG(coupling, params), CPG(coupling, params[4:5])
    for _ in range(100):
        together.advance(0.02)
        alone.advance(0.02)
    np.testing.assert_array_equal(together.goals()[4], alone.goals()[0])
    assert np.isfinite(together.x).all()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"oscillators": {"TAIL": {"input": "F_L_1"}}}, "'TAIL' is not a servo"),
        ({"oscillators": {"F_L_1": {"input": "F_L_1"}}}, "input must name another oscillator"),
        ({"shared": [["F_L_1"]]}, r"shared\[0\]"),
        ({"fixed": {"F_L_1": 5}}, "also has an oscillator"),
        ({"fixed": {"N_1": 1100}}, r"fixed.N_1"),
        ({"ranges": {"amplitude": [0.5, 0.1]}}, "low <= high"),
        ({"colour": "red"}, "unknown field"),
    ],
)
def test_bad_coupling_files_are_refused_naming_the_field(tmp_path, change, message):
    raw = json.loads(Path(read_coupling("experiment5").path).read_text())
    for key, value in change.items():
        if key == "oscillators":
            raw["oscillators"].update(value)
        else:
            raw[key] = value
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(raw))
    with pytest.raises(CouplingError, match=message) as error:
        read_coupling(path)
    assert str(path) in str(error.value)


def test_policy_files_load_by_name_and_parameters_are_checked(tmp_path):
    env = gym.make("skitter/BioloidWalk-v2")
    coupling = read_coupling("experiment6")
    params = np.linspace(0.1, 0.9, coupling.dimension)
    record = {"policy": "cpg", "robot": "bioloid", "coupling": coupling.to_dict(), "parameters": params.tolist()}
    good = tmp_path / "best.json"
    good.write_text(json.dumps(record))
    policy = load_policy(f"cpg:{good}", env)
    np.testing.assert_array_equal(policy.policy.parameters, params)
    obs, _ = env.reset(seed=0)
    action, state = policy.predict(obs)
    assert action.shape == (16,) and np.isfinite(state).all()
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**record, "parameters": [1.5] * coupling.dimension}))
    with pytest.raises(CouplingError, match="parameters"):
        read_policy_file(bad)
    with pytest.raises(CouplingError, match="a directory, not a file"):
        read_policy_file(tmp_path)
    # each field checked and named: parameters of the wrong kind, a robot it does not drive, a field it does not know
    for change, needle in [
        ({"parameters": {"a": 1}}, f"must be a list of {coupling.dimension} numbers in \\[0, 1\\]"),
        ({"parameters": ["x", *params[1:].tolist()]}, "'parameters' item 0 must be a number in \\[0, 1\\], got 'x'"),
        ({"parameters": [*params[:3].tolist(), math.nan, *params[4:].tolist()]}, "item 3 .* got nan"),
        ({"parameters": [True, *params[1:].tolist()]}, "item 0 .* got True"),
        ({"robot": "xjus"}, "field 'robot' must be 'bioloid'"),
        ({"extra": 1}, "unknown field 'extra'"),
    ]:
        bad.write_text(json.dumps({**record, **change}))
        with pytest.raises(CouplingError, match=needle):
            read_policy_file(bad)


def test_the_cpg_policy_runs_an_episode_and_replays_the_same():
    env = gym.make("skitter/BioloidWalk-v2", max_episode_steps=50)
    xs = []
    for _ in range(2):
        policy = load_policy("cpg", env)
        obs, _ = env.reset(seed=1)
        state = None
        for _ in range(50):
            action, state = policy.predict(obs, state)
            obs, *_, info = env.step(action)
        xs.append(info["x_position"])
    assert xs[0] == xs[1] and math.isfinite(xs[0])


def test_the_gait_check_replays_the_scored_rollout_and_its_variants_change_only_the_model(tmp_path):
    """benchmarks/bioloid_cpg_check.py (the verdict on the optimized gaits): its step-by-step replay ends where the
    optimizer's scored rollout ended (it raises otherwise), and its nominal variant gives the scored progress."""
    from agents.optimize.problem import Evaluator, parse_config
    from benchmarks.bioloid_cpg_check import gait_statistics, record_controls, replay

    coupling = read_coupling("experiment5")
    params = np.linspace(0.2, 0.8, coupling.dimension)
    config = {"env": "skitter/BioloidWalk-v2", "controller": "cpg", "seconds": 2.0, "objective": "distance_travelled",
              "sample_interval": 1.0, "max_tilt": 1.0, "coupling": "experiment5"}  # fmt: skip
    policy = tmp_path / "best.json"
    policy.write_text(json.dumps({"policy": "cpg", "robot": "bioloid", "coupling": coupling.to_dict(),
                                  "parameters": params.tolist(), "run": {"config": config}}))  # fmt: skip
    scored = Evaluator(parse_config(config), 1, nthread=1).evaluate(params[None])
    rollout = record_controls(policy)
    stats = gait_statistics(rollout)
    assert stats["progress_x"] == pytest.approx(scored["progress_x"][0], abs=1e-9)
    assert sum(stats["ground_force_share"].values()) == pytest.approx(1.0)
    assert stats["max_driving_torque_over_the_line"] <= 1e-9  # the servo model's torque-speed line holds
    assert replay(rollout)["progress_x"] == pytest.approx(scored["progress_x"][0], abs=1e-9)
    assert rollout["model"].opt.timestep == 0.002  # the variants edit copies
