"""
Exploration controls for the deep affective agents, on the same repeat machinery (``ActionRepeat``) and with SB3's own
epsilon (``exploration_initial_eps``, ``exploration_final_eps``, ``exploration_fraction``: DQN's linear schedule, or
a constant when initial equals final):

* ``EzGreedyDQN``: ez-greedy (Dabney, Ostrovski and Barreto 2021, "Temporally-extended epsilon-greedy exploration").
  With probability epsilon a decision takes a uniformly random action and repeats it for n env steps, n drawn from a
  zeta (power-law) distribution ``P(n) ~ n**-mu`` on 1..``max_duration``; otherwise it takes the greedy action for
  one step. It repeats actions without emotions: what "emotion" adds beyond "repeating actions" shows against it.
* ``SpeedEpsilonGreedyDQN``: epsilon-greedy given the affective agent's speeds, the deep twin of the tabular
  ``SpeedEpsilonGreedy``: the direction is epsilon-greedy and every decision (random or greedy) lasts a speed drawn
  uniformly from ``speeds`` (default 1 or 2 env steps, the affective agent's "fast").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from stable_baselines3 import DQN

from sb3_affect.agents.action_repeat import ActionRepeat
from sb3_affect.core.behaviour import MAX_SPEED


def zeta_probabilities(mu: float, max_duration: int) -> np.ndarray:
    """``P(n) = n**-mu / sum_k k**-mu`` for n = 1..``max_duration``: ez-greedy's durations."""
    weights = np.arange(1, max_duration + 1, dtype=float) ** -mu
    return weights / weights.sum()


def check_mu(mu: Any) -> float:
    if isinstance(mu, bool) or not isinstance(mu, (int, float)) or not 0 < mu < math.inf:
        raise ValueError(f"mu={mu!r} must be a finite number > 0 (the power law's exponent; Dabney et al. use 2)")
    return float(mu)


def check_max_duration(max_duration: Any) -> int:
    if isinstance(max_duration, bool) or not isinstance(max_duration, int) or not 1 <= max_duration <= MAX_SPEED:
        raise ValueError(f"max_duration={max_duration!r} must be an integer in [1, {MAX_SPEED:,}] (env steps)")
    return max_duration


def check_speeds(speeds: Any) -> list[int]:
    values = tuple(speeds) if isinstance(speeds, Sequence) and not isinstance(speeds, str) else ()
    if not values or not all(isinstance(k, int) and not isinstance(k, bool) and 0 <= k <= MAX_SPEED for k in values):
        raise ValueError(f"speeds={speeds!r} must be a non-empty list of integers in [0, {MAX_SPEED:,}] (env steps)")
    return list(values)


class EzGreedyExploration(ActionRepeat):
    """
    The ez-greedy decision rule as a mixin on an ``OffPolicyAlgorithm`` with an epsilon (``exploration_rate``), e.g.
    ``class EzGreedyQRDQN(EzGreedyExploration, QRDQN)``.

    :param mu: the exponent of the durations' power law (> 1 is heavy-tailed yet mostly short; Dabney et al.: 2)
    :param max_duration: the longest repeat of a random action, in env steps
    """

    def __init__(self, *args: Any, mu: float = 2.0, max_duration: int = 10, **kwargs: Any) -> None:
        self.mu, self.max_duration = check_mu(mu), check_max_duration(max_duration)
        super().__init__(*args, **kwargs)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_durations"]

    def _setup_model(self) -> None:
        super()._setup_model()
        self.mu, self.max_duration = check_mu(self.mu), check_max_duration(self.max_duration)  # a loaded file's values
        self._durations = zeta_probabilities(self.mu, self.max_duration)

    def _decide(self, index: int) -> tuple[bool, int]:
        rng = self._decision_rng
        if rng.random() < self.exploration_rate:
            return True, 1 + int(rng.choice(self.max_duration, p=self._durations))
        return False, 1


class SpeedEpsilonGreedyExploration(ActionRepeat):
    """
    Epsilon-greedy with the affective agent's speeds, as a mixin on an ``OffPolicyAlgorithm`` with an epsilon.

    :param speeds: the env steps a decision lasts, drawn uniformly (non-empty, integers >= 0; 0 is a wait)
    """

    def __init__(self, *args: Any, speeds: Sequence[int] = (1, 2), **kwargs: Any) -> None:
        self.speeds = check_speeds(speeds)  # plain data, saved with the model
        super().__init__(*args, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        self.speeds = check_speeds(self.speeds)  # a loaded file's value

    def _decide(self, index: int) -> tuple[bool, int]:
        rng = self._decision_rng
        speeds = self.speeds
        speed = speeds[0] if len(speeds) == 1 else speeds[int(rng.integers(len(speeds)))]
        return bool(rng.random() < self.exploration_rate), speed


class EzGreedyDQN(EzGreedyExploration, DQN):
    """
    SB3's DQN exploring with ez-greedy (``sb3_affect.agents.deep_controls``): DQN's arguments (its epsilon schedule
    included) and ``mu``, ``max_duration``.
    """


class SpeedEpsilonGreedyDQN(SpeedEpsilonGreedyExploration, DQN):
    """
    SB3's DQN exploring epsilon-greedy with the affective agent's speeds (``sb3_affect.agents.deep_controls``): DQN's
    arguments (its epsilon schedule included) and ``speeds``, ``wait_action``.
    """
