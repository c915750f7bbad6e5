"""
The reading decides: every claim's verdict under every reading of the appraisal (comparison x act x units), and the
emotion shares per reading. The affective runs are the reading ablation's (``DIR/ablation``,
experiments/ablation.yaml); the ε-greedy runs are the paper sweep's (no reading applies to them). Never-found runs
are censored (Kaplan-Meier) as in the verdict.
"""

from __future__ import annotations

import math
import re

import pandas as pd

from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.run_tables import EMOTIONS
from sb3_affect.study.report.sections.verdict import judged
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts.course_claims import EMOTION_SHARE, EMOTION_WINDOWS, first_optimal_summary

READING = ("comparison", "act", "units")
DEFAULT = "literal / episode / cells"


def reading_runs(ablation: pd.DataFrame, standard: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Per reading: its affective runs beside the ε-greedy runs, in ``judge_all``'s format."""
    out = {}
    for key, part in ablation.groupby(list(READING)):
        name = " / ".join(str(k) for k in key)
        affective = part.assign(agent=AFFECTIVE)
        out[name] = pd.concat([standard, affective], ignore_index=True)
    return out


def claims_by_reading(runs: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """One row per claim, one column per reading: the verdict's first words (the full verdicts in the CSV)."""
    columns: dict[str, list[str]] = {}
    labels: list[str] = []
    for name, m in runs.items():
        judged = claims.judge_all(m, cells=False)
        labels = [j.label for j in judged]
        columns[name] = [claims.verdict_word(j.verdict) + _detail(j) for j in judged]
    table = pd.DataFrame(columns, index=pd.Index(labels, name="claim"))
    return table


def _detail(j: claims.Judgement) -> str:
    """The numbers that decide a size claim, so a reading's row shows why: the estimate and the interval the rule uses."""
    if j.key == "episodes_to_optimal":
        interval = re.findall(r"\[[^\]]*\]", j.verdict)
        return f" ({j.ours.split(' (')[0]}; predictive interval at the paper's size {interval[-1] if interval else 'n/a'})"
    return ""


def first_optimal_by_reading(runs: dict[str, pd.DataFrame]) -> pd.DataFrame:
    """Per reading: the first optimal episode as the mean of the runs that found it, the KM restricted mean, the median."""
    rows = {}
    for name, m in runs.items():
        s = first_optimal_summary(m)
        rows[name] = {
            "mean of the runs that found it (biased low)": s["found-only mean"],
            "KM restricted mean (the verdict's)": s["restricted mean"],
            "KM median": s["median"] if math.isfinite(s["median"]) else f"> {int(s['horizon'])} (over half censored)",
            "never found (censored)": f"{int(s['censored'])} of {int(s['runs'])}",
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "reading"
    return table


def emotion_shares(ablation: pd.DataFrame) -> pd.DataFrame:
    """Per reading: decision-weighted share of each emotion in episodes 1-10 and 181-200 (means over runs)."""
    rows = {}
    for key, part in ablation.groupby(list(READING)):
        name = " / ".join(str(k) for k in key)
        row = {}
        for window in EMOTION_WINDOWS:
            for emotion in EMOTIONS:
                column = f"{emotion}_{window}_weighted"
                if column in part.columns:
                    row[f"{emotion} {window.replace('_', '-')}"] = float(part[column].mean())
        rows[name] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "reading"
    return table


def readings_section(ctx: ReportContext) -> None:
    ablation = ctx.study("ablation")
    if ablation is None or not ctx.has_paper_agents or ctx.verdict_refusal() or "comparison" not in ablation.columns:
        return
    if int(ablation.groupby([*list(READING), "epsilon"]).size().min()) < 5:
        return
    ctx.doc.h("The reading decides: every claim under every reading", 3)
    standard = ctx.metrics[ctx.metrics.agent == STANDARD]
    runs = reading_runs(ablation, standard)
    table = claims_by_reading(runs)
    n = int(ablation.groupby([*list(READING), "epsilon"]).size().min())
    ctx.doc.p(
        "The paper's text allows eight readings of its appraisal (comparison: literal or valence; act: per episode or "
        "remaining; units: cells or decisions; docs/definitions.md). Each column judges every claim with the same logic "
        f"as the verdict on that reading's affective runs ({n} seeds per cell, reading ablation) beside the paper "
        f"sweep's ε-greedy runs; the default reading is `{DEFAULT}`. Never-found runs are censored here too "
        "(Kaplan-Meier restricted mean to the last episode, with its median in the verdict table). With censoring "
        "only at the last episode that restricted mean equals the mean that scores never-found runs as the last "
        "episode: it is a lower bound on the mean first optimal episode, while the mean over the runs that found the "
        "path alone is biased low."
    )
    ctx.table(
        "claims_by_reading",
        table,
        "Each claim's verdict under each reading (first words; 27.35: the KM restricted mean [95% CI] and the 20-seed "
        "predictive interval the verdict tests 27.35 against; the long run: episodes 181-200 of these 200-episode runs)",
    )
    ctx.doc.p(default_column_sentence(ctx, table))
    ctx.table(
        "first_optimal_by_reading",
        first_optimal_by_reading(runs),
        "The affective agent's first optimal episode per reading, three ways (paper: 27.35)",
    )
    shares = emotion_shares(ablation)
    ctx.table(
        "emotion_shares_by_reading",
        shares,
        "Emotion shares per reading (decision-weighted per run, averaged over runs; episodes 1-10 and 181-200; the "
        f"reading ablation's runs, {n} seeds "
        "per cell; the verdict's four-emotions row reads the verdict's own runs)",
        3,
    )
    ctx.doc.p(rare_emotions_sentence(shares))


def default_column_sentence(ctx: ReportContext, table: pd.DataFrame) -> str:
    """Where the default reading's column and the verdict at the paper's protocol differ, and why they may."""

    _main, _n, protocol, n_protocol = judged(ctx)
    if protocol is None or DEFAULT not in table.columns:
        return ""
    words = {j.label: claims.verdict_word(j.verdict) for j in protocol}
    differ = [
        f"{label} ({word} here, {words[label]} in the verdict)"
        for label, word in table[DEFAULT].items()
        if label in words and str(word).split(" (")[0] != words[label]
    ]
    return (
        f"The column `{DEFAULT}` is the verdict's reading but not its runs: the reading ablation draws seeds of its own, "
        f"while the verdict's {n_protocol}-seed column judges the paper sweep's runs. "
        + (
            "The two differ on " + "; ".join(differ) + ": at 20 seeds per cell such a verdict turns on the draw (the "
            "headline's last column gives how often random 20-seed draws give the verdict's)."
            if differ
            else "Here they agree on every claim."
        )
    )


def rare_emotions_sentence(shares: pd.DataFrame) -> str:
    """Which emotions stay below the four-emotions rule's share in every window, reading by reading (from the table)."""
    rare: dict[str, list[str]] = {}
    for reading, row in shares.iterrows():
        largest = {e: max((v for c, v in row.items() if str(c).startswith(f"{e} ")), default=0.0) for e in EMOTIONS}
        below = [e for e in EMOTIONS if not largest[e] >= EMOTION_SHARE]
        rare.setdefault(", ".join(below) or "none", []).append(str(reading))
    valence_sadness = any("sadness" in emotions and any(r.startswith("valence") for r in readings)
                          for emotions, readings in rare.items())  # fmt: skip
    return (
        f"Emotions below {EMOTION_SHARE:.0%} of the decisions in both windows, by reading (the four-emotions rule): "
        + "; ".join(f"{emotions} under {', '.join(f'`{r}`' for r in readings)}" for emotions, readings in rare.items())
        + "."
        + (f" {WHY_SADNESS_VALENCE}" if valence_sadness else "")
    )


#: Why Table II never gives sadness under the valence comparison (the literal one: ``verdict.WHY_SADNESS_FEAR``).
WHY_SADNESS_VALENCE = (
    "Under the valence readings Table II compares the negated step counts, so sadness needs act > norm and exp1 >= act, "
    "hence exp1 > norm; but then -exp1 < -norm and the table's first row, fear, matches first: sadness never occurs."
)
