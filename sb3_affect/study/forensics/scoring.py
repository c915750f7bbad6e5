"""
Scoring printed numbers under a candidate: a synthetic likelihood (Wood 2010) of the paper's statistics.

For one candidate, the replications give a sample of the joint distribution of the printed statistics. Positive
statistics (means, variances, episodes) are taken on a log scale, Pearson r and t as they are; a multivariate Gaussian
is fitted to the transformed sample (full covariance shrunk 10% towards its diagonal), and the log density of the
printed numbers under it is the candidate's log-likelihood. With few replications (the screen) the statistics are
taken as independent and each is scored by its Student-t predictive density (a Gaussian of unknown mean and variance
under the usual non-informative prior: n - 1 degrees of freedom, scale s * sqrt(1 + 1/n)), which does not
over-trust a spread estimated from 2 or 3 values.
Under a uniform prior over the candidates, the posterior is the softmax of the log-likelihoods.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import numpy.typing as npt
from scipy import stats as sps

from sb3_affect.study.forensics.statistics import LOG_SCALE

#: Smallest standard deviation of a transformed statistic (keeps a constant statistic from giving an infinite density).
SD_FLOOR = 1e-3
#: Weight of the diagonal in the shrunk covariance.
SHRINKAGE = 0.1


def transform(values: npt.ArrayLike) -> np.ndarray:
    """Log of the positive statistics (non-positive values become NaN), the others unchanged; works on any leading shape."""
    data = np.array(values, dtype=float)
    log_scale = np.array(LOG_SCALE)
    with np.errstate(divide="ignore", invalid="ignore"):
        logged = np.where(data > 0, np.log(np.where(data > 0, data, 1.0)), math.nan)
    return np.where(log_scale, logged, data)


def log_likelihood(sample: npt.ArrayLike, observed: npt.ArrayLike, diagonal: bool = False) -> float:
    """
    Gaussian synthetic log-likelihood of ``observed`` (one value per statistic) under ``sample`` (replications x
    statistics), both untransformed. Replications with a missing statistic are left out; a statistic the candidate
    never produces while the paper prints it gives -inf.

    :param sample: simulated statistics, one row per replication
    :param observed: the printed statistics (NaN: not printed, left out)
    :param diagonal: ignore correlations between statistics and use the Student-t predictive (for screening)
    """
    x, y = transform(sample), transform(observed)
    keep = np.isfinite(y)
    x, y = x[:, keep], y[keep]
    x = x[np.isfinite(x).all(axis=1)]
    if len(x) < 2:
        return -math.inf
    mean = x.mean(axis=0)
    cov = np.atleast_2d(np.cov(x, rowvar=False))
    sd = np.maximum(np.sqrt(np.diag(cov)), SD_FLOOR)
    if diagonal or len(x) <= x.shape[1]:
        n = len(x)
        return float(sps.t.logpdf(y, df=n - 1, loc=mean, scale=sd * math.sqrt(1 + 1 / n)).sum())
    corr = cov / np.outer(np.sqrt(np.diag(cov)) + 1e-300, np.sqrt(np.diag(cov)) + 1e-300)
    corr = (1 - SHRINKAGE) * corr + SHRINKAGE * np.eye(len(y))
    scaled = (y - mean) / sd
    sign, logdet = np.linalg.slogdet(corr)
    if sign <= 0:
        return -math.inf
    quad = float(scaled @ np.linalg.solve(corr, scaled))
    return float(-0.5 * quad - 0.5 * logdet - np.log(sd).sum() - 0.5 * len(y) * math.log(2 * math.pi))


#: Bootstrap resamples of the replications for a log-likelihood's Monte Carlo error (seeded: the same on every run).
MC_RESAMPLES = 100


def monte_carlo_error(sample: npt.ArrayLike, observed: npt.ArrayLike, resamples: int = MC_RESAMPLES, seed: int = 0) -> float:
    """
    The Monte Carlo error of ``log_likelihood(sample, observed)``: its standard deviation over bootstrap resamples of
    the replications (the rows of ``sample``); NaN when the log-likelihood is not finite.
    """
    x = np.asarray(sample, dtype=float)
    if not math.isfinite(log_likelihood(x, observed)) or len(x) < 2:
        return math.nan
    rng = np.random.default_rng(seed)
    values = np.array([log_likelihood(x[rng.integers(0, len(x), len(x))], observed) for _ in range(resamples)])
    values = values[np.isfinite(values)]
    return float(values.std(ddof=1)) if len(values) > 1 else math.nan


def posterior(log_likelihoods: npt.ArrayLike, log_prior: npt.ArrayLike | None = None) -> np.ndarray:
    """Posterior probabilities from log-likelihoods and a log prior (default: uniform)."""
    ll = np.asarray(log_likelihoods, dtype=float)
    lp = np.zeros_like(ll) if log_prior is None else np.asarray(log_prior, dtype=float)
    total = ll + lp
    if not np.isfinite(total).any():
        return np.full_like(ll, 1.0 / len(ll))
    total = total - np.max(total[np.isfinite(total)])
    weights = np.where(np.isfinite(total), np.exp(total), 0.0)
    return weights / weights.sum()


def intervals(sample: npt.ArrayLike, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Per statistic: the central ``level`` interval of the simulated replications (percentiles, NaNs left out)."""
    data = np.asarray(sample, dtype=float)
    tail = (1 - level) / 2 * 100
    with np.errstate(all="ignore"):
        lo = np.array([np.nanpercentile(c, tail) if np.isfinite(c).any() else math.nan for c in data.T])
        hi = np.array([np.nanpercentile(c, 100 - tail) if np.isfinite(c).any() else math.nan for c in data.T])
    return lo, hi


