"""Soccer fields and balls for each robot, after RoboCup's leagues, and the spec edit that builds them.

The Bioloid plays on the RoboCup Four-Legged League's field (it was built for the Sony AIBO, a quadruped of the
Bioloid's size) with that league's ball. The other robots play on the same field scaled by their body length over
the Bioloid's (0.30 m): the xJüs (0.53 m) on one of about the Standard Platform League's size with that league's
100 mm ball, the VelociRoACH (0.10 m) on a tabletop field with a table-tennis ball. Every number, and where it comes
from, is in docs/soccer.md; tests/test_soccer_field.py checks the built field and the ball's roll and bounce
against them.

The field is built into a robot's scene by :func:`field_edit`: the scene's floor is the pitch (its friction is the
robot's, which its gaits were tuned on), the walls and each goal are bodies of their own (a robot's ground rules count
the world body's geoms as ground: a player that leans on a wall breaks none), the lines are visual only, and the ball
is a free body whose contact parameters rule its contacts (priority 2).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from envs.common.robot import check_number

BALL = "ball"
BOUNCE_DROPS = np.array([5.0, 10.0, 20.0])  # drop heights, ball radii, over which the ball's bounce is fitted
WALLS = "walls"
GOALS = ("goal_home", "goal_away")  # the goal the home team defends (at -x) and the one it attacks (at +x)
TOP_CAMERA = "top"
BALL_POS, BALL_VEL = "ball_pos", "ball_vel"  # the ball's sensors: world position and velocity
TOUCH = "touch_ball_"  # prefix of each player's contact sensor with the ball
HEAD_AXIS = "head_axis_"  # prefix of each player's head direction sensor (robots with a head that looks along -z)
GREEN = (0.18, 0.45, 0.2, 1.0)
WHITE = (0.95, 0.95, 0.95, 1.0)
GOAL_COLOURS = ((0.95, 0.8, 0.1, 1.0), (0.15, 0.35, 0.9, 1.0))  # yellow and sky-blue goals, as the league's


@dataclass(frozen=True)
class Ball:
    """A ball: its size, mass and how it rolls and bounces on the pitch.

    ``rolling_resistance`` is the dimensionless coefficient ``C_rr``: a ball rolling on the pitch slows at
    ``C_rr g / (1 + I / (m r^2))``. ``restitution`` is the ratio of rebound to impact speed on the pitch. MuJoCo's
    soft contacts and friction cones do not give either exactly from the textbook formulas, so
    :func:`ball_contact` fits the contact's damping and rolling friction to them in the scene's own physics options
    (timestep, integrator, cone), and tests/test_soccer_field.py measures both in the built scene.
    """

    name: str
    radius: float  # m
    mass: float  # kg
    shell: bool  # a hollow shell (I = 2/3 m r^2) or solid (2/5 m r^2)
    friction: float  # sliding friction on the pitch and the players
    rolling_resistance: float  # C_rr on the pitch
    restitution: float  # rebound / impact speed on the pitch
    contact_time: float = 0.02  # s, how long a bounce lasts (the contact spring's half period)

    @property
    def inertia(self) -> float:
        return self.inertia_ratio * self.mass * self.radius**2

    @property
    def inertia_ratio(self) -> float:
        """I / (m r^2): 2/3 for a thin shell, 2/5 for a solid ball."""
        return 2.0 / 3.0 if self.shell else 0.4

    def deceleration(self, gravity: float = 9.81) -> float:
        """How fast the ball slows as it rolls on the pitch, m/s^2."""
        return self.rolling_resistance * gravity / (1.0 + self.inertia_ratio)


def _ball_model(ball: Ball, option: mujoco.MjOption, damping: float, rolling: float) -> mujoco.MjModel:
    """The ball alone on a plane, in the scene's physics options."""
    spec = mujoco.MjSpec()
    spec.option.timestep, spec.option.integrator, spec.option.cone = option.timestep, option.integrator, option.cone
    spec.option.iterations, spec.option.ls_iterations = option.iterations, option.ls_iterations
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 1])
    body = spec.worldbody.add_body(pos=[0, 0, ball.radius])
    body.add_freejoint()
    _ball_geom(body, ball, damping, rolling)
    return spec.compile()


