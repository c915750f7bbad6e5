"""
The report read a part at a time (runs in parts, one agent's rows, the profile in ranges of episode numbers) gives
the numbers of the whole-frame computation: the same per-run metrics, profile and rows, and the same report. The one
pass (``reading.episode_scan``), its compiled grouped arithmetic (``estimation.grouped_sums``) and the kept bootstrap resamples
(``report.estimation.resamples``) give the numbers of the pandas and numpy code they replace, to the last bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.launcher.folder_reading import ordered_file_parts
from sb3_affect.study.report.build import build_report
from sb3_affect.study.report.estimation import resamples
from sb3_affect.study.report.estimation.bootstrap import (
    BLOCK_CELLS,
    bootstrap_ci,
    bootstrap_improvement,
    bootstrap_iqm_cis,
    iqm,
)
from sb3_affect.study.report.estimation.grouped_sums import KahanSums, Welford
from sb3_affect.study.report.reading import run_tables, settled_window
from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD
from sb3_affect.study.report.reading.episode_scan import curve_quantiles, merge_curves, scan
from sb3_affect.study.report.reading.run_tables import (
    EMOTIONS,
    REPORT_COLUMNS,
    load_results,
    profile,
    run_metrics,
    run_windows,
)
from sb3_affect.study.report.reading.settled_window import settled_numbers, settled_part
from sb3_affect.study.report.rendering.figures import episode_quantiles
from sb3_affect.study.report.sections import mechanism

ROOT = Path(__file__).resolve().parents[3]
PAPER = ROOT / "experiments" / "paper.yaml"


@pytest.fixture(scope="module")
def paper5(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's sweep at 5 seeds per cell (90 runs of 200 episodes, 18 chunks): enough for every section."""
    folder = tmp_path_factory.mktemp("lean") / "paper5"
    run_sweep(PAPER, folder, workers=1, overrides=["seeds=5"], progress=False)
    return folder


def test_parts_give_the_whole_frame_numbers(paper5: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run_tables, "RUNS_PER_PART", 7)  # several chunks a part, 13 parts
    results = load_results(paper5)
    whole_runs, whole = ResultsStore(paper5).results(REPORT_COLUMNS, seed=False)
    pd.testing.assert_frame_equal(results.runs, whole_runs)
    assert len(list(results.parts(("episode",), runs_per_part=7))) > 2
    pd.testing.assert_frame_equal(results.metrics(), run_metrics(whole, whole_runs))
    windows = ((1, 5), (11, 30), (191, 200))
    aff_rows = whole[whole.agent == AFFECTIVE]
    pd.testing.assert_frame_equal(results.metrics(AFFECTIVE, windows, with_runs=False), run_metrics(aff_rows, windows=windows))
    for agent in (STANDARD, AFFECTIVE):
        part = results.agent_episodes(agent, ("episode", "decisions", "joy"), 181, 200)
        mask = (whole.agent == agent) & (whole.episode >= 181) & (whole.episode <= 200)
        expected = whole.loc[mask].reset_index(drop=True)
        assert list(part.run_id.cat.categories) == sorted(set(expected.run_id.astype(str)))
        for column in ("episode", "decisions", "joy", "epsilon"):
            np.testing.assert_array_equal(np.asarray(part[column]), np.asarray(expected[column]), err_msg=column)
        np.testing.assert_array_equal(part.run_id.astype(str).to_numpy(), expected.run_id.astype(str).to_numpy())
    assert results.last_episode(AFFECTIVE) == int(aff_rows.episode.max()) == 200
    window = results.agent_episodes(AFFECTIVE, ("episode", "decisions", "joy"), 151, 200)
    assert settled_numbers(*settled_part(window, 151, 200)) == settled_numbers(*settled_part(aff_rows, 151, 200))
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 7)  # ranges of episode numbers, the last one short

    class Ctx:
        paper = results

    pd.testing.assert_frame_equal(mechanism.agent_profile(Ctx(), AFFECTIVE, 200), profile(aff_rows))  # type: ignore[arg-type]
    pd.testing.assert_frame_equal(results.episodes, whole)  # the whole frame is still there for small folders


