"""
How the compiled loop picks an action in a state: the row maximum of the Q-table, the greedy choice with ties drawn
at random (``policies.greedy_action``), the Boltzmann choice (``baselines.boltzmann.softmax_action``) and the UCB
choice (``UCBQLearning._decide``). Each does the same operations, and draws the same random numbers in the same order,
as its Python reference. ``i`` is the random stream's index and ``tw`` its tempered words (``mt19937.draw``); the
functions that draw return ``(action, i)``.
"""

from __future__ import annotations

import math

import numpy as np

from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.mt19937 import bit_length, draw_below


@kernel_inline
def row_max_n(q: np.ndarray, s: int, n: int) -> float:
    """``max(q[s])`` for a row of ``n`` actions."""
    best = q[s, 0]
    for a in range(1, n):
        v = q[s, a]
        if v > best:
            best = v
    return best


@kernel_inline
def row_max(q: np.ndarray, s: int) -> float:
    """``max(q[s])``; four actions (the grids') with a constant count, so that the compiler unrolls the loop."""
    if q.shape[1] == 4:
        return row_max_n(q, s, 4)
    return row_max_n(q, s, q.shape[1])


@kernel_inline
def greedy_n(q: np.ndarray, s: int, n: int, mt: np.ndarray, tw: np.ndarray, i: int, tie_first: bool) -> tuple[int, int]:
    """``greedy`` for a row of ``n`` actions."""
    best = row_max_n(q, s, n)
    count = 0
    first = n
    for a in range(n - 1, -1, -1):  # (no branches: the count of ties and the first of them)
        tie = q[s, a] == best
        count += tie
        first = a if tie else first
    if count == 1 or tie_first:
        return first, i
    pick, i = draw_below(mt, tw, i, count, 32 - bit_length(count))
    for a in range(first, n):
        if q[s, a] == best:
            if pick == 0:
                return a, i
            pick -= 1
    return first, i


#: four actions: for the mask of the maximal ones (bit ``a``: action ``a``), their number, the ``j``-th of them and the
#: shift of ``randbelow`` of their number (``32 - n.bit_length()``)
TIE_COUNT = np.array([bin(m).count("1") for m in range(16)], dtype=np.int64)
TIE_PICK = np.array([([a for a in range(4) if m >> a & 1] + [0] * 4)[:4] for m in range(16)], dtype=np.int64)
TIE_SHIFT = np.array([32 - n.bit_length() for n in range(5)], dtype=np.int64)


@kernel_inline
def greedy4(q: np.ndarray, s: int, mt: np.ndarray, tw: np.ndarray, i: int, tie_first: bool) -> tuple[int, int]:
    """``greedy`` for a row of four actions: the maximal ones as a mask, the choice among them by table."""
    q0, q1, q2, q3 = q[s, 0], q[s, 1], q[s, 2], q[s, 3]
    best = row_max_n(q, s, 4)
    mask = (1 if q0 == best else 0) | (2 if q1 == best else 0) | (4 if q2 == best else 0) | (8 if q3 == best else 0)
    count = TIE_COUNT[mask]
    if count == 1 or tie_first:
        return TIE_PICK[mask, 0], i
    pick, i = draw_below(mt, tw, i, count, TIE_SHIFT[count])
    return TIE_PICK[mask, pick], i


@kernel_inline
def greedy(q: np.ndarray, s: int, mt: np.ndarray, tw: np.ndarray, i: int, tie_first: bool) -> tuple[int, int]:
    """
    ``policies.greedy_action`` on ``q[s]``: arg-max, ties uniformly at random (one ``choice`` draw) or the first.
    ``i`` is the random stream's index and ``tw`` its tempered words (``mt19937.draw``); returns ``(action, i)``.
    Four actions (the grids') with a constant count, so that the compiler unrolls the loops.
    """
    if q.shape[1] == 4:
        return greedy4(q, s, mt, tw, i, tie_first)
    return greedy_n(q, s, q.shape[1], mt, tw, i, tie_first)


@kernel_jit
def softmax_action(q: np.ndarray, s: int, inv_temperature: float, u: float, compensated: bool, weights: np.ndarray) -> int:
    """``baselines.boltzmann.softmax_action`` on ``q[s]``; ``compensated``: ``sum`` is Neumaier's (Python >= 3.12)."""
    best = row_max(q, s)
    n = q.shape[1]
    for a in range(n):
        weights[a] = math.exp((q[s, a] - best) * inv_temperature)
    total = weights[0]
    c = 0.0
    for a in range(1, n):
        w = weights[a]
        if compensated:
            t = total + w
            if abs(total) >= abs(w):
                c += (total - t) + w
            else:
                c += (w - t) + total
            total = t
        else:
            total += w
    if c != 0.0 and math.isfinite(c):
        total += c
    x = u * total
    last = 0
    for a in range(n):
        w = weights[a]
        if w > 0.0:
            last = a
            x -= w
            if x < 0.0:
                return a
    return last


@kernel_jit
def ucb_action(
    q: np.ndarray,
    s: int,
    counts: np.ndarray,
    total: int,
    coef: float,
    mt: np.ndarray,
    tw: np.ndarray,
    i: int,
    scores: np.ndarray,
) -> tuple[int, int]:
    """``UCBQLearning._decide``'s choice in ``s`` (the caller updates the counts); returns ``(action, i)`` (see ``greedy``)."""
    n = q.shape[1]
    untried = 0
    for a in range(n):
        if counts[s, a] == 0:
            untried += 1
    if untried > 0:
        pick = 0
        if untried > 1:
            pick, i = draw_below(mt, tw, i, untried, 32 - bit_length(untried))
        for a in range(n):
            if counts[s, a] == 0:
                if pick == 0:
                    return a, i
                pick -= 1
    c = coef * math.sqrt(math.log(float(total)))
    for a in range(n):
        scores[a] = q[s, a] + c / math.sqrt(float(counts[s, a]))
    best = scores[0]
    for a in range(1, n):
        if scores[a] > best:
            best = scores[a]
    ties = 0
    for a in range(n):
        if scores[a] == best:
            ties += 1
    pick = 0
    if ties > 1:
        pick, i = draw_below(mt, tw, i, ties, 32 - bit_length(ties))
    for a in range(n):
        if scores[a] == best:
            if pick == 0:
                return a, i
            pick -= 1
    return 0, i


@kernel_inline
def insert_tie(ties: np.ndarray, count: int, c: int) -> int:
    """Insert ``c`` into the sorted, distinct ties ``ties[:count]`` (the evading prey's candidates); returns their count."""
    at = count
    for i in range(count):
        if ties[i] == c:
            return count
        if ties[i] > c:
            at = i
            break
    for i in range(count, at, -1):
        ties[i] = ties[i - 1]
    ties[at] = c
    return count + 1
