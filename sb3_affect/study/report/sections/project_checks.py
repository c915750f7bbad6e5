"""
The project's own checks, apart from the paper's claims: the speed-matched ε-greedy (a fair baseline), and rliable's
interquartile means with stratified bootstrap CIs, probabilities of improvement and performance profiles.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from rliable import metrics as rmetrics
from scipy import stats as sps

from sb3_affect.study.report.estimation.bootstrap import bootstrap_improvement, bootstrap_iqm_cis, bootstrap_profile
from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.run_tables import load_results, run_metrics
from sb3_affect.study.report.reading.study_tables import SPEED_AGENT
from sb3_affect.study.report.rendering.document import fmt, pval
from sb3_affect.study.report.rendering.figures import save

METRICS = (
    ("decisions_per_episode", "steps per episode"),
    ("decisions_before_optimal", "steps before the optimal path (walked)"),
    ("decisions_to_greedy_optimal", "steps until the greedy policy stays optimal"),
)
#: Bootstrap resamples: the IQM CIs (the probability of improvement takes REPS // 5), the profile bands.
REPS, PROFILE_REPS = 1000, 200


def groups(m: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Runs per agent configuration: the affective agent pooled over ε, ε-greedy per ε, the speed-matched agent."""
    out = {AFFECTIVE: m[m.agent == AFFECTIVE]}
    for eps in sorted(m[m.agent == STANDARD].epsilon.unique()):
        out[f"ε-greedy {eps:.1f}"] = m[(m.agent == STANDARD) & (m.epsilon == eps)]
    if (m.agent == SPEED_AGENT).any():
        out[SPEED_AGENT] = m[m.agent == SPEED_AGENT]
    return out


def rliable_table(m: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """
    IQM [95% bootstrap CI] per agent and metric, and P(affective better) [95% CI] against each agent.

    rliable's definitions (``aggregate_iqm``, ``probability_of_improvement``: the Mann-Whitney U over all pairs) with
    a seeded bootstrap of runs (one task: rliable's stratified bootstrap is the bootstrap of runs), ``REPS``
    resamples for the IQM and ``REPS // 5`` for the probability of improvement. rliable's own bootstrap draws from
    numpy's global random state (so its CIs changed from one report to the next) and ranks every pair anew each
    resample; ours is reproducible and costs O(runs) a resample.
    """
    every = groups(m)
    parts = {name: part for name, part in every.items() if len(part)}
    rows: dict[str, dict[str, str]] = {name: {} for name in every}
    columns = [column for column, _ in METRICS]
    # a group's metrics share their resamples (drawn once: the same numbers as one bootstrap each)
    found = [bootstrap_iqm_cis([part[c].to_numpy(float) for c in columns], n_boot=REPS, seed=seed) for part in parts.values()]
    cis = {name: dict(zip(columns, part_cis)) for name, part_cis in zip(parts, found)}
    pairs = [(c, name) for c in columns for name in parts if name != AFFECTIVE and AFFECTIVE in parts]
    better = dict(
        zip(
            pairs,
            [
                bootstrap_improvement(
                    parts[AFFECTIVE][column].to_numpy(float), parts[name][column].to_numpy(float), REPS // 5, seed=seed
                )
                for column, name in pairs
            ],
        )
    )
    for column, label in METRICS:
        scores = {name: part[column].to_numpy(float) for name, part in parts.items()}
        for name, values in scores.items():
            iqm = float(rmetrics.aggregate_iqm(values[:, None]))
            _, low, high = cis[name][column]
            rows[name][f"IQM {label}"] = f"{fmt(iqm, 1)} [{fmt(low, 1)}, {fmt(high, 1)}]"
            if name == AFFECTIVE or AFFECTIVE not in scores:
                continue
            point, low, high = better[(column, name)]
            rows[name][f"P(affective better), {label}"] = f"{fmt(point, 3)} [{fmt(low, 3)}, {fmt(high, 3)}]"
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "agent"
    return table


def profile_figure(m: pd.DataFrame, path: str, column: str = "decisions_before_optimal") -> str:
    """Performance profiles: the fraction of runs needing at most tau steps (95% bootstrap bands, seeded)."""
    parts = groups(m)
    keep = [AFFECTIVE, "ε-greedy 0.1", "ε-greedy 0.5", "ε-greedy 0.9", SPEED_AGENT]
    scores = {k: parts[k][column].to_numpy(float) for k in keep if k in parts and len(parts[k])}
    top = max(float(np.nanpercentile(s, 99)) for s in scores.values())
    bottom = min(float(np.nanpercentile(s, 1)) for s in scores.values())
    taus = np.logspace(np.log10(max(bottom / 1.5, 1.0)), np.log10(max(top, bottom + 1.0, 2.0)), 60)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    palette = [plt.get_cmap("tab10")(i) for i in range(10)]
    for i, (name, values) in enumerate(scores.items()):
        fraction, low, high = bootstrap_profile(values, taus, n_boot=PROFILE_REPS)
        ax.plot(taus, fraction, color=palette[i], label=name, lw=1.6)
        ax.fill_between(taus, low, high, color=palette[i], alpha=0.2)
    ax.set_xscale("log")
    ax.set_xlabel(f"τ: {column.replace('_', ' ')}")
    ax.set_ylabel("fraction of runs with at most τ")
    ax.set_title("Performance profiles (bootstrap 95% bands over runs)")
    ax.legend(fontsize=8)
    return str(save(fig, path))


def speed_matched(m: pd.DataFrame) -> list[str]:
    """Sentences comparing the affective agent with the speed-matched ε-greedy (Welch t-test with its Welch CI)."""
    aff, speed = m[m.agent == AFFECTIVE], m[m.agent == SPEED_AGENT]
    out = []
    for column, label in METRICS:
        a, s = aff[column].to_numpy(float), speed[column].to_numpy(float)
        if len(a) < 2 or len(s) < 2:
            continue
        welch = sps.ttest_ind(a, s, equal_var=False)
        ci, p = welch.confidence_interval(0.95), float(welch.pvalue)
        out.append(
            f"{label}: affective {fmt(float(a.mean()), 1)}, speed-matched ε-greedy {fmt(float(s.mean()), 1)}; "
            f"difference {fmt(float(a.mean() - s.mean()), 1)} [95% CI {fmt(float(ci.low), 1)}, {fmt(float(ci.high), 1)}], "
            f"Welch p {pval(p)} ({len(a):,} and {len(s):,} runs)"
        )
    return out


def with_speed_matched(ctx: ReportContext) -> pd.DataFrame:
    """Per-run metrics of the large-N study (else the paper sweep), with the baselines folder's speed-matched runs."""
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
        f"rliable's measures ({n} runs per affective cell): interquartile mean (IQM) with bootstrap 95% CIs over runs "
        f"({REPS} seeded resamples; {REPS // 5} for the probability of improvement), and the probability of "
        "improvement P(affective better than X) with its CI "
        "(0.5 = no difference; lower steps are better). The affective agent is pooled over its 9 ε labels."
    )
    ctx.table("rliable", rliable_table(m), "IQM and probability of improvement (rliable)")
    profile_figure(m, str(ctx.figure("performance_profiles")))
    ctx.doc.img(
        ctx.figure("performance_profiles"),
        "Performance profiles of steps before the optimal path: the fraction of runs that need at most τ steps",
    )
