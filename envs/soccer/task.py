"""What every soccer task computes for its players: the ball and the goals as each player sees them, goals scored.

A :class:`SoccerTask` runs on a robot built on a :class:`~envs.common.match.SharedScene` whose players are named
``home_<i>`` and ``away_<i>``: the home team attacks the goal at +x, the away team the one at -x. Every observation is
egocentric (in the player's own frame, its heading measured against the direction it attacks), so a player's view
does not depend on its side: turning the field by half a turn and swapping the teams swaps their observations.

It keeps the walking tasks' ground rules and falls (envs/common/locomotion.py): a fall ends a single robot's episode
and takes a player off the field in a match.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from envs.common.locomotion import GRACE_TIME, LocomotionTask
from envs.common.match import SharedScene
from envs.common.robot import Robot, check_flag, check_number
from envs.soccer.field import BALL_POS, BALL_VEL, HEAD_AXIS, TOUCH, Field

BALL_NOISE = 0.05  # what a player sees of the ball and the others: N(0, 5% of their distance) per axis
HOME, AWAY = "home", "away"


def team_of(player: str) -> str:
    """``home`` or ``away``, from a player's name (``home_0``, ``away_2``)."""
    team = player.split("_")[0]
    if team not in (HOME, AWAY):
        raise ValueError(f"a player's name starts with home_ or away_, got {player!r}")
    return team


