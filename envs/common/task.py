"""The task contract: observations, command, reward terms, termination and episode metrics over a robot's readings.

A task takes a robot (see envs/common/robot.py) and works on its readings, arrays with a leading simulation axis, so
that one implementation serves one simulation (the Gymnasium env, a batch of one) and a batch of many. It publishes
its observation layout by name (:attr:`Task.observation_structure`, like Gymnasium's ``observation_structure``);
scripted policies read that layout instead of indices.

Episode metrics come from running sums the task keeps per simulation and reports in every step's ``info``, so that
whoever sees an episode's last ``info`` (evaluate.py, the training callback after an auto-reset) can compute them.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from envs.common.robot import Robot


@dataclass(frozen=True)
class ObservationLayout:
    """Where each named part of an observation lies: name -> slice, in order."""

    slices: dict[str, slice]

    @classmethod
    def from_structure(cls, structure: Mapping[str, int]) -> ObservationLayout:
        slices, start = {}, 0
        for name, size in structure.items():
            slices[name] = slice(start, start + size)
            start += size
        return cls(slices)

    @property
    def size(self) -> int:
        return max((s.stop for s in self.slices.values()), default=0)

    def __contains__(self, name: str) -> bool:
        return name in self.slices

    def __getitem__(self, name: str) -> slice:
        if name not in self.slices:
            raise KeyError(f"the observation has no {name!r} (it has {', '.join(self.slices)})")
        return self.slices[name]

    def get(self, obs: np.ndarray, name: str) -> np.ndarray:
        """The named part of one observation (size,) or of a batch (n, size)."""
        return np.asarray(obs)[..., self[name]]


class Task(ABC):
    """Base of every task. Subclasses fill in the abstract methods; see :class:`envs.common.locomotion.WalkTask`.

    Attributes:
        metrics: name -> description of the task's own episode metrics (beside the generic ones in
            agents/evaluation.py).
        binary_metrics: those of them that are 1 or 0 an episode (a success): their intervals are a proportion's
            (agents/evaluation.py), not a bootstrap's, which collapses to a point when every episode agrees.
    """

    name: ClassVar[str]
    metrics: ClassVar[dict[str, str]] = {}
    binary_metrics: ClassVar[tuple[str, ...]] = ()

    def __init__(self, robot: Robot):
        self.robot = robot
        self.layout = ObservationLayout.from_structure(self.observation_structure)

    @property
    @abstractmethod
    def observation_structure(self) -> dict[str, int]:
        """name -> size of every part of the observation, in order (the robot's senses first)."""

    def prepare_reset(  # noqa: B027 (an optional hook)
        self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None
    ) -> None:
        """Before the robot resets in simulations ``ids``: draw what its reset depends on (where a soccer task puts
        the robot and the ball). Nothing by default."""

    @abstractmethod
    def reset(self, ids: np.ndarray, rngs: Sequence[np.random.Generator], options: Mapping | None, readings) -> None:
        """Start episodes in simulations ``ids``: draw their commands, zero their running sums."""

    @abstractmethod
    def update(self, readings: dict[str, np.ndarray], stepped: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """After a control step: the step's quantities (velocities, power, ...) per simulation, advancing the task's
        running sums. Called once per step, before the methods below. ``stepped`` (n,) bool, where some simulations
        were reset in this step instead of stepped (a batched env's auto-reset): their sums must not advance."""

    @abstractmethod
    def observe(self, readings: dict[str, np.ndarray]) -> np.ndarray:
        """Observations (n, size)."""

    @abstractmethod
    def reward_terms(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Weighted reward terms (n,) each; the reward is their sum."""

    @abstractmethod
    def terminated(self, state: dict[str, np.ndarray]) -> np.ndarray:
        """(n,) bool: the episode ends (the robot fell, or the task ended it)."""

    def fell(self, state: dict[str, np.ndarray], terminated: np.ndarray) -> np.ndarray:
        """(n,) bool: which of the ``terminated`` episodes ended in a fall (``info["fallen"]``): all of them, unless
        the task also ends episodes on success."""
        return terminated

    def info(self, readings: dict[str, np.ndarray], state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Per-simulation values for ``info`` (beside the reward terms)."""
        return dict(state)

    def episode_metrics(self, info: Mapping[str, Any]) -> dict[str, float]:
        """The task's own metrics of an episode, from its last step's ``info``."""
        return {}
