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
from sb3_affect.study.report.sections.lead_sources import mechanism_summary
from sb3_affect.study.report.sections.main_finding import SPEED_AGENT, comparison, finding_short
from sb3_affect.study.report.sections.project_checks import with_speed_matched
from sb3_affect.study.report.sections.verdict import judged, protocol_verdict, shown_word
from sb3_affect.study.report.verdicts import claims

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
    parts = [f"Of the paper's {len(groups)} claims (variants counted once), {len(held)} are reproduced"]
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
        f"The paper's own test (a paired t over the 9 per-ε means) is {outcome} ({test.ours}), while \"no difference\" "
        f"is {claims.verdict_word(claim.verdict)} ({claim.ours})."
    )


def ordinal(n: int) -> str:
    """1st, 2nd, 3rd, 4th, ... 11th, 12th, 13th, 21st."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def ranks_sentence(ranks: dict[str, tuple[int, ...]], before: dict[str, tuple[int, ...]]) -> str:
    """The affective agent's ranks among the fair baselines (20 seeds), on both metrics, with how many are clearly ahead."""
    if not ranks:
        return ""
    task, (position, total, *ahead) = next(iter(ranks.items()))

    def clear(found: list[int]) -> str:
        if not found:
            return ""
        return f" ({found[0]} ahead with non-overlapping 95% CIs)" if found[0] else " (its 95% CI overlapping every one ahead)"

    text = f"Among the {total} agents of the fair-baselines study ({task}, 20 seeds) the affective agent ranks " + (
        f"{ordinal(position)} on decisions per episode{clear(ahead)}"
    )
    if task in before:
        place, _, *clearly = before[task]
        text += f" and {ordinal(place)} on steps before the optimal path{clear(clearly)}"
    return text + "."


def cells_sentence(judged_main: list[claims.Judgement]) -> str:
    """The claims whose verdict changes when steps are counted as cells (the forensics does not decide the unit)."""
    changed = [
        f"{claim_name([j])} is \"{claims.verdict_word(j.cells_verdict)}\" in cells "
        f"(\"{claims.verdict_word(j.verdict)}\" in decisions)"
        for j in judged_main
        if j.cells_verdict and claims.verdict_word(j.cells_verdict) != claims.verdict_word(j.verdict)
    ]
    if not changed:
        return ""
    return "Counting steps as cells, " + "; ".join(changed) + "."


def abstract_sentences(
    judged_main: list[claims.Judgement], n: int, runs: int, finding: str = "", mechanism: str = "", ranks: str = ""
) -> list[str]:
    """
    The abstract's paragraphs: what was done, the main finding (once: its full numbers are the main finding section's)
    and the ranks; how many claims hold, in cells, the paper's test apart; how much of the lead remains at speed 1.
    """
    first = (
        f"We reran Badoy and Teknomo's grid-pursuit experiment (ε-greedy Q-learning against the affective agent, 9 ε "
        f"values, 200 episodes) at the paper's 20 seeds per cell and at {n:,} ({runs:,} runs), judging each claim with "
        "rules fixed in code and applied alike at every seed count."
    )
    paragraphs = (
        (first, finding, ranks),
        (count_sentence(judged_main), cells_sentence(judged_main), test_outcome_sentence(judged_main)),
        (mechanism,),
    )
    return [" ".join(s for s in paragraph if s) for paragraph in paragraphs if any(paragraph)]


#: The abstract's length limit in words (``abstract_words``; a test holds a built report's abstract to it).
MAX_WORDS = 300


def abstract_words(paragraphs: list[str]) -> int:
    """The abstract's words (whitespace-separated)."""
    return sum(len(paragraph.split()) for paragraph in paragraphs)


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
            row[f"{n_other} seeds (the paper protocol's runs)"] = claims.verdict_word(protocol_verdict(own)) if own else ""
        if share_column is not None and needed is not None and j.label in needed.index:
            share = float(str(needed.at[j.label, share_column]))
            row[share_column] = "fixed by the design" if math.isnan(share) else f"{share:.0%}"
            if j.key == "long_run" and not math.isnan(share):  # the power study has only the 200-episode runs
                row[share_column] += " (episodes 181-200 of the 200-episode runs)"
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
    found = ctx.cache.get("main finding")
    if found is None:
        m = with_speed_matched(ctx)
        aff, speed = m[m.agent == AFFECTIVE], m[m.agent == SPEED_AGENT]
        found = comparison(aff, speed) if len(aff) > 1 and len(speed) > 1 else None
    finding = finding_short(found) if found is not None else ""
    ranks = ranks_sentence(ctx.cache.get("baseline ranks", {}), ctx.cache.get("baseline ranks before optimal", {}))
    leads = ctx.cache.get("lead sources")
    mechanism = mechanism_summary(leads) if leads is not None else ""
    ctx.doc.h("Abstract")
    for paragraph in abstract_sentences(judged_main, n, runs, finding, mechanism, ranks):
        ctx.doc.p(paragraph)
    ctx.doc.h("Headline")
    needed = ctx.cache.get("seeds needed")
    ctx.table(
        "headline",
        headline_table(judged_main, other, n, n_other, needed),
        "Each claim's verdict in one or two words (the verdict section gives the numbers and the reasons); the last "
        "column: how often random draws of the paper's 20 seeds per cell from the large-N runs give the verdict of the "
        "paper protocol's own runs (a low share: that verdict is a rare draw)",
    )
