"""Bioloid quadruped names, source facts and servo settings.

The physical model constants (masses, anchors, axes, shapes) live in ``assets/bioloid/bioloid.xml``, each with its
source. This module holds what the code needs beside them: the servo names the report uses ([bioloid-webots,
Figure 41 and Table] 3), the postures in servo counts, each servo's allowed range, and the facts the model is checked
against.
"""

from __future__ import annotations

import math

import numpy as np

import assets

SCENE_XML = assets.path("bioloid", "scene.xml")

# --- names ([bioloid-webots, Table 3 and Figure 41]) ----------------------------------------------------
LEGS = ("F_L", "F_R", "B_L", "B_R")  # front/back, left/right
SIDES = ("left", "right")
LEG_SIDE = {"F_L": "left", "F_R": "right", "B_L": "left", "B_R": "right"}
SERVOS = (
    "PELVIS",
    "F_L_1", "F_L_2", "F_L_3",
    "F_R_1", "F_R_2", "F_R_3",
    "B_L_1", "B_L_2", "B_L_3",
    "B_R_1", "B_R_2", "B_R_3",
    "N_1", "N_2", "HEAD",
)  # fmt: skip
SERVO_INDEX = {name: i for i, name in enumerate(SERVOS)}
HIP = {leg: f"{leg}_1" for leg in LEGS}  # pitch at the hip
ABDUCTION = {leg: f"{leg}_2" for leg in LEGS}  # swings the leg out to the side
KNEE = {leg: f"{leg}_3" for leg in LEGS}
ROOT_BODY = "BODY"
ROOT_JOINT = "root"
FLOOR_GEOM = "floor"
FOOT_GEOM = {leg: f"{leg}_foot" for leg in LEGS}

# what may touch the ground when the robot walks: each leg's shank below the knee, its crutch and sole. Not the knee
# servo (on the thigh, where the shank turns): a body lowered onto its knees is a crawl, though the report's IK gaits
# set their front knees down at the back of the stroke (ik-trot: 12% of its steps, up to 16% turning hardest; the
# grace of envs/common/locomotion.py absorbs it). The report warns against gaits where the dog is "almost swimming" on
# the ground [bioloid-webots, IV.A]
FEET = tuple(KNEE.values())
# the body's origin above level ground in the gaits' ready posture (lowest sole on the ground), and the lowest point
# of the body's own geoms (CM-5 and its servo cases) then, m; from the model (assets/bioloid/);
# tests/test_ground_rules.py recomputes them
STANDING_HEIGHT = 0.1406
BELLY_CLEARANCE = 0.1157
CRUTCH_GEOM = {leg: f"{leg}_crutch" for leg in LEGS}
SOLE_SITE = {leg: f"{leg}_sole" for leg in LEGS}
SENSOR_TOUCH = {leg: f"{leg}_touch" for leg in LEGS}
SENSOR_GYRO, SENSOR_ACCEL = "gyro", "accel"
SENSOR_BODY_POS, SENSOR_BODY_QUAT, SENSOR_BODY_VEL = "body_pos", "body_quat", "body_vel"

