"""The tabular policy: a Q-table held as a torch buffer, so SB3's save/load, ``predict`` and ``evaluate_policy`` work."""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import PyTorchObs

from sb3_affect.agents.agent_checks import check_observation, check_table_size

_GYM_TUPLE_ERROR = (
    "You have passed a tuple to the predict() function instead of a Numpy array or a Dict. "
    "You are probably mixing Gym API with SB3 VecEnv API: `obs, info = env.reset()` (Gym) "
    "vs `obs = vec_env.reset()` (SB3 VecEnv). "
    "See related issue https://github.com/DLR-RM/stable-baselines3/issues/1694 "
    "and documentation for more information: "
    "https://stable-baselines3.readthedocs.io/en/master/guide/vec_envs.html#vecenv-api-vs-gym-api"
)


def check_not_gym_tuple(observation: Any) -> None:
    """Raise SB3's error for ``predict((obs, info))``, the Gym ``reset`` tuple passed as an observation."""
    if isinstance(observation, tuple) and len(observation) == 2 and isinstance(observation[1], dict):
        raise ValueError(_GYM_TUPLE_ERROR)


def greedy_action(row: list[float], rng: random.Random, first: bool = False) -> int:
    """Arg-max of one Q-table row, ties broken uniformly at random with ``rng`` (``first``: the lowest action, no draw)."""
    best = max(row)
    if first or row.count(best) == 1:
        return row.index(best)
    return rng.choice([a for a, value in enumerate(row) if value == best])


class TabularQPolicy(BasePolicy):
    """
    Greedy policy over a Q-table (one row per cell, one column per action).

    The table is a float64 buffer ``q_table`` of shape ``(n_observations, n_actions)``. ``predict(deterministic=True)``
    is deterministic: among tied maximal actions it takes the first (lowest index), on every call. With
    ``deterministic=False`` ties are broken uniformly at random with ``self.rng``, which the algorithm replaces with
    its own seeded generator (learning breaks ties at random too, with that generator).

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
        check_table_size(observation_space.n, action_space.n)
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

    def check_observation(self, observation: Any) -> None:
        """Refuse an observation that is not a state of the observation space (``agent_checks.check_observation``)."""
        check_not_gym_tuple(observation)
        if not isinstance(observation, dict):
            check_observation(observation, self.n_states, self.obs_start)

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``predict``, once the observation is checked to be states of the observation space."""
        self.check_observation(observation)
        return super().predict(observation, state, episode_start, deterministic)

    def forward(self, obs: th.Tensor, deterministic: bool = True) -> th.Tensor:
        return self._predict(obs, deterministic)

    def _predict(self, observation: PyTorchObs, deterministic: bool = True) -> th.Tensor:
        assert isinstance(observation, th.Tensor)
        states = (observation.reshape(-1).long() - self.obs_start).tolist()
        rows = self.q_table[states].tolist()
        if deterministic:
            actions = [row.index(max(row)) + self.action_start for row in rows]
        else:
            actions = [greedy_action(row, self.rng) + self.action_start for row in rows]
        return th.tensor(actions, dtype=th.long)

    @property
    def device(self) -> th.device:
        """The Q-table's device (the policy has a buffer and no parameter, which SB3's ``device`` looks for)."""
        return self.q_table.device

    def random_actions(self, observation: Any, pick: Callable[[int], int]) -> np.ndarray:
        """
        One ``pick(state)`` per observation, shaped as ``predict`` returns actions: shape ``()`` for a single
        observation, ``(n,)`` for a batch (SB3's DQN does the same in its exploration branch).
        """
        self.check_observation(observation)
        obs = np.asarray(observation)
        states = [int(s) for s in obs.reshape(-1)]
        if self.is_vectorized_observation(obs):
            return np.array([pick(s) for s in states])
        return np.array(pick(states[0]))

    def q_values(self, state: int) -> list[float]:
        """The Q-values of one cell, as a list."""
        return self.q_table[int(state) - self.obs_start].tolist()
