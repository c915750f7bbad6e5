"""The report: the spreadsheet paired t-test, bootstrap statistics, per-run metrics, and the report end to end."""

from __future__ import annotations

import hashlib
import math
import os
import re
import subprocess
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest
from number_formats import mixed_formats
from scipy import stats

from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.report import (
    bootstrap_ci,
    bootstrap_improvement,
    build_report,
    iqm,
    paired_ttest_table,
    probability_of_improvement,
)
from sb3_affect.study.report.estimation.bootstrap import TTEST_ROWS
from sb3_affect.study.report.reading.run_tables import run_metrics

ROOT = Path(__file__).resolve().parents[3]


def test_paired_ttest_matches_scipy_and_a_hand_calculation() -> None:
    a = [67.0, 60.0, 72.0, 55.0, 80.0]
    b = [56.0, 58.0, 59.0, 57.0, 55.0]
    table = paired_ttest_table(a, b)
    assert list(table.index) == list(TTEST_ROWS)
    # by hand: d = 11, 2, 13, -2, 25; mean 9.8; sample sd of d; t = 9.8 / (sd / sqrt 5); df 4
    d = np.array([11, 2, 13, -2, 25], dtype=float)
    sd = math.sqrt(((d - 9.8) ** 2).sum() / 4)
    t_hand = 9.8 / (sd / math.sqrt(5))
    assert table.at["t Stat", "Variable 1"] == pytest.approx(t_hand, rel=1e-12)
    reference = stats.ttest_rel(a, b)
    assert table.at["t Stat", "Variable 1"] == pytest.approx(reference.statistic, rel=1e-12)
    assert table.at["P(T<=t) two-tail", "Variable 1"] == pytest.approx(reference.pvalue, rel=1e-10)
    assert table.at["P(T<=t) one-tail", "Variable 1"] == pytest.approx(reference.pvalue / 2, rel=1e-10)
    assert table.at["df", "Variable 1"] == 4
    assert table.at["Mean", "Variable 1"] == pytest.approx(66.8) and table.at["Mean", "Variable 2"] == pytest.approx(57.0)
    assert table.at["Variance", "Variable 2"] == pytest.approx(np.var(b, ddof=1))
    assert table.at["Pearson Correlation", "Variable 1"] == pytest.approx(stats.pearsonr(a, b)[0], rel=1e-12)
    assert table.at["t Critical one-tail", "Variable 1"] == pytest.approx(2.131846786, rel=1e-8)  # T.INV(0.95, 4)
    assert table.at["t Critical two-tail", "Variable 1"] == pytest.approx(2.776445105, rel=1e-8)  # T.INV.2T(0.05, 4)
    assert math.isnan(table.at["t Stat", "Variable 2"])  # the spreadsheet leaves the second column empty


def test_paired_ttest_reproduces_the_papers_table_v_statistics() -> None:
    """Build two samples with the paper's Table V means, variances and correlation: t must come out 2.77."""
    rng = np.random.default_rng(0)
    z = rng.standard_normal((2, 9))
    z -= z.mean(axis=1, keepdims=True)
    q, _ = np.linalg.qr(z.T)  # two orthonormal, zero-mean columns
    u, v = q[:, 0] * math.sqrt(8), q[:, 1] * math.sqrt(8)
    r = -0.0623
    a = 110190.20 + math.sqrt(76689863) * u
    b = 99357.56 + math.sqrt(53278480) * (r * u + math.sqrt(1 - r * r) * v)
    table = paired_ttest_table(a, b)
    assert table.at["Pearson Correlation", "Variable 1"] == pytest.approx(r, abs=1e-9)
    assert table.at["t Stat", "Variable 1"] == pytest.approx(2.77, abs=0.005)
    assert table.at["P(T<=t) one-tail", "Variable 1"] == pytest.approx(0.012, abs=0.002)


def test_bootstrap_ci_known_answers() -> None:
    assert bootstrap_ci([5.0] * 30) == (5.0, 5.0, 5.0)
    sample = np.random.default_rng(1).normal(10.0, 2.0, size=4000)
    point, low, high = bootstrap_ci(sample, n_boot=2000, seed=3)
    half = 1.96 * sample.std(ddof=1) / math.sqrt(len(sample))
    assert point == pytest.approx(sample.mean())
    assert low == pytest.approx(sample.mean() - half, abs=0.25 * half)
    assert high == pytest.approx(sample.mean() + half, abs=0.25 * half)
    assert bootstrap_ci(sample, seed=3) == bootstrap_ci(sample, seed=3)  # seeded


