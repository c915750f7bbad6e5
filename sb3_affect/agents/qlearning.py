"""QLearning: the paper's standard agent, epsilon-greedy tabular Q-learning (Eq. 1), one cell per decision."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.utils import FloatSchedule

from sb3_affect.agents.policies import TabularQPolicy, check_not_gym_tuple, greedy_action
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.episode_log import Rows
from sb3_affect.core.setting_checks import check_exploration_rate
from sb3_affect.core.settings import QLearningSettings, TabularSettings

_S = QLearningSettings  # the defaults (one source: ``sb3_affect.core.settings``)


class QLearning(TabularQAlgorithm):
    """
    Epsilon-greedy tabular Q-learning (Sutton & Barto; the paper's Eq. 1 and Sec. I).

    Each decision: with probability ``exploration_rate`` a uniformly random action, otherwise the greedy one (ties
    broken uniformly at random); one cell per decision.

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param exploration_rate: epsilon, in [0, 1]; a float or an SB3-style schedule (``progress_remaining -> epsilon``),
        evaluated at the start of each episode
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

    settings_class: ClassVar[type[TabularSettings]] = QLearningSettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        exploration_rate: float | Schedule = _S.exploration_rate,
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
        self.exploration_rate = check_exploration_rate(exploration_rate)
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
        self.exploration_schedule = FloatSchedule(self.exploration_rate)
        self._exploration_source = self.exploration_rate
        self._epsilon = float(self.exploration_schedule(1.0))

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_exploration_source"]

    def _follow_exploration_rate(self) -> None:
        """A value the user assigned to ``exploration_rate`` since the schedule was built takes effect now."""
        if self.exploration_rate is not self._exploration_source:
            check_exploration_rate(self.exploration_rate)
            self.exploration_schedule = FloatSchedule(self.exploration_rate)
            self._exploration_source = self.exploration_rate
            self._epsilon = float(self.exploration_schedule(self._current_progress_remaining))

    def _update_schedules(self) -> None:
        super()._update_schedules()
        self._follow_exploration_rate()
        self._epsilon = float(self.exploration_schedule(self._current_progress_remaining))

    def _exploration_value(self) -> float:
        return self._epsilon

    def episode_exploration(self) -> float:
        return self._epsilon

    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        rng = self._rng
        if rng.random() < self._epsilon:
            return rng.randrange(len(q[state])), 1, True
        return greedy_action(q[state], rng, self._tie_first), 1, False

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """
        The greedy action (``deterministic=True``: ties to the first maximal action) or, like SB3's DQN, an
        epsilon-greedy one at the current epsilon: with probability epsilon every action of the call is drawn from
        the action space, otherwise greedy with ties at random. Assigning ``model.exploration_rate`` (a number or a
        schedule) takes effect at once, here and in the next ``learn``, as for DQN.
        """
        check_not_gym_tuple(observation)
        self._follow_exploration_rate()
        if not deterministic and self._rng.random() < self._epsilon:
            return self.policy.random_actions(observation, lambda _: self.action_space.sample()), state
        return super().predict(observation, state, episode_start, deterministic)
