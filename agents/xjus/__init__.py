"""xJüs's scripted controller [xjus-report]: ``POLICIES`` for agents/__init__.py."""

from agents import ScriptedPolicy


def _buehler(env, arg: str):
    from agents.xjus.buehler import buehler_for

    return buehler_for(env, arg)


_DESCRIPTION = (
    "[xjus-report]'s Buehler clock, PD and motor model: walk at T = 0.5 s on walking tasks, turn by a different ground "
    "sweep per side on a turning task; buehler:stand, buehler:walk, buehler:turn, buehler:T (walk at period T s)"
)

REFERENCE = "buehler"  # the gait the shared tools and tests run on every xJüs env
POLICIES = {
    "buehler": ScriptedPolicy(("xjus",), _DESCRIPTION, _buehler),
}