def test_iqm_and_probability_of_improvement_by_hand() -> None:
    assert iqm([1, 2, 3, 4, 5, 6, 7, 100]) == pytest.approx(4.5)  # middle half: 3, 4, 5, 6
    # lower is better: pairs (1,2) (1,3) (2,3) better, (2,2) a tie -> (3 + 0.5) / 4
    assert probability_of_improvement([1, 2], [2, 3]) == pytest.approx(0.875)
    assert probability_of_improvement([1, 2], [2, 3], lower_is_better=False) == pytest.approx(0.125)
    point, low, high = bootstrap_improvement([1.0] * 10, [2.0] * 10)
    assert (point, low, high) == (1.0, 1.0, 1.0)


def _episodes(run_id: str, optimal: list[bool], greedy: list[bool], decisions: list[int]) -> pd.DataFrame:
    n = len(optimal)
    return pd.DataFrame(
        {
            "run_id": run_id,
            "agent": "a",
            "seed": 0,
            "epsilon": 0.1,
            "replicate": 0,
            "episode": range(1, n + 1),
            "decisions": decisions,
            "cells": decisions,
            "reward": 100.0,
            "optimal": optimal,
            "truncated": False,
            "random_moves": 0.0,
            "waits": 0,
            "joy": decisions,
            "sadness": 0,
            "fear": 0,
            "anger": 0,
            "greedy_optimal": greedy,
            "norm": np.nan,
        }
    )


def test_run_metrics_definitions() -> None:
    found = _episodes("found", [False, False, True, False], [False, True, False, True], [50, 30, 12, 14])
    never = _episodes("never", [False, False], [True, True], [40, 20])
    metrics = run_metrics(pd.concat([found, never])).set_index("run_id")
    assert metrics.at["found", "first_optimal"] == 3
    assert metrics.at["found", "decisions_before_optimal"] == 80  # episodes 1 and 2
    assert metrics.at["found", "greedy_stays_optimal_from"] == 4  # stays optimal from episode 4 to the end
    assert not metrics.at["found", "censored"]
    assert metrics.at["never", "censored"] and math.isnan(metrics.at["never", "first_optimal"])
    assert metrics.at["never", "decisions_before_optimal"] == 60  # censored: all its steps
    assert metrics.at["never", "greedy_stays_optimal_from"] == 1
    assert metrics.at["found", "decisions_per_episode"] == pytest.approx(26.5)
    assert metrics.at["found", "decisions_to_greedy_optimal"] == 50 + 30 + 12 + 14  # episodes 1-4
    assert metrics.at["never", "decisions_to_greedy_optimal"] == 40  # greedy optimal after episode 1
    late = _episodes("late", [False, True], [True, False], [30, 12])
    assert run_metrics(late).set_index("run_id").at["late", "greedy_censored"]  # not optimal after the last episode


