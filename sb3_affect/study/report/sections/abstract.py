"""
The report's first minute: an abstract that leads with the main finding and a headline table (one line per claim: the
verdict at the largest seed count and at the paper's protocol), both written from the judged claims
(``report.sections.verdict.judged``) and the numbers other sections computed, never from fixed text. The abstract is placed
first but written last (``ReportContext.later``), once the sections it quotes have run.
"""

from __future__ import annotations

import math

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, ReportContext
from sb3_affect.study.report.reading.study_tables import SPEED_AGENT
from sb3_affect.study.report.rendering.document import fmt, pval
from sb3_affect.study.report.sections.project_checks import with_speed_matched
from sb3_affect.study.report.sections.verdict import judged, shown_word
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts.inference import welch

#: The row of the paper's own test outcome: given on its own, not counted as a claim.
TEST_OUTCOME = "table_iv:test"


def claim_groups(judged_main: list[claims.Judgement]) -> dict[str, list[claims.Judgement]]:
    """The claims, each with its definitional variants (``key:variant``) together; the test outcome left out."""
    groups: dict[str, list[claims.Judgement]] = {}
    for j in judged_main:
        if j.key != TEST_OUTCOME:
            groups.setdefault(j.key.split(":")[0], []).append(j)
    return groups


def group_word(variants: list[claims.Judgement]) -> str:
    """A claim's verdict word: its variants' common word, else ``depends on the definition``."""
    words = {shown_word(j) for j in variants}
    return words.pop() if len(words) == 1 else "depends on the definition"


def claim_name(variants: list[claims.Judgement]) -> str:
    """A claim's short name: its label up to the colon, without a variant's words in brackets."""
    name = variants[0].label.split(":")[0].split(" (")[0]
    return f"the printed means of {name}" if variants[0].key.startswith("printed_") else name


def count_sentence(judged_main: list[claims.Judgement]) -> str:
    """How many of the paper's claims hold (variants counted once, the test outcome apart), each one named."""
    groups = claim_groups(judged_main)
    words = {key: group_word(v) for key, v in groups.items()}
    names = {key: claim_name(v) for key, v in groups.items()}
    held = [names[k] for k, w in words.items() if w == "reproduced"]
    not_held = [names[k] for k, w in words.items() if w.startswith("not reproduced")]
    rest = [f"{names[k]} ({w})" for k, w in words.items() if w != "reproduced" and not w.startswith("not reproduced")]
    parts = [f"Of the paper's {len(groups)} claims (definitional variants counted once), {len(held)} are reproduced"]
    parts[0] += f" ({'; '.join(held)})" if held else ""
    parts.append(f"{len(not_held)} are not ({'; '.join(not_held)})" if not_held else "none is plainly not reproduced")
    if rest:
        parts.append(f"{len(rest)} hold in part ({'; '.join(rest)})")
    return ", ".join(parts[:-1]) + (", and " if len(parts) > 1 else "") + parts[-1] + "."


def test_outcome_sentence(judged_main: list[claims.Judgement]) -> str:
    """The paper's own test of Table IV, apart from the claims: what it tests and what it says about the agents."""
    by_key = {j.key: j for j in judged_main}
    test, claim = by_key.get(TEST_OUTCOME), by_key.get("table_iv")
    if test is None or claim is None:
        return ""
    outcome = "not significant, as printed" if test.verdict.startswith("reproduced") else "significant, unlike the paper's"
    return (
        f"The paper's own test, a paired t-test over the 9 per-ε means of steps per episode, is {outcome} "
        f"({test.ours}); the crossover of Fig. 3 keeps it so at any seed count, and as a claim about the agents "
        f"\"no difference\" is {claims.verdict_word(claim.verdict)} ({claim.ours})."
    )


