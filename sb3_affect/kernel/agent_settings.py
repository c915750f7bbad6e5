"""
What the kernel needs to know about an agent (``KernelAgent``), read from the agent's settings object
(``sb3_affect.core.settings``): its family (the kernel's kind), its behaviour rows and its appraisal options. The
per-episode learning rate and exploration come from the settings too (``TabularSettings.episode_parameters``).

The kernel knows no agent class: a model gives its settings (``TabularQAlgorithm.compiled_settings``), or says
itself why the kernel can not run it.
"""

from __future__ import annotations

import sys
from typing import Any, NamedTuple

import numpy as np

from sb3_affect.kernel import arrays


class KernelAgent(NamedTuple):
    """An agent as the kernel runs it."""

    kind: int
    behaviour: arrays.BehaviourRows
    valence: bool
    act_episode: bool
    units_cells: bool
    norm_scale: float
    ucb_coef: float


def behaviour_arrays(rows: list[tuple[bool, list[int]]]) -> arrays.BehaviourRows:
    """``(random direction, speeds)`` per emotion as the kernel's arrays."""
    width = max(len(speeds) for _, speeds in rows)
    beh_rand = np.zeros(4, dtype=np.int64)
    beh_speeds = np.zeros((4, width), dtype=np.int64)
    beh_n = np.ones(4, dtype=np.int64)
    for i, (random_direction, speeds) in enumerate(rows):
        beh_rand[i] = int(random_direction)
        beh_speeds[i, : len(speeds)] = speeds
        beh_n[i] = len(speeds)
    return arrays.BehaviourRows(beh_rand, beh_speeds, beh_n)


#: The kernel's kind of each family of agents (``TabularSettings.family``).
FAMILY_KINDS = {"epsilon": arrays.EPSILON, "affect": arrays.AFFECT, "boltzmann": arrays.BOLTZMANN, "ucb": arrays.UCB}


def kernel_agent(settings: Any) -> KernelAgent | str:
    """The kernel's view of an agent's settings (``sb3_affect.core.settings``), or the reason it has none."""
    kind = FAMILY_KINDS.get(settings.family)
    if kind is None:
        return f"{type(settings).__name__} are not the settings of an agent the kernel implements"
    behaviour = behaviour_arrays(settings.behaviour_rows())
    if kind != arrays.AFFECT:
        return KernelAgent(kind, behaviour, False, True, True, 1.0, float(getattr(settings, "exploration_coef", 0.0)))
    return KernelAgent(
        kind,
        behaviour,
        settings.comparison == "valence",
        settings.act == "episode",
        settings.units == "cells",
        float(settings.norm_scale),
        0.0,
    )


#: Python 3.12 made ``sum`` of floats compensated (Neumaier); Boltzmann's softmax sums its weights with ``sum``.
COMPENSATED_SUM = sys.version_info >= (3, 12)
