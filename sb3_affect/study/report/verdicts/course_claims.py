"""
The paper's claims about the affective agent's own course: 27.35 episodes to the optimal path (Kaplan-Meier,
never-found runs censored), the emotion profile (Fig. 5), the equivalent ε (Fig. 6), the long run, four emotions.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pandas as pd
from scipy import stats as sps

from sb3_affect.study.report.reading.run_tables import EMOTIONS
from sb3_affect.study.report.rendering.document import pval, sig
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.inference import Test, holm, mean_ci, significant, z_estimate
from sb3_affect.study.report.verdicts.judgement import (
    AFFECTIVE,
    Judgement,
    eps_list,
    per_epsilon,
    seeds_per_cell,
    size_against_paper,
)

#: "about 0.3" / "to 0.1" (Fig. 6) read as within this absolute distance.
ABOUT = 0.05


def km_restricted_mean(durations: np.ndarray, observed: np.ndarray, horizon: float) -> tuple[float, float, float]:
    """
    The Kaplan-Meier restricted mean of the first optimal episode up to ``horizon`` (lifelines), with a standard
    error (exact without censoring, a close bound with little) and the KM median.
    """
    from lifelines import KaplanMeierFitter  # (3 s to import, for this estimate only: not on every report import)

    fitter = KaplanMeierFitter().fit(durations, event_observed=observed)
    sf = fitter.survival_function_.iloc[:, 0]
    times = np.clip(np.append(sf.index.to_numpy(float), horizon), 0.0, horizon)
    rmst = float(np.sum(sf.to_numpy(float) * np.diff(times)))  # the area under lifelines' KM step function up to t
    se = float(np.std(np.minimum(durations, horizon), ddof=1)) / math.sqrt(len(durations)) if len(durations) > 1 else math.nan
    return rmst, se, float(fitter.median_survival_time_)


def first_optimal_summary(m: pd.DataFrame) -> dict[str, float]:
    """
    The affective agent's first optimal episode three ways: the mean over the runs that found the path (biased low),
    the Kaplan-Meier restricted mean to the last episode (never-found runs censored) with its SE, and the KM median;
    with the runs, the censored runs and the last episode.
    """
    aff = m[m.agent == AFFECTIVE]
    horizon = float(aff.episodes.max())
    observed = ~aff.censored.to_numpy(bool)
    durations = aff.first_optimal.fillna(aff.episodes).to_numpy(float)
    rmst, se, median = km_restricted_mean(durations, observed, horizon)
    found = durations[observed]
    return {
        "found-only mean": float(found.mean()) if len(found) else math.nan,
        "restricted mean": rmst,
        "se": se,
        "median": median,
        "runs": float(len(aff)),
        "censored": float((~observed).sum()),
        "horizon": horizon,
    }


def judge_episodes_to_optimal(m: pd.DataFrame) -> Judgement:
    """27.35 episodes: the Kaplan-Meier restricted mean of the first optimal episode, never-found runs censored."""
    summary = first_optimal_summary(m)
    rmst, se, horizon = summary["restricted mean"], summary["se"], int(summary["horizon"])
    est = z_estimate(rmst, se)
    runs, censored = int(summary["runs"]), int(summary["censored"])
    # the paper's 27.35 is one number over its 180 affective runs (9 ε x 20): the predictive interval of that statistic
    inside, ratio, where = size_against_paper(
        est, paper.EPISODES_TO_OPTIMAL, runs, paper.SEEDS_PER_CELL * len(paper.EPSILONS), "runs (9 ε x 20)"
    )
    z = (rmst - paper.EPISODES_TO_OPTIMAL) / se if se > 0 else math.inf
    j = Judgement(
        "episodes_to_optimal",
        "27.35 episodes until the optimal path (affective)",
        "27.35",
        f"{est.text()} (Kaplan-Meier restricted mean to episode {horizon}; {censored:,} of {runs:,} runs never find it: "
        f"censored; {where}); mean of the runs that found it {sig(summary['found-only mean'])}, KM median "
        f"{sig(summary['median'])}",
        direction=None,
        size=inside,
        ratio=ratio,
        tests=[Test("z-test of the KM restricted mean against 27.35 (two-sided)", float(2 * sps.norm.sf(abs(z))))],
    )
    j.decide = lambda j: (
        f"reproduced: 27.35 lies within the {where}" if j.size else
        f"not reproduced: {'fewer' if rmst < paper.EPISODES_TO_OPTIMAL else 'more'} episodes, 27.35 outside the {where}"
    )
    return j


#: p-values of ``_one_sample`` by the bytes of the sample (the windows section tests each window's values many times).
_TESTED: dict[bytes, float] = {}


def _one_sample(x: np.ndarray) -> float:
    x = np.ascontiguousarray(x[~np.isnan(x)], np.float64)
    if len(x) == 0 or not (x != 0).any():
        return 1.0
    key = hashlib.blake2b(x.tobytes(), digest_size=32).digest()
    if key not in _TESTED:
        if len(_TESTED) >= 64:
            _TESTED.pop(next(iter(_TESTED)))
        _TESTED[key] = float(sps.wilcoxon(x, alternative="greater").pvalue)
    return _TESTED[key]


def judge_fig5(m: pd.DataFrame, weighted: bool, early: str = "1_10", late: str = "181_200") -> Judgement:
    """Joy dominant early, anger later: both halves must hold (one-sided Wilcoxon per run, Holm over the two)."""
    aff = m[m.agent == AFFECTIVE]
    suffix = "_weighted" if weighted else ""
    joy_early = (aff[f"joy_{early}{suffix}"] - aff[f"anger_{early}{suffix}"]).to_numpy(float)
    anger_late = (aff[f"anger_{late}{suffix}"] - aff[f"joy_{late}{suffix}"]).to_numpy(float)
    e_est, l_est = mean_ci(joy_early), mean_ci(anger_late)
    name = "decision-weighted per run" if weighted else "mean of per-episode fractions"
    span = (early.replace("_", "-"), late.replace("_", "-"))
    j = Judgement(
        f"fig5:{'weighted' if weighted else 'mean'}",
        f"Fig. 5 ({name}): joy dominant early, anger later",
        "joy dominant early, anger later (no numbers printed)",
        f"joy - anger in episodes {span[0]}: {e_est.text()}; anger - joy in {span[1]}: {l_est.text()}",
        direction=bool(e_est.value > 0 and l_est.value > 0),
        tests=[
            Test(f"Wilcoxon: joy > anger in episodes {span[0]}, {name}", _one_sample(joy_early)),
            Test(f"Wilcoxon: anger > joy in episodes {span[1]}, {name}", _one_sample(anger_late)),
        ],
    )

    def decide(j: Judgement) -> str:
        joy_first = significant(j.tests[0]) and e_est.value > 0
        anger_later = significant(j.tests[1]) and l_est.value > 0
        if joy_first and anger_later:
            return "reproduced"
        if joy_first:
            late_word = "joy" if l_est.value < 0 else "neither"
            return f"not reproduced: joy dominates early, {late_word} dominates late (no switch from joy to anger)"
        if anger_later:
            return "not reproduced: anger dominates late, but joy does not dominate early (no switch)"
        return "not reproduced: neither joy early nor anger late"

    j.decide = decide
    return j


def judge_fig6(m: pd.DataFrame, first: str = "1_10", last: str = "181_200") -> Judgement:
    aff = m[m.agent == AFFECTIVE]
    early, late = aff[f"eqeps_{first}"].to_numpy(float), aff[f"eqeps_{last}"].to_numpy(float)
    e_est, l_est = mean_ci(early), mean_ci(late)
    size = abs(e_est.value - paper.EQUIVALENT_EPSILON_EARLY) <= ABOUT
    size = size and abs(l_est.value - paper.EQUIVALENT_EPSILON_LATE) <= ABOUT
    j = Judgement(
        "fig6",
        "Fig. 6: equivalent ε about 0.3 early, falling to 0.1",
        "about 0.3 early, 0.1 near the end",
        f"episodes {first.replace('_', '-')}: {e_est.text()}; {last.replace('_', '-')}: {l_est.text()} (mean of per-episode "
        "fractions)",
        direction=bool(e_est.value > l_est.value),
        size=bool(size),
        ratio=paper.EQUIVALENT_EPSILON_EARLY / e_est.value if e_est.value else None,
        tests=[Test(f"Wilcoxon signed-rank per run: episodes {first} > {last}".replace("_", "-"), _one_sample(early - late))],
    )

    def decide(j: Judgement) -> str:
        falls = significant(j.tests[0]) and bool(j.direction)
        if falls and j.size:
            return f"reproduced (levels within ±{ABOUT})"
        if falls:
            return f"direction reproduced (it falls), levels differ (tolerance ±{ABOUT})"
        return "not reproduced"

    j.decide = decide
    return j


def judge_long_run(m: pd.DataFrame, long: pd.DataFrame | None = None) -> Judgement:
    """
    Fewer steps in the long run: per ε, ε-greedy against the affective agent (all its runs) over the last 200
    episodes of ``long`` (runs of 2,000 episodes) when given, else over episodes 181-200 of ``m``.
    """
    data, window = m, "181_200"
    if long is not None and len(long):
        last = int(long.episodes.max())
        data, window = long, f"{last - 199}_{last}"
    aff = data[data.agent == AFFECTIVE]
    reference = aff[f"decisions_{window}"].to_numpy(float)
    span = window.replace("_", "-")
    diffs, tests = per_epsilon(data, f"decisions_{window}", f", episodes {span}", reference=reference)
    cell_diffs, _ = per_epsilon(data, f"cells_{window}", "", reference=aff[f"cells_{window}"].to_numpy(float)) if (
        f"cells_{window}" in data.columns
    ) else ({}, {})
    n = seeds_per_cell(data)
    _, by_label = per_epsilon(data, f"decisions_{window}", "")  # the other pairing: the affective runs of the same label
    holm(list(by_label.values()))
    j = Judgement(
        "long_run",
        "Long run: the affective agent takes fewer steps than the standard agent"
        + ("" if data is long else f" (episodes {span} of {int(data.episodes.max())}-episode runs)"),
        "no numbers printed",
        f"{n:,} runs per cell of {int(data.episodes.max()):,} episodes; steps per episode in episodes {span}: affective "
        f"{sig(float(np.nanmean(reference)))}; ε-greedy minus affective (all its runs: it ignores ε) "
        + ", ".join(f"ε {e:.1f}: {d.text()}" for e, d in diffs.items()),
        cells=("cells per episode, ε-greedy minus affective "
               + ", ".join(f"ε {e:.1f}: {d.text()}" for e, d in cell_diffs.items()))
        if cell_diffs else "",
        direction=all(d.value > 0 for d in diffs.values()) if diffs else None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        lower = [e for e, d in diffs.items() if significant(tests[e]) and d.value > 0]
        higher = [e for e, d in diffs.items() if significant(tests[e]) and d.value < 0]
        text = (
            f"affective significantly lower against ε {eps_list(lower)}, higher against {eps_list(higher)} (judged on "
            f"{n:,} runs per cell of {int(data.episodes.max()):,} episodes, episodes {span}{pairing_note(tests, by_label)})"
        )
        if lower and len(lower) == len(diffs):
            return "reproduced: " + text
        if lower and lower == sorted(diffs)[-len(lower):]:
            return f"not reproduced: holds only against ε >= {min(lower):.1f}; " + text
        return "not reproduced: " + text

    j.decide = decide
    return j


def pairing_note(pooled: dict[float, Test], by_label: dict[float, Test]) -> str:
    """Where pairing each ε-greedy cell with the affective runs of its own ε label changes a Holm-significant outcome."""
    changed = [e for e in pooled if e in by_label and significant(pooled[e]) != significant(by_label[e])]
    if not changed:
        return "; paired by ε label instead, the same ε are significant"
    return "; paired by ε label instead, " + ", ".join(
        f"ε {e:.1f} {'is not' if significant(pooled[e]) else 'is'} significant (Holm p {pval(by_label[e].p_holm)})"
        for e in changed
    )


#: "Four emotions shape behaviour": each emotion must take at least this share of the decisions in an early or a late
#: window (decision-weighted, mean over runs).
EMOTION_SHARE = 0.01
#: The windows the four-emotions rule reads (episodes 1-10 and 181-200).
EMOTION_WINDOWS = ("1_10", "181_200")


def emotion_window_shares(aff: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Per emotion, per window of ``EMOTION_WINDOWS``: its decision-weighted share of the decisions, mean over runs."""
    return {
        emotion: {
            window: float(np.nanmean(aff[f"{emotion}_{window}_weighted"].to_numpy(float)))
            for window in EMOTION_WINDOWS
            if f"{emotion}_{window}_weighted" in aff.columns
        }
        for emotion in EMOTIONS
    }


