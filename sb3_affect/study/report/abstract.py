"""
The report's first minute: a five-sentence abstract and a headline table (one line per claim: the verdict at the
largest seed count), both written from the judged claims (``report.verdict.judged``), never from fixed text.
"""

from __future__ import annotations

import pandas as pd

from sb3_affect.study.report import claims
from sb3_affect.study.report.context import ReportContext
from sb3_affect.study.report.verdict import judged


def _count(words: list[str], word: str) -> int:
    return sum(w == word for w in words)


def abstract_sentences(judged_main: list[claims.Judgement], n: int, runs: int) -> list[str]:
    """Five sentences: what was done, what holds, what does not, why, and what the numbers are worth."""
    words = [claims.verdict_word(j.verdict) for j in judged_main]
    by_key = {j.key: j for j in judged_main}
    held = [j.label for j in judged_main if words[judged_main.index(j)] == "reproduced"]
    first = (
        f"We reran Badoy and Teknomo's grid-pursuit experiment (ε-greedy Q-learning against the affective agent, 9 ε "
        f"values, 200 episodes) at the paper's 20 seeds per cell and at {n:,} seeds per cell ({runs:,} runs in the "
        "verdict), and judged each of the paper's claims with a rule written down before the numbers."
    )
    not_held = sum(w.startswith("not reproduced") for w in words)
    rest = len(words) - _count(words, "reproduced") - not_held
    second = (
        f"Of {len(words)} claims, {_count(words, 'reproduced')} are reproduced"
        + (f" ({'; '.join(held[:3])}{'; ...' if len(held) > 3 else ''})" if held else "")
        + f", {not_held} are not"
        + (f", and {rest} hold in part (direction only, partly, or inconclusive)" if rest else "")
        + "."
    )
    table_iv = by_key.get("table_iv")
    third = (
        "The paper's \"no significant difference\" in steps per episode is an outcome of its paired t-test over 9 ε "
        "means, which the crossover keeps non-significant at any seed count; as a claim about the agents it "
        + ("does not hold: " + table_iv.ours.split("; ")[-1] + " steps per episode averaged over ε"
           if table_iv and table_iv.verdict.startswith("not") else "is " + (table_iv.verdict if table_iv else "not judged"))
        + "."
    )
    fourth = (
        "The affective agent moves up to 2 cells per decision, so its lead counted in decisions (time) is much larger "
        "than in cells (distance), and Table II as printed never produces sadness or fear, so four emotions act as two."
    )
    fifth = (
        "Sizes are judged against what 20 seeds could have printed (predictive intervals and ratios), every verdict "
        "comes with its tests and Holm-corrected p-values, and the reading of the paper's appraisal changes several "
        "verdicts (claims x readings table)."
    )
    return [first, second, third, fourth, fifth]


def headline_table(
    judged_main: list[claims.Judgement], other: list[claims.Judgement] | None, n: int, n_other: int
) -> pd.DataFrame:
    others = {j.key: j for j in other or []}
    rows = {}
    for j in judged_main:
        row = {f"{n:,} seeds": claims.verdict_word(j.verdict)}
        if other is not None:
            row[f"{n_other} seeds"] = claims.verdict_word(others[j.key].verdict) if j.key in others else ""
        rows[j.label] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "claim"
    return table


def abstract_section(ctx: ReportContext) -> None:
    if ctx.verdict_refusal():
        return
    judged_main, n, other, n_other = judged(ctx)
    runs = len(ctx.large) if ctx.large is not None else len(ctx.metrics)
    ctx.doc.h("Abstract")
    ctx.doc.p(" ".join(abstract_sentences(judged_main, n, runs)))
    ctx.doc.h("Headline")
    ctx.table(
        "headline",
        headline_table(judged_main, other, n, n_other),
        "Each claim's verdict in one or two words (the verdict section gives the numbers and the reasons)",
    )
