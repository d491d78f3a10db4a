"""The soccer academy: one robot on its soccer field, with a ball, learning the game's first skills.

``<Robot>GoToBall``: reach the ball and touch it. ``<Robot>ScoreEmptyGoal``: put the ball into the empty goal at +x.
``<Robot>ScoreVsKeeper``: score past the scripted team's keeper, a second robot of the same kind
(envs/soccer/keeper.py). All run the robot's own action modes and keep the walking tasks' ground rules and falls (a
crawler or a faller ends its episode), on the robot's field (envs/soccer/field.py) in a
:class:`~envs.common.match.SharedScene` of one player (two with the keeper).
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces

from envs.common.env import SkitterEnv, entry_point
from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME
from envs.common.match import SharedScene
from envs.common.robot import Robot, check_flag
from envs.common.vector import vector_entry_point
from envs.soccer.field import BALL, Field, field_edit
from envs.soccer.keeper import KEEPER, KeeperMatch
from envs.soccer.robots import HEADS
from envs.soccer.scripted import KEEP
from envs.soccer.steering import COMMANDS, Commands
from envs.soccer.task import BALL_NOISE, SoccerTask

PLAYER = "home_0"  # the academy's one player: the home team's, attacking the goal at +x
# s, per robot (its name in ids): long enough for the robot's scripted player to win most of its GoToBall and
# ScoreEmptyGoal episodes in the commands mode. 20 s does for the roach (20 and 14 of 20) and the xJüs (20 and 10);
# the Bioloid, whose trot cruises at 0.07 m/s (a quarter of a body length a second against the xJüs's 1.3), won 3
# and 0 of 20 in 20 s, and in 120 s 17 and 13 (seeds 1000-1019, 2026-11-30; docs/soccer.md)
EPISODE_SECONDS = {"Roach": 20.0, "Xjus": 20.0, "Bioloid": 120.0}
APPROACH_WEIGHT = 0.1  # per body length closed: 10 lengths nearer the ball are worth a goal
PROGRESS_WEIGHT = 0.2  # per body length the ball moves nearer the goal's centre
MAX_DRAWS = 100  # draws of a start place before the fallback

# each robot's academy versions: the ids carry the last
HISTORY = {
    "Roach": ["first version.",
              "the commands mode spins the robot on the spot, its sides' clocks running opposite ways, where one side "
              "running alone pivoted it about the other; its gait map is new. The joints mode is unchanged.",
              "the robot's firmware is the real one, a voltage-mode PID with the lab's gains, as in RoachWalk-v3: "
              "the gait mode and the commands mode (whose gait map is measured again) change; the duty mode does not."],
    "Xjus": ["first version.",
             "the commands mode turns on the spot, one side's legs running the Buehler clock backward (as RHex turns "
             "in place), where the sweep difference turned it only at speed; its gait map is new. The joints mode is "
             "unchanged."],
    "Bioloid": ["first version.",
                "the commands mode turns the trot by sideways steps of the feet (front and back opposite, through the "
                "abduction servos) instead of a shortened stride, with a new gait map; the joints mode is "
                "unchanged.",
                "episodes last 120 s (were 20 s, in which the scripted player reached the ball in 3 of 20 and "
                "scored in none)."],
}  # fmt: skip


class AcademyTask(SoccerTask):
    """One robot of the home team and the ball on its field: what the academy's tasks share (placing the robot and
    the ball, ending the episode on the task's success or an own goal). Observations: :class:`SoccerTask`'s."""

    metrics: ClassVar[dict[str, str]] = {
        **SoccerTask.metrics,
        "success": "1 if the episode ended in the task's success (the ball touched, a goal scored), else 0",
        "ball_distance": "the ball's distance from the robot at the episode's end, body lengths",
    }
    binary_metrics: ClassVar[tuple[str, ...]] = ("success",)
    players: ClassVar[tuple[str, ...]] = (PLAYER,)  # the scene's players: the learner's first
    # the task's own version history, or one per robot (None: the robot's academy's)
    history: ClassVar[tuple[str, ...] | Mapping[str, tuple[str, ...]] | None] = None

    # --- placing --------------------------------------------------------------------------------------------------
    def prepare_reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None) -> None:
        """Draw (or take from ``options``: ``robot`` (x, y, heading), ``ball`` (x, y)) the robot's and the ball's
        places for the episodes starting in ``ids``, before the robot resets."""
        options = options or {}
        length = self.robot.facts.length
        radius = self.field.ball.radius
        for i, rng in zip(ids, rngs, strict=True):
            robot_place, ball_xy = self.draw_places(rng, length)
            if "robot" in options:
                robot_place = self._option_place(options["robot"], 3, "robot")
            if "ball" in options:
                ball_xy = self._option_place(options["ball"], 2, "ball")
            self.place_players(i, rng, robot_place, ball_xy, options)
            self.scene.place_object(np.array([i]), BALL, np.array([[*ball_xy, radius]]), np.zeros((1, 3)))

    def place_players(self, scene: int, rng: np.random.Generator, robot: np.ndarray, ball: np.ndarray,
                      options: Mapping) -> None:  # fmt: skip
        """Set the places of scene ``scene``'s players for its next reset: the robot's (the scene's only player)."""
        self.scene.placement[scene] = robot

    @abstractmethod
    def draw_places(self, rng: np.random.Generator, length: float) -> tuple[np.ndarray, np.ndarray]:
        """((x, y, heading) of the robot, (x, y) of the ball) for one episode."""

    def _option_place(self, value: Any, size: int, name: str) -> np.ndarray:
        try:
            place = np.asarray(value, dtype=np.float64) if not isinstance(value, str | bytes) else np.zeros(0)
        except (TypeError, ValueError):  # a mapping, a ragged list: not numbers
            place = np.zeros(0)
        hl, hw = self.field.half_length, self.field.half_width
        if place.shape != (size,) or not np.isfinite(place).all() or abs(place[0]) > hl or abs(place[1]) > hw:
            raise ValueError(
                f"options[{name!r}] must be {size} finite numbers with x, y inside the field "
                f"(|x| <= {hl:g}, |y| <= {hw:g} m), got {value!r}"
            )
        return place

    def _inside(self, xy: np.ndarray, margin: float) -> np.ndarray:
        """``xy`` moved inside the field's lines by at least ``margin``."""
        hl, hw = self.field.half_length - margin, self.field.half_width - margin
        return np.array([np.clip(xy[0], -hl, hl), np.clip(xy[1], -hw, hw)])

    # --- ending ---------------------------------------------------------------------------------------------------
    def terminated(self, state: dict[str, np.ndarray]) -> np.ndarray:
        return super().terminated(state) | self.success(state).astype(bool) | (state["conceded"] > 0)

    @abstractmethod
    def success(self, state: dict[str, np.ndarray]) -> np.ndarray:
        """(n,) bool: the episode ended in the task's success."""

    def fell(self, state: dict[str, np.ndarray], terminated: np.ndarray) -> np.ndarray:
        return terminated & ~self.success(state) & ~(state["conceded"] > 0)

    def info(self, readings: dict[str, np.ndarray], state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {**state, "success": self.success(state).astype(np.float64)}

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        return {**self.ground_metrics(info), "success": float(info.get("success", 0.0)),
                "ball_distance": float(info.get("ball_distance", float("nan")))}  # fmt: skip


class GoToBallTask(AcademyTask):
    """Reach the ball and touch it: +1 on the touch (the episode ends), and the distance closed as shaping."""

    name = "go_to_ball"
    history: ClassVar[Mapping[str, tuple[str, ...]]] = {
        robot: (*entries, "the robot starts 2 to 8 body lengths from the ball, both at least 2 inside the lines, drawn "
                "again until they are; the robot's place used to be moved inside the lines, which put 8.5% of the "
                "starts within a body length of the ball (4.9% within half of one: touched at once, or overlapping)")
        for robot, entries in HISTORY.items()
    }  # fmt: skip
    distance = (2.0, 8.0)  # body lengths between the robot and the ball at the start
    margin = 2.0  # body lengths inside the lines, for the ball and the robot

    def draw_places(self, rng: np.random.Generator, length: float) -> tuple[np.ndarray, np.ndarray]:
        inner = np.array([self.field.half_length, self.field.half_width]) - self.margin * length
        ball = rng.uniform(-1.0, 1.0, 2) * inner
        for _ in range(MAX_DRAWS):  # the share of an annulus about a ball in a corner is about a quarter
            bearing = rng.uniform(-np.pi, np.pi)
            robot = ball + rng.uniform(*self.distance) * length * np.array([np.cos(bearing), np.sin(bearing)])
            if (np.abs(robot) <= inner).all():
                break
        else:  # not met in practice (0.75 ** 100): the nearest place toward the field's centre
            norm = float(np.linalg.norm(ball))
            robot = ball - self.distance[0] * length * (ball / norm if norm > 0.0 else np.array([1.0, 0.0]))
        return np.array([*robot, rng.uniform(-np.pi, np.pi)]), ball

    def success(self, state: dict[str, np.ndarray]) -> np.ndarray:
        return state["touched"] > 0

    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        terms = {"touch": state["touched"].copy(), "conceded": -state["conceded"]}
        if not self.sparse:
            terms["approach"] = APPROACH_WEIGHT * state["approach"]
        return terms


class ScoreEmptyGoalTask(AcademyTask):
    """Score into the empty goal at +x: +1 on a goal (the episode ends; -1 for an own goal), and the distance closed
    to the ball and the ball's progress toward the goal as shaping."""

    name = "score_empty_goal"
    ball_out = (1.5, 5.0)  # body lengths between the ball and the goal line

    def draw_places(self, rng: np.random.Generator, length: float) -> tuple[np.ndarray, np.ndarray]:
        f = self.field
        ball = np.array([f.half_length - rng.uniform(*self.ball_out) * length,
                         rng.uniform(-1.0, 1.0) * (0.5 * f.goal_width + 1.5 * length)])  # fmt: skip
        ball = self._inside(ball, length)
        away = ball - np.array([f.half_length, 0.0])
        bearing = math.atan2(away[1], away[0]) + rng.uniform(-1.0, 1.0)  # behind the ball, seen from the goal
        robot = self._inside(ball + rng.uniform(1.5, 3.0) * length * np.array([np.cos(bearing), np.sin(bearing)]),
                             0.5 * length)  # fmt: skip
        facing = math.atan2(*(ball - robot)[::-1]) + rng.uniform(-0.8, 0.8)
        return np.array([*robot, facing]), ball

    def success(self, state: dict[str, np.ndarray]) -> np.ndarray:
        return state["scored"] > 0

    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        terms = {"goal": state["scored"] - state["conceded"]}
        if not self.sparse:
            terms["approach"] = APPROACH_WEIGHT * state["approach"]
            terms["ball_progress"] = PROGRESS_WEIGHT * state["ball_progress"]
        return terms


class ScoreVsKeeperTask(ScoreEmptyGoalTask):
    """Score past the scripted keeper (a second robot of the same kind, ``away_0``, keeping the goal at +x): +1 on a
    goal (the episode ends; -1 for an own goal), and the distance closed to the ball and the ball's progress toward
    the goal as shaping. The robot sees the keeper (``opponents``) as it sees the ball. A keeper that falls is put
    back standing beside its goal (envs/soccer/keeper.py); the episode goes on."""

    name = "score_vs_keeper"
    players = (PLAYER, KEEPER)
    history: ClassVar[Mapping[str, tuple[str, ...]]] = {
        "Roach": ("first version.", "the robot's and the keeper's firmware is the real one, as in RoachWalk-v3."),
        "Xjus": ("first version.",),
        "Bioloid": ("first version.", "episodes last 120 s (were 20 s)."),
    }
    ball_out = (3.0, 6.0)

    def place_players(self, scene: int, rng: np.random.Generator, robot: np.ndarray, ball: np.ndarray,
                      options: Mapping) -> None:  # fmt: skip
        """The robot's place and the keeper's, between the ball and its goal (or ``options["keeper"]``: (x, y,
        heading)); a robot and a keeper placed by ``options`` less than a body length apart are refused."""
        length = self.robot.facts.length
        keeper = self.keeper_place(rng, ball, length)
        if "keeper" in options:
            keeper = self._option_place(options["keeper"], 3, "keeper")
        placed = "keeper" in options or "robot" in options  # the draws keep them apart themselves
        if placed and np.hypot(*(keeper[:2] - robot[:2])) < length:
            raise ValueError(f"options: the keeper {keeper.tolist()} and the robot {robot.tolist()} must stand a body "
                             f"length ({length:g} m) apart or more")  # fmt: skip
        self.scene.placement[2 * scene] = robot
        self.scene.placement[2 * scene + 1] = keeper

    def keeper_place(self, rng: np.random.Generator, ball: np.ndarray, length: float) -> np.ndarray:
        """Where the scripted keeper stands at the start: as it plays, ``KEEP`` body lengths out from its goal's
        centre toward the ball, facing the ball, within a tenth of a body length and 0.1 rad."""
        goal = np.array([self.field.half_length, 0.0])
        toward = ball - goal
        reach = min(KEEP * length, float(np.hypot(*toward)))
        place = goal + toward / max(float(np.hypot(*toward)), 1e-9) * reach
        place = place + rng.uniform(-0.1, 0.1, 2) * length
        facing = math.atan2(*(ball - place)[::-1]) + rng.uniform(-0.1, 0.1)
        return np.array([*place, facing])

    def fallen(self, state: dict[str, np.ndarray]) -> np.ndarray:
        """(rows,) bool: which rows fell or broke the ground rules (the keeper's decide when it is put back)."""
        return SoccerTask.terminated(self, state)


class AcademyEnv(SkitterEnv):
    """A robot alone on its soccer field with a ball (see :class:`AcademyTask`); subclasses (:func:`make_academy`)
    name the robot, the field and the task.

    Args:
        action_mode, control_freq: the robot's (default its first mode, at its rate), or ``"commands"``: forward
            speed and turn rate, run by the robot's reference gait through its gait map, as in matches
            (envs/soccer/steering.py).
        kick: in the commands mode, a third action, ``kick``, for a robot that kicks (the Bioloid,
            envs/bioloid/kick.py; off by default: a random policy would be kicking nearly all the time).
        sensor_noise: the IMU's noise and bias.
        sparse, ball_noise, field_of_view, max_tilt, terminate_when_unhealthy, height_band, grace_time: the task's
            (:class:`envs.soccer.task.SoccerTask`).
        reset_noise_scale, telemetry, render_mode, width, height: as every env's. ``randomize`` is not taken: the
            robot shares its scene with the field, and per-robot parameters are refused there.
    """

    robot_class: ClassVar[type[Robot]]
    task_class: ClassVar[type[AcademyTask]]
    field: ClassVar[Field]

    def __init__(
        self,
        action_mode: str | None = None,
        control_freq: float | None = None,
        sensor_noise: bool = True,
        sparse: bool = False,
        ball_noise: float = BALL_NOISE,
        field_of_view: float | None = None,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: Sequence[float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        telemetry: bool = False,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
        kick: bool = False,
    ):
        robot_class = self.robot_class
        if check_flag("kick", kick) and action_mode != COMMANDS:
            raise ValueError(f"kick=True is the commands mode's kick action: give action_mode={COMMANDS!r}")
        first = next(iter(robot_class.action_modes))
        if action_mode is not None and action_mode != COMMANDS and action_mode not in robot_class.action_modes:
            raise ValueError(f"action_mode must be one of {sorted([*robot_class.action_modes, COMMANDS])}, got "
                             f"{action_mode!r}")  # fmt: skip
        mode = first if action_mode in (None, COMMANDS) else action_mode
        players = self.task_class.players
        if len(players) > 1 and mode != first:  # the others play through the reference gait, which runs that mode
            raise ValueError(f"action_mode must be {first!r} or {COMMANDS!r} with a scripted player on the field "
                             f"(its gait runs the robot's {first!r} mode), got {action_mode!r}")  # fmt: skip
        imu = ImuNoise() if check_flag("sensor_noise", sensor_noise) else None
        scene = SharedScene(
            lambda: robot_class(action_mode=mode, control_freq=control_freq, imu_noise=imu),
            players,
            [field_edit(self.field, players, robot_class.root_body, HEADS.get(robot_class.name))],
        )
        self.scene = scene
        head = HEADS.get(robot_class.name)
        task = self.task_class(scene.robot, scene, self.field, sparse, ball_noise, field_of_view, max_tilt,
                               terminate_when_unhealthy, height_band, grace_time, head)  # fmt: skip
        # speed and turn rate, run by the robot's reference gait (envs/soccer/steering.py)
        commands = Commands(scene.robot, kick) if action_mode == COMMANDS else None
        robot: Any = scene.robot
        if len(players) > 1:  # the learner's rows of a scene with a scripted keeper (envs/soccer/keeper.py)
            self.keeper = KeeperMatch(scene, task, commands)
            robot, task, commands = self.keeper.robot, self.keeper.task, self.keeper.commands
        super().__init__(robot, task, reset_noise_scale, None, telemetry, render_mode, width, height)
        if commands is not None:
            self.commands = commands
            self.action_space = spaces.Box(-1.0, 1.0, shape=(commands.mode.size,), dtype=np.float32)

    @property
    def model(self):
        return self.scene.model

    def tracked_body(self) -> str:
        return f"{PLAYER}/{self.robot.root_body}"


MANUAL = """{title}: {task}

    ## Description
    The {robot} {company} on its soccer field ({field}, envs/soccer/field.py) with its ball, a rung of the soccer
    academy (docs/soccer.md). The robot and the ball are placed at random each episode.

    ## Action Space
    {modes}, normalized to [-1, 1]; or ``action_mode="commands"``: forward speed and turn rate (2), run by its
    reference gait as in matches, and with ``kick=True`` a third, ``kick``, for a robot that kicks (the Bioloid).

    ## Observation Space
    The robot's proprioception, then the soccer task's egocentric view (``observation_structure`` names every
    slice): ``heading_error`` against the +x goal, ``ball`` and ``ball_velocity`` in its frame with noise of
    ``ball_noise`` times the ball's distance, ``ball_visible`` (``field_of_view``), ``goal`` and ``own_goal``{seen}.

    ## Rewards
    Named terms in ``info`` (``reward_<term>``), summed: the task's +1 (above), -1 for an own goal, and the
    shaping terms (differences of distance, so a detour costs what it gains back); ``sparse=True`` keeps the +1 and
    -1 only.

    ## Starting State
    The task draws the robot's place and heading and the ball's; ``reset(options={{"robot": (x, y, heading),
    "ball": (x, y){keeper_option}}})`` sets them.

    ## Episode End
    Terminated on the task's success, an own goal, or a fall or a ground rule broken (as in the walking tasks;
    ``info["fallen"]`` says which); truncated at ``episode_seconds`` ({seconds} s by default at any control rate).

    ## Version History
{history}"""


# revisions of a robot's model that every one of its academy ids takes after its own history (a task's later change
# of its own goes after these)
MODEL_REVISIONS: dict[str, tuple[str, ...]] = {
    "Roach": ("the robot's battery sags under its load (an internal resistance of 0.2 ohm, measured on the real "
              "logs), as in RoachWalk-v4: its battery sense reads the sagged voltage and its firmware's duty "
              "multiplies it.",),
    "Xjus": (),
    "Bioloid": (),
}  # fmt: skip


def history(robot: str, task_class: type[AcademyTask] | None = None) -> tuple[str, ...]:
    """The version history of a robot's academy id (its name in ids, as ``Bioloid``): the task's own where it has one
    (a task added after the others starts at v1), else the robot's academy's; then the robot's model revisions."""
    own = None if task_class is None else task_class.history
    if isinstance(own, Mapping):  # a task's history per robot
        own = own[robot]
    return (*(tuple(HISTORY[robot]) if own is None else own), *MODEL_REVISIONS[robot])


def version(robot: str, task_class: type[AcademyTask] | None = None) -> int:
    """The academy id's version for a robot (its name in ids, as ``Bioloid``) and task (default: GoToBall's)."""
    return len(history(robot, task_class))


def make_academy(robot_class: type[Robot], field: Field, task_class: type[AcademyTask], robot: str,
                 title: str) -> type[AcademyEnv]:  # fmt: skip
    """The academy env class of a robot (``robot``: its name in ids) and a task, with its entry points, as attributes
    of this module."""
    name = f"{title}Env"
    versions = "".join(f"    - v{i}: {entry}\n" for i, entry in enumerate(history(robot, task_class), start=1))
    keeper = KEEPER in task_class.players
    first = next(iter(robot_class.action_modes))
    modes = (f"The robot's {first!r} mode, as in its walking env (its other modes are refused: the keeper's gait "
             f"runs that one)" if keeper else
             "The robot's own, as in its walking env (``action_mode``: its modes, default the first)")  # fmt: skip
    doc = MANUAL.format(title=title, task=task_class.__doc__, robot=robot_class.__name__, field=field.name,
                        seconds=f"{EPISODE_SECONDS[robot]:g}", history=versions, modes=modes,
                        company="with the scripted team's keeper (a second one, in the goal at +x)" if keeper
                        else "alone",
                        seen=(", and ``opponents``: the keeper's place in its frame, noisy as the ball (not limited "
                              "by ``field_of_view``); ``info`` has ``keeper_x``, ``keeper_y`` and ``keeper_put_back``"
                              if keeper else ""),
                        keeper_option=', "keeper": (x, y, heading)' if keeper else "")  # fmt: skip
    attributes = {"robot_class": robot_class, "task_class": task_class, "field": field, "__module__": __name__,
                  "__qualname__": name, "__doc__": doc}  # fmt: skip
    env_class = type(name, (AcademyEnv,), attributes)
    # the class and its entry points are attributes of this module: registered by name, pickled by name
    env_class.make_env_name, env_class.make_batched_name = f"make_{name}", f"make_batched_{name}"
    globals()[name] = env_class
    globals()[env_class.make_env_name] = entry_point(env_class)
    globals()[env_class.make_batched_name] = vector_entry_point(env_class)
    return env_class
