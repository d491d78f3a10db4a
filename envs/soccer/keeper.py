"""A single-robot env with a scripted opponent on the field: the learner's view of a scene of two players.

``<Robot>ScoreVsKeeper`` puts the robot (``home_0``) on its field with the ball and the scripted team's keeper
(``away_0``, :class:`envs.soccer.scripted.ScriptedPlayer` with ``keeper=True``): a second robot of the same kind in
the same :class:`~envs.common.match.SharedScene`, stepped natively with it. The robot, task and commands the env
(and its batched twin) sees are views (:class:`LearnerRobot`, :class:`LearnerTask`, :class:`LearnerCommands`) that
hold the learner's rows of every array, so :class:`~envs.common.env.SkitterEnv` and
:class:`~envs.common.vector.SkitterVectorEnv` run unchanged: simulation ``i`` of the env is scene ``i``, its learner
row ``2 i`` and its keeper row ``2 i + 1`` of the robot underneath.

The keeper plays in the commands mode through the robot's reference gait, whatever the learner's mode (the robot's
first mode, which the gait drives, or the commands mode). It reads its own observation (egocentric, as a match's
away player sees), keeps its memory (an escape when stuck) from one step to the next, and draws its sensor noise from
a stream of its own, taken from the learner's at every reset: N single envs and one batched env of N stay identical.
A keeper that falls (the ground rules decide, as for any player) is put back standing beside its goal, on the side
away from the ball, in the next step (as a match's referee does, without the penalty time); the learner's episode
goes on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from envs.soccer.field import BALL_POS
from envs.soccer.scripted import MEMORY, scripted_player
from envs.soccer.steering import Commands

if TYPE_CHECKING:
    from envs.common.match import SharedScene
    from envs.soccer.task import SoccerTask

LEARNER, KEEPER = "home_0", "away_0"


class KeeperMatch:
    """The learner and the scripted keeper in ``scene`` (players ``(LEARNER, KEEPER)``): the views the env runs on.

    Args:
        scene: the scene, built with its two players.
        task: the task over the scene's robot (every row: the learner's and the keeper's); its ``prepare_reset``
            takes scene indices (it places both players and the ball), its ``fallen(state)`` says which rows fell.
        commands: the learner's commands mode over the scene's robot, or None when the learner acts in the robot's
            own mode (the keeper then gets a commands mode of its own).
    """

    def __init__(self, scene: SharedScene, task: SoccerTask, commands: Commands | None):
        if scene.players != (LEARNER, KEEPER):
            raise ValueError(f"a keeper's scene has the players {(LEARNER, KEEPER)}, got {scene.players}")
        self.scene, self.inner_robot, self.inner_task = scene, scene.robot, task
        n, k = scene.num_scenes, scene.num_players
        self.num_sims, self.k = n, k
        self.learner = np.arange(n) * k
        self.keeper = self.learner + 1
        self.steering = commands if commands is not None else Commands(scene.robot)
        self.player = scripted_player(task.layout, self.steering.mode, scene.robot.facts.length, task.field,
                                      self.steering, keeper=True)  # fmt: skip
        self.memory = np.zeros((n, len(MEMORY)))
        self.fresh = np.ones(n, dtype=bool)  # the keeper's memory starts again at its next move
        self.keeper_obs = np.zeros((n, task.layout.size))
        self.keeper_rngs: list[np.random.Generator | None] = [None] * n
        self.noise = 0.0
        self.full: dict[str, np.ndarray] = {}  # the last readings of every row
        self.down = np.zeros(n, dtype=bool)  # keepers that fell in the last step
        self.placed = np.zeros(n * k, dtype=bool)  # rows put back after the last step's physics
        self.put_backs = np.zeros(n)  # each episode's keeper put-backs so far
        self.robot = LearnerRobot(self)
        self.task = LearnerTask(self)
        self.commands = LearnerCommands(self) if commands is not None else None

    # --- rows -----------------------------------------------------------------------------------------------------
    def rows(self, ids: np.ndarray) -> np.ndarray:
        """The rows (learner, keeper) of scenes ``ids``, in order."""
        return (np.asarray(ids, dtype=np.int64)[:, None] * self.k + np.arange(self.k)).reshape(-1)

    def row_rngs(self, ids: np.ndarray, rngs: Sequence[np.random.Generator | None]) -> list:
        """The streams of :meth:`rows` of ``ids``: the learner's given, the keeper's its own (None with None)."""
        out: list = []
        for i, rng in zip(np.asarray(ids).tolist(), rngs, strict=True):
            out += [rng, None if rng is None else self.keeper_rngs[i]]
        return out

    def expand(self, stepped: bool | np.ndarray) -> bool | np.ndarray:
        """A per-simulation ``stepped`` as one per row, the rows put back after the step not stepped."""
        if isinstance(stepped, np.ndarray):
            stepped = np.repeat(stepped, self.k)
        if self.placed.any():
            stepped = np.broadcast_to(stepped, self.placed.shape) & ~self.placed
        return stepped

    # --- the keeper ---------------------------------------------------------------------------------------------
    def keeper_commands(self) -> np.ndarray:
        """The keeper's robot commands for the next step, from its last observation and its memory."""
        action, self.memory = self.player.predict(self.keeper_obs, self.memory, self.fresh)
        self.fresh[:] = False
        return self.steering.robot_commands(action, self.keeper)

    def put_back(self, scenes: np.ndarray) -> None:
        """Stand the fallen keepers of ``scenes`` beside their goal, facing the field, at whichever of
        :meth:`return_places` lies furthest from the ball and the learner; their rows are not stepped in this step's
        readings (:meth:`expand`)."""
        places = self.return_places()
        ball = self.scene.scene_sensor(BALL_POS)[scenes, :2]
        learner = self.full["position"][self.learner[scenes], :2]
        clearance = np.minimum(np.linalg.norm(places[None, :, :2] - ball[:, None], axis=2),
                               np.linalg.norm(places[None, :, :2] - learner[:, None], axis=2))  # fmt: skip
        rows = self.keeper[scenes]
        self.scene.placement[rows] = places[np.argmax(clearance, axis=1)]
        self.inner_robot.reset(rows, [self.keeper_rngs[s] for s in scenes], self.noise, None)
        self.steering.reset(rows)
        self.fresh[scenes] = True
        self.placed[rows] = True
        self.put_backs[scenes] += 1

    def return_places(self) -> np.ndarray:
        """Where a fallen keeper may come back, (4, 3) (x, y, heading): beside either post, a body length out, and
        three body lengths out, half a body length in from the goal line, facing the field."""
        field, length = self.inner_task.field, self.inner_robot.facts.length
        x = field.half_length - 0.5 * length
        ys = [side * (0.5 * field.goal_width + out * length) for out in (1.0, 3.0) for side in (1.0, -1.0)]
        return np.array([[x, y, math.pi] for y in ys])


