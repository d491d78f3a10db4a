"""Several robots of one kind in one MuJoCo model: a field with players and whatever else the scene holds (a ball).

A :class:`SharedScene` builds one model from a robot's configured spec: the robot's subtree attached ``players``
times (each copy's names prefixed ``<player>/``), each with its own ground contact sensors, then the scene's own
edits (a field, goals, a ball; added after the players, so that every player's qpos, qvel, act, ctrl and sensordata
are one block of the robot's own size, in the robot's own order, at a fixed stride). ``num_scenes`` such models run
together on a ``mujoco.batch.Batch`` (or one ``MjData`` for a single scene).

The robot is built once, inside :func:`envs.common.robot.hosted_robots`, with ``num_sims = num_scenes x players``:
every player of every scene is one "simulation" of the robot. Its simulation is a :class:`PlayerSimulation`, a view
that gives the robot its players' rows of the scenes' controls and sensor values, so the robot's own code (its
firmware, senses, telemetry, ground rules) runs unchanged for every player at once and one ``robot.step()`` steps
every scene natively: no Python per physics step, no Python per player. The robot resets at its own origin facing
+x; :attr:`SharedScene.placement` moves each player to its place on the field (x, y, heading) as it resets.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from envs.common.batch import BatchSimulation
from envs.common.mujoco_utils import sensor_slices
from envs.common.robot import _BATCH, GROUND_SENSOR, add_ground_contact_sensors, hosted_robots
from envs.common.simulation import Simulation, check_refine

if TYPE_CHECKING:
    from envs.common.robot import Robot

SceneEdit = Callable[[mujoco.MjSpec], None]
MAX_PLAYERS = 30  # players of a scene: contact bits 1 to 30 of MuJoCo's 32-bit contype (bit 0 is the world's)
# the model's arrays with one block per player, and the MjModel sizes of their blocks
# the object types of a sensor that reads a body's frame (the ball's position and velocity)
OBJECT_FRAMES = (int(mujoco.mjtObj.mjOBJ_BODY), int(mujoco.mjtObj.mjOBJ_XBODY))
_BLOCKS = {"qpos": "nq", "qvel": "nv", "act": "na", "ctrl": "nu", "sensordata": "nsensordata"}


def _unnamed(kind: str, index: int) -> str:
    """The name a scene gives a robot's unnamed element (its kind and index in the robot's spec)."""
    return f"_{kind}_{index}"


def yaw_quaternion(yaw: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) (w, x, y, z) of turns by ``yaw`` (n,) about world z."""
    half = 0.5 * np.asarray(yaw, dtype=np.float64)
    return np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=-1)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products a * b of quaternions (..., 4) (w, x, y, z)."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


