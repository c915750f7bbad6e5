"""
The report's one pass over the paper sweep's episode rows: every number a section draws from episode rows (not from
per-run metrics) is reduced here, part by part, while the rows are read once.

``paper_scan(ctx)`` reads the folder about ``RUNS_PER_PART`` runs at a time, each agent's runs in run id order
(``ResultsStore.results_parts(ordered=True)``), and gathers:

- the per-run metrics (``run_metrics``; the table ``Results.metrics`` gives), with the extra windows of the windows
  section for the affective agent;
- the largest episode number of each agent;
- the learning curves' counts: per (agent, ε) and episode number, how many runs took each number of decisions;
- the affective agent's settled window (``settled.settled_part``) and its per-episode emotion profile (``profile``:
  a second pass over its rows for the delta-method bands, which need the pooled ratios of the first).

Every reduction either sums integers (exact in any order) or adds floats in the order a whole-frame pandas groupby
would (``estimation.grouped_sums``), so the numbers are those of the whole-frame computations (test_report_lean.py).
Memory: one part's rows, the per-run table, the settled window's decisions and joy (8 bytes an episode of it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from sb3_affect.study.report.estimation.grouped_sums import KahanSums, Welford
from sb3_affect.study.report.reading import run_tables as metrics_module
from sb3_affect.study.report.reading.context import AFFECTIVE
from sb3_affect.study.report.reading.run_tables import (
    EARLY,
    EARLY_WINDOWS,
    EMOTIONS,
    LATE,
    LATE_WINDOWS,
    Results,
    join_parts,
    run_metrics,
    run_windows,
)
from sb3_affect.study.report.reading.settled_window import SETTLED, settled_part

if TYPE_CHECKING:
    from sb3_affect.study.report.reading.context import ReportContext

#: The profile's sources: each emotion, and the equivalent ε (random-direction decisions).
SOURCES = (*((x, x) for x in EMOTIONS), ("equivalent_epsilon", "random_moves"))
_KINDS = ("mean", "lo", "hi", "weighted", "weighted_lo", "weighted_hi")
#: The window features the windows section reads (Figs. 5 and 6: joy and anger, both weightings; equivalent ε).
WINDOW_SOURCES = ("joy", "anger", "eqeps")


@dataclass
class Scan:
    """
    What the sections read of the paper sweep's episode rows (``paper_scan``).

    :param metrics: ``run_metrics`` of every run (windows ``EARLY`` and ``LATE``), as ``Results.metrics()``
    :param windows: the profile agent's runs with episodes: ``run_id``, ``agent`` and the window features of
        ``EARLY``, ``LATE`` and ``extra_windows`` (``metrics.run_windows``) the windows section reads (``WINDOW_SOURCES``)
    :param last_episode: per agent, its largest episode number
    :param curves: per (agent, ε label or None), ``(keys, counts)``: the (episode number, decisions) pairs of its
        rows (``_pair_key``), sorted, and how many rows have each
    :param settled: the profile agent's ``settled.settled_part`` pieces of its settled window, joined over its runs,
        and the window ``(first, last)``; None when the agent has no rows there
    :param profile: the profile agent's ``metrics.profile``
    """

    metrics: pd.DataFrame
    windows: pd.DataFrame
    last_episode: dict[str, int]
    curves: dict[tuple[str, Any], tuple[np.ndarray, np.ndarray]]
    settled: tuple[tuple[int, int], pd.DataFrame, np.ndarray, np.ndarray] | None
    profile: pd.DataFrame | None = None


def paper_scan(ctx: ReportContext) -> Scan:
    """The scan of ``ctx.paper`` (made on first use, then kept in ``ctx.cache``)."""
    if "scan" not in ctx.cache:
        ctx.cache["scan"] = scan(ctx.paper, (*EARLY_WINDOWS, *LATE_WINDOWS))
    found: Scan = ctx.cache["scan"]
    return found


def scan(
    results: Results,
    extra_windows: Sequence[tuple[int, int]] = (),
    agent: str = AFFECTIVE,
) -> Scan:
    """
    One pass over ``results``' episode rows (and a second over ``agent``'s, for the profile's bands).

    :param extra_windows: window features computed for ``agent``'s runs besides ``EARLY`` and ``LATE``
    :param agent: the agent of the windows, the settled window and the profile (the affective agent)
    """
    runs = results.runs
    columns = tuple(dict.fromkeys((*results.columns, *metrics_module.REPORT_COLUMNS)))
    windows = tuple(dict.fromkeys((EARLY, LATE, *extra_windows)))
    frames: list[pd.DataFrame] = []
    window_frames: list[pd.DataFrame] = []
    last: dict[str, int] = {}
    curves: dict[tuple[str, Any], list[tuple[np.ndarray, np.ndarray]]] = {}
    predicted = int(runs.episodes[runs.agent == agent].max()) if (runs.agent == agent).any() else 0
    window = (SETTLED[0] if predicted >= SETTLED[1] else max(1, predicted // 4), predicted)
    pieces: list[tuple[pd.DataFrame, np.ndarray, np.ndarray]] = []
    first_pass = _ProfileSums()

    def read(name: str, part_runs: pd.DataFrame, part: pd.DataFrame) -> tuple[Any, ...]:
        """A part and its learning-curve counts and settled pieces."""
        counted = _part_curves(name, part) if len(part) else []
        return name, part_runs, part, counted, _settled(part, *window) if name == agent and len(part) else None

    every_part = (
        read(name, *found)
        for name in sorted(set(runs.agent))
        for found in results.parts(columns, name, metrics_module.RUNS_PER_PART, ordered=True)
    )
    for name, part_runs, part, counted, piece in every_part:
        frames.append(run_metrics(part, part_runs))
        for key, counts in counted:
            curves.setdefault(key, []).append(counts)
        if not len(part):
            continue
        episode = part.episode.to_numpy()
        last[name] = max(last.get(name, 0), int(episode.max()))
        if name == agent:
            window_frames.append(_narrowed(run_windows(part, windows, WINDOW_SOURCES)))
            pieces.append(piece)
            first_pass.add(part)
        del part, episode, piece
    table = join_parts(frames)
    del frames
    windows_table = pd.concat(window_frames, ignore_index=True) if window_frames else pd.DataFrame()  # in run id order
    if "agent" in windows_table.columns:  # compared with an agent's name by every claim judged on it: codes, not text
        windows_table["agent"] = pd.Categorical(windows_table["agent"])
    del window_frames
    settled = None
    if pieces and last.get(agent) == predicted and predicted:
        per_run = pd.concat([p[0] for p in pieces], ignore_index=True)
        settled = (window, per_run, _joined([p[1] for p in pieces]), _joined([p[2] for p in pieces]))
    del pieces
    profile = first_pass.second_pass(results, agent) if first_pass.groups else None
    merged = {key: merge_curves(parts) for key, parts in curves.items()}
    return Scan(table, windows_table, last, merged, settled, profile)


def _narrowed(windows: pd.DataFrame) -> pd.DataFrame:
    """The columns of ``run_windows`` the windows section reads (``WINDOW_SOURCES``)."""
    kept = [c for c in windows.columns if c in ("run_id", "agent") or c.split("_")[0] in WINDOW_SOURCES]
    return windows[[c for c in kept if not (c.startswith("eqeps") and c.endswith("_weighted"))]]


def _settled(part: pd.DataFrame, first: int, last: int) -> tuple[pd.DataFrame, np.ndarray, np.ndarray]:
    per_run, decisions, joy = settled_part(part, first, last)
    return per_run, _compact(decisions), _compact(joy)


def _compact(values: np.ndarray) -> np.ndarray:
    """Integer ``values`` as int16 when they fit (the same numbers in a quarter of int64's bytes), else as they are."""
    if values.dtype.kind == "i" and (not len(values) or (values.min() >= -(2**15) and values.max() < 2**15)):
        return values.astype(np.int16)
    return values


def _joined(pieces: list[np.ndarray]) -> np.ndarray:
    """Integer pieces end to end, in the widest dtype among them."""
    return np.concatenate(pieces) if pieces else np.zeros(0, np.int32)


#: Pairs (episode number, decisions) as one int64 key, ordered as the pairs (decisions within +- 2**31).
_SHIFT = 32


def _pair_key(episode: np.ndarray, decisions: np.ndarray) -> np.ndarray:
    return (episode.astype(np.int64) << _SHIFT) + decisions.astype(np.int64)


def pair_split(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(episode, decisions)`` of ``_pair_key`` keys."""
    episode = (keys + (1 << (_SHIFT - 1))) >> _SHIFT
    return episode, keys - (episode << _SHIFT)


def _counted(episode: np.ndarray, decisions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct (episode, decisions) pairs of rows, sorted, and their counts (a dense count when the span is small)."""
    if not len(episode):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    e0, d0 = int(episode.min()), int(decisions.min())
    rows, span = int(episode.max()) - e0 + 1, int(decisions.max()) - d0 + 1
    if rows * span <= 4 * len(episode) + 1_000_000:
        counts = np.bincount((episode.astype(np.int64) - e0) * span + (decisions.astype(np.int64) - d0), minlength=rows * span)
        where = np.flatnonzero(counts)
        return _pair_key(where // span + e0, where % span + d0), counts[where].astype(np.int64)
    keys, counts = np.unique(_pair_key(episode, decisions), return_counts=True)
    return keys, counts.astype(np.int64)


def merge_curves(curves: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """Learning-curve counts of several groups as one (their rows pooled)."""
    keys = np.concatenate([k for k, _ in curves])
    counts = np.concatenate([c for _, c in curves])
    unique, inverse = np.unique(keys, return_inverse=True)
    return unique, np.bincount(inverse, weights=counts, minlength=len(unique)).astype(np.int64)


def _part_curves(agent: str, part: pd.DataFrame) -> list[tuple[tuple[str, Any], tuple[np.ndarray, np.ndarray]]]:
    """A part's learning-curve counts (``_counted``) per (agent, ε label or None)."""
    episode, decisions = part.episode.to_numpy(), part.decisions.to_numpy()
    if "epsilon" not in part.columns:
        return [((agent, None), _counted(episode, decisions))]
    labels = part.epsilon
    codes = labels.cat.codes.to_numpy() if isinstance(labels.dtype, pd.CategoricalDtype) else pd.factorize(labels)[0]
    names = labels.cat.categories if isinstance(labels.dtype, pd.CategoricalDtype) else pd.factorize(labels)[1]
    out = []
    for code in np.unique(codes):
        rows = codes == code
        value = None if code < 0 else names[code]
        out.append(((agent, value), _counted(episode[rows], decisions[rows])))
    return out


def curve_quantiles(
    keys: np.ndarray, counts: np.ndarray, quantiles: tuple[float, ...] = (0.25, 0.5, 0.75)
) -> tuple[np.ndarray, list[np.ndarray]]:
    """
    ``figures.episode_quantiles`` from the counts of (episode, decisions) pairs: per episode number, the quantiles
    (linear interpolation) of decisions over the rows, the same numbers as from the rows themselves.
    """
    episode, decisions = pair_split(keys)
    episodes, first = np.unique(episode, return_index=True)
    totals = np.add.reduceat(counts, first) if len(first) else np.zeros(0, np.int64)
    ends = np.cumsum(counts)  # rows sorted by (episode, decisions): pair i holds rows ends[i] - counts[i] .. ends[i] - 1
    starts = np.r_[0, np.cumsum(totals)[:-1]].astype(np.int64)
    out = []
    for q in quantiles:
        h = (totals - 1) * q
        below = np.floor(h).astype(np.int64)
        above = np.minimum(below + 1, totals - 1)
        lo = decisions[np.searchsorted(ends, starts + below, side="right")].astype(float)
        hi = decisions[np.searchsorted(ends, starts + above, side="right")].astype(float)
        out.append(lo + (h - below) * (hi - lo))
    return episodes, out


class _ProfileSums:
    """``metrics.profile`` of one agent's rows fed in run id order: sums in a first pass, bands in a second."""

    def __init__(self) -> None:
        self.groups = 0
        self.rows = np.zeros(0, np.int64)
        self.decisions = np.zeros(0, np.int64)
        self.sums: dict[str, np.ndarray] = {}
        self.float_sums: dict[str, KahanSums] = {}
        self.fractions = {name: KahanSums() for name, _ in SOURCES}
        self.spread = {name: Welford() for name, _ in SOURCES}

    def _grow(self, groups: int) -> None:
        if groups > self.groups:
            pad = groups - len(self.rows)
            self.rows = np.r_[self.rows, np.zeros(pad, np.int64)]
            self.decisions = np.r_[self.decisions, np.zeros(pad, np.int64)]
            self.sums = {k: np.r_[v, np.zeros(pad, np.int64)] for k, v in self.sums.items()}
            self.groups = groups

    def add(self, part: pd.DataFrame) -> None:
        episode = part.episode.to_numpy().astype(np.int64)
        decisions = part.decisions.to_numpy()
        groups = int(episode.max()) + 1
        self._grow(groups)
        self.rows += np.bincount(episode, minlength=self.groups)
        self.decisions += _int_sums(episode, decisions, self.groups)
        for name, source in SOURCES:
            values = part[source].to_numpy()
            self.fractions[name].add(values / decisions, episode, self.groups)
            self.spread[name].add(values / decisions, episode, self.groups)
            if values.dtype.kind in "iu":
                self.sums[name] = self.sums.get(name, np.zeros(self.groups, np.int64)) + _int_sums(
                    episode, values, self.groups
                )
            else:
                self.float_sums.setdefault(name, KahanSums()).add(values, episode, self.groups)

    def second_pass(self, results: Results, agent: str) -> pd.DataFrame:
        """The bands of the decision-weighted fractions (a second read of the agent's rows), and the profile."""
        present = np.flatnonzero(self.rows)
        totals = self.decisions
        ratios: dict[str, np.ndarray] = {}
        for name, _ in SOURCES:
            summed = self.sums[name] if name in self.sums else _padded(self.float_sums[name].sums, self.groups)
            with np.errstate(invalid="ignore", divide="ignore"):
                ratios[name] = summed / totals
        residuals = {name: Welford() for name, _ in SOURCES}
        wanted = ("episode", "decisions", *(source for _, source in SOURCES))
        for _, part in results.parts(wanted, agent, metrics_module.RUNS_PER_PART, ordered=True):
            if not len(part):
                continue
            episode = part.episode.to_numpy().astype(np.int64)
            decisions = part.decisions.to_numpy()
            for name, source in SOURCES:
                values = part[source].to_numpy()
                residuals[name].add(values - ratios[name][episode] * decisions, episode, self.groups)
            del part
        index = pd.Index(present.astype(np.int64))
        series: dict[str, dict[str, pd.Series]] = {kind: {} for kind in _KINDS}
        per_run_decisions = pd.Series(totals[present] / self.rows[present], index=index)
        for name, _ in SOURCES:
            mean = pd.Series(_padded(self.fractions[name].mean(), self.groups)[present], index=index)
            half = 1.96 * pd.Series(_padded(self.spread[name].sem(), self.groups)[present], index=index).fillna(0.0)
            series["mean"][name], series["lo"][name], series["hi"][name] = mean, mean - half, mean + half
            ratio = pd.Series(ratios[name][present], index=index)
            series["weighted"][name] = ratio
            residual = residuals[name]
            std = pd.Series(_padded(residual.std(), self.groups)[present], index=index)
            count = pd.Series(_padded(residual.nobs, self.groups)[present], index=index)
            half_weighted = 1.96 * (std / np.sqrt(count) / per_run_decisions).fillna(0.0)
            series["weighted_lo"][name], series["weighted_hi"][name] = ratio - half_weighted, ratio + half_weighted
        out = pd.concat([pd.DataFrame(parts).add_suffix(f"_{kind}") for kind, parts in series.items()], axis=1)
        out.index = out.index.astype(np.int64).rename("episode")
        return out


def _int_sums(labels: np.ndarray, values: np.ndarray, groups: int) -> np.ndarray:
    """Per group, the sum of integer ``values`` (int64; exact: float64 holds every integer below 2**53)."""
    return np.bincount(labels, weights=values, minlength=groups).astype(np.int64)


def _padded(array: np.ndarray, size: int) -> np.ndarray:
    return array if len(array) >= size else np.r_[array, np.zeros(size - len(array), array.dtype)]
