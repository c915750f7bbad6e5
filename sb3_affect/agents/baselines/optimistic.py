"""Optimistic initial Q-values with a greedy policy."""

from __future__ import annotations

from typing import Any

from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_affect.agents.policies import TabularQPolicy
from sb3_affect.agents.qlearning import QLearning
from sb3_affect.core.settings import OptimisticQLearningSettings

_S = OptimisticQLearningSettings  # the defaults (one source: ``sb3_affect.core.settings``)


class OptimisticQLearning(QLearning):
    """
    Greedy tabular Q-learning (ties at random) that explores only through optimistic initial Q-values.

    This is ``QLearning`` with other defaults (``q_init=100``, the goal reward, and ``exploration_rate=0``); it exists
    so experiment files and reports can name it. Why the optimism survives the paper's ``alpha = 1, gamma = 0.8``
    even though one update overwrites an entry: with reward 0 off the goal, a tried entry becomes
    ``0.8 * max Q(s')``, at most ``0.8 * q_init``, while untried entries keep ``q_init``. So in any cell the greedy
    choice is an action not yet tried there, as long as one exists, and a tried action's value shrinks by a factor of
    0.8 per step of the path it leads along: the agent sweeps systematically through untried actions (a directed
    exploration, no randomness other than ties), and it settles on the shortest path once the true values, up to
    100 * 0.8^(d - 1) for a cell d steps from the goal, exceed what is left of the optimism elsewhere. With
    ``q_init`` at or above the goal reward (100) the optimism never falls below a true value before it is tried,
    so every state-action pair on the way is eventually tried; with a small ``q_init`` (e.g. 1) the optimism is
    overtaken by real values of about 100 * 0.8^d after the first capture and the agent turns greedy on what it knows.

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry (the optimism; > 0 to explore)
    :param exploration_rate: epsilon, in [0, 1] (0: purely greedy); a float or an SB3-style schedule
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

    settings_class = OptimisticQLearningSettings

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
