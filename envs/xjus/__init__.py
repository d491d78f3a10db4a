"""xJüs, the RHex-like hexapod with a passive spine [xjus-report]: robot, tasks. ``ENVS`` is what envs/__init__.py
registers; its calibration adapter (``calibrate.py --robot xjus``) is sysid/adapters/xjus.py."""

from envs.common.env import EPISODE_SECONDS  # the time limit, whatever the control rate

VERSIONS = {"Walk": 1, "Turn": 2, "Rough": 1}  # each id's version: raised when its dynamics or rewards change

ENVS = [
    {
        "id": f"skitter/Xjus{task}-v{version}",
        "entry_point": f"envs.xjus.{task.lower()}:make_env",
        "vector_entry_point": f"envs.xjus.{task.lower()}:make_batched",
        "kwargs": {"episode_seconds": EPISODE_SECONDS},
    }
    for task, version in VERSIONS.items()
]
