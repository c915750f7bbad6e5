"""Epsilon-greedy Q-learning whose epsilon decays over the episodes of a run."""

from __future__ import annotations

from typing import Any

from stable_baselines3.common.type_aliases import GymEnv, Schedule

from sb3_affect.agents.policies import TabularQPolicy
from sb3_affect.agents.qlearning import QLearning
from sb3_affect.core.setting_checks import check_decaying, episode_decay
from sb3_affect.core.settings import DecayingEpsilonGreedySettings

_S = DecayingEpsilonGreedySettings  # the defaults (one source: ``sb3_affect.core.settings``)


class DecayingEpsilonGreedy(QLearning):
    """
    Epsilon-greedy tabular Q-learning with epsilon decaying over *episodes* (one cell per decision).

    ``QLearning`` already accepts an SB3 schedule (e.g. ``LinearSchedule``) as ``exploration_rate``, but SB3 schedules
    are functions of the remaining progress ``1 - num_timesteps / total_timesteps``: when a run is stopped after N
    episodes (``StopTrainingOnMaxEpisodes``) with a generous ``total_timesteps`` the decay barely starts. This agent
    decays over the run's finished episodes instead, and its schedule is plain data (expressible in YAML).
    Epsilon is set at the start of each episode: episode ``e`` (1-based) uses the value after ``e - 1`` finished
    episodes.

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param exploration_initial_eps: epsilon of the first episode, in [0, 1]
    :param exploration_final_eps: epsilon once the decay is over, in [0, 1]
    :param exploration_decay_episodes: number of episodes the decay lasts (>= 1)
    :param decay: ``"linear"`` or ``"exponential"`` (a constant factor per episode; both epsilons must be > 0)
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

    settings_class = DecayingEpsilonGreedySettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        exploration_initial_eps: float = _S.exploration_initial_eps,
        exploration_final_eps: float = _S.exploration_final_eps,
        exploration_decay_episodes: int = _S.exploration_decay_episodes,
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
        self.exploration_initial_eps, self.exploration_final_eps, self.exploration_decay_episodes, self.decay = check_decaying(
            exploration_initial_eps, exploration_final_eps, exploration_decay_episodes, decay
        )
        super().__init__(
            policy,
            env,
            learning_rate=learning_rate,
            gamma=gamma,
            q_init=q_init,
            exploration_rate=self.exploration_initial_eps,
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

    def epsilon_at(self, finished_episodes: int) -> float:
        """Epsilon of an episode that starts after ``finished_episodes`` finished episodes of the run."""
        return episode_decay(
            self.exploration_initial_eps,
            self.exploration_final_eps,
            self.exploration_decay_episodes,
            self.decay,
            finished_episodes,
        )

    def _update_schedules(self) -> None:
        super()._update_schedules()
        self._epsilon = self.epsilon_at(len(self._episode_blocks))
