"""
Broekens, Jacobs and Jonker's emotion model in numba (``sb3_affect.agents.broekens.BroekensCallback`` is the
reference), as the team kernel runs it beside each hunter (``kernel.team_emotions``): joy and distress the positive
and negative parts of a decision's TD error ``delta = r + gamma * V(s') - V(s)``, hope and fear those of the value
``V(s')`` reached; an episode's row holds their means per decision and the last decision's joy (``goal_joy``: NaN when
the episode was cut).

An observer's state is a row of ``N_STATE`` floats (``V`` the value of the state the decision started in, the
episode's sums, the last decision's joy); an episode's row is ``COLUMNS``, the columns the registry names
(``EMOTION_MODELS["broekens"]``), in the order this module writes them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import cfunc

from sb3_affect.kernel.team_emotions import CLOSE_EPISODE, OBSERVE, START

V, JOY, DISTRESS, HOPE, FEAR, LAST_JOY = range(6)
N_STATE = 6
COLUMNS = ("joy", "distress", "hope", "fear", "goal_joy")
OUT_JOY, OUT_DISTRESS, OUT_HOPE, OUT_FEAR, OUT_GOAL_JOY = range(5)


@cfunc(OBSERVE, cache=True)
def observe(b: np.ndarray, reward: float, gamma: float, reached: float) -> None:
    """
    One decision: its ``reward`` as the callbacks see it (float32, SB3's ``rewards``), the value ``reached`` after
    it; adds the decision's emotions to the sums.
    """
    delta = float(np.float32(reward)) + gamma * reached - b[V]
    joy = max(delta, 0.0)
    b[JOY] += joy
    b[DISTRESS] += max(-delta, 0.0)
    b[HOPE] += max(reached, 0.0)
    b[FEAR] += max(-reached, 0.0)
    b[V] = reached
    b[LAST_JOY] = joy


@cfunc(START, cache=True)
def start(b: np.ndarray, value: float) -> None:
    """An episode starts in a state of this ``value``."""
    b[V] = value


@cfunc(CLOSE_EPISODE, cache=True)
def close_episode(b: np.ndarray, out: np.ndarray, decisions: float, cut: bool) -> None:
    """An episode's row (``out``: the means over its ``decisions``, the last decision's joy unless it was ``cut``)."""
    out[OUT_JOY] = b[JOY] / decisions
    out[OUT_DISTRESS] = b[DISTRESS] / decisions
    out[OUT_HOPE] = b[HOPE] / decisions
    out[OUT_FEAR] = b[FEAR] / decisions
    out[OUT_GOAL_JOY] = math.nan if cut else b[LAST_JOY]
    b[JOY] = b[DISTRESS] = b[HOPE] = b[FEAR] = 0.0
