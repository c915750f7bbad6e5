"""The forensics section on the step unit: candidates that differ only in it, paired, and how far the leaders are apart."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from sb3_affect.study.forensics.section import largest_separation, step_unit_lines


def _leaders() -> pd.DataFrame:
    """Four leaders: two settings (alpha 0.5 and 1.0), each read with steps as decisions and as cells."""
    return pd.DataFrame(
        {
            "alpha": [0.5, 1.0, 0.5, 1.0], "gamma": [0.9] * 4, "step": ["decisions", "decisions", "cells", "cells"],
            "loglik": [-10.0, -12.0, -16.0, -11.0], "loglik_mc_error": [3.0, 4.0, 4.0, 3.0],
            "loglik_reachable": [-5.0, -6.0, -4.0, -1.0], "loglik_reachable_mc_error": [0.3, 0.4, 0.4, 0.3],
        }
    )  # fmt: skip


def test_the_step_unit_pairs_are_the_candidates_that_differ_only_in_it() -> None:
    line = step_unit_lines(_leaders())[0]
    assert "2 pairs of leading candidates differ only in it" in line
    assert "ranks 1 (decisions) and 3 (cells): full likelihood +6.0 ± 5.0, reachable statistics -1.0 ± 0.5" in line
    assert "ranks 2 (decisions) and 4 (cells): full likelihood -1.0 ± 5.0, reachable statistics -5.0 ± 0.5" in line
    assert "On the full likelihood decisions score higher in 1 of 2 pairs (0 of the 2 differences reach two" in line
    assert "on the reachable statistics decisions score higher in 0 of 2 pairs (1 of the 2 differences reach two" in line
    assert step_unit_lines(_leaders().drop(columns="step")) == []


def test_the_largest_separation_is_in_monte_carlo_errors_of_the_difference() -> None:
    """The best is -10 ± 3; -16 ± 4 is 6 / 5 = 1.2 errors away, the largest of the three."""
    assert largest_separation(_leaders()) == pytest.approx(6.0 / 5.0)
    assert math.isnan(largest_separation(_leaders().assign(loglik=-math.inf)))


def test_the_verdict_settings_column_is_the_reports_own_spreadsheet(tmp_path: Path) -> None:
    """The sensitivity table's column for the verdict's setting equals the report's Tables IV and V on the same runs."""
    from sb3_affect.study.forensics.section import protocol_statistics
    from sb3_affect.study.forensics.statistics import STATISTICS
    from sb3_affect.study.launcher import run_sweep
    from sb3_affect.study.report.estimation.bootstrap import paired_ttest_table
    from sb3_affect.study.report.reading.run_tables import load_results, run_metrics
    from sb3_affect.study.report.sections.paper_tables import per_epsilon

    run_sweep(Path(__file__).resolve().parents[3] / "experiments" / "smoke.yaml", tmp_path / "paper", workers=1,
              progress=False)  # fmt: skip
    own = dict(zip(STATISTICS, protocol_statistics(tmp_path / "paper")))  # type: ignore[arg-type]
    results = load_results(tmp_path / "paper")
    m = run_metrics(results.episodes, results.runs)
    iv = paired_ttest_table(*per_epsilon(m, "decisions_per_episode").to_numpy().T)
    v = paired_ttest_table(*per_epsilon(m, "decisions_before_optimal", "sum").to_numpy().T)
    assert own["IV mean ε-greedy"] == pytest.approx(iv.at["Mean", "Variable 1"])
    assert own["IV t Stat"] == pytest.approx(iv.at["t Stat", "Variable 1"])
    assert own["V mean affective"] == pytest.approx(v.at["Mean", "Variable 2"])
    assert own["V variance ε-greedy"] == pytest.approx(v.at["Variance", "Variable 1"])
    assert protocol_statistics(tmp_path / "nothing") is None
