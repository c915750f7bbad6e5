"""
The emotion models the team kernel runs beside each hunter: every model of the registry (``EMOTION_MODELS``), each
from the kernel module its entry names, so that adding a model that runs compiled takes its modules and its entry.

A model's kernel module (``kernel.td_emotions`` is Broekens') holds ``N_STATE`` (the floats of an observer's state),
``COLUMNS`` (its episode row's columns, the registry's names) and three numba ``cfunc``s of the signatures below:
``start(state, value)`` (an episode starts in a state of ``value``, ``max_a Q``), ``observe(state, reward, gamma,
reached)`` (one decision: its ``reward`` as the callbacks see it, the hunter's ``gamma``, the value ``reached`` after
it) and ``close_episode(state, out, decisions, cut)`` (the episode's row into ``out``, its ``decisions``; ``cut`` when
a time limit or the team's cap ended it). The team loop calls them through their addresses (numba's first-class
functions), so it is compiled and cached once, whatever models the registry lists, and a model's own cached code is
its module's.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, NamedTuple

import numpy as np
from numba import types
from numba.core.errors import NumbaExperimentalFeatureWarning

from sb3_affect.core.registry import EMOTION_MODELS

#: ``start(state, value)``.
START = types.void(types.float64[:], types.float64)
#: ``observe(state, reward, gamma, reached)``.
OBSERVE = types.void(types.float64[:], types.float64, types.float64, types.float64)
#: ``close_episode(state, out, decisions, cut)``.
CLOSE_EPISODE = types.void(types.float64[:], types.float64[:], types.float64, types.boolean)


class Observers(NamedTuple):
    """The registry's models as the team loop calls them, in the registry's order (read only)."""

    start: tuple[Any, ...]  # each model's ``start`` cfunc
    observe: tuple[Any, ...]
    close_episode: tuple[Any, ...]
    state_at: np.ndarray  # int64[models + 1]: where each model's state starts among a hunter's observer floats
    out_at: np.ndarray  # int64[models + 1]: where each model's columns start among a hunter's observer columns


class TeamEmotions(NamedTuple):
    """The team loop's ``Observers`` and, per model name, where each column the registry names is among theirs."""

    observers: Observers
    columns: dict[str, dict[str, int]]

    @property
    def n_state(self) -> int:
        return int(self.observers.state_at[-1])

    @property
    def n_out(self) -> int:
        return int(self.observers.out_at[-1])


def team_emotions() -> TeamEmotions | str:
    """Every model of the registry from its kernel module, or the reason the team kernel can not compute them."""
    if not EMOTION_MODELS:
        return "the registry lists no emotion model"
    modules = []
    for name, model in EMOTION_MODELS.items():
        if model.kernel is None:
            return f"the emotion model {name} has no kernel module (Python teams only)"
        modules.append(importlib.import_module(model.kernel))
    state_at = np.cumsum([0, *(module.N_STATE for module in modules)], dtype=np.int64)
    out_at = np.cumsum([0, *(len(module.COLUMNS) for module in modules)], dtype=np.int64)
    observers = Observers(
        tuple(module.start for module in modules),
        tuple(module.observe for module in modules),
        tuple(module.close_episode for module in modules),
        state_at,
        out_at,
    )
    columns = {
        name: {column: int(at) + module.COLUMNS.index(column) for column in model.columns}
        for (name, model), module, at in zip(EMOTION_MODELS.items(), modules, out_at)
    }
    return TeamEmotions(observers, columns)


@contextmanager
def first_class_functions() -> Iterator[None]:
    """Without numba's warning that calls through a function's address are an experimental feature (it types them)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=NumbaExperimentalFeatureWarning)
        yield
