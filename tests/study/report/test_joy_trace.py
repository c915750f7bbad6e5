"""Traced runs (a sweep file's ``trace: true``): stored by the launcher, read by the report, the run itself unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sb3_affect.core.episode_log import EPISODE_COLUMNS, TRACE_COLUMNS
from sb3_affect.study.launcher import SweepError, load_sweep, run_sweep
from sb3_affect.study.report.sections import joy_trace

SWEEP = """\
name: traced
env: {{id: sb3_affect/GridPursuit-v0, kwargs: {{size: 7, goal: [3, 3]}}}}
episodes: 30
seeds: [4, 1]
agents:
  - name: affective
    algo: AffectQ
{trace}    kwargs: {{learning_rate: 1.0, gamma: 0.8, q_init: 0.0}}
"""


def _episodes(folder: Path) -> dict[int, dict[str, np.ndarray]]:
    """The episode columns of each run of a folder, by seed (the report's loader)."""
    from sb3_affect.study.report.reading.run_tables import load_results

    columns = [c for c in EPISODE_COLUMNS if c != "episode"]
    results = load_results(folder, ("episode", *columns))
    seeds = dict(zip(results.runs.run_id, results.runs.seed))
    frame = results.episodes
    return {
        int(seeds[rid]): {c: rows[c].to_numpy(float) for c in ("episode", *columns)}
        for rid, rows in frame.groupby("run_id", observed=True)
    }


def test_a_traced_run_is_the_untraced_run_and_the_report_reads_its_trace(tmp_path: Path) -> None:
    plain, traced = tmp_path / "plain.yaml", tmp_path / "traced.yaml"
    plain.write_text(SWEEP.format(trace=""))
    traced.write_text(SWEEP.format(trace="    trace: true\n"))
    assert run_sweep(plain, tmp_path / "plain", workers=1, progress=False).finished == 2
    assert run_sweep(traced, tmp_path / "traced", workers=1, progress=False).finished == 2
    # the untraced cell runs as one batch on the compiled engine; the traced runs one at a time on the Python loop
    assert list((tmp_path / "plain" / "chunks").glob("*.parquet")) and not list((tmp_path / "plain" / "runs").glob("*.json"))
    files = sorted((tmp_path / "traced" / "runs").glob("*.json"))
    assert len(files) == 2 and all(TRACE_COLUMNS[0] in json.loads(f.read_text())["episodes"] for f in files)
    # tracing changes nothing the run does: every column of the episode log equal, seed by seed
    before, after = _episodes(tmp_path / "plain"), _episodes(tmp_path / "traced")
    assert sorted(before) == sorted(after) == [1, 4]
    for seed, columns in before.items():
        for name, values in columns.items():
            np.testing.assert_array_equal(after[seed][name], values, err_msg=f"seed {seed}, {name}")

    frame = joy_trace.traced(tmp_path / "traced")
    assert frame is not None and len(frame) == 60
    assert list(frame.seed) == [1] * 30 + [4] * 30 and list(frame.episode) == [*range(1, 31)] * 2
    felt = frame.joy > 0
    assert felt.any() and (frame.first_joy.isna() == ~felt).all() and frame.act_at_first_joy[~felt].isna().all()
    assert ((frame.first_joy[felt] >= 1) & (frame.first_joy[felt] <= frame.decisions[felt])).all()
    assert (frame.joy_exits <= frame.joy).all()
    # an episode that never leaves joy spends every decision from its first joy decision in joy (the log's count)
    kept = felt & (frame.joy_exits == 0)
    assert kept.any()
    np.testing.assert_array_equal(frame.first_joy[kept] + frame.joy[kept] - 1, frame.decisions[kept])
    summary = joy_trace.summary(frame)
    assert summary["runs"] == 2 and summary["episodes"] == 30 and summary["joy decisions"] == frame.joy.sum()
    assert joy_trace.traced(tmp_path / "plain" / "nothing") is None


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        ("algo: QLearning\n    trace: true", "only AffectQ's runs can be traced (its emotion callback), not 'QLearning'"),
        ("algo: AffectQ\n    trace: true\n    kwargs: {personality: optimistic}", "give no personality with trace: true"),
    ],
)
def test_trace_is_refused_where_it_can_not_run(tmp_path: Path, agent: str, message: str) -> None:
    path = tmp_path / "sweep.yaml"
    path.write_text(f"name: t\nepisodes: 5\nseeds: 1\nagents:\n  - name: a\n    {agent}\n")
    with pytest.raises(SweepError, match=r"agents\[0\] \(a\): trace: ") as info:
        load_sweep(path)
    assert message in str(info.value) and str(path) in str(info.value)


def test_an_untraced_sweep_saves_and_names_its_runs_as_before(tmp_path: Path) -> None:
    """No ``trace`` key in the saved sweep or in a run config unless asked: folders written before resume."""
    path = tmp_path / "plain.yaml"
    path.write_text(SWEEP.format(trace=""))
    sweep = load_sweep(path)
    assert "trace" not in sweep.model_dump()["agents"][0]
    assert all("trace" not in config for config in sweep.run_configs())
    path.write_text(SWEEP.format(trace="    trace: true\n"))
    assert all(config["trace"] is True for config in load_sweep(path).run_configs())
