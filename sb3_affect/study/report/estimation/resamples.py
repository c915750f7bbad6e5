"""
The bootstraps' resamples (in the narrowest integer type) and their statistics computed in compiled loops.

Every bootstrap of ``bootstrap`` seeds its own generator, so its draws are those of the generator, in its order.
The compiled statistics do the floating-point operations of the numpy code they replace in the same order (integer
sums are exact in any order), so the numbers are the same to the last bit (tests/study/report/test_report_lean.py compares them
with that code).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit

#: Resamples of at most this many entries in all are drawn whole (in the narrowest integer type); more, in blocks.
WHOLE_CELLS = 20_000_000
#: Resamples drawn at a time in blocks (memory: 8 bytes an index).
BLOCK_CELLS = 4_000_000


def _wide_enough(counts: np.ndarray, largest: int) -> np.ndarray:
    return counts if largest <= np.iinfo(counts.dtype).max else counts.astype(np.int64)


def _narrow(n: int) -> type:
    return np.int16 if n <= np.iinfo(np.int16).max else np.int32


def mean_indices(n: int, n_boot: int, seed: int) -> np.ndarray:
    """The indices of ``n_boot`` resamples of ``n`` values, one row each, as ``rng.integers(0, n, n)`` draws them."""

    def make() -> np.ndarray:
        rng = np.random.default_rng(seed)
        out: np.ndarray = np.empty((n_boot, n), _narrow(n))
        block = max(1, BLOCK_CELLS // max(1, n))
        for first in range(0, n_boot, block):
            out[first : first + block] = rng.integers(0, n, size=(min(block, n_boot - first), n))
        return out

    return make()


@njit(cache=True, nogil=True)
def count_draws(draws: np.ndarray, out: np.ndarray) -> None:
    """Add to ``out[rep]`` how often each value is drawn in ``draws[rep]`` (``bincount`` of each row)."""
    for rep in range(draws.shape[0]):
        for j in range(draws.shape[1]):
            out[rep, draws[rep, j]] += 1


def iqm_resamples(values: np.ndarray, order: np.ndarray, n_boot: int, seed: int) -> np.ndarray:
    """
    The IQM of ``n_boot`` resamples of ``values`` (sorted; ``order`` their sort of the sample), each resample drawn as
    ``rng.integers(0, n, n)`` from one generator seeded ``seed``: ``stats._iqm_resamples``' numbers.
    """
    return iqm_resamples_of([values], [order], n_boot, seed)[0]


def iqm_resamples_of(samples: Sequence[np.ndarray], orders: Sequence[np.ndarray], n_boot: int, seed: int) -> list[np.ndarray]:
    """``iqm_resamples`` of several samples of one size (sorted, with their sorts), from one set of draws."""
    n = len(samples[0])
    low = int(0.25 * n)  # as scipy.stats.trim_mean cuts
    high = n - low
    every = [np.empty(n_boot) for _ in samples]
    block = max(1, BLOCK_CELLS // max(1, n))

    def drawn(rng: np.random.Generator, first: int) -> np.ndarray:
        out = np.zeros((min(block, n_boot - first), n), np.int32)
        count_draws(rng.integers(0, n, size=out.shape), out)
        return out

    def make() -> np.ndarray:  # counted straight into narrow rows, a block of draws at a time
        rng = np.random.default_rng(seed)
        out: np.ndarray = np.zeros((n_boot, n), _narrow(n))
        for first in range(0, n_boot, block):
            count_draws(rng.integers(0, n, size=(min(block, n_boot - first), n)), out[first : first + block])
        return out

    if n * n_boot <= WHOLE_CELLS:
        counts = make()
        for values, order, boots in zip(samples, orders, every):
            iqm_of_counts(counts, order, values, low, high, boots)
        return every
    rng = np.random.default_rng(seed)
    for first in range(0, n_boot, block):  # too many to draw whole: a block at a time
        part = drawn(rng, first)
        for values, order, boots in zip(samples, orders, every):
            iqm_of_counts(part, order, values, low, high, boots[first : first + len(part)])
    return every


def improvement_resamples(
    n_a: int,
    n_b: int,
    n_boot: int,
    seed: int,
    comparisons: tuple[np.ndarray, np.ndarray, np.ndarray],
    lower_is_better: bool,
) -> np.ndarray:
    """
    The probability of improvement of ``n_boot`` resamples (each draws ``n_a`` of X, then ``n_b`` of Y, from one
    generator seeded ``seed``), from ``stats._comparisons(X, Y)``: ``stats.bootstrap_improvement``'s numbers.
    """
    below, not_above, order = comparisons
    boots = np.empty(n_boot)

    def one(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        a = np.bincount(rng.integers(0, n_a, n_a), minlength=n_a)
        return a, np.bincount(rng.integers(0, n_b, n_b), minlength=n_b)

    def make() -> tuple[np.ndarray, np.ndarray]:
        rng = np.random.default_rng(seed)
        a, b = np.zeros((n_boot, n_a), np.uint8), np.zeros((n_boot, n_b), np.uint8)  # a value drawn 256 times: wider
        for rep in range(n_boot):
            row_a, row_b = one(rng)
            a, b = _wide_enough(a, int(row_a.max())), _wide_enough(b, int(row_b.max()))
            a[rep], b[rep] = row_a, row_b
        return a, b

    args = (order, below, not_above, lower_is_better, n_a * n_b)
    if (n_a + n_b) * n_boot <= WHOLE_CELLS:
        weights, drawn = make()
        improvement_of_counts(weights, drawn, *args, boots)
        return boots
    rng = np.random.default_rng(seed)
    for rep in range(n_boot):  # too many to draw whole: one resample at a time
        a, b = one(rng)
        improvement_of_counts(a[None], b[None], *args, boots[rep : rep + 1])
    return boots


@njit(cache=True, nogil=True)
def iqm_of_counts(counts: np.ndarray, order: np.ndarray, values: np.ndarray, low: int, high: int, out: np.ndarray) -> None:
    """
    The IQM of each resample (a row of ``counts``), as ``stats._iqm_resamples`` computes it: ``values`` sorted,
    ``order`` the sort, the middle half the positions ``low .. high - 1`` of the resample sorted.
    """
    for rep in range(counts.shape[0]):
        end = 0
        first, last = -1, -1
        end_first, end_last, drawn_last = 0, 0, 0
        acc, at_first, before_last = 0.0, 0.0, 0.0
        for i in range(len(order)):
            drawn = int(counts[rep, order[i]])
            end += drawn
            previous = acc
            acc = values[i] * drawn if i == 0 else acc + values[i] * drawn  # the running sum of numpy's cumsum
            if first < 0 and end > low:
                first, end_first, at_first = i, end, acc
            if end >= high:
                last, end_last, drawn_last, before_last = i, end, drawn, previous
                break
        if first == last:
            total = values[first] * (high - low)
        else:
            middle = before_last - at_first
            total = values[first] * (end_first - low) + middle + values[last] * (high - end_last + drawn_last)
        out[rep] = total / (high - low)


@njit(cache=True, nogil=True)
def improvement_of_counts(
    weights: np.ndarray,
    drawn: np.ndarray,
    order: np.ndarray,
    below: np.ndarray,
    not_above: np.ndarray,
    lower_is_better: bool,
    pairs: int,
    out: np.ndarray,
) -> None:
    """
    The probability of improvement of each resample, as ``stats.bootstrap_improvement`` computes it: ``weights`` the
    draw counts of X's values, ``drawn`` those of Y's, ``order`` Y's sort, ``below`` / ``not_above`` where each X value
    falls in Y sorted (integer sums: exact).
    """
    n_b = drawn.shape[1]
    cumulative = np.zeros(n_b + 1, np.int64)
    for rep in range(weights.shape[0]):
        for j in range(n_b):
            cumulative[j + 1] = cumulative[j] + drawn[rep, order[j]]
        better, ties = 0, 0
        for i in range(len(below)):
            w = np.int64(weights[rep, i])
            if w == 0:
                continue
            at_most, under = cumulative[not_above[i]], cumulative[below[i]]
            better += w * ((n_b - at_most) if lower_is_better else under)
            ties += w * (at_most - under)
        out[rep] = (float(better) + 0.5 * float(ties)) / pairs


@njit(cache=True, nogil=True)
def _block_sum(data: np.ndarray, index: np.ndarray, lo: int, n: int) -> float:
    """numpy's pairwise sum of a block of at most 128 values: eight running sums, then the rest one by one."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += data[index[i]]
        return res
    r0, r1, r2, r3 = data[index[lo]], data[index[lo + 1]], data[index[lo + 2]], data[index[lo + 3]]
    r4, r5, r6, r7 = data[index[lo + 4]], data[index[lo + 5]], data[index[lo + 6]], data[index[lo + 7]]
    i = 8
    while i < n - (n % 8):
        j = lo + i
        r0 += data[index[j]]
        r1 += data[index[j + 1]]
        r2 += data[index[j + 2]]
        r3 += data[index[j + 3]]
        r4 += data[index[j + 4]]
        r5 += data[index[j + 5]]
        r6 += data[index[j + 6]]
        r7 += data[index[j + 7]]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += data[index[lo + i]]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _means(data: np.ndarray, indices: np.ndarray, out: np.ndarray) -> None:
    """
    ``data[indices].mean(axis=1)`` with numpy's pairwise sum (``pairwise_sum_DOUBLE``): a run of more than 128 values
    is the sum of its halves (the first half's length a multiple of 8), added as numpy adds them. Without recursion
    (numba's cached code and recursion do not mix): the halves on a stack, their sums on another.
    """
    n = indices.shape[1]
    los, sizes, pending = np.empty(256, np.int64), np.empty(256, np.int64), np.empty(256, np.int64)
    sums = np.empty(256)
    for rep in range(indices.shape[0]):
        index = indices[rep]
        top, filled = 0, 0
        los[0], sizes[0], pending[0] = 0, n, 0
        top = 1
        while top:
            top -= 1
            lo, size, state = los[top], sizes[top], pending[top]
            if state == 1:  # both halves summed: left + right
                filled -= 1
                sums[filled - 1] = sums[filled - 1] + sums[filled]
            elif size <= 128:
                sums[filled] = _block_sum(data, index, lo, size)
                filled += 1
            else:
                half = size // 2
                half -= half % 8
                los[top], sizes[top], pending[top] = lo, size, 1  # then add them
                los[top + 1], sizes[top + 1], pending[top + 1] = lo + half, size - half, 0  # the right half second
                los[top + 2], sizes[top + 2], pending[top + 2] = lo, half, 0  # the left half first
                top += 3
        out[rep] = (0.0 + sums[0]) / n


def resample_means(data: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """``data[indices].mean(axis=1)`` to the last bit (numpy's summation order), without the gathered matrix."""
    out = np.empty(len(indices))
    _means(np.ascontiguousarray(data, np.float64), indices, out)
    return out
