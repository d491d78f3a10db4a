"""Multi-robot soccer as a PettingZoo environment: two teams of one robot kind on its field, one ball.

``parallel_env(robot="bioloid", players_per_team=3)`` is PettingZoo's ``ParallelEnv``; ``env(...)`` is the same match
as an AEC env (PettingZoo's ``parallel_to_aec``). Agents ``home_0 ..`` attack the goal at +x, ``away_0 ..`` the goal
at -x; every player is one row of a single robot object on a :class:`~envs.common.match.SharedScene`, so a match of
six robots is one native physics step per control step. Observations are each player's own
(:class:`envs.soccer.task.SoccerTask`): egocentric, so a player's view does not depend on its side.

Rewards: +1 to every player of a team that scores, -1 to every player of the other; the shaping terms (``approach``,
``ball_progress``) are in ``infos``. A goal is followed by a kickoff: players and ball back to their kickoff places.
A fallen player (tilted, or breaking the ground rules, as in the walking tasks) is taken off the field as a referee
would and put back standing at the touch line of its own half after ``penalty_seconds``, unless ``referee=False``
lets it try to get up by itself. A ball that leaves the field is put back by the referee (``throw_in``). The game
ends by rule (terminated) only when a team reaches ``max_goals``; the time limit (``max_cycles``) truncates it.

Where a player is taken off, put back, or everyone kicks off, the change happens in the step after the one that
called for it (the step's physics runs, then those players are placed), as Gymnasium's vector envs reset: each
step reads the robots once.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import mujoco
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from envs.common.imu import ImuNoise
from envs.common.locomotion import GRACE_TIME
from envs.common.match import SharedScene
from envs.common.rendering import FrameRenderer, tracking_camera
from envs.common.robot import check_flag, check_number
from envs.soccer.field import BALL, BALL_POS, TOP_CAMERA, field_edit
from envs.soccer.robots import BY_NAME, FIELDS, HEADS, ROBOTS
from envs.soccer.steering import COMMANDS, Commands
from envs.soccer.task import BALL_NOISE, SoccerTask

MAX_PLAYERS = 4  # a team: 1 to 4 (the Four-Legged League played 4 a side; the report's six Bioloids are 3 vs 3)
MATCH_SECONDS = 60.0  # the default time limit
PENALTY_SECONDS = 10.0  # how long a fallen player stays off the field (assumed)
RETURN_CLEARANCE = 2.0  # body lengths between a player put back and anyone else (a body length each way; assumed)
RETURN_ROWS = 3  # rows of places a player may come back to: its touch line, then two further in
# a control step whose scene diverges is run again from its start at physics steps this many times shorter
# (envs/common/simulation.py): the xJüs's 2 ms step let legs wedged between two robots blow a scene up 14 times in
# 1280 s of random two-a-side play; from the start of such a block, 0.25 ms steps hold (docs/soccer.md)
REFINE_UNSTABLE = 8
# kickoff places of the home team, (x / half length, y / half width), by team size; the away team's are these turned
# by half a turn about the centre spot. The last player of a team of three or more keeps goal.
FORMATIONS = {
    1: ((-0.3, 0.0),),
    2: ((-0.3, 0.35), (-0.3, -0.35)),
    3: ((-0.3, 0.35), (-0.3, -0.35), (-0.85, 0.0)),
    4: ((-0.2, 0.0), (-0.45, 0.45), (-0.45, -0.45), (-0.85, 0.0)),
}


class MatchTask(SoccerTask):
    """The task of every player in a match: :class:`SoccerTask`'s observations, +1 to a team that scores and -1 to
    the other. ``terminated`` says which players fell (the match takes them off)."""

    name = "soccer_match"

    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {"goal": state["scored"] - state["conceded"]}


def _whole(value: Any) -> bool:
    """Whether ``value`` is a whole number (a Python or numpy integer, not a bool or a float)."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def action_modes(robot: str) -> list[str]:
    """The action modes a match of ``robot`` (lower case) takes: the robot's own (its default first) and
    ``commands``."""
    return [*ROBOTS[BY_NAME[robot]].action_modes, COMMANDS]


