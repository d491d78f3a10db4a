"""The VelociRoACH [roach-sim]: robot, tasks, real-telemetry format. ``ENVS`` is what envs/__init__.py registers; its
calibration adapter and the reader of its text telemetry for calibration are in sysid/adapters."""

from envs.common.env import EPISODE_SECONDS  # the time limit, whatever the control rate

_MODES = {"": ("gait", 50.0), "Duty": ("duty", 1000.0)}
# each task's version in each mode (gait "", duty "Duty"): raised when its dynamics or rewards change
VERSIONS = {("Walk", ""): 4, ("Walk", "Duty"): 3, ("Turn", ""): 5, ("Turn", "Duty"): 4}

ENVS = [
    {
        "id": f"skitter/Roach{task}{suffix}-v{VERSIONS[task, suffix]}",
        "entry_point": f"envs.velociroach.{task.lower()}:make_env",
        "vector_entry_point": f"envs.velociroach.{task.lower()}:make_batched",
        "kwargs": {"action_mode": mode, "control_freq": freq, "episode_seconds": EPISODE_SECONDS},
    }
    for task in ("Walk", "Turn")
    for suffix, (mode, freq) in _MODES.items()
]
