"""AffectQ: the paper's affective agent. No epsilon: each decision's emotion sets its direction and speed."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.agents.policies import TabularQPolicy, greedy_action
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.appraisal import Appraiser
from sb3_affect.core.behaviour import Behaviour, behaviour_by_emotion
from sb3_affect.core.emotions import Emotion
from sb3_affect.core.episode_log import COLUMN, Rows
from sb3_affect.core.goals import GoalTest
from sb3_affect.core.personalities import PersonalityAppraiser
from sb3_affect.core.setting_checks import check_affect
from sb3_affect.core.settings import AffectQSettings, TabularSettings

_S = AffectQSettings  # the defaults (one source: ``sb3_affect.core.settings``)

SelfAffectQ = TypeVar("SelfAffectQ", bound="AffectQ")


class AffectQ(TabularQAlgorithm):
    """
    Q-learning with basic emotions (Badoy & Teknomo 2014).

    Before each decision the agent appraises its progress (``norm``, ``exp1``, ``act``), feels one emotion by
    Table II, and the emotion's behaviour (Table III) sets the direction (random for joy, greedy otherwise) and the
    cells moved (joy and anger 1 or 2, sadness and fear 0 or 1). The appraisal and the emotion come from an
    ``EmotionCallback`` that AffectQ drives through its affect hook (see ``sb3_affect.agents.callbacks``); the first
    episode, with nothing to appraise, is all joy. Which terminations reach the goal (what the known map learns) is
    the callback's goal test: on envs other than the package's, see ``sb3_affect.core.goals`` (e.g. FrozenLake's holes
    are not goals; CliffWalking needs ``EmotionCallback(goal=every_termination)``).

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param comparison: Table II reading: ``"literal"`` (compare step counts) or ``"valence"`` (compare their negations)
    :param act: ``"episode"`` (act = elapsed + known remaining) or ``"remaining"`` (known remaining only)
    :param units: ``"cells"`` or ``"decisions"``: what norm, exp1 and act count
    :param behaviour_table: emotion -> ``Behaviour(random_direction, speeds)`` (keys ``Emotion`` or their names,
        ``"joy"``, as a sweep file writes ``{joy: [true, [1, 2]], ...}``), or a table's name (``"table-iii"``,
        ``"table-iii-reversed"``: ``sb3_affect.core.behaviour.BEHAVIOUR_TABLES``); default Table III
    :param emotion_callback: an ``EmotionCallback`` (or subclass) to drive instead of one built from the options above
    :param max_episode_decisions: safety cap: an episode that reaches this many decisions is truncated (and counted)
    :param stats_window_size: window of the rollout/ep_*_mean logger keys (episodes)
    :param tensorboard_log: folder for TensorBoard logs (None: none)
    :param policy_kwargs: extra arguments for the policy
    :param verbose: 0 silent, 1 training logs on stdout
    :param seed: seed of every random choice
    :param device: torch device of the Q-table
    :param personality: ``"neutral"`` (the paper), ``"optimistic"`` or ``"pessimistic"``: a bias on the appraisal's
        norm (``sb3_affect.core.personalities``); not combinable with ``emotion_callback``
    :param engine: ``"auto"``, ``"python"`` or ``"compiled"``: which engine runs ``learn`` (see ``TabularQAlgorithm``)
    :param tie_break: greedy ties while learning: ``"random"`` (default) or ``"first"`` (the lowest action)
    :param multi_cell: a decision of k cells: ``"steps"`` (k one-cell transitions, one Eq. 1 update each) or
        ``"jump"`` (k cells moved, one Eq. 1 update from the start cell to the end cell with the summed reward)
    :param _init_setup_model: build the policy now (SB3 convention)
    """

    settings_class = AffectQSettings

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        comparison: str = _S.comparison,
        act: str = _S.act,
        units: str = _S.units,
        behaviour_table: Mapping[Emotion, Behaviour] | str | None = _S.behaviour_table,
        emotion_callback: EmotionCallback | None = None,
        max_episode_decisions: int = _S.max_episode_decisions,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: Any = "cpu",
        personality: str = _S.personality,
        engine: str = _S.engine,
        tie_break: str = _S.tie_break,
        multi_cell: str = _S.multi_cell,
        _init_setup_model: bool = True,
    ) -> None:
        self.behaviour_table: dict[str, list[Any]]
        self.multi_cell, self.personality, self.comparison, self.act, self.units, self.behaviour_table = check_affect(
            multi_cell, personality, comparison, act, units, behaviour_table, emotion_callback
        )
        if emotion_callback is not None and not isinstance(emotion_callback, EmotionCallback):
            raise TypeError(f"emotion_callback must be an EmotionCallback, got {type(emotion_callback).__name__}")
        self.emotion_callback = emotion_callback
        self._affect_state: dict[str, Any] | None = None
        self._emotion_counts: list[int] | None = None
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
        if self.emotion_callback is None:
            if self.personality == "neutral":
                self.emotion_callback = EmotionCallback(comparison=self.comparison, act=self.act, units=self.units)
            else:
                appraiser = PersonalityAppraiser.preset(
                    self.personality,
                    int(self.observation_space.n),  # type: ignore[attr-defined]
                    act=self.act,
                    units=self.units,
                )
                self.emotion_callback = EmotionCallback(comparison=self.comparison, appraiser=appraiser)
        self.emotion_callback.bind(int(self.observation_space.n))  # type: ignore[attr-defined]
        if self._affect_state is not None:
            assert self.emotion_callback.appraiser is not None
            self.emotion_callback.appraiser.set_state(self._affect_state)
        if self._emotion_counts is not None:  # the episode in progress when the model was saved
            self.emotion_callback.counts = [int(c) for c in self._emotion_counts]
        # the behaviour table as a list indexed by emotion, for the hot loop
        self._behaviour = behaviour_by_emotion(self.behaviour_table)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "emotion_callback", "_behaviour"]

    def save(self, path: Any, exclude: Any = None, include: Any = None) -> None:
        assert self.emotion_callback is not None and self.emotion_callback.appraiser is not None
        self._affect_state = self.emotion_callback.appraiser.get_state()
        self._emotion_counts = list(self.emotion_callback.counts)
        try:
            super().save(path, exclude=exclude, include=include)
        finally:
            self._affect_state = None
            self._emotion_counts = None

    # -- the affect hook -------------------------------------------------------------------------------------------
    def learn(
        self: SelfAffectQ,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int | None = 4,
        tb_log_name: str | None = None,
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfAffectQ:
        """
        Learn as ``TabularQAlgorithm.learn``; the emotion callback is bound to this model for logging.

        :param total_timesteps: number of decisions to take (0 is allowed and takes none)
        :param callback: SB3 callback(s) called after every decision
        :param log_interval: dump the logger every this many episodes (None: never)
        :param tb_log_name: TensorBoard run name (None: the class name, as ``AffectQ_1``)
        :param reset_num_timesteps: start counting (and the episode log and the norm's history) from zero
        :param progress_bar: show a progress bar (tqdm and rich)
        :return: the trained model
        """
        before = 0 if reset_num_timesteps else self._episode_num  # SB3 counts the episodes of a new run from 0
        super().learn(total_timesteps, callback, log_interval, tb_log_name, reset_num_timesteps, progress_bar)
        if self.engine_used == "compiled":  # the kernel ran the episodes: the hook that counts them was not called
            assert self.emotion_callback is not None
            self.emotion_callback.count_episodes(self._episode_num - before, reached_goal=False)
        return self

    def start_run(
        self,
        total_timesteps: int,
        callback: MaybeCallback,
        reset_num_timesteps: bool,
        tb_log_name: str | None,
        progress_bar: bool,
        new_episode: bool,
    ) -> tuple[int, BaseCallback]:
        assert self.emotion_callback is not None
        self.emotion_callback.init_callback(self)  # bound to this model for logging
        return super().start_run(
            total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar, new_episode
        )

    def _new_run(self) -> None:
        assert self.emotion_callback is not None and self.emotion_callback.appraiser is not None
        self.emotion_callback.appraiser.reset_history()

    def _start_episode(self) -> None:
        assert self.emotion_callback is not None
        self.emotion_callback.begin_episode()

    def _end_episode(self, reached_goal: bool) -> tuple[list[int], float]:
        assert self.emotion_callback is not None
        return self.emotion_callback.end_episode(reached_goal)

    def _transition_hook(self) -> Any:
        assert self.emotion_callback is not None
        return self.emotion_callback.observe

    def _goal_test(self) -> GoalTest:
        assert self.emotion_callback is not None
        return self.emotion_callback.goal

    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        rng = self._rng
        assert self.emotion_callback is not None
        random_direction, speeds = self._behaviour[self.emotion_callback.feel(state)]
        cells = speeds[0] if len(speeds) == 1 else speeds[rng.randrange(len(speeds))]
        if random_direction:
            return rng.randrange(len(q[state])), cells, True
        return greedy_action(q[state], rng, self._tie_first), cells, False

    def _exploration_value(self) -> float:
        if not self._episode_blocks:
            return 1.0
        row = self._episode_blocks.last()
        return row[COLUMN["random_moves"]] / row[COLUMN["decisions"]]

    # -- the compiled engine ---------------------------------------------------------------------------------------
    def compiled_settings(self) -> TabularSettings | str:
        """
        ``TabularQAlgorithm.compiled_settings``, with the appraisal and the behaviour the model runs: those of its
        emotion callback and appraiser (the package's ``EmotionCallback`` with a Table II rule, and an ``Appraiser``
        or ``PersonalityAppraiser``; the kernel can not call the hooks of others).
        """
        settings = super().compiled_settings()
        if isinstance(settings, AffectQSettings):
            appraiser = self.emotion_callback.appraiser  # type: ignore[union-attr]
            settings.norm_scale = float(getattr(appraiser, "norm_scale", 1.0))
        return settings

    def _settings_values(self) -> dict[str, Any] | str:
        callback = self.emotion_callback
        if type(callback) is not EmotionCallback:
            return f"the emotion callback is a {type(callback).__name__}, whose hooks the kernel can not call"
        comparison = getattr(callback.emotion_rule, "table_ii_comparison", None)
        if comparison is None:
            return "the emotion callback has a custom emotion_rule, which the kernel can not call"
        appraiser = callback.appraiser
        if appraiser is None or type(appraiser) not in (Appraiser, PersonalityAppraiser):
            return f"the appraiser is a {type(appraiser).__name__}, which the kernel can not call"
        values = super()._settings_values()
        assert isinstance(values, dict)
        values.update(
            comparison=comparison,
            act=appraiser.act_mode,
            units=appraiser.units,
            behaviour_table=dict(zip(Emotion, self._behaviour)),
        )
        return values

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """
        The greedy action: ties to the first maximal action with ``deterministic=True``, at random otherwise.
        Emotions steer learning only: outside ``learn`` there is no appraisal, so there is no exploration either.
        """
        return super().predict(observation, state, episode_start, deterministic)
