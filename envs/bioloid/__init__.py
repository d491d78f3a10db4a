"""The Bioloid quadruped of seed 002 (16 AX-12 servos): robot, tasks. ``ENVS`` is what envs/__init__.py registers;
its calibration adapter (``calibrate.py --robot bioloid``) is sysid/adapters/bioloid.py."""

EPISODE_SECONDS = 10.0
CONTROL_FREQ = 50.0  # Hz, as envs/bioloid/constants.py: the goal-position packets' rate

ENVS = [
    {
        "id": f"skitter/Bioloid{task}-v1",
        "entry_point": f"envs.bioloid.{task.lower()}:Bioloid{task}Env",
        "vector_entry_point": f"envs.bioloid.{task.lower()}:make_batched",
        "max_episode_steps": round(EPISODE_SECONDS * CONTROL_FREQ),
    }
    for task in ("Walk", "Turn")
]
