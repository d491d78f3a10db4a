"""Bench rigs: one actuator driving a load, on the robot contract (no Gymnasium env)."""
