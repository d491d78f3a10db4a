"""Soccer: each robot's field and ball (field.py) and its academy tasks (academy.py).

``ACADEMY`` holds the academy's registrations, one per robot and task, made with ``gymnasium.register(**entry)``.
They join ``ENVS`` (what envs/__init__.py registers) once the shared tools (hyperparameters, the ground-rules
benchmark, the reference gaits' steering) take them; until then build them with ``gymnasium.register`` or from
their classes in academy.py.
"""

from envs.bioloid import constants as bioloid
from envs.bioloid.robot import Bioloid
from envs.soccer import academy
from envs.soccer.field import FOUR_LEGGED, SPL_BALL, TABLE_TENNIS_BALL, field_for
from envs.velociroach import constants as roach
from envs.velociroach.robot import VelociRoach
from envs.xjus import constants as xjus
from envs.xjus.robot import Xjus

FIELDS = {
    "Bioloid": FOUR_LEGGED,
    "Xjus": field_for(xjus.LENGTH, SPL_BALL, "Four-Legged League field x 1.77 (xJüs)"),
    "Roach": field_for(roach.LENGTH, TABLE_TENNIS_BALL, "Four-Legged League field x 0.33 (VelociRoACH)"),
}
ROBOTS = {"Bioloid": Bioloid, "Xjus": Xjus, "Roach": VelociRoach}
TASKS = {"GoToBall": academy.GoToBallTask, "ScoreEmptyGoal": academy.ScoreEmptyGoalTask}
assert abs(bioloid.LENGTH - 0.30) < 1e-9  # the Four-Legged field's scale is the Bioloid's length

ACADEMY = []
for _robot, _robot_class in ROBOTS.items():
    for _task, _task_class in TASKS.items():
        _env = academy.make_academy(_robot_class, FIELDS[_robot], _task_class, f"{_robot}{_task}")
        ACADEMY.append(
            {
                "id": f"skitter/{_robot}{_task}-v1",
                "entry_point": f"envs.soccer.academy:{_env.make_env_name}",
                "vector_entry_point": f"envs.soccer.academy:{_env.make_batched_name}",
                "kwargs": {"episode_seconds": academy.EPISODE_SECONDS},
            }
        )
