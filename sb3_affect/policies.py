"""The tabular policy: a Q-table held as a torch buffer, so SB3's save/load, ``predict`` and ``evaluate_policy`` work."""

from __future__ import annotations

import random
from typing import Any

import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import PyTorchObs


def greedy_action(row: list[float], rng: random.Random, first: bool = False) -> int:
    """Arg-max of one Q-table row, ties broken uniformly at random with ``rng`` (``first``: the lowest action, no draw)."""
    best = max(row)
    if first or row.count(best) == 1:
        return row.index(best)
    return rng.choice([a for a, value in enumerate(row) if value == best])


class TabularQPolicy(BasePolicy):
    """
    Greedy policy over a Q-table (one row per cell, one column per action).

    The table is a float64 buffer ``q_table`` of shape ``(n_observations, n_actions)``. Greedy ties are broken
    uniformly at random with ``self.rng``, which the algorithm replaces with its own seeded generator.

    :param observation_space: a ``Discrete`` observation space
    :param action_space: a ``Discrete`` action space
    :param lr_schedule: unused (kept for SB3's policy signature)
    :param q_init: initial value of every entry
    """

    q_table: th.Tensor

    def __init__(
        self,
        observation_space: spaces.Space,
        action_space: spaces.Space,
        lr_schedule: Any = None,
        q_init: float = 0.0,
        **kwargs: Any,
    ) -> None:
        super().__init__(observation_space, action_space, **kwargs)
        if not isinstance(observation_space, spaces.Discrete) or not isinstance(action_space, spaces.Discrete):
            raise TypeError(
                "TabularQPolicy supports Discrete observation and action spaces only, "
                f"got observation_space={observation_space}, action_space={action_space}"
            )
        self.q_init = float(q_init)
        self.n_states = int(observation_space.n)
        self.n_actions = int(action_space.n)
        self.obs_start = int(observation_space.start)
        self.action_start = int(action_space.start)
        self.register_buffer("q_table", th.full((self.n_states, self.n_actions), self.q_init, dtype=th.float64))
        self.rng = random.Random()

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(q_init=self.q_init)
        return data

    def forward(self, obs: th.Tensor, deterministic: bool = True) -> th.Tensor:
        return self._predict(obs, deterministic)

    def _predict(self, observation: PyTorchObs, deterministic: bool = True) -> th.Tensor:
        assert isinstance(observation, th.Tensor)
        states = (observation.reshape(-1).long() - self.obs_start).tolist()
        rows = self.q_table[states].tolist()
        actions = [greedy_action(row, self.rng) + self.action_start for row in rows]
        return th.tensor(actions, dtype=th.long)

    def q_values(self, state: int) -> list[float]:
        """The Q-values of one cell, as a list."""
        return self.q_table[int(state) - self.obs_start].tolist()
