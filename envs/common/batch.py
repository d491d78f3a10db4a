"""Many simulations of one robot model in one process, on ``mujoco.batch.Batch``.

:class:`BatchSimulation` has the interface of :class:`envs.common.simulation.Simulation` with a leading axis of
``num_sims``: a control block per simulation, run by one ``Batch.rollout`` call on the batch's thread pool. MuJoCo's
batch is bit-identical to a loop over single ``MjData``s at any thread count, and it starts each block from the same
state the single simulation does (time, qpos, qvel, act, warm-start accelerations, ...), so N single envs and one
batched env of N give identical results (tests/test_batch.py). Physical parameters are per simulation through the
batch's expanded model fields.
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import mujoco
import numpy as np
from mujoco import batch

from envs.common.simulation import CTRL_SPEC, check_refine, diverged, refined_block

THREADS_VARIABLE = "SKITTER_THREADS"  # caps the threads of every batch and calibration rollout of this process


def default_threads() -> int:
    """The machine's cores (those this process may use), or fewer where ``$SKITTER_THREADS`` says so (processes
    that share the machine, such as the calibration matrix's parallel cases, take their share of it)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    cap = os.environ.get(THREADS_VARIABLE, "").strip()
    if not cap:
        return cores
    if not cap.isdigit() or int(cap) < 1:
        raise ValueError(f"environment variable {THREADS_VARIABLE}={cap!r}: expected a whole number of at least 1")
    return min(int(cap), cores)


