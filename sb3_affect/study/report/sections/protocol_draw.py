"""
Is the paper protocol's draw rare, or is the predictive interval wrong? The large-N study's replicates split into
disjoint blocks of the paper's 20 seeds per cell (its first block is the protocol's own runs: ``seeds_from: paper``);
each block's statistic is computed as the verdict computes the protocol's (the mean over the 9 ε values of the cell
means, per 20 runs for Table V). The other blocks test the interval: a 95% interval leaves about 5% of them outside.
The protocol block's rank among all blocks says how rare its draw is.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from scipy import stats as sps

from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.document import pval, sig
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.inference import ALPHA, predictive
from sb3_affect.study.report.verdicts.judgement import STANDARD, cell_means, over_eps, seeds_per_cell

#: The printed means the verdict sizes with the predictive interval: (label, agent, column, scale, the paper's number).
STATISTICS = (
    ("Table IV: ε-greedy, steps per episode", STANDARD, "decisions_per_episode", 1, paper.TABLE_IV["Mean"][0]),
    ("Table IV: affective, steps per episode", "affective", "decisions_per_episode", 1, paper.TABLE_IV["Mean"][1]),
    ("Table V: ε-greedy, walked (per 20 runs)", STANDARD, "decisions_before_optimal", paper.SEEDS_PER_CELL,
     paper.TABLE_V["Mean"][0]),
    ("Table V: affective, walked (per 20 runs)", "affective", "decisions_before_optimal", paper.SEEDS_PER_CELL,
     paper.TABLE_V["Mean"][1]),
    ("Table V: ε-greedy, greedy (per 20 runs)", STANDARD, "decisions_to_greedy_optimal", paper.SEEDS_PER_CELL,
     paper.TABLE_V["Mean"][0]),
    ("Table V: affective, greedy (per 20 runs)", "affective", "decisions_to_greedy_optimal", paper.SEEDS_PER_CELL,
     paper.TABLE_V["Mean"][1]),
)  # fmt: skip
#: Column names of ``block_table``.
VALUE, INTERVAL = "protocol's runs", "95% predictive interval"
OUTSIDE, RANK, CAUSE = "other blocks outside the interval", "protocol's rank among the blocks (1 = lowest)", "cause"
PAPER_SIDE = "on the paper's side of the other blocks' mean"


def block_statistics(m: pd.DataFrame, agent: str, column: str, scale: float, block: int) -> pd.Series:
    """The statistic of each disjoint block of ``block`` replicates per cell (block b: replicates b*block ...)."""
    runs = m[m.agent == agent]
    blocks = runs.replicate.to_numpy(int) // block
    frame = pd.DataFrame({"block": blocks, "epsilon": runs.epsilon.to_numpy(float), "v": runs[column].to_numpy(float)})
    whole = frame.groupby("block").epsilon.transform("size") == frame.groupby("block").epsilon.transform("size").max()
    per_cell = frame[whole].groupby(["block", "epsilon"]).v.mean()
    return per_cell.groupby(level="block").mean() * scale


def block_row(
    large: pd.DataFrame, protocol: pd.DataFrame, agent: str, column: str, scale: float, printed: float
) -> dict[str, object]:
    """
    One statistic: the protocol's value, the predictive interval at the paper's seeds from ``large``, the other
    blocks outside it (and a one-sided binomial test of that count against 5%), the protocol's rank among the blocks,
    its distance from the other blocks' mean in their standard deviations, whether it lies on the side of the paper's
    number ``printed``, and the cause these point to.
    """
    block = paper.SEEDS_PER_CELL
    est = over_eps(cell_means(large, column), agent).scaled(scale)
    low, high = predictive(est, seeds_per_cell(large), block)
    value = over_eps(cell_means(protocol, column), agent).value * scale
    stats = block_statistics(large, agent, column, scale, block)
    others = stats.drop(index=0, errors="ignore")
    outside = int(((others < low) | (others > high)).sum())
    binomial = float(sps.binomtest(outside, len(others), 1 - 0.95, alternative="greater").pvalue) if len(others) else math.nan
    rank = int((stats < value).sum()) + 1
    spread = float(others.std(ddof=1)) if len(others) > 1 else math.nan
    z = (value - float(others.mean())) / spread if spread and spread > 0 else math.nan
    inside = low <= value <= high
    if inside:
        cause = "inside the interval"
    elif binomial < ALPHA:
        cause = "the interval: too many blocks fall outside it"
    else:
        cause = "the draw: the interval holds for the other blocks"
    return {
        VALUE: sig(value),
        INTERVAL: f"[{sig(low)}, {sig(high)}]",
        OUTSIDE: f"{outside} of {len(others)} (binomial p {pval(binomial)} against 5%)",
        RANK: f"{rank} of {len(stats)}",
        "protocol - other blocks' mean, in their SDs": f"{z:+.2f}" if not math.isnan(z) else "",
        PAPER_SIDE: "yes" if (value - float(others.mean())) * (printed - float(others.mean())) > 0 else "no",
        CAUSE: cause,
    }


def block_table(large: pd.DataFrame, protocol: pd.DataFrame) -> pd.DataFrame:
    """``block_row`` for each printed mean the verdict sizes (``STATISTICS``)."""
    rows = {
        label: block_row(large, protocol, agent, column, scale, printed)
        for label, agent, column, scale, printed in STATISTICS
        if column in large.columns and column in protocol.columns
    }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "statistic"
    return table


def per_epsilon_excess(large: pd.DataFrame, agent: str, column: str) -> tuple[int, int, float]:
    """
    Per ε: how many of the protocol's cell means (replicates 0-19) lie above the other replicates' mean, of how
    many, and the protocol's pooled mean over the others' (a ratio).
    """
    runs = large[large.agent == agent]
    own = runs.replicate < paper.SEEDS_PER_CELL
    first, rest = runs[own].groupby("epsilon")[column].mean(), runs[~own].groupby("epsilon")[column].mean()
    above = int((first > rest).sum())
    ratio = float(runs[own][column].mean() / runs[~own][column].mean()) if len(runs[~own]) else math.nan
    return above, len(first), ratio


def finding(table: pd.DataFrame) -> str:
    """One sentence: which statistics lie outside their interval and what the blocks say about why."""
    outside = table[table[CAUSE] != "inside the interval"]
    if not len(outside):
        return "Every printed mean's protocol statistic lies inside its predictive interval."
    parts = [
        f"{label}: {row[VALUE]} outside {row[INTERVAL]}, rank {row[RANK]} among the "
        f"disjoint 20-seed blocks, {row[OUTSIDE]} ({row[CAUSE]})"
        for label, row in outside.iterrows()
    ]
    causes = set(outside[CAUSE])
    verdict = (
        "The interval is right and the protocol's draw is rare"
        if causes == {"the draw: the interval holds for the other blocks"}
        else "The interval is too narrow for some statistics"
        if causes == {"the interval: too many blocks fall outside it"}
        else "The causes differ between statistics"
    )
    return f"{verdict}. " + "; ".join(parts) + "."


def block_count(large: pd.DataFrame) -> int:
    """How many whole disjoint blocks of the paper's 20 seeds per cell the large-N study holds."""
    return int(np.floor(seeds_per_cell(large) / paper.SEEDS_PER_CELL))


