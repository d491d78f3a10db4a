"""The VelociRoACH (seed 000): robot, tasks, real-telemetry format. ``ENVS`` is what envs/__init__.py registers;
``CALIBRATION`` names the calibration adapter (``calibrate.py --robot roach``), ``LOG_READERS`` the reader of its text
telemetry for calibration."""

EPISODE_SECONDS = 10.0  # the time limit, whatever the control rate (envs/common/env.py)
CALIBRATION = {"roach": "envs.velociroach.calibration:RoachAdapter"}
LOG_READERS = ["envs.velociroach.logs:READER"]
_MODES = {"": ("gait", 50.0), "Duty": ("duty", 1000.0)}

ENVS = [
    {
        "id": f"skitter/Roach{task}{suffix}-v1",
        "entry_point": f"envs.velociroach.{task.lower()}:make_env",
        "vector_entry_point": f"envs.velociroach.{task.lower()}:make_batched",
        "kwargs": {"action_mode": mode, "control_freq": freq, "episode_seconds": EPISODE_SECONDS},
    }
    for task in ("Walk", "Turn")
    for suffix, (mode, freq) in _MODES.items()
]
