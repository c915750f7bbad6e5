"""
Where the affective agent's lead over ε-greedy comes from, per metric: its lead with its 2-cell moves and with its
speed fixed at 1 (the speed ablation), averaged over ε, and how much of the lead remains at speed 1. The abstract's
mechanism sentence is written from these numbers, never from fixed text.
"""

from __future__ import annotations

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.study_tables import SPEED_ONE_AGENT
from sb3_affect.study.report.rendering.document import sig
from sb3_affect.study.report.sections.speed_ablation import METRICS
from sb3_affect.study.report.sections.verdict import units_table
from sb3_affect.study.report.verdicts.judgement import cell_means, diff_over_eps, over_eps


def lead_numbers(main: pd.DataFrame, speed_one: pd.DataFrame) -> pd.DataFrame:
    """
    Per metric (``speed_ablation.METRICS``): ε-greedy's mean over ε, the affective agent's lead (ε-greedy minus it)
    with 2-cell moves and at speed 1, both as shares of ε-greedy's mean, and the share of the lead that remains at
    speed 1 (NaN when there is no lead to keep).
    """
    standard = main[main.agent == STANDARD]
    rows = {}
    for column, name in METRICS:
        if column not in main.columns or column not in speed_one.columns:
            continue
        two = cell_means(main, column)
        one = cell_means(pd.concat([standard, speed_one.assign(agent=AFFECTIVE)], ignore_index=True), column)
        base = over_eps(two, STANDARD).value
        lead_two, lead_one = diff_over_eps(two).value, diff_over_eps(one).value
        rows[name] = {
            "ε-greedy": base,
            "lead, 1 or 2 cells": lead_two,
            "lead, speed 1": lead_one,
            "lead share, 1 or 2 cells": lead_two / base if base else float("nan"),
            "lead share, speed 1": lead_one / base if base else float("nan"),
            "remains at speed 1": lead_one / lead_two if lead_two > 0 else float("nan"),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "metric (mean over the 9 ε values)"
    return table


def metric_clause(name: str, row: pd.Series) -> str:
    """What one metric says about the source of the lead, in words chosen by its numbers."""
    two, one, base = float(row["lead, 1 or 2 cells"]), float(row["lead, speed 1"]), float(row["ε-greedy"])
    if two <= 0:
        return f"in {name} the affective agent is behind ε-greedy by {-two / base:.1%} ({sig(-two)})"
    kept = float(row["remains at speed 1"])
    where = f"in {name} its lead of {sig(two)} becomes {sig(one)} at speed 1"
    if kept >= 0.5:
        return f"{where} ({kept:.0%} remains: mostly its direction rule, not its 2-cell moves)"
    if kept > 0:
        return f"{where} ({kept:.0%} remains: mostly its 2-cell moves)"
    return f"{where} (none remains: its 2-cell moves)"


def mechanism_sentence(table: pd.DataFrame, per_eps: str = "") -> str:
    """The abstract's sentence on where the lead comes from, per metric, then per ε (``per_eps``: the speed ablation's)."""
    if not len(table):
        return ""
    clauses = [metric_clause(str(name), row) for name, row in table.iterrows()]
    text = "Where the affective agent's lead comes from (averaged over ε; the speed ablation fixes its speed at 1): " + (
        "; ".join(clauses)
    )
    return text + (f". Per ε, {per_eps}" if per_eps else "") + "."


def lead_section(ctx: ReportContext) -> None:
    """Where the lead comes from: per metric (with and without the 2-cell moves), then per ε in decisions and cells."""
    if not ctx.has_paper_agents or ctx.verdict_refusal():
        return
    main = ctx.large if ctx.large is not None else ctx.metrics
    n = int(main[main.agent == AFFECTIVE].groupby("epsilon").size().min())
    ctx.doc.h("Where the affective agent's lead comes from")
    speed_one = ctx.study("speed_one")
    if speed_one is not None:
        table = lead_numbers(main, speed_one[speed_one.agent == SPEED_ONE_AGENT])
        ctx.cache["lead sources"] = table
        shown = pd.DataFrame(
            {
                "ε-greedy": [sig(v) for v in table["ε-greedy"]],
                "lead, 1 or 2 cells (share of ε-greedy's)": [
                    f"{sig(v)} ({s:.1%})" for v, s in zip(table["lead, 1 or 2 cells"], table["lead share, 1 or 2 cells"])
                ],
                "lead, speed fixed at 1 (share)": [
                    f"{sig(v)} ({s:.1%})" for v, s in zip(table["lead, speed 1"], table["lead share, speed 1"])
                ],
                "share of the lead that remains at speed 1": [
                    f"{v:.0%}" if v == v else "no lead" for v in table["remains at speed 1"]
                ],
            },
            index=table.index,
        )
        ctx.table(
            "lead_sources",
            shown,
            f"Per metric, averaged over the 9 ε values ({n:,} seeds per cell): the affective agent's lead over ε-greedy "
            "(ε-greedy minus affective; negative: ε-greedy ahead) with its 1- or 2-cell moves and with its speed fixed "
            "at 1 (the speed ablation's own seeds), and how much of the lead remains at speed 1",
        )
        ctx.doc.p(mechanism_sentence(table))
    units = units_table(main)
    if "lead in cells [95% CI]" in units.columns:
        ctx.table(
            "lead_in_decisions_and_cells",
            units,
            f"Per ε: the affective agent's lead before the first walked optimal path, in decisions and in cells (per "
            f"run, {n:,} seeds per cell; Welch 95% CIs); the speed-1 table below qualifies it per ε",
        )
