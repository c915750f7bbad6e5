"""
The speed ablation: does the affective agent's advantage come from its 2-cell moves? The affective agent with every
speed fixed at 1 cell (experiments/speed_one.yaml) beside the affective agent and ε-greedy, in decisions (time)
and in cells (distance).
"""

from __future__ import annotations

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.study_tables import SPEED_ONE_AGENT
from sb3_affect.study.report.rendering.document import pval, sig
from sb3_affect.study.report.sections.verdict import units_table
from sb3_affect.study.report.verdicts.censoring import censored_runs, difference_sign, difference_text, marked
from sb3_affect.study.report.verdicts.inference import Estimate, Test, holm, significant
from sb3_affect.study.report.verdicts.judgement import cell_means, diff_over_eps, eps_list, over_eps, per_epsilon

METRICS = (
    ("decisions_per_episode", "decisions per episode"),
    ("cells_per_episode", "cells per episode"),
    ("decisions_before_optimal", "decisions before the optimal path (walked)"),
    ("cells_before_optimal", "cells before the optimal path (walked)"),
    ("decisions_to_greedy_optimal", "decisions until the greedy policy stays optimal (greedy)"),
)
#: The two definitions of "optimal path found" the per-ε comparison reads (column, name): the Definitions give both.
DEFINITIONS = (
    ("decisions_before_optimal", "walked"),
    ("decisions_to_greedy_optimal", "greedy"),
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
        bound = ">=" if censored_runs(standard, column) else ""
        row = {"ε-greedy": marked(over_eps(cell_means(main, column), STANDARD).text(), bound)}
        for label, runs in variants.items():
            cells = cell_means(pd.concat([standard, runs], ignore_index=True), column)
            lead, base = diff_over_eps(cells), over_eps(cells, STANDARD).value
            own = ">=" if censored_runs(runs, column) else ""
            row[label] = marked(over_eps(cells, AFFECTIVE).text(), own)
            text = f"{lead.text()} ({lead.value / base:.1%})" if base else lead.text()
            row[f"ε-greedy minus {label}"] = marked(text, difference_sign(bool(bound), bool(own)))
        rows[name] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "mean over the 9 ε values [95% CI]"
    return table


BETTER, WORSE, SAME = "speed 1 fewer", "ε-greedy fewer", "no significant difference"


def speed_one_per_eps(main: pd.DataFrame, speed_one: pd.DataFrame) -> pd.DataFrame:
    """
    Per ε, under each definition of "optimal path found" (``DEFINITIONS``): ε-greedy's mean decisions before it, ε-greedy
    minus the affective agent at speed 1 with its Welch 95% CI and Welch test (Holm over the ε values, per definition),
    and the outcome at that ε. The speed-1 agent ignores ε, so every ε-greedy cell is compared with all its runs (its ε
    labels only split its seeds). A mean that counts censored runs is a lower bound (``>=``), and so is a difference
    from it.
    """
    standard = main[main.agent == STANDARD]
    rows: dict[str, dict[str, str]] = {}
    for column, name in DEFINITIONS:
        if column not in main.columns or column not in speed_one.columns:
            continue
        diffs, tests = per_epsilon(standard, column, "", reference=speed_one[column].to_numpy(float))
        holm(list(tests.values()))
        for eps, d in diffs.items():
            cell = standard[standard.epsilon == eps]
            row = rows.setdefault(f"{eps:.1f}", {})
            row[f"ε-greedy, {name}"] = marked(sig(float(cell[column].mean())), ">=" if censored_runs(cell, column) else "")
            row[f"minus speed 1, {name} [95% CI]"] = difference_text(d, cell, speed_one, column)
            row[f"Holm p, {name}"] = pval(tests[eps].p_holm)  # the p each outcome is judged on
            row[f"at this ε, {name}"] = outcome(d, tests[eps])
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "ε"
    return table


def outcome(d: Estimate, test: Test) -> str:
    """One ε's outcome: speed 1 significantly fewer decisions, ε-greedy significantly fewer, or neither."""
    return SAME if not significant(test) else BETTER if d.value > 0 else WORSE


def per_eps_conclusion(table: pd.DataFrame, name: str) -> str:
    """The speed ablation's conclusion per ε under definition ``name``, read from ``speed_one_per_eps``'s outcomes."""
    outcome = {float(str(e)): str(o) for e, o in table[f"at this ε, {name}"].items()}
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
    return f"{name}: {lead}: speed 1 needs " + ", ".join(parts)


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
        f"with all its {len(slow):,} runs (their mean: "
        + "; ".join(f"{sig(float(slow[c].mean()))} {name}" for c, name in DEFINITIONS if c in slow.columns)
        + ")."
    )
    ctx.table(
        "speed_one_per_eps",
        per_eps,
        "Per ε, decisions before the optimal path under both definitions (walked: the first episode whose path is "
        "shortest; greedy: until the greedy policy stays optimal): ε-greedy's mean per run and ε-greedy minus the "
        "affective agent at speed 1 (Welch 95% CIs; Welch tests, Holm-adjusted over the ε values per definition; "
        "where ε-greedy runs never found the path, \">=\" marks a lower bound and the interval is the Kaplan-Meier "
        "restricted-mean difference to the horizon both reach)",
    )
    names = [name for _, name in DEFINITIONS if f"at this ε, {name}" in per_eps.columns]
    conclusion = "; ".join(per_eps_conclusion(per_eps, name) for name in names)
    ctx.cache["speed one conclusion"] = conclusion
    ctx.doc.p(f"Per ε, {conclusion} (Welch tests, Holm over the ε values).")


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
        "values, where ε-greedy explores most; \">=\": a lower bound (runs that never found the path counted at their "
        "total); per ε: the main text's table",
    )
    units = units_table(main)
    if "lead in cells [95% CI]" in units.columns:
        n = int(main[main.agent == AFFECTIVE].groupby("epsilon").size().min())
        ctx.table(
            "lead_in_decisions_and_cells",
            units,
            f"Per ε: the affective agent's lead before the first walked optimal path, in decisions and in cells (per "
            f"run, {n:,} seeds per cell; Welch 95% CIs; where ε-greedy runs never found the path, \">=\" marks a lower "
            "bound and the interval is the Kaplan-Meier restricted-mean difference to the horizon both agents reach)",
        )
