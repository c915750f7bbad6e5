"""
The paper's claims judged on per-run metrics: direction, size against the paper's 20-seed protocol (predictive
interval, ratio), the paper's own test beside robust ones, one Holm family per claim, one verdict per claim.

``judge_all(m)`` takes one row per run (``report.reading.run_tables.run_metrics`` columns plus ``agent`` and ``epsilon``) and
returns the ``Judgement`` list; it is analytic (``report.verdicts.inference``), so it is cheap enough to repeat on hundreds of
subsamples (the seed-count study). Rules every verdict follows:

- a "no difference" claim is judged by an equivalence test (TOST) with a stated margin, never by a non-significant
  test: absence of evidence is never "reproduced";
- the paper's test outcome and the paper's claim are separate rows: the paired t-test over 9 ε values answers a
  question about the 9 ε values (a crossover makes it non-significant at any seed count), not about the agents;
- each claim's tests form their own Holm family (the ε values of a claim are a natural family); the paper's own
  single test is judged on its raw p-value, as the paper did;
- time (decisions) and distance (cells) are reported side by side where the claim counts steps.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
from scipy import stats as sps

from sb3_affect.study.report.rendering.document import first_words, fmt, pval, sig
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.censoring import difference_sign, marked, restricted_over_eps
from sb3_affect.study.report.verdicts.course_claims import (
    ABOUT,
    judge_episodes_to_optimal,
    judge_fig5,
    judge_fig6,
    judge_four_emotions,
    judge_long_run,
)
from sb3_affect.study.report.verdicts.inference import ALPHA, Estimate, Test, holm, significant, tost, two_sided_p
from sb3_affect.study.report.verdicts.judgement import (
    AFFECTIVE,
    STANDARD,
    Judgement,
    cell_means,
    diff_over_eps,
    eps_list,
    over_eps,
    per_epsilon,
    seeds_per_cell,
    size_against_paper,
)

__all__ = ["ABOUT", "ALPHA", "EQUIVALENCE_MARGIN", "Judgement", "Test", "judge_all", "verdict_word"]

#: The equivalence margin of "no difference in steps per episode": ± this share of the ε-greedy agent's mean.
EQUIVALENCE_MARGIN = 0.05


def _paired(a: pd.Series, b: pd.Series, alternative: str) -> tuple[Test, list[Test]]:
    """The spreadsheet's paired t-test over epsilons (the paper's test), and Wilcoxon and the paired t on logs."""
    side = {"two-sided": "two-tailed", "greater": "one-tailed"}[alternative]
    primary = Test(f"paired t over the {len(a)} ε values ({side}, the paper's test)", float(sps.ttest_rel(a, b, alternative=alternative).pvalue))  # noqa: E501
    diff = a - b
    wil = float(sps.wilcoxon(a, b, alternative=alternative).pvalue) if (diff != 0).any() else 1.0
    robust = [Test(f"Wilcoxon signed-rank over the ε values ({side})", wil)]
    if (a > 0).all() and (b > 0).all():
        robust.append(Test(f"paired t on log values ({side})", float(sps.ttest_rel(np.log(a), np.log(b), alternative=alternative).pvalue)))  # noqa: E501
    return primary, robust


def _lead(m: pd.DataFrame, column: str) -> str:
    """ε-greedy minus affective, averaged over ε, with its CI and as a share of the ε-greedy agent's number."""
    if column not in m.columns:
        return "n/a"
    cells = cell_means(m, column)
    est, base = diff_over_eps(cells), over_eps(cells, STANDARD).value
    return f"{est.text()} ({est.value / base:.1%} of ε-greedy's {sig(base)})" if base else est.text()


def judge_table_iv_test(m: pd.DataFrame) -> Judgement:
    """The paper's test outcome: the paired t over the 9 ε cell means is not significant (two-tailed P 0.44)."""
    cells = cell_means(m, "decisions_per_episode")
    primary, _ = _paired(cells[f"mean_{STANDARD}"], cells[f"mean_{AFFECTIVE}"], "two-sided")
    j = Judgement(
        "table_iv:test",
        "Table IV, the paper's test: paired t over the 9 ε values not significant",
        "P two-tail 0.44",
        f"P two-tail {pval(primary.p)}",
        primary=primary,
        seed_dependent=False,
    )
    j.decide = lambda j: (
        f"reproduced: the paper's test is not significant (p {pval(primary.p)}); it compares the 9 ε means, whose "
        "crossover keeps it non-significant at any seed count"
        if primary.p >= ALPHA
        else f"not reproduced: the paper's test is significant (p {pval(primary.p)})"
    )
    return j


