"""
The compiled decision loop's arguments (``sb3_affect.kernel.loop``): a few named tuples of arrays and scalars, which
numba passes as one argument each, and the indices of the run's scalars in ``RunState.ist`` and ``RunState.fst`` and
of the episode rows' columns.

``EnvTable`` (the env's moves), ``Config`` (the run's fixed scalars) and ``BehaviourRows`` (what each emotion does)
are read only; ``RunState`` (the Q-table, the random stream and the run's counters), ``Appraisal`` (the known map and
the power fit) and ``Episodes`` (per-episode parameters in, episode rows out) are read and written; ``Work`` is work
space.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from sb3_affect.kernel.mt19937 import TW_SIZE

# agent kinds (``TabularSettings.family``)
EPSILON, AFFECT, BOLTZMANN, UCB = 0, 1, 2, 3


class EnvTable(NamedTuple):
    """
    The env's moves (read only): ``trans[s, a]`` (int64), the true distance to the goal ``tdist[s]`` and the most
    cells with a move into one cell (the width of the known map's predecessor rows).
    """

    trans: np.ndarray
    tdist: np.ndarray
    max_pred: int


class Config(NamedTuple):
    """The run's fixed scalars (read only)."""

    kind: int  # EPSILON, AFFECT, BOLTZMANN or UCB
    goal: int  # the goal state
    start: int  # the state an episode starts in
    shortest: int  # cells of a shortest path from the start
    time_limit: int  # the env's TimeLimit (0: none)
    cap: int  # max_episode_decisions
    act_episode: bool  # the appraisal's act: elapsed + remaining (else remaining)
    units_cells: bool  # the appraisal counts cells (else decisions)
    valence: bool  # Table II compares negated step counts
    tie_first: bool  # greedy ties go to the first action (else drawn)
    jump: bool  # multi_cell="jump": one Eq. 1 update per decision
    compensated_sum: bool  # Boltzmann's softmax sums as Python >= 3.12's sum
    gamma: float
    goal_reward: float
    step_reward: float
    norm_scale: float  # the personality's bias on the norm
    ucb_coef: float  # UCB's exploration weight
    q_init: float  # a fresh run's Q-values
    n_actions: int


class BehaviourRows(NamedTuple):
    """What each emotion does (read only; row 0: the epsilon family's speeds, for agents without emotions)."""

    random: np.ndarray  # int64[4]: the direction is random
    speeds: np.ndarray  # int64[4, K]: the cells a decision may move, drawn uniformly
    n: np.ndarray  # int64[4]: how many speeds each row has


class RunState(NamedTuple):
    """The run's state (read and written): Q-table, random stream, scalars, UCB counts."""

    q: np.ndarray  # float64[n_states, n_actions]
    mt: np.ndarray  # int64[mt19937.STATE_SIZE]: the random stream's words and index
    ist: np.ndarray  # int64[N_IST]
    fst: np.ndarray  # float64[N_FST]
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
    rows_i: np.ndarray  # int64[episodes, N_OUT_I]: the row's int columns (O_*)
    rows_f: np.ndarray  # float64[episodes, 2]: reward, norm


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


# RunState.ist: int run state
(
    I_T,
    I_STATE,
    I_DECISIONS,
    I_CELLS,
    I_RANDOM,
    I_WAITS,
    I_JOY,
    I_SADNESS,
    I_FEAR,
    I_ANGER,
    I_CHANGED,
    I_GREEDY,
    I_TL_ELAPSED,
    I_NFIT,
    I_EL_CELLS,
    I_EL_DECISIONS,
    I_LAST_ACTION,
    I_LAST_PREV,
    I_LAST_S2,
    I_LAST_TERMINATED,
) = range(20)
N_IST = 20
# RunState.fst: float run state
S_REWARD, S_NORM, S_LAST_ACT, S_LAST_REWARD, S_FIT0 = range(5)  # S_FIT0..S_FIT0+3: the power fit's running sums
N_FST = 9

# Episodes.rows_i columns (rows_f: reward, norm)
(O_DECISIONS, O_CELLS, O_OPTIMAL, O_TRUNCATED, O_RANDOM, O_WAITS, O_JOY, O_SADNESS, O_FEAR, O_ANGER, O_GREEDY) = range(11)
N_OUT_I = 11

# why run returned
STOP_TIMESTEPS, STOP_EPISODES = 0, 1
