"""
The grid's compiled decision loop's arguments (``sb3_affect.kernel.grid_loop``): a few named tuples of arrays and
scalars, which numba passes as one argument each. The indices of the run's scalars in ``RunState.ist`` and
``RunState.fst`` and of the episode rows' columns are ``kernel.state_layout``'s (the grid adds none of its own).

``EnvTable`` (the env's moves), ``Config`` (the run's fixed scalars, the agent's ``AgentSettings`` among them) and
``agent_settings.BehaviourRows`` (what each emotion does) are read only; ``RunState`` (the Q-table, the random stream
and the run's counters), ``Appraisal`` (the known map and
the power fit) and ``Episodes`` (per-episode parameters in, episode rows out) are read and written; ``Work`` is work
space.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from sb3_affect.kernel.agent_settings import AgentSettings
from sb3_affect.kernel.mt19937 import TW_SIZE


class EnvTable(NamedTuple):
    """
    The env's moves (read only): ``trans[s, a]`` (int64), the true distance to the goal ``tdist[s]`` and the most
    cells with a move into one cell (the width of the known map's predecessor rows).
    """

    trans: np.ndarray
    tdist: np.ndarray
    max_pred: int


class Config(NamedTuple):
    """The run's fixed scalars (read only): the agent's and the env's."""

    agent: AgentSettings
    goal: int  # the goal state
    start: int  # the state an episode starts in
    shortest: int  # cells of a shortest path from the start
    time_limit: int  # the env's TimeLimit (0: none)
    goal_reward: float
    step_reward: float
    n_actions: int


class RunState(NamedTuple):
    """The run's state (read and written): Q-table, random stream, scalars, UCB counts."""

    q: np.ndarray  # float64[n_states, n_actions]
    mt: np.ndarray  # int64[mt19937.STATE_SIZE]: the random stream's words and index
    ist: np.ndarray  # int64[state_layout.N_IST]
    fst: np.ndarray  # float64[state_layout.N_FST]
    ucb_n: np.ndarray  # int64[n_states, n_actions]: UCB's visit counts
    ucb_tot: np.ndarray  # int64[n_states]


class Appraisal(NamedTuple):
    """AffectQ's appraisal (read and written): the known map (``kernel.affect``) and the power fit's values."""

    dist: np.ndarray  # float64[n_states]: known distance to a goal
    edge: np.ndarray  # bool[n_states, n_actions]: moves seen
    pred: np.ndarray  # int64[n_states, max_pred]: known predecessors
    pred_n: np.ndarray  # int64[n_states]
    goal: np.ndarray  # bool[n_states]: goals seen
    fit_vals: np.ndarray  # float64[episodes]: the fit's y values (their count: ist[I_NFIT])


class Episodes(NamedTuple):
    """Per episode ``j`` of a call: its parameters (read) and, once finished, its row (written)."""

    alpha: np.ndarray  # float64: the learning rate
    p: np.ndarray  # float64: epsilon or the inverse temperature
    rows_i: np.ndarray  # int64[episodes, N_OUT_I]: the row's int columns (state_layout.O_*)
    rows_f: np.ndarray  # float64[episodes, N_OUT_F]: reward, norm (state_layout.F_*)


class Seeds(NamedTuple):
    """Fresh runs' seeds: the ``random.Random`` seed words of run ``r``, ``keys[r, :lengths[r]]``."""

    keys: np.ndarray
    lengths: np.ndarray


class Work(NamedTuple):
    """Work space (contents not kept): ``work`` (n_actions floats), ``seen`` (n_states zeros), ``stack``
    (n_states * n_actions + 1), ``queue`` (n_states + 1), ``tw`` (the random stream's tempered words)."""

    work: np.ndarray
    seen: np.ndarray
    stack: np.ndarray
    queue: np.ndarray
    tw: np.ndarray


@njit(cache=True)
def work_space(n_states, n_actions):
    """A fresh ``Work`` for a table of ``n_states`` x ``n_actions``."""
    return Work(
        np.empty(n_actions),
        np.zeros(n_states, dtype=np.int64),
        np.empty(n_states * n_actions + 1, dtype=np.int64),
        np.empty(n_states + 1, dtype=np.int64),
        np.empty(TW_SIZE, dtype=np.int64),
    )


# why run returned
STOP_TIMESTEPS, STOP_EPISODES = 0, 1