class _View:
    """What the view does not hold itself comes from what it views."""

    _target: str

    def __init__(self, match: KeeperMatch):
        self._match = match

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):  # never forwarded: pickling and copying look these up before __dict__ is filled
            raise AttributeError(name)
        return getattr(getattr(self._match, self._target), name)


class LearnerRobot(_View):
    """The robot as the env sees it: the learner's rows (``num_sims``: one per scene) of what the env calls (reset,
    command, step, read, telemetry). Whatever else it is asked comes from the robot underneath, whose arrays and
    methods (``sim``, ``sensor``, ``battery``, ...) hold both players' rows: learner ``2 i``, keeper ``2 i + 1``."""

    _target = "inner_robot"

    @property
    def num_sims(self) -> int:
        return self._match.num_sims

    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], noise: float,
              options: Mapping | None) -> None:  # fmt: skip
        """Scenes ``ids`` kick off: both players reset at their places; the keeper's stream is drawn from the
        learner's."""
        m = self._match
        ids = np.asarray(ids, dtype=np.int64)
        for i, rng in zip(ids.tolist(), rngs, strict=True):
            m.keeper_rngs[i] = np.random.default_rng(int(rng.integers(2**63)))
        m.noise = noise
        rows = m.rows(ids)
        m.inner_robot.reset(rows, m.row_rngs(ids, rngs), noise, options)
        m.steering.reset(rows)
        m.fresh[ids], m.down[ids], m.placed[rows], m.put_backs[ids] = True, False, False, 0.0

    def command(self, command: np.ndarray) -> None:
        m = self._match
        full = np.zeros((m.num_sims * m.k, command.shape[1]))
        full[m.learner] = command
        full[m.keeper] = m.keeper_commands()
        m.inner_robot.command(full)

    def step(self, ids: np.ndarray | None = None) -> np.ndarray:
        m = self._match
        stable = m.inner_robot.step(None if ids is None else m.rows(ids))
        down = m.down.copy() if ids is None else m.down & np.isin(np.arange(m.num_sims), ids)
        m.down[:] = False
        if down.any():
            m.put_back(np.flatnonzero(down))
        return np.asarray(stable)[m.learner]

    def read(self, rngs: Sequence[np.random.Generator | None], stepped: bool | np.ndarray = True) -> dict:
        m = self._match
        m.full = m.inner_robot.read(m.row_rngs(np.arange(m.num_sims), rngs), m.expand(stepped))
        return {key: value[m.learner] for key, value in m.full.items()}

    def telemetry(self, readings: dict[str, np.ndarray], sensordata: np.ndarray | None = None) -> np.ndarray:
        """The learner's telemetry rows after the step that gave ``readings`` (read from every row's)."""
        m = self._match
        if sensordata is not None:
            raise ValueError("the learner's view reads its own sensors: no sensordata")
        return m.inner_robot.telemetry(m.full)[m.learner]

    def physics_telemetry(self, readings: dict[str, np.ndarray]) -> np.ndarray:
        m = self._match
        return m.inner_robot.physics_telemetry(m.full)[m.learner]


