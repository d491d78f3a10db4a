"""The optimizers, as ask-and-tell objects whose whole state pickles (a checkpoint resumes them exactly); both
maximize over the unit box [0, 1]^n (the report's mapping of parameters, VI.B.3).

**PSO** ([bioloid-webots, VI.B.2], eqs. 15-16, after Kennedy and Eberhart 1995 [16] as Bourquin [15] ran it)::

    v_id(t+1) = w(t) v_id(t) + phi1 rand() (p_id - x_id(t)) + phi2 rand() (p_gd - x_id(t))
    x_id(t+1) = x_id(t) + v_id(t+1)

- 50 particles by default (the report's swarm), initialized uniformly in the box, velocities uniformly within
  +-``v_max`` (assumed);
- inertia w decreasing linearly from 0.9 to 0.4 over the run (the report's "decreasing inertia", after Shi and
  Eberhart 1998 [17], whose values these are);
- phi1 = phi2 = 2 (Kennedy and Eberhart's; the report gives no values);
- geometric neighbourhood (the report's choice): p_g is the best previous position among the ``neighbours`` particles
  nearest to particle i in the parameter space (i included), distances recomputed at every iteration; 5 by default
  (assumed: the report says "a few particles to the entire swarm");
- velocities clipped to +-``v_max`` = 0.2 of the box (assumed, common practice); a particle leaving the box is put
  back on its face and its velocity along that axis zeroed (assumed).

No maintained library offers this variant with an ask-and-tell interface and a swarm state that checkpoints and
resumes exactly (pyswarms, the best known, was last released in 2021, runs its own loop over an objective function
and keeps its random state global), so it is written here, in numpy, on its own random generator.

**CMA-ES**: the ``cma`` package (Hansen's reference implementation), bounded to the box, initial step 0.25 of the box
(assumed), population = ``particles``. ``cma`` samples from numpy's global random state: the optimizer sets it to the
run's own state around every ask and tell and keeps it, so the checkpoint saves and restores it.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

INERTIA = (0.9, 0.4)  # Shi and Eberhart 1998 [17]
PHI1 = PHI2 = 2.0  # Kennedy and Eberhart 1995 [16]
NEIGHBOURS = 5
V_MAX = 0.2
CMA_SIGMA0 = 0.25


class PSO:
    """The report's particle swarm optimizer over [0, 1]^dimension (see the module docstring), maximizing.

    Args:
        dimension: number of parameters.
        particles: swarm size.
        iterations: the run's length (the inertia decreases over it).
        seed: the swarm's random generator's seed.
        neighbours: size of the geometric neighbourhood (nearest particles in parameter space, self included).
    """

    name = "pso"

    def __init__(self, dimension: int, particles: int, iterations: int, seed: int, neighbours: int = NEIGHBOURS):
        self.dimension, self.particles, self.iterations = dimension, particles, iterations
        self.neighbours = min(neighbours, particles)
        self.rng = np.random.default_rng(seed)
        self.x = self.rng.uniform(0.0, 1.0, (particles, dimension))
        self.v = self.rng.uniform(-V_MAX, V_MAX, (particles, dimension))
        self.best_x = self.x.copy()
        self.best_score = np.full(particles, -np.inf)
        self.iteration = 0  # iterations told

    def inertia(self) -> float:
        lo, hi = INERTIA[1], INERTIA[0]
        fraction = self.iteration / max(1, self.iterations - 1)
        return hi - (hi - lo) * min(1.0, fraction)

    def ask(self) -> np.ndarray:
        """The swarm's positions to evaluate, (particles, dimension)."""
        return self.x.copy()

    def tell(self, scores: np.ndarray) -> None:
        """Scores of the positions asked; then the swarm moves (eqs. 15-16)."""
        scores = np.asarray(scores, dtype=np.float64)
        better = scores > self.best_score
        self.best_x[better] = self.x[better]
        self.best_score[better] = scores[better]
        # geometric neighbourhood: the nearest particles now, self included
        distance = np.linalg.norm(self.x[:, None, :] - self.x[None, :, :], axis=2)
        near = np.argsort(distance, axis=1, kind="stable")[:, : self.neighbours]
        leader = near[np.arange(self.particles), np.argmax(self.best_score[near], axis=1)]
        social = self.best_x[leader]
        r1 = self.rng.uniform(0.0, 1.0, self.x.shape)
        r2 = self.rng.uniform(0.0, 1.0, self.x.shape)
        self.v = self.inertia() * self.v + PHI1 * r1 * (self.best_x - self.x) + PHI2 * r2 * (social - self.x)
        self.v = np.clip(self.v, -V_MAX, V_MAX)
        self.x = self.x + self.v
        out = (self.x < 0.0) | (self.x > 1.0)
        self.x = np.clip(self.x, 0.0, 1.0)
        self.v[out] = 0.0
        self.iteration += 1

    def state(self) -> dict[str, Any]:
        return {"x": self.x, "v": self.v, "best_x": self.best_x, "best_score": self.best_score}


class CMAES:
    """CMA-ES (the ``cma`` package) over [0, 1]^dimension, maximizing.

    Args:
        dimension, particles (the population), iterations, seed: as :class:`PSO`.
    """

    name = "cmaes"

    def __init__(self, dimension: int, particles: int, iterations: int, seed: int):
        import cma

        self.dimension, self.particles, self.iterations = dimension, particles, iterations
        self.random_state = np.random.RandomState(seed).get_state()  # cma's global generator's state
        with self._random():
            self.es = cma.CMAEvolutionStrategy(
                [0.5] * dimension,
                CMA_SIGMA0,
                {
                    "popsize": particles,
                    "bounds": [0.0, 1.0],
                    "verbose": -9,
                    "maxiter": math.inf,
                    "randn": _GlobalRandn(),
                },
            )
        self._asked: list[np.ndarray] | None = None
        self.iteration = 0

    @contextmanager
    def _random(self) -> Iterator[None]:
        """numpy's global generator (which ``cma`` samples from) set to this run's state, and restored after."""
        saved = np.random.get_state()  # noqa: NPY002
        np.random.set_state(self.random_state)  # noqa: NPY002
        try:
            yield
        finally:
            self.random_state = np.random.get_state()  # noqa: NPY002
            np.random.set_state(saved)  # noqa: NPY002

    def ask(self) -> np.ndarray:
        with self._random():
            self._asked = self.es.ask()
        return np.clip(np.array(self._asked), 0.0, 1.0)

    def tell(self, scores: np.ndarray) -> None:
        with self._random():
            self.es.tell(self._asked, (-np.asarray(scores, dtype=np.float64)).tolist())
        self._asked = None
        self.iteration += 1

    def state(self) -> dict[str, Any]:
        return {"mean": np.asarray(self.es.mean), "sigma": float(self.es.sigma)}


class _GlobalRandn:
    """numpy's global ``randn``, looked up at every call: ``cma``'s default is the bound method ``np.random.randn``,
    which a pickle (a checkpoint) turns into a private copy of the global generator, so that a resumed run would draw
    other numbers than an uninterrupted one."""

    def __call__(self, *shape: int) -> np.ndarray:
        return np.random.randn(*shape)  # noqa: NPY002


OPTIMIZERS = {"pso": PSO, "cmaes": CMAES}
