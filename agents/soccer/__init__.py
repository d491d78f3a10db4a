"""Soccer's policies: self-play training (selfplay.py), matches between any two teams (play.py), the batched
matches' VecEnv (vec_env.py), and ``POLICIES``: the scripted player (envs/soccer/scripted.py) as the reference
of the soccer academy's tasks in the ``commands`` mode."""

from __future__ import annotations

import json
from typing import Any

from agents import Policy, ScriptedPolicy

ACADEMY_KWARGS = {"action_mode": "commands"}  # an academy env in the commands mode, where the scripted player plays


def academy_commands(env: Any) -> Any:
    """The ``commands`` of a soccer academy env (single or batched) made in the commands mode
    (envs/soccer/steering.py); None for any other env."""
    base = env.unwrapped
    if not hasattr(getattr(base, "task", None), "field"):
        return None
    return getattr(base, "commands", None) or getattr(getattr(base, "env", None), "commands", None)


def reference_for(env: Any) -> str | None:
    """The reference of a soccer academy env in the commands mode, the scripted player (agents.env_reference)."""
    return "scripted" if academy_commands(env) is not None else None


def _scripted(env: Any, arg: str) -> Policy:
    """The scripted field player of an academy env (single or batched) in the commands mode."""
    from envs.soccer.scripted import scripted_player

    if arg:
        raise ValueError(f"policy 'scripted:{arg}': the scripted player takes no argument")
    base = env.unwrapped
    commands = academy_commands(env)
    if commands is None and not hasattr(getattr(base, "task", None), "field"):
        spec = getattr(env, "spec", None)
        raise ValueError(f"policy 'scripted' plays the soccer academy's tasks (skitter/<Robot>GoToBall and the like), "
                         f"not {spec.id if spec else type(base).__name__}; in matches: evaluate.py --soccer ROBOT "
                         "--home scripted")  # fmt: skip
    if commands is None:
        raise ValueError(f"policy 'scripted' plays in the commands mode: make the env with action_mode='commands' "
                         f"(evaluate.py --env-kwargs '{json.dumps(ACADEMY_KWARGS)}')")  # fmt: skip
    return scripted_player(base.task.layout, commands.mode, base.robot.facts.length, base.task.field, commands)


POLICIES = {
    "scripted": ScriptedPolicy(
        ("velociroach", "xjus", "bioloid"),
        "the scripted soccer player on an academy task in the commands mode: it walks behind the ball on the line "
        "to the goal and pushes (kicks, with kick=True)",
        _scripted,
    ),
}
