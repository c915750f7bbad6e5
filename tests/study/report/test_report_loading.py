"""
The report's column-wise loader and vectorised metrics give the numbers of the record-by-record path (JSON, chunks and
mixed folders), and the scalable statistics give the numbers of their direct definitions.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.report.estimation import bootstrap
from sb3_affect.study.report.reading.run_tables import (
    REPORT_COLUMNS,
    load_results,
    load_run_records,
    profile,
    run_metrics,
)
from sb3_affect.study.report.reading.settled_window import settled_numbers, settled_part

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "experiments" / "smoke.yaml"


def episodes_frame(runs: list[dict[str, Any]]) -> pd.DataFrame:
    """One row per episode of run records (``load_run_records``), with the run's agent, seed and labels as columns."""
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


@pytest.fixture(scope="module")
def mixed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """
    A folder of one sweep (smoke, 3 seeds) holding both layouts: its runs first ran one file each (logs on), then all
    but replicate 2's files were removed and the rerun (logs off: the same sweep) stored them in Parquet chunks.
    """
    folder = tmp_path_factory.mktemp("loading") / "mixed"
    overrides = ["episodes=12", "seeds=3"]
    run_sweep(SMOKE, folder, workers=1, overrides=[*overrides, "logs=[csv]"], progress=False)
    for path in (folder / "runs").glob("[!.]*.json"):
        if json.loads(path.read_text())["config"]["labels"]["replicate"] != 2:
            path.unlink()
    assert run_sweep(SMOKE, folder, workers=1, overrides=overrides, progress=False).finished == 8
    assert len(list((folder / "chunks").glob("*.parquet"))) >= 1 and len(list((folder / "runs").glob("*.json"))) == 4
    return folder


def test_loader_and_metrics_equal_the_record_path_on_a_mixed_folder(mixed: Path) -> None:
    results = load_results(mixed)
    records = load_run_records(mixed)
    assert len(results.runs) == len(records) == 8 + 4 and results.runs.run_id.is_monotonic_increasing
    reference = episodes_frame(records)
    e = results.episodes
    assert list(e.columns[:4]) == ["run_id", "agent", "epsilon", "replicate"] and "seed" not in e.columns
    assert e.episode.dtype == np.int32 and e.optimal.dtype == bool and isinstance(e.run_id.dtype, pd.CategoricalDtype)
    for column in REPORT_COLUMNS:  # the same rows in the same order (runs by run id, episodes in order)
        np.testing.assert_array_equal(e[column].to_numpy(), reference[column].to_numpy(), err_msg=column)
    np.testing.assert_array_equal(e.run_id.astype(str).to_numpy(), reference.run_id.to_numpy())
    fast = run_metrics(results.episodes, results.runs)
    slow = run_metrics(reference, records)  # string run ids, object labels: the generic path
    pd.testing.assert_frame_equal(fast, slow)
    shuffled = reference.sample(frac=1.0, random_state=0)  # rows in any order: sorted by run and episode first
    pd.testing.assert_frame_equal(run_metrics(shuffled, records), slow)
    pd.testing.assert_frame_equal(profile(e), profile(reference))
    aff = e.agent == "affective"
    affective = reference[reference.agent == "affective"]
    assert settled_numbers(*settled_part(e[aff], 1, 12)) == settled_numbers(*settled_part(affective, 1, 12))


def test_runs_that_finished_no_episode_are_kept_censored(mixed: Path) -> None:
    results = load_results(mixed)
    ghost = results.runs.iloc[[0]].assign(run_id="zz-no-episodes", decisions=777, episodes=0)
    metrics = run_metrics(results.episodes, pd.concat([results.runs, ghost], ignore_index=True)).set_index("run_id")
    row = metrics.loc["zz-no-episodes"]
    assert row.censored and row.decisions_before_optimal == 777 and row.episodes == 0 and row.seed == ghost.seed.iloc[0]


def test_status_counts_from_the_footers(mixed: Path) -> None:
    name, per_agent, not_counted = ResultsStore(mixed).progress()
    assert name == "smoke" and per_agent == {"epsilon-greedy": (6, 6, 0), "affective": (6, 6, 0)} and not_counted == []


def _pairwise(x: np.ndarray, y: np.ndarray, lower_is_better: bool) -> float:
    a, b = x[:, None], y[None, :]
    better = (a < b) if lower_is_better else (a > b)
    return float(better.mean() + 0.5 * (a == b).mean())


def test_probability_of_improvement_equals_the_pairwise_count() -> None:
    rng = np.random.default_rng(1)
    x, y = rng.integers(0, 30, 301).astype(float), rng.integers(5, 40, 203).astype(float)  # many ties
    for lower in (True, False):
        assert bootstrap.probability_of_improvement(x, y, lower) == _pairwise(x, y, lower)


def test_bootstrap_improvement_equals_resampling_each_pair() -> None:
    rng = np.random.default_rng(2)
    x, y = rng.integers(0, 20, 57).astype(float), rng.integers(3, 25, 41).astype(float)
    point, low, high = bootstrap.bootstrap_improvement(x, y, n_boot=300, seed=5)
    draws = np.random.default_rng(5)
    boots = []
    for _ in range(300):  # each resample's pairs counted one by one: (better + half the ties) / pairs
        a, b = x[draws.integers(0, 57, 57)][:, None], y[draws.integers(0, 41, 41)][None, :]
        boots.append((int((a < b).sum()) + 0.5 * int((a == b).sum())) / (57 * 41))
    tail = (1 - 0.95) / 2 * 100  # as bootstrap_improvement computes it (not exactly 2.5)
    expected = (_pairwise(x, y, True), float(np.percentile(boots, tail)), float(np.percentile(boots, 100 - tail)))
    assert (point, low, high) == expected


def test_bootstrap_ci_in_blocks_equals_one_draw(monkeypatch: pytest.MonkeyPatch) -> None:
    values = np.random.default_rng(3).exponential(10.0, 501)
    whole = bootstrap.bootstrap_ci(values, "iqm", n_boot=400, seed=7)
    monkeypatch.setattr(bootstrap, "BLOCK_CELLS", 501 * 7)  # blocks of 7 resamples
    assert bootstrap.bootstrap_ci(values, "iqm", n_boot=400, seed=7) == whole
    samples = values[np.random.default_rng(7).integers(0, 501, size=(400, 501))]
    boots = np.sort(samples, axis=1)[:, 125:376].mean(axis=1)  # the 25%-trimmed mean of 501 values
    assert whole[1] == pytest.approx(np.percentile(boots, 2.5)) and whole[2] == pytest.approx(np.percentile(boots, 97.5))


def test_bootstrap_profile_bands_hold_the_fraction() -> None:
    values = np.random.default_rng(4).lognormal(5.0, 1.0, 400)
    taus = np.array([50.0, 150.0, 400.0, 1e6])
    fraction, low, high = bootstrap.bootstrap_profile(values, taus, n_boot=200, seed=0)
    np.testing.assert_array_equal(fraction, [(values <= t).mean() for t in taus])
    assert np.all(low <= fraction) and np.all(fraction <= high) and high[-1] == low[-1] == 1.0
    assert np.array_equal(bootstrap.bootstrap_profile(values, taus, n_boot=200, seed=0)[1], low)  # seeded
