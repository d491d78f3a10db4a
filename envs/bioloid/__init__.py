"""The Bioloid quadruped of [bioloid-webots] (16 AX-12 servos): robot, tasks. ``ENVS`` is what envs/__init__.py
registers; its calibration adapter (``calibrate.py --robot bioloid``) is sysid/adapters/bioloid.py."""

from envs.common.env import EPISODE_SECONDS  # the time limit, whatever the control rate

VERSIONS = {"Walk": 2, "Turn": 5}  # bumped when a task's rewards, observations, actions or model change

ENVS = [
    {
        "id": f"skitter/Bioloid{task}-v{version}",
        "entry_point": f"envs.bioloid.{task.lower()}:make_env",
        "vector_entry_point": f"envs.bioloid.{task.lower()}:make_batched",
        "kwargs": {"episode_seconds": EPISODE_SECONDS},
    }
    for task, version in VERSIONS.items()
]
