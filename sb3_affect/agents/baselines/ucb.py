"""UCB exploration: the greedy action on Q plus a count-based bonus (UCB1 per cell)."""

from __future__ import annotations

import math
from typing import Any

from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_affect.agents.policies import TabularQPolicy
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.episode_log import Rows
from sb3_affect.core.setting_checks import check_number
from sb3_affect.core.settings import UCBQLearningSettings

_S = UCBQLearningSettings  # the defaults (one source: ``sb3_affect.core.settings``)


class UCBQLearning(TabularQAlgorithm):
    """
    Tabular Q-learning (Eq. 1) exploring by upper confidence bounds (UCB1 applied per cell), one cell per decision.

    In cell ``s`` an action never tried there is taken first (ties at random); once every action has been tried the
    agent takes ``argmax_a Q(s, a) + c * sqrt(ln N(s) / N(s, a))`` (ties at random), where ``N(s, a)`` counts the
    decisions that took ``a`` in ``s`` and ``N(s) = sum_a N(s, a)``. The counts are knowledge like the Q-table: they
    are kept across ``learn`` calls and saved with the model. A decision counts as a random move (``random_moves``)
    when its action is not greedy on Q alone. ``c`` is in the units of Q (the paper's reward is 100).

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param exploration_coef: ``c >= 0``, the weight of the bonus (0: greedy after every action was tried once)
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

    settings_class = UCBQLearningSettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        exploration_coef: float = _S.exploration_coef,
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
        self.exploration_coef = check_number("exploration_coef", exploration_coef, 0.0, 1e300)
        self.counts: list[list[int]] | None = None
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
        n_states = int(self.observation_space.n)  # type: ignore[attr-defined]
        n_actions = int(self.action_space.n)  # type: ignore[attr-defined]
        if self.counts is None or len(self.counts) != n_states:
            self.counts = [[0] * n_actions for _ in range(n_states)]
        self._totals = [sum(row) for row in self.counts]

    @property
    def totals(self) -> list[int]:
        """The decisions taken in each state (each row of ``counts`` summed), as UCB's ``ln t`` reads them."""
        return self._totals

    @totals.setter
    def totals(self, totals: list[int]) -> None:
        self._totals = totals

    def _exploration_value(self) -> float:
        return self.exploration_coef

    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        assert self.counts is not None
        n = self.counts[state]
        row = q[state]
        rng = self._rng
        if 0 in n:
            untried = [a for a, count in enumerate(n) if count == 0]
            action = untried[0] if len(untried) == 1 else untried[rng.randrange(len(untried))]
        else:
            c = self.exploration_coef * math.sqrt(math.log(self._totals[state]))
            scores = [v + c / math.sqrt(k) for v, k in zip(row, n)]
            best = max(scores)
            ties = [a for a, v in enumerate(scores) if v == best]
            action = ties[0] if len(ties) == 1 else ties[rng.randrange(len(ties))]
        n[action] += 1
        self._totals[state] += 1
        return action, 1, row[action] != max(row)
