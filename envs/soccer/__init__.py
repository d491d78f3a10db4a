"""Soccer: each robot's field and ball (field.py, robots.py), what a soccer task computes for its players (task.py),
the academy's single-robot tasks (academy.py) and multi-robot matches as a PettingZoo environment (match.py).

``ENVS`` holds the academy's registrations, one per robot and task, which envs/__init__.py registers as every
robot's (``ACADEMY`` is the same list).
"""

from envs.soccer import academy
from envs.soccer.robots import FIELDS, ROBOTS

TASKS = {
    "GoToBall": academy.GoToBallTask,
    "ScoreEmptyGoal": academy.ScoreEmptyGoalTask,
    "ScoreVsKeeper": academy.ScoreVsKeeperTask,
}

ACADEMY = []
for _robot, _robot_class in ROBOTS.items():
    for _task, _task_class in TASKS.items():
        _env = academy.make_academy(_robot_class, FIELDS[_robot], _task_class, _robot, f"{_robot}{_task}")
        ACADEMY.append(
            {
                "id": f"skitter/{_robot}{_task}-v{academy.version(_robot, _task_class)}",
                "entry_point": f"envs.soccer.academy:{_env.make_env_name}",
                "vector_entry_point": f"envs.soccer.academy:{_env.make_batched_name}",
                "kwargs": {"episode_seconds": academy.EPISODE_SECONDS[_robot]},
            }
        )
ENVS = ACADEMY
