"""
From run files to tidy tables: one row per episode, and one row of metrics per run (docs/definitions.md).

``load_results`` is the report's only access to a results folder: every section reads runs through it, so a change of
the results store (files, format) is one change here.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

EMOTIONS = ("joy", "sadness", "fear", "anger")
#: Windows of episodes the report summarises (early, after the first optimal path on average, late).
EARLY, LATE = (1, 10), (181, 200)


@dataclass
class Results:
    """A results folder's finished runs: ``episodes`` (one row per episode) and ``runs`` (the run records)."""

    folder: Path
    episodes: pd.DataFrame
    runs: list[dict[str, Any]]


def load_runs(run_dir: Path) -> list[dict[str, Any]]:
    """Every finished run of a results folder, whatever its layout (Parquet chunks or one JSON file per run)."""
    from sb3_affect.experiments.store import ResultsStore

    return [r for r in ResultsStore(run_dir).load_runs() if r.get("status", "ok") == "ok"]


def load_results(run_dir: Path) -> Results:
    """The finished runs of ``run_dir`` as a ``Results`` (the report's one loader)."""
    runs = load_runs(run_dir)
    return Results(Path(run_dir), episodes_frame(runs), runs)


def episodes_frame(runs: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per episode of every run, with the run's agent, seed and labels as columns."""
    frames = []
    for run in runs:
        config = run["config"]
        frame = pd.DataFrame(run["episodes"])
        frame["run_id"] = run["run_id"]
        frame["agent"] = config["agent"]
        frame["seed"] = config["seed"]
        for key, value in config["labels"].items():
            frame[key] = value
        frames.append(frame)
    if not frames:
        return pd.DataFrame()
    with warnings.catch_warnings():  # all-NaN columns (e.g. norm of an ε-greedy run) are expected
        warnings.simplefilter("ignore", FutureWarning)
        out = pd.concat(frames, ignore_index=True)
    for column in ("optimal", "truncated", "greedy_optimal"):
        out[column] = out[column].fillna(False).astype(bool)
    for column in ("random_moves", "norm"):
        out[column] = pd.to_numeric(out[column], errors="coerce")
    return out


_EPISODE_VALUE_COLUMNS = (
    "episode",
    "decisions",
    "cells",
    "reward",
    "optimal",
    "truncated",
    "random_moves",
    "waits",
    *EMOTIONS,
    "greedy_optimal",
    "norm",
)


def _window(e: pd.DataFrame, runs: pd.Index, lo: int, hi: int) -> dict[str, pd.Series]:
    """Per run: mean over the window's episodes of per-episode fractions, and decision-weighted fractions."""
    part = e[(e.episode >= lo) & (e.episode <= hi)]
    decisions = part.decisions.where(part.decisions > 0)
    out: dict[str, pd.Series] = {}
    g = part.groupby("run_id", sort=False)
    total = g.decisions.sum().reindex(runs)
    for name, column in (*((x, x) for x in EMOTIONS), ("eqeps", "random_moves")):
        out[f"{name}_{lo}_{hi}"] = (part[column] / decisions).groupby(part.run_id).mean().reindex(runs)
        out[f"{name}_{lo}_{hi}_weighted"] = g[column].sum().reindex(runs) / total.where(total > 0)
    out[f"decisions_{lo}_{hi}"] = g.decisions.mean().reindex(runs)
    return out


def run_metrics(episodes: pd.DataFrame, runs: list[dict[str, Any]] | None = None) -> pd.DataFrame:
    """
    The metrics of docs/definitions.md, one row per run (vectorised: fast for thousands of runs):

    - ``decisions_per_episode``, ``cells_per_episode``: means over the run's episodes (the paper's "steps" are decisions)
    - ``first_optimal``: first episode whose path is a shortest path; ``censored`` when none is
    - ``decisions_before_optimal`` / ``cells_before_optimal``: summed over the episodes before it (censored: all)
    - ``greedy_optimal_from``: first episode after which the greedy policy from the start always walks a shortest path
      (NaN, ``greedy_censored``, when it is not optimal after the last episode)
    - ``decisions_to_greedy_optimal``: decisions of episodes 1 .. ``greedy_optimal_from`` (censored: all)
    - ``truncated``: episodes ended by the safety cap
    - ``total_decisions``: every decision of the run, the unfinished last episode included (from the run file)
    - window features (``EARLY``, ``LATE``): ``joy_1_10`` (mean of per-episode fractions), ``joy_1_10_weighted``
      (decision-weighted), the same for every emotion and ``eqeps`` (random-direction decisions), ``decisions_181_200``

    ``runs`` (the run files) adds the runs that finished no episode at all (e.g. a DQN that never reached the goal
    within its step budget): censored, with all their decisions before the optimal path.
    """
    rows = _vector_metrics(episodes) if len(episodes) else pd.DataFrame()
    records = {r["run_id"]: r for r in runs or []}
    if len(rows) and records:
        totals = rows.run_id.map(lambda rid: (records.get(rid) or {}).get("timings", {}).get("decisions"))
        known = totals.notna()
        rows.loc[known, "total_decisions"] = totals[known].astype(int)
        fix = known & rows.censored  # the unfinished last episode was spent before the optimal path too
        rows.loc[fix, "decisions_before_optimal"] = rows.loc[fix, "total_decisions"].astype(float)
        gfix = known & rows.greedy_censored
        rows.loc[gfix, "decisions_to_greedy_optimal"] = rows.loc[gfix, "total_decisions"].astype(float)
    seen = set(rows.run_id) if len(rows) else set()
    extra = []
    for record in runs or []:
        if record["run_id"] in seen:
            continue
        total = float(record.get("timings", {}).get("decisions") or 0)
        config = record["config"]
        row = {"agent": config["agent"], "seed": config["seed"], **config["labels"]}
        row.update(
            run_id=record["run_id"],
            episodes=0,
            censored=True,
            greedy_censored=True,
            decisions_before_optimal=total,
            decisions_to_greedy_optimal=total,
            truncated=0,
            total_decisions=int(total),
        )
        extra.append(row)
    if extra:
        rows = pd.concat([rows, pd.DataFrame(extra)], ignore_index=True)
    return rows


def _vector_metrics(episodes: pd.DataFrame) -> pd.DataFrame:
    e = episodes.sort_values(["run_id", "episode"], kind="stable").copy()
    for column in ("optimal", "truncated", "greedy_optimal"):  # None where an env does not define it
        e[column] = e[column].eq(True)
    g = e.groupby("run_id", sort=False)
    run_index = pd.Index(g.size().index, name="run_id")
    label_columns = [c for c in e.columns if c not in _EPISODE_VALUE_COLUMNS and c != "run_id"]
    out = g[label_columns].first() if label_columns else pd.DataFrame(index=run_index)
    first = e[e.optimal].groupby("run_id").episode.min().reindex(run_index)
    cutoff = e.run_id.map(first)
    before = e.episode < cutoff.fillna(np.inf)
    last_episode = g.episode.max()
    last_false = e[~e.greedy_optimal].groupby("run_id").episode.max().reindex(run_index)
    greedy_from = (last_false + 1).fillna(1.0).where(last_false.fillna(-1) != last_episode)
    upto_greedy = e.episode <= e.run_id.map(greedy_from).fillna(np.inf)
    out["episodes"] = g.size()
    out["decisions_per_episode"] = g.decisions.mean()
    out["cells_per_episode"] = g.cells.mean()
    out["first_optimal"] = first.astype(float)
    out["censored"] = first.isna()
    out["decisions_before_optimal"] = e.decisions.where(before, 0).groupby(e.run_id).sum().astype(float)
    out["cells_before_optimal"] = e.cells.where(before, 0).groupby(e.run_id).sum().astype(float)
    out["greedy_optimal_from"] = greedy_from.astype(float)
    out["greedy_censored"] = greedy_from.isna()
    out["decisions_to_greedy_optimal"] = e.decisions.where(upto_greedy, 0).groupby(e.run_id).sum().astype(float)
    out["truncated"] = g.truncated.sum().astype(int)
    out["total_decisions"] = g.decisions.sum().astype(int)
    for window in (EARLY, LATE):
        for key, series in _window(e, run_index, *window).items():
            out[key] = series
    return out.reset_index()


def profile(episodes: pd.DataFrame) -> pd.DataFrame:
    """
    Per episode number: the mean over runs of each emotion's fraction of decisions and of the equivalent epsilon,
    with a 95% band of the mean (mean +- 1.96 standard errors over runs: ``_lo`` / ``_hi``), and the
    decision-weighted fraction (all decisions of that episode number pooled over runs: ``_weighted``).
    """
    fractions = episodes[[*EMOTIONS]].div(episodes.decisions, axis=0)
    fractions["equivalent_epsilon"] = episodes.random_moves / episodes.decisions
    fractions["episode"] = episodes.episode
    grouped = fractions.groupby("episode")
    mean = grouped.mean()
    half = 1.96 * grouped.sem().fillna(0.0)
    sums = episodes.assign(equivalent_epsilon=episodes.random_moves).groupby("episode")
    totals = sums.decisions.sum()
    weighted = sums[[*EMOTIONS, "equivalent_epsilon"]].sum().div(totals, axis=0)
    return pd.concat(
        [
            mean.add_suffix("_mean"),
            (mean - half).add_suffix("_lo"),
            (mean + half).add_suffix("_hi"),
            weighted.add_suffix("_weighted"),
        ],
        axis=1,
    )


def window_mean(prof: pd.DataFrame, column: str, first: int, last: int, kind: str = "mean") -> float:
    """Mean of a profile column (``kind`` ``mean`` or ``weighted``) over episodes ``first..last``."""
    window = prof.loc[(prof.index >= first) & (prof.index <= last), f"{column}_{kind}"]
    return float(window.mean()) if len(window) else math.nan
