"""From run files to tidy tables: one row per episode, and one row of metrics per run (docs/definitions.md)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

EMOTIONS = ("joy", "sadness", "fear", "anger")


def load_runs(run_dir: Path) -> list[dict[str, Any]]:
    """Every finished run of a results folder (``DIR/runs/*.json``)."""
    files = sorted((Path(run_dir) / "runs").glob("*.json"))
    runs = [json.loads(p.read_text()) for p in files if not p.name.startswith(".")]
    return [r for r in runs if r.get("status", "ok") == "ok"]


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
    out = pd.concat(frames, ignore_index=True)
    for column in ("optimal", "truncated", "greedy_optimal"):
        out[column] = out[column].fillna(False).astype(bool)
    for column in ("random_moves", "norm"):
        out[column] = pd.to_numeric(out[column], errors="coerce")
    return out


def _first_stable(flags: np.ndarray) -> float:
    """First episode (1-based) from which ``flags`` stays True to the end; NaN if the last one is False."""
    if len(flags) == 0 or not flags[-1]:
        return math.nan
    false_positions = np.flatnonzero(~flags)
    return float(false_positions[-1] + 2) if len(false_positions) else 1.0


def run_metrics(episodes: pd.DataFrame, runs: list[dict[str, Any]] | None = None) -> pd.DataFrame:
    """
    The metrics of docs/definitions.md, one row per run:

    - ``decisions_per_episode``, ``cells_per_episode``: means over the run's episodes (the paper's "steps" are decisions)
    - ``first_optimal``: first episode whose path is a shortest path; ``censored`` when none is
    - ``decisions_before_optimal`` / ``cells_before_optimal``: summed over the episodes before it (censored: all)
    - ``greedy_optimal_from``: first episode after which the greedy policy from the start always walks a shortest path
    - ``truncated``: episodes ended by the safety cap
    - ``total_decisions``: every decision of the run, the unfinished last episode included (from the run file)

    ``runs`` (the run files) adds the runs that finished no episode at all (e.g. a DQN that never reached the goal
    within its step budget): censored, with all their decisions before the optimal path.
    """
    rows = []
    label_columns = [c for c in episodes.columns if c not in _EPISODE_VALUE_COLUMNS and c not in ("run_id",)]
    for run_id, run in episodes.groupby("run_id", sort=False):
        run = run.sort_values("episode")
        optimal = run.optimal.to_numpy()
        hits = np.flatnonzero(optimal)
        first = int(run.episode.iloc[hits[0]]) if len(hits) else math.nan
        before = run.iloc[: hits[0]] if len(hits) else run
        row = {key: run[key].iloc[0] for key in label_columns}
        row.update(
            run_id=run_id,
            episodes=len(run),
            decisions_per_episode=run.decisions.mean(),
            cells_per_episode=run.cells.mean(),
            first_optimal=first,
            censored=not len(hits),
            decisions_before_optimal=float(before.decisions.sum()),
            cells_before_optimal=float(before.cells.sum()),
            greedy_optimal_from=_first_stable(run.greedy_optimal.to_numpy()),
            truncated=int(run.truncated.sum()),
            total_decisions=int(run.decisions.sum()),
        )
        rows.append(row)
    totals = {r["run_id"]: r.get("timings", {}).get("decisions") for r in runs or []}
    for row in rows:
        if totals.get(row["run_id"]) is not None:
            row["total_decisions"] = int(totals[row["run_id"]])
            if row["censored"]:  # the unfinished last episode was spent before the optimal path too
                row["decisions_before_optimal"] = float(row["total_decisions"])
    seen = {row["run_id"] for row in rows}
    for record in runs or []:
        if record["run_id"] in seen:
            continue
        total = float(record.get("timings", {}).get("decisions") or 0)
        config = record["config"]
        row = {"agent": config["agent"], "seed": config["seed"], **config["labels"]}
        row.update(
            run_id=record["run_id"],
            episodes=0,
            decisions_per_episode=math.nan,
            cells_per_episode=math.nan,
            first_optimal=math.nan,
            censored=True,
            decisions_before_optimal=total,
            cells_before_optimal=math.nan,
            greedy_optimal_from=math.nan,
            truncated=0,
            total_decisions=int(total),
        )
        rows.append(row)
    return pd.DataFrame(rows)


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


def profile(episodes: pd.DataFrame) -> pd.DataFrame:
    """
    Per episode number: the mean over runs of each emotion's fraction of decisions and of the equivalent epsilon,
    with a 95% band of the mean (mean +- 1.96 standard errors over runs: ``_lo`` / ``_hi``).
    """
    fractions = episodes[[*EMOTIONS]].div(episodes.decisions, axis=0)
    fractions["equivalent_epsilon"] = episodes.random_moves / episodes.decisions
    fractions["episode"] = episodes.episode
    grouped = fractions.groupby("episode")
    mean = grouped.mean()
    half = 1.96 * grouped.sem().fillna(0.0)
    return pd.concat([mean.add_suffix("_mean"), (mean - half).add_suffix("_lo"), (mean + half).add_suffix("_hi")], axis=1)


def window_mean(prof: pd.DataFrame, column: str, first: int, last: int) -> float:
    """Mean of a profile column over episodes ``first..last``."""
    window = prof.loc[(prof.index >= first) & (prof.index <= last), f"{column}_mean"]
    return float(window.mean()) if len(window) else math.nan
