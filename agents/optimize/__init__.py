"""Tuning controllers by particle swarm (the report's PSO) or CMA-ES, over any robot's optimizable controllers.

- ``problem``: the run configuration and the :class:`~agents.optimize.problem.Evaluator` that scores a batch of
  parameter vectors as one ``mujoco.batch`` of rollouts (the report's eq. 17, +x progress, falls);
- ``optimizers``: PSO ([bioloid-webots, eqs. 15-16]: decreasing inertia, geometric neighbourhood) and CMA-ES (``cma``),
  as ask-and-tell objects whose state checkpoints;
- ``run``: the loop, its checkpoint, the best parameters as a policy file, the local and Ray backends;
- ``__main__``: the command line, ``python -m agents.optimize``.

A robot folder offers controllers to tune in ``CONTROLLERS`` (name -> ``"module:builder"``), as it offers gaits in
``POLICIES``; adding one edits nothing here.
"""
