"""From run files to tidy tables: one row per episode, and one row of metrics per run (docs/definitions.md)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

EMOTIONS = ("joy", "sadness", "fear", "anger")


def load_runs(run_dir: Path) -> list[dict[str, Any]]:
    """Every finished run of a results folder as a run record (JSON layout); small folders only (see ``load_results``)."""
    from sb3_affect.experiments.store import ResultsStore

    return ResultsStore(run_dir).load_runs()


def load_results(run_dir: Path, columns: tuple[str, ...] | None = None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """
    The report's one loader: every finished run of a results folder, whatever its layout (Parquet chunks or one JSON
    file per run), without a Python object per episode.

    :param columns: the episode columns wanted (default: all)
    :return: ``(runs, episodes)``: one row per run (``ResultsStore.runs_frame``: run_id, agent, seed, labels,
        decisions, episodes, wall_seconds, max_timesteps) and one row per episode (run_id as a categorical, agent,
        seed and labels, then the episode columns)
    """
    from sb3_affect.experiments.store import ResultsStore

    runs, episodes = ResultsStore(run_dir).results(columns)
    for column in episodes.columns:  # labels as plain values: groupby over them sees only the groups present
        if column != "run_id" and isinstance(episodes[column].dtype, pd.CategoricalDtype):
            episodes[column] = np.asarray(episodes[column])
            if episodes[column].dtype == object:
                episodes[column] = episodes[column].infer_objects()
    return runs, episodes


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


def run_metrics(episodes: pd.DataFrame, runs: pd.DataFrame | None = None) -> pd.DataFrame:
    """
    The metrics of docs/definitions.md, one row per run:

    - ``decisions_per_episode``, ``cells_per_episode``: means over the run's episodes (the paper's "steps" are decisions)
    - ``first_optimal``: first episode whose path is a shortest path; ``censored`` when none is
    - ``decisions_before_optimal`` / ``cells_before_optimal``: summed over the episodes before it (censored: all)
    - ``greedy_optimal_from``: first episode after which the greedy policy from the start always walks a shortest path
    - ``truncated``: episodes ended by the safety cap
    - ``total_decisions``: every decision of the run, the unfinished last episode included (from ``runs``)

    ``runs`` (``load_results``' run table) adds the runs that finished no episode at all (e.g. a DQN that never
    reached the goal within its step budget): censored, with all their decisions before the optimal path.
    Computed with whole-column operations (no Python loop over runs), for folders of any size.
    """
    label_columns = [c for c in episodes.columns if c not in _EPISODE_VALUE_COLUMNS and c not in ("run_id",)]
    codes, uniques = pd.factorize(episodes["run_id"], sort=False)
    episode = episodes["episode"].to_numpy()
    if len(codes) > 1 and not (np.all(np.diff(codes) >= 0) and np.all((np.diff(episode) > 0) | (np.diff(codes) > 0))):
        order = np.lexsort((episode, codes))  # each run's rows together, by episode
        episodes, codes, episode = episodes.iloc[order], codes[order], episode[order]
    n, size = len(uniques), len(codes)
    counts = np.bincount(codes, minlength=n)
    starts = np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)
    ends = starts + counts
    positions = np.arange(size)
    decisions = episodes["decisions"].to_numpy(dtype=np.float64)
    cells = episodes["cells"].to_numpy(dtype=np.float64)
    optimal = episodes["optimal"].to_numpy(dtype=bool)
    greedy = episodes["greedy_optimal"].to_numpy(dtype=bool)
    first_pos = np.minimum.reduceat(np.where(optimal, positions, size), starts) if n else np.zeros(0, np.int64)
    found = first_pos < size
    before = positions < first_pos[codes]
    last_false = np.maximum.reduceat(np.where(~greedy, positions, -1), starts) if n else np.zeros(0, np.int64)
    greedy_from = np.where(last_false < starts, 1.0, (last_false - starts + 2).astype(np.float64))
    greedy_from[~greedy[ends - 1]] = math.nan
    total = np.bincount(codes, decisions, minlength=n)
    columns: dict[str, Any] = {key: _plain_values(episodes[key].to_numpy()[starts]) for key in label_columns}
    columns.update(
        run_id=np.asarray(uniques).astype(object),
        episodes=counts,
        decisions_per_episode=total / counts,
        cells_per_episode=np.bincount(codes, cells, minlength=n) / counts,
        first_optimal=np.where(found, episode[np.minimum(first_pos, size - 1)], math.nan).astype(np.float64),
        censored=~found,
        decisions_before_optimal=np.bincount(codes, decisions * before, minlength=n),
        cells_before_optimal=np.bincount(codes, cells * before, minlength=n),
        greedy_optimal_from=greedy_from,
        truncated=np.bincount(codes, episodes["truncated"].to_numpy(dtype=np.float64), minlength=n).astype(np.int64),
        total_decisions=total.astype(np.int64),
    )
    out = pd.DataFrame(columns)
    if runs is None or runs.empty:
        return out
    totals = runs.set_index("run_id")["decisions"]
    recorded = out.run_id.map(totals)
    known = recorded.notna().to_numpy()
    out.loc[known, "total_decisions"] = recorded[known].astype(np.int64)
    # A censored run spent its unfinished last episode before the optimal path too.
    censored_known = known & out.censored.to_numpy()
    out.loc[censored_known, "decisions_before_optimal"] = out.loc[censored_known, "total_decisions"].astype(float)
    empty = runs[~runs.run_id.isin(out.run_id)]
    if len(empty):
        extra = empty.drop(columns=[c for c in _RUN_ONLY if c in empty])
        total_empty = empty["decisions"].fillna(0).astype(float).to_numpy()
        extra = extra.assign(
            episodes=0,
            decisions_per_episode=math.nan,
            cells_per_episode=math.nan,
            first_optimal=math.nan,
            censored=True,
            decisions_before_optimal=total_empty,
            cells_before_optimal=math.nan,
            greedy_optimal_from=math.nan,
            truncated=0,
            total_decisions=total_empty.astype(np.int64),
        )
        out = pd.concat([out, extra], ignore_index=True)
    return out


_RUN_ONLY = ("algo", "decisions", "episodes", "wall_seconds", "max_timesteps")


def _plain_values(values: np.ndarray) -> Any:
    """Per-run label values as a plain column (numbers as numbers, not objects)."""
    return pd.Series(values).infer_objects().to_numpy() if values.dtype == object else values


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
