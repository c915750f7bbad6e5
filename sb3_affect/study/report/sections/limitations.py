"""
The limitations of this replication, written from what the report computed (the protocol's draw, the censored runs,
the step unit, the seed counts of the exploratory studies), never as fixed claims about numbers.
"""

from __future__ import annotations

from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.sections.protocol_draw import draw_table, rare_draws


def limitations_section(ctx: ReportContext) -> None:
    if ctx.verdict_refusal():
        return

    found = ctx.cache.get("main finding")
    blocks = draw_table(ctx)
    rare = rare_draws(blocks) if blocks is not None else ""
    items = [
        "The paper's implementation is not available: every verdict compares our implementation of the paper's text "
        "with its printed numbers. Where the text allows several readings of the appraisal, the verdict uses the "
        "literal one and Appendix A judges every claim under every reading.",
        "The step unit: the paper counts steps, and a step is a decision (time) or a cell (distance). The verdict leads "
        "in decisions; each claim that counts steps has its verdict in cells beside it, and the replication forensics "
        "(Appendix C) does not decide between the two.",
        "Censoring: a run that never walks an optimal path within its 200 episodes enters Table V's means with all its "
        "decisions, so those means are lower bounds"
        + (
            f" ({found.censored[0]:,} affective and {found.censored[1]:,} speed-matched runs in the main finding);"
            if found
            else ";"
        )
        + " the main finding puts the Kaplan-Meier restricted means beside them.",
        "The paper protocol's 20 seeds per cell are one draw of the large-N study's disjoint 20-seed blocks"
        + (f"; a rare one for {rare} (rank among the blocks, 1 = lowest; Appendix B)" if rare else " (Appendix B)")
        + ", so the verdicts at 20 seeds are read beside those at the large seed count.",
        "The long-run claim is judged on separate runs of 2,000 episodes (50 per cell), not on the paper's 200-episode "
        "runs; the seed-count study's power table judges episodes 181-200 of the 200-episode runs.",
        "The exploratory studies (two hunters, MiniGrid, fair baselines) use few seeds: they report intervals, and "
        "say where those intervals do not separate the agents; they are not part of the verdict.",
    ]
    ctx.doc.h("Limitations")
    ctx.doc.ul(items)