def test_report_end_to_end_from_the_smoke_sweep(tmp_path: Path) -> None:
    out = tmp_path / "smoke"
    run_sweep(ROOT / "experiments" / "smoke.yaml", out, workers=2, progress=False)
    report = build_report(out)
    text = _pages(report)
    assert len(report.read_bytes()) <= 30 * 1024 and len(re.findall(r"\(appendix-[\w-]+\.md\)", report.read_text())) == 3
    assert mixed_formats(text) == []  # one format per quantity, on every page
    for section in (
        "Verdict",
        "No verdict: too few runs",
        "Why the affective agent behaves as it does",
        "Fig. 5 under both weightings",
        "Table IV",
        "Table V",
        "Figures 3 and 4",
        "The first optimal episode as time-to-event data",
        "The project's own checks",
        "Learning curves",
        "Reading ablation",
        "DQN on the same task",
        "Reproducibility record",
        "Definitions",
        "t-Test: Paired Two Sample for Means",
        "P(T<=t) one-tail",
        "110190.20",  # the paper's cells verbatim
        "76689863",
    ):
        assert section in text, section
    # too few runs (2 seeds, 2 epsilons, 20 episodes): no verdict at all
    assert "Supported" not in text and "| reproduced" not in text
    assert not (out / "tables" / "verdict.csv").exists()
    figures = sorted((out / "figures").glob("*.png"))
    assert len(figures) >= 8
    for png in figures:
        image = mpimg.imread(png)
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100
        assert f"figures/{png.name}" in text
    html = "".join(page.read_text() for page in sorted(out.glob("*.html")))
    assert html.count("data:image/png;base64,") == len(figures) and "<table>" in html
    assert "<ul><li>" in html and "<p>- " not in html  # lists render as lists
    for table in ("table_iv", "table_v_walked", "table_v_greedy", "kaplan_meier_paper", "rliable", "profile_windows"):
        frame = pd.read_csv(out / "tables" / f"{table}.csv")
        assert len(frame) > 0
    windows = pd.read_csv(out / "tables" / "profile_windows.csv").iloc[:, 0]
    assert windows.str.startswith("episodes 1-10").all()  # only the windows 20-episode runs reach: no empty rows
    assert "The smallest (agent, ε) cell has 2 runs (a verdict needs 5)" in text
    assert "Episodes truncated by the safety cap (20,000 decisions)" in text  # read from the agents' settings
    assert re.search(r"is a shortest path \((\d+) cells on this task\)", text)  # read from the sweep's env
    # the record: a lock file of every installed package, checksums of every run table, forensics not run
    lock = (out / "packages.lock").read_text().splitlines()
    assert any(line.startswith("numpy==") for line in lock) and any(line.lower().startswith("sb3-affect==") for line in lock)
    sums = [line.split("  ") for line in (out / "checksums.sha256").read_text().splitlines()]
    assert len(sums) == len(list((out / "chunks").glob("*.parquet"))) + len(list((out / "runs").glob("*.json"))) > 0
    for digest, name in sums:
        assert hashlib.sha256((out / name).read_bytes()).hexdigest() == digest
    assert "Replication forensics: not run" in text and "packages.lock" in text


def test_the_record_takes_no_commit_from_a_repository_around_an_installed_package(tmp_path: Path) -> None:
    """A package folder inside some other git repository (site-packages in a project) has no commit of its own."""
    from sb3_affect.study.report.sections.reproducibility import commit

    site = tmp_path / "project" / "venv" / "site-packages" / "sb3_affect"
    site.mkdir(parents=True)
    subprocess.run(["git", "init", "-q", str(tmp_path / "project")], check=True)
    assert commit(site).startswith("none")
    checkout = tmp_path / "checkout"
    (checkout / "sb3_affect").mkdir(parents=True)
    (checkout / "pyproject.toml").write_text("[project]\nname = 'sb3-affect'\n")
    subprocess.run(["git", "init", "-q", str(checkout)], check=True)
    env = {"GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    subprocess.run(["git", "-C", str(checkout), "add", "."], check=True)
    subprocess.run(["git", "-C", str(checkout), "commit", "-qm", "x"], check=True, env={**os.environ, **env})
    head = subprocess.run(["git", "-C", str(checkout), "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    assert commit(checkout / "sb3_affect") == head


def test_the_report_layer_imports_nothing_above_it() -> None:
    """report is below forensics, cli and replicate: not even a lazy import inside a function."""
    above = re.compile(r"^\s*(from|import) sb3_affect\.study\.(forensics|cli|replicate)\b", re.MULTILINE)
    paths = list((ROOT / "sb3_affect" / "study" / "report").glob("*.py"))
    assert paths
    for path in paths:
        assert not above.search(path.read_text()), path.name
    study = re.compile(r"^\s*(from|import) sb3_affect\.(engine|study)\b", re.MULTILINE)
    paths = list((ROOT / "sb3_affect" / "agents").rglob("*.py"))
    assert paths
    for path in paths:  # the agents layer reads no results
        assert not study.search(path.read_text()), path.name


def test_report_refuses_a_folder_without_results(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="holds no results"):
        build_report(tmp_path)


def test_html_inline_markup_renders_emphasis_bold_and_code_but_not_arithmetic() -> None:
    from sb3_affect.study.report.rendering.document import _inline

    rendered = _inline("A *step* is one decision; **bold** and `code`; 2 * 3 * 4; a*b*c <x>")
    assert rendered == "A <i>step</i> is one decision; <b>bold</b> and <code>code</code>; 2 * 3 * 4; a*b*c &lt;x&gt;"


def _pages(report: Path) -> str:
    """report.md and every appendix page it links to, in order (a link to a missing page fails here)."""
    main = report.read_text()
    linked = re.findall(r"^- \[[^\]]+\]\(([\w-]+\.md)\)$", main, re.M)
    return "\n".join([main, *((report.parent / name).read_text() for name in linked)])