def _ball_geom(body: mujoco.MjsBody, ball: Ball, damping: float, rolling: float) -> None:
    body.mass, body.inertia, body.explicitinertial = ball.mass, [ball.inertia] * 3, True
    body.ipos, body.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
    omega = math.pi / ball.contact_time
    body.add_geom(name=BALL, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[ball.radius, 0, 0], rgba=[1.0, 0.45, 0.05, 1.0],
                  condim=6, priority=2, friction=[ball.friction, rolling, rolling],
                  solref=[-omega * omega, -damping], solimp=[0.95, 0.99, 0.001, 0.5, 2], mass=0,
                  density=0)  # fmt: skip


def measure_bounce(model: mujoco.MjModel, drop: float, body: str | int = 1, at: Sequence[float] = (0, 0)) -> float:
    """The ball's coefficient of restitution as the table-tennis rules measure it: the square root of its rebound
    height over its drop height, dropped from ``drop`` m onto the ground at ``at`` (x, y) (``body``: the ball's free
    body)."""
    data = mujoco.MjData(model)
    q, v = _free_addresses(model, body)
    data.qpos[q : q + 2] = at
    rest = float(data.qpos[q + 2])
    first = int(model.body_geomadr[model.body(body).id])
    geoms = np.arange(first, first + int(model.body_geomnum[model.body(body).id]))
    data.qpos[q + 2] += drop
    touched, top = False, None
    for _ in range(int((2.0 + 4.0 * math.sqrt(drop / 9.81)) / model.opt.timestep)):
        mujoco.mj_step(model, data)
        touched = touched or bool(np.isin(data.contact.geom[: data.ncon], geoms).any())
        if touched and data.qvel[v + 2] > 0:
            top = max(top or 0.0, float(data.qpos[q + 2]))
        elif top is not None and data.qvel[v + 2] <= 0:
            break
    return math.sqrt(max(top - rest, 0.0) / drop) if top is not None else 0.0


def measure_deceleration(
    model: mujoco.MjModel, speed: float, seconds: float = 0.5, body: str | int = 1, at: Sequence[float] = (0, 0)
) -> float:
    """How fast the ball slows, m/s^2, rolling without slipping along x from ``speed`` on the ground from ``at``
    (over ``seconds``; ``body``: the ball's free body)."""
    data = mujoco.MjData(model)
    q, v = _free_addresses(model, body)
    data.qpos[q : q + 2] = at
    radius = float(model.geom_size[model.body_geomadr[model.body(body).id], 0])
    data.qvel[v], data.qvel[v + 4] = speed, speed / radius
    mujoco.mj_forward(model, data)
    steps = round(seconds / model.opt.timestep)
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return (speed - float(data.qvel[v])) / (steps * model.opt.timestep)


def _free_addresses(model: mujoco.MjModel, body: str | int) -> tuple[int, int]:
    joint = int(model.body_jntadr[model.body(body).id])
    return int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])


