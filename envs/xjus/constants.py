"""xJüs names, source facts and controller constants.

The physical model constants (masses, geometry, stiffnesses, the motor's Table 1) live in the MJCF files under
``assets/xjus/``, each with its source. This module holds what the code needs beside them: the names it looks up, the
facts from the sources that the model is checked against, and the constants of the controller (Buehler clock and
PD), which are not part of the physical model.
"""

from __future__ import annotations

import numpy as np

import assets

SCENE_XML = assets.path("xjus", "scene.xml")

# --- names ------------------------------------------------------------------------------------------------------
SIDES = ("left", "right")
LEGS = ("FL", "ML", "BL", "FR", "MR", "BR")  # front/middle/back (rear) segment, left/right
LEFT_LEGS = ("FL", "ML", "BL")
TRIPOD_A = ("FL", "BL", "MR")  # in stance at the reset pose
TRIPOD_B = ("FR", "BR", "ML")
ROOT_BODY = "middle"

# what may touch the ground when the robot walks: its six compliant legs (RHex's legs [saranli2001])
FEET = tuple(f"{leg}_leg" for leg in LEGS)
# the middle segment's origin above level ground at the reset pose, and the lowest point of the middle segment then,
# m; from the model (assets/xjus/); tests/test_ground_rules.py recomputes them
STANDING_HEIGHT = 0.1818
BELLY_CLEARANCE = 0.1568
ROOT_JOINT = "root"
SEGMENTS = ("front", "middle", "rear")
SPINE_JOINTS = ("front_pitch", "front_roll", "rear_pitch", "rear_roll")  # joint, then axis
FLOOR_GEOM = "floor"
HIP_JOINTS = {leg: f"{leg}_hip" for leg in LEGS}
SPRING_JOINTS = {leg: f"{leg}_spring" for leg in LEGS}
SENSOR_ANGLE = {leg: f"{leg}_angle" for leg in LEGS}
SENSOR_SPEED = {leg: f"{leg}_hip_speed" for leg in LEGS}  # added by the shared motor model
SENSOR_TORQUE = {leg: f"{leg}_torque" for leg in LEGS}
SENSOR_DEFLECTION = {leg: f"{leg}_deflection" for leg in LEGS}
SENSOR_GRF = {leg: f"{leg}_grf" for leg in LEGS}
SENSOR_SPINE = {joint: f"{joint}_angle" for joint in SPINE_JOINTS}  # added when the spine is compliant
SENSOR_GYRO = "gyro"
SENSOR_ACCEL = "accel"
SENSOR_BODY_POS = "body_pos"
SENSOR_BODY_QUAT = "body_quat"
SENSOR_BODY_VEL = "body_vel"
SENSOR_SEGMENT_QUAT = {"front": "front_quat", "rear": "rear_quat"}
NUMERIC_MOTOR = (  # custom numerics of the MJCF, in MotorConstants' field order
    ("gear_ratio", "gear_ratio"),
    ("efficiency", "efficiency"),
    ("supply_voltage", "battery_voltage"),
    ("motor_resistance", "motor_resistance"),
    ("amplifier_resistance", "amplifier_resistance"),
    ("torque_constant", "torque_constant"),
    ("speed_constant", "speed_constant"),
)

# --- facts from the sources (what the model is checked against) -------------------------------------------------
MASS = 4.467  # kg, total with the battery, [xjus-report, section 3.1]
BATTERY_MASS = 0.401  # kg, [xjus-report, Table 2]
LENGTH = 0.53  # m, body length: Research RHex's [saranli2001]; the report follows its dimensions
LEG_DIAMETER = 7 * 0.0254  # m, 7 in semicircles, [xjus-report, sections 3.3 and 4]
LEG_TEST_LOAD = 29.2  # N, the FEA's dynamic load per leg, [xjus-report, section 3.3]
LEG_TEST_DEFLECTION = 0.30 * 0.0254  # m, 0.30 in under that load, [xjus-report, section 3.3]
STALL_TORQUE = 2.17  # N m at the shaft, Table 1 through the motor formula [xjus-report, Table 1]
NO_LOAD_SPEED = 29.6  # rad/s, Vs / Ks, Table 1
SPINE_DESIGN_STIFFNESS = 60 * 0.112984829 / np.radians(20.0)  # N m/rad: 60 lbf in after 20 deg, section 3.4 (19.4)
SPINE_STIFFNESS_RANGE = (0.1, 20.0)  # x the design stiffness: the range offered (docs/xjus.md)
# the most a constructor takes, x the design stiffness: stiffer spines go numerically unstable on rough ground
# (measured in docs/xjus.md, "Spine stiffness: the range offered")
SPINE_STIFFNESS_MAX_SCALE = 50.0
SPINE_STIFFNESS_MAX = SPINE_STIFFNESS_MAX_SCALE * SPINE_DESIGN_STIFFNESS  # N m/rad (971)
MOTOR_CONTINUOUS_CURRENT = 1.08  # A per motor, max continuous, [xjus-report, section 3.2]
EFFICIENCY_CAP = 0.37  # eta N Kt / Ks: the most the report's motor model can convert (envs/actuators/motor.py)
RHEX_SPEED = 0.55  # m/s, Research RHex on flat ground [saranli2001]
RHEX_MASS = 7.0  # kg, the same source

# --- controller: the report's Buehler clock and PD [xjus-report, sections 2.4 and 2.5] ---------------------------
FOURIER_TERMS = 10  # M, [xjus-report, section 2.5]
# The PD of [xjus-report, section 2.4]: desired torque J (theta_d'' + kp e + kd e'), then the motor model inverted for
# the voltage Vpd. Gains as a second-order error system, natural frequency 40 rad/s and damping ratio 0.8 (assumed,
# the report gives none): fast against a 0.5 s stride, slow enough for the 8 ms logic step (w dt = 0.32).
PD_KP = 40.0**2  # 1/s^2
PD_KD = 2 * 0.8 * 40.0  # 1/s
CONTROL_FREQ = 125.0  # Hz: the logic step, 8 ms, at least as fast as the report's 8.3 ms (section 2.2)
MIN_GAIT_CONTROL_FREQ = 120.0  # Hz: the clock and PD run at the control rate, never slower than the report's logic
PERIOD_RANGE = (0.5, 1.5)  # s, the gait action's bound on the Buehler-clock period
SWEEP_RANGE = (0.0, np.pi / 2)  # rad, ground sweep angle per side (the report: generally 45 to 90 deg)
WALK_SWEEP = np.radians(60.0)  # rad: the reference walk's ground sweep angle (within the report's 45-90 deg)
SPINE_DAMPING = 0.1  # N m s/rad per axis, as assets/xjus/xjus.xml has it (assumed there)
