"""A control block that diverges, run again at shorter physics steps (envs/common/simulation.py): the single and the
batched simulation keep the shorter run where it holds, as a direct run at those steps gives it, and leave every
block that did not diverge as it was."""

import mujoco
import numpy as np
import pytest

from envs.common.batch import BatchSimulation
from envs.common.simulation import DIVERGED_SPEED, REFINE_AGAIN, Simulation, diverged, refined_block

# a 1 kg slider on a spring of 90,000 N/m (omega = 300 rad/s) under the semi-implicit Euler integrator: stable for
# omega dt < 2, so a 10 ms step grows an oscillation about 7-fold a step, and a step 8 times shorter (omega dt 0.375)
# holds it; a position sensor records it at every physics step
SPRING = """
<mujoco>
  <option timestep="0.01" integrator="Euler" gravity="0 0 0"/>
  <worldbody>
    <body>
      <joint name="slide" type="slide" axis="1 0 0" stiffness="90000"/>
      <geom type="sphere" size="0.05" mass="1" contype="0" conaffinity="0"/>
    </body>
  </worldbody>
  <actuator><motor joint="slide" name="push"/></actuator>
  <sensor><jointpos joint="slide"/></sensor>
</mujoco>
"""
SUBSTEPS, REFINE = 10, 8


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(SPRING)


def direct(model: mujoco.MjModel, qpos: float, ctrl: np.ndarray, factor: int) -> tuple[mujoco.MjData, np.ndarray]:
    """The block run step by step on a model with steps ``factor`` times shorter: its end and its sensor record at
    the block's own physics steps."""
    finer = mujoco.MjModel.from_xml_string(SPRING)
    finer.opt.timestep = model.opt.timestep / factor
    data = mujoco.MjData(finer)
    data.qpos[0] = qpos
    record = []
    for k in range(SUBSTEPS * factor):
        data.ctrl[:] = ctrl[k // factor]
        mujoco.mj_step(finer, data)
        record.append(data.sensordata.copy())
    return data, np.array(record)[::factor]


def test_a_diverging_block_is_run_again_at_shorter_steps_as_a_direct_run_gives_it(model):
    ctrl = np.linspace(-1.0, 1.0, SUBSTEPS)[:, None]
    sim = Simulation(model, SUBSTEPS, refine=REFINE)
    sim.data.qpos[0] = 0.01
    sim.ctrl[0] = ctrl
    assert sim.step().tolist() == [True] and sim.refined.tolist() == [True]
    expected, record = direct(model, 0.01, ctrl, REFINE)
    assert sim.data.time == pytest.approx(SUBSTEPS * model.opt.timestep)
    assert np.array_equal(sim.data.qpos, expected.qpos) and np.array_equal(sim.data.qvel, expected.qvel)
    assert np.array_equal(sim.substep_sensordata[0], record)
    assert np.array_equal(sim.sensordata[0], record[-1]), "the sensors as mj_step leaves them: the last step's"
    assert abs(sim.data.qpos[0]) < 0.02, "the oscillation held, not grown"
    # the next block starts where the shorter run ended, at the model's own step, and diverges again: run again
    assert sim.step().tolist() == [True] and sim.refined.tolist() == [True]


def test_without_refinement_the_same_block_diverges(model):
    sim = Simulation(model, SUBSTEPS)
    sim.data.qpos[0] = 0.01
    stable = sim.step()
    assert (not stable[0]) or diverged(sim.data.qvel), "a 7-fold growth a step for 10 steps"
    assert sim.refined.tolist() == [False]


def test_a_block_that_holds_is_not_run_again(model):
    model_ok = mujoco.MjModel.from_xml_string(SPRING)
    model_ok.opt.timestep = model.opt.timestep / REFINE
    sim, plain = Simulation(model_ok, SUBSTEPS, refine=REFINE), Simulation(model_ok, SUBSTEPS)
    for s in (sim, plain):
        s.data.qpos[0] = 0.01
        s.ctrl[0] = 0.3
        assert s.step().tolist() == [True]
    assert sim.refined.tolist() == [False]
    assert np.array_equal(sim.data.qpos, plain.data.qpos) and np.array_equal(
        sim.substep_sensordata, plain.substep_sensordata
    )


def test_a_block_that_diverges_at_every_step_tried_stays_unstable(model):
    sim = Simulation(model, SUBSTEPS, refine=REFINE)
    sim.data.qvel[0] = 10 * DIVERGED_SPEED  # already diverged: no shorter step brings it back under the limit
    assert sim.step().tolist() == [False] and sim.refined.tolist() == [False]
    start = mujoco.MjData(model)
    start.qvel[0] = 10 * DIVERGED_SPEED
    assert refined_block(model, start, np.zeros((SUBSTEPS, 1)), REFINE) is None
    assert REFINE_AGAIN > 1


def test_the_batch_runs_again_only_the_simulations_that_diverged(model):
    ctrl = np.zeros((SUBSTEPS, 1))
    sims = BatchSimulation(model, SUBSTEPS, 3, nthread=1, refine=REFINE)
    sims.qpos[:, 0] = [0.0, 0.01, 0.0]  # at rest on its spring, nothing grows: only simulation 1 diverges
    sims.ctrl[:] = ctrl
    assert sims.step().tolist() == [True, True, True]
    assert sims.refined.tolist() == [False, True, False]
    expected, record = direct(model, 0.01, ctrl, REFINE)
    assert np.array_equal(sims.qpos[1], expected.qpos) and np.array_equal(sims.qvel[1], expected.qvel)
    assert np.array_equal(sims.substep_sensordata[1], record)
    assert np.all(sims.qpos[[0, 2]] == 0.0) and sims.time.tolist() == pytest.approx([SUBSTEPS * 0.01] * 3)
    # stepping a subset: the others are neither stepped nor run again, even one whose state is past the limit
    sims.qvel[2, 0] = 10 * DIVERGED_SPEED
    assert sims.step(np.array([1])).tolist() == [True, True, True]
    assert sims.refined.tolist() == [False, True, False] and sims.qvel[2, 0] == 10 * DIVERGED_SPEED
    plain = BatchSimulation(model, SUBSTEPS, 3, nthread=1)
    plain.qpos[:, 0] = [0.0, 0.01, 0.0]
    assert plain.step().tolist() == [True, False, True] and plain.refined.tolist() == [False, False, False]


def test_refine_must_be_a_whole_number_of_at_least_one(model):
    for bad in (0, 1.5, True, "8"):
        with pytest.raises(ValueError, match="refine must be a whole number"):
            Simulation(model, SUBSTEPS, refine=bad)
