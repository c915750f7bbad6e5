"""The per-episode record every agent keeps (``model.episode_log``) and the path checks behind its columns."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.envs.transition_table import TransitionTable

if TYPE_CHECKING:
    import pandas as pd

#: Columns of ``model.episode_log`` / ``EmotionCallback.episode_log``, in order.
EPISODE_COLUMNS: tuple[str, ...] = (
    "episode",  # 1-based episode number within the run
    "decisions",  # decisions taken (the paper's "steps"; one unit of time each)
    "cells",  # one-cell env transitions (a bump into a wall counts: the agent spent the move)
    "reward",  # sum of rewards
    "optimal",  # reached the goal in exactly the shortest possible number of cells
    "truncated",  # ended by the safety cap (or the env's own time limit), not at the goal
    "random_moves",  # decisions whose direction was drawn at random (NaN when the algorithm does not say)
    "waits",  # decisions that moved 0 cells
    *EMOTION_NAMES,  # decisions taken in each emotion: joy, sadness, fear, anger
    "greedy_optimal",  # after this episode, every greedy choice from the start walks a shortest path
    "norm",  # the appraisal norm in force during the episode (NaN when there was none)
)

#: The columns a traced run adds to its episodes (a sweep file's ``trace: true``: each decision's emotion and ``act``
#: recorded on the Python loop, stored per episode).
TRACE_COLUMNS: tuple[str, ...] = (
    "first_joy",  # the first decision felt in joy (1-based; NaN when the episode never feels joy)
    "act_at_first_joy",  # act at that decision (the appraisal's units), when the episode crosses the norm
    "joy_exits",  # decisions in joy followed by another emotion in the same episode
)

#: The columns by type: counts, flags (NaN where a run can not tell) and floats.
INT_COLUMNS: tuple[str, ...] = ("episode", "decisions", "cells", "waits", *EMOTION_NAMES)
FLAG_COLUMNS: tuple[str, ...] = ("optimal", "truncated", "greedy_optimal")
FLOAT_COLUMNS: tuple[str, ...] = ("reward", "random_moves", "norm")

#: Where each column sits in a row of the episode log (``row[COLUMN["decisions"]]``).
COLUMN: dict[str, int] = {name: i for i, name in enumerate(EPISODE_COLUMNS)}


class Geometry(NamedTuple):
    """What the path columns need to know about a grid env: its dynamics and true distances."""

    transitions: Sequence[Sequence[int]]
    distances: Sequence[float]
    start_state: int
    shortest_path_length: int


def env_geometry(env: Any) -> Geometry | None:
    """
    The geometry of an env (possibly wrapped) that exposes it: from its transition table
    (``sb3_affect.envs.transition_table``), or its ``transitions``, ``distances``, ``start_state`` and
    ``shortest_path_length``; ``None`` otherwise.
    """
    base = getattr(env, "unwrapped", env)
    describe = getattr(base, "transition_table", None)
    table = describe() if callable(describe) else None
    if isinstance(table, TransitionTable):
        return Geometry(table.transitions, table.distances, int(table.start), table.shortest_path_length)
    try:
        return Geometry(base.transitions, base.distances, int(base.start_state), int(base.shortest_path_length))
    except AttributeError:
        return None


class Rows(Protocol):
    """A Q-table read row by row: ``q[state]`` is the state's Q-values (a list of rows, or a mapping of rows)."""

    def __getitem__(self, state: int, /) -> list[float]: ...


def greedy_walks_shortest_path(q: Rows, geometry: Geometry) -> bool:
    """
    Whether the greedy policy of ``q`` walks a shortest path from the start whatever way its ties are broken:
    every action in the arg-max set of every cell it can reach must bring it one cell closer to the goal.
    """
    transitions, distances = geometry.transitions, geometry.distances
    stack = [geometry.start_state]
    seen: set[int] = set()
    while stack:
        s = stack.pop()
        d = distances[s]
        if d == 0 or s in seen:
            continue
        seen.add(s)
        row = q[s]
        best = max(row)
        for a, value in enumerate(row):
            if value == best:
                t = transitions[s][a]
                if distances[t] != d - 1:
                    return False
                stack.append(t)
    return True


def deterministic_walk_is_shortest(actions: Sequence[int], geometry: Geometry) -> bool:
    """Whether following one fixed action per cell (e.g. a DQN's greedy actions) from the start is a shortest path."""
    s = geometry.start_state
    for _ in range(geometry.shortest_path_length):
        s = geometry.transitions[s][int(actions[s])]
    return geometry.distances[s] == 0


def make_frame(rows: Sequence[Sequence[Any]]) -> pd.DataFrame:
    """The episode log as a DataFrame with typed columns."""
    import pandas as pd

    frame = pd.DataFrame(list(rows), columns=list(EPISODE_COLUMNS))
    for column in INT_COLUMNS:
        frame[column] = frame[column].astype("int64")
    for column in FLAG_COLUMNS:
        if frame[column].notna().all():
            frame[column] = frame[column].astype(bool)
    for column in ("reward", "random_moves", "norm"):
        frame[column] = frame[column].astype("float64")
    return frame
