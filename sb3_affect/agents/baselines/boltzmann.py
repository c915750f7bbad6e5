"""Boltzmann (softmax) exploration: actions drawn with probability proportional to exp(Q / temperature)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.utils import FloatSchedule

from sb3_affect.agents.policies import TabularQPolicy, check_not_gym_tuple
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.episode_log import Rows
from sb3_affect.core.setting_checks import check_boltzmann, temperature_at
from sb3_affect.core.settings import BoltzmannSettings

_S = BoltzmannSettings  # the defaults (one source: ``sb3_affect.core.settings``)


def softmax_action(row: list[float], inv_temperature: float, u: float) -> int:
    """
    Draw an action with probability ``exp((Q - max Q) / T)`` normalised, using the uniform number ``u`` in [0, 1).

    Plain Python (it runs once per decision). At very low temperature every non-maximal weight underflows to 0 and
    the draw is a uniform choice among the maximal actions, i.e. greedy with random ties.
    """
    best = max(row)
    exp = math.exp
    weights = [exp((v - best) * inv_temperature) for v in row]
    x = u * sum(weights)
    last = 0
    for a, w in enumerate(weights):
        if w > 0.0:
            last = a
            x -= w
            if x < 0.0:
                return a
    return last  # rounding: u * total landed on the total


class Boltzmann(TabularQAlgorithm):
    """
    Tabular Q-learning (Eq. 1) with Boltzmann (softmax) exploration, one cell per decision.

    Each decision draws action ``a`` with probability ``exp(Q(s, a) / T) / sum_b exp(Q(s, b) / T)``. ``T -> 0`` is
    greedy (ties at random), ``T -> inf`` uniform. The temperature is in the units of Q: with the paper's reward of 100
    and gamma 0.8, Q-values near the start are a few units apart, so T around 1 is already nearly greedy there.
    A decision counts as a random move (``random_moves`` in the episode log) when the drawn action is not greedy.

    The temperature is fixed (``temperature``), an SB3 schedule of the remaining progress, or decays over the run's
    episodes from ``temperature`` to ``temperature_final`` (plain data, expressible in YAML).

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param temperature: T > 0 (first-episode value when ``temperature_final`` is given); a float or an SB3-style
        schedule (``progress_remaining -> T``) evaluated at the start of each episode
    :param temperature_final: None (no episode decay) or the temperature once the decay is over (> 0)
    :param temperature_decay_episodes: episodes the decay lasts (>= 1)
    :param decay: ``"exponential"`` (a constant factor per episode) or ``"linear"``
    :param max_episode_decisions: safety cap: an episode that reaches this many decisions is truncated (and counted)
    :param stats_window_size: window of the rollout/ep_*_mean logger keys (episodes)
    :param tensorboard_log: folder for TensorBoard logs (None: none)
    :param policy_kwargs: extra arguments for the policy
    :param verbose: 0 silent, 1 training logs on stdout
    :param seed: seed of every random choice
    :param device: torch device of the Q-table
    :param engine: ``"auto"``, ``"python"`` or ``"compiled"``: which engine runs ``learn`` (see ``TabularQAlgorithm``)
    :param tie_break: greedy ties while learning: ``"random"`` (default) or ``"first"`` (the lowest action)
    :param _init_setup_model: build the policy now (SB3 convention)
    """

    settings_class = BoltzmannSettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        temperature: float | Schedule = _S.temperature,
        temperature_final: float | None = _S.temperature_final,
        temperature_decay_episodes: int = _S.temperature_decay_episodes,
        decay: str = _S.decay,
        max_episode_decisions: int = _S.max_episode_decisions,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: Any = "cpu",
        engine: str = _S.engine,
        tie_break: str = _S.tie_break,
        _init_setup_model: bool = True,
    ) -> None:
        self.temperature, self.temperature_final, self.temperature_decay_episodes, self.decay = check_boltzmann(
            temperature, temperature_final, temperature_decay_episodes, decay
        )
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            gamma=gamma,
            q_init=q_init,
            max_episode_decisions=max_episode_decisions,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            policy_kwargs=policy_kwargs,
            verbose=verbose,
            seed=seed,
            device=device,
            engine=engine,
            tie_break=tie_break,
            _init_setup_model=_init_setup_model,
        )

    def _setup_model(self) -> None:
        super()._setup_model()
        self.temperature_schedule = FloatSchedule(self.temperature)
        self._set_temperature(float(self.temperature_schedule(1.0)))

    def _set_temperature(self, value: float) -> None:
        self._temperature = value
        self._inv_temperature = 1.0 / value

    def temperature_at(self, finished_episodes: int, progress_remaining: float = 1.0) -> float:
        """The temperature of an episode that starts after ``finished_episodes`` episodes at this progress."""
        return temperature_at(
            self.temperature,
            self.temperature_final,
            self.temperature_decay_episodes,
            self.decay,
            finished_episodes,
            progress_remaining,
        )

    def _update_schedules(self) -> None:
        super()._update_schedules()
        self._set_temperature(self.temperature_at(len(self._episode_blocks), self._current_progress_remaining))

    def _exploration_value(self) -> float:
        return self._temperature

    def episode_exploration(self) -> float:
        return self._inv_temperature

    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        row = q[state]
        action = softmax_action(row, self._inv_temperature, self._rng.random())
        return action, 1, row[action] != max(row)

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """The greedy action (``deterministic=True``: ties to the first maximal action) or a softmax draw at the
        current temperature, one per observation, shaped as SB3's ``predict`` returns actions."""
        if deterministic:
            return super().predict(observation, state, episode_start, deterministic)
        check_not_gym_tuple(observation)
        self._sync_policy()
        start = int(self.action_space.start)  # type: ignore[attr-defined]
        policy = self.policy

        def draw(s: int) -> int:
            return softmax_action(policy.q_values(s), self._inv_temperature, self._rng.random()) + start

        return policy.random_actions(observation, draw), state


__all__ = ["Boltzmann", "softmax_action"]
