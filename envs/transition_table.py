"""
``TransitionTable``: an env's moves written out as a table, in the spirit of Gymnasium toy_text's ``P``.

An env that can describe its dynamics this way (every step deterministic, the reward a function of whether the goal
was entered) gives ``transition_table()``; the compiled engine (``sb3_affect.kernel``) then steps it from the table
without calling ``step``. A new grid env gets the kernel by describing its moves; an env that can not (a moving prey
that draws random numbers) returns from ``transition_table()`` the reason instead, as a string.

What a table promises about ``step(a)`` in state ``s``: the next state is ``transitions[s][a]``; the episode
terminates exactly when it is ``goal``, with reward ``goal_reward``, and every other step gives ``step_reward``; the
env never truncates by itself; ``reset`` returns ``start``; the info of a step from ``s`` to ``s2`` is
``{"cell": divmod(s2, width), "moved": s2 != s}``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple


class TransitionTable(NamedTuple):
    """A deterministic env's moves, rewards and true distances (see the module docstring)."""

    transitions: Sequence[Sequence[int]]  # transitions[s][a]: the state action a leads to from s
    distances: Sequence[float]  # shortest number of steps from each state to the goal (inf: unreachable)
    start: int  # the state reset returns
    goal: int  # entering it terminates the episode
    goal_reward: float  # the reward of the step that enters the goal
    step_reward: float  # the reward of every other step
    width: int  # states are numbered row by row, ``width`` to a row (the info's ``cell``)

    @property
    def shortest_path_length(self) -> int:
        """Steps of a shortest path from the start to the goal."""
        return int(self.distances[self.start])
