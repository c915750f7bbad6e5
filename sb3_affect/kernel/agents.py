"""
What the kernel needs to know about an agent: its kind, its fixed configuration and the per-episode parameters
(learning rate and epsilon or inverse temperature), or why the kernel can not run it.

An *agent* here is a model, or the settings object of one of the package's agents (``sb3_affect.settings``): both
name their hyperparameters alike, so the functions below read either (the settings without importing torch).
"""

from __future__ import annotations

import sys
from typing import Any, NamedTuple

import numpy as np

from sb3_affect.kernel import loop


class AgentSpec(NamedTuple):
    """An agent as the kernel runs it."""

    kind: int
    beh_rand: np.ndarray  # int64[4]: random direction per emotion (AffectQ)
    beh_speeds: np.ndarray  # int64[4, K]: speeds per emotion (row 0: the epsilon family's speeds)
    beh_n: np.ndarray  # int64[4]: how many speeds per row
    valence: bool
    act_episode: bool
    units_cells: bool
    norm_scale: float
    ucb_coef: float


def _speeds_table(rows: list[tuple[bool, list[int]]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    width = max(len(speeds) for _, speeds in rows)
    beh_rand = np.zeros(4, dtype=np.int64)
    beh_speeds = np.zeros((4, width), dtype=np.int64)
    beh_n = np.ones(4, dtype=np.int64)
    for i, (random_direction, speeds) in enumerate(rows):
        beh_rand[i] = int(random_direction)
        beh_speeds[i, : len(speeds)] = speeds
        beh_n[i] = len(speeds)
    return beh_rand, beh_speeds, beh_n


#: The kernel's kind of each family of agents (``TabularSettings.family``).
FAMILY_KINDS = {"epsilon": loop.EPSILON, "affect": loop.AFFECT, "boltzmann": loop.BOLTZMANN, "ucb": loop.UCB}


def _kinds() -> dict[type, int]:
    """The kind of each agent class the kernel implements (imports the classes: torch)."""
    from sb3_affect.affectq import AffectQ
    from sb3_affect.baselines import (
        Boltzmann,
        DecayingEpsilonGreedy,
        OptimisticQLearning,
        SpeedEpsilonGreedy,
        UCBQLearning,
    )
    from sb3_affect.qlearning import QLearning

    classes = (QLearning, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, AffectQ, Boltzmann, UCBQLearning)
    return {cls: FAMILY_KINDS[cls.settings_class.family] for cls in classes}


def _plain_spec(agent: Any, kind: int) -> AgentSpec:
    """The spec of an agent whose direction rule has no emotions (epsilon, Boltzmann, UCB): speeds aside, fixed."""
    ucb_coef = float(getattr(agent, "exploration_coef", 0.0))
    speeds = [int(k) for k in getattr(agent, "speeds", [1])]
    rows = [(False, speeds)] + [(False, [1])] * 3
    return AgentSpec(kind, *_speeds_table(rows), False, True, True, 1.0, ucb_coef)


def settings_spec(settings: Any) -> AgentSpec | str:
    """The kernel's view of an agent's settings (``sb3_affect.settings``): what a model built from them gives."""
    kind = FAMILY_KINDS.get(settings.family)
    if kind is None:
        return f"{type(settings).__name__} are not the settings of an agent the kernel implements"
    if kind != loop.AFFECT:
        return _plain_spec(settings, kind)
    # AffectQ builds EmotionCallback(comparison, act, units) or, for a personality, a PersonalityAppraiser preset
    return AgentSpec(
        kind,
        *_speeds_table(settings.behaviour_rows()),
        settings.comparison == "valence",
        settings.act == "episode",
        settings.units == "cells",
        float(settings.norm_scale),
        0.0,
    )


def agent_spec(model: Any) -> AgentSpec | str:
    """The kernel's view of ``model`` (a model or an agent's settings), or the reason it has none."""
    from sb3_affect.settings import TabularSettings

    if isinstance(model, TabularSettings):
        return settings_spec(model)
    from sb3_affect.appraisal import Appraiser
    from sb3_affect.callbacks import EmotionCallback
    from sb3_affect.personalities import PersonalityAppraiser

    kind = _kinds().get(type(model))
    if kind is None:
        return (
            f"{type(model).__name__} is not one of the agents the kernel implements (QLearning, AffectQ and the "
            "baselines, not subclasses of them, which may change the loop)"
        )
    ucb_coef = float(getattr(model, "exploration_coef", 0.0))
    if kind != loop.AFFECT:
        return _plain_spec(model, kind)
    callback = model.emotion_callback
    if type(callback) is not EmotionCallback:
        return f"the emotion callback is a {type(callback).__name__}, whose hooks the kernel can not call"
    comparison = getattr(callback.emotion_rule, "table_ii_comparison", None)
    if comparison is None:
        return "the emotion callback has a custom emotion_rule, which the kernel can not call"
    appraiser = callback.appraiser
    if appraiser is None or type(appraiser) not in (Appraiser, PersonalityAppraiser):
        return f"the appraiser is a {type(appraiser).__name__}, which the kernel can not call"
    from sb3_affect.emotions import Emotion

    rows = [(bool(r), [int(k) for k in speeds]) for r, speeds in (model._behaviour[e] for e in Emotion)]
    return AgentSpec(
        kind,
        *_speeds_table(rows),
        comparison == "valence",
        appraiser.act_mode == "episode",
        appraiser.units == "cells",
        float(getattr(appraiser, "norm_scale", 1.0)),
        ucb_coef,
    )


def current_exploration(model: Any, kind: int) -> float:
    """The exploration parameter of the episode in progress (epsilon or inverse temperature; 0 when unused)."""
    if kind == loop.EPSILON:
        return float(model._epsilon)
    if kind == loop.BOLTZMANN:
        return float(model._inv_temperature)
    return 0.0


def episode_schedule(model: Any, kind: int, first: int, count: int) -> tuple[np.ndarray, np.ndarray] | None:
    """
    Learning rate and exploration parameter of the episodes that start after ``first``, ``first + 1``, ...
    finished episodes of the run, or None when they depend on the training progress (an SB3 schedule of the
    remaining progress), which only the Python side can evaluate, one episode at a time. ``model``: a model or an
    agent's settings (an episode-decaying epsilon is the ``epsilon_at`` both ``DecayingEpsilonGreedy`` and its
    settings have).
    """
    if callable(model.learning_rate):
        return None
    alpha = np.full(count, float(model.learning_rate))
    if kind == loop.EPSILON:
        epsilon_at = getattr(model, "epsilon_at", None)
        if epsilon_at is not None:
            p = np.array([epsilon_at(first + j) for j in range(count)], dtype=np.float64)
        elif callable(model.exploration_rate):
            return None
        else:
            p = np.full(count, float(model.exploration_rate))
    elif kind == loop.BOLTZMANN:
        if model.temperature_final is None and callable(model.temperature):
            return None
        p = np.array([1.0 / model.temperature_at(first + j) for j in range(count)], dtype=np.float64)
    else:
        p = np.zeros(count)
    return alpha, p


#: Python 3.12 made ``sum`` of floats compensated (Neumaier); Boltzmann's softmax sums its weights with ``sum``.
COMPENSATED_SUM = sys.version_info >= (3, 12)
