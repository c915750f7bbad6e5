"""Epsilon-greedy Q-learning given the affective agent's speeds, to separate speed from emotion-driven direction."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_affect.agents.policies import TabularQPolicy, greedy_action
from sb3_affect.agents.qlearning import QLearning
from sb3_affect.core.episode_log import Rows
from sb3_affect.core.setting_checks import check_speeds
from sb3_affect.core.settings import SpeedEpsilonGreedySettings

_S = SpeedEpsilonGreedySettings  # the defaults (one source: ``sb3_affect.core.settings``)


class SpeedEpsilonGreedy(QLearning):
    """
    Epsilon-greedy tabular Q-learning whose decisions move a random number of cells, as the affective agent's do.

    The direction is epsilon-greedy exactly as in ``QLearning``; the number of cells is drawn uniformly from
    ``speeds`` (default 1 or 2, the affective agent's "fast"; ``(0, 1, 2)`` mixes in its waits). A decision that moves
    k cells makes k one-cell transitions in the same direction, each with its own Eq. 1 update, stopping early at
    the goal; 0 is a wait. Compared with AffectQ it has the speeds without the emotions.

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param exploration_rate: epsilon, in [0, 1]; a float or an SB3-style schedule, evaluated at each episode start
    :param speeds: cells a decision moves, drawn uniformly (non-empty, integers >= 0)
    :param max_episode_decisions: safety cap: an episode that reaches this many decisions is truncated (and counted)
    :param stats_window_size: window of the rollout/ep_*_mean logger keys (episodes)
    :param tensorboard_log: folder for TensorBoard logs (None: none)
    :param policy_kwargs: extra arguments for the policy
    :param verbose: 0 silent, 1 training logs on stdout
    :param seed: seed of every random choice
    :param device: torch device of the Q-table
    :param engine: ``"auto"``, ``"python"`` or ``"compiled"``: which engine runs ``learn`` (see ``TabularQAlgorithm``)
    :param tie_break: greedy ties while learning: ``"random"`` (default) or ``"first"`` (the lowest action)
    :param multi_cell: a decision of k cells: ``"steps"`` (k one-cell transitions, one Eq. 1 update each) or
        ``"jump"`` (k cells moved, one Eq. 1 update from the start cell to the end cell with the summed reward)
    :param _init_setup_model: build the policy now (SB3 convention)
    """

    settings_class = SpeedEpsilonGreedySettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        exploration_rate: float | Schedule = _S.exploration_rate,
        speeds: Sequence[int] = _S.speeds,
        max_episode_decisions: int = _S.max_episode_decisions,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: Any = "cpu",
        engine: str = _S.engine,
        tie_break: str = _S.tie_break,
        multi_cell: str = _S.multi_cell,
        _init_setup_model: bool = True,
    ) -> None:
        self.multi_cell, self.speeds = check_speeds(multi_cell, speeds)
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            gamma=gamma,
            q_init=q_init,
            exploration_rate=exploration_rate,
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

    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        rng = self._rng
        speeds = self.speeds
        cells = speeds[0] if len(speeds) == 1 else speeds[rng.randrange(len(speeds))]
        if rng.random() < self._epsilon:
            return rng.randrange(len(q[state])), cells, True
        return greedy_action(q[state], rng, self._tie_first), cells, False
