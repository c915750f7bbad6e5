"""The reading ablation: rank the 8 readings of the appraisal by how close they come to the paper."""

from __future__ import annotations

import math

import pandas as pd

from sb3_affect.report import paper
from sb3_affect.report.metrics import profile, run_metrics, window_mean

MEASURE = (
    "Distance measure: the sum of six terms, each 0 for a perfect match: relative errors "
    "|x - paper| / paper of (1) mean steps per episode (paper 56.28), (2) mean first optimal episode (paper 27.35; "
    "runs that never find it count as 200), (3) equivalent epsilon in episodes 1-10 (paper ~0.3) and (4) in the "
    "last 20 episodes (paper ~0.1); plus (5) 1 if joy is not the dominant emotion in episodes 1-10 and (6) 1 if "
    "anger is not the dominant emotion in the last 20 episodes. Lower is closer."
)


def rank_readings(episodes: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """One row per reading (comparison / act / units) with its features and distance, closest first."""
    rows = []
    for (comparison, act, units), part in episodes.groupby(["comparison", "act", "units"]):
        metrics = run_metrics(part)
        prof = profile(part)
        last = int(prof.index.max())
        first_late = max(1, last - 19)
        first_optimal = metrics.first_optimal.fillna(float(last)).mean()
        emotions = ("joy", "sadness", "fear", "anger")
        early = {e: window_mean(prof, e, 1, 10) for e in emotions}
        late = {e: window_mean(prof, e, first_late, last) for e in emotions}
        eq_early = window_mean(prof, "equivalent_epsilon", 1, 10)
        eq_late = window_mean(prof, "equivalent_epsilon", first_late, last)
        steps = metrics.decisions_per_episode.mean()
        terms = [
            abs(steps - paper.STEPS_PER_EPISODE_AFFECTIVE) / paper.STEPS_PER_EPISODE_AFFECTIVE,
            abs(first_optimal - paper.EPISODES_TO_OPTIMAL) / paper.EPISODES_TO_OPTIMAL,
            abs(eq_early - paper.EQUIVALENT_EPSILON_EARLY) / paper.EQUIVALENT_EPSILON_EARLY,
            abs(eq_late - paper.EQUIVALENT_EPSILON_LATE) / paper.EQUIVALENT_EPSILON_LATE,
            float(max(emotions, key=lambda e: early[e]) != "joy"),
            float(max(emotions, key=lambda e: late[e]) != "anger"),
        ]
        rows.append(
            {
                "reading": f"{comparison} / {act} / {units}",
                "runs": len(metrics),
                "steps per episode": steps,
                "cells per episode": metrics.cells_per_episode.mean(),
                "first optimal episode": first_optimal,
                "never optimal": int(metrics.censored.sum()),
                "eq. epsilon 1-10": eq_early,
                "eq. epsilon late": eq_late,
                "dominant early": max(emotions, key=lambda e: early[e]),
                "dominant late": max(emotions, key=lambda e: late[e]),
                "truncated episodes": int(metrics.truncated.sum()),
                "distance": sum(t for t in terms if not math.isnan(t)),
            }
        )
    ranking = pd.DataFrame(rows).sort_values("distance").reset_index(drop=True)
    return ranking, MEASURE