def draw_table(ctx: ReportContext) -> pd.DataFrame | None:
    """``block_table`` of the report's large-N study and paper sweep, computed once per report (None: no blocks)."""
    if ctx.large is None or not ctx.has_paper_agents or ctx.verdict_refusal() or block_count(ctx.large) < 2:
        return None
    if "protocol draw" not in ctx.cache:
        ctx.cache["protocol draw"] = block_table(ctx.large, ctx.metrics)
    return ctx.cache["protocol draw"]


def protocol_draw_section(ctx: ReportContext) -> None:
    """The protocol's statistics among the disjoint 20-seed blocks of the large-N study (appendix)."""
    table = draw_table(ctx)
    if table is None or ctx.large is None:
        return
    above, cells, ratio = per_epsilon_excess(ctx.large, "affective", "decisions_before_optimal")
    ctx.doc.h("The protocol's draw against the large-N blocks")
    ctx.doc.p(
        f"The large-N study's {seeds_per_cell(ctx.large):,} replicates per cell split into {block_count(ctx.large)} "
        "disjoint blocks of the paper's 20 seeds per cell; the first block is the paper protocol's own runs (same "
        "seeds, same numbers). Each block's statistic is computed as the verdict computes the protocol's. A 95% "
        "predictive interval built for that statistic leaves about 5% of the other blocks outside it; a protocol "
        "statistic outside it while the other blocks fit says the draw is rare, not that the interval is wrong."
    )
    ctx.table("protocol_draw", table, "Each printed mean's statistic: the protocol's runs among the disjoint 20-seed blocks")
    ctx.doc.p(
        finding(table) + f" The protocol's affective runs lie above the other replicates' mean at {above} of {cells} ε "
        f"values; pooled over ε, they take {abs(ratio - 1):.1%} {'more' if ratio >= 1 else 'fewer'} decisions before the "
        "optimal path than the other replicates."
    )