# --- facts from the sources (what the model is checked against) ---------------------------------------------------
MASS = 1.76  # kg, [bioloid-webots, Table 3] (the sum of its parts: 1.760 kg)
MASS_TOLERANCE = 0.02  # the model's parts sum to MASS within +-2% (tests/test_bioloid_model.py)
PARTS_G = {  # g, [bioloid-webots, Table 3]
    "BODY": 692, "PELVIS": 146, "N_1": 10, "N_2": 118, "HEAD": 110,
    **{f"{leg}_1": 12 for leg in LEGS}, **{f"{leg}_2": 126 for leg in LEGS},
    "F_L_3": 32, "F_R_3": 32, "B_L_3": 34, "B_R_3": 34,
}  # fmt: skip
HIP_ANCHOR_FRONT = (0.0565, 0.086, 0.0135)  # m, front-left hip in the body frame [webots-bioloid]
L1_SEED, L2_SEED = 0.09, 0.085  # m, the leg segments the report's IK used [bioloid-webots, VI.A]
ABDUCTION_DROP = 0.0145  # m, hip pitch axis to abduction axis (Webots model)
THIGH = 0.083  # m, abduction axis to knee, "0.083 m joint-to-joint" [webots-bioloid]
SHANK = 0.085  # m, knee to sole, L2 [bioloid-webots, VI.A]
BACK_CRUTCH_OFFSET = 0.0145  # m, the back crutches sit behind their knee line (Webots model)
KNEE_LIMIT = math.radians(90.0)  # the knee cannot bend past 90 deg ([bioloid-webots, VI.A.2], Figure 27)
# ... nor stretch past straight: the report's postures hold every knee straight (513, Table 4) and its IK bends it one
# way only (eq. 3's arccos); the report's own Webots controller keeps the knee between 50 and 90 deg of bend
# (cyberbotics/webots, projects/robots/robotis/bioloid/controllers/bioloid_dog/Robot.cpp, computeWalkingPosition)
# and other public Bioloid models limit their knees to one side (dxydas/ros-bioloid bioloid.xacro: -pi..0;
# verlab/bioloid_common typea.xacro). No source gives a backward stop (docs/bioloid.md, "Why the knees stop at
# straight").
KNEE_EXTENSION = 0.0
KNEE_WEDGE = math.radians(18.0)  # the "aibo style" wedge at each knee ([bioloid-webots, IV.A], Figure 11)
LENGTH = 0.30  # m, body length at the standing posture, the head's front to the pelvis' back (measured on the model
# in tests/test_bioloid_model.py, within 1 cm); hip to hip 0.165 m
BATTERY_VOLTAGE = (
    10.0  # V: the servos' supply; AX-12 rated figures at 10 V [bioloid-webots, Table 2]; the CM-5's pack is
)
# 9.6 V [bioloid-webots, II.A]

# --- servo counts (AX-12: 0..1023 over 300 deg, 512 = 0 rad; [ax12-manual]) ---------------------------------------
COUNTS = 1024
CENTER = 512.0
RAD_PER_COUNT = math.radians(300.0) / (COUNTS - 1)


def counts(angle: float) -> float:
    return CENTER + angle / RAD_PER_COUNT


# The standing posture: legs down (servo 2 at +-90 deg, the Webots model's standing routine), neck up and head
# forward (N_1 at -90 deg), everything else at the centre; the gaits move servos 1 and 3 from here.
STAND_ANGLES = {name: 0.0 for name in SERVOS}
STAND_ANGLES.update({"F_L_2": math.pi / 2, "B_L_2": math.pi / 2, "F_R_2": -math.pi / 2, "B_R_2": -math.pi / 2})
STAND_ANGLES["N_1"] = -math.pi / 2

# Each servo's allowed range in counts: the AX-12's full 0..1023 (its angle limits' factory settings, ROBOTIS), except
# the knees: from straight (KNEE_EXTENSION) to bent 90 deg [bioloid-webots, VI.A.2]. An action of -1..1 spans this
# range.
SERVO_RANGE = {name: (0.0, float(COUNTS - 1)) for name in SERVOS}
for _leg in LEGS:
    SERVO_RANGE[KNEE[_leg]] = (counts(-KNEE_EXTENSION), counts(KNEE_LIMIT))
RANGE_LOW = np.array([SERVO_RANGE[s][0] for s in SERVOS])
RANGE_HIGH = np.array([SERVO_RANGE[s][1] for s in SERVOS])
JOINT_STOP = math.radians(150.0)  # the AX-12's 300 deg span; the knees stop at -KNEE_EXTENSION and KNEE_LIMIT

CONTROL_FREQ = 50.0  # Hz: a goal-position packet to all 16 servos every 20 ms (the Webots model's controller ran at
# 16 ms; the CM-5's bus at 1 Mbps carries a 16-servo sync write in well under 1 ms)
