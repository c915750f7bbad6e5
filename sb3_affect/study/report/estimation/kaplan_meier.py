"""
The interquartile mean of censored values: the IQM of the Kaplan-Meier distribution, with a seeded percentile
bootstrap over runs. A run that never found the optimal path counts at its total, a value the path would have come
after; Kaplan-Meier treats it as censored there instead of as an event. The IQM is then twice the integral of the
estimated quantile function from 0.25 to 0.75, which is known only when the curve's distribution function reaches 0.75
before the last value: with more than a quarter of the runs censored above every event it is not estimable.
Without censoring it is the 25%-trimmed mean (``bootstrap.iqm``) whenever the number of values is a multiple of 4.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

#: The interquartile window of the distribution function.
LOW, HIGH = 0.25, 0.75


def _sorted(values: npt.ArrayLike, censored: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """The values by size, an event before a censored value of the same size (Kaplan-Meier's convention for ties)."""
    data, flags = np.asarray(values, dtype=float), np.asarray(censored, dtype=bool)
    order = np.lexsort((flags, data))
    return data[order], flags[order]


def _iqm_of_weights(data: np.ndarray, flags: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """
    The Kaplan-Meier IQM of ``data`` (sorted, with ``flags`` the censored ones) for each row of ``weights`` (how often
    each value is drawn: one row per resample); NaN where the distribution function stays below ``HIGH``.

    The values are taken one at a time in order: an event of weight w with r at risk multiplies the survival by
    1 - w / r (several events at one time so give Kaplan-Meier's 1 - d / r), a censored value only leaves the risk set.
    """
    at_risk = np.cumsum(weights[:, ::-1], axis=1)[:, ::-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.where(~flags & (at_risk > 0), 1 - weights / np.where(at_risk > 0, at_risk, 1), 1.0)
    cdf = 1 - np.cumprod(factor, axis=1)
    before = np.concatenate([np.zeros((len(weights), 1)), cdf[:, :-1]], axis=1)
    share = np.clip(cdf, LOW, HIGH) - np.clip(before, LOW, HIGH)
    means = (share * data).sum(axis=1) / (HIGH - LOW)
    return np.where(cdf[:, -1] >= HIGH - 1e-12, means, np.nan)


def km_iqm(values: npt.ArrayLike, censored: npt.ArrayLike) -> float:
    """The interquartile mean of the Kaplan-Meier distribution of ``values`` (``censored``: lower bounds); NaN if unknown."""
    data, flags = _sorted(values, censored)
    if not len(data):
        return math.nan
    return float(_iqm_of_weights(data, flags, np.ones((1, len(data))))[0])


def bootstrap_km_iqm(
    values: npt.ArrayLike, censored: npt.ArrayLike, n_boot: int = 1000, confidence: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """
    ``(km_iqm, low, high)``: the percentile bootstrap over runs (each resample a multinomial draw of the runs, seeded);
    the interval is NaN when a resample's IQM is not estimable (its share of such resamples would bias it).
    """
    data, flags = _sorted(values, censored)
    point = km_iqm(data, flags)
    if math.isnan(point):
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    block = max(1, 4_000_000 // len(data))
    boots = []
    for first in range(0, n_boot, block):
        weights = rng.multinomial(len(data), np.full(len(data), 1 / len(data)), size=min(block, n_boot - first))
        boots.append(_iqm_of_weights(data, flags, weights.astype(float)))
    every = np.concatenate(boots)
    if np.isnan(every).any():
        return point, math.nan, math.nan
    tail = (1 - confidence) / 2 * 100
    return point, float(np.percentile(every, tail)), float(np.percentile(every, 100 - tail))
