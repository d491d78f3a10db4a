"""VelociRoACH names, source facts and firmware constants.

The physical model constants (masses, geometry, stiffness, motor constants) live in the MJCF files under
``assets/velociroach/``, each with its source. This module holds what the code needs beside them: the names it looks
up, the facts from the sources that the model is checked against, and the constants of the robot's firmware (leg
clock and PID), which are not part of the physical model.
"""

from __future__ import annotations

import numpy as np

import assets

SCENE_XML = assets.path("velociroach", "scene.xml")

# --- names ------------------------------------------------------------------------------------------------------
SIDES = ("left", "right")
LEGS = ("FL", "ML", "BL", "FR", "MR", "BR")  # front/middle/back, left/right
TRIPOD_A = ("FL", "BL", "MR")  # down at the home pose
ROOT_BODY = "chassis"

# what may touch the ground when the robot runs: its C-legs (the chassis never does in the tripod gait)
FEET = tuple(f"{leg}_leg" for leg in LEGS)
# the chassis origin above level ground at the reset pose (tripod A down), and the chassis's lowest point then, m;
# from the model (assets/velociroach/); tests/test_ground_rules.py recomputes them
STANDING_HEIGHT = 0.0156
BELLY_CLEARANCE = 0.0144
ROOT_JOINT = "root"
CHASSIS_GEOM = "chassis"
FLOOR_GEOM = "floor"
CRANK_JOINTS = {"left": "crank_left", "right": "crank_right"}
MOTORS = {"left": "motor_left", "right": "motor_right"}
SENSOR_LEG_POS = {"left": "leg_pos_left", "right": "leg_pos_right"}
SENSOR_LEG_VEL = {"left": "leg_vel_left", "right": "leg_vel_right"}
SENSOR_MOTOR_TORQUE = {"left": "motor_torque_left", "right": "motor_torque_right"}
SENSOR_MOTOR_VEL = {"left": "motor_vel_left", "right": "motor_vel_right"}
SENSOR_GYRO = "gyro"
SENSOR_ACCEL = "accel"
SENSOR_BODY_POS = "body_pos"
SENSOR_BODY_QUAT = "body_quat"
SENSOR_BODY_VEL = "body_vel"
SENSOR_GRF = {leg: f"grf_{leg}" for leg in LEGS}
NUMERIC_BATTERY = "battery_voltage"
NUMERIC_BATTERY_RESISTANCE = "battery_resistance"
NUMERIC_SWEEP = "sweep_amplitude"
NUMERIC_LIFT = "lift_amplitude"

# --- facts from the sources (what the model is checked against) -------------------------------------------------
MASS = 0.030  # kg, [roach-sim]; ICRA 2013
LENGTH = 0.10  # m, overall, [roach-sim]; ICRA 2013
COM_HEIGHT = 0.015  # m, V-REP model, [roach-sim, Table 1]
RELATIVE_LEG_STIFFNESS = 10.3  # k L / (m g) per leg, [roach-sim] (SLIP analysis)
LEG_INERTIA = 30e-9  # kg m^2 (30 g mm^2), real robot, [roach-sim, Table 1]
GRF_PER_LEG = 0.1  # N in stance, [roach-sim, Table 1]
MAX_STRIDE_FREQUENCY = 45.0  # Hz, real robot, [roach-sim, Table 1]
TOP_SPEED = 2.7  # m/s, ICRA 2013 abstract
STRAIGHT_PHASE = np.pi  # rad: left/right offset of an alternating tripod (firmware phase 0x8000 of 65536)

# --- firmware: leg clock and per-side PID (the lab's roach firmware runs them at 1 kHz) ----------------------------
# The firmware drives each side's motor with a PWM duty, duty = ff + Kp e + Ki int(e) + Kd (v_cmd - v), in its own
# fixed-point units (envs/velociroach/firmware.py): a voltage-mode PID, no back-EMF compensation. Its gains are the
# lab's experiment script's, [roach-firmware]: Kp = 1800, Ki = 200, Kd = 100, anti-windup 0, feed-forward 0. The
# gains are a setting of the firmware, not of the robot: the real logs ran [1800, 100, 200, 0, 200],
# [1800, 100, 100, 0, 0] and [1800, 20, 100, 0, 0] (every one Kp 1800; Ki 100 or 20, Kd 200 or 100), and a regression
# of their duty on these terms gives their own headers' gains back, each within or at the edge of its 95% interval
# (docs/real-logs.md); the calibration replays each log with its own. In duty per leg radian through the firmware's
# arithmetic: Kp 1.175, Ki 0.51, Kd 0.0167, ff 0.
FIRMWARE_GAINS = (1800, 200, 100, 0, 0)  # [Kp, Ki, Kd, Kaw, ff], the firmware's units, [roach-firmware]
# duty: bound of the integral term, 0 for none: the firmware's anti-windup gain Kaw is 0 in [roach-firmware]'s
# script and in every real log's header, and the calibration's replay of the logs leaves the integrator unbounded
PID_INTEGRAL_LIMIT = 0.0
PHASE_SLEW = 2 * np.pi * 5.0  # rad/s: fastest change of the left/right phase the firmware makes
MAX_COMMAND_FREQUENCY = MAX_STRIDE_FREQUENCY  # Hz: the gait action's bound, what the real robot strides (v1; v0: 50)