def test_the_report_read_in_parts_equals_the_report_read_whole(
    paper5: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every table and the text, byte for byte: parts of 7 runs and 7 episode numbers against one part of all."""
    monkeypatch.setattr(run_tables, "RUNS_PER_PART", 10**9)
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 10**9)
    build_report(paper5, out=tmp_path / "whole")
    monkeypatch.setattr(run_tables, "RUNS_PER_PART", 7)
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 7)
    build_report(paper5, out=tmp_path / "parts")
    tables = sorted(p.name for p in (tmp_path / "whole" / "tables").glob("*.csv"))
    assert len(tables) >= 10 and tables == sorted(p.name for p in (tmp_path / "parts" / "tables").glob("*.csv"))
    for name in tables:
        assert (tmp_path / "parts" / "tables" / name).read_bytes() == (tmp_path / "whole" / "tables" / name).read_bytes(), name
    pages = sorted(p.name for p in (tmp_path / "whole").glob("*.md"))
    assert "report.md" in pages and len(pages) > 1 and pages == sorted(p.name for p in (tmp_path / "parts").glob("*.md"))
    for name in pages:  # the main text and every appendix page
        assert (tmp_path / "parts" / name).read_text() == (tmp_path / "whole" / name).read_text(), name


# -- the one pass (episode_scan), the compiled grouped arithmetic (grouped_sums) and the kept resamples ------------------


def _pandas_window(episodes: pd.DataFrame, lo: int, hi: int) -> pd.DataFrame:
    """The window features as pandas groupby computed them before the compiled loop (the reference)."""
    rows = episodes[(episodes.episode >= lo) & (episodes.episode <= hi)]
    key = rows.run_id.astype(str).to_numpy()
    runs = sorted(set(episodes.run_id.astype(str)))
    decisions = pd.Series(rows.decisions.to_numpy())
    fraction_of = decisions.where(decisions > 0).to_numpy()
    total = decisions.groupby(key).sum().reindex(runs).to_numpy()
    total = np.where(total > 0, total, np.nan)
    out = {}
    for name, source in (*((x, x) for x in EMOTIONS), ("eqeps", "random_moves")):
        values = pd.Series(rows[source].to_numpy())
        out[f"{name}_{lo}_{hi}"] = (values / fraction_of).groupby(key).mean().reindex(runs).to_numpy()
        out[f"{name}_{lo}_{hi}_weighted"] = values.groupby(key).sum().reindex(runs).to_numpy() / total
    out[f"decisions_{lo}_{hi}"] = decisions.groupby(key).mean().reindex(runs).to_numpy()
    out[f"cells_{lo}_{hi}"] = pd.Series(rows.cells.to_numpy()).groupby(key).mean().reindex(runs).to_numpy()
    return pd.DataFrame(out, index=runs)


def test_grouped_sums_are_pandas_groupby_to_the_last_bit() -> None:
    rng = np.random.default_rng(3)
    n, groups = 20_000, 40
    labels = rng.integers(0, groups - 2, n)  # the last two groups hold no row
    values = rng.random(n) * 10.0 ** rng.integers(-6, 6, n)
    values[rng.random(n) < 0.05] = np.nan
    values[labels == 5] = np.nan  # a group of missing values only
    values[labels == 7] = [np.inf, *values[labels == 7][1:]]
    values[np.flatnonzero(labels == 9)[1:]] = np.nan  # a group of one value
    sums, spread = KahanSums(), Welford()
    for part in np.array_split(np.arange(n), 7):  # fed a part at a time, in order
        sums.add(values[part], labels[part], groups)
        spread.add(values[part], labels[part], groups)
    grouped = pd.Series(values).groupby(labels)
    seen = grouped.mean().index.to_numpy()
    for name, expected, got in (
        ("mean", grouped.mean(), sums.mean()),
        ("sum", grouped.sum(), sums.sums),
        ("sem", grouped.sem(), spread.sem()),
        ("std", grouped.std(), spread.std()),
        ("count", grouped.count(), spread.nobs),
    ):
        np.testing.assert_array_equal(got[seen], expected.to_numpy(), err_msg=name)
    assert np.isnan(sums.mean()[-2:]).all() and (sums.sums[-2:] == 0).all()


def test_window_features_are_the_pandas_groupby_numbers(paper5: Path) -> None:
    """With missing equivalent ε, episodes of no decision, and windows no run reaches or only some runs reach."""
    _, whole = ResultsStore(paper5).results(REPORT_COLUMNS, seed=False)
    whole = whole.copy()
    whole.loc[whole.index % 7 == 0, "random_moves"] = np.nan
    whole.loc[whole.index % 11 == 0, "decisions"] = 0
    short = whole.run_id.astype(str).isin(sorted(set(whole.run_id.astype(str)))[:3]) & (whole.episode > 150)
    whole = whole[~short].reset_index(drop=True)  # three runs stop at episode 150
    windows = ((1, 10), (140, 160), (151, 200), (300, 400))
    got = run_windows(whole, windows).set_index("run_id")
    for window in windows:
        expected = _pandas_window(whole, *window)
        for column in expected.columns:
            np.testing.assert_array_equal(got[column].to_numpy(), expected[column].to_numpy(), err_msg=column)
    assert got["joy_300_400"].isna().all() and got["joy_151_200"].isna().sum() == 3


def test_ordered_parts_follow_run_id_order(paper5: Path) -> None:
    files = ResultsStore(paper5).checked_files()
    parts = ordered_file_parts(list(files.run_files), files.chunk_files, 7)
    assert len(parts) > 2
    seen: list[str] = []
    for json_part, chunk_part in parts:
        ids = sorted([p.stem for p in json_part] + [r[0] for p in chunk_part for r in files.chunk_files[p]["runs"]])
        assert not seen or ids[0] > seen[-1]  # every run of a part after every run of the parts before
        seen.extend(ids)
    assert len(seen) == 90 and seen == sorted(seen)


def test_the_scan_gives_the_whole_frame_numbers(paper5: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(run_tables, "RUNS_PER_PART", 7)
    results = load_results(paper5)
    whole_runs, whole = ResultsStore(paper5).results(REPORT_COLUMNS, seed=False)
    extra = ((1, 5), (11, 30), (191, 200))
    found = scan(results, extra)
    pd.testing.assert_frame_equal(found.metrics, run_metrics(whole, whole_runs), check_exact=True)
    aff_rows = whole[whole.agent == AFFECTIVE]
    aff = run_metrics(aff_rows, windows=(run_tables.EARLY, run_tables.LATE, *extra))
    assert list(found.windows.run_id) == list(aff.run_id)
    for column in found.windows.columns.drop(["run_id", "agent"]):
        np.testing.assert_array_equal(found.windows[column].to_numpy(), aff[column].to_numpy(), err_msg=column)
    assert {"joy_1_5", "anger_191_200_weighted", "eqeps_11_30"} <= set(found.windows.columns)
    pd.testing.assert_frame_equal(found.profile, profile(aff_rows), check_exact=True)
    assert found.settled is not None
    window, per_run, decisions, joy = found.settled
    assert window == (51, 200) and found.last_episode == {AFFECTIVE: 200, STANDARD: 200}
    assert settled_numbers(per_run, decisions, joy) == settled_numbers(*settled_part(aff_rows, 51, 200))
    for (agent, eps), counts in found.curves.items():
        rows = whole[(whole.agent == agent) & (whole.epsilon == eps)]
        episodes, quartiles = episode_quantiles(rows.episode.to_numpy(), rows.decisions.to_numpy())
        got_episodes, got = curve_quantiles(*counts)
        np.testing.assert_array_equal(got_episodes, episodes)
        for a, b in zip(got, quartiles):
            np.testing.assert_array_equal(a, b)
    pooled = curve_quantiles(*merge_curves([c for (agent, _), c in found.curves.items() if agent == AFFECTIVE]))
    expected = episode_quantiles(aff_rows.episode.to_numpy(), aff_rows.decisions.to_numpy())
    np.testing.assert_array_equal(pooled[0], expected[0])
    for a, b in zip(pooled[1], expected[1]):
        np.testing.assert_array_equal(a, b)


def _draw_by_draw_ci(values: np.ndarray, statistic: str, n_boot: int, seed: int) -> tuple[float, float, float]:
    """``stats.bootstrap_ci`` as it drew and reduced each resample before the kept draws (the reference)."""
    data = values[~np.isnan(values)]
    rng = np.random.default_rng(seed)
    if statistic == "iqm":
        n = len(data)
        order = np.argsort(data, kind="stable")
        ordered = data[order]
        low, high = int(0.25 * n), n - int(0.25 * n)
        boots = np.empty(n_boot)
        for rep in range(n_boot):
            drawn = np.bincount(rng.integers(0, n, n), minlength=n)[order]
            end = np.cumsum(drawn)
            first, last = np.searchsorted(end, low, side="right"), np.searchsorted(end, high, side="left")
            if first == last:
                total = ordered[first] * (high - low)
            else:
                summed = np.cumsum(ordered * drawn)
                middle = summed[last - 1] - summed[first]
                total = ordered[first] * (end[first] - low) + middle + ordered[last] * (high - end[last] + drawn[last])
            boots[rep] = total / (high - low)
        point = iqm(data)
    else:
        block = max(1, BLOCK_CELLS // len(data))  # rows reduced together, as then (the rounding of a mean depends on it)
        boots = np.concatenate(
            [
                data[rng.integers(0, len(data), size=(min(block, n_boot - first), len(data)))].mean(axis=1)
                for first in range(0, n_boot, block)
            ]
        )
        point = float(np.mean(data))
    tail = (1 - 0.95) / 2 * 100  # as stats computes it (not quite 2.5)
    return point, float(np.percentile(boots, tail)), float(np.percentile(boots, 100 - tail))


def _draw_by_draw_improvement(x: np.ndarray, y: np.ndarray, n_boot: int, seed: int, lower: bool) -> tuple[float, float]:
    order = np.argsort(y, kind="stable")
    ordered = y[order]
    below, not_above = np.searchsorted(ordered, x, side="left"), np.searchsorted(ordered, x, side="right")
    rng = np.random.default_rng(seed)
    boots = np.empty(n_boot)
    for rep in range(n_boot):
        weights = np.bincount(rng.integers(0, len(x), len(x)), minlength=len(x))
        drawn = np.r_[0, np.cumsum(np.bincount(rng.integers(0, len(y), len(y)), minlength=len(y))[order])]
        at_most, under = drawn[not_above], drawn[below]
        better = (len(y) - at_most) if lower else under
        boots[rep] = (int(weights @ better) + 0.5 * int(weights @ (at_most - under))) / (len(x) * len(y))
    tail = (1 - 0.95) / 2 * 100
    return float(np.percentile(boots, tail)), float(np.percentile(boots, 100 - tail))


@pytest.mark.parametrize("whole", [resamples.WHOLE_CELLS, 100])  # draws drawn whole, and a block at a time
def test_bootstraps_are_the_draw_by_draw_numbers(whole: int, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(resamples, "WHOLE_CELLS", whole)
    rng = np.random.default_rng(8)
    for n in (1, 2, 5, 64, 301, 4000):
        for values in (rng.integers(0, 40, n).astype(float), rng.lognormal(3.0, 2.0, n)):  # ties, and none
            values[: n // 10] = np.nan if n > 20 else values[: n // 10]
            for statistic in ("mean", "iqm"):
                expected = _draw_by_draw_ci(values, statistic, 120, n)
                assert bootstrap_ci(values, statistic, n_boot=120, seed=n) == expected, (n, statistic)
                assert bootstrap_ci(values, statistic, n_boot=120, seed=n) == expected, (n, statistic)  # drawn again
            shared = [values, values[::-1] * 2.0, np.sqrt(np.abs(values))]  # one size: one set of draws
            assert bootstrap_iqm_cis(shared, n_boot=120, seed=n) == [_draw_by_draw_ci(v, "iqm", 120, n) for v in shared]
            mixed = [values, values[: max(1, n // 2)]]  # sizes differ: each its own draws
            assert bootstrap_iqm_cis(mixed, n_boot=120, seed=n) == [_draw_by_draw_ci(v, "iqm", 120, n) for v in mixed]
            other = rng.lognormal(3.0, 2.0, max(1, n // 3))
            for lower in (True, False):
                got = bootstrap_improvement(values[~np.isnan(values)], other, n_boot=40, seed=2, lower_is_better=lower)
                assert got[1:] == _draw_by_draw_improvement(values[~np.isnan(values)], other, 40, 2, lower), (n, lower)


def test_the_mechanism_bootstrap_of_integer_sums_is_the_gathered_one() -> None:
    """Counts times values (integers: exact) against the values gathered and added, for the same seeded draws."""
    rng = np.random.default_rng(4)
    per_run = pd.DataFrame({"a": rng.integers(0, 50, 3001).astype(float), "b": rng.integers(1, 90, 3001).astype(float)})
    statistics = {"a over b": "a/b", "b over a": "b/a"}
    got = settled_window._bootstrap(per_run, statistics, reps=300, seed=3)
    draws = np.random.default_rng(3).integers(0, 3001, size=(300, 3001))
    for key, ratio in statistics.items():
        num, den = (per_run[c].to_numpy()[draws].sum(axis=1) for c in ratio.split("/"))
        expected = np.nanpercentile(num / np.where(den > 0, den, np.nan), [2.5, 97.5])
        assert got[key] == (float(expected[0]), float(expected[1])), key
