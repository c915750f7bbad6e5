"""
Grouped means, sums and variances with pandas' own arithmetic, compiled (numba), and able to run a part at a time.

pandas' ``groupby(...).mean()`` / ``.sum()`` of floats add each group's values in row order with Kahan's compensated
summation, and ``.var()`` / ``.std()`` / ``.sem()`` use Welford's online update (``pandas/_libs/groupby.pyx``). The
functions here do the same floating-point operations in the same order, so they give the same numbers to the last
bit (test_report_lean.py compares them with pandas), without a hash of the group keys per call and with their
state kept between calls: rows fed part by part, in the order a whole-frame groupby would see them, give the numbers
of that groupby. Missing values (NaN) are skipped, as pandas skips them.

A state is a few arrays with one entry per group (``KahanSums``, ``Welford``); the group of each row is an integer
label (negative: the row is left out).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _kahan_add(values: np.ndarray, labels: np.ndarray, nobs: np.ndarray, sums: np.ndarray, comp: np.ndarray) -> None:
    for i in range(len(values)):
        lab = labels[i]
        if lab < 0:
            continue
        val = values[i]
        if val != val:
            continue
        nobs[lab] += 1
        y = val - comp[lab]
        t = sums[lab] + y
        comp[lab] = t - sums[lab] - y
        if comp[lab] != comp[lab]:  # an infinite value: pandas resets the compensation
            comp[lab] = 0.0
        sums[lab] = t


@njit(cache=True, nogil=True)
def _welford_add(values: np.ndarray, labels: np.ndarray, nobs: np.ndarray, mean: np.ndarray, m2: np.ndarray) -> None:
    for i in range(len(values)):
        lab = labels[i]
        if lab < 0:
            continue
        val = values[i]
        if val != val:
            continue
        nobs[lab] += 1
        oldmean = mean[lab]
        mean[lab] += (val - oldmean) / nobs[lab]
        m2[lab] += (val - mean[lab]) * (val - oldmean)


def _grown(array: np.ndarray, size: int) -> np.ndarray:
    return array if len(array) >= size else np.concatenate([array, np.zeros(size - len(array), array.dtype)])


@dataclass
class KahanSums:
    """Per group: the count of non-missing values and their Kahan sum (pandas' ``sum`` / ``mean`` of floats)."""

    nobs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    sums: np.ndarray = field(default_factory=lambda: np.zeros(0))
    comp: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def add(self, values: np.ndarray, labels: np.ndarray, groups: int) -> None:
        """Add the rows (``values`` float64, ``labels`` their groups, ``groups`` at least max label + 1), in order."""
        self.nobs, self.sums, self.comp = (_grown(a, groups) for a in (self.nobs, self.sums, self.comp))
        _kahan_add(np.ascontiguousarray(values, np.float64), _labels(labels), self.nobs, self.sums, self.comp)

    def mean(self) -> np.ndarray:
        """pandas' ``mean``: the sum over the count (NaN for a group without values)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.nobs > 0, self.sums / self.nobs, np.nan)


@dataclass
class Welford:
    """Per group: count, running mean and sum of squared deviations (pandas' ``var``, ``std`` and ``sem``)."""

    nobs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    mean: np.ndarray = field(default_factory=lambda: np.zeros(0))
    m2: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def add(self, values: np.ndarray, labels: np.ndarray, groups: int) -> None:
        """Add the rows (``values`` float64, ``labels`` their groups, ``groups`` at least max label + 1), in order."""
        self.nobs, self.mean, self.m2 = (_grown(a, groups) for a in (self.nobs, self.mean, self.m2))
        _welford_add(np.ascontiguousarray(values, np.float64), _labels(labels), self.nobs, self.mean, self.m2)

    def std(self, ddof: int = 1) -> np.ndarray:
        """pandas' ``std``: ``sqrt(m2 / (n - ddof))``, NaN for a group of at most ``ddof`` values."""
        count = self.nobs.astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.nobs > ddof, np.sqrt(self.m2 / (count - ddof)), np.nan)

    def sem(self, ddof: int = 1) -> np.ndarray:
        """pandas' ``sem``: ``sqrt(m2 / (n - ddof) / n)``, NaN for a group of at most ``ddof`` values."""
        count = self.nobs.astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.nobs > ddof, np.sqrt(self.m2 / (count - ddof) / count), np.nan)


def _labels(labels: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(labels, np.int64)


@njit(cache=True, nogil=True)
def _window_bounds(
    episode: np.ndarray, starts: np.ndarray, counts: np.ndarray, lo: int, hi: int, first: np.ndarray, last: np.ndarray
) -> None:
    for run in range(len(starts)):
        i, end = starts[run], starts[run] + counts[run]
        while i < end and episode[i] < lo:
            i += 1
        j = i
        while j < end and episode[j] <= hi:
            j += 1
        first[run], last[run] = i, j


def window_bounds(
    episode: np.ndarray, starts: np.ndarray, counts: np.ndarray, lo: int, hi: int
) -> tuple[np.ndarray, np.ndarray]:
    """
    Per run (rows ``starts[r] .. starts[r] + counts[r] - 1``, episodes ascending): the rows ``first .. last - 1`` whose
    episode is within ``lo..hi`` (``first == last``: none).
    """
    first, last = np.empty(len(starts), np.int64), np.empty(len(starts), np.int64)
    _window_bounds(episode, starts.astype(np.int64), counts.astype(np.int64), lo, hi, first, last)
    return first, last


@njit(cache=True, nogil=True)
def _segment_kahan(
    values: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    divisor: np.ndarray,
    use_divisor: bool,
    means: np.ndarray,
    sums: np.ndarray,
) -> None:
    for run in range(len(first)):
        nobs, total, comp = 0, 0.0, 0.0  # pandas' mean of the fractions (or of the values)
        summed, summed_comp = 0.0, 0.0  # pandas' sum of the values
        for i in range(first[run], last[run]):
            x = float(values[i])
            if x == x:
                y = x - summed_comp
                t = summed + y
                summed_comp = t - summed - y
                if summed_comp != summed_comp:
                    summed_comp = 0.0
                summed = t
            if use_divisor:
                if divisor[i] <= 0:
                    continue
                x = x / float(divisor[i])
            if x != x:
                continue
            nobs += 1
            y = x - comp
            t = total + y
            comp = t - total - y
            if comp != comp:
                comp = 0.0
            total = t
        means[run] = total / nobs if nobs > 0 else np.nan
        sums[run] = summed


def segment_means(
    values: np.ndarray, first: np.ndarray, last: np.ndarray, divisor: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """
    Per run, over its rows ``first .. last - 1`` in order: pandas' ``groupby(run).mean()`` of ``values`` (of
    ``values / divisor`` where ``divisor > 0``, when given; NaN: nothing to average) and ``groupby(run).sum()`` of
    ``values`` (0.0: no rows).
    """
    means, sums = np.empty(len(first)), np.empty(len(first))
    none = np.zeros(0, np.int64)
    _segment_kahan(values, first, last, none if divisor is None else divisor, divisor is not None, means, sums)
    return means, sums
