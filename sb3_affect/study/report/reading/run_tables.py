"""
From run files to tidy tables: one row per episode, and one row of metrics per run (docs/definitions.md).

``load_results`` is the report's only access to a results folder: every section reads runs through it, so a change of
the results store (files, format) is one change here. It reads column-wise (only ``REPORT_COLUMNS``, compact dtypes),
and ``run_metrics`` reduces the episode rows run by run with numpy segment reductions, so a folder of 180,000 runs
(36 M episodes) costs its columns in memory and no Python loop over runs.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher.folder_files import MAX_RUN_FILE_BYTES
from sb3_affect.study.launcher.folder_reading import read_folder
from sb3_affect.study.launcher.regular_files import read_json
from sb3_affect.study.launcher.store import ResultsStore
from sb3_affect.study.report.estimation.grouped_sums import segment_means, window_bounds

EMOTIONS = EMOTION_NAMES
#: Windows of episodes the report summarises (early, after the first optimal path on average, late).
EARLY, LATE = (1, 10), (181, 200)
#: The early and late windows the windows section tries (Figs. 5 and 6: how the verdicts move with the windows).
EARLY_WINDOWS = ((1, 5), (1, 10), (1, 20), (11, 30))
LATE_WINDOWS = ((151, 200), (181, 200), (191, 200))
#: The episode columns the report reads (``load_results``): what the sections use, nothing more.
REPORT_COLUMNS = ("episode", "decisions", "cells", "optimal", "truncated", "random_moves", *EMOTIONS, "greedy_optimal")


#: Runs read at a time by the chunk-wise readers (``Results.metrics``, ``Results.parts``): about 2 M episode rows.
RUNS_PER_PART = 10_000


@dataclass
class Results:
    """
    A results folder's finished runs: the run table at once, the episode rows when asked for.

    :param folder: the results folder
    :param runs: one row per finished run, sorted by run id (``ResultsStore.runs_frame``: ``run_id``, ``agent``,
        ``algo``, ``seed``, the labels, ``decisions`` (every decision, an unfinished last episode included),
        ``episodes``, ``wall_seconds``, ``max_timesteps``)
    :param columns: the episode columns read (default ``REPORT_COLUMNS``)

    ``episodes`` is every episode row at once (read on first use, then kept): one row per episode, ``run_id``,
    ``agent`` and one column per label (categoricals), then the episode columns (int32 counts, bool flags, float64
    ``random_moves``); runs in run id order, each run's episodes together and in order. A large folder is read
    a part at a time instead: ``metrics`` (the per-run metrics, part by part) and ``agent_episodes`` (one agent's
    rows, only the columns asked for).
    """

    folder: Path
    runs: pd.DataFrame
    columns: tuple[str, ...] = REPORT_COLUMNS
    files: Any = None
    _episodes: pd.DataFrame | None = field(default=None, repr=False)

    @property
    def kinds(self) -> set[str]:
        """The kinds of records the folder holds (``FolderFiles.kinds``: episodes, a deep study's evaluations)."""
        if self.files is None:
            self.files = ResultsStore(self.folder).checked_files()
        return self.files.kinds()

    @property
    def episodes(self) -> pd.DataFrame:
        if self._episodes is None:
            self._episodes = next(iter(self.parts(self.columns)))[1]
        return self._episodes

    def parts(
        self,
        columns: Sequence[str],
        agent: str | None = None,
        runs_per_part: int | None = None,
        ordered: bool = False,
    ) -> Iterator[tuple[pd.DataFrame, pd.DataFrame]]:
        """
        ``(runs, episodes)`` of ``agent``'s runs (None: every run), about ``runs_per_part`` runs at a time (``ordered``:
        the parts one after the other in run id order, ``ResultsStore.results_parts``).
        """

        store = ResultsStore(self.folder)
        if self.files is None:
            self.files = store.checked_files()
        yield from store.results_parts(columns, False, agent, runs_per_part, self.files, ordered)

    def agent_episodes(
        self,
        agent: str,
        columns: Sequence[str],
        first: int | None = None,
        last: int | None = None,
    ) -> pd.DataFrame:
        """
        The rows of ``episodes`` of ``agent``'s runs whose episode is within ``first..last`` (None: no bound), with
        ``run_id``, ``agent``, the labels and ``columns`` only, in the same order; read ``RUNS_PER_PART`` runs at a
        time, so only the rows kept are held (``run_id``: a categorical of the runs kept, in run id order).
        """
        wanted = tuple(dict.fromkeys(("episode", *columns)))
        pieces: list[dict[str, Any]] = []
        for _, part in self.parts(wanted, agent, RUNS_PER_PART):
            episode = part.episode.to_numpy()
            keep = np.ones(len(part), bool) if first is None else episode >= first
            if last is not None:
                keep &= episode <= last
            rows = None if keep.all() else np.flatnonzero(keep)
            piece: dict[str, Any] = {}
            for name in part.columns:
                if name in wanted and name not in columns:
                    continue
                values = part[name]
                if isinstance(values.dtype, pd.CategoricalDtype):  # codes and categories: no object per row
                    codes = values.cat.codes.to_numpy()
                    piece[name] = (codes if rows is None else codes[rows], values.cat.categories)
                else:
                    array = values.to_numpy()
                    piece[name] = array if rows is None else array[rows]
            pieces.append(piece)
            del part
        if not pieces:
            return pd.DataFrame()
        names = list(pieces[0])
        run_id = _joined([piece["run_id"] for piece in pieces])
        order = np.argsort(run_id.codes, kind="stable")  # run id order (sorted categories), episodes kept in order
        del run_id
        frame = pd.DataFrame(index=pd.RangeIndex(len(order)))
        for name in names:  # one column joined at a time, its pieces let go
            joined = _joined([piece.pop(name) for piece in pieces])
            if isinstance(joined, pd.Categorical):
                column = pd.Categorical.from_codes(joined.codes[order], dtype=joined.dtype)
                frame[name] = column.remove_unused_categories() if name == "run_id" else column
            else:
                frame[name] = joined[order]
            del joined
        return frame

    def last_episode(self, agent: str) -> int:
        """The largest episode number of ``agent``'s runs (0: none)."""
        parts = self.parts(("episode",), agent, RUNS_PER_PART)
        return max((int(part.episode.max()) for _, part in parts if len(part)), default=0)

    def metrics(
        self, agent: str | None = None, windows: Sequence[tuple[int, int]] = (EARLY, LATE), with_runs: bool = True
    ) -> pd.DataFrame:
        """
        ``run_metrics`` of the folder's runs (``agent``'s only, when given), computed ``RUNS_PER_PART`` runs at a
        time: the same table as ``run_metrics(episodes, runs)`` (``with_runs``; else ``run_metrics(episodes)``), with
        one part's episode rows in memory at a time.
        """
        columns = tuple(dict.fromkeys((*self.columns, *REPORT_COLUMNS)))
        frames = [
            run_metrics(episodes, runs if with_runs else None, windows)
            for runs, episodes in self.parts(columns, agent, RUNS_PER_PART)
        ]
        return join_parts(frames)


def _joined(pieces: list[Any]) -> Any:
    """Arrays joined end to end; ``(codes, categories)`` pieces as one categorical over their sorted categories."""
    if not isinstance(pieces[0], tuple):
        return np.concatenate(pieces)
    categories = pieces[0][1]
    for _, more in pieces[1:]:
        categories = categories.union(more)
    categories = categories.sort_values()
    codes = np.concatenate([np.where(c >= 0, categories.get_indexer(cats)[c], -1).astype(np.int32) for c, cats in pieces])
    return pd.Categorical.from_codes(codes, categories=categories)


def join_parts(frames: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """
    Per-run tables of parts of a folder (``run_metrics`` of each part) as one, in ``run_metrics``'s order: the runs
    with episodes by run id, then those without any (``episodes == 0``) by run id.
    """
    frames = [f for f in frames if len(f.columns)]
    if not frames:
        return pd.DataFrame()
    if len(frames) == 1:
        return frames[0]
    order = next((list(f.columns) for f in frames if "first_optimal" in f.columns), list(frames[0].columns))
    with warnings.catch_warnings():  # parts without a column (no runs without episodes) are expected
        warnings.simplefilter("ignore", FutureWarning)
        out = pd.concat(frames, ignore_index=True)
    out = out[order + [c for c in out.columns if c not in order]]
    empty = (out.episodes == 0).to_numpy() if "first_optimal" in out.columns else np.zeros(len(out), bool)
    rank = np.lexsort((out.run_id.to_numpy(dtype=object).astype(str), empty))
    return out.iloc[rank].reset_index(drop=True)


def load_run_records(run_dir: str | Path) -> list[dict[str, Any]]:
    """
    Every finished (``status == "ok"``) run of a results folder as run records with their episode lists (small
    folders only): chunks and ``runs/*.json`` of a results folder, or loose ``run_dir/*.json`` run files.
    """
    root = Path(run_dir)
    if (root / "runs").is_dir() or (root / "chunks").is_dir():

        records = ResultsStore(root).load_runs()
    else:

        records = [read_json(f, MAX_RUN_FILE_BYTES) for f in sorted(root.glob("*.json"))]
    return [r for r in records if r.get("status", "ok") == "ok"]


def load_results(run_dir: Path, columns: Sequence[str] = REPORT_COLUMNS) -> Results:
    """
    The finished runs of ``run_dir`` (Parquet chunks, one JSON file per run, or both) as a ``Results``: the report's
    one loader.

    The run table is read at once (the chunks' footers and ``run`` column); the episode columns (only ``columns``, read
    column-wise by ``ResultsStore.results_parts``, each allocated once at its final size) when a section asks: all of
    them (``Results.episodes``: about 40 bytes an episode, 1.5 GB for 36 M episodes), or a part at a time.
    """

    store = ResultsStore(run_dir)
    files = store.checked_files()
    footers = files.episode_chunks()  # (a deep study's evaluations: not episodes, ``ResultsStore.evaluations``)
    runs = read_folder(list(files.run_files), list(footers), (), Path(run_dir), footers, files.episode_counts)[0]
    return Results(Path(run_dir), runs, tuple(columns), files)


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


def run_metrics(
    episodes: pd.DataFrame,
    runs: pd.DataFrame | Sequence[dict[str, Any]] | None = None,
    windows: Sequence[tuple[int, int]] = (EARLY, LATE),
) -> pd.DataFrame:
    """
    The metrics of docs/definitions.md, one row per run, sorted by run id (vectorised: numpy reductions over each
    run's rows, no loop over runs):

    - ``decisions_per_episode``, ``cells_per_episode``: means over the run's episodes (the paper's "steps" are decisions)
    - ``first_optimal``: first episode whose path is a shortest path; ``censored`` when none is
    - ``decisions_before_optimal`` / ``cells_before_optimal``: summed over the episodes before it (censored: all)
    - ``greedy_stays_optimal_from``: first episode after which the greedy policy from the start always walks a shortest path
      (NaN, ``greedy_censored``, when it is not optimal after the last episode)
    - ``decisions_to_greedy_optimal``: decisions of episodes 1 .. ``greedy_stays_optimal_from`` (censored: all)
    - ``truncated``: episodes ended by the safety cap
    - ``total_decisions``: every decision of the run, the unfinished last episode included (from the run table)
    - window features (``EARLY``, ``LATE``): ``joy_1_10`` (mean of per-episode fractions), ``joy_1_10_weighted``
      (decision-weighted), the same for every emotion and ``eqeps`` (random-direction decisions), ``decisions_181_200``
      and ``cells_181_200`` (mean decisions and cells per episode of the window)

    :param episodes: one row per episode (``Results.episodes``, or any frame with ``run_id``, the episode columns and
        label columns)
    :param runs: the run table (``Results.runs``) or run records (``load_run_records``): adds each run's total decisions,
        its ``seed`` when ``episodes`` has none, and the runs that finished no episode at all (e.g. a DQN that never
        reached the goal within its step budget): censored, with all their decisions before the optimal path
    :param windows: the (first, last) episode windows of the window features (default ``EARLY`` and ``LATE``)
    """
    rows = _vector_metrics(episodes, windows) if len(episodes) else pd.DataFrame()
    table = _run_table(runs)
    if table is None or not len(table):
        return rows
    totals = pd.Series(table.decisions.to_numpy(), index=pd.Index(table.run_id.to_numpy()))
    totals = totals[~totals.index.duplicated()]
    if len(rows):
        if "seed" not in rows.columns and "agent" in rows.columns:
            seeds = pd.Series(table.seed.to_numpy(), index=pd.Index(table.run_id.to_numpy()))
            place = list(rows.columns).index("agent") + 1
            rows.insert(place, "seed", rows.run_id.map(seeds[~seeds.index.duplicated()]))
        known_totals = pd.to_numeric(rows.run_id.map(totals), errors="coerce")
        known = known_totals.notna()
        rows.loc[known, "total_decisions"] = known_totals[known].astype(int)
        fix = known & rows.censored  # the unfinished last episode was spent before the optimal path too
        rows.loc[fix, "decisions_before_optimal"] = rows.loc[fix, "total_decisions"].astype(float)
        gfix = known & rows.greedy_censored
        rows.loc[gfix, "decisions_to_greedy_optimal"] = rows.loc[gfix, "total_decisions"].astype(float)
    seen = pd.Index(rows.run_id) if len(rows) else pd.Index([])
    missing = table[~table.run_id.isin(seen)]
    if not len(missing):
        return rows
    total = pd.to_numeric(missing.decisions, errors="coerce").fillna(0).astype(float).to_numpy()
    labels = [c for c in missing.columns if c not in _TABLE_COLUMNS]
    extra = pd.DataFrame({"agent": missing.agent.to_numpy(), "seed": missing.seed.to_numpy()})
    for key in labels:
        extra[key] = missing[key].to_numpy()
    extra = extra.assign(
        run_id=missing.run_id.to_numpy(),
        episodes=0,
        censored=True,
        greedy_censored=True,
        decisions_before_optimal=total,
        decisions_to_greedy_optimal=total,
        truncated=0,
        total_decisions=total.astype(int),
    )
    if not len(rows):
        return extra
    return pd.concat([rows, extra], ignore_index=True)


#: Columns of a run table that are not labels.
_TABLE_COLUMNS = ("run_id", "agent", "algo", "seed", "decisions", "episodes", "wall_seconds", "max_timesteps")


def _run_table(runs: pd.DataFrame | Sequence[dict[str, Any]] | None) -> pd.DataFrame | None:
    """The run table from ``Results.runs`` or from run records (``run_id``, ``agent``, ``seed``, labels, ``decisions``)."""
    if runs is None or isinstance(runs, pd.DataFrame):
        return runs
    rows = []
    for record in runs:
        config = record["config"]
        rows.append(
            {
                "run_id": record["run_id"],
                "agent": config["agent"],
                "seed": config["seed"],
                **config["labels"],
                "decisions": record.get("timings", {}).get("decisions"),
            }
        )
    return pd.DataFrame(rows) if rows else None


@dataclass
class _Rows:
    """The episode rows of ``_vector_metrics`` by run: codes, episode numbers and each run's span, sorted."""

    codes: np.ndarray
    names: Any
    episode: np.ndarray
    take: np.ndarray | None
    starts: np.ndarray
    counts: np.ndarray
    run_codes: np.ndarray


def _runs_of(episodes: pd.DataFrame) -> _Rows:
    run_ids = episodes["run_id"]
    names: Any
    if isinstance(run_ids.dtype, pd.CategoricalDtype) and run_ids.cat.categories.is_monotonic_increasing:
        codes, names = run_ids.cat.codes.to_numpy(), run_ids.cat.categories
    else:
        codes, names = pd.factorize(run_ids.to_numpy(dtype=object), sort=True)
    episode = episodes["episode"].to_numpy()
    if episode.dtype.kind not in "iu":
        episode = episode.astype(np.int64)
    # Rows sorted by run (in run id order) and episode: already so when read by load_results.
    ordered = len(codes) < 2 or bool(
        np.all((codes[1:] > codes[:-1]) | ((codes[1:] == codes[:-1]) & (episode[1:] >= episode[:-1])))
    )
    take = None if ordered else np.lexsort((episode, codes))
    if take is not None:
        codes, episode = codes[take], episode[take]
    starts = np.flatnonzero(np.r_[True, codes[1:] != codes[:-1]])
    counts = np.diff(np.r_[starts, len(codes)])
    return _Rows(codes, names, episode, take, starts, counts, codes[starts])


def _column_of(episodes: pd.DataFrame, take: np.ndarray | None) -> Any:
    def column(name: str) -> np.ndarray:
        values = episodes[name]
        if name in ("optimal", "truncated", "greedy_optimal") and values.dtype != bool:
            values = values.eq(True)  # None where an env does not define it
        array = values.to_numpy()
        return array if take is None else array[take]

    return column


def run_windows(
    episodes: pd.DataFrame, windows: Sequence[tuple[int, int]], sources: Sequence[str] | None = None
) -> pd.DataFrame:
    """
    The window features of ``run_metrics`` alone (``run_id``, ``agent`` when there, and each window's columns), one
    row per run with episodes, sorted by run id: the same numbers as ``run_metrics(episodes, windows=windows)``.
    ``sources``: only the features of these (emotions, ``eqeps``, ``cells``; ``decisions`` always), not all.
    """
    if not len(episodes):
        return pd.DataFrame()
    rows = _runs_of(episodes)
    column = _column_of(episodes, rows.take)
    out = pd.DataFrame({"run_id": np.asarray(rows.names)[rows.run_codes]})
    if "agent" in episodes.columns:
        out["agent"] = _labels(episodes["agent"], rows.take, rows.starts, rows.counts)
    for window in windows:
        for key, series in _window(column, rows.starts, rows.counts, rows.episode, *window, sources).items():
            out[key] = series
    return out


def _vector_metrics(episodes: pd.DataFrame, windows: Sequence[tuple[int, int]] = (EARLY, LATE)) -> pd.DataFrame:
    """The per-run metrics of ``run_metrics`` from the episode rows alone (numpy reductions over each run's rows)."""
    rows = _runs_of(episodes)
    names, episode, take = rows.names, rows.episode, rows.take
    starts, counts, run_codes = rows.starts, rows.counts, rows.run_codes
    column = _column_of(episodes, take)

    out = pd.DataFrame(index=pd.Index(np.asarray(names)[run_codes], name="run_id"))
    for name in (c for c in episodes.columns if c not in _EPISODE_VALUE_COLUMNS and c != "run_id"):
        out[name] = _labels(episodes[name], take, starts, counts)
    decisions, cells = column("decisions"), column("cells")  # summed in int64 (reduceat's dtype), not copied
    never = episode.dtype.type(np.iinfo(episode.dtype).max)  # of the episode's own dtype (int32 when read)
    first = np.minimum.reduceat(np.where(column("optimal"), episode, never), starts)
    first_found = first < never
    first_float = np.where(first_found, first, np.nan)
    before = episode < np.repeat(first, counts)
    last_episode = np.maximum.reduceat(episode, starts)
    last_false = np.maximum.reduceat(np.where(column("greedy_optimal"), episode.dtype.type(-1), episode), starts)
    greedy_from = np.where(last_false < 0, 1.0, last_false + 1.0)
    greedy_from[last_false == last_episode] = np.nan
    upto_greedy = episode <= np.repeat(np.where(np.isnan(greedy_from), np.inf, greedy_from), counts)
    out["episodes"] = counts.astype(np.int64)
    total_decisions = np.add.reduceat(decisions, starts, dtype=np.int64)
    out["decisions_per_episode"] = total_decisions / counts
    out["cells_per_episode"] = np.add.reduceat(cells, starts, dtype=np.int64) / counts
    out["first_optimal"] = first_float
    out["censored"] = ~first_found
    out["decisions_before_optimal"] = np.add.reduceat(np.where(before, decisions, 0), starts, dtype=np.int64).astype(float)
    out["cells_before_optimal"] = np.add.reduceat(np.where(before, cells, 0), starts, dtype=np.int64).astype(float)
    out["greedy_stays_optimal_from"] = greedy_from
    out["greedy_censored"] = np.isnan(greedy_from)
    to_greedy = np.add.reduceat(np.where(upto_greedy, decisions, 0), starts, dtype=np.int64)
    out["decisions_to_greedy_optimal"] = to_greedy.astype(float)
    out["truncated"] = np.add.reduceat(column("truncated"), starts, dtype=np.int64)
    out["total_decisions"] = total_decisions
    del decisions, cells, before, upto_greedy
    for window in windows:
        for key, series in _window(column, starts, counts, episode, *window).items():
            out[key] = series
    return out.reset_index()


def _labels(values: pd.Series, take: np.ndarray | None, starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Each run's label value (its first non-missing one; labels are constant within a run) as a plain array."""
    if isinstance(values.dtype, pd.CategoricalDtype):
        codes = values.cat.codes.to_numpy()
        codes = codes if take is None else codes[take]
        first = np.asarray(values.cat.categories.take(codes[starts], allow_fill=True))
        if (codes[starts] >= 0).all():
            return first
        plain = np.asarray(values.to_numpy())
    else:
        plain = values.to_numpy()
        first = plain[starts] if take is None else plain[take[starts]]
        if not pd.isna(first).any():
            return first
    plain = plain if take is None else plain[take]
    return pd.Series(plain).groupby(np.repeat(np.arange(len(starts)), counts)).first().to_numpy()


def _window(
    column: Any,
    starts: np.ndarray,
    counts: np.ndarray,
    episode: np.ndarray,
    lo: int,
    hi: int,
    sources: Sequence[str] | None = None,
) -> dict[str, np.ndarray]:
    """
    Per run: mean over the window's episodes of per-episode fractions, and decision-weighted fractions (NaN: a run
    without episodes in the window), with pandas' groupby arithmetic in row order (``estimation.grouped_sums``); ``sources``:
    only these (``run_windows``).
    """
    first, last = window_bounds(episode, starts, counts, lo, hi)
    absent = first == last
    decisions = column("decisions")
    means, total = segment_means(decisions, first, last)
    total = np.where(absent | ~(total > 0), np.nan, total)
    out: dict[str, np.ndarray] = {}
    for name, source in (*((x, x) for x in EMOTIONS), ("eqeps", "random_moves")):
        if sources is not None and name not in sources:
            continue
        fraction, summed = segment_means(column(source), first, last, decisions)
        out[f"{name}_{lo}_{hi}"] = fraction
        out[f"{name}_{lo}_{hi}_weighted"] = np.where(absent, np.nan, summed) / total
    out[f"decisions_{lo}_{hi}"] = means
    if sources is None or "cells" in sources:
        out[f"cells_{lo}_{hi}"] = segment_means(column("cells"), first, last)[0]
    return out


def plain_labels(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with its categorical columns as plain values (for small tables grouped by label with pandas)."""
    categorical = [c for c in frame.columns if isinstance(frame[c].dtype, pd.CategoricalDtype)]
    return frame.assign(**{c: np.asarray(frame[c]) for c in categorical}) if categorical else frame


def profile(episodes: pd.DataFrame) -> pd.DataFrame:
    """
    Per episode number: the mean over runs of each emotion's fraction of decisions and of the equivalent epsilon,
    with a 95% band of the mean (mean +- 1.96 standard errors over runs: ``_lo`` / ``_hi``), and the
    decision-weighted fraction (all decisions of that episode number pooled over runs: ``_weighted``) with its 95%
    band over runs (the ratio estimator's delta-method standard error: ``_weighted_lo`` / ``_weighted_hi``).

    One column at a time (memory: a few columns of ``episodes``, whatever its length).
    """
    episode = episodes.episode.to_numpy()
    decisions = episodes.decisions.to_numpy()
    totals = pd.Series(decisions.astype(np.int64)).groupby(episode).sum()
    kinds = ("mean", "lo", "hi", "weighted", "weighted_lo", "weighted_hi")
    parts: dict[str, dict[str, pd.Series]] = {kind: {} for kind in kinds}
    for name, source in (*((x, x) for x in EMOTIONS), ("equivalent_epsilon", "random_moves")):
        values = episodes[source].to_numpy()
        grouped = pd.Series(values / decisions).groupby(episode)
        mean = grouped.mean()
        half = 1.96 * grouped.sem().fillna(0.0)
        parts["mean"][name], parts["lo"][name], parts["hi"][name] = mean, mean - half, mean + half
        summed = pd.Series(values.astype(np.int64) if values.dtype.kind in "iu" else values).groupby(episode).sum()
        ratio = summed / totals
        parts["weighted"][name] = ratio
        # the ratio's 95% band over runs (delta method): se = sd(x_i - R d_i) / (sqrt(n) mean(d_i)) per episode
        residual = pd.Series(values - ratio.reindex(episode).to_numpy() * decisions).groupby(episode)
        per_run_decisions = pd.Series(decisions.astype(float)).groupby(episode).mean()
        half_weighted = 1.96 * (residual.std(ddof=1) / np.sqrt(residual.count()) / per_run_decisions).fillna(0.0)
        parts["weighted_lo"][name], parts["weighted_hi"][name] = ratio - half_weighted, ratio + half_weighted
    out = pd.concat([pd.DataFrame(series).add_suffix(f"_{kind}") for kind, series in parts.items()], axis=1)
    out.index = out.index.astype(np.int64).rename("episode")
    return out


def window_mean(prof: pd.DataFrame, column: str, first: int, last: int, kind: str = "mean") -> float:
    """Mean of a profile column (``kind`` ``mean`` or ``weighted``) over episodes ``first..last``."""
    window = prof.loc[(prof.index >= first) & (prof.index <= last), f"{column}_{kind}"]
    return float(window.mean()) if len(window) else math.nan
