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
from sb3_affect.study.report.sections.speed_ablation import DEFINITIONS, METRICS
from sb3_affect.study.report.verdicts.censoring import UNBOUNDED, censored_runs, difference_sign, marked
from sb3_affect.study.report.verdicts.judgement import cell_means, diff_over_eps, over_eps


def lead_numbers(main: pd.DataFrame, speed_one: pd.DataFrame) -> pd.DataFrame:
    """
    Per metric (``speed_ablation.METRICS``: before the optimal path under both definitions): ε-greedy's mean over ε,
    the affective agent's lead (ε-greedy minus it) with 2-cell moves and at speed 1, both as shares of ε-greedy's mean,
    the share of the lead that remains at speed 1 (NaN when there is no lead to keep), the censored runs of each agent
    (counted at their total) and the mark of each number as a bound (``censoring.difference_sign``).
    """
    standard, affective = main[main.agent == STANDARD], main[main.agent == AFFECTIVE]
    rows = {}
    for column, name in METRICS:
        if column not in main.columns or column not in speed_one.columns:
            continue
        two = cell_means(main, column)
        one = cell_means(pd.concat([standard, speed_one.assign(agent=AFFECTIVE)], ignore_index=True), column)
        base = over_eps(two, STANDARD).value
        lead_two, lead_one = diff_over_eps(two).value, diff_over_eps(one).value
        censored = [censored_runs(runs, column) for runs in (standard, affective, speed_one)]
        sign_two, sign_one = (difference_sign(censored[0] > 0, c > 0) for c in censored[1:])
        rows[name] = {
            "ε-greedy": base,
            "lead, 1 or 2 cells": lead_two,
            "lead, speed 1": lead_one,
            "lead share, 1 or 2 cells": lead_two / base if base else float("nan"),
            "lead share, speed 1": lead_one / base if base else float("nan"),
            "remains at speed 1": lead_one / lead_two if lead_two > 0 else float("nan"),
            "censored (ε-greedy, affective, speed 1)": censored,
            "runs (ε-greedy)": len(standard),
            "bound, ε-greedy": ">=" if censored[0] else "",
            "bound, 1 or 2 cells": sign_two,
            "bound, speed 1": sign_one,
            "bound, remains": remains_sign(censored, lead_two - lead_one),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "metric (mean over the 9 ε values)"
    return table


def remains_sign(censored: list[int], gap: float) -> str:
    """
    The mark of the share that remains, (E - s) / (E - a), when censored runs enter it: with only ε-greedy's mean E a
    lower bound, the share rises with E where the speed-1 mean s is above the affective mean a (``gap`` = s - a > 0),
    so it is a lower bound there, an upper bound otherwise; with the others' means bounds too, no bound.
    """
    if not any(censored):
        return ""
    if any(censored[1:]):
        return UNBOUNDED
    return ">=" if gap > 0 else "<="


def censoring_note(row: pd.Series) -> str:
    """Where a metric's numbers are bounds: how many ε-greedy runs never found the path (counted at their total)."""
    censored = row["censored (ε-greedy, affective, speed 1)"]
    if not any(censored):
        return ""
    return f"{censored[0]:,} of {int(row['runs (ε-greedy)']):,} ε-greedy runs censored: bounds"


def metric_clause(name: str, row: pd.Series) -> str:
    """What one metric says of the lead at speed 1, its numbers marked as bounds where censored runs enter them."""
    two, one, base = float(row["lead, 1 or 2 cells"]), float(row["lead, speed 1"]), float(row["ε-greedy"])
    note = censoring_note(row)
    if two <= 0:
        return f"in {name} the affective agent is behind ε-greedy by {-two / base:.1%} ({sig(-two)})"
    kept, sign = float(row["remains at speed 1"]), str(row["bound, remains"])
    where = (
        f"in {name} its lead of {marked(sig(two), str(row['bound, 1 or 2 cells']))} becomes "
        f"{marked(sig(one), str(row['bound, speed 1']))} at speed 1"
    )
    return f"{where} ({kept_text(kept, sign)}{'; ' + note if note else ''})"


def kept_text(kept: float, sign: str) -> str:
    """How much of the lead remains at speed 1, its share marked as a bound where it is one."""
    share = marked(f"{kept:.0%}", sign)
    if kept > 0:
        return f"{share} remains"
    return f"none remains ({share})" if sign else "none remains"


def mechanism_sentence(table: pd.DataFrame, per_eps: str = "") -> str:
    """The sentence on where the lead comes from, per metric, then per ε (``per_eps``: the speed ablation's)."""
    if not len(table):
        return ""
    clauses = [metric_clause(str(name), row) for name, row in table.iterrows()]
    text = "At speed 1 (averaged over ε): " + "; ".join(clauses)
    return text + (f". Per ε, {per_eps}" if per_eps else "") + "."


def mechanism_summary(table: pd.DataFrame) -> str:
    """
    The abstract's sentence: how much of the lead before the optimal path remains at speed 1 under each definition of
    "optimal path found", the share and its bound read from the table (``lead_numbers``).
    """
    names, parts = dict(METRICS), []
    rows = dict(iter(table.iterrows()))
    for column, definition in DEFINITIONS:
        row = rows.get(names[column])
        if row is None:
            continue
        kept, two = float(row["remains at speed 1"]), float(row["lead, 1 or 2 cells"])
        share = "no lead to keep" if two <= 0 else kept_text(kept, str(row["bound, remains"]))
        censored = row["censored (ε-greedy, affective, speed 1)"][0]
        parts.append(f"{share} under the {definition} definition ({censored:,} ε-greedy runs censored)")
    if not parts:
        return ""
    return "At speed 1, of the affective agent's lead before the optimal path (mean over ε) " + " and ".join(parts) + "."


def shown_leads(table: pd.DataFrame) -> pd.DataFrame:
    """``lead_numbers`` as the report prints it: each number marked as a bound where censored runs enter it."""

    def column(value: str, share: str, bound: str) -> list[str]:
        return [marked(f"{sig(v)} ({s:.1%})", b) for v, s, b in zip(table[value], table[share], table[bound])]

    remains = zip(table["remains at speed 1"], table["bound, remains"])
    return pd.DataFrame(
        {
            "ε-greedy": [marked(sig(v), b) for v, b in zip(table["ε-greedy"], table["bound, ε-greedy"])],
            "lead, 1 or 2 cells (share of ε-greedy's)": column(
                "lead, 1 or 2 cells", "lead share, 1 or 2 cells", "bound, 1 or 2 cells"
            ),
            "lead, speed fixed at 1 (share)": column("lead, speed 1", "lead share, speed 1", "bound, speed 1"),
            "share of the lead that remains at speed 1": [marked(f"{v:.0%}", b) if v == v else "no lead" for v, b in remains],
            "censored runs (ε-greedy, affective, speed 1)": [
                ", ".join(f"{c:,}" for c in cs) for cs in table["censored (ε-greedy, affective, speed 1)"]
            ],
        },
        index=table.index,
    )


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
        shown = shown_leads(table)
        ctx.table(
            "lead_sources",
            shown,
            f"Per metric, averaged over the 9 ε values ({n:,} seeds per cell): the affective agent's lead over ε-greedy "
            "(ε-greedy minus affective; negative: ε-greedy ahead) with its 1- or 2-cell moves and with its speed fixed "
            "at 1 (the speed ablation's own seeds), and how much of the lead remains at speed 1; before the optimal path "
            "under both definitions (walked: the first episode whose path is shortest; greedy: until the greedy policy "
            "stays optimal). \">=\": a lower bound (runs that never found the path counted at their total; only "
            "ε-greedy's mean is one here, so the share that remains is a bound too, in the direction marked)",
        )
        ctx.doc.p(mechanism_sentence(table))
