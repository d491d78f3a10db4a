"""xJüs, the RHex-like hexapod with a passive spine (seed 001): robot, tasks. ``ENVS`` is what envs/__init__.py
registers; its calibration adapter (``calibrate.py --robot xjus``) is sysid/adapters/xjus.py."""

EPISODE_SECONDS = 10.0
CONTROL_FREQ = 125.0  # Hz, as envs/xjus/constants.py: the default of both action modes

ENVS = [
    {
        "id": f"skitter/Xjus{task}-v0",
        "entry_point": f"envs.xjus.{task.lower()}:Xjus{task}Env",
        "vector_entry_point": f"envs.xjus.{task.lower()}:make_batched",
        "max_episode_steps": round(EPISODE_SECONDS * CONTROL_FREQ),
    }
    for task in ("Walk", "Turn", "Rough")
]
