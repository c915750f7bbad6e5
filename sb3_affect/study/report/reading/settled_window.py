"""
The affective agent's settled window (episodes 51-200): its episodes are bimodal, short greedy ones and long random
walks in joy. ``settled_part`` reduces some runs' rows (parts of the runs, in run id order, joined end to end give the
pieces of all of them: ``episode_scan`` feeds it part by part), ``settled_numbers`` gives the mechanism section's
figures with bootstrap CIs over runs.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sb3_affect.study.report.estimation import resamples

#: An episode longer than this many decisions is "long" (the shortest path is 12 cells, 6 to 12 decisions).
LONG = 20
#: The settled phase: after the first optimal path on average.
SETTLED = (51, 200)


#: Bootstrap resamples of the mechanism's CIs, and how many are drawn at a time (memory: block x runs indices).
REPS, BLOCK_CELLS = 1000, 4_000_000


def _bootstrap(
    per_run: pd.DataFrame, statistics: dict[str, str], reps: int = REPS, seed: int = 0
) -> dict[str, tuple[float, float]]:
    """
    Percentile 95% CIs of ratios of per-run sums (each ``numerator/denominator`` column names), resampling runs.

    Every statistic sees the same resamples (one seeded stream), drawn in blocks of rows so that memory stays
    ``BLOCK_CELLS`` indices whatever the number of runs (the stream, and so the numbers, are those of one draw).
    """
    n = len(per_run)
    rng = np.random.default_rng(seed)
    columns = {name: per_run[name].to_numpy(float) for ratio in statistics.values() for name in ratio.split("/")}
    sums: dict[str, list[np.ndarray]] = {name: [] for name in columns}
    block = max(1, BLOCK_CELLS // max(1, n))
    matrix = np.column_stack(list(columns.values())) if columns else np.zeros((n, 0))
    # integers whose every resample sum stays below 2**53: exact in any order, so a resample's sums are its draw
    # counts times the values (one matrix product) rather than the values gathered and added
    exact = bool(np.all(matrix == np.round(matrix))) and n * float(np.abs(matrix).max(initial=0.0)) < 2.0**53
    for first in range(0, reps, block):
        idx = rng.integers(0, n, size=(min(block, reps - first), n))
        if exact:
            counts = np.zeros(idx.shape, np.int32)
            resamples.count_draws(idx, counts)
            for name, summed in zip(columns, (counts @ matrix).T):
                sums[name].append(summed)
            continue
        for name, values in columns.items():
            sums[name].append(values[idx].sum(axis=1))
    out = {}
    for key, ratio in statistics.items():
        num, den = ratio.split("/")
        a, b = np.concatenate(sums[num]), np.concatenate(sums[den])
        ratios = a / np.where(b > 0, b, np.nan)
        low, high = np.nanpercentile(ratios, [2.5, 97.5])
        out[key] = (float(low), float(high))
    return out


def settled_part(episodes: pd.DataFrame, first: int, last: int) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    """
    What ``settled_numbers`` reads of episodes ``first..last`` of some runs: per run (in run id order) the sums of the
    columns of its CIs, and the window's decisions and joy (pooled, in row order). Parts of the runs, in run id order,
    give pieces that joined end to end are those of all the runs.
    """
    episode = episodes.episode.to_numpy()
    rows = np.flatnonzero((episode >= first) & (episode <= last))
    decisions, joy = episodes.decisions.to_numpy()[rows], episodes.joy.to_numpy()[rows]
    run_ids = episodes.run_id.iloc[rows]
    if isinstance(run_ids.dtype, pd.CategoricalDtype):
        key = run_ids.cat.codes.to_numpy()
    else:
        key = pd.factorize(run_ids.to_numpy(dtype=object), sort=True)[0]
    long = decisions > LONG
    columns = {
        "long": long,
        "one": None,
        "decisions": decisions,
        "long_decisions": np.where(long, decisions, 0),
        "long_joy": np.where(long, joy, 0),
        "joy": joy,
        "any_joy": joy > 0,
    }  # per-run sums of integers: exact in float64, so in any order
    if len(key) and bool(np.all(key[1:] >= key[:-1])):  # rows in run order (as read): each run's rows together
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        sums = {
            name: (np.diff(np.r_[starts, len(key)]) if v is None else np.add.reduceat(v, starts, dtype=np.int64))
            for name, v in columns.items()
        }
        return pd.DataFrame({name: v.astype(float) for name, v in sums.items()}), decisions, joy
    present = np.flatnonzero(np.bincount(key))  # the runs in run id order, as a groupby's
    per_run = pd.DataFrame(
        {
            name: np.bincount(key, weights=None if v is None else v.astype(float))[present].astype(float)
            for name, v in columns.items()
        }
    )
    return per_run, decisions, joy


def settled_numbers(per_run: pd.DataFrame, decisions: np.ndarray, joy: np.ndarray) -> dict[str, float]:
    """
    The figures of the mechanism from ``settled_part``'s pieces (joined over the runs) of the affective agent's
    episodes in a window, pooled over runs.
    """
    long = decisions > LONG
    long_decisions = np.where(long, decisions, 0)
    long_joy = np.where(long, joy, 0)
    any_joy = joy > 0
    total, long_total = int(decisions.sum(dtype=np.int64)), int(long_decisions.sum(dtype=np.int64))
    joy_total, long_joy_total = int(joy.sum(dtype=np.int64)), int(long_joy.sum(dtype=np.int64))
    short_decisions = total - long_total
    out = {
        "episodes": float(len(decisions)),
        "runs": float(len(per_run)),
        "median decisions": float(np.median(decisions)),
        "mean decisions": float(decisions.mean()),
        "share of long episodes": float(long.mean()),
        "share of decisions in long episodes": float(long_total / total),
        "joy share of decisions in long episodes": float(long_joy_total / max(1, long_total)),
        "joy share of decisions in short episodes": float((joy_total - long_joy_total) / max(1, short_decisions)),
        "share of episodes with any joy": float(any_joy.mean()),
        "mean per-episode joy fraction (equivalent ε)": float(pd.Series(joy / decisions).mean()),
        "decision-weighted joy fraction": float(joy_total / total),
    }
    cis = {
        "share of long episodes": "long/one",
        "share of decisions in long episodes": "long_decisions/decisions",
        "joy share of decisions in long episodes": "long_joy/long_decisions",
        "share of episodes with any joy": "any_joy/one",
        "decision-weighted joy fraction": "joy/decisions",
    }
    for key_name, (low, high) in _bootstrap(per_run, cis).items():
        out[f"{key_name} (low)"], out[f"{key_name} (high)"] = low, high
    return out
