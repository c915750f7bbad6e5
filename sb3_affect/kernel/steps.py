"""
The pieces of a decision that the kernels of moving prey (``kernel.moving``) and of hunter teams (``kernel.team``)
share: the choice of direction and speed of every agent kind (``decide``) and the known map over observations
(``obs_known_add``), each doing the same operations, with the same random draws in the same order, as its Python
reference (``_decide`` of each agent class, ``appraisal.KnownMap.add``). Eq. 1 is the decision loop's own
``q_update`` (``kernel.loop``), re-exported here.
"""

from __future__ import annotations

import math

import numpy as np

from sb3_affect.kernel.affect import propagate, table_ii
from sb3_affect.kernel.arrays import AFFECT, BOLTZMANN, EPSILON
from sb3_affect.kernel.choice import greedy, row_max, softmax_action, ucb_action
from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.loop import q_update
from sb3_affect.kernel.mt19937 import bit_length, draw01, draw_below

__all__ = ["AFFECT", "decide", "known_widths", "obs_known_add", "q_update"]


@kernel_inline
def decide(
    kind, q, s, mt, tw, r, tie_first, beh_rand, beh_speeds, beh_n, p, compensated, ucb_n, ucb_tot, ucb_coef, work,
    norm, elapsed, last_act, remaining, act_episode, valence,
):  # fmt: skip
    """
    One decision of an agent of ``kind`` in state ``s``: ``(action, cells, explored, emotion, last_act, r)``.

    ``r`` is the random stream's index (``mt19937.draw``); ``p`` epsilon or the inverse temperature. For AffectQ the
    appraisal's ``norm``, ``elapsed`` (cells or decisions of the episode so far), ``last_act`` and the known distance
    ``remaining`` of ``s`` give the emotion (Table II; -1 for the other kinds) and the new ``last_act``. UCB's counts
    are updated here, as ``UCBQLearning._decide`` does.
    """
    n_actions = q.shape[1]
    explored = False
    emotion = -1
    if kind == AFFECT:
        emotion = 0
        if norm == norm:
            if remaining != math.inf:
                last_act = elapsed + remaining if act_episode else remaining
            exp1 = norm if norm > elapsed else float(elapsed)
            emotion = table_ii(norm, exp1, last_act, valence)
        ns = beh_n[emotion]
        if ns == 1:
            k = beh_speeds[emotion, 0]
        else:
            pick, r = draw_below(mt, tw, r, ns, 32 - bit_length(ns))
            k = beh_speeds[emotion, pick]
        if beh_rand[emotion]:
            action, r = draw_below(mt, tw, r, n_actions, 32 - bit_length(n_actions))
            explored = True
        else:
            action, r = greedy(q, s, mt, tw, r, tie_first)
    elif kind == EPSILON:
        ns = beh_n[0]
        if ns == 1:
            k = beh_speeds[0, 0]
        else:
            pick, r = draw_below(mt, tw, r, ns, 32 - bit_length(ns))
            k = beh_speeds[0, pick]
        u, r = draw01(mt, tw, r)
        if u < p:
            action, r = draw_below(mt, tw, r, n_actions, 32 - bit_length(n_actions))
            explored = True
        else:
            action, r = greedy(q, s, mt, tw, r, tie_first)
    elif kind == BOLTZMANN:
        k = 1
        u, r = draw01(mt, tw, r)
        action = softmax_action(q, s, p, u, compensated, work)
        explored = q[s, action] != row_max(q, s)
    else:
        k = 1
        action, r = ucb_action(q, s, ucb_n, ucb_tot[s], ucb_coef, mt, tw, r, work)
        ucb_n[s, action] += 1
        ucb_tot[s] += 1
        explored = q[s, action] != row_max(q, s)
    return action, k, explored, emotion, last_act, r


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
