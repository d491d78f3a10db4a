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
lets it try to get up by itself. The game ends by rule (terminated) only when a team reaches ``max_goals``; the time
limit (``max_cycles``) truncates it.

Where a player is taken off, put back, or everyone kicks off, the change happens in the step after the one that
called for it (the step's physics runs, then those players are placed), as Gymnasium's vector envs reset: each
step reads the robots once.
"""

from __future__ import annotations

import functools
import math
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
from envs.soccer.field import BALL, TOP_CAMERA, field_edit
from envs.soccer.robots import FIELDS, ROBOTS
from envs.soccer.steering import COMMANDS, Commands
from envs.soccer.task import BALL_NOISE, SoccerTask

MAX_PLAYERS = 4  # a team: 1 to 4 (the Four-Legged League played 4 a side; the report's six Bioloids are 3 vs 3)
MATCH_SECONDS = 60.0  # the default time limit
PENALTY_SECONDS = 10.0  # how long a fallen player stays off the field (assumed)
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


class SoccerParallelEnv(ParallelEnv):
    """A soccer match of ``players_per_team`` against ``players_per_team`` robots of one kind (see the module
    docstring).

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
        sparse, ball_noise, field_of_view, max_tilt, terminate_when_unhealthy, height_band, grace_time: as the
            academy's (:class:`envs.soccer.task.SoccerTask`; the ground rules decide when a player has fallen).
        reset_noise_scale: perturbation of the robots' kickoff pose (the robot's ``reset``), and of their places
            (x ``reset_noise_scale`` body lengths) and headings (x ``reset_noise_scale`` rad).
        sensor_noise: the robots' IMU noise and bias.
        render_mode: ``"rgb_array"`` (frames; ``camera``: ``"top"``, the whole field, or an agent's name, following
            it), or ``"human"`` (a window from the top camera, where the machine has a display; not in ``metadata``,
            which lists what renders headless).
        width, height: frame size, pixels.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "skitter_soccer_v1",
        "render_modes": ["rgb_array"],
        "is_parallelizable": True,
        "render_fps": 50,
    }

    def __init__(
        self,
        robot: str = "bioloid",
        players_per_team: int = 3,
        action_mode: str | None = None,
        max_cycles: int | None = None,
        max_goals: int | None = None,
        referee: bool = True,
        penalty_seconds: float = PENALTY_SECONDS,
        sparse: bool = False,
        ball_noise: float = BALL_NOISE,
        field_of_view: float | None = None,
        max_tilt: float = 1.4,
        terminate_when_unhealthy: bool = True,
        height_band: tuple[float, float] | None = None,
        grace_time: float = GRACE_TIME,
        reset_noise_scale: float = 0.1,
        sensor_noise: bool = True,
        render_mode: str | None = None,
        camera: str = TOP_CAMERA,
        width: int = 480,
        height: int = 360,
    ):
        names = {name.lower(): name for name in ROBOTS}
        if robot not in names:
            raise ValueError(f"robot must be one of {sorted(names)}, got {robot!r}")
        if isinstance(players_per_team, bool) or players_per_team not in range(1, MAX_PLAYERS + 1):
            raise ValueError(
                f"players_per_team must be a whole number from 1 to {MAX_PLAYERS}, got {players_per_team!r}"
            )
        if render_mode is not None and render_mode not in (*self.metadata["render_modes"], "human"):
            raise ValueError(f"render_mode must be 'rgb_array' or 'human', got {render_mode!r}")
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 1 <= value <= 4096:
                raise ValueError(f"{name} must be a whole number of pixels in [1, 4096], got {value!r}")
        robot_class, self.field = ROBOTS[names[robot]], FIELDS[names[robot]]
        k = int(players_per_team)
        self.possible_agents = [f"home_{i}" for i in range(k)] + [f"away_{i}" for i in range(k)]
        if camera != TOP_CAMERA and camera not in self.possible_agents:
            raise ValueError(f"camera must be {TOP_CAMERA!r} or an agent's name {self.possible_agents}, got {camera!r}")
        self.referee = check_flag("referee", referee)
        self.penalty_seconds = check_number("penalty_seconds", penalty_seconds, 0)
        self.reset_noise_scale = check_number("reset_noise_scale", reset_noise_scale, 0)
        if max_goals is not None and (isinstance(max_goals, bool) or not isinstance(max_goals, int) or max_goals < 1):
            raise ValueError(f"max_goals must be a whole number >= 1 or None, got {max_goals!r}")
        self.max_goals = max_goals
        mode = next(iter(robot_class.action_modes)) if action_mode is None else action_mode
        if mode not in (*robot_class.action_modes, COMMANDS):
            raise ValueError(f"action_mode must be one of {[*robot_class.action_modes, COMMANDS]}, got {mode!r}")
        self.action_mode = mode
        native = next(iter(robot_class.action_modes)) if mode == COMMANDS else mode
        imu = ImuNoise() if check_flag("sensor_noise", sensor_noise) else None
        self.scene = SharedScene(
            lambda: robot_class(action_mode=native, imu_noise=imu),
            self.possible_agents,
            [field_edit(self.field, self.possible_agents, robot_class.root_body)],
        )
        self.robot = self.scene.robot
        # the commands mode: forward speed and turn rate, run by the robot's reference gait (envs/soccer/steering.py)
        self.commands = Commands(self.robot) if mode == COMMANDS else None
        self.mode = self.robot.mode if self.commands is None else self.commands.mode
        self.task = MatchTask(self.robot, self.scene, self.field, sparse, ball_noise, field_of_view, max_tilt,
                              terminate_when_unhealthy, height_band, grace_time)  # fmt: skip
        self.dt = self.robot.control_dt
        default = round(MATCH_SECONDS / self.dt)
        if max_cycles is not None and (
            isinstance(max_cycles, bool) or not isinstance(max_cycles, int) or max_cycles < 1
        ):
            raise ValueError(f"max_cycles must be a whole number >= 1, got {max_cycles!r}")
        self.max_cycles = default if max_cycles is None else int(max_cycles)
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.dt)}
        self.render_mode, self.camera = render_mode, camera
        self._size = (int(width), int(height))
        self._renderer: Any = None
        n = len(self.possible_agents)
        self._observation_space = spaces.Box(-np.inf, np.inf, shape=(self.task.layout.size,), dtype=np.float64)
        self._action_space = spaces.Box(-1.0, 1.0, shape=(self.mode.size,), dtype=np.float32)
        # what a player off the field is sent: standing still in the commands mode, mid-range commands otherwise
        self._rest = np.array([-1.0, 0.0]) if self.commands is not None else np.zeros(self.mode.size)
        self._seed_sequence = np.random.SeedSequence()
        self._rng = np.random.default_rng(self._seed_sequence.spawn(1)[0])
        self._rngs = [np.random.default_rng(s) for s in self._seed_sequence.spawn(n)]
        self._off_until = np.full(n, np.nan)  # a player off the field: the time it comes back
        self._pending = np.zeros(n, dtype=bool)  # players to place at the next step (taken off, put back)
        self._kickoff = False
        self.score = {"home": 0, "away": 0}
        self.cycles = 0
        self.agents: list[str] = []
        self._obs = np.zeros((n, self.task.layout.size))

    # --- spaces -------------------------------------------------------------------------------------------------
    @functools.cache  # noqa: B019 (one space object per agent, as PettingZoo's envs give)
    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    @functools.cache  # noqa: B019
    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    @property
    def observation_structure(self) -> dict[str, int]:
        """name -> size of every part of a player's observation, in order."""
        return self.task.observation_structure

    # --- places -------------------------------------------------------------------------------------------------
    def kickoff_places(self) -> np.ndarray:
        """(x, y, heading) of every player at kickoff, each perturbed by the match's random stream."""
        k = len(self.possible_agents) // 2
        hl, hw = self.field.half_length, self.field.half_width
        noise, length = self.reset_noise_scale, self.robot.facts.length
        home = np.array([[x * hl, y * hw, 0.0] for x, y in FORMATIONS[k]])
        places = np.vstack([home, home * [-1.0, -1.0, 1.0] + [0.0, 0.0, math.pi]])
        places[:, :2] += self._rng.uniform(-noise, noise, (len(places), 2)) * length
        places[:, 2] += self._rng.uniform(-noise, noise, len(places))
        return places

    def _off_place(self, i: int) -> np.ndarray:
        """Where player ``i`` waits while it is off: beyond the wall on its own side, clear of the others."""
        f, length = self.field, self.robot.facts.length
        side = 1.0 if self.possible_agents[i].startswith("home") else -1.0
        y = f.half_width + f.side_border + 3.0 * length
        return np.array([-side * (0.5 + 2.0 * i) * length, -side * y, 0.0])

    def _return_place(self, i: int) -> np.ndarray:
        """Where player ``i`` comes back: at the touch line of its own half, facing into the field."""
        f, length = self.field, self.robot.facts.length
        side = 1.0 if self.possible_agents[i].startswith("home") else -1.0
        y = -side * (f.half_width - 0.5 * length)
        return np.array([-side * 0.5 * f.half_length, y, side * math.pi / 2])

    # --- PettingZoo API ---------------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        n = len(self.possible_agents)
        if seed is not None:
            self._seed_sequence = np.random.SeedSequence(seed)
            self._rng = np.random.default_rng(self._seed_sequence.spawn(1)[0])
            self._rngs = [np.random.default_rng(s) for s in self._seed_sequence.spawn(n)]
        self.agents = list(self.possible_agents)
        self.score = {"home": 0, "away": 0}
        self.cycles = 0
        self._off_until[:] = np.nan
        self._pending[:] = False
        self._kickoff = False
        ids = np.arange(n)
        self._place_kickoff()
        self._place_options(options)
        self.robot.reset(ids, self._rngs, self.reset_noise_scale, None)
        if self.commands is not None:
            self.commands.reset(ids)
        readings = self.robot.read(self._rngs, False)
        self.task.reset(ids, self._rngs, None, readings)
        self._obs = self.task.observe(readings)
        infos = {agent: {"score": dict(self.score), "off": False} for agent in self.agents}
        return self._by_agent(self._obs), infos

    def _place_options(self, options: dict | None) -> None:
        """A reset's set piece: ``options["places"]`` (agent -> (x, y, heading)) and ``options["ball"]`` ((x, y)),
        each inside the field's walls; the next kickoffs are the formation's again. Other keys are ignored."""
        options = options or {}  # other keys are left alone (PettingZoo's API test passes one of its own)
        f = self.field
        reach = (f.half_length + f.end_border, f.half_width + f.side_border)
        places = options.get("places", {})
        if not isinstance(places, dict) or not set(places) <= set(self.possible_agents):
            raise ValueError(f"options['places'] must map agents {self.possible_agents} to (x, y, heading), "
                             f"got {places!r}")  # fmt: skip
        for agent, value in places.items():
            self.scene.placement[self.possible_agents.index(agent)] = self._check_place(
                value, 3, f"places'][{agent!r}", reach
            )
        if "ball" in options:
            x, y = self._check_place(options["ball"], 2, "ball", reach)
            self.scene.place_object(np.array([0]), BALL, np.array([[x, y, f.ball.radius]]), np.zeros((1, 3)))

    @staticmethod
    def _check_place(value: Any, size: int, name: str, reach: tuple[float, float]) -> np.ndarray:
        place = np.zeros(0) if isinstance(value, str | bytes) else np.asarray(value, dtype=np.float64).reshape(-1)
        if (
            place.shape != (size,)
            or not np.isfinite(place).all()
            or abs(place[0]) > reach[0]
            or abs(place[1]) > reach[1]
        ):
            raise ValueError(f"options['{name}'] must be {size} finite numbers with |x| <= {reach[0]:g} and "
                             f"|y| <= {reach[1]:g} m (inside the walls), got {value!r}")  # fmt: skip
        return place

    def _place_kickoff(self) -> None:
        self.scene.placement[:] = self.kickoff_places()
        self.scene.place_object(np.array([0]), BALL, np.array([[0.0, 0.0, self.field.ball.radius]]), np.zeros((1, 3)))

    def step(self, actions: dict[str, np.ndarray]):
        if not self.agents:
            raise RuntimeError("the match is over: call reset()")
        n = len(self.possible_agents)
        chosen = np.tile(self._rest, (n, 1))
        for i, agent in enumerate(self.possible_agents):
            if agent in actions and actions[agent] is not None and np.isnan(self._off_until[i]):
                action = np.asarray(actions[agent], dtype=np.float64).reshape(-1)
                if action.shape != self._action_space.shape or not np.isfinite(action).all():
                    raise ValueError(f"{agent}'s action must be {self._action_space.shape[0]} finite numbers, "
                                     f"got {actions[agent]!r}")  # fmt: skip
                chosen[i] = action
        if self.commands is None:
            self.robot.command(self.robot.mode.to_command(chosen))
        else:
            self.robot.command(self.commands.robot_commands(chosen))
        self.robot.step()
        placed = self._place_pending()
        stepped = ~placed
        readings = self.robot.read(self._rngs, stepped if placed.any() else True)
        if placed.any():
            self.task.reset(np.flatnonzero(placed), [self._rngs[i] for i in np.flatnonzero(placed)], None, readings)
        state = self.task.update(readings, stepped if placed.any() else None)
        self._obs = self.task.observe(readings)
        self.cycles += 1
        plus, minus = (g[0] for g in self.task.scene_goals())
        goal = state["scored"] - state["conceded"]
        if plus or minus:
            self.score["home" if plus else "away"] += 1
            self._kickoff = True
        self._take_off(self.task.terminated(state) & stepped)
        ended = self.max_goals is not None and max(self.score.values()) >= self.max_goals
        truncated = self.cycles >= self.max_cycles
        rewards = {agent: float(goal[i]) for i, agent in enumerate(self.possible_agents)}
        infos = {
            agent: {
                "score": dict(self.score),
                "off": bool(not np.isnan(self._off_until[i])),
                "fallen": bool(self.task.terminated(state)[i] and stepped[i]),
                **{f"reward_{key}": float(value[i]) for key, value in self.task.reward_terms(state).items()},
                **{key: float(state[key][i]) for key in ("approach", "ball_progress", "touched", "ball_distance")},
            }
            for i, agent in enumerate(self.possible_agents)
        }
        terminations = dict.fromkeys(self.possible_agents, bool(ended))
        truncations = dict.fromkeys(self.possible_agents, bool(truncated and not ended))
        observations = self._by_agent(self._obs)
        if ended or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _take_off(self, fallen: np.ndarray) -> None:
        """Mark the fallen players (a referee takes them off at the next step)."""
        if not self.referee:
            return
        for i in np.flatnonzero(fallen & np.isnan(self._off_until)):
            self._off_until[i] = float(self.scene.time[0]) + self.penalty_seconds
            self._pending[i] = True

    def _place_pending(self) -> np.ndarray:
        """After the step's physics: a kickoff (everyone), or the players taken off or put back. (players,) bool:
        who was placed."""
        n = len(self.possible_agents)
        now = float(self.scene.time[0])
        placed = np.zeros(n, dtype=bool)
        if self._kickoff:
            self._kickoff = False
            self._off_until[:] = np.nan
            self._pending[:] = False
            self._place_kickoff()
            placed[:] = True
        else:
            back = ~np.isnan(self._off_until) & (self._off_until <= now + 1e-9) & ~self._pending
            for i in np.flatnonzero(back):
                self._off_until[i] = np.nan
                self.scene.placement[i] = self._return_place(i)
            for i in np.flatnonzero(self._pending):
                self.scene.placement[i] = self._off_place(i)
            placed = back | self._pending
            self._pending[:] = False
        if placed.any():
            ids = np.flatnonzero(placed)
            self.robot.reset(ids, [self._rngs[i] for i in ids], self.reset_noise_scale, None)
            if self.commands is not None:
                self.commands.reset(ids)
        return placed

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
