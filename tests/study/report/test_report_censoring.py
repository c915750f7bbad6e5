"""Censoring in the report on synthetic data with known answers: profiles, restricted means, lower bounds, the draw."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from sb3_affect.study.report.estimation import bootstrap as stats
from sb3_affect.study.report.estimation.kaplan_meier import bootstrap_km_iqm, km_iqm
from sb3_affect.study.report.sections.protocol_draw import CAUSE, RANK, block_table
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts.censoring import censored_mean, restricted_mean, restricted_over_eps


def test_a_performance_profile_plateaus_at_the_share_of_runs_that_found_the_path() -> None:
    """Ten runs, four censored with small totals: at any τ at most 6 of 10 count, and all 6 once τ passes them."""
    values = np.array([5, 7, 9, 11, 13, 15, 2, 3, 4, 50], dtype=float)
    censored = np.array([False] * 6 + [True] * 4)
    taus = np.array([1.0, 6.0, 10.0, 15.0, 1e9])
    fraction, low, high = stats.bootstrap_profile(values, taus, n_boot=200, seed=0, censored=censored)
    np.testing.assert_allclose(fraction, [0.0, 0.1, 0.3, 0.6, 0.6])
    assert (low <= fraction + 1e-12).all() and (high >= fraction - 1e-12).all() and high[-1] < 1.0
    counted = stats.bootstrap_profile(values, taus, n_boot=10, seed=0)[0]  # without the flags every run counts
    assert counted[-1] == 1.0 and counted[1] == 0.4


def test_the_restricted_mean_is_the_area_under_the_kaplan_meier_curve() -> None:
    """By hand: 4 runs, one censored at 3; S = 1 on [0,2), 3/4 on [2,4), 3/8 on [4,6), 0 after: area to 5 = 3.875."""
    values = np.array([2.0, 3.0, 4.0, 6.0])
    censored = np.array([False, True, False, False])
    mean, variance = restricted_mean(values, censored, 5.0)
    assert mean == pytest.approx(2 * 1 + 2 * 0.75 + 1 * 0.375)
    # Greenwood's variance: event times 2 (n 4, d 1) and 4 (n 2, d 1); areas from them to 5 are 1.875 and 0.375
    assert variance == pytest.approx(1.875**2 / (4 * 3) + 0.375**2 / (2 * 1))
    uncensored = np.array([1.0, 2.0, 3.0, 10.0])
    whole, spread = restricted_mean(uncensored, np.zeros(4, bool), 10.0)
    assert whole == pytest.approx(4.0) and spread == pytest.approx(uncensored.var() / 4)  # no censoring: the plain mean
    assert censored_mean(values, censored) == ">= 4" and censored_mean(values, ~censored & False) == "4"


def test_the_kaplan_meier_iqm_is_the_trimmed_mean_without_censoring_and_integrates_the_curve_with_it() -> None:
    """
    Uncensored, 8 values: the 25%-trimmed mean. By hand with censoring: 8 runs, the one at 3 censored; the curve's
    distribution function F steps at 1 (1/8), 2 (2/8), 4 (2/8 + 6/8 x 1/5 = 0.4), 5 (0.55), 6 (0.7), 7 (0.85), 8 (1): the
    quantile function on [0.25, 0.75] is 4 up to 0.4, 5 to 0.55, 6 to 0.7 and 7 to 0.75, so the IQM is
    (4 x 0.15 + 5 x 0.15 + 6 x 0.15 + 7 x 0.05) / 0.5 = 5.1. With the top half censored above every event: not estimable.
    """
    values = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0])
    assert km_iqm(values, np.zeros(8, bool)) == pytest.approx(stats.iqm(values))
    assert km_iqm(values, values == 3.0) == pytest.approx((4 * 0.15 + 5 * 0.15 + 6 * 0.15 + 7 * 0.05) / 0.5)
    assert np.isnan(km_iqm(values, values > 4.0)) and np.isnan(bootstrap_km_iqm(values, values > 4.0, 50)[1])
    rng = np.random.default_rng(3)
    spread = rng.exponential(100.0, 400)
    censored = rng.random(400) < 0.2
    point, low, high = bootstrap_km_iqm(spread, censored, 300, seed=1)
    assert low < point < high and point > stats.iqm(np.where(censored, spread / 2, spread))  # halving the bounds lowers it
    assert bootstrap_km_iqm(spread, censored, 300, seed=1) == (point, low, high)  # seeded


def test_the_restricted_mean_over_epsilon_averages_the_cells_to_one_horizon() -> None:
    """
    Two ε cells of two agents, nothing censored and every cell reaching 10: the plain means over ε (6 and 4) and their
    difference; Greenwood's variance without censoring is each cell's variance / n, so the CI is the plain one's.
    """
    first = np.array([2.0, 6.0, 10.0, 6.0])
    second = np.array([1.0, 3.0, 10.0, 2.0])
    m = pd.DataFrame({"agent": ["a"] * 8 + ["b"] * 8, "epsilon": np.tile(np.repeat([0.1, 0.2], 4), 2),
                      "decisions_before_optimal": np.r_[first, first, second, second], "censored": False})  # fmt: skip
    horizon, one = restricted_over_eps(m, "decisions_before_optimal", ("a",))
    assert horizon == 10.0 and one.value == pytest.approx(6.0) and one.se == pytest.approx(np.sqrt(2 * first.var() / 4) / 2)
    _, both = restricted_over_eps(m, "decisions_before_optimal", ("a", "b"))
    assert both.value == pytest.approx(2.0)
    # one run at 6 of ε 0.1 never found it: S = 3/4 after 2, 1/2 after the event at 6, 0 after 10; area 2 + 3 + 2 = 7
    m.loc[m.index[1], "censored"] = True
    _, censored = restricted_over_eps(m, "decisions_before_optimal", ("a",))
    assert censored.value == pytest.approx((7.0 + 6.0) / 2)


def _censored_standard(censored: int) -> pd.DataFrame:
    """ε-greedy runs, 9 ε x 1,000: decisions to the greedy optimum spread over 4,000-6,000, the first ``censored``
    runs of the table censored (their totals stay in the mean: a lower bound)."""
    values = np.tile(np.linspace(4000.0, 6000.0, 1000), 9)
    runs = pd.DataFrame({"agent": "epsilon-greedy", "epsilon": np.repeat(np.round(np.arange(0.1, 1.0, 0.1), 1), 1000),
                         "replicate": np.tile(np.arange(1000), 9), "decisions_to_greedy_optimal": values,
                         "greedy_censored": np.arange(9000) < censored})  # fmt: skip
    return runs


def _judged(runs: pd.DataFrame) -> claims.Judgement:
    m = pd.concat([runs, runs.assign(agent="affective")], ignore_index=True)
    j = claims.judge_printed_mean(m.assign(decisions_before_optimal=1.0, censored=False), "v", "epsilon-greedy", "greedy")
    return claims._decide(j)


def test_a_censored_lower_bound_is_not_reproduced_when_reaching_the_paper_needs_implausible_runs() -> None:
    """
    The paper's 110,190 per 20 runs is 5,509.5 per run, ours 5,000: the 9,000 runs must gain 509.5 x 9,000
    decisions; 9 censored runs would each need 509,510 more, far beyond the 6,000 of any run that found it.
    """
    runs = _censored_standard(9)
    shortfall, longest = claims.censored_shortfall(runs, "decisions_to_greedy_optimal", "greedy_censored", 110190.20 / 20)
    assert shortfall == pytest.approx((110190.20 / 20 - 5000.0) * 9000 / 9) and longest == 6000.0
    j = _judged(runs)
    assert j.bound == "lower" and j.verdict.startswith("not reproduced: paper / ours <= ")
    assert "each of the 9 censored runs would need about 509,510 more decisions, more than the 6,000" in j.verdict


def test_a_censored_lower_bound_stays_inconclusive_when_the_censored_runs_could_reach_the_paper() -> None:
    """900 censored runs: about 5,095 more decisions each, less than the 6,000 a run that found it took."""
    j = _judged(_censored_standard(900))
    assert j.verdict.startswith("inconclusive: the paper's number is above ours, a lower bound"), j.verdict


def _blocks(shift: float, block_effect: float, seed: int = 0) -> pd.DataFrame:
    """1,000 affective and ε-greedy runs per ε (normal, sd 100), block 0 shifted, each 20-block with its own offset."""
    rng = np.random.default_rng(seed)
    rows = []
    for agent in ("affective", "epsilon-greedy"):
        offsets = rng.normal(0, block_effect, 50)
        for eps in np.round(np.arange(0.1, 1.0, 0.1), 1):
            values = 1000 + rng.normal(0, 100, 1000) + np.repeat(offsets, 20)
            values[:20] += shift if agent == "affective" else 0.0
            rows.append(pd.DataFrame({"agent": agent, "epsilon": eps, "replicate": np.arange(1000),
                                      "decisions_before_optimal": values}))  # fmt: skip
    return pd.concat(rows, ignore_index=True)


def test_a_rare_protocol_draw_is_told_apart_from_an_interval_that_is_too_narrow() -> None:
    """
    The protocol block shifted 8 standard errors up, the others independent: rank 50 of 50, the draw. Blocks that
    share an offset (runs not independent within a block): many blocks fall outside the interval, the interval.
    """
    large = _blocks(shift=60.0, block_effect=0.0)  # 8 standard errors of the block statistic (100 / sqrt(180))
    protocol = large[large.replicate < 20]
    table = block_table(large, protocol)
    walked = table.loc["Table V: affective, walked (per 20 runs)"]
    assert walked[RANK] == "50 of 50" and walked[CAUSE] == "the draw: the interval holds for the other blocks"
    assert table.loc["Table V: ε-greedy, walked (per 20 runs)", CAUSE] == "inside the interval"
    clustered = _blocks(shift=0.0, block_effect=60.0)
    table = block_table(clustered, clustered[clustered.replicate < 20])
    assert (table[CAUSE] != "the draw: the interval holds for the other blocks").all()
    outside = int(table.loc["Table V: affective, walked (per 20 runs)", "other blocks outside the interval"].split()[0])
    assert outside > 10  # of 49: a 95% interval built for independent runs misses most of the clustered blocks
