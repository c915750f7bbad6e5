"""
The main finding: the affective agent against the speed-matched ε-greedy (ε 0.01, 1 or 2 cells per decision) before
the first optimal path, with the runs that never found it counted: a plain mean that counts a censored run's decisions
is a lower bound, so beside it stand the censoring-aware Kaplan-Meier restricted means to a common horizon and the
probability of improvement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from sb3_affect.study.report.estimation.bootstrap import bootstrap_improvement
from sb3_affect.study.report.reading.context import AFFECTIVE, ReportContext
from sb3_affect.study.report.reading.study_tables import SPEED_AGENT
from sb3_affect.study.report.rendering.document import fmt, pval
from sb3_affect.study.report.sections.project_checks import with_speed_matched
from sb3_affect.study.report.verdicts.censoring import censored_mean, restricted_means
from sb3_affect.study.report.verdicts.inference import Z, welch

COLUMN = "decisions_before_optimal"
#: Bootstrap resamples of the probability of improvement (the project's checks use the same count).
REPS = 200


@dataclass(frozen=True)
class Comparison:
    """
    The main finding's numbers, affective first in each pair, the speed-matched ε-greedy second.

    :param runs: runs of each
    :param censored: runs that never found the optimal path
    :param mean: the plain mean of decisions before it, ``>=`` where a censored run enters it
    :param welch_p: the Welch t-test's p-value, affective against speed-matched on the plain means
    :param horizon: the restricted means' horizon (decisions)
    :param restricted: the Kaplan-Meier restricted means to it
    :param restricted_difference: affective minus speed-matched restricted mean, with its normal 95% CI
    :param improvement: P(affective better) with its bootstrap 95% CI
    :param per_episode: decisions per episode
    """

    runs: tuple[int, int]
    censored: tuple[int, int]
    mean: tuple[str, str]
    welch_p: float
    horizon: float
    restricted: tuple[float, float]
    restricted_difference: tuple[float, float, float]
    improvement: tuple[float, float, float]
    per_episode: tuple[float, float]


def comparison(aff: pd.DataFrame, speed: pd.DataFrame) -> Comparison:
    """The numbers of the main finding (affective against the speed-matched ε-greedy)."""
    a, s = aff[COLUMN].to_numpy(float), speed[COLUMN].to_numpy(float)
    ca, cs = aff.censored.to_numpy(bool), speed.censored.to_numpy(bool)
    _, p = welch(a, s)
    horizon, rm = restricted_means({"a": (a, ca), "s": (s, cs)})
    rdiff = rm["a"][0] - rm["s"][0]
    rse = math.sqrt(rm["a"][1] + rm["s"][1])
    return Comparison(
        runs=(len(a), len(s)),
        censored=(int(ca.sum()), int(cs.sum())),
        mean=(censored_mean(a, ca), censored_mean(s, cs)),
        welch_p=p,
        horizon=horizon,
        restricted=(rm["a"][0], rm["s"][0]),
        restricted_difference=(rdiff, rdiff - Z * rse, rdiff + Z * rse),
        improvement=bootstrap_improvement(a, s, REPS, seed=0),
        per_episode=(float(aff.decisions_per_episode.mean()), float(speed.decisions_per_episode.mean())),
    )


def finding_table(c: Comparison) -> pd.DataFrame:
    """The two agents side by side: runs, censored runs, the plain mean (a lower bound), the restricted mean."""
    rows = {}
    for i, name in enumerate((AFFECTIVE, f"{SPEED_AGENT} (ε 0.01)")):
        rows[name] = {
            "runs": c.runs[i],
            "never found the optimal path (censored)": c.censored[i],
            "mean decisions before it (censored runs counted at their total: a lower bound)": c.mean[i],
            f"Kaplan-Meier restricted mean to {fmt(c.horizon, 0)} decisions": fmt(c.restricted[i], 0),
            "decisions per episode": fmt(c.per_episode[i], 1),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "agent"
    return table


def finding_sentence(c: Comparison) -> str:
    """The main finding in one sentence with every number from ``comparison`` (the abstract's is ``finding_short``)."""
    rdiff, low, high = c.restricted_difference
    point, plow, phigh = c.improvement
    outcome = "needs fewer" if low > 0 else "needs more" if high < 0 else "does not need significantly fewer"
    return (
        f"The speed-matched ε-greedy {outcome} decisions before the first optimal path than the affective "
        f"agent: Kaplan-Meier restricted means to {fmt(c.horizon, 0)} decisions {fmt(c.restricted[1], 0)} against "
        f"{fmt(c.restricted[0], 0)} (affective minus speed-matched {fmt(rdiff, 0)} [95% CI {fmt(low, 0)}, "
        f"{fmt(high, 0)}]); plain means {c.mean[1]} against {c.mean[0]} ({c.censored[1]:,} of the speed-matched and "
        f"{c.censored[0]:,} of the affective runs never found it: a lower bound where any did; Welch p "
        f"{pval(c.welch_p)}); P(affective better) {fmt(point, 3)} [{fmt(plow, 3)}, {fmt(phigh, 3)}]"
    )


def finding_short(c: Comparison) -> str:
    """The main finding as the abstract states it (once; ``finding_sentence`` gives every number)."""
    rdiff, low, high = c.restricted_difference
    outcome = "needs fewer" if low > 0 else "needs more" if high < 0 else "does not need significantly fewer"
    return (
        "Main finding: an ε-greedy agent moving 1 or 2 cells per decision like the affective agent (ε 0.01) "
        f"{outcome} decisions before the first optimal path (Kaplan-Meier restricted means {fmt(c.restricted[1], 0)} "
        f"against {fmt(c.restricted[0], 0)}; difference {fmt(rdiff, 0)} [95% CI {fmt(low, 0)}, {fmt(high, 0)}])."
    )


def main_finding_section(ctx: ReportContext) -> None:
    """The speed-matched ε-greedy against the affective agent, censoring counted (main text)."""
    if ctx.verdict_refusal():
        return
    m = with_speed_matched(ctx)
    aff, speed = m[m.agent == AFFECTIVE], m[m.agent == SPEED_AGENT]
    if len(aff) < 2 or len(speed) < 2:
        return
    c = comparison(aff, speed)
    ctx.cache["main finding"] = c
    ctx.doc.h("Main finding: the speed-matched ε-greedy")
    ctx.doc.p(
        "The speed-matched ε-greedy (ε 0.01, moving 1 or 2 cells a decision like the affective agent; the project's "
        "baseline, not the paper's) against the affective agent, before the first walked optimal path. A run that "
        "never walks it is censored: its decisions count in the plain mean, which is then a lower bound (\">=\"). The "
        "Kaplan-Meier restricted mean treats it as censored, up to the horizon both agents' runs reach; the probability "
        "of improvement counts pairs (a censored run's total stands for its unknown value)."
    )
    caption = "Before the first optimal path: the affective agent and the speed-matched ε-greedy"
    ctx.table("main_finding", finding_table(c), caption)
    ctx.doc.p(finding_sentence(c) + ".")
