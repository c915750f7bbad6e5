"""
The limitations of this replication, written from what the report computed (the censored runs, the protocol's draw
and how often a random 20-seed draw gives its verdicts, the step unit, the size of the exploratory studies), never as
fixed claims about numbers. Placed in the main text, written once every section has run (``ReportContext.later``).
"""

from __future__ import annotations

import math

import pandas as pd

from sb3_affect.study.report.estimation.bootstrap import EXPLORATORY_RULE
from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.sections.evidence import REPETITIONS
from sb3_affect.study.report.sections.main_finding import Comparison
from sb3_affect.study.report.sections.protocol_draw import PAPER_SIDE, RANK, draw_table
from sb3_affect.study.report.verdicts.censoring import censored_runs
from sb3_affect.study.report.verdicts.judgement import eps_list

#: A share of random 20-seed draws below this gives the protocol's verdict rarely (the limitations name it).
RARE = 0.05


def censoring_item(runs: pd.DataFrame, found: Comparison | None) -> str:
    """How many runs of each paper agent never found the optimal path, under both definitions, and where."""
    standard, affective = runs[runs.agent == STANDARD], runs[runs.agent == AFFECTIVE]
    walked = censored_runs(standard, "decisions_before_optimal")
    greedy = censored_runs(standard, "decisions_to_greedy_optimal")
    shares = standard.groupby("epsilon").censored.mean()
    heavy = [float(str(e)) for e, share in shares.items() if share >= 0.5]
    text = (
        f"Censoring: {walked:,} of the {len(standard):,} ε-greedy runs never walk an optimal path within their episodes "
        f"({greedy:,} never reach a greedy policy that stays optimal; affective runs: "
        f"{censored_runs(affective, 'decisions_before_optimal'):,} and "
        f"{censored_runs(affective, 'decisions_to_greedy_optimal'):,})"
    )
    if heavy:
        text += f", most of them at ε {eps_list(heavy)}, where half or more of a cell's runs are censored"
    if found is not None:
        text += f"; the main finding's speed-matched ε-greedy: {found.censored[1]:,} of {found.runs[1]:,}"
    return (
        text + ". They count with all their decisions, so every mean and difference they enter is a bound, marked "
        "\">=\" or \"<=\" where it is printed, and the main finding, Table V's cards, the speed ablation per ε and the "
        "lead per ε (Appendix B) put Kaplan-Meier restricted means beside the bounds (rliable's IQMs: the Kaplan-Meier "
        "distribution's, or a bound where it is not estimable)."
    )


def draw_item(blocks: pd.DataFrame | None, needed: pd.DataFrame | None) -> str:
    """The protocol's draw: its affective blocks' ranks toward the paper, and the verdicts a random draw rarely gives."""
    parts = []
    if blocks is not None:
        affective = blocks[[label.split(":")[1].strip().startswith("affective") for label in blocks.index]]
        toward = [label for label in affective.index if affective.loc[label, PAPER_SIDE] == "yes"]
        total = str(blocks[RANK].iloc[0]).split(" of ")[1]
        if toward:
            ranks = ", ".join(f"{affective.loc[label, RANK].split(' of ')[0]} ({label})" for label in toward)
            parts.append(
                f"The paper protocol's 20 seeds per cell are one of the large-N study's {total} disjoint 20-seed blocks, "
                f"and its affective runs lean toward the paper's numbers: ranks {ranks} of {total} (1 = lowest), each on "
                "the paper's side of the other blocks"
            )
    column = next((c for c in (needed.columns if needed is not None else []) if "protocol's verdict" in c), None)
    if needed is not None and column is not None:
        rare = [(str(label), float(str(share))) for label, share in needed[column].items()
                if not math.isnan(float(str(share))) and float(str(share)) < RARE]  # fmt: skip
        if rare:
            parts.append(
                "the protocol's verdict is a rare draw for "
                + "; ".join(f"{label} ({share:.0%} of {REPETITIONS} random 20-seed subsamples give it)"
                            for label, share in rare)
            )  # fmt: skip
    if not parts:
        return ""
    return (
        "; ".join(parts) + ". One possible cause is selection: the protocol's seeds are the ones in view while the "
        "implementation was written and checked. The verdicts at the large seed count do not depend on that draw; "
        "the verdicts at 20 seeds are read beside them."
    )


def limitations_section(ctx: ReportContext) -> None:
    if ctx.verdict_refusal():
        return
    ctx.later(_write_limitations)


def _write_limitations(ctx: ReportContext) -> None:
    runs = ctx.large if ctx.large is not None else ctx.metrics
    items = [
        "The paper's implementation is not available: every verdict compares our implementation of the paper's text "
        "with its printed numbers. Where the text allows several readings of the appraisal, the verdict uses the "
        "literal one and Appendix A judges every claim under every reading.",
        "The verdict's rules are fixed in code and applied alike at every seed count (Appendix D gives each verdict "
        "from 5 to the largest seed count); they were revised during development, after results had been seen.",
        "The step unit: the paper counts steps, and a step is a decision (time) or a cell (distance). The verdict leads "
        "in decisions; each claim that counts steps has its verdict in cells beside it, and the replication forensics "
        "(Appendix C) does not decide between the two.",
        censoring_item(runs, ctx.cache.get("main finding")),
        draw_item(ctx.cache.get("protocol draw"), ctx.cache.get("seeds needed")) if draw_table(ctx) is not None else "",
        "The long-run claim is judged on separate runs of 2,000 episodes (50 per cell), not on the paper's 200-episode "
        "runs; the seed-count study's power table judges episodes 181-200 of the 200-episode runs.",
        "The exploratory studies (two hunters, MiniGrid, fair baselines, the deep study) are not part of the verdict; "
        f"where they compare agents they use one rule, {EXPLORATORY_RULE}, and say where it does not tell them apart.",
    ]
    ctx.doc.h("Limitations")
    ctx.doc.ul([item for item in items if item])
