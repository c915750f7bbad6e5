"""
The speed ablation: does the affective agent's advantage come from its 2-cell moves? The affective agent with every
speed fixed at 1 cell (experiments/speed_one.yaml) beside the affective agent and ε-greedy, in decisions (time)
and in cells (distance).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.study_tables import SPEED_ONE_AGENT
from sb3_affect.study.report.rendering.document import sig
from sb3_affect.study.report.verdicts.inference import holm, significant
from sb3_affect.study.report.verdicts.judgement import cell_means, diff_over_eps, eps_list, over_eps, p_text, per_epsilon

METRICS = (
    ("decisions_per_episode", "decisions per episode"),
    ("cells_per_episode", "cells per episode"),
    ("decisions_before_optimal", "decisions before the optimal path"),
    ("cells_before_optimal", "cells before the optimal path"),
)


def speed_table(main: pd.DataFrame, speed_one: pd.DataFrame) -> pd.DataFrame:
    """Per metric: each agent's mean over ε [95% CI], and each affective variant's lead over ε-greedy (share)."""
    standard = main[main.agent == STANDARD]
    variants = {
        "affective (1 or 2 cells)": main[main.agent == AFFECTIVE],
        "affective, speed fixed at 1": speed_one.assign(agent=AFFECTIVE),
    }
    rows = {}
    for column, name in METRICS:
        if column not in main.columns or column not in speed_one.columns:
            continue
        row = {"ε-greedy": over_eps(cell_means(main, column), STANDARD).text()}
        for label, runs in variants.items():
            cells = cell_means(pd.concat([standard, runs], ignore_index=True), column)
            lead, base = diff_over_eps(cells), over_eps(cells, STANDARD).value
            row[label] = over_eps(cells, AFFECTIVE).text()
            row[f"ε-greedy minus {label}"] = f"{lead.text()} ({lead.value / base:.1%})" if base else lead.text()
        rows[name] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "mean over the 9 ε values [95% CI]"
    return table


#: The per-ε comparison of the speed ablation: before the first walked optimal path (the lead the verdict tabulates).
PER_EPS = ("decisions_before_optimal", "decisions before the optimal path")
BETTER, WORSE, SAME = "speed 1 fewer", "ε-greedy fewer", "no significant difference"


#: The speed-1 column of ``speed_one_per_eps``: the mean its difference column subtracts (every run, pooled).
SPEED_ONE_POOLED = "affective, speed fixed at 1 (all its runs: it ignores ε)"


def speed_one_per_eps(main: pd.DataFrame, speed_one: pd.DataFrame, column: str = PER_EPS[0]) -> pd.DataFrame:
    """
    Per ε: ε-greedy, the affective agent and the affective agent at speed 1, ε-greedy minus speed 1 with its Welch 95%
    CI and Welch test (Holm over the ε values), and the outcome at that ε. The speed-1 agent ignores ε, so every ε-greedy
    cell is compared with all its runs (its ε labels only split its seeds); its column gives the mean of all its runs,
    the number the difference subtracts (so ε-greedy minus that column is the difference column).
    """
    standard = main[main.agent == STANDARD]
    pooled = speed_one[column].to_numpy(float)
    diffs, tests = per_epsilon(standard, column, "", reference=pooled)
    holm(list(tests.values()))
    means = {
        "ε-greedy": standard.groupby("epsilon")[column].mean(),
        "affective (1 or 2 cells)": main[main.agent == AFFECTIVE].groupby("epsilon")[column].mean(),
    }
    pooled_mean = float(np.nanmean(pooled)) if len(pooled) else float("nan")
    rows = {}
    for eps, d in diffs.items():
        test = tests[eps]
        outcome = SAME if not significant(test) else BETTER if d.value > 0 else WORSE
        rows[f"{eps:.1f}"] = {
            **{name: sig(float(series.get(eps, float("nan")))) for name, series in means.items()},
            SPEED_ONE_POOLED: sig(pooled_mean),
            "ε-greedy minus speed 1 [95% CI]": d.text(),
            "Welch test": p_text(test),
            "at this ε": outcome,
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "ε"
    return table


def per_eps_conclusion(table: pd.DataFrame) -> str:
    """The speed ablation's conclusion per ε, read from ``speed_one_per_eps``'s outcomes."""
    outcome = {float(str(e)): str(o) for e, o in table["at this ε"].items()}
    better = sorted(e for e, o in outcome.items() if o == BETTER)
    worse = sorted(e for e, o in outcome.items() if o == WORSE)
    same = sorted(e for e, o in outcome.items() if o == SAME)
    if better and better == sorted(outcome)[-len(better):] and len(better) < len(outcome):
        lead = f"the direction rule alone beats ε-greedy only against ε >= {min(better):.1f}"
    elif better and len(better) == len(outcome):
        lead = "the direction rule alone beats ε-greedy at every ε"
    elif better:
        lead = f"the direction rule alone beats ε-greedy at ε {eps_list(better)}"
    else:
        lead = "the direction rule alone beats ε-greedy at no ε"
    parts = [f"significantly fewer decisions at ε {eps_list(better)}", f"significantly more at ε {eps_list(worse)}"]
    if same:
        parts.append(f"neither at ε {eps_list(same)}")
    return f"{lead}: speed 1 needs " + ", ".join(parts) + " (Welch tests, Holm over the ε values)"


def speed_one_section(ctx: ReportContext) -> None:
    """The speed ablation per ε, beside the lead table it qualifies (main text; the table per metric: the appendix)."""
    speed_one = ctx.study("speed_one")
    if speed_one is None or not ctx.has_paper_agents or ctx.verdict_refusal():
        return
    main = ctx.large if ctx.large is not None else ctx.metrics
    n = int(speed_one.groupby("epsilon").size().min())
    slow = speed_one[speed_one.agent == SPEED_ONE_AGENT]
    per_eps = speed_one_per_eps(main, slow)
    if not len(per_eps):
        return
    ctx.doc.p(
        "The affective agent moves 1 or 2 cells per decision in joy and anger (Table III), ε-greedy 1. The speed "
        f"ablation keeps every emotion's direction rule and fixes the speed at 1 cell ({n:,} seeds per ε label; seeds "
        "of its own), so a decision and a cell are the same again. It ignores ε, so every ε-greedy cell is compared "
        f"with all its {len(slow):,} runs."
    )
    ctx.table(
        "speed_one_per_eps",
        per_eps,
        f"Per ε: {PER_EPS[1]}, ε-greedy against the affective agent at speed 1 (means per run; the difference is "
        "ε-greedy's column minus the speed-1 column; Welch 95% CIs, Holm over the ε values)",
    )
    conclusion = per_eps_conclusion(per_eps)
    ctx.cache["speed one conclusion"] = conclusion
    ctx.doc.p(f"Per ε, {conclusion}; the rest of the affective agent's lead is its 2-cell moves.")


def speed_table_section(ctx: ReportContext) -> None:
    """The speed ablation per metric, averaged over ε, with CIs (appendix)."""
    speed_one = ctx.study("speed_one")
    if speed_one is None or not ctx.has_paper_agents or ctx.verdict_refusal():
        return
    main = ctx.large if ctx.large is not None else ctx.metrics
    ctx.doc.h("The speed ablation per metric")
    table = speed_table(main, speed_one[speed_one.agent == SPEED_ONE_AGENT])
    ctx.table(
        "speed_one",
        table,
        "ε-greedy, the affective agent, and the affective agent at speed 1, in decisions and cells (means over the 9 ε "
        "values [95% CI]; the lead as a share of ε-greedy's mean). The lead averaged over ε is dominated by the large ε "
        "values, where ε-greedy explores most; per ε: the main text's table",
    )
