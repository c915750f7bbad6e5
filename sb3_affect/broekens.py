"""
A second emotion model: Broekens, Jacobs and Jonker (2015), "A reinforcement learning model of joy, distress, hope
and fear" (Connection Science 27(3)), as an SB3 callback that observes any value-based algorithm.

The model reads emotions off the learner's own signals:

* **joy / distress**: the positive / negative part of the temporal-difference error of a step,
  ``delta = r + gamma * V(s') - V(s)`` (``V(s') = 0`` when ``s'`` ends the episode at a terminal state);
* **hope / fear**: the positive / negative part of the learned value ``V(s')`` of the state the step reached (the
  anticipation of gain or loss from there; 0 at a terminal state).

``V(s)`` is the value *before* the step's learning update (recorded when ``s`` was reached), ``V(s')`` the value after
it. For tabular agents and DQN ``V(s) = max_a Q(s, a)``; for PPO and A2C the value head. These are the plain
definitions: the paper's own experiments use further scaling that is not reproduced here (see docs/hunters.md).
A *step* is what the algorithm calls its callbacks for: one env step for SB3's algorithms, one decision (of 0, 1 or
2 cells, discounted once) for the package's tabular agents.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import torch as th
from stable_baselines3.common.callbacks import BaseCallback

#: Columns of ``BroekensCallback.episode_log``.
BROEKENS_COLUMNS: tuple[str, ...] = ("episode", "steps", "reward", "joy", "distress", "hope", "fear", "goal_joy")
BROEKENS_EMOTIONS: tuple[str, ...] = ("joy", "distress", "hope", "fear")

ValueFn = Callable[[Any, Any], float]


def tabular_value(model: Any, obs: Any) -> float:
    """``max_a Q(s, a)`` of a tabular agent of this package (its live table during ``learn``)."""
    q = getattr(model, "_q", None)
    index = int(np.asarray(obs).reshape(-1)[0]) - int(model.observation_space.start)
    if q is not None:
        return float(max(q[index]))
    return float(model.q_table[index].max())


def dqn_value(model: Any, obs: Any) -> float:
    """``max_a Q(s, a)`` of SB3's DQN (its online Q-network)."""
    with th.no_grad():
        tensor, _ = model.policy.obs_to_tensor(np.asarray(obs))
        return float(model.q_net(tensor).max())


def critic_value(model: Any, obs: Any) -> float:
    """``V(s)`` from the value head of an actor-critic policy (PPO, A2C)."""
    with th.no_grad():
        tensor, _ = model.policy.obs_to_tensor(np.asarray(obs))
        return float(model.policy.predict_values(tensor).reshape(-1)[0])


def default_value_fn(model: Any) -> ValueFn:
    """The state-value function of a model, chosen by what it has: a Q-table, a Q-network or a value head."""
    from sb3_affect.tabular import TabularQAlgorithm

    if isinstance(model, TabularQAlgorithm):
        return tabular_value
    if hasattr(model, "q_net"):
        return dqn_value
    if hasattr(getattr(model, "policy", None), "predict_values"):
        return critic_value
    raise TypeError(
        f"BroekensCallback needs a value-based algorithm (a tabular agent, DQN, PPO or A2C); {type(model).__name__} has "
        "no Q-table, Q-network or value head: pass value_fn=lambda model, obs: V(obs)"
    )


class BroekensCallback(BaseCallback):
    """
    Observe joy, distress, hope and fear (Broekens, Jacobs & Jonker 2015; see the module docstring) of any
    value-based SB3 algorithm on a single env. Logs the episode means as ``<prefix>joy|distress|hope|fear`` through
    the model's logger and keeps ``episode_log`` (one row per episode, ``BROEKENS_COLUMNS``): the mean intensity of
    each emotion per step, and ``goal_joy``, the joy of the step that ended the episode at a terminal state (NaN when
    it was cut off).

    :param value_fn: ``value_fn(model, obs) -> V(obs)``; default by algorithm (``default_value_fn``)
    :param gamma: discount of the TD error; default the model's ``gamma``
    :param prefix: prefix of the logger keys
    :param verbose: verbosity level
    """

    def __init__(
        self, value_fn: ValueFn | None = None, gamma: float | None = None, prefix: str = "affect/broekens/", verbose: int = 0
    ) -> None:
        super().__init__(verbose)
        if gamma is not None and not 0.0 <= float(gamma) <= 1.0:
            raise ValueError(f"gamma={gamma!r} must be in [0, 1]")
        self.value_fn = value_fn
        self.gamma = gamma
        self.prefix = prefix
        self.rows: list[list[Any]] = []
        self._value: ValueFn = tabular_value
        self._gamma = 1.0
        self._v = 0.0
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._steps = 0
        self._reward = 0.0

    def _init_callback(self) -> None:
        self._value = self.value_fn or default_value_fn(self.model)
        self._gamma = float(self.gamma if self.gamma is not None else getattr(self.model, "gamma", 1.0))

    def _on_training_start(self) -> None:
        last_obs = getattr(self.model, "_last_obs", None)
        if last_obs is None:
            raise RuntimeError("BroekensCallback: the algorithm has no current observation at training start")
        self._v = self._value(self.model, self._one(last_obs))
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._steps = 0
        self._reward = 0.0

    @staticmethod
    def _one(obs: Any) -> Any:
        """The first env's observation as a batch of one."""
        array = np.asarray(obs)
        return array[:1] if array.ndim >= 1 else array.reshape(1)

    def _on_step(self) -> bool:
        if self.training_env is not None and self.training_env.num_envs != 1:
            raise ValueError("BroekensCallback observes a single env; this VecEnv has several")
        done = bool(np.asarray(self.locals["dones"]).reshape(-1)[0])
        info = self.locals["infos"][0]
        reward = float(np.asarray(self.locals["rewards"]).reshape(-1)[0])
        truncated = done and bool(info.get("TimeLimit.truncated", False))
        if done and not truncated:
            reached = 0.0  # a terminal state anticipates nothing
        else:
            s2 = info["terminal_observation"] if done and "terminal_observation" in info else self.locals["new_obs"]
            reached = self._value(self.model, self._one(s2))
        delta = reward + self._gamma * reached - self._v
        joy, distress = max(delta, 0.0), max(-delta, 0.0)
        hope, fear = max(reached, 0.0), max(-reached, 0.0)
        sums = self._sums
        sums[0] += joy
        sums[1] += distress
        sums[2] += hope
        sums[3] += fear
        self._steps += 1
        self._reward += reward
        if done:
            self._close_episode(joy if not truncated else math.nan)
            self._v = self._value(self.model, self._one(self.locals["new_obs"]))
        else:
            self._v = reached
        return True

    def _close_episode(self, goal_joy: float) -> None:
        steps = self._steps
        means = [value / steps for value in self._sums]
        self.rows.append([len(self.rows) + 1, steps, self._reward, *means, goal_joy])
        if self.logger.output_formats:
            for name, value in zip(BROEKENS_EMOTIONS, means):
                self.logger.record(self.prefix + name, value)
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._steps = 0
        self._reward = 0.0

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per finished episode, columns ``BROEKENS_COLUMNS``."""
        frame = pd.DataFrame(self.rows, columns=list(BROEKENS_COLUMNS))
        for name in ("episode", "steps"):
            frame[name] = frame[name].astype("int64")
        return frame
