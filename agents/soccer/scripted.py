"""The scripted soccer team, the matches' reference opponent: it plays in the ``commands`` mode (forward speed and
turn rate, run by each robot's reference gait), so one script serves every robot.

Each field player walks to the point behind the ball on the line from the goal it attacks through the ball, and once
there pushes the ball along that line; from three a side the last player keeps goal, staying between the ball and the
centre of its own goal. Every player reads its own observation by name (``ball``, ``goal``, ``own_goal``: positions in
its frame) and steers on the bearing of its target: it turns toward it and walks faster the more it faces it.
Players follow Stable-Baselines3's ``predict(observation, state, episode_start, deterministic)``, batched or not.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.common.robot import ActionMode
from envs.common.task import ObservationLayout

BEHIND = 0.6  # body lengths behind the ball (beyond its radius) where a field player lines up
LINED_UP = 0.35  # body lengths off the line (and behind the ball) within which it pushes
KEEP = 1.5  # body lengths in front of its goal's centre where the keeper stands, toward the ball
TURN_GAIN = 2.0  # rad/s of commanded turn rate per rad of bearing
SLOW_WITHIN = 2.0  # body lengths from its target within which a player slows down
CRUISE = 10.0  # body lengths per second: the fastest a player runs (the roach's tripod runs 24; it overshoots)
PUSH = 0.5  # of its cruising speed, with which a player pushes the ball (and the least it slows to)


class ScriptedPlayer:
    """One scripted player (a field player, or the keeper) for a match in the ``commands`` mode.

    Args:
        layout: the match's observation layout (``env.observation_structure``).
        mode: the commands mode (``env.mode``: speed and turn rate with their bounds).
        length: the robot's body length, m; ``ball_radius``: the ball's, m.
        keeper: keep goal instead of chasing the ball.
    """

    def __init__(self, layout: ObservationLayout, mode: ActionMode, length: float, ball_radius: float,
                 keeper: bool = False):  # fmt: skip
        if mode.commands != ("speed", "yaw_rate"):
            raise ValueError(f"the scripted team plays in the commands mode, not {mode.name!r}")
        self.layout, self.mode, self.length, self.ball_radius, self.keeper = layout, mode, length, ball_radius, keeper

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
        line = goal - ball
        u = line / np.maximum(np.linalg.norm(line, axis=1, keepdims=True), 1e-9)
        behind = np.sum(ball * u, axis=1)  # how far the player (the origin) is behind the ball along the line
        off_line = np.abs(-ball[:, 0] * u[:, 1] + ball[:, 1] * u[:, 0])
        pushing = (behind > 0.0) & (off_line < LINED_UP * self.length)
        spot = ball - u * (self.ball_radius + BEHIND * self.length)
        through = ball + u * self.length
        # a player in front of the ball goes round it: to the spot behind, past the ball's side
        side = np.sign(-ball[:, 0] * u[:, 1] + ball[:, 1] * u[:, 0])[:, None] * np.column_stack([-u[:, 1], u[:, 0]])
        around = np.where((behind < 0.0)[:, None], spot + side * (self.ball_radius + self.length), spot)
        return np.where(pushing[:, None], through, around), pushing

    def predict(self, observation: np.ndarray, state: Any = None, episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:  # fmt: skip
        obs = np.atleast_2d(np.asarray(observation, dtype=np.float64))
        target, pushing = self.targets(obs)
        bearing = np.arctan2(target[:, 1], target[:, 0])
        distance = np.linalg.norm(target, axis=1)
        low, high = self.mode.low[1], self.mode.high[1]
        yaw_rate = np.clip(TURN_GAIN * bearing, low, high)
        facing = np.maximum(np.cos(bearing), 0.0) ** 2
        cruise = min(self.mode.high[0], CRUISE * self.length)
        near = np.where(pushing, PUSH, np.clip(distance / (SLOW_WITHIN * self.length), PUSH, 1.0))
        speed = cruise * facing * near
        if self.keeper:  # at its place, it faces the ball
            ball = self.layout.get(obs, "ball")
            settled = distance < 0.3 * self.length
            yaw_rate = np.where(settled, np.clip(TURN_GAIN * np.arctan2(ball[:, 1], ball[:, 0]), low, high), yaw_rate)
            speed = np.where(settled, 0.0, speed)
        action = self.mode.to_action(np.column_stack([speed, yaw_rate]))
        single = np.asarray(observation).ndim == 1
        return (action[0], None) if single else (action, None)


def scripted_team(env, team: str) -> dict[str, ScriptedPlayer]:
    """The scripted players of ``team`` (``"home"`` or ``"away"``) for a match (``envs.soccer.match``) in the
    commands mode: from three a side, the team's last player keeps goal."""
    base = getattr(env, "unwrapped", env)
    if team not in ("home", "away"):
        raise ValueError(f"team must be 'home' or 'away', got {team!r}")
    players = [agent for agent in base.possible_agents if agent.startswith(team)]
    layout = base.task.layout
    length, radius = base.robot.facts.length, base.field.ball.radius
    return {agent: ScriptedPlayer(layout, base.mode, length, radius, keeper=len(players) >= 3 and i == len(players) - 1)
            for i, agent in enumerate(players)}  # fmt: skip
