"""
The affective appraisal in numba: the known map, the power fit, ``exp1`` and ``act`` and Table II (``feel``: the
kernel's one copy of them; ``sb3_affect.core.appraisal`` and ``sb3_affect.core.emotions`` are the readable reference;
every operation here is the same, in the same order).

The known map lives in arrays: ``dist[s]`` the shortest known distance (cells) to a reached goal (``inf`` unknown),
``edge[s, a]`` whether the transition ``s -> trans[s, a]`` has been experienced, ``pred[v, :pred_n[v]]`` the cells with an
experienced transition into ``v``, ``goal[s]`` the goals reached. Distances are exact shortest distances over the known
edges after every update (the incremental propagation reaches the same fixed point in any order), so they equal the
Python ``KnownMap``'s. The power fit keeps its points ``fit_vals[:n]`` and the running sums ``fsum = (sx, sy, sxx,
sxy)``, added to in the same order as ``PowerFit.add``.
"""

from __future__ import annotations

import math

import numpy as np

from sb3_affect.kernel.jit import kernel_inline, kernel_jit

JOY, SADNESS, FEAR, ANGER = 0, 1, 2, 3
INF = math.inf


@kernel_jit
def propagate(dist: np.ndarray, pred: np.ndarray, pred_n: np.ndarray, start: int, queue: np.ndarray) -> None:
    """
    A decrease of ``dist[start]`` reaches every cell that can walk into it (``KnownMap._propagate``). The Python
    reference uses a stack, this a FIFO queue: both reach the same fixed point (the shortest known distances), and in
    first-in first-out order each cell decreases at most once, so ``queue`` needs ``n_states + 1`` entries.
    """
    queue[0] = start
    head, tail = 0, 1
    while head < tail:
        v = queue[head]
        head += 1
        dv = dist[v] + 1.0
        for k in range(pred_n[v]):
            u = pred[v, k]
            if dv < dist[u]:
                dist[u] = dv
                queue[tail] = u
                tail += 1


@kernel_jit
def known_add(
    dist: np.ndarray,
    edge: np.ndarray,
    pred: np.ndarray,
    pred_n: np.ndarray,
    trans: np.ndarray,
    s: int,
    a: int,
    s2: int,
    queue: np.ndarray,
) -> None:
    """Record the experienced transition ``s -> s2`` (taken with action ``a``, ``s != s2``): ``KnownMap.add``."""
    if edge[s, a]:
        return
    for b in range(trans.shape[1]):
        if trans[s, b] == s2:
            edge[s, b] = True
    pred[s2, pred_n[s2]] = s
    pred_n[s2] += 1
    if dist[s2] + 1 < dist[s]:
        dist[s] = dist[s2] + 1
        propagate(dist, pred, pred_n, s, queue)


@kernel_jit
def known_add_goal(
    dist: np.ndarray, goal: np.ndarray, pred: np.ndarray, pred_n: np.ndarray, g: int, queue: np.ndarray
) -> None:
    """Record that entering ``g`` ended an episode at the goal: ``KnownMap.add_goal``."""
    if dist[g] > 0:
        goal[g] = True
        dist[g] = 0.0
        propagate(dist, pred, pred_n, g, queue)


@kernel_jit
def fit_add(fit_vals: np.ndarray, fsum: np.ndarray, n: int, y: float) -> int:
    """``PowerFit.add(y)`` on a fit with ``n`` points; returns the new number of points."""
    fit_vals[n] = y
    n += 1
    x = math.log(float(n))
    ly = math.log(max(y, 1e-12))
    fsum[0] += x
    fsum[1] += ly
    fsum[2] += x * x
    fsum[3] += x * ly
    return n


@kernel_jit
def fit_predict(fit_vals: np.ndarray, fsum: np.ndarray, n: int, t: int) -> float:
    """``PowerFit.predict(t)`` on a fit with ``n >= 1`` points."""
    if n == 1:
        return fit_vals[0]
    sx, sy, sxx, sxy = fsum[0], fsum[1], fsum[2], fsum[3]
    denominator = n * sxx - sx * sx
    b = 0.0 if n == 1 or denominator <= 1e-300 else (n * sxy - sx * sy) / denominator
    ln_a = (sy - b * sx) / n
    a = math.exp(ln_a)
    value = a * math.exp(b * math.log(float(t))) if t > 0 else a
    return value if math.isfinite(value) else 1e300


@kernel_inline
def table_ii(norm: float, exp1: float, act: float, valence: bool) -> int:
    """Table II, first match wins (``sb3_affect.core.emotions.table_ii``)."""
    if valence:
        norm, exp1, act = -norm, -exp1, -act
    if exp1 < norm:
        return FEAR
    if act < norm:
        return ANGER if exp1 > act else SADNESS
    return JOY


@kernel_inline
def feel(
    norm: float, elapsed: int, dist: np.ndarray, s: int, last_act: float, act_episode: bool, valence: bool
) -> tuple[int, float]:
    """
    The emotion before a decision: ``Appraiser.appraise`` and Table II (``table_ii``), the kernel's one copy of both.

    ``norm`` is the episode's norm (NaN before the first finished episode: joy), ``elapsed`` the cells or decisions
    of the episode so far, ``dist[s]`` the known distance to a goal from the current state ``s`` (``inf`` unknown:
    ``act`` keeps its last value ``last_act``). ``exp1 = max(norm, elapsed)``; ``act = elapsed + dist[s]`` (``act_episode``)
    or ``dist[s]``. Returns ``(emotion, act)``.
    """
    emotion = JOY
    if norm == norm:
        remaining = dist[s]
        if remaining != INF:
            last_act = elapsed + remaining if act_episode else remaining
        exp1 = norm if norm > elapsed else float(elapsed)
        emotion = table_ii(norm, exp1, last_act, valence)
    return emotion, last_act


@kernel_jit
def start_norm(fit_vals: np.ndarray, fsum: np.ndarray, n: int, norm_scale: float) -> float:
    """The norm of an episode that starts after ``n`` finished ones (``Appraiser.start_episode``, personality bias)."""
    norm = fit_predict(fit_vals, fsum, n, n + 1) if n else math.nan
    return norm * norm_scale
