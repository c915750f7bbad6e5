"""Statistics of the report: the spreadsheet paired t-test of Tables IV and V, and rliable-style bootstrap summaries."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import stats as sps

#: Row labels of a spreadsheet "t-Test: Paired Two Sample for Means", in its order.
TTEST_ROWS: tuple[str, ...] = (
    "Mean",
    "Variance",
    "Observations",
    "Pearson Correlation",
    "Hypothesized Mean Difference",
    "df",
    "t Stat",
    "P(T<=t) one-tail",
    "t Critical one-tail",
    "P(T<=t) two-tail",
    "t Critical two-tail",
)


def paired_ttest_table(a: npt.ArrayLike, b: npt.ArrayLike, alpha: float = 0.05) -> pd.DataFrame:
    """
    The spreadsheet's "t-Test: Paired Two Sample for Means" of ``a`` (Variable 1) against ``b`` (Variable 2).

    Means and sample variances (n - 1) per variable; the shared rows (Pearson r, hypothesized difference 0, df,
    t Stat of the differences ``a - b``, one- and two-tail p-values of ``|t|`` and the critical values) are in the
    first column, the second left empty, exactly as the spreadsheet lays them out.
    """
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.shape != y.shape or x.ndim != 1 or len(x) < 2:
        raise ValueError(f"a paired t-test needs two equal-length samples of at least 2 values, got {len(x)} and {len(y)}")
    n = len(x)
    d = x - y
    df = n - 1
    sd = d.std(ddof=1)
    t = d.mean() / (sd / math.sqrt(n)) if sd > 0 else math.copysign(math.inf, d.mean()) if d.mean() else math.nan
    p_one = float(sps.t.sf(abs(t), df)) if math.isfinite(t) else (0.0 if math.isinf(t) else math.nan)
    r = float(np.corrcoef(x, y)[0, 1]) if x.std() > 0 and y.std() > 0 else math.nan
    shared = {
        "Pearson Correlation": r,
        "Hypothesized Mean Difference": 0.0,
        "df": float(df),
        "t Stat": float(t),
        "P(T<=t) one-tail": p_one,
        "t Critical one-tail": float(sps.t.ppf(1 - alpha, df)),
        "P(T<=t) two-tail": 2 * p_one,
        "t Critical two-tail": float(sps.t.ppf(1 - alpha / 2, df)),
    }
    rows = {
        "Mean": (x.mean(), y.mean()),
        "Variance": (x.var(ddof=1), y.var(ddof=1)),
        "Observations": (float(n), float(n)),
        **{key: (value, math.nan) for key, value in shared.items()},
    }
    return pd.DataFrame.from_dict(rows, orient="index", columns=["Variable 1", "Variable 2"]).loc[list(TTEST_ROWS)]


def iqm(values: npt.ArrayLike) -> float:
    """Interquartile mean: the mean of the middle 50% (scipy's 25%-trimmed mean, as rliable computes it)."""
    data = np.asarray(values, dtype=float)
    return float(sps.trim_mean(data, 0.25)) if len(data) else math.nan


def probability_of_improvement(x: npt.ArrayLike, y: npt.ArrayLike, lower_is_better: bool = True) -> float:
    """P(X better than Y) + 0.5 P(tie) over all pairs (the Mann-Whitney U statistic divided by n_x n_y)."""
    a, b = np.asarray(x, dtype=float)[:, None], np.asarray(y, dtype=float)[None, :]
    better = (a < b) if lower_is_better else (a > b)
    return float(better.mean() + 0.5 * (a == b).mean())


def bootstrap_ci(
    values: npt.ArrayLike, statistic: str = "mean", n_boot: int = 2000, confidence: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """(point estimate, low, high) of the mean or IQM with a percentile bootstrap over the values (seeded)."""
    data = np.asarray(values, dtype=float)
    data = data[~np.isnan(data)]
    if len(data) == 0:
        return math.nan, math.nan, math.nan
    fn = _statistic(statistic)
    rng = np.random.default_rng(seed)
    samples = data[rng.integers(0, len(data), size=(n_boot, len(data)))]
    boots = sps.trim_mean(samples, 0.25, axis=1) if statistic == "iqm" else samples.mean(axis=1)
    tail = (1 - confidence) / 2 * 100
    return float(fn(data)), float(np.percentile(boots, tail)), float(np.percentile(boots, 100 - tail))


def bootstrap_improvement(
    x: npt.ArrayLike,
    y: npt.ArrayLike,
    n_boot: int = 2000,
    confidence: float = 0.95,
    seed: int = 0,
    lower_is_better: bool = True,
) -> tuple[float, float, float]:
    """Probability of improvement of X over Y with a percentile bootstrap CI (runs of each resampled separately)."""
    a, b = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    a, b = a[~np.isnan(a)], b[~np.isnan(b)]
    if len(a) == 0 or len(b) == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    boots = [
        _improvement_sorted(a[rng.integers(0, len(a), len(a))], np.sort(b[rng.integers(0, len(b), len(b))]), lower_is_better)
        for _ in range(n_boot)
    ]
    tail = (1 - confidence) / 2 * 100
    return (
        probability_of_improvement(a, b, lower_is_better),
        float(np.percentile(boots, tail)),
        float(np.percentile(boots, 100 - tail)),
    )


def _improvement_sorted(a: np.ndarray, b_sorted: np.ndarray, lower_is_better: bool) -> float:
    """``probability_of_improvement`` in O(n log n) with ``b`` sorted (same value, via rank counts)."""
    below = np.searchsorted(b_sorted, a, side="left")  # b values < a
    not_above = np.searchsorted(b_sorted, a, side="right")  # b values <= a
    ties = not_above - below
    better = (len(b_sorted) - not_above) if lower_is_better else below
    return float((better.sum() + 0.5 * ties.sum()) / (len(a) * len(b_sorted)))


def _statistic(name: str) -> Callable[[np.ndarray], float]:
    if name == "mean":
        return lambda data: float(np.mean(data))
    if name == "iqm":
        return iqm
    raise ValueError(f"statistic={name!r} is not supported; use 'mean' or 'iqm'")