class LearnerTask(_View):
    """The task as the env sees it: the learner's rows of its states and observations."""

    _target = "inner_task"

    def prepare_reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None) -> None:
        self._match.inner_task.prepare_reset(ids, rngs, options)

    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None, readings) -> None:
        m = self._match
        m.inner_task.reset(m.rows(ids), m.row_rngs(ids, rngs), options, m.full)

    def update(self, readings: dict[str, np.ndarray], stepped: np.ndarray | None = None) -> dict[str, np.ndarray]:
        m = self._match
        full_stepped = None if stepped is None else np.repeat(stepped, m.k)
        if m.placed.any():  # keepers put back: they start again in their new place
            rows = np.flatnonzero(m.placed)
            m.inner_task.reset(rows, [m.keeper_rngs[r // m.k] for r in rows], None, m.full)
            full_stepped = (np.ones(len(m.placed), dtype=bool) if full_stepped is None else full_stepped) & ~m.placed
            m.placed[:] = False
        state = m.inner_task.update(m.full, full_stepped)
        fell = m.inner_task.fallen(state)[m.keeper]
        m.down = fell if stepped is None else fell & stepped
        return {key: value[m.learner] for key, value in state.items()}

    def info(self, readings: dict[str, np.ndarray], state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The task's info of the learner, and where the keeper is (``keeper_x``, ``keeper_y``, m) and how often it
        was put back in the episode (``keeper_put_back``)."""
        m = self._match
        keeper = m.full["position"][m.keeper]
        return {**m.inner_task.info(readings, state), "keeper_x": keeper[:, 0].copy(), "keeper_y": keeper[:, 1].copy(),
                "keeper_put_back": m.put_backs.copy()}  # fmt: skip

    def observe(self, readings: dict[str, np.ndarray]) -> np.ndarray:
        m = self._match
        full = m.inner_task.observe(m.full)
        m.keeper_obs = full[m.keeper]
        return full[m.learner]


class LearnerCommands(_View):
    """The learner's commands mode (forward speed and turn rate) on its rows of the robot's steering."""

    _target = "steering"

    def reset(self, ids: np.ndarray) -> None:
        m = self._match
        m.steering.reset(m.rows(ids))

    def robot_commands(self, actions: np.ndarray) -> np.ndarray:
        m = self._match
        return m.steering.robot_commands(actions, m.learner)
