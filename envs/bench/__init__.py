"""Bench rigs: one actuator driving a load, on the robot contract (no Gymnasium env). ``CALIBRATION`` names the
calibration adapters (``calibrate.py --robot motor|servo``)."""

CALIBRATION = {
    "motor": "envs.bench.calibration:MotorAdapter",
    "servo": "envs.bench.calibration:ServoAdapter",
}
