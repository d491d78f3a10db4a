"""skitter environments: importing this package registers them under ``skitter/`` and does nothing else."""

from gymnasium.envs.registration import register

EPISODE_SECONDS = 10.0

for _task, _entry in (("Walk", "envs.velociroach.walk:RoachWalkEnv"), ("Turn", "envs.velociroach.turn:RoachTurnEnv")):
    register(
        id=f"skitter/Roach{_task}-v0",
        entry_point=_entry,
        max_episode_steps=int(EPISODE_SECONDS * 50),
        kwargs={"action_mode": "gait", "control_freq": 50.0},
    )
    register(
        id=f"skitter/Roach{_task}Duty-v0",
        entry_point=_entry,
        max_episode_steps=int(EPISODE_SECONDS * 1000),
        kwargs={"action_mode": "duty", "control_freq": 1000.0},
    )
