"""
The verdict's statistics: estimates with 95% CIs, Welch tests paired with Welch intervals, the equivalence test
(TOST), the predictive interval of a statistic at the paper's seed count, and Holm's correction within one family.

Everything is analytic (scipy.stats, statsmodels), so a verdict is cheap enough to repeat on hundreds of subsamples.
"""

from __future__ import annotations

import gc
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats as sps
from statsmodels.stats.multitest import multipletests

from sb3_affect.study.report.rendering.document import sig

ALPHA = 0.05
Z = float(sps.norm.ppf(0.975))


@dataclass(frozen=True)
class Estimate:
    """A point estimate with its 95% CI and standard error (``se`` NaN when it has none)."""

    value: float
    low: float
    high: float
    se: float = math.nan

    def text(self, digits: int = 3) -> str:

        return f"{sig(self.value, digits)} [{sig(self.low, digits)}, {sig(self.high, digits)}]"

    def scaled(self, factor: float) -> Estimate:
        return Estimate(self.value * factor, self.low * factor, self.high * factor, self.se * abs(factor))


@dataclass
class Test:
    """One hypothesis test: its name, raw p-value and Holm-adjusted p-value within its claim's family."""

    name: str
    p: float
    p_holm: float = math.nan


def mean_ci(x: np.ndarray) -> Estimate:
    """Mean with its t interval (runs independent)."""
    x = np.asarray(x, dtype=float)
    x = x[~np.isnan(x)]
    if len(x) < 2:
        value = float(x.mean()) if len(x) else math.nan
        return Estimate(value, math.nan, math.nan)
    se = float(x.std(ddof=1)) / math.sqrt(len(x))
    if se == 0:
        return Estimate(float(x.mean()), float(x.mean()), float(x.mean()), 0.0)
    half = float(sps.t.ppf(0.975, len(x) - 1)) * se
    return Estimate(float(x.mean()), float(x.mean()) - half, float(x.mean()) + half, se)


def welch(a: np.ndarray, b: np.ndarray) -> tuple[Estimate, float]:
    """Mean of ``a`` minus mean of ``b`` with the Welch 95% CI, and the Welch t-test's two-sided p-value (one method)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    d = float(a.mean() - b.mean())
    if len(a) < 2 or len(b) < 2:
        return Estimate(d, math.nan, math.nan), math.nan
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    if va + vb == 0:
        return Estimate(d, d, d, 0.0), (1.0 if d == 0 else 0.0)
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))  # Welch-Satterthwaite
    se = math.sqrt(va + vb)
    half = float(sps.t.ppf(0.975, df)) * se
    p = float(2 * sps.t.sf(abs(d) / se, df))
    return Estimate(d, d - half, d + half, se), p


def z_estimate(value: float, se: float) -> Estimate:
    """A normal 95% CI."""
    return Estimate(value, value - Z * se, value + Z * se, se)


def two_sided_p(est: Estimate) -> float:
    """The z-test of ``est`` against 0."""
    if not est.se > 0:
        return 1.0 if est.value == 0 else 0.0
    return float(2 * sps.norm.sf(abs(est.value) / est.se))


def tost(est: Estimate, margin: float) -> float:
    """
    The equivalence test: two one-sided z-tests of ``est`` against ``-margin`` and ``+margin`` (Schuirmann's TOST);
    its p-value is the larger of the two. Small: the difference lies within ±margin.
    """
    if not est.se > 0:
        return 0.0 if abs(est.value) < margin else 1.0
    lower = float(sps.norm.sf((est.value + margin) / est.se))  # H0: d <= -margin
    upper = float(sps.norm.cdf((est.value - margin) / est.se))  # H0: d >= +margin
    return max(lower, upper)


def predictive(est: Estimate, n_ours: int, n_paper: int) -> tuple[float, float]:
    """
    The 95% predictive interval of the same statistic computed from ``n_paper`` seeds per cell (the paper's protocol):
    our estimate's uncertainty plus the paper's own sampling noise, whose variance is ours times ``n_ours / n_paper``.
    """
    if not est.se >= 0 or n_paper < 1:
        return math.nan, math.nan
    half = Z * est.se * math.sqrt(1 + n_ours / n_paper)
    return est.value - half, est.value + half


def holm(tests: Sequence[Test]) -> None:
    """Holm's step-down correction over ``tests`` (one family; in place)."""
    if not tests:
        return
    pvalues = np.array([t.p if not math.isnan(t.p) else 1.0 for t in tests])
    gc.freeze()  # statsmodels' Holm branch calls gc.collect(): keep it from scanning the whole heap each time
    try:
        adjusted = multipletests(pvalues, alpha=ALPHA, method="holm")[1]
    finally:
        gc.unfreeze()
    for t, p in zip(tests, adjusted):
        t.p_holm = float(p)


def significant(test: Test) -> bool:
    return bool(test.p_holm < ALPHA)
