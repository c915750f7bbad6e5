"""
The project's own checks, apart from the paper's claims: the speed-matched ε-greedy (issue 7), and rliable's
interquartile means with stratified bootstrap CIs, probabilities of improvement and performance profiles.
"""

from __future__ import annotations

import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from rliable import library as rly
from rliable import metrics as rmetrics
from scipy import stats as sps

from sb3_affect.report.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.report.document import fmt
from sb3_affect.report.figures import save
from sb3_affect.report.largen import SPEED_AGENT
from sb3_affect.report.metrics import load_results, run_metrics

METRICS = (
    ("decisions_per_episode", "steps per episode"),
    ("decisions_before_optimal", "steps before the optimal path (walked)"),
    ("decisions_to_greedy_optimal", "steps until the greedy policy stays optimal"),
)
REPS = 1000


def groups(m: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Runs per agent configuration: the affective agent pooled over ε, ε-greedy per ε, the speed-matched agent."""
    out = {AFFECTIVE: m[m.agent == AFFECTIVE]}
    for eps in sorted(m[m.agent == STANDARD].epsilon.unique()):
        out[f"ε-greedy {eps:.1f}"] = m[(m.agent == STANDARD) & (m.epsilon == eps)]
    if (m.agent == SPEED_AGENT).any():
        out[SPEED_AGENT] = m[m.agent == SPEED_AGENT]
    return out


def rliable_table(m: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """IQM [95% stratified-bootstrap CI] per agent and metric, and P(affective better) [95% CI] against each agent."""
    parts = groups(m)
    rows: dict[str, dict[str, str]] = {name: {} for name in parts}
    for column, label in METRICS:
        scores = {name: part[column].to_numpy(float)[:, None] for name, part in parts.items() if len(part)}
        pairs = {name: [-scores[AFFECTIVE], -s] for name, s in scores.items() if name != AFFECTIVE}
        with warnings.catch_warnings():  # rliable hands arch a RandomState, which arch deprecates
            warnings.simplefilter("ignore", FutureWarning)
            point, cis = rly.get_interval_estimates(
                scores, lambda s: np.array([rmetrics.aggregate_iqm(s)]), reps=REPS, random_state=np.random.RandomState(seed)
            )
            poi, poi_ci = rly.get_interval_estimates(
                pairs, rmetrics.probability_of_improvement, reps=REPS // 5, random_state=np.random.RandomState(seed)
            )
        for name in scores:
            low, high = np.ravel(cis[name])[:2]
            iqm = float(np.ravel(point[name])[0])
            rows[name][f"IQM {label}"] = f"{fmt(iqm, 1)} [{fmt(float(low), 1)}, {fmt(float(high), 1)}]"
            if name in poi:
                low, high = np.ravel(poi_ci[name])[:2]
                rows[name][f"P(affective better), {label}"] = (
                    f"{fmt(float(np.ravel(poi[name])[0]), 3)} [{fmt(float(low), 3)}, {fmt(float(high), 3)}]"
                )
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "agent"
    return table


def profile_figure(m: pd.DataFrame, path: str, column: str = "decisions_before_optimal") -> str:
    """rliable performance profiles: the fraction of runs needing at most tau steps (95% bands)."""
    parts = groups(m)
    keep = [AFFECTIVE, "ε-greedy 0.1", "ε-greedy 0.5", "ε-greedy 0.9", SPEED_AGENT]
    scores = {k: parts[k][column].to_numpy(float)[:, None] for k in keep if k in parts and len(parts[k])}
    top = max(float(np.nanpercentile(s, 99)) for s in scores.values())
    bottom = min(float(np.nanpercentile(s, 1)) for s in scores.values())
    taus = np.logspace(np.log10(max(bottom / 1.5, 1.0)), np.log10(max(top, bottom + 1.0, 2.0)), 60)

    def at_most(s: np.ndarray, t: np.ndarray) -> np.ndarray:
        return np.array([np.mean(s <= x) for x in t])

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        prof, prof_ci = rly.create_performance_profile(scores, taus, custom_profile_func=at_most, reps=200)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    palette = [plt.get_cmap("tab10")(i) for i in range(10)]
    for i, name in enumerate(scores):
        ax.plot(taus, prof[name], color=palette[i], label=name, lw=1.6)
        ax.fill_between(taus, prof_ci[name][0], prof_ci[name][1], color=palette[i], alpha=0.2)
    ax.set_xscale("log")
    ax.set_xlabel(f"τ: {column.replace('_', ' ')}")
    ax.set_ylabel("fraction of runs with at most τ")
    ax.set_title("Performance profiles (rliable, stratified bootstrap 95% bands)")
    ax.legend(fontsize=8)
    return str(save(fig, path))


def speed_matched(m: pd.DataFrame) -> list[str]:
    """Sentences comparing the affective agent with the speed-matched ε-greedy (Welch CI, Mann-Whitney U)."""
    aff, speed = m[m.agent == AFFECTIVE], m[m.agent == SPEED_AGENT]
    out = []
    for column, label in METRICS:
        a, s = aff[column].to_numpy(float), speed[column].to_numpy(float)
        if len(a) < 2 or len(s) < 2:
            continue
        ci = sps.ttest_ind(a, s, equal_var=False).confidence_interval(0.95)
        p = float(sps.mannwhitneyu(a, s).pvalue)
        out.append(
            f"{label}: affective {fmt(float(a.mean()), 1)}, speed-matched ε-greedy {fmt(float(s.mean()), 1)}; "
            f"difference {fmt(float(a.mean() - s.mean()), 1)} [95% CI {fmt(float(ci.low), 1)}, {fmt(float(ci.high), 1)}], "
            f"Mann-Whitney p = {fmt(p, 3)} ({len(a)} and {len(s)} runs)"
        )
    return out


def with_speed_matched(ctx: ReportContext) -> pd.DataFrame:
    """Per-run metrics of the large-N study (else the paper sweep), with the issue 7 speed-matched runs if needed."""
    m = ctx.large if ctx.large is not None else ctx.metrics
    if SPEED_AGENT not in set(m.agent) and "baselines" in ctx.folders:
        results = load_results(ctx.folders["baselines"])
        base = run_metrics(results.episodes, results.runs) if len(results.episodes) else pd.DataFrame()
        if len(base) and SPEED_AGENT in set(base.agent):
            m = pd.concat([m, base[base.agent == SPEED_AGENT]], ignore_index=True)
    return m


def checks_section(ctx: ReportContext) -> None:
    ctx.doc.h("The project's own checks (not the paper's claims)")
    if not ctx.has_paper_agents:
        ctx.doc.p("Skipped: both paper agents are needed.")
        return
    m = with_speed_matched(ctx)
    n = int(m[m.agent == AFFECTIVE].groupby("epsilon").size().min()) if len(m[m.agent == AFFECTIVE]) else 0
    ctx.doc.p(
        "The speed-matched ε-greedy (ε = 0.01, 1 or 2 cells a decision; docs/beyond_the_paper.md) is compared with the "
        "affective agent in the verdict; it is in the tables below too."
    )
    ctx.doc.p(
        f"rliable ({n} runs per affective cell): interquartile mean (IQM) with stratified-bootstrap 95% CIs "
        f"({REPS} resamples), and the probability of improvement P(affective better than X) with its CI "
        "(0.5 = no difference; lower steps are better). The affective agent is pooled over its 9 ε labels."
    )
    ctx.table("rliable", rliable_table(m), "IQM and probability of improvement (rliable)")
    profile_figure(m, str(ctx.figure("performance_profiles")))
    ctx.doc.img(
        ctx.figure("performance_profiles"),
        "Performance profiles of steps before the optimal path: the fraction of runs that need at most τ steps",
    )
