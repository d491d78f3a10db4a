"""Which robots play soccer, on which field: name -> (robot class, field)."""

from __future__ import annotations

from envs.bioloid import constants as bioloid
from envs.bioloid.robot import Bioloid
from envs.common.robot import Robot
from envs.soccer.field import BIOLOID_LENGTH, FOUR_LEGGED, SIZE_3_BALL, TABLE_TENNIS_BALL, Field, field_for
from envs.velociroach import constants as roach
from envs.velociroach.robot import VelociRoach
from envs.xjus import constants as xjus
from envs.xjus.robot import Xjus

if abs(bioloid.LENGTH - BIOLOID_LENGTH) > 1e-9:  # the Four-Legged field's scale is the Bioloid's length
    raise RuntimeError(f"the Bioloid's length is {bioloid.LENGTH} m, the fields' scale {BIOLOID_LENGTH} m")

# the robot's name in ids (RoachGoToBall) and in the match's ``robot`` argument (lower case)
ROBOTS: dict[str, type[Robot]] = {"Bioloid": Bioloid, "Xjus": Xjus, "Roach": VelociRoach}
BY_NAME: dict[str, str] = {name.lower(): name for name in ROBOTS}  # a match's ``robot`` -> its key in ROBOTS
# the body each robot sees from, looking along its -z axis: the Bioloid's head (assets/bioloid/bioloid.xml; with the
# neck raised, N_2 pans it and HEAD tilts it), so an optional field of view follows its neck and head servos
HEADS: dict[str, str] = {Bioloid.name: "HEAD"}
FIELDS: dict[str, Field] = {
    "Bioloid": FOUR_LEGGED,
    "Xjus": field_for(xjus.LENGTH, SIZE_3_BALL, "Four-Legged League field x 1.77 (xJüs)"),
    "Roach": field_for(roach.LENGTH, TABLE_TENNIS_BALL, "Four-Legged League field x 0.33 (VelociRoACH)"),
}