class BatchSimulation:
    """``num_sims`` simulations of ``model``, advanced a control block at a time on ``nthread`` threads.

    Attributes:
        ctrl: the next control blocks, (num_sims, n_substeps, nu).
        substep_sensordata: sensor values of every physics step of the last blocks, (num_sims, n_substeps, nsensor).
        sensordata: the sensor values after the last block, (num_sims, nsensordata), as ``mj_step`` leaves them.
    """

    def __init__(
        self, model: mujoco.MjModel, n_substeps: int, num_sims: int, nthread: int | None = None, refine: int = 1
    ):
        for name, value in (("num_sims", num_sims), ("nthread", 1 if nthread is None else nthread)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"{name} must be a whole number of at least 1, got {value!r}")
        self.model = model
        self.refine = check_refine(refine)  # run an unstable block again at shorter steps (envs/common/simulation.py)
        self.num_sims = int(num_sims)
        self.refined = np.zeros(num_sims, dtype=bool)  # whether each simulation's last block was run again
        self.n_substeps = n_substeps
        self.nthread = default_threads() if nthread is None else int(nthread)
        self.batch = batch.Batch(model, num_sims, self.nthread)
        self.ctrl = np.zeros((num_sims, n_substeps, model.nu))
        self.substep_sensordata = np.zeros((num_sims, n_substeps, model.nsensordata))
        self._bind()

    def _bind(self) -> None:
        b = self.batch
        self.qpos, self.qvel, self.act = b.bind("qpos"), b.bind("qvel"), b.bind("act")
        self._time = b.bind("time")
        # an output field is refreshed after every call once bound (bound later, it reads zero until the next call)
        self._sensordata = b.bind("sensordata")
        self._start = np.empty_like(b.state) if self.refine > 1 else None
        self._gains: np.ndarray | None = None  # the per-simulation actuator gains, once a robot writes them
        self._out = {"sensordata": self.substep_sensordata}
        self._block_time = self.n_substeps * self.model.opt.timestep

    @property
    def sensordata(self) -> np.ndarray:
        return self.substep_sensordata[:, -1]

    @property
    def time(self) -> np.ndarray:
        return self._time.copy()

    @property
    def data(self) -> mujoco.MjData:
        raise AttributeError("a batch of simulations has no single MjData: use get_data(i)")

    def get_data(self, sim: int = 0) -> mujoco.MjData:
        """A copy of simulation ``sim``'s state, with its derived quantities computed (for rendering, inspection)."""
        model = self.batch.get_model(sim)
        data = self.batch.get_data(sim)
        mujoco.mj_forward(model, data)
        return data

    def reset(self, ids: np.ndarray, state: dict[str, np.ndarray]) -> None:
        """Reset simulations ``ids`` to the model's defaults, write ``state`` (qpos, qvel, act, ctrl; (len(ids), ...))
        and compute their derived quantities (sensordata among them)."""
        b = self.batch
        b.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        for name, value in state.items():
            b.bind(name)[ids] = value
        b.forward(ids)
        self.substep_sensordata[ids] = self._sensordata[ids][:, None, :]

    def write(self, ids: np.ndarray, columns: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """Write some entries of the state of simulations ``ids``, keep the rest, and compute their derived
        quantities: name (qpos, qvel, act, ctrl) -> (indices, values), each (len(ids), count). Returns the sensor
        values of the new states, (len(ids), nsensordata); the last block's record (``substep_sensordata``) is
        kept."""
        b = self.batch
        rows = np.asarray(ids)[:, None]
        for name, (cols, values) in columns.items():
            b.bind(name)[rows, cols] = values
        b.forward(ids)
        return self._sensordata[ids].copy()

    def step(self, ids: np.ndarray | None = None) -> np.ndarray:
        """Run the control blocks of simulations ``ids`` (default all). (num_sims,) bool: False where one went
        numerically unstable (MuJoCo stopped it; its episode should end) and, with ``refine``, diverged again when
        run at shorter steps (:attr:`refined` says where that held); True for those not stepped."""
        end = self._time + self._block_time
        start = None
        if self.refine > 1:  # the blocks' starts, to run one again
            start = self._start
            np.copyto(start, self.batch.state)
        if ids is None:
            self.batch.rollout(self.n_substeps, self.ctrl, CTRL_SPEC, record=("sensordata",), out=self._out)
            stable = np.abs(self._time - end) < 0.5 * self.model.opt.timestep
        else:
            stable = np.ones(self.num_sims, dtype=bool)
            if len(ids):
                out = self.batch.rollout(self.n_substeps, self.ctrl[ids], CTRL_SPEC, record=("sensordata",), ids=ids)
                self.substep_sensordata[ids] = out["sensordata"]
                stable[ids] = np.abs(self._time[ids] - end[ids]) < 0.5 * self.model.opt.timestep
        self.refined[:] = False
        if start is not None:  # a block stepped that ends with a joint at an impossible speed diverged too
            if ids is None:
                stable &= ~diverged(self.qvel)
            elif len(ids):
                stable[ids] &= ~diverged(self.qvel[ids])
        if start is not None and not stable.all():
            self._refine(np.flatnonzero(~stable), start, stable)
        return stable

    def _refine(self, sims: np.ndarray, start: np.ndarray, stable: np.ndarray) -> None:
        """Run the blocks of simulations ``sims``, which diverged, again from their starts at shorter physics steps;
        keep each run that does not (its state, its record, stable again)."""
        for s in sims.tolist():
            model = self.batch.get_model(s)
            data = mujoco.MjData(model)
            mujoco.mj_setState(model, data, start[s], mujoco.mjtState.mjSTATE_INTEGRATION)
            finer = refined_block(model, data, self.ctrl[s], self.refine)
            if finer is not None:
                self.batch.state[s], self.substep_sensordata[s] = finer
                stable[s] = self.refined[s] = True

    def expand(self, field: str) -> np.ndarray:
        """Per-simulation values of a model field, (num_sims, ...) (see ``Batch.expand``)."""
        return self.batch.expand(field)

    def set_actuator_gains(self, actuators: np.ndarray, slots: np.ndarray, values: np.ndarray) -> None:
        """Write the gain parameters ``slots`` of ``actuators`` in each simulation before the next block: ``values``
        (num_sims, actuators, slots) (see :meth:`envs.common.simulation.Simulation.set_actuator_gains`)."""
        if self._gains is None:
            self._gains = self.batch.expand("actuator_gainprm")
        self._gains[:, actuators[:, None], slots] = values

    def set_const(self, ids: np.ndarray) -> None:
        self.batch.set_const(ids)

    def __getstate__(self):
        raise TypeError(
            "a batched simulation holds a thread pool and cannot be pickled; make the env again from its id "
            "(gymnasium.make_vec) instead"
        )
