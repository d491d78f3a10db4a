"""The VelociRoACH's scripted gaits ([roach-sim] and the lab's firmware): ``POLICIES`` for agents/__init__.py."""

from agents import ScriptedPolicy


def _tripod(env, arg: str):
    from agents.velociroach.tripod import tripod_for

    return tripod_for(env, arg)


REFERENCE = "tripod"  # the gait the shared tools and tests run on every VelociRoACH env
POLICIES = {
    "tripod": ScriptedPolicy(
        ("velociroach",),
        "the alternating tripod: 45 Hz straight on a walking task, the measured turning table on a turning task; "
        "tripod:F runs straight at F Hz",
        _tripod,
    ),
}
