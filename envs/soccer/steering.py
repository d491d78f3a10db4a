"""The ``commands`` action mode: forward speed and turn rate, run by each robot's reference gait.

A :class:`Steering` turns two numbers per player, a drive and a turn, into the robot's own commands at every control
step: the VelociRoACH's tripod (stride frequency, and a different one per side: differential drive), the xJüs's
Buehler clock (stride frequency, and a different ground sweep per side, or one side backward) and the Bioloid's IK
trot at 1.5 Hz (stride length, and each foot stepping sideways in its stance). What speed and turn rate each (drive,
turn) gives was measured on the model over a grid (``python -m benchmarks.gait_maps``, written to
``envs/soccer/gait_maps/``), and a :class:`GaitMap` inverts it: a commanded (speed, turn rate) goes to the measured
(drive, turn) whose speed and turn rate were nearest to it.

A robot that can kick (the Bioloid, envs/bioloid/kick.py) has a third command when asked for (``kick=True``),
``kick``: it kicks with its left front leg at or above ``KICK_THRESHOLD`` and with its right one at or below minus
that. A kick runs to its end (1.4 s), whatever is commanded meanwhile; the gait then starts again from its ready
posture. The command is off by default: a random or untrained policy, its actions spread over [-1, 1], would be
kicking nearly all the time (a kick blocks 71 control steps). Its :class:`KickZone` says where the ball must lie
for the kick to send it forward.
"""

from __future__ import annotations

import functools
import json
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
from scipy.spatial import cKDTree

from envs.bioloid.gait import TROT, TROT_FREQUENCY, IKGoals
from envs.bioloid.kick import KICK_AHEAD, KICK_SIDE, KICK_WIDTH, Kick
from envs.common.robot import ActionMode, Robot, check_flag
from envs.xjus import constants as xjus

MAPS = Path(__file__).resolve().parent / "gait_maps"
COMMANDS = "commands"
KICK_THRESHOLD = 0.5  # |kick| at or above which a kick starts (normalized: the command's range is [-1, 1])


@dataclass(frozen=True)
class KickZone:
    """Where the ball's centre must lie in a robot's frame when its kick starts, for the kick to send it straight:
    ``ahead`` (nearest, farthest) m in front of the body's centre, ``side`` m to the kicking leg's side, within
    ``width``."""

    ahead: tuple[float, float]
    side: float
    width: float


