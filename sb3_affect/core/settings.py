"""
The tabular agents' settings: each agent's hyperparameters, their defaults and their validation, without torch.

One dataclass per agent class (``QLearningSettings`` for ``QLearning``, ...). The agent's constructor takes its
defaults from it (``gamma: float = QLearningSettings.gamma``) and checks its arguments with the functions of
``sb3_affect.core.setting_checks`` (``check_tabular``, ``check_exploration_rate``, ...); a settings object runs the same
checks in the same order when it is built. So a settings object holds exactly what the constructor accepts,
normalised as the agent stores it, and a bad value is the same error (argument, value, what is allowed) either way.
The compiled engine reads a settings
object, never a model (``sb3_affect.kernel``): its family, its behaviour rows and its per-episode parameters
(``behaviour_rows``, ``episode_parameters``); a sweep of the package's agents runs without building an SB3 model, or
importing torch, and a model hands the kernel its settings (``TabularQAlgorithm.compiled_settings``).

Only the hyperparameters the learning loop reads are settings. SB3's own arguments (``seed``, ``device``,
``verbose``, ``policy_kwargs``, ``tensorboard_log``, ``stats_window_size``) and objects (``emotion_callback``) are
not: where they are given, the model is built.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from sb3_affect.core.emotions import Emotion
from sb3_affect.core.personalities import PERSONALITIES
from sb3_affect.core.setting_checks import (
    Rate,
    check_affect,
    check_boltzmann,
    check_decaying,
    check_exploration_rate,
    check_number,
    check_speeds,
    check_tabular,
    episode_decay,
    temperature_at,
)


# -- one dataclass per agent -----------------------------------------------------------------------------------------
@dataclass
class TabularSettings:
    """
    The settings every tabular agent has (``TabularQAlgorithm``'s; see its parameters).

    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param max_episode_decisions: the safety cap on an episode's decisions
    :param engine: ``"auto"``, ``"python"`` or ``"compiled"``
    :param tie_break: greedy ties while learning: ``"random"`` or ``"first"``
    """

    learning_rate: Rate = 1.0
    gamma: float = 0.8
    q_init: float = 0.0
    max_episode_decisions: int = 20_000
    engine: str = "auto"
    tie_break: str = "random"

    #: how the agent decides, as the kernel groups agents: "epsilon", "affect", "boltzmann", "ucb" ("": no kernel)
    family: ClassVar[str] = ""
    #: the agent class: ``"module:Class"`` where it is defined
    agent: ClassVar[str] = "sb3_affect.agents.tabular:TabularQAlgorithm"
    #: packages that export the class too (``from sb3_affect import QLearning``)
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect",)

    def __post_init__(self) -> None:
        self._check()

    def _check(self) -> None:
        """Validate and normalise the fields, in the order the agent's constructors do (subclasses: theirs first)."""
        self.engine, self.tie_break, self.gamma, self.q_init, self.max_episode_decisions = check_tabular(
            self.learning_rate, self.gamma, self.q_init, self.max_episode_decisions, self.engine, self.tie_break
        )

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The constructor arguments that are settings."""
        return tuple(f.name for f in dataclasses.fields(cls) if f.init)

    def behaviour_rows(self) -> list[tuple[bool, list[int]]]:
        """
        ``(random_direction, speeds)`` per emotion, in ``Emotion`` order. An agent without emotions: its speeds in the
        first row (one cell a decision), the other rows unused.
        """
        return [(False, [1])] * 4

    def episode_parameters(self, first: int, count: int) -> tuple[np.ndarray, np.ndarray] | None:
        """
        Learning rate and exploration parameter (epsilon, the inverse temperature, or 0 when the agent has none) of
        the episodes that start after ``first``, ``first + 1``, ... finished episodes of the run; None when either
        depends on the training progress (an SB3 schedule of the remaining progress), which only the model evaluates,
        one episode at a time.
        """
        if callable(self.learning_rate):
            return None
        exploration = self.exploration_at(first, count)
        if exploration is None:
            return None
        return np.full(count, float(self.learning_rate)), exploration

    def exploration_at(self, first: int, count: int) -> np.ndarray | None:
        """The exploration parameter of ``episode_parameters`` (None: a schedule of the progress)."""
        return np.zeros(count)


@dataclass
class QLearningSettings(TabularSettings):
    """
    ``QLearning``'s settings (and ``TabularSettings``').

    :param exploration_rate: epsilon, in [0, 1]; a float or a schedule of the remaining progress
    """

    exploration_rate: Rate = 0.1

    family: ClassVar[str] = "epsilon"
    agent: ClassVar[str] = "sb3_affect.agents.qlearning:QLearning"

    def _check(self) -> None:
        self.exploration_rate = check_exploration_rate(self.exploration_rate)
        super()._check()

    def exploration_at(self, first: int, count: int) -> np.ndarray | None:
        if callable(self.exploration_rate):
            return None
        return np.full(count, float(self.exploration_rate))


@dataclass
class OptimisticQLearningSettings(QLearningSettings):
    """``OptimisticQLearning``'s settings: ``QLearning``'s with other defaults."""

    q_init: float = 100.0
    exploration_rate: Rate = 0.0

    agent: ClassVar[str] = "sb3_affect.agents.baselines.optimistic:OptimisticQLearning"
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect.agents.baselines",)


@dataclass
class SpeedEpsilonGreedySettings(QLearningSettings):
    """
    ``SpeedEpsilonGreedy``'s settings (and ``QLearningSettings``').

    :param speeds: cells a decision moves, drawn uniformly (non-empty, integers >= 0)
    :param multi_cell: ``"steps"`` or ``"jump"``
    """

    speeds: Sequence[int] = (1, 2)
    multi_cell: str = "steps"

    agent: ClassVar[str] = "sb3_affect.agents.baselines.speed:SpeedEpsilonGreedy"
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect.agents.baselines",)

    def _check(self) -> None:
        self.multi_cell, self.speeds = check_speeds(self.multi_cell, self.speeds)
        super()._check()

    def behaviour_rows(self) -> list[tuple[bool, list[int]]]:
        return [(False, [int(k) for k in self.speeds])] + [(False, [1])] * 3


@dataclass
class DecayingEpsilonGreedySettings(TabularSettings):
    """
    ``DecayingEpsilonGreedy``'s settings (and ``TabularSettings``'): epsilon decays over the run's episodes.

    :param exploration_initial_eps: epsilon of the first episode, in [0, 1]
    :param exploration_final_eps: epsilon once the decay is over, in [0, 1]
    :param exploration_decay_episodes: episodes the decay lasts (>= 1)
    :param decay: ``"linear"`` or ``"exponential"``
    """

    exploration_initial_eps: float = 1.0
    exploration_final_eps: float = 0.05
    exploration_decay_episodes: int = 50
    decay: str = "linear"

    family: ClassVar[str] = "epsilon"
    agent: ClassVar[str] = "sb3_affect.agents.baselines.decaying:DecayingEpsilonGreedy"
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect.agents.baselines",)

    def _check(self) -> None:
        values = check_decaying(
            self.exploration_initial_eps, self.exploration_final_eps, self.exploration_decay_episodes, self.decay
        )
        self.exploration_initial_eps, self.exploration_final_eps, self.exploration_decay_episodes, self.decay = values
        check_exploration_rate(self.exploration_initial_eps)  # QLearning's check of the epsilon it is given
        super()._check()

    def epsilon_at(self, finished_episodes: int) -> float:
        """Epsilon of an episode that starts after ``finished_episodes`` finished episodes of the run."""
        return episode_decay(
            self.exploration_initial_eps,
            self.exploration_final_eps,
            self.exploration_decay_episodes,
            self.decay,
            finished_episodes,
        )

    def exploration_at(self, first: int, count: int) -> np.ndarray | None:
        return np.array([self.epsilon_at(first + j) for j in range(count)], dtype=np.float64)


@dataclass
class BoltzmannSettings(TabularSettings):
    """
    ``Boltzmann``'s settings (and ``TabularSettings``'): a fixed, scheduled or episode-decaying temperature.

    :param temperature: T > 0 (the first episode's when ``temperature_final`` is given); a float or a schedule
    :param temperature_final: None (no decay) or the temperature once the decay is over (> 0)
    :param temperature_decay_episodes: episodes the decay lasts (>= 1)
    :param decay: ``"exponential"`` or ``"linear"``
    """

    temperature: Rate = 1.0
    temperature_final: float | None = None
    temperature_decay_episodes: int = 100
    decay: str = "exponential"

    family: ClassVar[str] = "boltzmann"
    agent: ClassVar[str] = "sb3_affect.agents.baselines.boltzmann:Boltzmann"
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect.agents.baselines",)

    def _check(self) -> None:
        self.temperature, self.temperature_final, self.temperature_decay_episodes, self.decay = check_boltzmann(
            self.temperature, self.temperature_final, self.temperature_decay_episodes, self.decay
        )
        super()._check()

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

    def exploration_at(self, first: int, count: int) -> np.ndarray | None:
        """The inverse temperature (a schedule of the progress without ``temperature_final``: None)."""
        if self.temperature_final is None and callable(self.temperature):
            return None
        return np.array([1.0 / self.temperature_at(first + j) for j in range(count)], dtype=np.float64)


@dataclass
class UCBQLearningSettings(TabularSettings):
    """
    ``UCBQLearning``'s settings (and ``TabularSettings``').

    :param exploration_coef: the weight c >= 0 of the bonus
    """

    exploration_coef: float = 1.0

    family: ClassVar[str] = "ucb"
    agent: ClassVar[str] = "sb3_affect.agents.baselines.ucb:UCBQLearning"
    exported_from: ClassVar[tuple[str, ...]] = ("sb3_affect.agents.baselines",)

    def _check(self) -> None:
        self.exploration_coef = check_number("exploration_coef", self.exploration_coef, 0.0, 1e300)
        super()._check()


@dataclass
class AffectQSettings(TabularSettings):
    """
    ``AffectQ``'s settings (and ``TabularSettings``'): the reading of Table II, the appraisal, the behaviour table,
    the personality.

    :param comparison: ``"literal"`` or ``"valence"``
    :param act: ``"episode"`` or ``"remaining"``
    :param units: ``"cells"`` or ``"decisions"``
    :param behaviour_table: emotion -> ``Behaviour(random_direction, speeds)``, or a name of ``BEHAVIOUR_TABLES``; None:
        Table III
    :param personality: ``"neutral"``, ``"optimistic"`` or ``"pessimistic"``
    :param multi_cell: ``"steps"`` or ``"jump"``
    """

    comparison: str = "literal"
    act: str = "episode"
    units: str = "cells"
    behaviour_table: Mapping[Emotion, Any] | str | None = None
    personality: str = "neutral"
    multi_cell: str = "steps"

    #: the behaviour table as the agent stores it (``{emotion name: [random_direction, speeds]}``)
    stored_behaviour_table: dict[str, list[Any]] = field(init=False, repr=False, compare=False, default_factory=dict)
    #: the appraisal's bias on the norm: the personality's (``sb3_affect.core.personalities``), or the one of a model's own
    #: appraiser (``AffectQ.compiled_settings`` sets it)
    norm_scale: float = field(init=False, repr=False, compare=False, default=1.0)

    family: ClassVar[str] = "affect"
    agent: ClassVar[str] = "sb3_affect.agents.affectq:AffectQ"

    def _check(self) -> None:
        self.multi_cell, self.personality, self.comparison, self.act, self.units, table = check_affect(
            self.multi_cell, self.personality, self.comparison, self.act, self.units, self.behaviour_table
        )
        self.stored_behaviour_table = table
        self.norm_scale = PERSONALITIES[self.personality]
        super()._check()

    def behaviour_rows(self) -> list[tuple[bool, list[int]]]:
        """``(random_direction, speeds)`` per emotion, in ``Emotion`` order (as ``AffectQ._behaviour``)."""
        table = self.stored_behaviour_table
        return [(bool(r), [int(k) for k in speeds]) for r, speeds in (table[e.name.lower()] for e in Emotion)]


#: The package's tabular agents that the compiled engine runs, by settings class.
AGENT_SETTINGS: tuple[type[TabularSettings], ...] = (
    QLearningSettings,
    AffectQSettings,
    DecayingEpsilonGreedySettings,
    BoltzmannSettings,
    UCBQLearningSettings,
    OptimisticQLearningSettings,
    SpeedEpsilonGreedySettings,
)


def settings_class(module: str, name: str) -> type[TabularSettings] | None:
    """
    The settings class of the agent ``module:name`` names (where it is defined or a package that exports it), without
    importing it; None for any other class.
    """
    for settings in AGENT_SETTINGS:
        home, _, cls_name = settings.agent.partition(":")
        if name == cls_name and module in (home, *settings.exported_from):
            return settings
    return None