class SharedScene:
    """``players`` robots of one kind and the scene's objects in one model, ``num_scenes`` such models stepped
    together.

    Args:
        make_robot: builds the robot (its class with its arguments); called once, inside this scene's
            :func:`~envs.common.robot.hosted_robots` block.
        players: names of the players, each the prefix of its copy's element names (``home_0/...``).
        edits: functions that add the scene's own elements (field, goals, ball, their sensors) to the spec after
            the players.
        num_scenes: scenes stepped together (default: one, or what an enclosing
            :func:`~envs.common.robot.batched_robots` says).
        nthread, batched: threads of the batch; run on ``mujoco.batch.Batch`` even for one scene (default: when
            ``num_scenes > 1``).
        refine: a scene's control block that goes numerically unstable is run again from its start at physics
            steps this many times shorter, and kept where it stays stable (1: not run again; see
            envs/common/simulation.py).
    """

    def __init__(
        self,
        make_robot: Callable[[], Robot],
        players: Sequence[str],
        edits: Sequence[SceneEdit] = (),
        num_scenes: int | None = None,
        nthread: int | None = None,
        batched: bool | None = None,
        refine: int = 1,
    ):
        if not players or len(set(players)) != len(players) or not all(isinstance(p, str) and p for p in players):
            raise ValueError(f"players must be distinct non-empty names, got {players!r}")
        context = _BATCH.get()
        if num_scenes is None:
            num_scenes, nthread = context if context is not None else (1, nthread)
            batched = context is not None if batched is None else batched
        if isinstance(num_scenes, bool) or not isinstance(num_scenes, int | np.integer) or num_scenes < 1:
            raise ValueError(f"num_scenes must be a whole number >= 1, got {num_scenes!r}")
        self.players = tuple(players)
        self.num_players = len(self.players)
        self.num_scenes = int(num_scenes)
        self.num_sims = self.num_scenes * self.num_players  # the robot's simulations: every player of every scene
        self.batched = self.num_scenes > 1 if batched is None else bool(batched)
        self.nthread = nthread
        self.refine = check_refine(refine)
        self._edits = tuple(edits)
        # each player's place (x, y, heading) for its next reset, (num_scenes * players, 3); the task sets it
        self.placement = np.zeros((self.num_sims, 3))
        self.model: mujoco.MjModel | None = None
        self.spec: mujoco.MjSpec | None = None
        # the objects' places for the scenes' next kickoff: full qpos and qvel rows (made with the model)
        self._pending: dict[str, np.ndarray] = {}
        with hosted_robots(self):
            self.robot = make_robot()
        if self.model is None:
            raise RuntimeError("the robot was not built on the scene (its class does not call Robot.__init__?)")

    # --- building (called by Robot.__init__ through hosted_robots) ---------------------------------------------
    def host(self, robot: Robot, spec: mujoco.MjSpec) -> PlayerSimulation:
        """Build the scene's model from the robot's configured ``spec`` (without its ground contact sensors) and
        return the robot's simulation."""
        scene = spec.copy()
        scene.delete(scene.body(robot.root_body))
        for kind in ("sensors", "actuators", "equalities", "tendons", "excludes"):
            for element in list(getattr(scene, kind)):  # what the robot had besides its bodies: attached with it
                scene.delete(element)
        spec = spec.copy()
        for kind in ("actuators", "sensors"):  # attach orders unnamed elements apart: each gets a name
            for i, element in enumerate(getattr(spec, kind)):
                element.name = element.name or _unnamed(kind, i)
        for p, player in enumerate(self.players):
            frame = scene.worldbody.add_frame()
            frame.attach_body(spec.copy().body(robot.root_body), f"{player}/", "")
            self._collide_with_the_others(scene.body(f"{player}/{robot.root_body}"), p)
            if robot.feet is not None:
                add_ground_contact_sensors(scene, f"{player}/{robot.root_body}", [f"{player}/{f}" for f in robot.feet])
        for edit in self._edits:
            edit(scene)
        self.spec = scene.copy()
        self.model = model = scene.compile()
        self._check_blocks(robot.model, model)
        self.sensors = sensor_slices(model, [model.sensor(i).name for i in range(model.nsensor)])
        self.objects = self._object_joints(model)
        if self.batched:
            self.sim: Simulation | BatchSimulation = BatchSimulation(
                model, robot.n_substeps, self.num_scenes, self.nthread, self.refine
            )
        elif self.num_scenes == 1:
            self.sim = Simulation(model, robot.n_substeps, self.refine)
        else:
            raise ValueError(f"one MjData runs one scene, not {self.num_scenes}: pass batched=True")
        self.view = PlayerSimulation(self, robot)
        return self.view

    def _collide_with_the_others(self, root: mujoco.MjsBody, p: int) -> None:
        """Player ``p``'s colliding geoms meet the other players' as well as what they met alone (the world's:
        floor, walls, ball), and still not each other: each player has a contact bit of its own (bit ``p + 1``) in its
        ``contype``, and the others' bits beside the world's (bit 0) in its ``conaffinity``."""
        if len(self.players) > MAX_PLAYERS:
            raise ValueError(
                f"a scene holds at most {MAX_PLAYERS} players (a contact bit each), not {len(self.players)}"
            )
        others = sum(1 << (q + 1) for q in range(len(self.players)) if q != p)
        for geom in root.find_all(mujoco.mjtObj.mjOBJ_GEOM):  # the root's own geoms among them
            if geom.contype or geom.conaffinity:
                if geom.contype & ~1 or geom.conaffinity & ~1:
                    raise ValueError(
                        f"{geom.name or 'a geom'} uses contact bits beyond the world's: the scene needs them"
                    )
                geom.contype, geom.conaffinity = 1 << (p + 1), geom.conaffinity | others

    def _check_blocks(self, single: mujoco.MjModel, model: mujoco.MjModel) -> None:
        """Every player's qpos, qvel, act, ctrl and sensordata form one block of the robot's size at a fixed stride,
        in the robot's own order (RuntimeError otherwise: the robot's model holds something attach reorders)."""
        k = self.num_players
        self.block = {name: int(getattr(single, size)) for name, size in _BLOCKS.items()}
        for name, size in _BLOCKS.items():
            if getattr(model, size) < k * getattr(single, size):
                raise RuntimeError(f"the scene's {name} is smaller than {k} robots'")
        for kind, plural, count, adr, stride in (
            (mujoco.mjtObj.mjOBJ_JOINT, "joints", single.njnt, single.jnt_qposadr, single.nq),
            (mujoco.mjtObj.mjOBJ_ACTUATOR, "actuators", single.nactuator, single.actuator_ctrladr, single.nu),
            (mujoco.mjtObj.mjOBJ_SENSOR, "sensors", single.nsensor, single.sensor_adr, single.nsensordata),
        ):
            at = {"joints": model.jnt_qposadr, "actuators": model.actuator_ctrladr, "sensors": model.sensor_adr}[plural]
            for p, player in enumerate(self.players):
                for i in range(count):
                    name = mujoco.mj_id2name(single, kind, i) or _unnamed(plural, i)
                    if name.startswith(GROUND_SENSOR):
                        continue  # named after the player's bodies: checked by position below
                    j = mujoco.mj_name2id(model, kind, f"{player}/{name}")
                    if j < 0 or int(at[j]) != p * stride + int(adr[i]):
                        raise RuntimeError(f"player {player!r}: {name} is not at its place in the scene's block")
        for p in range(k):
            acts = model.actuator_actadr[p * single.nactuator : (p + 1) * single.nactuator]
            if not np.array_equal(np.where(acts >= 0, acts - p * single.na, -1), single.actuator_actadr):
                raise RuntimeError(f"player {self.players[p]!r}: its actuator states are not at their places")
            if not np.array_equal(model.sensor_type[p * single.nsensor : (p + 1) * single.nsensor], single.sensor_type):
                raise RuntimeError(f"player {self.players[p]!r}: its sensors are not in the robot's order")

    @staticmethod
    def _object_joints(model: mujoco.MjModel) -> dict[str, tuple[int, int]]:
        """Free joints of the scene's own bodies (not a player's): body name -> (qpos address, qvel address)."""
        objects = {}
        for j in range(model.njnt):
            body = model.body(int(model.jnt_bodyid[j]))
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE and "/" not in body.name:
                objects[body.name] = (int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]))
        return objects

    # --- the scene's own objects --------------------------------------------------------------------------------
    def scene_sensor(self, name: str, substeps: bool = False) -> np.ndarray:
        """A scene sensor's values after the last step, (num_scenes, dim), or at every physics step of it,
        (num_scenes, n_substeps, dim)."""
        values = self.sim.substep_sensordata[..., self.sensors[name]]
        return values if substeps else values[:, -1]

    def place_object(self, scenes: np.ndarray, body: str, position: np.ndarray, velocity: np.ndarray) -> None:
        """Put a free object (the ball) at ``position`` (len(scenes), 3), level, moving at ``velocity``
        (len(scenes), 3), in ``scenes``; its pending place is written at the scenes' next reset (a kickoff)."""
        if body not in self.objects:
            raise KeyError(f"the scene has no free body {body!r} (it has {sorted(self.objects)})")
        qadr, vadr = self.objects[body]
        qpos = self._pending.setdefault("qpos", np.tile(self.model.qpos0, (self.num_scenes, 1)))
        qvel = self._pending.setdefault("qvel", np.zeros((self.num_scenes, self.model.nv)))
        qpos[scenes, qadr : qadr + 3] = position
        qpos[scenes, qadr + 3 : qadr + 7] = [1.0, 0.0, 0.0, 0.0]
        qvel[scenes, vadr : vadr + 3] = velocity
        qvel[scenes, vadr + 3 : vadr + 6] = 0.0

    def move_object(self, scenes: np.ndarray, body: str, position: np.ndarray, velocity: np.ndarray) -> None:
        """Put a free object (the ball) at ``position`` (len(scenes), 3), level, moving at ``velocity``
        (len(scenes), 3), in running ``scenes`` now (a referee's placement during play): the object's own sensors
        (those whose object is the body) read its new state in the last step's record; every other record is
        kept."""
        if body not in self.objects:
            raise KeyError(f"the scene has no free body {body!r} (it has {sorted(self.objects)})")
        scenes = np.asarray(scenes, dtype=np.int64)
        qadr, vadr = self.objects[body]
        n = len(scenes)
        qpos = np.column_stack([position, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))])
        qvel = np.column_stack([velocity, np.zeros((n, 3))])
        sensordata = self.sim.write(
            scenes,
            {"qpos": (np.tile(np.arange(qadr, qadr + 7), (n, 1)), qpos),
             "qvel": (np.tile(np.arange(vadr, vadr + 6), (n, 1)), qvel)},
        )  # fmt: skip
        m = self.model
        own = (m.sensor_objid == m.body(body).id) & np.isin(m.sensor_objtype, OBJECT_FRAMES)
        for i in np.flatnonzero(own):  # the object's own sensors (its position and velocity)
            columns = slice(int(m.sensor_adr[i]), int(m.sensor_adr[i] + m.sensor_dim[i]))
            self.sim.substep_sensordata[scenes, -1, columns] = sensordata[:, columns]

    def pending_state(self, scenes: np.ndarray) -> dict[str, np.ndarray]:
        """The full state rows that a kickoff of ``scenes`` starts from: the model's defaults with the objects at
        their pending places (the players' blocks are written over them)."""
        pending = self._pending
        m = self.model
        qpos = pending["qpos"][scenes] if "qpos" in pending else np.tile(m.qpos0, (len(scenes), 1))
        qvel = pending["qvel"][scenes] if "qvel" in pending else np.zeros((len(scenes), m.nv))
        return {"qpos": qpos.copy(), "qvel": qvel.copy(), "act": np.zeros((len(scenes), m.na)),
                "ctrl": np.zeros((len(scenes), m.nu))}  # fmt: skip

    @property
    def time(self) -> np.ndarray:
        return self.sim.time

    def __getstate__(self):
        state = self.__dict__.copy()
        state["spec"], state["_edits"] = None, ()  # an MjSpec and the edits' closures: only building needs them
        return state


