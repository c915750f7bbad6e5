"""
The reading ablation: rank the 8 readings of the appraisal (comparison x act x units) by how close they come to the
paper. Runs: experiments/ablation.yaml through the launcher (``DIR/ablation``).
"""

from __future__ import annotations

import math

import pandas as pd

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.reading.run_tables import load_results, run_metrics
from sb3_affect.study.report.rendering import figures
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.course_claims import km_restricted_mean

MEASURE = (
    "Distance measure: the sum of six terms, each 0 for a perfect match: relative errors "
    "|x - paper| / paper of (1) mean steps per episode (paper 56.28), (2) mean first optimal episode (paper 27.35; "
    "the Kaplan-Meier restricted mean: runs that never find it are censored, as in the verdict), (3) equivalent ε "
    "in episodes 1-10 (paper ~0.3) and (4) in episodes 181-200 (paper ~0.1); plus (5) 1 if joy is not the dominant "
    "emotion in episodes 1-10 and (6) 1 if anger is not the dominant emotion in episodes 181-200 (mean of per-episode "
    "fractions). Lower is closer."
)
EMOTIONS = EMOTION_NAMES


def rank_readings(m: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """One row per reading with its features and distance, closest first (``m``: one row per run)."""
    rows = []
    for (comparison, act, units), part in m.groupby(["comparison", "act", "units"]):
        last = int(part.episodes.max())
        durations = part.first_optimal.fillna(part.episodes).to_numpy(float)
        first_optimal = km_restricted_mean(durations, ~part.censored.to_numpy(bool), float(last))[0]
        early = {e: float(part[f"{e}_1_10"].mean()) for e in EMOTIONS}
        late = {e: float(part[f"{e}_181_200"].mean()) for e in EMOTIONS}
        eq_early, eq_late = float(part.eqeps_1_10.mean()), float(part.eqeps_181_200.mean())
        steps = float(part.decisions_per_episode.mean())
        terms = [
            abs(steps - paper.STEPS_PER_EPISODE_AFFECTIVE) / paper.STEPS_PER_EPISODE_AFFECTIVE,
            abs(first_optimal - paper.EPISODES_TO_OPTIMAL) / paper.EPISODES_TO_OPTIMAL,
            abs(eq_early - paper.EQUIVALENT_EPSILON_EARLY) / paper.EQUIVALENT_EPSILON_EARLY,
            abs(eq_late - paper.EQUIVALENT_EPSILON_LATE) / paper.EQUIVALENT_EPSILON_LATE,
            float(max(EMOTIONS, key=lambda e: early[e]) != "joy"),
            float(max(EMOTIONS, key=lambda e: late[e]) != "anger"),
        ]
        rows.append(
            {
                "reading": f"{comparison} / {act} / {units}",
                "runs": len(part),
                "steps per episode": steps,
                "cells per episode": float(part.cells_per_episode.mean()),
                "first optimal episode": first_optimal,
                "never optimal": int(part.censored.sum()),
                "eq. ε 1-10": eq_early,
                "eq. ε 181-200": eq_late,
                "dominant early": max(EMOTIONS, key=lambda e: early[e]),
                "dominant late": max(EMOTIONS, key=lambda e: late[e]),
                "truncated episodes": int(part.truncated.sum()),
                "distance": sum(t for t in terms if not math.isnan(t)),
            }
        )
    ranking = pd.DataFrame(rows).sort_values("distance").reset_index(drop=True)
    return ranking, MEASURE


def ablation_section(ctx: ReportContext) -> None:
    ctx.doc.h("Reading ablation: which reading of the appraisal comes closest to the paper")
    if "ablation" in ctx.folders:
        results = load_results(ctx.folders["ablation"])
        m = run_metrics(results.episodes, results.runs) if len(results.episodes) else pd.DataFrame()
        source = f"launcher runs in {ctx.folders['ablation']}"
    else:
        ctx.doc.p("Skipped: no ablation results (run experiments/ablation.yaml, or `sb3-affect replicate`).")
        return
    if m.empty or "comparison" not in m.columns:
        ctx.doc.p("Skipped: the ablation folder holds no finished runs.")
        return
    ranking, measure = rank_readings(m)
    ctx.doc.p(f"{measure} Source: {source}.")
    ctx.table("ablation_ranking", ranking.set_index("reading"), "Readings ranked by distance (closest first)", 3)
    path = figures.ablation_bars(ranking, ctx.figure("ablation_distance"))
    ctx.doc.img(path, "Distance of each reading to the paper's numbers and profile")
    best = ranking.iloc[0]
    readings = ranking.reading.tolist()
    default = "literal / episode / cells"
    place = str(readings.index(default) + 1) if default in readings else "n/a"
    ctx.doc.p(
        f"Closest reading: **{best.reading}** (distance {fmt(best.distance, 3)}). The default preset "
        f"({default}) ranks {place} of {len(ranking)} on this distance, which scores only the affective agent's numbers "
        "and profile. The replication forensics (its own section) scores all of the paper's printed statistics, the "
        "ε-greedy agent's included, and may rank the readings differently. No reading changes the ε-greedy agent, so "
        "none can bring the printed ε-greedy means nearer (the verdict's rows for the printed means; the forensics "
        "says which printed numbers a leading candidate reaches)."
    )
