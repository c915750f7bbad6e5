"""
The report read a part at a time (runs in parts, one agent's rows, the profile in ranges of episode numbers) gives
the numbers of the whole-frame computation: the same per-run metrics, profile and rows, and the same report.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sb3_affect.experiments import ResultsStore, run_sweep
from sb3_affect.report import mechanism, metrics
from sb3_affect.report.build import build_report
from sb3_affect.report.context import AFFECTIVE, STANDARD
from sb3_affect.report.mechanism import bimodality
from sb3_affect.report.metrics import REPORT_COLUMNS, load_results, profile, rows_where, run_metrics

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "experiments" / "paper.yaml"


@pytest.fixture(scope="module")
def paper5(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The paper's sweep at 5 seeds per cell (90 runs of 200 episodes, 18 chunks): enough for every section."""
    folder = tmp_path_factory.mktemp("lean") / "paper5"
    run_sweep(PAPER, folder, workers=1, overrides=["seeds=5"], progress=False)
    return folder


def test_parts_give_the_whole_frame_numbers(paper5: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(metrics, "RUNS_PER_PART", 7)  # several chunks a part, 13 parts
    results = load_results(paper5)
    whole_runs, whole = ResultsStore(paper5).results(REPORT_COLUMNS, seed=False)
    pd.testing.assert_frame_equal(results.runs, whole_runs)
    assert len(list(results.parts(("episode",), runs_per_part=7))) > 2
    pd.testing.assert_frame_equal(results.metrics(), run_metrics(whole, whole_runs))
    windows = ((1, 5), (11, 30), (191, 200))
    aff_rows = rows_where(whole, whole.agent == AFFECTIVE)
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
    assert bimodality(results.agent_episodes(AFFECTIVE, ("episode", "decisions", "joy"), 151, 200), 151, 200) == bimodality(
        aff_rows, 151, 200
    )
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 7)  # ranges of episode numbers, the last one short

    class Ctx:
        paper = results

    pd.testing.assert_frame_equal(mechanism.agent_profile(Ctx(), AFFECTIVE, 200), profile(aff_rows))  # type: ignore[arg-type]
    pd.testing.assert_frame_equal(results.episodes, whole)  # the whole frame is still there for small folders


def test_the_report_read_in_parts_equals_the_report_read_whole(
    paper5: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every table and the text, byte for byte: parts of 7 runs and 7 episode numbers against one part of all."""
    monkeypatch.setattr(metrics, "RUNS_PER_PART", 10**9)
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 10**9)
    build_report(paper5, out=tmp_path / "whole")
    monkeypatch.setattr(metrics, "RUNS_PER_PART", 7)
    monkeypatch.setattr(mechanism, "PROFILE_EPISODES", 7)
    build_report(paper5, out=tmp_path / "parts")
    tables = sorted(p.name for p in (tmp_path / "whole" / "tables").glob("*.csv"))
    assert len(tables) >= 10 and tables == sorted(p.name for p in (tmp_path / "parts" / "tables").glob("*.csv"))
    for name in tables:
        assert (tmp_path / "parts" / "tables" / name).read_bytes() == (tmp_path / "whole" / "tables" / name).read_bytes(), name
    assert (tmp_path / "parts" / "report.md").read_text() == (tmp_path / "whole" / "report.md").read_text()