class Steering(ABC):
    """(drive, turn) per player -> the robot's own commands, at every control step.

    Attributes:
        drives, turns: the grid of drives and turns the gait map measures (their ends bound both).
    """

    robot_name: ClassVar[str]
    drives: ClassVar[tuple[float, ...]]
    turns: ClassVar[tuple[float, ...]]
    kick_zone: ClassVar[KickZone | None] = None  # a robot that can kick: where the ball must lie
    # the share of its cruising speed at which the scripted player pushes the ball with this gait, and the least it
    # slows to near a target (None: the player's own default, envs/soccer/scripted.py)
    push_share: ClassVar[float | None] = None

    def __init__(self, robot: Robot):
        if robot.name != self.robot_name:
            raise ValueError(f"{type(self).__name__} steers a {self.robot_name}, not a {robot.name}")
        self.robot = robot
        self.dt = robot.control_dt

    def reset(self, ids: np.ndarray) -> None:  # noqa: B027 (an optional hook)
        """Players ``ids`` start again (a gait with a clock of its own starts it at 0)."""

    @abstractmethod
    def commands(self, drive: np.ndarray, turn: np.ndarray, rows: np.ndarray | None = None,
                 kick: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        """The robot's commands (n, its mode's size) for the next control step, in its physical units, of the
        robot's simulations ``rows`` (default: all of them, in order; a gait with a state of its own keeps it per
        simulation); ``kick`` (n,) in [-1, 1] for a robot that can kick."""


class RoachSteering(Steering):
    """The tripod as a differential drive: drive = mean stride frequency (Hz), turn = right side's frequency less
    the left's (Hz; > 0 turns left), the sides 180 deg apart when equal. Two motors, one per side, make the
    VelociRoACH and its kin differential-drive robots (Pullin, Kohut, Zarrouk, Fearing, "Dynamic turning of 13 cm
    robot comparing tail and differential drive", ICRA 2012). The phase offset by which the real robot also turns
    [roach-sim] steers the model weakly and, above 10 Hz, with no consistent sign (gait map of 2026-11-28: at most
    1 rad/s); a 2 Hz difference turns it 1.0-2.4 rad/s at every drive. A turn of more than twice the drive runs one
    side's clock backward (a negative frequency; the motors run either way, as the duty mode's [-1, 1] does), so at
    drive 0 the robot spins on the spot: +-1 Hz a side turns the model 1.2 rad/s, +-4 Hz 5.9 rad/s, where one side
    running alone pivots the robot about its other side and presses that side into whatever it is against."""

    robot_name = "velociroach"
    drives = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)
    turns = (-8.0, -4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0, 8.0)

    def commands(self, drive: np.ndarray, turn: np.ndarray, rows: np.ndarray | None = None,
                 kick: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        half = 0.5 * np.asarray(turn)
        left, right = drive - half, drive + half
        return np.column_stack([left, right, np.full_like(left, np.pi)])


class XjusSteering(Steering):
    """The Buehler clock: drive = stride frequency (1 / period, Hz), turn = right sweep less left sweep (rad) around
    the walking sweep (a larger sweep on the right turns left) [xjus-report, 2.5]. That turns the model only while it
    runs fast (above 1.5 Hz, at 0.5 m/s and more), so a turn of +-``SPIN`` turns it on the spot as RHex turns in
    place: one side's legs run the clock backward (``Xjus.backward``), the left side's to turn left."""

    robot_name = "xjus"
    drives = (1.0 / 1.5, 0.8, 1.0, 1.25, 1.5, 1.75, 2.0)
    SPIN = np.pi  # the turn that runs a side backward (beyond any sweep difference: the sweeps span pi / 2)
    turns = (-SPIN, *np.radians(np.arange(-60.0, 61.0, 15.0)).tolist(), SPIN)

    def commands(self, drive: np.ndarray, turn: np.ndarray, rows: np.ndarray | None = None,
                 kick: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        spin = np.abs(turn) >= self.SPIN
        self.robot.backward[slice(None) if rows is None else rows] = np.column_stack(
            [spin & (turn > 0), spin & (turn < 0)]
        )
        half = np.where(spin, 0.0, 0.5 * turn)
        low, high = xjus.SWEEP_RANGE
        sweeps = np.clip(np.column_stack([xjus.WALK_SWEEP - half, xjus.WALK_SWEEP + half]), low, high)
        return np.column_stack([1.0 / drive, sweeps])


class BioloidSteering(Steering):
    """The IK trot at 1.5 Hz [bioloid-webots, VI.A] steered as the Four-Legged League's quadrupeds turned: each foot's
    path turned in the ground plane about the body's centre, so that in its stance a front foot steps to one side
    and a back foot to the other (Hengst, Ibbotson, Pham, Sammut, "Omnidirectional locomotion for quadruped robots",
    RoboCup 2001, LNAI 2377). Here the abduction servos (servo 2 of each leg) move the foot sideways in step with its
    ellipse (``IKGoals.turning``, envs/bioloid/gait.py). Drive = stride factor (0 marks time, 1 the full ellipse);
    turn in [-1, 1] (> 0 turns left) scales the sideways swing. The report's gait only walks straight; the
    stride-shortening turn that steered it before turned less than the trot drifts (gait map of 2026-11-28), while
    this one turns 0.2-0.46 rad/s with a spread of about 0.01 rad/s between seeds (``python -m
    benchmarks.gait_maps``). Each player's clock starts at 0 when it resets, with the gait's lead-in.

    It kicks (envs/bioloid/kick.py): a kick starts from the goals the trot left the legs at, blends into the kick's
    lean over the lean's time, runs to its end, and the trot's clock then starts again at 0."""

    kick_zone = KickZone(KICK_AHEAD, KICK_SIDE, KICK_WIDTH)
    # Its gait map runs straight at several settings. Asked for half its cruise, it pushes at (drive 0.5, turn 1),
    # whose legs knock the ball aside; asked for 0.3-0.4 of it, at (0.5, -0.75). One-a-side against random, 20
    # matches of 600 s on seeds 100-119 (2026-11-29): 0.35 won 19 (38 goals), 0.5 16 (22), 0.25 7 (10), 1.0 4 (4).
    push_share = 0.35

    robot_name = "bioloid"
    drives = (0.0, 0.125, 0.25, 0.375, 0.5, 0.75, 1.0)
    turns = (-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0)

    def __init__(self, robot: Robot):
        super().__init__(robot)
        self.goals = IKGoals(TROT, TROT_FREQUENCY, robot.wedge)
        self.kick = Kick(robot.wedge)
        n = robot.num_sims
        self.clock = np.zeros(n)
        self.kick_time = np.full(n, np.inf)  # s since each simulation's kick started (inf: not kicking)
        self.kick_side = np.zeros(n)
        self.kick_from = np.tile(self.kick.ready, (n, 1))  # the goals the kick started from
        self.last = np.tile(self.kick.ready, (n, 1))  # the goals last commanded

    def reset(self, ids: np.ndarray) -> None:
        self.clock[ids] = 0.0
        self.kick_time[ids] = np.inf
        self.last[ids] = self.kick.ready

    def kicking(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Whether each simulation (of ``rows``) is in a kick (its commands are ignored until the kick ends)."""
        return (self.kick_time if rows is None else self.kick_time[rows]) < self.kick.duration

    def commands(self, drive: np.ndarray, turn: np.ndarray, rows: np.ndarray | None = None,
                 kick: np.ndarray | None = None) -> np.ndarray:  # fmt: skip
        goal = self._trot(drive, turn, rows)
        ids = np.arange(len(self.clock)) if rows is None else np.asarray(rows)
        if kick is not None:
            kick = np.asarray(kick, dtype=np.float64)
            start = ~self.kicking(ids) & (np.abs(kick) >= KICK_THRESHOLD)
            self.kick_time[ids[start]] = 0.0
            self.kick_side[ids[start]] = np.sign(kick[start])
            self.kick_from[ids[start]] = self.last[ids[start]]
        active = self.kicking(ids)
        if active.any():
            kicker = ids[active]
            goal[active] = self.kick.counts(self.kick_time[kicker], self.kick_side[kicker], self.kick_from[kicker])
            self.kick_time[kicker] += self.dt
            self.clock[kicker] = 0.0  # the trot starts again from its ready posture when the kick ends
        self.last[ids] = goal
        return goal

    def _trot(self, drive: np.ndarray, turn: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
        clock = self.clock if rows is None else self.clock[rows]
        goal = self.goals.steered(clock, drive, turn)
        if rows is None:
            self.clock = self.clock + self.dt
        else:
            self.clock[rows] += self.dt
        return goal


STEERING: dict[str, type[Steering]] = {s.robot_name: s for s in (RoachSteering, XjusSteering, BioloidSteering)}
SPREAD = 0.25  # the most a point's speed or turn rate may vary between seeds, as a share of the map's largest


def usable(points: list[dict]) -> list[dict]:
    """The measured points a gait map holds: those that ran without a fall on every seed and that repeat, their
    speed and turn rate varying between seeds by at most ``SPREAD`` of the largest speed and turn rate among the
    points without a fall. A setting whose turn rate changes sign from seed to seed would steer a player at random."""
    safe = [p for p in points if p["falls"] == 0]
    speed, rate = max(abs(p["speed"]) for p in safe), max(abs(p["yaw_rate"]) for p in safe)
    return [p for p in safe if p["speed_sd"] <= SPREAD * speed and p["yaw_rate_sd"] <= SPREAD * rate]


@dataclass(frozen=True)
class GaitMap:
    """What speed (m/s, along the heading) and turn rate (rad/s, + to the left) each (drive, turn) of a robot's
    steering gave on the model, averaged over seeds, and its inverse."""

    robot: str
    drive: np.ndarray  # (points,)
    turn: np.ndarray
    speed: np.ndarray
    yaw_rate: np.ndarray
    max_speed: float  # the fastest straight run
    max_yaw_rate: float  # the largest turn rate either way that every drive above the slowest reaches

    @classmethod
    def read(cls, robot: str) -> GaitMap:
        path = MAPS / f"{robot}.json"
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no gait map for the {robot} (python -m benchmarks.gait_maps writes it)")
        data = json.loads(path.read_text())
        points = usable(data["points"])
        return cls(robot, *(np.array([p[k] for p in points], dtype=np.float64)
                            for k in ("drive", "turn", "speed", "yaw_rate")),
                   float(data["max_speed"]), float(data["max_yaw_rate"]))  # fmt: skip

    @functools.cached_property
    def _inverse(self) -> tuple[cKDTree, np.ndarray]:
        """A k-d tree of the measured (speed, turn rate), each scaled by the map's largest, and each point's (drive,
        turn): what scipy's NearestNDInterpolator builds, kept here to look up without its per-call checks."""
        scaled = np.column_stack([self.speed / self.max_speed, self.yaw_rate / self.max_yaw_rate])
        return cKDTree(scaled), np.column_stack([self.drive, self.turn])

    def controls(self, speed: np.ndarray, yaw_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(drive, turn) per row: the measured point nearest to (speed, yaw rate), each scaled by the map's largest.
        Nearest, not interpolated: several (drive, turn) can give much the same speed and turn rate (the Bioloid's
        trot turns by shortening a stride and slows with it), so a blend of neighbours in that space could be a
        setting nobody measured. The queries must be numbers (the actions are checked finite before)."""
        query = np.column_stack([np.asarray(speed) / self.max_speed, np.asarray(yaw_rate) / self.max_yaw_rate])
        tree, values = self._inverse
        found = values[tree.query(query)[1]]
        return found[:, 0], found[:, 1]


class Commands:
    """The ``commands`` mode of a robot: a normalized action (forward speed, turn rate) in [-1, 1] per player, run by
    its steering gait through its gait map. Speed from 0 (-1) to the map's fastest straight run (+1); turn rate up to
    the map's ``max_yaw_rate`` either way (+ to the left). With ``kick``, a robot that can kick has a third action,
    ``kick`` in [-1, 1]. ``kick_zone`` is where the robot's kick sends the ball forward (None: it cannot kick),
    whether or not the action is on."""

    def __init__(self, robot: Robot, kick: bool = False):
        self.steering = STEERING[robot.name](robot)
        self.map = GaitMap.read(robot.name)
        self.kick_zone = self.steering.kick_zone
        self.push_share = self.steering.push_share
        self.kicks = check_flag("kick", kick)
        if self.kicks and self.kick_zone is None:
            kickers = [name for name, s in STEERING.items() if s.kick_zone is not None]
            raise ValueError(f"kick: the {robot.name} has no kick (robots that kick: {', '.join(kickers)})")
        names, units, low, high = ("speed", "yaw_rate"), ("m/s", "rad/s"), (0.0, -self.map.max_yaw_rate), \
            (self.map.max_speed, self.map.max_yaw_rate)  # fmt: skip
        what = "forward speed and turn rate, run by the robot's reference gait"
        if self.kicks:
            names, units, low, high = (*names, "kick"), (*units, "side"), (*low, -1.0), (*high, 1.0)
            what += (f"; and a kick: at or above {KICK_THRESHOLD:g} with the left front leg, at or below "
                     f"{-KICK_THRESHOLD:g} with the right (it runs to its end)")  # fmt: skip
        self.mode = ActionMode(COMMANDS, names, units, low, high, 1.0 / robot.control_dt, what)

    def reset(self, ids: np.ndarray) -> None:
        self.steering.reset(ids)

    def robot_commands(self, actions: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """The robot's own commands (n, its mode's size) for normalized actions (n, 2) of its simulations ``rows``
        (default: all of them)."""
        wanted = self.mode.to_command(actions)
        drive, turn = self.map.controls(wanted[:, 0], wanted[:, 1])
        return self.steering.commands(drive, turn, rows, wanted[:, 2] if self.kicks else None)
