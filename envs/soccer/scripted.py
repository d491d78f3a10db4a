"""The scripted soccer team, the matches' reference opponent: it plays in the ``commands`` mode (forward speed and
turn rate, run by each robot's reference gait), so one script serves every robot.

Each field player walks to the point behind the ball on the line from its aim through the ball, and once there pushes
the ball along that line. It aims behind the centre of the goal it attacks where the ball's straight way there
enters the goal; else (a ball wide of the goal near its line) at the goal line's centre, to bring the ball in front
of the goal first. From three a side the last player keeps goal, staying between the ball and the centre of its own
goal. Every player reads its own observation by name (``ball``, ``goal``, ``own_goal``: positions in its frame) and
steers on the bearing of its target: it turns toward it and walks faster the more it faces it.

A robot that can kick (the Bioloid, whose ball also fits under its body) lines up with the ball in front of its
right front foot, not of its centre (a player choosing its foot afresh at every step would swap sides while on the
line): it walks the line to the goal shifted to its left by the foot's offset, and closes in slowly. Where its
commands have the kick (``kick=True``), it kicks with either foot when the ball lies in that foot's kick zone
(``Commands.kick_zone``) and its aim in the goal it attacks is ahead.

A player that has neither moved nor turned for ``stuck_seconds`` while it wants to (pressed into a goal's net, wedged
between a post and the wall, pushing a ball against the wall) escapes: it turns to the centre spot and walks toward
it for ``ESCAPE_WALK`` body lengths, then plays on. Its memory is the recurrent state of Stable-Baselines3's
``predict(observation, state, episode_start, deterministic) -> (action, state)``: pass back the state it returned,
with ``episode_start`` for rows that start a new match; without a state each call starts afresh and a player never
escapes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from envs.common.robot import ActionMode
from envs.common.task import ObservationLayout
from envs.soccer.field import Field
from envs.soccer.steering import Commands, KickZone

BEHIND = 0.6  # body lengths behind the ball (beyond its radius) where a field player lines up
LINED_UP = 0.35  # body lengths off the line (and behind the ball) within which it pushes
KEEP = 1.5  # body lengths in front of its goal's centre where the keeper stands, toward the ball
AT_PLACE = 0.5  # body lengths from its place within which the keeper stands and faces the ball
TURN_GAIN = 2.0  # rad/s of commanded turn rate per rad of bearing
SLOW_WITHIN = 2.0  # body lengths from its target within which a player slows down
CRUISE = 10.0  # body lengths per second: the fastest a player runs (the roach's tripod runs 24; it overshoots)
PUSH = 0.5  # of its cruising speed, with which a player pushes the ball (and the least a field player slows to),
# unless its gait says otherwise (``Steering.push_share``)
STUCK_SECONDS = 2.0  # a player that has neither moved nor turned for this long, wanting to, is stuck, or
STUCK_LENGTHS = 2.0  # for as long as it takes to walk this many body lengths at cruise, if longer (a slow robot)
STUCK_MOVE = 0.3  # body lengths: less than this from where it was is not moving
STUCK_TURN = 0.5  # rad: less than this from the heading it had is not turning
ESCAPE_WALK = 3.0  # body lengths a stuck player walks toward the centre spot after turning to it
# a player kicks only with the goal it attacks at most this far off straight ahead (a kick goes where the robot
# faces; at 45 deg the scripted Bioloid kicked ten times as often and scored less than half as many goals, 2026-11-29)
KICK_TOWARD = np.radians(20.0)
KICK_SLOW_WITHIN = 0.5  # body lengths from its kick zone within which a kicker pushing the ball slows down, to
KICK_CREEP = 0.15  # of its cruising speed
AIM_DEPTH = 0.5  # of the goal's width: how far behind the goal line's centre a field player aims
JUMP = 1.0  # body lengths between two steps: the player was placed (a kickoff, a penalty), and starts afresh
# the memory of each row (``predict``'s state): where it is and its heading on the field; where it was and its heading
# when it last moved or turned, and how long ago; the seconds left of an escape
MEMORY = ("x", "y", "heading", "anchor_x", "anchor_y", "anchor_heading", "waiting", "escape")


class ScriptedPlayer:
    """One scripted player (a field player, or the keeper) for a match in the ``commands`` mode.

    Args:
        layout: the match's observation layout (``env.observation_structure``).
        mode: the commands mode (``env.mode``: speed and turn rate with their bounds).
        length: the robot's body length, m.
        field: the match's field (its walls and ball).
        keeper: keep goal instead of chasing the ball.
        kick: where the ball must lie for the robot's kick (``Commands.kick_zone``), if it can kick: the player then
            pushes with that foot, and kicks if ``mode`` has the ``kick`` command.
        push: the share of its cruising speed with which it pushes the ball, and the least it slows to as it nears
            any target (``Commands.push_share``; None: ``PUSH``).
    """

    def __init__(self, layout: ObservationLayout, mode: ActionMode, length: float, field: Field,
                 keeper: bool = False, kick: KickZone | None = None, push: float | None = None):  # fmt: skip
        if mode.commands[:2] != ("speed", "yaw_rate"):
            raise ValueError(f"the scripted team plays in the commands mode, not {mode.name!r}")
        self.may_kick = "kick" in mode.commands  # the commands have the kick action (else it only pushes with a foot)
        if self.may_kick and kick is None:
            raise ValueError(f"kick: a commands mode with a kick ({mode.commands}) needs the robot's kick zone")
        self.layout, self.mode, self.length, self.keeper, self.kick = layout, mode, length, keeper, kick
        self.push = PUSH if push is None else float(push)
        if not 0.0 < self.push <= 1.0:
            raise ValueError(f"push: a share of the cruising speed in (0, 1], got {push!r}")
        self.ball_radius = field.ball.radius
        self.aim_depth = AIM_DEPTH * field.goal_width
        self.goal_half_width = 0.5 * field.goal_width
        # how far from the centre spot a player's target may lie: a body length inside the walls
        self.inside = (0.5 * field.length + field.end_border - length, 0.5 * field.width + field.side_border - length)

    def __repr__(self) -> str:
        return f"ScriptedPlayer({'keeper' if self.keeper else 'field player'})"

    def targets(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each row's target point in its own frame (n, 2), and whether it is pushing the ball (n,)."""
        ball, goal, own = (self.layout.get(obs, name) for name in ("ball", "goal", "own_goal"))
        if self.keeper:
            toward = ball - own
            reach = np.linalg.norm(toward, axis=1, keepdims=True)
            keep = np.minimum(KEEP * self.length, reach)
            return own + toward / np.maximum(reach, 1e-9) * keep, np.zeros(len(obs), dtype=bool)
        line = self.aim(ball, goal, own) - ball
        u = line / np.maximum(np.linalg.norm(line, axis=1, keepdims=True), 1e-9)
        if self.kick is not None and not self.keeper:  # the line shifted to its left: the right foot on the line
            ball = ball + np.column_stack([-u[:, 1], u[:, 0]]) * self.kick.side
        reach = self.ball_radius + BEHIND * self.length  # from the ball's centre to the player's, lined up behind it
        # where the player stands relative to the ball, along the line to the goal and across it
        along = -np.sum(ball * u, axis=1)  # < 0: behind the ball
        across = ball[:, 0] * u[:, 1] - ball[:, 1] * u[:, 0]
        # the approach point slides behind the ball along the line, the further the more the player is off it: lined
        # up it aims through the ball; beside or ahead of the ball it aims at a point behind the ball on its own side
        misaligned = np.clip((along + reach) / reach, 0.0, None) + np.abs(across) / reach
        pushing = (along < 0.0) & (np.abs(across) < LINED_UP * self.length)
        back = np.clip(misaligned, 0.0, 1.0)[:, None]
        normal = np.column_stack([-u[:, 1], u[:, 0]])
        side = np.where(across >= 0.0, 1.0, -1.0)[:, None]  # the player's side of the line (the normal points left)
        ahead = (along > -0.5 * reach)[:, None]  # beside or ahead of the ball: round it on its own side
        behind = ball - u * reach * back
        detour = normal * (reach + self.ball_radius)
        target = np.where(ahead, behind + side * detour, behind)
        # by a wall, the way round on the player's own side can lie beyond it: then it goes round the other side
        walled = ahead & (np.linalg.norm(self.on_field(target, goal, own) - target, axis=1) > 0.5 * reach)[:, None]
        target = np.where(walled, behind - side * detour, target)
        through = ball + u * self.length
        return self.on_field(np.where(pushing[:, None], through, target), goal, own), pushing

    def aim(self, ball: np.ndarray, goal: np.ndarray, own: np.ndarray) -> np.ndarray:
        """Where each row's field player aims the ball (n, 2), in its frame: ``AIM_DEPTH`` behind the centre of the
        goal line it attacks, if the ball's straight way there enters the goal a ball's width inside the posts; else
        (a ball wide of the goal near its line) the centre of the goal line, which brings the ball in front of the
        goal first. (Aimed at the line's centre, a ball just short of the line would be pushed along it.)"""
        centre, ex, ey = self.field_frame(goal, own)
        rel = ball - centre
        x, y = np.sum(rel * ex, axis=1), np.sum(rel * ey, axis=1)
        line = np.linalg.norm(goal - centre, axis=1)
        crossing = y * self.aim_depth / np.maximum(line + self.aim_depth - x, 1e-9)  # where it crosses the line
        # a ball on the line (not yet wholly over it) counts as short of it: aimed at the line's centre it would be
        # pushed back out
        through = (x < line + self.ball_radius) & (np.abs(crossing) <= self.goal_half_width - 2.0 * self.ball_radius)
        return goal + np.where(through[:, None], self.aim_depth * ex, 0.0)

    @staticmethod
    def field_frame(goal: np.ndarray, own: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The field's frame in each row's own frame, from the two goals it sees: the centre spot (their midpoint),
        and the unit vectors along the field toward the goal it attacks and across it to the left (n, 2) each."""
        centre = 0.5 * (goal + own)
        ex = (goal - own) / np.maximum(np.linalg.norm(goal - own, axis=1, keepdims=True), 1e-9)
        return centre, ex, np.column_stack([-ex[:, 1], ex[:, 0]])

    def on_field(self, points: np.ndarray, goal: np.ndarray, own: np.ndarray) -> np.ndarray:
        """Points (n, 2) in each player's frame, moved inside the walls by a body length: a ball against a wall has
        its approach point beyond it, and a player sent there would walk into the wall. The field's frame comes from
        the two goals the player sees (their midpoint the centre spot, the line through them the x axis)."""
        centre, ex, ey = self.field_frame(goal, own)
        rel = points - centre
        x = np.clip(np.sum(rel * ex, axis=1), -self.inside[0], self.inside[0])
        y = np.clip(np.sum(rel * ey, axis=1), -self.inside[1], self.inside[1])
        return centre + x[:, None] * ex + y[:, None] * ey

    def pose(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each row's place on the field (n, 2) and heading (n,), in the frame of the goal it attacks (+x), from where
        it sees the two goals."""
        goal, own = self.layout.get(obs, "goal"), self.layout.get(obs, "own_goal")
        along = goal - own  # the field's +x in the player's frame
        heading = -np.arctan2(along[:, 1], along[:, 0])
        centre = 0.5 * (goal + own)  # the centre spot in the player's frame: -R(heading)^T p
        c, s = np.cos(heading), np.sin(heading)
        place = -np.column_stack([c * centre[:, 0] - s * centre[:, 1], s * centre[:, 0] + c * centre[:, 1]])
        return place, heading

    def kicks(self, obs: np.ndarray) -> np.ndarray:
        """Each row's kick command: +1 (the left front leg) or -1 (the right) where the ball lies in the kick zone on
        that side and its aim (:meth:`aim`) is ahead, else 0."""
        n = len(obs)
        if not self.may_kick or self.keeper:
            return np.zeros(n)
        ball, goal, own = (self.layout.get(obs, name) for name in ("ball", "goal", "own_goal"))
        aim = self.aim(ball, goal, own)
        near, far = self.kick.ahead
        in_zone = (ball[:, 0] >= near) & (ball[:, 0] <= far) & (np.abs(np.abs(ball[:, 1]) - self.kick.side)
                                                                  <= self.kick.width)  # fmt: skip
        ahead = np.abs(np.arctan2(aim[:, 1], aim[:, 0])) <= KICK_TOWARD
        return np.where(in_zone & ahead, np.sign(ball[:, 1]), 0.0)

    def steer(self, target: np.ndarray, pushing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed and turn rate (n,) toward each row's target point in its own frame."""
        bearing = np.arctan2(target[:, 1], target[:, 0])
        distance = np.linalg.norm(target, axis=1)
        yaw_rate = np.clip(TURN_GAIN * bearing, self.mode.low[1], self.mode.high[1])
        facing = np.maximum(np.cos(bearing), 0.0) ** 2
        least = 0.0 if self.keeper else self.push  # the keeper comes to rest at its place; a field player keeps pace
        near = np.where(pushing, self.push, np.clip(distance / (SLOW_WITHIN * self.length), least, 1.0))
        return self.cruise * facing * near, yaw_rate

    @property
    def cruise(self) -> float:
        return min(self.mode.high[0], CRUISE * self.length)

    @property
    def stuck_seconds(self) -> float:
        """How long a player waits, neither moving nor turning, before it escapes."""
        return max(STUCK_SECONDS, STUCK_LENGTHS * self.length / self.cruise)

    @property
    def escape_seconds(self) -> float:
        """How long an escape lasts: a half turn at the mode's largest turn rate, then ``ESCAPE_WALK`` at cruise."""
        return np.pi / self.mode.high[1] + ESCAPE_WALK * self.length / self.cruise

    def predict(self, observation: np.ndarray, state: np.ndarray | None = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
        n, dt = len(obs), 1.0 / self.mode.control_freq
        place, heading = self.pose(obs)
        fresh = np.column_stack([place, heading, place, heading, np.zeros((n, 2))])
        memory = fresh if state is None else np.array(np.atleast_2d(state), dtype=np.float64)
        if memory.shape != (n, len(MEMORY)):
            raise ValueError(f"state: expected ({n}, {len(MEMORY)}) as predict returned it, got {memory.shape}")
        restart = np.linalg.norm(place - memory[:, 0:2], axis=1) > JUMP * self.length
        if episode_start is not None:
            restart |= np.asarray(episode_start, dtype=bool).reshape(-1)
        memory[restart] = fresh[restart]
        target, pushing = self.targets(obs)
        speed, yaw_rate = self.steer(target, pushing)
        if self.kick is not None and not self.keeper:  # a kicker closes in on its kick zone slowly: its gait's
            # swinging front legs would knock the ball aside before it lies there
            gap = self.layout.get(obs, "ball")[:, 0] - np.mean(self.kick.ahead)
            closing = np.clip(gap / (KICK_SLOW_WITHIN * self.length), KICK_CREEP, 1.0) * self.cruise
            speed = np.where(pushing, np.minimum(speed, closing), speed)
        idle = np.zeros(n, dtype=bool)
        if self.keeper:  # at its place, it faces the ball
            ball = self.layout.get(obs, "ball")
            idle = np.linalg.norm(target, axis=1) < AT_PLACE * self.length
            low, high = self.mode.low[1], self.mode.high[1]
            yaw_rate = np.where(idle, np.clip(TURN_GAIN * np.arctan2(ball[:, 1], ball[:, 0]), low, high), yaw_rate)
            speed = np.where(idle, 0.0, speed)
        # stuck: neither moved nor turned for stuck_seconds, wanting to; then the escape to the centre spot
        turned = np.abs(np.angle(np.exp(1j * (heading - memory[:, 5])))) > STUCK_TURN
        moved = np.linalg.norm(place - memory[:, 3:5], axis=1) > STUCK_MOVE * self.length
        anchor = moved | turned | idle | (memory[:, 7] > 0.0)
        memory[anchor, 3:6] = np.column_stack([place, heading])[anchor]
        memory[:, 6] = np.where(anchor, 0.0, memory[:, 6] + dt)
        stuck = memory[:, 6] >= self.stuck_seconds - 0.5 * dt  # on the step that completes it, sums of dt aside
        memory[stuck, 6], memory[stuck, 7] = 0.0, self.escape_seconds
        escaping = memory[:, 7] > 0.0
        if escaping.any():
            centre = 0.5 * (self.layout.get(obs, "goal") + self.layout.get(obs, "own_goal"))
            run_speed, run_yaw = self.steer(centre, np.zeros(n, dtype=bool))
            speed, yaw_rate = np.where(escaping, run_speed, speed), np.where(escaping, run_yaw, yaw_rate)
            memory[:, 7] = np.maximum(memory[:, 7] - dt, 0.0)
        memory[:, 0:3] = np.column_stack([place, heading])
        commands = [speed, yaw_rate, self.kicks(obs)] if self.may_kick else [speed, yaw_rate]
        action = self.mode.to_action(np.column_stack(commands))
        single = np.asarray(observation).ndim == 1
        return (action[0], memory[0]) if single else (action, memory)


def scripted_team(env, team: str) -> dict[str, ScriptedPlayer]:
    """The scripted players of ``team`` (``"home"`` or ``"away"``) for a match (``envs.soccer.match``) in the
    commands mode: from three a side, the team's last player keeps goal."""
    base = getattr(env, "unwrapped", env)
    if team not in ("home", "away"):
        raise ValueError(f"team must be 'home' or 'away', got {team!r}")
    players = [agent for agent in base.possible_agents if agent.startswith(team)]
    layout = base.task.layout
    length = base.robot.facts.length
    keeper = len(players) - 1 if len(players) >= 3 else None
    return {agent: scripted_player(layout, base.mode, length, base.field, base.commands, keeper=i == keeper)
            for i, agent in enumerate(players)}  # fmt: skip


class ScriptedTeam:
    """Scripted players acting together, in one :meth:`ScriptedPlayer.predict` call per role rather than one per
    player: every field player of the team (or of both teams: a player's view does not depend on its side) in one,
    every keeper in another, on their observations stacked. Each player's actions and memory are bit for bit those
    of its own ``predict``; only the calls are fewer, which is most of a scripted match's time besides its physics.

    Args:
        players: the players in their order (:func:`scripted_team`'s values, of one team or of both); those that
            play alike (the same role, observation layout, mode, body length, field, kick and push) share a call.
    """

    def __init__(self, players: Sequence[ScriptedPlayer]):
        self.players = list(players)
        if not self.players:
            raise ValueError("players: a scripted team needs at least one player")
        roles: dict[tuple, list[int]] = {}
        for i, p in enumerate(self.players):
            alike = (p.keeper, id(p.layout), id(p.mode), p.length, repr(p.kick), p.push, p.ball_radius, p.aim_depth,
                     p.goal_half_width, p.inside)  # fmt: skip
            roles.setdefault(alike, []).append(i)
        self.roles = [(self.players[i[0]], np.array(i)) for i in roles.values()]

    @classmethod
    def of(cls, env: Any, teams: Sequence[str] = ("home", "away")) -> tuple[ScriptedTeam, list[str]]:
        """The scripted players of ``teams`` of a match in the commands mode, and their agents in the order of
        :meth:`act`'s columns."""
        players = {agent: p for team in teams for agent, p in scripted_team(env, team).items()}
        return cls(list(players.values())), list(players)

    def act(self, obs: np.ndarray, memory: np.ndarray | None = None,
            episode_start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
        """Every player's action in each of ``n`` matches: ``obs`` (n, players, size), ``memory`` (n, players,
        ``len(MEMORY)``) as this returned it (None: every player starts afresh), ``episode_start`` (n,) for matches
        that start again; returns the actions (n, players, action size) and the memory."""
        obs = np.asarray(obs, dtype=np.float64)
        n, k = obs.shape[:2]
        if k != len(self.players):
            raise ValueError(f"obs: expected {len(self.players)} players in axis 1, got shape {obs.shape}")
        if memory is None:  # as ScriptedPlayer.predict without a state: every row afresh
            memory, start = np.zeros((n, k, len(MEMORY))), np.ones(n, dtype=bool)
        else:
            memory = np.array(memory, dtype=np.float64)
            if memory.shape != (n, k, len(MEMORY)):
                raise ValueError(f"memory: expected {(n, k, len(MEMORY))} as act returned it, got {memory.shape}")
            start = np.zeros(n, dtype=bool) if episode_start is None else np.asarray(episode_start, bool).reshape(n)
        actions: np.ndarray | None = None
        for player, columns in self.roles:
            rows = obs[:, columns].reshape(n * len(columns), -1)
            action, state = player.predict(rows, memory[:, columns].reshape(len(rows), -1),
                                           np.repeat(start, len(columns)))  # fmt: skip
            if actions is None:
                actions = np.empty((n, k, action.shape[-1]))
            actions[:, columns] = action.reshape(n, len(columns), -1)
            memory[:, columns] = state.reshape(n, len(columns), -1)
        return actions, memory


def scripted_player(layout: ObservationLayout, mode: ActionMode, length: float, field: Field,
                    commands: Commands | None, keeper: bool = False) -> ScriptedPlayer:  # fmt: skip
    """A scripted player of a robot whose ``commands`` (``envs.soccer.steering.Commands``; None outside the commands
    mode, which the player refuses) give its kick zone and push share."""
    kick = None if commands is None else commands.kick_zone
    push = None if commands is None else commands.push_share
    return ScriptedPlayer(layout, mode, length, field, keeper=keeper, kick=kick, push=push)
