"""Stepping the physics natively: a control step is a block of per-physics-step controls run by ``mujoco.rollout``.

Every input to the physics is a ``ctrl`` value, given for each physics step of a control step (a firmware's clock
ramps within the step; a held duty cycle repeats), and one native call runs them: no Python per physics step, and
nothing writes the model during an episode. A recorded episode is its initial state plus the concatenated control
blocks, and ``mujoco.rollout`` replays it exactly (tests/test_contract.py).

:class:`Simulation` holds one ``MjData`` (the single Gymnasium env: a batch of one). The batched envs run the same
robots and tasks on ``mujoco.batch.Batch``; both give arrays with a leading simulation axis.

A simulation made with ``refine=r`` (a multi-robot scene's) runs a control block that diverged once more from its
start, at physics steps ``r`` times shorter (:func:`refined_block`), and keeps that run where it does not diverge.
A block diverges where MuJoCo finds a bad acceleration (it then resets the data) or where any joint ends it faster
than :data:`DIVERGED_SPEED`: where two robots wedge a leg between them, the contact forces of a 2 ms step can outgrow
the solver and throw a joint to thousands of rad/s within a step, a block before MuJoCo's own test trips, and those of
shorter steps do not (docs/soccer.md). A block that does not diverge is never run twice, so it is unchanged.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping

import mujoco
import numpy as np
from mujoco import rollout

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS  # what a control block starts from (time, qpos, qvel, act, history)
CTRL_SPEC = mujoco.mjtState.mjSTATE_CTRL.value
# applied forces (a user's push through data.qfrc_applied or xfrc_applied) are held over the block with the controls
APPLIED_SPEC = CTRL_SPEC | mujoco.mjtState.mjSTATE_QFRC_APPLIED.value | mujoco.mjtState.mjSTATE_XFRC_APPLIED.value
# a joint faster than this (rad/s, or m/s) at the end of a block has diverged: the fastest the robots' joints turn in
# random play is 443 rad/s (a roach crank-train joint; its cranks turn at most 283 rad/s, a 45 Hz stride) and 11 rad/s
# (the Bioloid's); the xJüs's stay within a few tens of rad/s, and reach thousands in a step where its scene diverges
DIVERGED_SPEED = 1e3
REFINE_AGAIN = 4  # where a block run again at shorter steps diverges too: steps this many times shorter still


class Simulation:
    """One simulation of ``model``, advanced a control block (``n_substeps`` physics steps) at a time.

    Arrays carry a leading simulation axis of length 1, as a batch's would.

    Attributes:
        ctrl: the next control block, (1, n_substeps, nu); the robot writes it before :meth:`step`.
        substep_sensordata: sensor values of every physics step of the last block, (1, n_substeps, nsensordata),
            each as ``mj_step`` leaves it (computed at the state before that step's integration).
    """

    num_sims = 1

    def __init__(self, model: mujoco.MjModel, n_substeps: int, refine: int = 1):
        self.model = model
        self.refine = check_refine(refine)
        self.refined = np.zeros(1, dtype=bool)  # whether the last block was run again at shorter steps
        self.data = mujoco.MjData(model)
        self.n_substeps = n_substeps
        self.ctrl = np.zeros((1, n_substeps, model.nu))
        self.substep_sensordata = np.zeros((1, n_substeps, model.nsensordata))
        self._rollout = rollout.Rollout(nthread=0)
        self._start = np.zeros((1, mujoco.mj_stateSize(model, STATE_SPEC)))
        self._warmstart = np.zeros((1, model.nv))
        self._views()

    def _views(self) -> None:
        """Views of the data's buffers, looked up once (each attribute access makes a new array object)."""
        self._qfrc_applied, self._xfrc_applied = self.data.qfrc_applied, self.data.xfrc_applied
        self._qacc_warmstart = self.data.qacc_warmstart
        self._sensordata = self.data.sensordata[None]
        self._start0, self._warmstart0 = self._start[0], self._warmstart[0]
        self._block_time = self.n_substeps * self.model.opt.timestep
        self._half_step = 0.5 * self.model.opt.timestep

    # --- views with the simulation axis -------------------------------------------------------------------------
    @property
    def sensordata(self) -> np.ndarray:
        return self._sensordata

    @property
    def qpos(self) -> np.ndarray:
        return self.data.qpos[None]

    @property
    def qvel(self) -> np.ndarray:
        return self.data.qvel[None]

    @property
    def act(self) -> np.ndarray:
        return self.data.act[None]

    @property
    def time(self) -> np.ndarray:
        return np.array([self.data.time])

    def get_data(self, sim: int = 0) -> mujoco.MjData:
        """The simulation's ``MjData`` (live: writes to it change the simulation)."""
        if sim != 0:
            raise IndexError(f"a single simulation has only simulation 0, not {sim}")
        return self.data

    # --- stepping -----------------------------------------------------------------------------------------------
    def reset(self, ids: np.ndarray, state: dict[str, np.ndarray]) -> None:
        """Reset the simulations ``ids`` (here [0]) to the model's defaults, then write ``state`` (qpos, qvel, act,
        ctrl; each (len(ids), ...)) and compute the derived quantities."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        for name, value in state.items():
            getattr(d, name)[:] = value[0]
        mujoco.mj_forward(m, d)
        self.substep_sensordata[:] = d.sensordata

    def write(self, ids: np.ndarray, columns: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """Write some entries of the state of simulations ``ids`` (here [0]), keep the rest, and compute the derived
        quantities: name (qpos, qvel, act, ctrl) -> (indices, values), each (len(ids), count). Returns the sensor
        values of the new state, (len(ids), nsensordata); the last block's record (``substep_sensordata``) is kept."""
        for name, (cols, values) in columns.items():
            getattr(self.data, name)[cols[0]] = values[0]
        mujoco.mj_forward(self.model, self.data)
        return self.data.sensordata[None].copy()

    def step(self, ids: np.ndarray | None = None) -> np.ndarray:
        """Run the control block in ``ctrl``. Returns, per simulation, whether it stayed numerically stable; an
        unstable one has been reset by MuJoCo and should end its episode. With ``refine``, a block that diverged is
        run again at shorter steps first (:attr:`refined` says where that held). ``ids``: [0] or empty (step
        nothing)."""
        if ids is not None and len(ids) == 0:
            return np.array([True])
        m, d = self.model, self.data
        end = d.time + self._block_time
        mujoco.mj_getState(m, d, self._start0, STATE_SPEC)
        self._warmstart0[:] = self._qacc_warmstart
        control, spec = self.ctrl, CTRL_SPEC
        if np.count_nonzero(self._qfrc_applied) or np.count_nonzero(self._xfrc_applied):  # the cheapest test
            control, spec = self._with_applied_forces(), APPLIED_SPEC
        self._rollout.rollout(
            [m],
            [d],
            self._start,
            control,
            control_spec=spec,
            skip_checks=True,
            nstep=self.n_substeps,
            initial_warmstart=self._warmstart,
            state=None,
            sensordata=self.substep_sensordata,
            chunk_size=1,
        )
        # on a NaN, infinite or huge state MuJoCo warns, resets the data (time 0) and the rollout stops early
        stable = abs(d.time - end) < self._half_step
        self.refined[0] = False
        if self.refine > 1 and stable:
            stable = not diverged(d.qvel)
        if not stable and self.refine > 1 and spec == CTRL_SPEC:  # (a block under applied forces: not again)
            start = mujoco.MjData(m)
            mujoco.mj_setState(m, start, self._start0, STATE_SPEC)
            start.qacc_warmstart[:] = self._warmstart0
            finer = refined_block(m, start, self.ctrl[0], self.refine)
            if finer is not None:
                state, sensordata = finer
                mujoco.mj_setState(m, d, state, mujoco.mjtState.mjSTATE_INTEGRATION)
                mujoco.mj_forward(m, d)  # the derived quantities of the state reached (rendering reads them)
                self.substep_sensordata[0] = sensordata
                d.sensordata[:] = sensordata[-1]  # as mj_step leaves it: the last physics step's
                stable = self.refined[0] = True
        return np.array([stable])

    def _with_applied_forces(self) -> np.ndarray:
        """The control block with the data's applied forces held over it (the rollout would zero them otherwise)."""
        inputs = np.empty(mujoco.mj_stateSize(self.model, APPLIED_SPEC))
        mujoco.mj_getState(self.model, self.data, inputs, APPLIED_SPEC)
        block = np.tile(inputs, (1, self.n_substeps, 1))
        block[0, :, : self.model.nu] = self.ctrl[0]
        return block

    def set_actuator_gains(self, actuators: np.ndarray, slots: np.ndarray, values: np.ndarray) -> None:
        """Write the gain parameters ``slots`` of ``actuators`` before the next block: ``values`` (1, actuators,
        slots). For a controller whose gains follow a quantity that changes during an episode (a sagging battery),
        written between control blocks, never within one."""
        self.model.actuator_gainprm[actuators[:, None], slots] = values[0]

    def __getstate__(self):
        state = self.__dict__.copy()
        for name in (
            "_rollout",
            "_qfrc_applied",
            "_xfrc_applied",
            "_qacc_warmstart",
            "_sensordata",
            "_start0",
            "_warmstart0",
        ):  # a thread pool handle and views: made anew
            del state[name]
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._rollout = rollout.Rollout(nthread=0)
        self._views()

    def initial_state(self) -> np.ndarray:
        """The full physics state (``mjSTATE_FULLPHYSICS``) now, to replay from with ``mujoco.rollout``."""
        state = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, state, STATE_SPEC)
        return state