def check_cycles(value: Any) -> int:
    """``max_cycles`` as an int; ValueError unless a whole number >= 1."""
    if not _whole(value) or value < 1:
        raise ValueError(f"max_cycles must be a whole number >= 1, got {value!r}")
    return int(value)


class Matches:
    """``num_matches`` soccer matches of one configuration, stepped together: the engine behind
    :class:`SoccerParallelEnv` (one match) and :class:`agents.soccer.vec_env.SoccerVecEnv` (many, on one
    ``mujoco.batch``). Every array has a row per player of every match (match-major: row ``m * players + p``); the
    bookkeeping (score, clock, referee) is per match, in arrays, with no Python loop over matches in a step.

    Arguments: :class:`SoccerParallelEnv`'s, and ``num_matches``, ``nthread`` and ``batched`` (run on
    ``mujoco.batch.Batch``; default: when there is more than one match).
    """

    def __init__(
        self,
        robot: str = "bioloid",
        players_per_team: int = 3,
        action_mode: str | None = None,
        max_cycles: int | None = None,
        max_goals: int | None = None,
        referee: bool = True,
        penalty_seconds: float = PENALTY_SECONDS,
        ball_noise: float = BALL_NOISE,
        field_of_view: float | None = None,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: tuple[float, float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        sensor_noise: bool = True,
        num_matches: int = 1,
        nthread: int | None = None,
        kick: bool = False,
        throw_in: bool = True,
        batched: bool | None = None,
    ):
        if not isinstance(robot, str) or robot not in BY_NAME:
            raise ValueError(f"robot must be one of {sorted(BY_NAME)}, got {robot!r}")
        if not _whole(players_per_team) or players_per_team not in range(1, MAX_PLAYERS + 1):
            raise ValueError(
                f"players_per_team must be a whole number from 1 to {MAX_PLAYERS}, got {players_per_team!r}"
            )
        if not _whole(num_matches) or num_matches < 1:
            raise ValueError(f"num_matches must be a whole number >= 1, got {num_matches!r}")
        robot_class, self.field = ROBOTS[BY_NAME[robot]], FIELDS[BY_NAME[robot]]
        self.robot_name = robot
        k = int(players_per_team)
        self.possible_agents = [f"home_{i}" for i in range(k)] + [f"away_{i}" for i in range(k)]
        self.referee = check_flag("referee", referee)
        self.throw_in = check_flag("throw_in", throw_in)
        self.penalty_seconds = check_number("penalty_seconds", penalty_seconds, 0)
        self.reset_noise_scale = check_number("reset_noise_scale", reset_noise_scale, 0)
        if max_goals is not None and (not _whole(max_goals) or max_goals < 1):
            raise ValueError(f"max_goals must be a whole number >= 1 or None, got {max_goals!r}")
        self.max_goals = None if max_goals is None else int(max_goals)
        modes = action_modes(robot)
        mode = modes[0] if action_mode is None else action_mode
        if mode not in modes:
            raise ValueError(f"action_mode must be one of {modes}, got {mode!r}")
        if max_cycles is not None:
            check_cycles(max_cycles)
        self.action_mode = mode
        native = next(iter(robot_class.action_modes)) if mode == COMMANDS else mode
        imu = ImuNoise() if check_flag("sensor_noise", sensor_noise) else None
        self.num_matches = int(num_matches)
        self.scene = SharedScene(
            lambda: robot_class(action_mode=native, imu_noise=imu),
            self.possible_agents,
            [field_edit(self.field, self.possible_agents, robot_class.root_body, HEADS.get(robot_class.name))],
            num_scenes=self.num_matches,
            nthread=nthread,
            batched=batched,
            refine=REFINE_UNSTABLE,
        )
        self.robot = self.scene.robot
        # the commands mode: forward speed and turn rate, run by the robot's reference gait (envs/soccer/steering.py)
        if check_flag("kick", kick) and mode != COMMANDS:
            raise ValueError(f"kick=True is the commands mode's kick action: give action_mode={COMMANDS!r}")
        self.commands = Commands(self.robot, kick) if mode == COMMANDS else None
        self.mode = self.robot.mode if self.commands is None else self.commands.mode
        head = HEADS.get(robot_class.name)
        # a match's reward is the goal alone, +1 / -1; its shaping terms are in the infos
        self.task = MatchTask(self.robot, self.scene, self.field, True, ball_noise, field_of_view, max_tilt,
                              terminate_when_unhealthy, height_band, grace_time, head)  # fmt: skip
        self.dt = self.robot.control_dt
        self.max_cycles = round(MATCH_SECONDS / self.dt) if max_cycles is None else int(max_cycles)
        n, rows = len(self.possible_agents), self.robot.num_sims
        self.players = n
        self._match_of = np.arange(rows) // n
        self._home = np.tile([agent.startswith("home") for agent in self.possible_agents], self.num_matches)
        self._home_grid = self._home.reshape(self.num_matches, n)  # (matches, players): who is of the home team
        # what a player off the field is sent: standing still in the commands mode, mid-range commands otherwise
        self.rest = np.zeros(self.mode.size)  # speed 0 (the action -1), no turn, no kick
        if self.commands is not None:
            self.rest[0] = -1.0
        self._match_rngs = [np.random.default_rng() for _ in range(self.num_matches)]
        self.rngs = [np.random.default_rng() for _ in range(rows)]
        self.off_until = np.full(rows, np.nan)  # a player off the field: the time it comes back
        self._pending = np.zeros(rows, dtype=bool)  # players to place at the next step (taken off, put back)
        self._kickoff = np.zeros(self.num_matches, dtype=bool)
        # who touched the ball last: +1 home, -1 away, 0 nobody since the kickoff or the last throw-in
        self._last_touch = np.zeros(self.num_matches, dtype=np.int64)
        self.scores = np.zeros((self.num_matches, 2), dtype=np.int64)  # home, away
        self.cycles = np.zeros(self.num_matches, dtype=np.int64)
        self.obs = np.zeros((rows, self.task.layout.size))
        self._where = np.zeros((rows, 2))  # every player's (x, y) at the last reading: where not to put another

    def rows_of(self, matches: np.ndarray) -> np.ndarray:
        """The rows of every player of ``matches``."""
        return (np.asarray(matches)[:, None] * self.players + np.arange(self.players)).reshape(-1)

    # --- places -------------------------------------------------------------------------------------------------
    def kickoff_places(self, match: int) -> np.ndarray:
        """(x, y, heading) of every player of ``match`` at kickoff, each perturbed by the match's random stream."""
        k = self.players // 2
        hl, hw = self.field.half_length, self.field.half_width
        noise, length = self.reset_noise_scale, self.robot.facts.length
        home = np.array([[x * hl, y * hw, 0.0] for x, y in FORMATIONS[k]])
        places = np.vstack([home, home * [-1.0, -1.0, 1.0] + [0.0, 0.0, math.pi]])
        rng = self._match_rngs[match]
        places[:, :2] += rng.uniform(-noise, noise, (len(places), 2)) * length
        places[:, 2] += rng.uniform(-noise, noise, len(places))
        return places

    def _off_place(self, row: int) -> np.ndarray:
        """Where a player waits while it is off: beyond the wall on its own side, clear of the others."""
        f, length = self.field, self.robot.facts.length
        side, i = (1.0 if self._home[row] else -1.0), row % self.players
        y = f.half_width + f.side_border + 3.0 * length
        return np.array([-side * (0.5 + 2.0 * i) * length, -side * y, 0.0])

    def _return_place(self, row: int, where: np.ndarray) -> np.ndarray:
        """Where a player comes back: at the touch line of its own half, facing into the field, on the first spot
        clear of every other player of its match and of the ball (``RETURN_CLEARANCE`` body lengths between centres;
        ``where``: every row's (x, y) now), tried from the middle of the half outward along the line; if none is
        clear, the clearest. Two players coming back at once, or onto a spot someone stands on, would otherwise be
        put one inside the other, and the solver blows the scene up."""
        length = self.robot.facts.length
        side = 1.0 if self._home[row] else -1.0
        spots = self._return_spots(side)
        rows = self.rows_of(np.array([self._match_of[row]]))
        others = where[rows[(rows != row) & np.isnan(self.off_until[rows])]]  # those off wait outside the field
        ball = self.scene.scene_sensor(BALL_POS)[self._match_of[row], :2]
        gap = np.linalg.norm(spots[:, None, :] - np.vstack([others, ball])[None], axis=2).min(axis=1)
        clear = np.flatnonzero(gap >= RETURN_CLEARANCE * length)
        x, y = spots[clear[0] if len(clear) else int(np.argmax(gap))]
        return np.array([x, y, side * math.pi / 2])

    def _return_spots(self, side: float) -> np.ndarray:
        """The places a player of the team attacking ``side`` (+1 home) may come back to, (spots, 2), in the order
        they are tried: on its touch line, a body length in from its half's ends, from the middle of the half outward
        ``RETURN_CLEARANCE`` body lengths apart; then as many rows again, each that much further into the field (up
        to ``RETURN_ROWS``): at least nine spots on every robot's field."""
        f, length = self.field, self.robot.facts.length
        spacing = RETURN_CLEARANCE * length
        middle = 0.5 * f.half_length
        reach = int((middle - length) // spacing)  # spots either way that stay a body length inside the half
        offsets = [0.0] + [sign * j * spacing for j in range(1, reach + 1) for sign in (1.0, -1.0)]
        lines = [f.half_width - 0.5 * length - k * spacing for k in range(RETURN_ROWS)]
        return np.array([[-side * (middle + o), -side * y] for y in lines if y > 0 for o in offsets])

    def _place_kickoff(self, match: int) -> None:
        self.scene.placement[self.rows_of(np.array([match]))] = self.kickoff_places(match)
        self.scene.place_object(np.array([match]), BALL, np.array([[0.0, 0.0, self.field.ball.radius]]),
                                np.zeros((1, 3)))  # fmt: skip

    def _place_options(self, match: int, options: dict | None) -> None:
        """A reset's set piece: ``options["places"]`` (agent -> (x, y, heading)) and ``options["ball"]`` ((x, y)),
        each inside the field's walls; the next kickoffs are the formation's again. Other keys are ignored
        (PettingZoo's API test passes one of its own)."""
        options = options or {}
        f = self.field
        reach = (f.half_length + f.end_border, f.half_width + f.side_border)
        places = options.get("places", {})
        if not isinstance(places, dict) or not set(places) <= set(self.possible_agents):
            raise ValueError(f"options['places'] must map agents {self.possible_agents} to (x, y, heading), "
                             f"got {places!r}")  # fmt: skip
        for agent, value in places.items():
            row = match * self.players + self.possible_agents.index(agent)
            self.scene.placement[row] = self._check_place(value, 3, f"['places'][{agent!r}]", reach)
        if "ball" in options:
            x, y = self._check_place(options["ball"], 2, "['ball']", reach)
            self.scene.place_object(np.array([match]), BALL, np.array([[x, y, f.ball.radius]]), np.zeros((1, 3)))

    @staticmethod
    def _check_place(value: Any, size: int, name: str, reach: tuple[float, float]) -> np.ndarray:
        place = np.zeros(0) if isinstance(value, str | bytes) else np.asarray(value, dtype=np.float64).reshape(-1)
        inside = place.shape == (size,) and np.isfinite(place).all()
        if not inside or abs(place[0]) > reach[0] or abs(place[1]) > reach[1]:
            raise ValueError(f"options{name} must be {size} finite numbers with |x| <= {reach[0]:g} and "
                             f"|y| <= {reach[1]:g} m (inside the walls), got {value!r}")  # fmt: skip
        return place

    # --- reset and step -------------------------------------------------------------------------------------------
    def seed(self, match: int, seed: int | None) -> None:
        """Seed a match's streams: its kickoff places' and each player's (as one match seeded with ``seed``)."""
        sequence = np.random.SeedSequence(seed)
        self._match_rngs[match] = np.random.default_rng(sequence.spawn(1)[0])
        for row, child in zip(self.rows_of(np.array([match])), sequence.spawn(self.players), strict=True):
            self.rngs[row] = np.random.default_rng(child)

    def reset(self, matches: np.ndarray, options: dict | None = None) -> None:
        """Start ``matches`` again (their kickoff, or the set piece of ``options``); their rows of :attr:`obs` are
        their first observations. The other matches go on untouched."""
        matches = np.asarray(matches, dtype=np.int64)
        rows = self.rows_of(matches)
        self.scores[matches] = 0
        self.cycles[matches] = 0
        self._kickoff[matches] = False
        self._last_touch[matches] = 0
        self.off_until[rows] = np.nan
        self._pending[rows] = False
        for m in matches:
            self._place_kickoff(int(m))
            self._place_options(int(m), options)
        self._reset_rows(rows)
        # a reset's reading: no step to integrate, and the players not reset draw nothing
        reset = np.zeros(len(self.rngs), dtype=bool)
        reset[rows] = True
        readings = self.robot.read([rng if r else None for rng, r in zip(self.rngs, reset, strict=True)], False)
        self.task.reset(rows, [self.rngs[i] for i in rows], None, readings)
        self.obs[rows] = self.task.observe(readings)[rows]
        self._where[rows] = readings["position"][rows, :2]

    def _reset_rows(self, rows: np.ndarray) -> None:
        self.robot.reset(rows, [self.rngs[i] for i in rows], self.reset_noise_scale, None)
        if self.commands is not None:
            self.commands.reset(rows)

    def step(self, actions: np.ndarray) -> dict[str, np.ndarray]:
        """One control step of every match from normalized actions (rows, action size) (a player off the field is
        sent :attr:`rest`). Returns per row ``reward``, ``fallen``, ``off`` and the shaping terms, and per match
        ``goal_home``, ``goal_away``, ``throw_in`` (the referee put the ball back), ``ended`` (by ``max_goals``),
        ``truncated`` (by ``max_cycles``, or by the
        scene going unstable, when MuJoCo resets its data: then its rewards are 0), ``unstable``, and ``refined``
        (the step went unstable and was run again at shorter physics steps, which held: it counts as any step)."""
        on = np.isnan(self.off_until)
        chosen = actions if on.all() else np.where(on[:, None], actions, self.rest)
        if self.commands is None:
            self.robot.command(self.robot.mode.to_command(chosen))
        else:
            self.robot.command(self.commands.robot_commands(chosen))
        stable = self.robot.step()
        # a scene that went unstable (MuJoCo reset its data) ends its match: nothing after it counts
        unstable = ~np.asarray(stable, dtype=bool).reshape(self.num_matches, -1).all(axis=1)
        refined = np.asarray(self.scene.sim.refined, dtype=bool).copy()
        placed = self._place_pending()
        stepped = ~placed
        any_placed = bool(placed.any())
        readings = self.robot.read(self.rngs, stepped if any_placed else True)
        if any_placed:
            ids = np.flatnonzero(placed)
            self.task.reset(ids, [self.rngs[i] for i in ids], None, readings)
        state = self.task.update(readings, stepped if any_placed else None)
        self.obs = self.task.observe(readings)
        self._where[:] = readings["position"][:, :2]
        self.cycles += 1
        plus, minus = self.task.last_scene_goals  # this step's, as the task's update saw them
        plus, minus = plus & ~unstable, minus & ~unstable
        self.scores[:, 0] += plus
        self.scores[:, 1] += minus
        self._kickoff |= plus | minus
        fell = self.task.terminated(state) & stepped
        if self.referee and fell.any():
            taken = fell & np.isnan(self.off_until)
            self.off_until[taken] = self.scene.time[self._match_of[taken]] + self.penalty_seconds
            self._pending |= taken
        ended = np.zeros(self.num_matches, dtype=bool)
        if self.max_goals is not None:
            ended = self.scores.max(axis=1) >= self.max_goals
        thrown = self._throw_in(state["touched"], plus | minus | unstable, readings)
        reward, approach, progress = self.task.reward_terms(state)["goal"], state["approach"], state["ball_progress"]
        if unstable.any():
            quiet = unstable[self._match_of]
            reward, approach, progress = (np.where(quiet, 0.0, v) for v in (reward, approach, progress))
        return {
            "reward": reward,
            "fallen": fell,
            "off": ~np.isnan(self.off_until),
            "approach": approach,
            "ball_progress": progress,
            "touched": state["touched"],
            "ball_distance": state["ball_distance"],
            "goal_home": plus,
            "goal_away": minus,
            "ended": ended,
            "throw_in": thrown,
            "truncated": ((self.cycles >= self.max_cycles) | unstable) & ~ended,
            "unstable": unstable,
            "refined": refined,
        }

    def _throw_in(self, touched: np.ndarray, skip: np.ndarray, readings: dict[str, np.ndarray]) -> np.ndarray:
        """The referee's ball out: who touched the ball last in each match (of one team alone in a step; if both
        touched it, the earlier toucher stands), and the ball of every match (not in ``skip``) that left the field
        this step put back at its throw-in place (``Field.throw_in``, clear of the players by a body length), at
        rest, at once (this step's observations still see it where it left); nobody has touched it since.
        (num_matches,) bool: where it was put back."""
        hit = touched.reshape(self.num_matches, self.players) > 0
        if hit.any():  # nobody touched the ball (most steps): who touched it last stands
            home = self._home_grid
            by_home, by_away = (hit & home).any(axis=1), (hit & ~home).any(axis=1)
            self._last_touch = np.where(by_home != by_away, np.where(by_home, 1, -1), self._last_touch)
        if not self.throw_in:
            return np.zeros(self.num_matches, dtype=bool)
        ball = self.scene.scene_sensor(BALL_POS)
        out = self.field.left_field(ball[:, 0], ball[:, 1]) & ~skip
        if out.any():
            ids = np.flatnonzero(out)
            positions = readings["position"][:, :2]
            spots = [
                self.field.throw_in(
                    ball[m, 0],
                    ball[m, 1],
                    self._last_touch[m],
                    positions[self.rows_of(np.array([m]))],
                    self.task.length,
                )
                for m in ids
            ]
            x, y = np.array(spots).T
            place = np.column_stack([x, y, np.full(len(ids), self.field.ball.radius)])
            self.scene.move_object(ids, BALL, place, np.zeros((len(ids), 3)))
            self._last_touch[ids] = 0
            self.task.ball_moved(readings, self.rows_of(ids))
        return out

    def _place_pending(self) -> np.ndarray:
        """After the step's physics: the kickoffs called for (every player of those matches), the players taken off
        and those whose penalty is over put back. (rows,) bool: who was placed."""
        placed = np.zeros(len(self.rngs), dtype=bool)
        # whose penalty is over (a player on the field, off_until NaN, compares False)
        due = self.off_until <= self.scene.time[self._match_of] + 1e-9
        if not (self._kickoff.any() or self._pending.any() or due.any()):
            return placed  # nobody to place: most steps
        if self._kickoff.any():
            matches = np.flatnonzero(self._kickoff)
            rows = self.rows_of(matches)
            self._kickoff[matches] = False
            self._last_touch[matches] = 0
            self.off_until[rows] = np.nan
            self._pending[rows] = False
            for m in matches:
                self._place_kickoff(int(m))
            placed[rows] = True
        back = due & ~self._pending & ~placed  # a kickoff's players are placed already
        where = self._where.copy()
        for row in np.flatnonzero(back):
            self.off_until[row] = np.nan
            self.scene.placement[row] = self._return_place(row, where)
            where[row] = self.scene.placement[row, :2]  # the next one to come back keeps clear of it too
        going = self._pending & ~placed
        for row in np.flatnonzero(going):
            self.scene.placement[row] = self._off_place(row)
        self._pending[:] = False
        placed |= back | going
        if placed.any():
            self._reset_rows(np.flatnonzero(placed))
        return placed


class SoccerParallelEnv(ParallelEnv):
    """A soccer match of ``players_per_team`` against ``players_per_team`` robots of one kind (see the module
    docstring): PettingZoo's ``ParallelEnv`` over one :class:`Matches`.

    Args:
        robot: ``"bioloid"``, ``"xjus"`` or ``"roach"``.
        players_per_team: 1 to 4.
        action_mode: the robot's own action mode (default its first: the Bioloid's ``goal``, the others' ``gait``),
            or ``"commands"``: forward speed and turn rate, run by its reference gait (envs/soccer/steering.py).
        max_cycles: steps before the match is truncated (default: ``MATCH_SECONDS`` of play at the control rate).
        max_goals: the match ends (terminated) when a team has scored this many (None: it runs to its time limit).
        referee: take fallen players off for ``penalty_seconds`` and put them back standing (False: they stay and
            may get up by themselves).
        penalty_seconds: how long a fallen player stays off.
        throw_in: a ball that leaves the field (wholly past a touch line, or past a goal line beside the goal) is put
            back at once, at rest, as a referee would: ``THROW_IN_BACK`` (1 m on the Bioloid's field, scaled with the
            field) behind where it left toward the goal of the team that touched it last, ``THROW_IN_INSET`` inside
            the touch line (``Field.throw_in``); the step's ``info`` says ``throw_in``. False: the walls keep it in
            play, where it can lie pinned in a corner for the rest of the match.
        ball_noise, field_of_view, max_tilt, terminate_when_unhealthy, height_band, grace_time: as the
            academy's (:class:`envs.soccer.task.SoccerTask`; the ground rules decide when a player has fallen).
        reset_noise_scale: perturbation of the robots' kickoff pose (the robot's ``reset``), and of their places
            (x ``reset_noise_scale`` body lengths) and headings (x ``reset_noise_scale`` rad).
        sensor_noise: the robots' IMU noise and bias.
        kick: in the commands mode, a third action per player, ``kick``, for a robot that kicks (the Bioloid,
            envs/bioloid/kick.py; off by default: a random policy would be kicking nearly all the time).
        render_mode: ``"rgb_array"`` (frames; ``camera``: ``"top"``, the whole field, or an agent's name, following
            it), or ``"human"`` (a window from the top camera, where the machine has a display; not in ``metadata``,
            which lists what renders headless).
        width, height: frame size, pixels.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "skitter_soccer_v8",
        "render_modes": ["rgb_array"],
        "is_parallelizable": True,
        "render_fps": 50,
    }

    def __init__(self, render_mode: str | None = None, camera: str = TOP_CAMERA, width: int = 480, height: int = 360,
                 **kwargs: Any):  # fmt: skip
        if render_mode is not None and render_mode not in (*self.metadata["render_modes"], "human"):
            raise ValueError(f"render_mode must be 'rgb_array' or 'human', got {render_mode!r}")
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= 4096:
                raise ValueError(f"{name} must be a whole number of pixels in [1, 4096], got {value!r}")
        self.engine = Matches(**kwargs, num_matches=1, batched=False)
        self.possible_agents = list(self.engine.possible_agents)
        if camera != TOP_CAMERA and camera not in self.possible_agents:
            raise ValueError(f"camera must be {TOP_CAMERA!r} or an agent's name {self.possible_agents}, got {camera!r}")
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.engine.dt)}
        self.render_mode, self.camera = render_mode, camera
        self._size = (int(width), int(height))
        self._renderer: Any = None
        self._observation_space = spaces.Box(-np.inf, np.inf, shape=(self.task.layout.size,), dtype=np.float64)
        self._action_space = spaces.Box(-1.0, 1.0, shape=(self.mode.size,), dtype=np.float32)
        self.agents: list[str] = []

    # --- the engine's parts, by name --------------------------------------------------------------------------------
    scene = property(lambda self: self.engine.scene)
    robot = property(lambda self: self.engine.robot)
    task = property(lambda self: self.engine.task)
    field = property(lambda self: self.engine.field)
    mode = property(lambda self: self.engine.mode)
    commands = property(lambda self: self.engine.commands)
    dt = property(lambda self: self.engine.dt)

    @property
    def max_cycles(self) -> int:
        return self.engine.max_cycles

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        self.engine.max_cycles = check_cycles(value)

    @property
    def score(self) -> dict[str, int]:
        """Goals so far: ``{"home": .., "away": ..}``."""
        return {"home": int(self.engine.scores[0, 0]), "away": int(self.engine.scores[0, 1])}

    @property
    def observation_structure(self) -> dict[str, int]:
        """name -> size of every part of a player's observation, in order."""
        return self.task.observation_structure

    @functools.cache  # noqa: B019 (one space object per agent, as PettingZoo's envs give)
    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    # --- PettingZoo API ---------------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            if not _whole(seed) or seed < 0:
                raise ValueError(f"seed must be a whole number >= 0 or None, got {seed!r}")
            self.engine.seed(0, seed)
        self.agents = list(self.possible_agents)
        self.engine.reset(np.array([0]), options)
        infos = {agent: {"score": self.score, "off": False} for agent in self.agents}
        return self._by_agent(self.engine.obs), infos

    def step(self, actions: dict[str, np.ndarray]):
        if not self.agents:
            raise RuntimeError("the match is over: call reset()")
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions must be a dict of agent name -> action, got {type(actions).__name__}")
        unknown = [a for a in actions if a not in self.possible_agents]
        if unknown:
            raise ValueError(f"actions for agents not in this match: {unknown}; its agents are {self.possible_agents}")
        engine = self.engine
        chosen = np.tile(engine.rest, (len(self.possible_agents), 1))
        for i, agent in enumerate(self.possible_agents):
            if agent in actions and actions[agent] is not None:
                action = np.asarray(actions[agent], dtype=np.float64).reshape(-1)
                if action.shape != self._action_space.shape or not np.isfinite(action).all():
                    raise ValueError(
                        f"{agent}'s action must be {self._action_space.shape[0]} finite numbers, got {actions[agent]!r}"
                    )  # fmt: skip
                chosen[i] = action
        out = engine.step(chosen)
        ended, truncated = bool(out["ended"][0]), bool(out["truncated"][0])
        rewards = {agent: float(out["reward"][i]) for i, agent in enumerate(self.possible_agents)}
        infos = {
            agent: {
                "score": self.score,
                "off": bool(out["off"][i]),
                "fallen": bool(out["fallen"][i]),
                "reward_goal": float(out["reward"][i]),
                "sim_unstable": bool(out["unstable"][0]),
                "sim_refined": bool(out["refined"][0]),
                "throw_in": bool(out["throw_in"][0]),
                **{key: float(out[key][i]) for key in ("approach", "ball_progress", "touched", "ball_distance")},
            }
            for i, agent in enumerate(self.possible_agents)
        }
        terminations = dict.fromkeys(self.possible_agents, ended)
        truncations = dict.fromkeys(self.possible_agents, truncated)
        observations = self._by_agent(engine.obs)
        if ended or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _by_agent(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        return {agent: rows[i].copy() for i, agent in enumerate(self.possible_agents) if agent in self.agents}

    # --- rendering ------------------------------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            return None
        model, data = self.scene.model, self.scene.sim.get_data(0)
        if self.render_mode == "human":  # a window, where the machine has a display
            if self._renderer is None:
                from gymnasium.envs.mujoco.mujoco_rendering import MujocoRenderer

                self._renderer = MujocoRenderer(model, data, None, *self._size, camera_name=TOP_CAMERA)
            return self._renderer.render("human")
        if self._renderer is None:
            if self.camera == TOP_CAMERA:
                camera = mujoco.MjvCamera()
                camera.type, camera.fixedcamid = mujoco.mjtCamera.mjCAMERA_FIXED, model.camera(TOP_CAMERA).id
            else:
                config = {"distance": 3.5 * self.robot.facts.length, "elevation": -25.0}
                camera = tracking_camera(model, config, model.body(f"{self.camera}/{self.robot.root_body}").id)
            self._renderer = FrameRenderer(model, camera, *self._size)
        return self._renderer.render(data)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def parallel_env(**kwargs: Any) -> SoccerParallelEnv:
    """A soccer match as PettingZoo's ``ParallelEnv`` (arguments: :class:`SoccerParallelEnv`)."""
    return SoccerParallelEnv(**kwargs)


def env(**kwargs: Any):
    """A soccer match as PettingZoo's AEC env (PettingZoo's ``parallel_to_aec`` of :func:`parallel_env`)."""
    return parallel_to_aec(parallel_env(**kwargs))