def judge_table_iv(m: pd.DataFrame, column: str = "decisions_per_episode") -> Judgement:
    """The paper's claim: no difference in steps per episode (averaged over ε), by TOST, and per ε by Welch."""
    cells = cell_means(m, column)
    est = diff_over_eps(cells)
    margin = EQUIVALENCE_MARGIN * over_eps(cells, STANDARD).value
    _diffs, per_eps = per_epsilon(m, column, "")
    paper_diff = paper.TABLE_IV["Mean"][0] - paper.TABLE_IV["Mean"][1]
    inside, ratio, _where = size_against_paper(est, paper_diff, seeds_per_cell(m))
    equivalence = Test(f"TOST: |ε-greedy - affective| < {sig(margin)} (equivalence, averaged over ε)", tost(est, margin))
    difference = Test("z-test: ε-greedy - affective = 0 (averaged over ε, two-sided)", two_sided_p(est))
    j = Judgement(
        "table_iv",
        "Table IV, the paper's claim: no difference in steps per episode",
        f"67.02 vs 56.28 (difference {fmt(paper_diff)})",
        f"{sig(over_eps(cells, STANDARD).value)} vs {sig(over_eps(cells, AFFECTIVE).value)}; difference {est.text()}",
        cells=f"cells per episode, difference {_lead(m, 'cells_per_episode')}",
        direction=est.value > 0,
        size=inside,
        ratio=ratio,
        tests=[difference, *per_eps.values()],
        equivalence=equivalence,
    )

    def decide(j: Judgement) -> str:
        differ = [e for e in per_eps if significant(per_eps[e])]
        if equivalence.p < ALPHA:  # judged on its own: outside the Holm family of the difference tests
            return f"reproduced: equivalent within ±{sig(margin)} steps (TOST p {pval(equivalence.p)})"
        if significant(difference):
            return (
                f"not reproduced: the agents differ by {est.text()} steps per episode averaged over ε (outside the "
                f"±{sig(margin)} equivalence margin); significant at {len(differ)} of {len(per_eps)} ε"
            )
        return f"inconclusive: neither a difference nor equivalence within ±{sig(margin)} shown"

    j.decide = decide
    return j


#: Fig. 3's rule: a single crossover whose last ε-greedy-better ε is at least CROSSOVER[0] and whose first
#: affective-better ε is at most CROSSOVER[1] (the paper: better below 0.5, above 0.6; one ε value of slack each side).
CROSSOVER = (0.4, 0.7)