def main_finding(m: pd.DataFrame, ranks: dict[str, tuple[int, int]]) -> str:
    """The speed-matched ε-greedy against the affective agent, and the affective agent's rank among the baselines."""

    aff, speed = m[m.agent == AFFECTIVE], m[m.agent == SPEED_AGENT]
    if len(aff) < 2 or len(speed) < 2:
        return ""
    before = {name: g.decisions_before_optimal.to_numpy(float) for name, g in (("a", aff), ("s", speed))}
    per_episode = {name: g.decisions_per_episode.to_numpy(float) for name, g in (("a", aff), ("s", speed))}
    _diff, p = welch(before["a"], before["s"])
    faster = before["s"].mean() < before["a"].mean()
    text = (
        f"Main finding: an ε-greedy agent that moves 1 or 2 cells per decision like the affective agent (ε 0.01, the "
        f"project's speed-matched baseline) {'beats' if faster else 'does not beat'} the affective agent: "
        f"{fmt(float(before['s'].mean()), 0)} against {fmt(float(before['a'].mean()), 0)} decisions before the first "
        f"optimal path (Welch p {pval(p)}) and {fmt(float(per_episode['s'].mean()), 1)} against "
        f"{fmt(float(per_episode['a'].mean()), 1)} decisions per episode, so the affective agent's lead over the "
        "paper's ε-greedy comes from its 2-cell moves"
    )
    if ranks:
        task, (position, total) = next(iter(ranks.items()))
        text += f"; among the fair baselines ({task}) it ranks {position} of {total} on decisions per episode"
    return text + "."


def abstract_sentences(judged_main: list[claims.Judgement], n: int, runs: int, finding: str = "") -> list[str]:
    """What was done, the main finding, how many claims hold, the paper's test apart, why, and what it is worth."""
    by_key = {j.key: j for j in judged_main}
    first = (
        f"We reran Badoy and Teknomo's grid-pursuit experiment (ε-greedy Q-learning against the affective agent, 9 ε "
        f"values, 200 episodes) at the paper's 20 seeds per cell and at {n:,} seeds per cell ({runs:,} runs in the "
        "verdict), and judged each of the paper's claims with a rule written down before the numbers."
    )
    four = by_key.get("four_emotions")
    why = (
        "The affective agent moves up to 2 cells per decision, so its lead counted in decisions (time) is much larger "
        "than in cells (distance)"
        + (f"; four emotions: {four.verdict}" if four is not None else "")
        + "."
    )
    worth = (
        "Sizes are judged against what 20 seeds could have printed (predictive intervals and ratios), every verdict "
        "comes with its tests and Holm-corrected p-values, and the reading of the paper's appraisal changes several "
        "verdicts (claims x readings table)."
    )
    return [s for s in (first, finding, count_sentence(judged_main), test_outcome_sentence(judged_main), why, worth) if s]


def headline_table(
    judged_main: list[claims.Judgement],
    other: list[claims.Judgement] | None,
    n: int,
    n_other: int,
    needed: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """
    One row per judged row: the verdict word at ``n`` seeds and at the paper's protocol, and (from the power study,
    ``needed``) how often random draws of the paper's size give the protocol's verdict.
    """
    others = {j.key: j for j in other or []}
    share_column = next((c for c in (needed.columns if needed is not None else []) if "protocol's verdict" in c), None)
    rows = {}
    for j in judged_main:
        row = {f"{n:,} seeds": shown_word(j)}
        if other is not None:
            own = others.get(j.key)
            row[f"{n_other} seeds (the paper protocol's runs)"] = claims.verdict_word(own.verdict) if own else ""
        if share_column is not None and needed is not None and j.label in needed.index:
            share = float(str(needed.at[j.label, share_column]))
            row[share_column] = "fixed by the design" if math.isnan(share) else f"{share:.0%}"
        rows[j.label] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "claim"
    return table


def abstract_section(ctx: ReportContext) -> None:
    if ctx.verdict_refusal():
        return
    ctx.later(_write_abstract)


def _write_abstract(ctx: ReportContext) -> None:

    judged_main, n, other, n_other = judged(ctx)
    runs = len(ctx.large) if ctx.large is not None else len(ctx.metrics)
    finding = main_finding(with_speed_matched(ctx), ctx.cache.get("baseline ranks", {}))
    ctx.doc.h("Abstract")
    ctx.doc.p(" ".join(abstract_sentences(judged_main, n, runs, finding)))
    ctx.doc.h("Headline")
    needed = ctx.cache.get("seeds needed")
    ctx.table(
        "headline",
        headline_table(judged_main, other, n, n_other, needed),
        "Each claim's verdict in one or two words (the verdict section gives the numbers and the reasons); the last "
        "column: how often random draws of the paper's 20 seeds per cell from the large-N runs give the verdict of the "
        "paper protocol's own runs (a low share: that verdict is a rare draw)",
    )
