"""The report's numbers do not depend on the engine: the paper sweep on the kernel equals the same sweep on the Python loop."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from sb3_affect.study.launcher import ResultsStore, run_sweep
from sb3_affect.study.report.reading.run_tables import load_results, run_metrics

PAPER = Path(__file__).resolve().parents[2] / "experiments" / "paper.yaml"


def summary_numbers(run_dir: Path) -> dict[str, float]:
    """A few headline numbers of a results folder: decisions per episode per agent, runs, censored runs."""
    metrics = run_metrics(load_results(Path(run_dir)).episodes)
    return {
        f"{agent} decisions_per_episode": float(group.decisions_per_episode.mean())
        for agent, group in metrics.groupby("agent")
    } | {"runs": float(len(metrics)), "censored": float(metrics.censored.sum())}


def test_paper_sweep_and_its_report_numbers_are_the_python_engines(tmp_path: Path) -> None:
    size = ["seeds=2", "episodes=40"]
    python = [f"agents.{agent}.kwargs.engine=python" for agent in ("epsilon-greedy", "affective")]
    compiled = run_sweep(PAPER, tmp_path / "compiled", workers=2, overrides=size, progress=False)
    reference = run_sweep(PAPER, tmp_path / "python", workers=2, overrides=[*size, *python], progress=False)
    assert (compiled.finished, compiled.failed) == (reference.finished, reference.failed) == (36, 0)
    fast, slow = load_results(tmp_path / "compiled"), load_results(tmp_path / "python")
    key = ["agent", "epsilon", "replicate", "episode"]  # a replicate has the same seed in both folders
    left = fast.episodes.drop(columns="run_id").sort_values(key).reset_index(drop=True)
    right = slow.episodes.drop(columns="run_id").sort_values(key).reset_index(drop=True)
    assert len(left) == 36 * 40
    pd.testing.assert_frame_equal(left, right)
    records = ResultsStore(tmp_path / "python").load_runs()
    assert [r["config"]["algo_kwargs"].get("engine") for r in records] == ["python"] * 36  # the reference really was
    assert fast.runs.seed.tolist() != [] and sorted(fast.runs.seed) == sorted(slow.runs.seed)
    numbers = summary_numbers(tmp_path / "compiled")
    assert numbers and numbers == summary_numbers(tmp_path / "python")