@functools.lru_cache(maxsize=32)
def ball_contact(ball: Ball, timestep: float, integrator: int, cone: int, iterations: int) -> tuple[float, float]:
    """(damping, rolling friction) of the ball's contact that give its ``restitution`` and its rolling deceleration
    in a scene of these physics options: the damping by bisection on a simulated drop, the rolling friction scaled
    from one simulated roll (the deceleration is proportional to it)."""
    option = mujoco.MjOption()
    option.timestep, option.integrator, option.cone, option.iterations = timestep, integrator, cone, iterations
    option.ls_iterations = max(iterations // 2, 1)
    drops = BOUNCE_DROPS * ball.radius
    low, high = 0.0, 4.0 * math.pi / ball.contact_time  # critical damping is 2 omega
    rolling = ball.rolling_resistance * ball.radius
    for _ in range(16):  # to within 1/65536 of the range: the restitution to about 0.001
        damping = 0.5 * (low + high)
        model = _ball_model(ball, option, damping, rolling)
        if np.mean([measure_bounce(model, drop) for drop in drops]) > ball.restitution:
            low = damping
        else:
            high = damping
    damping = 0.5 * (low + high)
    speed = max(4.0 * ball.deceleration() * 0.5, 0.1)
    measured = measure_deceleration(_ball_model(ball, option, damping, rolling), speed)
    return damping, rolling * ball.deceleration() / measured


@dataclass(frozen=True)
class Field:
    """A field: the playing area inside the lines, the border to the walls, the goals, the lines and the ball.

    The home team defends the goal at -x and attacks the one at +x; the centre spot is the origin.
    """

    name: str
    length: float  # m, between the goal lines
    width: float  # m, between the touch lines
    end_border: float  # m, from the goal lines to the walls
    side_border: float  # m, from the touch lines to the walls
    goal_width: float  # m, inside the posts
    goal_height: float  # m, under the crossbar
    goal_depth: float  # m, from the goal line to the back of the goal
    wall_height: float  # m
    line_width: float  # m
    centre_circle: float  # m, radius
    ball: Ball
    scale: float = 1.0  # the factor this field was scaled by from its league's (1: as the rules give it)

    def scaled(self, factor: float, name: str, ball: Ball) -> Field:
        """This field with every length times ``factor``, and its own ball."""
        factor = check_number("factor", factor, 0, strict=True)
        lengths = ("length", "width", "end_border", "side_border", "goal_width", "goal_height", "goal_depth",
                   "wall_height", "line_width", "centre_circle")  # fmt: skip
        return replace(
            self, name=name, ball=ball, scale=self.scale * factor, **{k: getattr(self, k) * factor for k in lengths}
        )

    @property
    def half_length(self) -> float:
        return 0.5 * self.length

    @property
    def half_width(self) -> float:
        return 0.5 * self.width

    def left_field(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Whether a ball at (``x``, ``y``) has left the field: wholly past a touch line, or wholly past a goal line
        beside the goal (past it between the posts is a goal)."""
        r = self.ball.radius
        past_goal_line = (np.abs(x) > self.half_length + r) & (np.abs(y) >= 0.5 * self.goal_width)
        return (np.abs(y) > self.half_width + r) | past_goal_line

    def throw_in(self, x: float, y: float, last: int, players: np.ndarray, clearance: float) -> tuple[float, float]:
        """Where a referee puts back a ball that left the field at (``x``, ``y``): ``THROW_IN_BACK`` toward the goal
        of the team that touched it last (``last``: +1 the home team, whose goal is at -x; -1 the away team; 0
        nobody since the kickoff or the last throw-in: toward the halfway line, not past it), at least that far from
        either goal line, ``THROW_IN_INSET`` inside the touch lines; then moved along the touch line by
        ``clearance``, first the way the ball was sent, until none of ``players`` ((n, 2) positions) lies within
        ``clearance`` of it (a ball put inside a robot is shot out of it), or left there if no such place is within
        those limits."""
        back, inset = THROW_IN_BACK * self.scale, THROW_IN_INSET * self.scale
        way = -last if last != 0 else (-float(np.sign(x)) or 1.0)  # the way the ball is sent back (+x from the centre)
        placed = x - last * back if last != 0 else np.sign(x) * max(abs(x) - back, 0.0)
        limit = self.half_length - back
        placed = float(np.clip(placed, -limit, limit))
        y = float(np.clip(y, inset - self.half_width, self.half_width - inset))
        players = np.asarray(players, dtype=np.float64).reshape(-1, 2)
        steps = int(2.0 * limit / clearance) + 2 if clearance > 0 else 1
        # the placed spot first (+ 0.0: a spot at the halfway line as +0, never -0), then along the line both ways
        spots = [placed + 0.0] + [placed + side * k * clearance for k in range(1, steps) for side in (way, -way)]
        for spot in spots:
            near = len(players) and np.min(np.hypot(players[:, 0] - spot, players[:, 1] - y)) <= clearance
            if abs(spot) <= limit + 1e-9 and not near:
                return float(spot), y
        return placed, y


def _box(body: mujoco.MjsBody, name: str, centre, half, rgba, collide: bool = True) -> None:
    body.add_geom(
        name=name,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=list(centre),
        size=list(half),
        rgba=list(rgba),
        contype=1 if collide else 0,
        conaffinity=1 if collide else 0,
        group=0 if collide else 2,
    )


def field_edit(field: Field, players: Sequence[str] = (), root_body: str | None = None, head: str | None = None):
    """A scene edit that builds ``field`` into a robot's scene: the pitch colour, lines, walls, two goals, the ball
    at the centre spot, a top-down camera, the ball's sensors (world position and velocity), a contact sensor
    between each player's subtree (``<player>/<root_body>``) and the ball and, for a robot with a ``head`` body, the
    direction of each player's head (its z axis in the world, ``head_axis_<player>``)."""

    def edit(spec: mujoco.MjSpec) -> None:
        f, b = field, field.ball
        hl, hw = f.half_length, f.half_width
        for material in spec.materials:
            if material.name == "grid":  # the shared floor's checker: a pitch's green
                material.rgba = list(GREEN)
                material.textures = [""] * len(material.textures)
        world = spec.worldbody
        lines = world.add_body(name="lines")
        t = 0.5 * f.line_width
        lift = 1e-4  # above the pitch, so that it draws
        for name, centre, half in (
            ("touch_line_left", (0, hw, lift), (hl + t, t, lift)),
            ("touch_line_right", (0, -hw, lift), (hl + t, t, lift)),
            ("goal_line_home", (-hl, 0, lift), (t, hw + t, lift)),
            ("goal_line_away", (hl, 0, lift), (t, hw + t, lift)),
            ("halfway_line", (0, 0, lift), (t, hw, lift)),
        ):
            _box(lines, name, centre, half, WHITE, collide=False)
        lines.add_geom(name="centre_circle", type=mujoco.mjtGeom.mjGEOM_CYLINDER, pos=[0, 0, lift],
                       size=[f.centre_circle, lift, 0], rgba=[1, 1, 1, 0.35], contype=0, conaffinity=0,
                       group=2)  # fmt: skip
        # walls at the edge of the border, as thick as a line, around the whole field
        walls = world.add_body(name=WALLS)
        wt = max(f.line_width, 0.01 * f.scale)
        xw, yw, zh = hl + f.end_border + wt, hw + f.side_border + wt, 0.5 * f.wall_height
        for name, centre, half in (
            ("wall_left", (0, yw, zh), (xw + wt, wt, zh)),
            ("wall_right", (0, -yw, zh), (xw + wt, wt, zh)),
            ("wall_home", (-xw, 0, zh), (wt, yw, zh)),
            ("wall_away", (xw, 0, zh), (wt, yw, zh)),
        ):
            _box(walls, name, centre, half, WHITE)
        # each goal: a back, two sides and a roof, open to the field at its goal line
        for side, (body_name, colour) in zip((-1, 1), zip(GOALS, GOAL_COLOURS, strict=True), strict=True):
            goal = world.add_body(name=body_name)
            x_back = side * (hl + f.goal_depth + t)
            x_mid = side * (hl + 0.5 * f.goal_depth)
            gh, gw, gd = 0.5 * f.goal_height, 0.5 * f.goal_width, 0.5 * f.goal_depth
            for name, centre, half in (
                ("back", (x_back, 0, gh), (t, gw + 2 * t, gh)),
                ("side_left", (x_mid, gw + t, gh), (gd, t, gh)),
                ("side_right", (x_mid, -gw - t, gh), (gd, t, gh)),
                ("roof", (x_mid, 0, f.goal_height + t), (gd, gw + 2 * t, t)),
            ):
                _box(goal, f"{body_name}_{name}", centre, half, colour)
            # the posts, white, at the goal line
            for y in (gw + t, -gw - t):
                _box(goal, f"{body_name}_post_{'left' if y > 0 else 'right'}", (side * hl, y, gh + t), (t, t, gh + t),
                     WHITE)  # fmt: skip
        damping, rolling = ball_contact(b, spec.option.timestep, int(spec.option.integrator), int(spec.option.cone),
                                        spec.option.iterations)  # fmt: skip
        ball = world.add_body(name=BALL, pos=[0, 0, b.radius])
        ball.add_freejoint(name=BALL)
        _ball_geom(ball, b, damping, rolling)
        spec.add_sensor(name=BALL_POS, type=mujoco.mjtSensor.mjSENS_FRAMEPOS, objtype=mujoco.mjtObj.mjOBJ_BODY,
                        objname=BALL)  # fmt: skip
        spec.add_sensor(name=BALL_VEL, type=mujoco.mjtSensor.mjSENS_FRAMELINVEL, objtype=mujoco.mjtObj.mjOBJ_BODY,
                        objname=BALL)  # fmt: skip
        for player in players:  # each team in its goal's colour (the home team defends the yellow goal)
            body = spec.body(f"{player}/{root_body}") if root_body else None
            if body is not None:
                colour = GOAL_COLOURS[0] if player.startswith("home") else GOAL_COLOURS[1]
                for geom in body.find_all(mujoco.mjtObj.mjOBJ_GEOM):  # the root's own geoms among them
                    if geom.contype or geom.conaffinity or geom.group < 3:
                        geom.material, geom.rgba = "", list(colour)
        for player in players:
            spec.add_sensor(
                name=TOUCH + player,
                type=mujoco.mjtSensor.mjSENS_CONTACT,
                objtype=mujoco.mjtObj.mjOBJ_XBODY,
                objname=f"{player}/{root_body}",
                reftype=mujoco.mjtObj.mjOBJ_BODY,
                refname=BALL,
                intprm=[1, 0, 1],  # data "found", no reduction, one match
            )
        for player in players if head else ():
            spec.add_sensor(name=HEAD_AXIS + player, type=mujoco.mjtSensor.mjSENS_FRAMEZAXIS,
                            objtype=mujoco.mjtObj.mjOBJ_XBODY, objname=f"{player}/{head}")  # fmt: skip
        # a camera above the centre spot that sees the whole field and its walls (45 deg field of view)
        reach = max(xw + wt, (yw + wt) * 4.0 / 3.0)
        world.add_camera(name=TOP_CAMERA, pos=[0, 0, 1.1 * reach / math.tan(math.radians(22.5))], fovy=45.0)

    return edit


# --- the leagues' fields and balls: each number's source is in docs/soccer.md ---------------------------------------
# a ball that leaves the field is put back by the referee 1 m behind where it left, toward the goal of the team that
# touched it last (RoboCup SPL rule book, "ball leaving the field"; scaled with the field); the SPL puts it on the
# touch line, here it goes a Bioloid's body length inside it (assumed), so that a player gets round it on either side
# and a pushing player does not pin it to the wall again
THROW_IN_BACK = 1.0  # m on the Four-Legged field
THROW_IN_INSET = 0.3  # m on the Four-Legged field
# the Four-Legged League's ball: 84 mm (rUNSWift's 2005 field definition, BALL_RADIUS = 4.2 cm), a hollow plastic
# shell; its mass is assumed (30 g: no source found); its roll: C_rr 0.05, a deceleration of 0.29 m/s^2, within the
# 0.19-0.35 m/s^2 that RoboCup teams' simulators use for balls on carpet and turf; its bounce on carpet is assumed
AIBO_BALL = Ball("Four-Legged League ball", radius=0.042, mass=0.030, shell=True, friction=0.5,
                 rolling_resistance=0.05, restitution=0.5)  # fmt: skip
# the 2005 field: 5.4 x 3.6 m inside the lines, a carpet 0.3 m beyond the goal lines and 0.2 m beyond the touch
# lines (6.0 x 4.0 m), goals 0.8 m wide, 0.3 m deep and 0.3 m high, a centre circle of 0.36 m; the wall around the
# carpet is the 2004 rule book's outer wall, 0.3 m high; the 25 mm lines are assumed
FOUR_LEGGED = Field("RoboCup Four-Legged League field (2005)", length=5.4, width=3.6, end_border=0.3,
                    side_border=0.2, goal_width=0.8, goal_height=0.3, goal_depth=0.3, wall_height=0.3,
                    line_width=0.025, centre_circle=0.18, ball=AIBO_BALL)  # fmt: skip
BIOLOID_LENGTH = 0.30  # m, the Bioloid's body length (envs/bioloid/constants.py): the Four-Legged field's scale
# ITTF Technical Leaflet T3: 40 mm, 2.7 g; it rebounds 240-260 mm dropped from 305 mm onto steel (e 0.89-0.92: 0.905
# at 250 mm), the roach's pitch being a hard, smooth floor; its rolling resistance is assumed as the other balls'
TABLE_TENNIS_BALL = Ball("table-tennis ball", radius=0.020, mass=0.0027, shell=True, friction=0.5,
                         rolling_resistance=0.05, restitution=0.905)  # fmt: skip

# a size-3 soccer ball, the smallest of the youth sizes: 23-24 in (58-61 cm) round, 11-12 oz (310-340 g) (youth
# leagues' ball-size tables); the xJüs plays with it because the SPL's 100 mm ball rolls under its 0.157 m belly,
# between its legs, untouched (measured: it walked over it); its bounce on turf and its roll are assumed as the others'
SIZE_3_BALL = Ball("size-3 soccer ball", radius=0.094, mass=0.31, shell=True, friction=0.5, rolling_resistance=0.05,
                   restitution=0.6)  # fmt: skip


def field_for(length: float, ball: Ball, name: str) -> Field:
    """The Four-Legged League's field scaled to a robot of body length ``length`` (m), with its ball."""
    return FOUR_LEGGED.scaled(length / BIOLOID_LENGTH, name, ball)
