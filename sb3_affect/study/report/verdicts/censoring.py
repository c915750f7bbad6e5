"""
Censored quantities: a run that never finds the optimal path counts with all its decisions, so a plain mean over it is
a lower bound. Here are the marks of bounds (``>=``, ``<=``) on means and on differences of means, and the
Kaplan-Meier restricted means that treat such runs as censored (the report's estimate where a plain mean is a bound).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sb3_affect.study.report.rendering.document import fmt, sig
from sb3_affect.study.report.verdicts.inference import Estimate, Z

#: The flag of censored runs behind each column that counts them at their total (a lower bound where one is).
FLAGS = {
    "decisions_before_optimal": "censored",
    "cells_before_optimal": "censored",
    "decisions_to_greedy_optimal": "greedy_censored",
}

#: What a difference of two lower bounds is: no bound in either direction.
UNBOUNDED = "both sides censored: not a bound"


def censored_mean(values: np.ndarray, censored: np.ndarray, digits: int = 0) -> str:
    """The mean of ``values``, prefixed ``>=`` when a censored value (a lower bound) enters it."""
    text = fmt(float(np.mean(values)), digits)
    return f">= {text}" if np.asarray(censored, bool).any() else text


def restricted_mean(values: np.ndarray, censored: np.ndarray, horizon: float) -> tuple[float, float]:
    """
    The Kaplan-Meier restricted mean of ``values`` up to ``horizon`` (the area under the survival curve from 0 to it;
    a censored value leaves the risk set without an event) and its variance (Greenwood's formula for the restricted
    mean: the sum over event times t of A(t)^2 d / (n (n - d)), A(t) the area from t to the horizon).
    """
    values, censored = np.asarray(values, float), np.asarray(censored, bool)
    times = np.unique(values)
    deaths = np.bincount(np.searchsorted(times, values[~censored]), minlength=len(times)).astype(float)
    leaving = np.bincount(np.searchsorted(times, values), minlength=len(times)).astype(float)
    at_risk = len(values) - np.r_[0.0, np.cumsum(leaving)[:-1]]
    survival = np.cumprod(1 - deaths / at_risk)  # S just after each time
    keep = times < horizon
    edges = np.r_[0.0, times[keep], horizon]
    level = np.r_[1.0, survival[keep]]  # S on each interval between the edges
    pieces = level * np.diff(edges)
    mean = float(pieces.sum())
    tail = np.cumsum(pieces[::-1])[::-1][1:]  # area from each event time to the horizon
    d, n = deaths[keep], at_risk[keep]
    ok = (d > 0) & (n > d)
    variance = float(np.sum(tail[ok] ** 2 * d[ok] / (n[ok] * (n[ok] - d[ok]))))
    return mean, variance


def restricted_means(groups: dict[str, tuple[np.ndarray, np.ndarray]]) -> tuple[float, dict[str, tuple[float, float]]]:
    """
    ``restricted_mean`` of each group's ``(values, censored)`` to a common horizon (the smallest of the groups' largest
    values, so every curve is defined up to it): ``(horizon, {name: (mean, variance)})``.
    """
    horizon = min(float(np.max(values)) for values, _ in groups.values())
    return horizon, {name: restricted_mean(values, censored, horizon) for name, (values, censored) in groups.items()}


def difference_sign(first_censored: bool, second_censored: bool) -> str:
    """
    The mark of ``first - second`` when each is a mean that counts censored runs (a lower bound when it does): ``>=``
    when only the first is a bound, ``<=`` when only the second is, ``""`` when neither, ``UNBOUNDED`` when both.
    """
    if first_censored and second_censored:
        return UNBOUNDED
    return ">=" if first_censored else "<=" if second_censored else ""


def marked(text: str, sign: str) -> str:
    """``text`` with its bound's mark in front (``>= 8,937``), or after it when the quantity is no bound at all."""
    if sign == UNBOUNDED:
        return f"{text} ({sign})"
    return f"{sign} {text}" if sign else text


def restricted_difference(
    first: tuple[np.ndarray, np.ndarray], second: tuple[np.ndarray, np.ndarray]
) -> tuple[float, Estimate]:
    """
    ``first`` minus ``second`` in Kaplan-Meier restricted means (each ``(values, censored)``) to their common horizon,
    with a normal 95% CI from Greenwood's variances: ``(horizon, estimate)``.
    """
    horizon, means = restricted_means({"first": first, "second": second})
    (a, va), (b, vb) = means["first"], means["second"]
    se = math.sqrt(va + vb)
    return horizon, Estimate(a - b, a - b - Z * se, a - b + Z * se, se)


def restricted_over_eps(m: pd.DataFrame, column: str, agents: tuple[str, ...]) -> tuple[float, Estimate]:
    """
    The mean over ε of one agent's Kaplan-Meier restricted means in ``column`` (``agents`` of one name), or of the
    first agent's minus the second's (two names), every (agent, ε) cell to the horizon all of them reach, with a normal
    95% CI from Greenwood's variances (the cells independent): ``(horizon, estimate)``. The estimate a mean over ε of
    plain means becomes where censored runs make those means bounds.
    """
    flag = FLAGS[column]
    cells: dict[tuple[str, float], tuple[np.ndarray, np.ndarray]] = {}
    for agent in agents:
        runs = m[m.agent == agent]
        for eps in np.unique(runs.epsilon.to_numpy(float)):
            part = runs[runs.epsilon == eps]
            cells[agent, float(eps)] = (part[column].to_numpy(float), part[flag].to_numpy(bool))
    horizon, means = restricted_means({f"{agent} {eps}": cell for (agent, eps), cell in cells.items()})
    epsilons = sorted({eps for _, eps in cells})
    signs = dict(zip(agents, (1.0, -1.0)))
    value = sum(signs[agent] * means[f"{agent} {eps}"][0] for agent, eps in cells) / len(epsilons)
    se = math.sqrt(sum(means[f"{agent} {eps}"][1] for agent, eps in cells)) / len(epsilons)
    return horizon, Estimate(value, value - Z * se, value + Z * se, se)


def difference_text(difference: Estimate, first: pd.DataFrame, second: pd.DataFrame, column: str) -> str:
    """
    ``first`` minus ``second`` in ``column`` as the report prints it: the Welch estimate ``difference`` with its CI when
    no censored run enters it; else the plain difference marked as a bound (``difference_sign``) and, in place of the
    Welch CI of a bound, the Kaplan-Meier restricted-mean difference to the horizon both reach, with its CI.
    """
    sign = difference_sign(censored_runs(first, column) > 0, censored_runs(second, column) > 0)
    if not sign:
        return difference.text()
    flag = FLAGS[column]
    horizon, km = restricted_difference(
        *((runs[column].to_numpy(float), runs[flag].to_numpy(bool)) for runs in (first, second))
    )
    return f"{marked(sig(difference.value), sign)}; KM to {sig(horizon)}: {km.text()}"


def censored_runs(runs: pd.DataFrame, column: str) -> int:
    """How many of ``runs`` count at their total in ``column`` (never found the optimal path; 0 for other columns)."""
    flag = FLAGS.get(column)
    return int(runs[flag].sum()) if flag is not None and flag in runs.columns else 0
