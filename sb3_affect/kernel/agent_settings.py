"""
An agent as the kernel runs it (``KernelAgent``), read from the agent's settings object (``sb3_affect.core.settings``)
by the one builder ``kernel_agent``: its fixed scalars (``AgentSettings``, which every world's configuration nests:
the grid's ``grid_arrays.Config``, moving prey's ``moving_loop.Config``, a team's ``team_loop.Hunters``) and what each
emotion does (``BehaviourRows``). The per-episode learning rate and exploration come from the settings too
(``TabularSettings.episode_parameters``).

The kernel knows no agent class: a model gives its settings (``TabularQAlgorithm.compiled_settings``), or says
itself why the kernel can not run it.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from sb3_affect.core.registry import known_settings

# agent kinds (``TabularSettings.family``: ``FAMILY_KINDS``)
EPSILON, AFFECT, BOLTZMANN, UCB = 0, 1, 2, 3

#: The kernel's kind of each family of agents (``TabularSettings.family``).
FAMILY_KINDS = {"epsilon": EPSILON, "affect": AFFECT, "boltzmann": BOLTZMANN, "ucb": UCB}

#: Python 3.12 made ``sum`` of floats compensated (Neumaier); Boltzmann's softmax sums its weights with ``sum``.
COMPENSATED_SUM = sys.version_info >= (3, 12)


class AgentSettings(NamedTuple):
    """An agent's fixed scalars (read only): what ``decision.decide`` and every world's loop read of an agent."""

    kind: int  # EPSILON, AFFECT, BOLTZMANN or UCB
    cap: int  # max_episode_decisions
    act_episode: bool  # the appraisal's act: elapsed + remaining (else remaining)
    units_cells: bool  # the appraisal counts cells (else decisions)
    valence: bool  # Table II compares negated step counts
    tie_first: bool  # greedy ties go to the first action (else drawn)
    jump: bool  # multi_cell="jump": one Eq. 1 update per decision
    compensated_sum: bool  # Boltzmann's softmax sums as Python >= 3.12's sum
    gamma: float
    norm_scale: float  # the personality's bias on the norm
    ucb_coef: float  # UCB's exploration weight
    q_init: float  # a fresh run's Q-values


class BehaviourRows(NamedTuple):
    """What each emotion does (read only; row 0: the epsilon family's speeds, for agents without emotions)."""

    random: np.ndarray  # int64[4]: the direction is random
    speeds: np.ndarray  # int64[4, K]: the cells a decision may move, drawn uniformly
    n: np.ndarray  # int64[4]: how many speeds each row has


class KernelAgent(NamedTuple):
    """An agent as the kernel runs it: its fixed scalars and its behaviour rows."""

    settings: AgentSettings
    behaviour: BehaviourRows

    @property
    def kind(self) -> int:
        """``settings.kind``."""
        return self.settings.kind


def behaviour_arrays(rows: list[tuple[bool, list[int]]]) -> BehaviourRows:
    """``(random direction, speeds)`` per emotion as the kernel's arrays."""
    width = max(len(speeds) for _, speeds in rows)
    beh_rand = np.zeros(4, dtype=np.int64)
    beh_speeds = np.zeros((4, width), dtype=np.int64)
    beh_n = np.ones(4, dtype=np.int64)
    for i, (random_direction, speeds) in enumerate(rows):
        beh_rand[i] = int(random_direction)
        beh_speeds[i, : len(speeds)] = speeds
        beh_n[i] = len(speeds)
    return BehaviourRows(beh_rand, beh_speeds, beh_n)


def kernel_agent(settings: Any) -> KernelAgent | str:
    """The kernel's view of an agent's settings (``sb3_affect.core.settings``), or the reason it has none."""
    kind = FAMILY_KINDS.get(settings.family)
    if kind is None:
        return f"{type(settings).__name__} are not the settings of an agent the kernel implements"
    affect = kind == AFFECT
    fixed = AgentSettings(
        kind=kind,
        cap=int(settings.max_episode_decisions),
        act_episode=settings.act == "episode" if affect else True,
        units_cells=settings.units == "cells" if affect else True,
        valence=settings.comparison == "valence" if affect else False,
        tie_first=settings.tie_break == "first",
        jump=getattr(settings, "multi_cell", "steps") == "jump",
        compensated_sum=COMPENSATED_SUM,
        gamma=float(settings.gamma),
        norm_scale=float(settings.norm_scale) if affect else 1.0,
        ucb_coef=0.0 if affect else float(getattr(settings, "exploration_coef", 0.0)),
        q_init=float(settings.q_init),
    )
    return KernelAgent(fixed, behaviour_arrays(settings.behaviour_rows()))


def settings_class(algo: str | type, kwargs: Mapping[str, Any]) -> type | None:
    """
    The settings class of ``algo`` (``sb3_affect.core.registry.known_settings``) when every one of ``kwargs`` is one of
    its settings; None where the model-based path must decide (a class of your own, an argument that is not a setting).
    """
    settings_cls = known_settings(algo)
    if settings_cls is None or not set(kwargs) <= set(settings_cls.names()):
        return None
    return settings_cls


def kernel_settings(settings_cls: type, kwargs: Mapping[str, Any]) -> Any | None:
    """
    The settings object of ``kwargs`` (bad kwargs raise the constructor's error), or None when the kernel does not run
    it: not an agent it implements, or a schedule of the training progress (only the Python side evaluates it).
    """
    settings = settings_cls(**kwargs)
    if isinstance(kernel_agent(settings), str) or settings.episode_parameters(0, 1) is None:
        return None
    return settings
