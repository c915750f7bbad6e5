"""
Broekens, Jacobs and Jonker's emotion model in numba (``sb3_affect.agents.broekens.BroekensCallback`` is the
reference), as the team kernel runs it beside each hunter: joy and distress the positive and negative parts of a
decision's TD error ``delta = r + gamma * V(s') - V(s)``, hope and fear those of the value ``V(s')`` reached; an
episode's row holds their means per decision and the last decision's joy (``goal_joy``: NaN when the episode was cut).

An observer's state is a row of ``N_STATE`` floats (``V`` the value of the state the decision started in, then the
episode's sums); an episode's row is ``COLUMNS``, the columns the registry names (``EMOTION_MODELS["broekens"]``),
in the order this module writes them (compiled in: the registry's order may change without this module).
"""

from __future__ import annotations

import math

import numpy as np

from sb3_affect.kernel.jit import kernel_inline

V, JOY, DISTRESS, HOPE, FEAR = range(5)
N_STATE = 5
COLUMNS = ("joy", "distress", "hope", "fear", "goal_joy")
OUT_JOY, OUT_DISTRESS, OUT_HOPE, OUT_FEAR, OUT_GOAL_JOY = range(5)
N_OUT = 5


@kernel_inline
def observe(b: np.ndarray, reward: float, gamma: float, reached: float) -> float:
    """
    One decision: its ``reward`` as the callbacks see it (float32, SB3's ``rewards``), the value ``reached`` after
    it; adds the decision's emotions to the sums and returns its joy.
    """
    delta = float(np.float32(reward)) + gamma * reached - b[V]
    joy = max(delta, 0.0)
    b[JOY] += joy
    b[DISTRESS] += max(-delta, 0.0)
    b[HOPE] += max(reached, 0.0)
    b[FEAR] += max(-reached, 0.0)
    b[V] = reached
    return joy


@kernel_inline
def start(b: np.ndarray, value: float) -> None:
    """An episode starts in a state of this ``value``."""
    b[V] = value


@kernel_inline
def close_episode(b: np.ndarray, out: np.ndarray, decisions: float, joy: float, cut: bool) -> None:
    """An episode's row (``out``: the means over its ``decisions``, the last decision's ``joy`` unless it was ``cut``)."""
    out[OUT_JOY] = b[JOY] / decisions
    out[OUT_DISTRESS] = b[DISTRESS] / decisions
    out[OUT_HOPE] = b[HOPE] / decisions
    out[OUT_FEAR] = b[FEAR] / decisions
    out[OUT_GOAL_JOY] = math.nan if cut else joy
    b[JOY] = b[DISTRESS] = b[HOPE] = b[FEAR] = 0.0