def predictive_reach(sample: npt.ArrayLike, observed: npt.ArrayLike, level: float = 0.95) -> np.ndarray:
    """
    Per statistic: is the printed value inside the ``level`` Student-t predictive interval of the (transformed)
    sample? (n - 1 degrees of freedom, scale s * sqrt(1 + 1/n): honest coverage for a handful of replications)
    """
    x, y = transform(sample), transform(observed)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        n = np.isfinite(x).sum(axis=0)
        mean, sd = np.nanmean(x, axis=0), np.nanstd(x, axis=0, ddof=1)
        half = sps.t.ppf(0.5 + level / 2, np.maximum(n - 1, 1)) * np.maximum(np.nan_to_num(sd), SD_FLOOR) * np.sqrt(1 + 1 / n)
    return np.asarray((n >= 2) & (np.abs(y - mean) <= half))


#: What the evidence shows about one printed number (``reach_findings``).
REACHED = "reached"
NOT_RULED_OUT = "not ruled out at screen size"
NOT_REACHED = "not reached"
#: Fewest replications of one candidate whose predictive interval may count a printed number as reached: a Student-t
#: interval from fewer is so wide (2 replications: 12.7 standard deviations either side) that covering says little.
MIN_REACH_REPS = 10


def reach_findings(
    leaders: list[np.ndarray], screened: list[np.ndarray], observed: npt.ArrayLike, level: float = 0.95
) -> list[str]:
    """
    Per printed statistic, what the replications show: ``REACHED`` when the ``level`` predictive interval of some
    candidate with at least ``MIN_REACH_REPS`` replications (the leaders) holds it; else ``NOT_RULED_OUT`` when only
    intervals from fewer replications (the screen) hold it, which is no evidence that a candidate prints it; else
    ``NOT_REACHED``. A statistic the paper does not print (NaN) is ``"not printed"``.

    :param leaders: one sample (replications x statistics) per leading candidate
    :param screened: one sample per screened candidate
    :param observed: the printed statistics
    """
    y = np.asarray(observed, dtype=float)
    by_leaders = np.zeros(y.shape, dtype=bool)
    by_screen = np.zeros(y.shape, dtype=bool)
    for sample in leaders:
        sample = np.asarray(sample, dtype=float)
        enough = np.isfinite(transform(sample)).sum(axis=0) >= MIN_REACH_REPS
        reach = predictive_reach(sample, y, level) if len(sample) else np.zeros(y.shape, dtype=bool)
        by_leaders |= reach & enough
        by_screen |= reach & ~enough
    for sample in screened:
        if len(sample):
            by_screen |= predictive_reach(np.asarray(sample, dtype=float), y, level)
    return [
        "not printed" if not np.isfinite(v) else REACHED if a else NOT_RULED_OUT if b else NOT_REACHED
        for v, a, b in zip(y, by_leaders, by_screen)
    ]
