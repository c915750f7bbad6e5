"""
``BroekensCallback`` on a small Discrete space (its table of values) queues an off-policy algorithm's steps and settles
them before the algorithm next learns, or at an episode's end, valuing their states in one burst: what it logs equals
what settling each step at its own step gave, to the last bit (real DQN, real envs, several hundred steps).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch as th
from stable_baselines3 import DQN
from stable_baselines3.common.env_util import make_vec_env

from sb3_affect.agents.broekens import BroekensCallback


class EveryStep(BroekensCallback):
    """The reference: each step settled at its own step, as the callback did before it queued them."""

    def _on_step(self) -> bool:
        result = super()._on_step()
        self._settle_queue()
        return result


class Queued(BroekensCallback):
    """The callback as it is, noting the longest queue it held (so the test is not vacuous)."""

    longest = 0

    def _on_step(self) -> bool:
        result = super()._on_step()
        self.longest = max(self.longest, len(self._queue))
        return result


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


@pytest.mark.parametrize(("env_id", "n_envs", "env_kwargs"), [
    ("FrozenLake-v1", 1, {"max_episode_steps": 12}),  # truncations: the last observation valued at its step
    ("FrozenLake-v1", 2, {}),
    ("sb3_affect/GridPursuit-v0", 1, {"size": 3, "goal": (1, 1)}),
])
def test_queued_steps_settle_as_each_step_settled_at_once(env_id: str, n_envs: int, env_kwargs: dict) -> None:
    th.set_num_threads(1)
    env = make_vec_env(env_id, n_envs=n_envs, seed=0, env_kwargs=env_kwargs)
    model = DQN("MlpPolicy", env, learning_starts=50, train_freq=4, batch_size=16, seed=0,
                policy_kwargs={"net_arch": [32, 32]})
    queued, reference = Queued(position="discrete"), EveryStep(position="discrete")
    model.learn(600, callback=[queued, reference])
    assert queued._table_states and queued.longest > 1 and model._n_updates > 50
    assert len(queued.rows) == len(reference.rows) >= 5
    for mine, theirs in zip(queued.rows, reference.rows):
        assert all(same(a, b) for a, b in zip(mine, theirs)), (mine, theirs)
    assert queued.cell_log.equals(reference.cell_log)
    assert all(same(a, b) for a, b in zip(queued._window.means(), reference._window.means()))
    if env_kwargs.get("max_episode_steps"):  # some episodes were cut off: their last observation valued at its step
        assert np.isnan(queued.episode_log.goal_joy).any()
