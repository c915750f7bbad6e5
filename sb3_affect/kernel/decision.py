"""
The decision step every compiled loop runs (the grid's ``kernel.grid_loop``, moving prey's ``kernel.moving_loop``,
hunter teams' ``kernel.team_loop``): the choice of direction and speed of every agent kind after the appraisal's
emotion (``decide``), Eq. 1 (``q_update``), the known map over observations (``obs_known_add``) and the end of a
single agent's episode (``end_episode``, ``last_decision``), each doing the same operations, with the same random
draws in the same order, as its Python reference (``_decide`` of each agent class, ``reference_loop.q_update``,
``appraisal.KnownMap.add``, the Python loop's episode end).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sb3_affect.kernel.affect import feel, fit_add, propagate, start_norm
from sb3_affect.kernel.agent_settings import AFFECT, BOLTZMANN, EPSILON
from sb3_affect.kernel.choice import greedy, row_max, softmax_action, ucb_action
from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.mt19937 import bit_length, draw01, draw_below
from sb3_affect.kernel.state_layout import (
    F_NORM,
    F_REWARD,
    I_JOY,
    I_LAST_ACTION,
    I_LAST_PREV,
    I_LAST_S2,
    I_LAST_TERMINATED,
    I_NFIT,
    O_CELLS,
    O_DECISIONS,
    O_JOY,
    O_RANDOM,
    O_TRUNCATED,
    O_WAITS,
    S_FIT0,
    S_LAST_REWARD,
)

__all__ = ["AFFECT", "ObsAppraisal", "decide", "end_episode", "known_widths", "last_decision", "obs_known_add", "q_update"]


class ObsAppraisal(NamedTuple):
    """
    AffectQ's appraisal over observations (read and written; ``obs_known_add``): the known distances ``dist``, the
    successors seen from each observation (``succ[s, :succ_n[s]]``), the predecessors of each in the order they were
    added (``pred[v, :pred_n[v]]``), the goals reached and the power fit's values (``fit_vals``). The moving-prey
    kernel's are one agent's; the team kernel's have one row per hunter first.
    """

    dist: np.ndarray  # float64[n_states]
    succ: np.ndarray  # int32[n_states, succ_width]
    succ_n: np.ndarray  # int64[n_states]
    pred: np.ndarray  # int32[n_states, pred_width]
    pred_n: np.ndarray  # int64[n_states]
    goal: np.ndarray  # bool[n_states]
    fit_vals: np.ndarray  # float64[episodes]


@kernel_inline
def q_update(q, s, action, reward, s2, terminated, alpha, gamma):
    """
    Eq. 1 for ``q[s, action]`` after a move to ``s2`` with ``reward`` (the only place the kernel writes it); returns
    whether the entry changed.
    """
    old = q[s, action]
    new = old + alpha * ((reward if terminated else reward + gamma * row_max(q, s2)) - old)
    if new != old:
        q[s, action] = new
        return True
    return False


@kernel_inline
def action_shift(n_actions: int) -> int:
    """``32 - n_actions.bit_length()`` (``mt19937.draw_below``'s shift), a constant for four actions (the grids')."""
    return 29 if n_actions == 4 else 32 - bit_length(n_actions)


@kernel_inline
def decide(config, behaviour, state, work, s, r, p, norm, elapsed, last_act, dist):
    """
    One decision of an agent in state ``s``: ``(action, cells, explored, emotion, last_act, r)``.

    ``config`` is the agent's fixed scalars (``agent_settings.AgentSettings``), ``behaviour`` its
    ``agent_settings.BehaviourRows``, ``state`` its Q-table ``q``, random stream ``mt`` and UCB counts ``ucb_n``, ``ucb_tot``
    (``grid_arrays.RunState``), ``work`` its work space ``work`` and ``tw`` (``grid_arrays.Work``); ``r`` is the random
    stream's
    index (``mt19937.draw``), ``p`` epsilon or the inverse temperature. For AffectQ the appraisal's ``norm``,
    ``elapsed`` (cells or decisions of the episode so far), ``last_act`` and the known distances ``dist`` give the
    emotion (``affect.feel``; -1 for the other kinds) and the new ``last_act``. UCB's counts are updated here, as
    ``UCBQLearning._decide`` does.
    """
    q, mt, tw = state.q, state.mt, work.tw
    beh_n, beh_speeds = behaviour.n, behaviour.speeds
    n_actions = q.shape[1]
    kind = config.kind
    explored = False
    emotion = -1
    if kind == AFFECT:
        emotion, last_act = feel(norm, elapsed, dist, s, last_act, config.act_episode, config.valence)
        ns = beh_n[emotion]
        if ns == 1:
            k = beh_speeds[emotion, 0]
        else:
            pick, r = draw_below(mt, tw, r, ns, 32 - bit_length(ns))
            k = beh_speeds[emotion, pick]
        if behaviour.random[emotion]:
            action, r = draw_below(mt, tw, r, n_actions, action_shift(n_actions))
            explored = True
        else:
            action, r = greedy(q, s, mt, tw, r, config.tie_first)
    elif kind == EPSILON:
        ns = beh_n[0]
        if ns == 1:
            k = beh_speeds[0, 0]
        else:
            pick, r = draw_below(mt, tw, r, ns, 32 - bit_length(ns))
            k = beh_speeds[0, pick]
        u, r = draw01(mt, tw, r)
        if u < p:
            action, r = draw_below(mt, tw, r, n_actions, action_shift(n_actions))
            explored = True
        else:
            action, r = greedy(q, s, mt, tw, r, config.tie_first)
    elif kind == BOLTZMANN:
        k = 1
        u, r = draw01(mt, tw, r)
        action = softmax_action(q, s, p, u, config.compensated_sum, work.work)
        explored = q[s, action] != row_max(q, s)
    else:
        ucb_n, ucb_tot = state.ucb_n, state.ucb_tot
        k = 1
        action, r = ucb_action(q, s, ucb_n, ucb_tot[s], config.ucb_coef, mt, tw, r, work.work)
        ucb_n[s, action] += 1
        ucb_tot[s] += 1
        explored = q[s, action] != row_max(q, s)
    return action, k, explored, emotion, last_act, r


@kernel_inline
def end_episode(
    agent, row, frow, ist, fst, fit_vals, decisions, cells, terminated, random_moves, waits, reward_sum, norm, elapsed
):
    """
    A single agent's episode ends (the grid's and moving prey's loops): its row (``row``: ints, ``frow``: floats; each
    emotion's count moves from ``ist`` into the row), then for AffectQ the episode's ``elapsed`` cells or decisions
    into its power fit. Returns the next episode's norm (``norm`` itself for the other kinds).
    """
    row[O_DECISIONS] = decisions
    row[O_CELLS] = cells
    row[O_TRUNCATED] = 0 if terminated else 1
    row[O_RANDOM] = random_moves
    row[O_WAITS] = waits
    for e in range(4):
        row[O_JOY + e] = ist[I_JOY + e]
        ist[I_JOY + e] = 0
    frow[F_REWARD] = reward_sum
    frow[F_NORM] = norm if agent.kind == AFFECT else math.nan
    if agent.kind != AFFECT:
        return norm
    fsum = fst[S_FIT0 : S_FIT0 + 4]
    ist[I_NFIT] = fit_add(fit_vals, fsum, ist[I_NFIT], float(elapsed))
    return start_norm(fit_vals, fsum, ist[I_NFIT], agent.norm_scale)


@kernel_inline
def last_decision(ist, fst, action, prev, s2, terminated, reward):
    """The last decision of the episode that just ended, kept for its callbacks (``I_LAST_*``, ``S_LAST_REWARD``)."""
    ist[I_LAST_ACTION] = action
    ist[I_LAST_PREV] = prev
    ist[I_LAST_S2] = s2
    ist[I_LAST_TERMINATED] = 1 if terminated else 0
    fst[S_LAST_REWARD] = reward


@kernel_jit
def obs_known_add(
    dist: np.ndarray,
    succ: np.ndarray,
    succ_n: np.ndarray,
    pred: np.ndarray,
    pred_n: np.ndarray,
    s: int,
    s2: int,
    queue: np.ndarray,
) -> None:
    """
    ``KnownMap.add(s, s2)`` on a known map whose transitions are not a fixed table (observations of a moving prey,
    of other hunters): ``succ[s, :succ_n[s]]`` the successors seen from ``s``, ``pred[v, :pred_n[v]]`` the
    predecessors of ``v`` in the order they were added, ``dist`` the shortest known distances.
    """
    if s == s2:
        return
    for j in range(succ_n[s]):
        if succ[s, j] == s2:
            return
    succ[s, succ_n[s]] = s2
    succ_n[s] += 1
    pred[s2, pred_n[s2]] = s
    pred_n[s2] += 1
    if dist[s2] + 1 < dist[s]:
        dist[s] = dist[s2] + 1
        propagate(dist, pred, pred_n, s, queue)


def known_widths(cell_trans: np.ndarray, prey_moves: bool) -> tuple[int, int]:
    """
    The most successors and predecessors an observation of a hunter and (``prey_moves``) a prey can have, from the
    cells' one-move table: what ``obs_known_add``'s ``succ`` and ``pred`` need per row.
    """
    n = cell_trans.shape[0]
    hunter_next = [set(cell_trans[c].tolist()) for c in range(n)]
    prey_next = [({c} | set(cell_trans[c].tolist())) if prey_moves else {c} for c in range(n)]
    into_h = np.zeros(n, dtype=np.int64)
    into_p = np.zeros(n, dtype=np.int64)
    for c in range(n):
        for t in hunter_next[c]:
            into_h[t] += 1
        for t in prey_next[c]:
            into_p[t] += 1
    succ = max(len(h) for h in hunter_next) * max(len(p) for p in prey_next)
    pred = int(into_h.max()) * int(into_p.max())
    return succ, pred