def judge_four_emotions(m: pd.DataFrame) -> Judgement:
    """Each of the four emotions takes at least ``EMOTION_SHARE`` of the decisions in episodes 1-10 or 181-200."""
    shares = emotion_window_shares(m[m.agent == AFFECTIVE])
    largest = {emotion: max(by_window.values(), default=0.0) for emotion, by_window in shares.items()}
    rare = [emotion for emotion in EMOTIONS if not largest[emotion] >= EMOTION_SHARE]
    windows = " / ".join(w.replace("_", "-") for w in EMOTION_WINDOWS)
    j = Judgement(
        "four_emotions",
        "Four emotions shape behaviour (sadness and fear included)",
        "all four emotions in Fig. 5",
        f"share of the decisions in episodes {windows} (decision-weighted per run, averaged over runs): "
        + "; ".join(f"{e} " + " / ".join(sig(v) for v in shares[e].values()) for e in EMOTIONS),
        direction=not rare,
    )
    j.decide = lambda j: (
        f"reproduced: each of the four emotions takes at least {EMOTION_SHARE:.0%} of the decisions in episodes "
        f"{windows.replace(' / ', ' or ')}"
        if not rare
        else f"not reproduced: {' and '.join(rare)} below {EMOTION_SHARE:.0%} of the decisions in episodes "
        f"{windows.replace(' / ', ' and ')}"
    )
    return j
