"""xJüs, the RHex-like hexapod with a passive spine (seed 001): robot, tasks. ``ENVS`` is what envs/__init__.py
registers; ``CALIBRATION`` names the calibration adapter (``calibrate.py --robot xjus``)."""

EPISODE_SECONDS = 10.0
CONTROL_FREQ = 125.0  # Hz, as envs/xjus/constants.py: the default of both action modes
CALIBRATION = {"xjus": "envs.xjus.calibration:XjusAdapter"}

ENVS = [
    {
        "id": f"skitter/Xjus{task}-v0",
        "entry_point": f"envs.xjus.{task.lower()}:Xjus{task}Env",
        "vector_entry_point": f"envs.xjus.{task.lower()}:make_batched",
        "max_episode_steps": round(EPISODE_SECONDS * CONTROL_FREQ),
    }
    for task in ("Walk", "Turn", "Rough")
]
