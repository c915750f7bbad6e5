"""
``ReplayedEpsilonDQN``: SB3's DQN whose epsilon follows a given list of values instead of the linear schedule, one
value per equal part of training. Given another agent's logged share of random decisions (``AffectDQN``'s
``affect/random_share``, part by part), it takes random actions as often as that agent did, at the same points of
training, but uniformly in time: a control that has the emotions' amount of randomness without their timing.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3 import DQN


class ReplayedEpsilonDQN(DQN):
    """
    SB3's DQN with ``epsilons[k]`` as its epsilon during the k-th of ``len(epsilons)`` equal parts of training (by
    SB3's progress, ``num_timesteps / total_timesteps``). Everything else is DQN's; ``learning_starts`` still warms up
    with uniformly random actions.

    :param epsilons: epsilon of each part of training, each in [0, 1]
    """

    def __init__(self, *args: Any, epsilons: Sequence[float], **kwargs: Any) -> None:
        values = np.asarray(epsilons, dtype=float).reshape(-1)
        if not len(values) or not np.all((values >= 0) & (values <= 1)):
            raise ValueError(f"epsilons={list(epsilons)!r} must be a non-empty list of values in [0, 1]")
        given = [key for key in ("exploration_initial_eps", "exploration_final_eps", "exploration_fraction") if key in kwargs]
        if given:
            raise TypeError(f"ReplayedEpsilonDQN takes its epsilon from epsilons, not {given[0]}={kwargs[given[0]]!r}")
        self.epsilons = [float(value) for value in values]  # plain data, saved with the model
        super().__init__(*args, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        self.exploration_schedule = self._replayed

    def _replayed(self, progress_remaining: float) -> float:
        """The epsilon of the part of training ``1 - progress_remaining`` falls in."""
        parts = len(self.epsilons)
        return self.epsilons[min(int((1.0 - progress_remaining) * parts), parts - 1)]
