"""The Bioloid quadruped's scripted controllers [bioloid-webots, VI]: ``POLICIES`` and ``REFERENCE`` for
agents/__init__.py.

- ``ik-<gait>`` and ``ik-<gait>:<Hz>``: the inverse-kinematics gait library (trot, walk, gallop, canter, pace,
  bound, pronk), steering by each side's stride on a turning task (agents/bioloid/ik.py);
- ``cpg``: the coupled oscillators of eq. 14 with a coupling file's default parameters (``cpg``, the report's
  experiment 5 model at the middle of its parameter box), ``cpg:<file>``: a coupling file, or a policy file written
  by ``python -m agents.optimize`` (agents/bioloid/cpg.py).
"""

from functools import partial

from agents import ScriptedPolicy
from agents.bioloid.ik import GAITS


def _ik(gait: str, env, arg: str):
    from agents.bioloid.ik import ik_for

    return ik_for(env, gait, arg)


def _cpg(env, arg: str):
    from agents.bioloid.cpg import cpg_for

    return cpg_for(env, arg)


CONTROLLERS = {"cpg": "agents.bioloid.cpg:optimizer_controller"}  # what agents.optimize can tune
REFERENCE = "ik-trot"  # the gait the shared tools and tests run on every Bioloid env
POLICIES = {
    **{
        f"ik-{name}": ScriptedPolicy(
            ("bioloid",),
            f"[bioloid-webots]'s IK {name} (ellipse, eqs. 3-8) at 1.5 Hz; ik-{name}:<Hz> at another stride frequency",
            partial(_ik, name),
        )
        for name in GAITS
    },
    "cpg": ScriptedPolicy(
        ("bioloid",),
        "[bioloid-webots]'s coupled oscillators (eq. 14): cpg (experiment 5's coupling, mid parameters), "
        "cpg:<coupling or policy file>",
        _cpg,
    ),
}