def diverged(qvel: np.ndarray) -> np.ndarray | bool:
    """Whether a state's velocities (nv,) or each row of them (n, nv) hold a joint faster than
    :data:`DIVERGED_SPEED`."""
    return np.abs(qvel).max(axis=-1, initial=0.0) > DIVERGED_SPEED


def check_refine(refine: int) -> int:
    """A refinement factor: a whole number of at least 1 (1: a block that goes unstable is not run again)."""
    if isinstance(refine, bool) or not isinstance(refine, int | np.integer) or refine < 1:
        raise ValueError(f"refine must be a whole number of at least 1, got {refine!r}")
    return int(refine)


def refined_block(
    model: mujoco.MjModel, start: mujoco.MjData, ctrl: np.ndarray, refine: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """Run a control block again from ``start`` (an ``MjData`` of ``model`` holding the block's starting state and
    warm start) at physics steps ``refine`` times shorter, each physics step's controls (``ctrl``, (substeps, nu))
    held over its ``refine`` shorter steps. Returns the state reached (``mjSTATE_INTEGRATION``) and the sensor values
    at the block's own physics steps, (substeps, nsensordata), each as ``mj_step`` leaves it (at the state before
    that step); None if the shorter steps diverge too. Where they do, steps ``REFINE_AGAIN`` times shorter still
    are tried once more (a block that starts already shaken, with a joint at hundreds of rad/s, can need them)."""
    for factor in (refine, REFINE_AGAIN * refine):
        finer = run_at_shorter_steps(model, start, ctrl, factor)
        if finer is not None:
            return finer
    return None


def run_at_shorter_steps(
    model: mujoco.MjModel, start: mujoco.MjData, ctrl: np.ndarray, refine: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The block run once from ``start`` at physics steps ``refine`` times shorter (1: the model's own), as
    :func:`refined_block` describes; None where it diverges."""
    finer = copy.copy(model)
    finer.opt.timestep = model.opt.timestep / refine
    substeps = ctrl.shape[0]
    data = mujoco.MjData(finer)
    state = np.empty(mujoco.mj_stateSize(finer, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(model, start, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    mujoco.mj_setState(finer, data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    initial = np.empty((1, mujoco.mj_stateSize(finer, STATE_SPEC)))
    mujoco.mj_getState(finer, data, initial[0], STATE_SPEC)
    sensordata = np.zeros((1, substeps * refine, finer.nsensordata))
    end = start.time + substeps * model.opt.timestep
    rollout.rollout(
        [finer],
        [data],
        initial,
        np.repeat(ctrl, refine, axis=0)[None],
        control_spec=CTRL_SPEC,
        skip_checks=True,
        nstep=substeps * refine,
        initial_warmstart=start.qacc_warmstart[None].copy(),
        state=None,
        sensordata=sensordata,
    )
    if not abs(data.time - end) < 0.5 * finer.opt.timestep or diverged(data.qvel):
        return None
    mujoco.mj_getState(finer, data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
    return state, sensordata[0, ::refine]