class SoccerTask(LocomotionTask):
    """The ball, the goals and the other players as each player sees them; goals scored; the ground rules.

    Observations, after the robot's senses (see ``observation_structure``): ``heading_error`` (sin, cos of the
    player's heading, integrated from its gyro and its known heading at kickoff, against the direction it attacks),
    ``ball`` and ``ball_velocity`` (x, y in the player's frame, with noise of ``ball_noise`` times the ball's
    distance), ``ball_visible`` (1, or 0 outside ``field_of_view`` where the ball reads as zeros; the field of view
    is centred on the ``head``'s view where the robot has one, the Bioloid's), ``goal`` and
    ``own_goal`` (the centres of the goal it attacks and of its own, in its frame) and, in a match, ``teammates`` and
    ``opponents`` (their positions in its frame, noisy as the ball, in the order of their names).
    """

    metrics: ClassVar[dict[str, str]] = {**LocomotionTask.metrics}

    def __init__(
        self,
        robot: Robot,
        scene: SharedScene,
        field: Field,
        sparse: bool = False,
        ball_noise: float = BALL_NOISE,
        field_of_view: float | None = None,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        head: str | None = None,
    ):
        self.scene, self.field = scene, field
        self.sparse = check_flag("sparse", sparse)
        self.ball_noise = check_number("ball_noise", ball_noise, 0)
        self.field_of_view = (
            None if field_of_view is None else check_number("field_of_view", field_of_view, 0, 2 * math.pi, True)
        )
        players = scene.players
        k, n = len(players), robot.num_sims
        teams = [team_of(p) for p in players]
        self._home = [p for p, t in zip(players, teams, strict=True) if t == HOME]
        self._away = [p for p, t in zip(players, teams, strict=True) if t == AWAY]
        self.team_size = max(len(self._home), len(self._away))
        if self._away and len(self._home) != len(self._away):
            raise ValueError(f"the teams must be of one size, got {len(self._home)} and {len(self._away)}")
        self._k = k
        self._scene_of = np.arange(n) // k
        self._side = np.tile([1.0 if t == HOME else -1.0 for t in teams], n // k)  # the x each player attacks
        self._is_home = self._side > 0
        self._attacked_heading = np.where(self._is_home, 0.0, math.pi)  # the field heading of the x it attacks
        # for each player: the indices (in its scene) of its teammates and of its opponents, in name order
        self._mates = [[j for j in range(k) if j != i and teams[j] == teams[i]] for i in range(k)]
        self._opponents = [[j for j in range(k) if teams[j] != teams[i]] for i in range(k)]
        self._order = np.array([self._mates[i] + self._opponents[i] for i in range(k)], dtype=np.int64).reshape(
            k, k - 1
        )
        # every player's contact sensor with the ball: their columns in the scene's sensor values, read in one gather
        touches = [scene.sensors[f"{TOUCH}{p}"] for p in players]
        columns = np.concatenate([np.arange(sl.start, sl.stop) for sl in touches])
        # in one run of columns (as the scene builds them): a slice, a view where a gather would copy
        contiguous = len(columns) and np.array_equal(columns, np.arange(columns[0], columns[0] + len(columns)))
        self._touch_columns = slice(int(columns[0]), int(columns[-1]) + 1) if contiguous else columns
        self._head_sensors = [f"{HEAD_AXIS}{p}" for p in players] if head is not None else None
        self._ball_obs = np.zeros((n, 5))
        self._goals_obs = np.zeros((n, 4))
        self._others_obs = np.zeros((n, 2 * (k - 1)))
        self._start_yaw = np.zeros(n)
        self._ball_distance = np.zeros(n)
        self._goal_distance = np.zeros(n)
        self.last_scene_goals = (np.zeros(n // k, dtype=bool), np.zeros(n // k, dtype=bool))  # goals()' last
        super().__init__(robot, False, 0.0, max_tilt, terminate_when_unhealthy, height_band, grace_time)
        self._draws = np.empty((n, 2 * (self._k + 1)))
        # each row's draw of what it sees: its stream's standard_normal (set at its reset) into its row of _draws
        self._normals: list[Any] = [None] * n
        self._rows = np.arange(n)
        self._attacked_x = self._side * field.half_length  # the x of the goal each player attacks
        # the goal attacked and the own goal's centres, per player
        self._goal_points = self._attacked_x[:, None, None] * np.array([[1.0, 0.0], [-1.0, 0.0]])
        self._goal_line = field.half_length + field.ball.radius  # the ball's centre past it: the whole ball is

    # --- layout ---------------------------------------------------------------------------------------------------
    def _command_structure(self) -> dict[str, int]:
        structure = {"ball": 2, "ball_velocity": 2, "ball_visible": 1, "goal": 2, "own_goal": 2}
        if self._k > 1:
            structure.update({"teammates": 2 * (self.team_size - 1), "opponents": 2 * len(self._opponents[0])})
        return {name: size for name, size in structure.items() if size}

    def _command_obs(self) -> list[np.ndarray]:
        return [self._ball_obs, self._goals_obs, self._others_obs]

    def _target_heading(self, elapsed: np.ndarray) -> np.ndarray:
        # the heading error is the field heading (gyro heading + heading at kickoff) against the attacked direction
        return self._attacked_heading - self._start_yaw

    # --- the contract ---------------------------------------------------------------------------------------------
    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None, readings) -> None:
        self._start_yaw[ids] = self.scene.placement[ids, 2]
        super().reset(ids, rngs, options, readings)
        for i, rng in zip(ids, rngs, strict=True):  # each player's stream, for what it sees at every step
            self._normals[i] = rng.standard_normal
        ball = self.ball_moved(readings, ids)
        self._observe(readings, ball, ids)

    def ball_moved(self, readings: dict[str, np.ndarray], ids: np.ndarray) -> dict[str, np.ndarray]:
        """The ball was put somewhere (a reset, a referee's throw-in): players ``ids``' shaping terms count from its
        new place, not across the jump. Returns the ball's state as every player sees it."""
        ball, to_goal = self._ball_state(readings)
        self._ball_distance[ids] = ball["distance"][ids]
        self._goal_distance[ids] = to_goal[ids]
        return ball

    def update(self, readings: dict[str, np.ndarray], stepped: np.ndarray | None = None) -> dict[str, np.ndarray]:
        state = super().update(readings, stepped)
        ball, to_goal = self._ball_state(readings)
        length = self.length
        ids = self._rows if stepped is None else np.flatnonzero(stepped)
        approach = (self._ball_distance - ball["distance"]) / length
        progress = (self._goal_distance - to_goal) / length
        self._ball_distance, self._goal_distance = ball["distance"], to_goal
        scored, conceded = self.goals()
        touches = self._touches()
        self._observe(readings, ball, ids, state["yaw"])
        return {
            **state,
            "ball_x": ball["position"][:, 0].copy(),
            "ball_y": ball["position"][:, 1].copy(),
            "ball_distance": ball["distance"] / length,
            "approach": approach,
            "ball_progress": progress,
            "scored": scored.astype(np.float64),
            "conceded": conceded.astype(np.float64),
            "touched": (touches > 0).astype(np.float64),
        }

    def _touches(self) -> np.ndarray:
        """(n,) each player's largest contact force with the ball over the last step's physics steps (one gather of
        every player's touch sensor)."""
        values = self.scene.sim.substep_sensordata[..., self._touch_columns]  # (scenes, substeps, players x size)
        return values.reshape(*values.shape[:2], self._k, -1).max(axis=(1, 3)).reshape(-1)

    def _ball_state(self, readings: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], np.ndarray]:
        position = self.scene.scene_sensor(BALL_POS)[self._scene_of]
        velocity = self.scene.scene_sensor(BALL_VEL)[self._scene_of]
        offset = position[:, :2] - readings["position"][:, :2]
        to_goal = np.hypot(self._attacked_x - position[:, 0], position[:, 1])
        return {"position": position, "velocity": velocity, "offset": offset,
                "distance": np.hypot(offset[:, 0], offset[:, 1])}, to_goal  # fmt: skip

    def scene_goals(self) -> tuple[np.ndarray, np.ndarray]:
        """(into the goal at +x, into the goal at -x) per scene: whether the whole ball was past that goal line,
        between the posts and under the crossbar, at any physics step of the last control step."""
        f = self.field
        path = self.scene.scene_sensor(BALL_POS, substeps=True)
        x, y, z = path[..., 0], path[..., 1], path[..., 2]
        line = self._goal_line
        if not (np.abs(x) > line).any():  # the ball past neither goal line (most steps): no goal anywhere
            return np.zeros(len(path), dtype=bool), np.zeros(len(path), dtype=bool)
        mouth = (np.abs(y) < 0.5 * f.goal_width) & (z < f.goal_height)
        return ((x > line) & mouth).any(axis=1), ((x < -line) & mouth).any(axis=1)

    def goals(self) -> tuple[np.ndarray, np.ndarray]:
        """(scored, conceded) per player: its team's goal, its own goal. Keeps the scenes' goals of this step in
        :attr:`last_scene_goals`, for the match that counts them."""
        plus, minus = self.last_scene_goals = self.scene_goals()
        if not (plus.any() or minus.any()):  # no goal in any scene (most steps)
            return np.zeros(len(self._scene_of), dtype=bool), np.zeros(len(self._scene_of), dtype=bool)
        plus, minus = plus[self._scene_of], minus[self._scene_of]
        home = self._is_home
        return np.where(home, plus, minus), np.where(home, minus, plus)

    def _observe(self, readings, ball, ids: np.ndarray, yaw: np.ndarray | None = None) -> None:
        """The ball, the goals and the others as each player sees them, in its own frame; the noise of row ``i`` is
        one draw from its own stream (the ball's position and velocity, then the others). ``yaw``: each row's, where
        the caller has it (the locomotion task's update computes it from the same quaternion, the same way)."""
        if yaw is None:
            quat = readings["quaternion"]
            w, x, y, z = quat[:, 0], quat[:, 1], quat[:, 2], quat[:, 3]
            yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
        c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        pos = readings["position"][:, :2]
        n, k = len(pos), self._k
        every = len(ids) == n
        rows = slice(None) if every else ids  # every row (the usual step) without a gather
        # every world-frame vector a player sees, turned into its frame in one go: the ball's offset and velocity,
        # the goals' offsets (attacked, own), the others' offsets
        world = np.empty((n, 4 + k - 1, 2))
        world[:, 0], world[:, 1] = ball["offset"], ball["velocity"][:, :2]
        np.subtract(self._goal_points, pos[:, None, :], out=world[:, 2:4])
        if k > 1:
            in_scene = pos.reshape(-1, k, 2)
            others = world.reshape(-1, k, 4 + k - 1, 2)[:, :, 4:]  # a view of world's rows, scene by scene
            np.subtract(in_scene[:, self._order, :], in_scene[:, :, None, :], out=others)
        cw, sw = c[:, :, None] * world, s[:, :, None] * world  # (c x, c y) and (s x, s y) of every vector
        turned = np.empty(world.shape)
        np.add(cw[..., 0], sw[..., 1], out=turned[..., 0])  # c x + s y
        np.subtract(cw[..., 1], sw[..., 0], out=turned[..., 1])  # c y - s x
        seen, goals, others = turned[:, :2], turned[:, 2:4], turned[:, 4:]
        if self.ball_noise > 0 and len(ids):
            # standard_normal(out=) is normal(0, 1)'s values at half its cost
            for i in range(n) if every else np.asarray(ids).tolist():
                self._normals[i](out=self._draws[i])
            draws = self._draws[rows]
            sigma = np.empty((len(ids), k))
            sigma[:, 0] = ball["distance"][rows]
            np.hypot(others[rows, :, 0], others[rows, :, 1], out=sigma[:, 1:])
            sigma *= self.ball_noise
            seen[rows] += draws[:, :4].reshape(-1, 2, 2) * sigma[:, :1, None]
            if k > 1:
                others[rows] += draws[:, 4:].reshape(-1, k - 1, 2) * sigma[:, 1:, None]
        ball_obs = self._ball_obs
        if self.field_of_view is None:
            ball_obs[rows, :4] = seen.reshape(n, 4)[rows]
            ball_obs[rows, 4] = 1.0
        else:
            bearing = np.arctan2(seen[:, 0, 1], seen[:, 0, 0])  # of the ball, in the body's frame
            if self._head_sensors is not None:  # the head's view, panned and tilted by the neck, against the body
                axis = np.stack([self.scene.scene_sensor(s) for s in self._head_sensors], axis=1).reshape(n, 3)
                bearing = np.angle(np.exp(1j * (bearing - (np.arctan2(-axis[:, 1], -axis[:, 0]) - yaw))))
            visible = (np.abs(bearing) <= 0.5 * self.field_of_view).astype(np.float64)
            ball_obs[rows] = np.concatenate([seen.reshape(n, 4) * visible[:, None], visible[:, None]], axis=1)[rows]
        self._others_obs[rows] = others.reshape(n, -1)[rows]
        self._goals_obs = goals.reshape(n, 4)

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        return self.ground_metrics(info)