def judge_fig3(m: pd.DataFrame, column: str = "decisions_per_episode") -> Judgement:
    diffs, tests = per_epsilon(m, column, "")
    point = sorted((e, d.value > 0) for e, d in diffs.items())
    cross = [f"{fmt(a, 1)}-{fmt(b, 1)}" for (a, sa), (b, sb) in itertools.pairwise(point) if sa != sb]
    low = [d.value for e, d in diffs.items() if e < 0.45]
    high = [d.value for e, d in diffs.items() if e > 0.65]
    cell_diffs, _ = per_epsilon(m, "cells_per_episode", "") if column.startswith("decisions") else ({}, {})
    j = Judgement(
        "fig3",
        "Fig. 3: crossover, ε-greedy better below ε 0.5, affective better above 0.6",
        f"ε-greedy better below 0.5, affective above 0.6 (reproduced when the significant differences change sign "
        f"once, the last ε-greedy-better ε >= {CROSSOVER[0]} and the first affective-better ε <= {CROSSOVER[1]})",
        f"ε-greedy minus affective {'steps' if column.startswith('decisions') else 'cells'} per episode: "
        + "; ".join(f"ε {fmt(e, 1)}: {d.text()}" for e, d in diffs.items())
        + f". Point estimates change sign between ε {', '.join(cross) or 'none'}"
        + (f"; in cells, ε {fmt(min(cell_diffs), 1)} to {fmt(max(cell_diffs), 1)}: "
           + ", ".join(sig(d.value) for d in cell_diffs.values()) if cell_diffs else ""),
        cells=(
            "ε-greedy minus affective cells per episode: "
            + "; ".join(f"ε {fmt(e, 1)}: {d.text()}" for e, d in cell_diffs.items())
        )
        if cell_diffs
        else "",
        direction=bool(all(x < 0 for x in low) and all(x > 0 for x in high)) if low and high else None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        sign = {e: (1 if d.value > 0 else -1) if significant(tests[e]) else 0 for e, d in diffs.items()}
        signs = [sign[e] for e in sorted(sign) if sign[e] != 0]
        changes = sum(1 for x, y in itertools.pairwise(signs) if x != y)
        if changes == 1 and signs[0] < 0:
            last_neg = max(e for e in sign if sign[e] < 0)
            first_pos = min(e for e in sign if sign[e] > 0)
            where = f"significant differences change sign between ε {fmt(last_neg, 1)} and {fmt(first_pos, 1)}"
            if last_neg >= CROSSOVER[0] and first_pos <= CROSSOVER[1]:
                return f"reproduced: a crossover, {where}"
            return (
                f"crossover reproduced, shifted: {where} (the rule: last ε-greedy-better ε >= {CROSSOVER[0]}, first "
                f"affective-better ε <= {CROSSOVER[1]})"
            )
        if not signs:
            return "not reproduced: no significant difference at any ε"
        return "not reproduced: " + ("affective better everywhere it differs" if min(signs) > 0 else "no single crossover")

    j.decide = decide
    return j


def judge_table_v(m: pd.DataFrame, column: str = "decisions_before_optimal", definition: str = "walked") -> Judgement:
    """Fewer steps before the optimal path: the paper's one-tailed paired t over ε (raw p), robust tests beside it."""
    cells = cell_means(m, column)
    runs = paper.SEEDS_PER_CELL
    est = diff_over_eps(cells).scaled(runs)  # per 20 runs, as the paper's table
    paper_diff = paper.TABLE_V["Mean"][0] - paper.TABLE_V["Mean"][1]
    inside, ratio, where = size_against_paper(est, paper_diff, seeds_per_cell(m))
    primary, robust = _paired(cells[f"mean_{STANDARD}"], cells[f"mean_{AFFECTIVE}"], "greater")
    cell_column = "cells_before_optimal" if definition == "walked" else ""
    flag = "censored" if definition == "walked" else "greedy_censored"
    counts = [int(m[m.agent == agent][flag].sum()) if flag in m.columns else 0 for agent in (STANDARD, AFFECTIVE)]
    sign = difference_sign(counts[0] > 0, counts[1] > 0)
    means = (
        marked(sig(over_eps(cells, agent).value * runs), ">=" if c else "") for agent, c in zip((STANDARD, AFFECTIVE), counts)
    )
    share = marked(f"{diff_over_eps(cells).value / over_eps(cells, STANDARD).value:.1%}", sign)
    censored_text = f"; {counts[0]:,} ε-greedy and {counts[1]:,} affective runs censored: bounds" if sign else ""
    j = Judgement(
        f"table_v:{definition}",
        f"Table V ({definition} definition): affective needs significantly fewer steps",
        f"110190.20 vs 99357.56 per 20 runs (difference {fmt(paper_diff)}), P one-tail 0.01",
        " vs ".join(means) + f" per 20 runs; difference {_difference(m, column, est, sign, runs)} ({share} of ε-greedy's"
        f"{censored_text})",
        cells=f"cells before it, per run: ε-greedy minus affective {marked(_lead(m, cell_column), sign)}"
        if cell_column
        else "n/a",
        direction=est.value > 0,
        size=inside,
        ratio=ratio,
        bound={">=": "lower", "<=": "upper"}.get(sign, ""),
        tests=[primary, *robust],
        primary=primary,
    )

    def decide(j: Judgement) -> str:
        robust_sig = sum(significant(t) for t in robust)
        if j.direction and primary.p < ALPHA and j.size:
            return f"reproduced: the paper's test significant (one-tailed p {pval(primary.p)}), size inside the {where}"
        if j.direction and primary.p < ALPHA:
            ratio_text = {">=": "<= ", "<=": ">= "}.get(sign, "") + sig(ratio)  # ours a bound: the ratio one the other way
            return (
                f"direction reproduced: the paper's test significant (one-tailed p {pval(primary.p)}); size differs "
                f"(paper / ours {ratio_text}, outside the {where})"
            )
        if j.direction and robust_sig:
            return "not reproduced by the paper's test (p " + pval(primary.p) + "); a robust test is significant"
        if j.direction:
            return f"not reproduced: same direction, not significant (p {pval(primary.p)})"
        return "not reproduced: opposite direction"

    j.decide = decide
    return j


def _difference(m: pd.DataFrame, column: str, est: Estimate, sign: str, runs: int) -> str:
    """
    Table V's difference per ``runs`` runs: ``est`` with its CI, or, where censored runs make it a bound (``sign``),
    the bound marked and the Kaplan-Meier restricted-mean difference in place of the interval of a bound.
    """
    if not sign:
        return est.text()
    horizon, km = restricted_over_eps(m, column, (STANDARD, AFFECTIVE))
    return f"{marked(sig(est.value), sign)}; Kaplan-Meier to {sig(horizon)} decisions a run: {km.scaled(runs).text()}"


def judge_fig4(m: pd.DataFrame, column: str = "decisions_before_optimal", definition: str = "walked") -> Judgement:
    diffs, tests = per_epsilon(m, column, f", {definition}")
    cell_diffs, cell_tests = per_epsilon(m, "cells_before_optimal", ", cells") if definition == "walked" else ({}, {})
    holm(list(cell_tests.values()))
    fewer = [e for e, d in diffs.items() if d.value > 0]
    cells_fewer = [e for e, d in cell_diffs.items() if significant(cell_tests[e]) and d.value > 0]
    j = Judgement(
        f"fig4:{definition}",
        f"Fig. 4 ({definition} definition): affective needs fewer steps at every ε but 0.7",
        "fewer at 8 of 9 ε (all but 0.7)",
        f"affective fewer (point estimate) at {len(fewer)} of {len(diffs)} ε: {eps_list(fewer)}",
        cells=f"in cells: affective significantly fewer at {len(cells_fewer)} of {len(cell_diffs)} ε: {eps_list(cells_fewer)}"
        if cell_diffs else "n/a",
        direction=len(fewer) >= len(diffs) - 1 if diffs else None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        aff = [e for e, d in diffs.items() if significant(tests[e]) and d.value > 0]
        std = [e for e, d in diffs.items() if significant(tests[e]) and d.value < 0]
        text = f"affective significantly fewer at ε {eps_list(aff)}; significantly more at {eps_list(std)}"
        at_07 = next((e for e in diffs if abs(e - 0.7) < 1e-9), None)
        if at_07 is not None and at_07 not in std:
            text += "; the paper's exception at ε 0.7 does not appear"
        if len(aff) >= len(diffs) - 1 and not [e for e in std if e != at_07]:
            return "reproduced: " + text
        if aff and len(aff) > len(std):
            return "partly reproduced: " + text
        return "not reproduced: " + text

    j.decide = decide
    return j


def judge_printed_mean(m: pd.DataFrame, table: str, agent: str, definition: str = "walked") -> Judgement:
    """
    One agent's printed mean of Table IV or V (Table V per 20 runs, under the ``walked`` or ``greedy`` definition of
    the optimal path) against ours (the baselines' own numbers).
    """
    column, printed, scale = {
        "iv": ("decisions_per_episode", paper.TABLE_IV, 1.0),
        "v": ("decisions_before_optimal" if definition == "walked" else "decisions_to_greedy_optimal", paper.TABLE_V,
              float(paper.SEEDS_PER_CELL)),
    }[table]
    flag = "censored" if definition == "walked" else "greedy_censored"
    value = printed["Mean"][0 if agent == STANDARD else 1]
    est = over_eps(cell_means(m, column), agent).scaled(scale)
    inside, ratio, where = size_against_paper(est, value, seeds_per_cell(m))
    what = "steps per episode" if table == "iv" else "steps before the optimal path"
    name = f"Table {table.upper()}: {agent} mean {what}" + (f" ({definition} definition)" if table == "v" else "")
    runs = m[m.agent == agent]
    # a run that never finds the path counts all its decisions: a lower bound on its steps before the optimal path
    censored = int(runs[flag].astype(bool).sum()) if table == "v" and flag in runs.columns else 0
    if censored:  # a lower bound: the Kaplan-Meier restricted mean in place of the interval of a bound
        horizon, km = restricted_over_eps(m, column, (agent,))
        bound = f">= {sig(est.value)}; Kaplan-Meier restricted mean to {sig(horizon)} decisions a run: "
        bound += km.scaled(scale).text()
    else:
        bound = est.text()
    j = Judgement(
        f"printed_{table}:{agent}" + (f":{definition}" if table == "v" else ""),
        name,
        f"{fmt(value)}" + (" per 20 runs" if table == "v" else ""),
        bound + (" per 20 runs" if table == "v" else "")
        + (f" ({censored:,} of {len(runs):,} runs never find the path: censored, so a lower bound)" if censored else ""),
        size=inside,
        ratio=ratio,
        bound="lower" if censored else "",
    )

    extra, longest = censored_shortfall(runs, column, flag, value / scale) if censored else (math.nan, math.nan)

    def decide(j: Judgement) -> str:
        if j.size:
            return f"reproduced: inside the {where}"
        if censored and value > est.value and not extra > longest:
            return f"inconclusive: the paper's number is above ours, a lower bound (censored runs); {where}"
        ratio_text = f"<= {sig(ratio)}" if censored else sig(ratio)
        text = f"not reproduced: paper / ours {ratio_text}, outside the {where}"
        if censored and value > est.value:
            text += (
                f"; ours is a lower bound, but to reach the paper's number each of the {censored:,} censored runs would "
                f"need about {sig(extra)} more decisions, more than the {sig(longest)} any run that found the path took "
                "in all"
            )
        return text

    j.decide = decide
    return j


def censored_shortfall(runs: pd.DataFrame, column: str, flag: str, printed: float) -> tuple[float, float]:
    """
    How many more decisions each censored run would need for the runs' mean over the ε cells to reach ``printed``
    (per run), and the largest value among the runs that found the path (what a run has been seen to take).
    """
    censored = runs[flag].astype(bool).to_numpy()
    values = runs[column].to_numpy(float)
    cells = runs.groupby("epsilon")[column].agg(["mean", "size"])
    per_cell = float(cells["size"].min()) if len(cells) else math.nan
    # the mean over ε of cell means rises by d / (cells x runs per cell) when one run's value rises by d
    shortfall = (printed - float(cells["mean"].mean())) * len(cells) * per_cell
    found = values[~censored & ~np.isnan(values)]
    return shortfall / max(int(censored.sum()), 1), float(found.max()) if len(found) else math.nan


def judge_all(m: pd.DataFrame, long: pd.DataFrame | None = None, cells: bool = True) -> list[Judgement]:
    """
    Every claim judged on ``m`` (one row per run), Holm-corrected within each claim, verdicts filled in.

    :param long: runs of 2,000 episodes for the long-run claim (its last 200 episodes); None: episodes 181-200 of m
    :param cells: also judge the step-counting claims with steps counted as cells (``Judgement.cells_verdict``)
    """
    judgements = [
        judge_table_iv_test(m),
        judge_table_iv(m),
        judge_fig3(m),
        judge_table_v(m, "decisions_before_optimal", "walked"),
        judge_table_v(m, "decisions_to_greedy_optimal", "greedy"),
        judge_fig4(m, "decisions_before_optimal", "walked"),
        judge_fig4(m, "decisions_to_greedy_optimal", "greedy"),
        judge_printed_mean(m, "iv", STANDARD),
        judge_printed_mean(m, "iv", AFFECTIVE),
        judge_printed_mean(m, "v", STANDARD, "walked"),
        judge_printed_mean(m, "v", STANDARD, "greedy"),
        judge_printed_mean(m, "v", AFFECTIVE, "walked"),
        judge_printed_mean(m, "v", AFFECTIVE, "greedy"),
        judge_episodes_to_optimal(m),
        judge_fig5(m, weighted=False),
        judge_fig5(m, weighted=True),
        judge_fig6(m),
        judge_long_run(m, long),
        judge_four_emotions(m),
    ]
    for j in judgements:
        _decide(j)
    in_cells = {
        "table_iv": lambda: judge_table_iv(m, "cells_per_episode"),
        "fig3": lambda: judge_fig3(m, "cells_per_episode"),
        "table_v:walked": lambda: judge_table_v(m, "cells_before_optimal", "walked"),
        "fig4:walked": lambda: judge_fig4(m, "cells_before_optimal", "walked"),
    }
    cells_columns = {"cells_per_episode", "cells_before_optimal"}
    if cells and cells_columns <= set(m.columns) and m[list(cells_columns)].notna().any().all():
        for j in judgements:
            if j.key in in_cells:
                j.cells_verdict = _decide(in_cells[j.key]()).verdict
    return judgements


def _decide(j: Judgement) -> Judgement:
    holm(j.tests)
    j.verdict = j.decide(j) if j.decide else ""
    return j


#: The verdict's first words, for compact tables.
verdict_word = first_words
