"""Bench rigs: one actuator driving a load, on the robot contract (no Gymnasium env). Their calibration adapters
(``calibrate.py --robot motor|servo``) are in sysid/adapters/bench.py."""