class PlayerSimulation:
    """The robot's view of a :class:`SharedScene`: ``num_scenes x players`` simulations (scene-major: simulation
    ``s * players + p`` is player ``p`` of scene ``s``), with the interface of
    :class:`envs.common.simulation.Simulation`.

    Attributes:
        ctrl: the players' next control blocks, (num_sims, n_substeps, robot nu).
        substep_sensordata: the players' sensor values at every physics step of the last block, (num_sims,
            n_substeps, robot nsensordata).
    """

    def __init__(self, scene: SharedScene, robot: Robot):
        self.scene = scene
        self.model = scene.model
        self.num_sims = scene.num_sims
        self.n_substeps = robot.n_substeps
        self._k = scene.num_players
        self._block = scene.block
        single = robot.model
        self.ctrl = np.zeros((self.num_sims, self.n_substeps, single.nu))
        self.substep_sensordata = np.zeros((self.num_sims, self.n_substeps, single.nsensordata))
        root = single.body(robot.root_body).id
        joint = int(single.body_jntadr[root])
        free = joint >= 0 and single.jnt_type[joint] == mujoco.mjtJoint.mjJNT_FREE
        # the robot's root free joint: moved to each player's place as it resets
        self._root = (int(single.jnt_qposadr[joint]), int(single.jnt_dofadr[joint])) if free else None
        # the scene's actuator of each player's robot actuator, (players, robot actuators)
        names = [single.actuator(i).name or _unnamed("actuators", i) for i in range(single.nactuator)]
        actuator = mujoco.mjtObj.mjOBJ_ACTUATOR
        self._actuators = np.array(
            [[mujoco.mj_name2id(scene.model, actuator, f"{p}/{a}") for a in names] for p in scene.players],
            dtype=np.int64,
        )
        self._refresh()

    @property
    def sensordata(self) -> np.ndarray:
        return self.substep_sensordata[:, -1]

    @property
    def time(self) -> np.ndarray:
        return np.repeat(self.scene.sim.time, self._k)

    @property
    def batch(self):
        """The scenes' ``mujoco.batch.Batch`` (a batched scene only)."""
        return self.scene.sim.batch

    def get_data(self, sim: int = 0) -> mujoco.MjData:
        """The ``MjData`` of the scene that holds simulation (player) ``sim``: the whole scene."""
        return self.scene.sim.get_data(sim // self._k)

    def _columns(self, name: str) -> np.ndarray:
        size = self._block[name]
        return np.arange(self._k * size).reshape(self._k, size)

    def _refresh(self, scenes: np.ndarray | None = None) -> None:
        """Copy the players' sensor blocks of ``scenes`` (default every scene) out of the scenes' substep sensor
        values."""
        k, size = self._k, self._block["sensordata"]
        if scenes is None:  # every scene: one copy between views, no gathers
            n = self.scene.num_scenes
            sub = self.scene.sim.substep_sensordata[:, :, : k * size].reshape(n, self.n_substeps, k, size)
            self.substep_sensordata.reshape(n, k, self.n_substeps, size)[...] = sub.transpose(0, 2, 1, 3)
            return
        n = len(scenes)
        sub = self.scene.sim.substep_sensordata[scenes, :, : k * size]
        rows = (scenes[:, None] * k + np.arange(k)).reshape(-1)
        blocks = sub.reshape(n, self.n_substeps, k, size).transpose(0, 2, 1, 3)
        self.substep_sensordata[rows] = blocks.reshape(n * k, self.n_substeps, size)

    def _place(self, ids: np.ndarray, state: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The robot's reset state of players ``ids`` moved to their places: the root's position and heading turned
        and shifted, its world-frame linear velocity turned (its angular velocity is in its own frame)."""
        state = {name: np.array(value, dtype=np.float64) for name, value in state.items()}
        if self._root is None:
            return state
        qadr, vadr = self._root
        x, y, yaw = self.scene.placement[ids].T
        c, s = np.cos(yaw), np.sin(yaw)
        if "qpos" in state:
            q = state["qpos"]
            px, py = q[:, qadr].copy(), q[:, qadr + 1].copy()
            q[:, qadr], q[:, qadr + 1] = x + c * px - s * py, y + s * px + c * py
            q[:, qadr + 3 : qadr + 7] = quat_multiply(yaw_quaternion(yaw), q[:, qadr + 3 : qadr + 7])
        if "qvel" in state:
            v = state["qvel"]
            vx, vy = v[:, vadr].copy(), v[:, vadr + 1].copy()
            v[:, vadr], v[:, vadr + 1] = c * vx - s * vy, s * vx + c * vy
        return state

    def reset(self, ids: np.ndarray, state: dict[str, np.ndarray]) -> None:
        """Reset players ``ids`` to ``state`` (their robot's rows: qpos, qvel, act, ctrl), each at its place. A scene
        all of whose players reset starts over (a kickoff): the model's defaults, its objects at their pending
        places (:meth:`SharedScene.place_object`), then its players; a player reset alone (put back after a fall)
        is written into its running scene, which keeps everything else (the other players' and the scene's sensor
        records of the last step among them)."""
        ids = np.asarray(ids, dtype=np.int64)
        state = self._place(ids, state)
        k = self._k
        scenes, players = ids // k, ids % k
        touched = np.unique(scenes)
        whole = np.array([np.count_nonzero(scenes == s) == k for s in touched], dtype=bool)
        sim = self.scene.sim
        kickoff = touched[whole]
        if len(kickoff):
            full = self.scene.pending_state(kickoff)
            for name in full.keys() & state.keys():
                cols = self._columns(name)
                for row, s in enumerate(kickoff):
                    mine = np.flatnonzero(scenes == s)
                    full[name][row, cols[players[mine]].reshape(-1)] = state[name][mine].reshape(-1)
            sim.reset(kickoff, full)
        self._refresh(kickoff)
        size = self._block["sensordata"]
        for s in touched[~whole]:
            mine = np.flatnonzero(scenes == s)
            columns = {
                name: (self._columns(name)[players[mine]].reshape(1, -1), state[name][mine].reshape(1, -1))
                for name in state
            }
            sensordata = sim.write(np.array([s]), columns)[0]
            # the players written read their new state at every physics step of the record; the others, and the
            # scene's own sensors (the ball's path), keep the last step's record
            for i, p in zip(ids[mine], players[mine], strict=True):
                self.substep_sensordata[i] = sensordata[p * size : (p + 1) * size]

    def step(self, ids: np.ndarray | None = None) -> np.ndarray:
        """Run the control blocks of every player, one scene step each (of the scenes of players ``ids``; a scene is
        stepped whole). (num_sims,) bool: False for every player of a scene that went unstable."""
        k, nu = self._k, self._block["ctrl"]
        ctrl = self.scene.sim.ctrl
        n = self.scene.num_scenes
        ctrl[:, :, : k * nu] = (
            self.ctrl.reshape(n, k, self.n_substeps, nu).transpose(0, 2, 1, 3).reshape(n, self.n_substeps, k * nu)
        )
        if ids is None:
            stable = self.scene.sim.step()
            self._refresh()
        else:
            scenes = np.unique(np.asarray(ids, dtype=np.int64) // k)
            stable = self.scene.sim.step(scenes)
            self._refresh(scenes)
        return np.repeat(np.asarray(stable), k)

    def expand(self, field: str) -> np.ndarray:
        raise ValueError("robots on a shared scene take no per-robot physical parameters (randomize, set_parameters)")

    def set_actuator_gains(self, actuators: np.ndarray, slots: np.ndarray, values: np.ndarray) -> None:
        """Write the gain parameters ``slots`` of the robot's ``actuators`` in every player before the next block:
        ``values`` (num_sims, actuators, slots), players scene-major (see
        :meth:`envs.common.simulation.Simulation.set_actuator_gains`)."""
        scene = self._actuators[:, np.asarray(actuators)].reshape(-1)  # each player's, player-major
        n = self.scene.num_scenes
        self.scene.sim.set_actuator_gains(scene, slots, values.reshape(n, len(scene), len(slots)))

    def set_const(self, ids: np.ndarray) -> None:
        self.expand("")
