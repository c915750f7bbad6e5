"""
The project's own checks, apart from the paper's claims: the speed-matched ε-greedy (a fair baseline), and rliable's
interquartile means with stratified bootstrap CIs, probabilities of improvement and performance profiles.
"""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from rliable import metrics as rmetrics

from sb3_affect.study.report.estimation.bootstrap import bootstrap_improvement, bootstrap_iqm_cis, bootstrap_profile
from sb3_affect.study.report.estimation.kaplan_meier import bootstrap_km_iqm
from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.reading.run_tables import load_results, run_metrics
from sb3_affect.study.report.reading.study_tables import SPEED_AGENT
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.rendering.figures import save
from sb3_affect.study.report.verdicts.censoring import FLAGS, censored_runs, difference_sign, marked

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
        # a run that never found the path counts at its total: an IQM over it is a lower bound, and so on
        bounded = {name: censored_runs(part, column) > 0 for name, part in parts.items()}
        for name, values in scores.items():
            rows[name][f"IQM {label}"] = iqm_text(values, parts[name], column, cis[name][column], seed)
            if name == AFFECTIVE or AFFECTIVE not in scores:
                continue
            point, low, high = better[(column, name)]
            sign = difference_sign(bounded[name], bounded[AFFECTIVE])  # P(affective lower) rises with the other's values
            rows[name][f"P(affective better), {label}"] = marked(f"{fmt(point, 3)} [{fmt(low, 3)}, {fmt(high, 3)}]", sign)
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "agent"
    return table


def iqm_text(values: np.ndarray, runs: pd.DataFrame, column: str, ci: tuple[float, float, float], seed: int) -> str:
    """
    The IQM [95% CI] of one agent's ``values``: rliable's when no run is censored in ``column``; else the Kaplan-Meier
    IQM with its bootstrap CI (``KM``), or, where more than a quarter of the runs are censored above every event, the
    plain IQM marked as the lower bound it is, with the censored share and no interval.
    """
    if not censored_runs(runs, column):
        _, low, high = ci
        return f"{fmt(float(rmetrics.aggregate_iqm(values[:, None])), 1)} [{fmt(low, 1)}, {fmt(high, 1)}]"
    censored = runs[FLAGS[column]].to_numpy(bool)
    point, low, high = bootstrap_km_iqm(values, censored, REPS, seed=seed)
    if math.isnan(low):
        share = f"{censored.mean():.0%} censored: not estimable"
        return f"{marked(fmt(float(rmetrics.aggregate_iqm(values[:, None])), 1), '>=')} ({share})"
    return f"KM {fmt(point, 1)} [{fmt(low, 1)}, {fmt(high, 1)}]"


def profile_figure(m: pd.DataFrame, path: str, column: str = "decisions_before_optimal") -> str:
    """
    Performance profiles: the fraction of runs that found the optimal path within tau steps (95% bootstrap bands,
    seeded); a run that never found it (censored) never counts, so each curve plateaus at its share of runs that did.
    """
    parts = groups(m)
    keep = [AFFECTIVE, "ε-greedy 0.1", "ε-greedy 0.5", "ε-greedy 0.9", SPEED_AGENT]
    chosen = {k: parts[k] for k in keep if k in parts and len(parts[k])}
    scores = {k: part[column].to_numpy(float) for k, part in chosen.items()}
    censored = {k: part.censored.to_numpy(bool) for k, part in chosen.items()}
    found = [s[~censored[k]] for k, s in scores.items() if (~censored[k]).any()]
    top = max((float(np.nanpercentile(s, 99)) for s in found), default=2.0)
    bottom = min((float(np.nanpercentile(s, 1)) for s in found), default=1.0)
    taus = np.logspace(np.log10(max(bottom / 1.5, 1.0)), np.log10(max(top, bottom + 1.0, 2.0)), 60)
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    palette = [plt.get_cmap("tab10")(i) for i in range(10)]
    for i, (name, values) in enumerate(scores.items()):
        fraction, low, high = bootstrap_profile(values, taus, n_boot=PROFILE_REPS, censored=censored[name])
        share = 1 - censored[name].mean()
        ax.plot(taus, fraction, color=palette[i], label=f"{name} (found it: {share:.1%})", lw=1.6)
        ax.fill_between(taus, low, high, color=palette[i], alpha=0.2)
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(f"τ: {column.replace('_', ' ')}")
    ax.set_ylabel("fraction of runs that found it within τ")
    ax.set_title("Performance profiles (95% bootstrap bands; a censored run never counts)", fontsize=10)
    ax.legend(fontsize=8)
    return str(save(fig, path))


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
        f"rliable's measures ({n:,} runs per affective cell): interquartile mean (IQM) with bootstrap 95% CIs over runs "
        f"({REPS:,} seeded resamples; {REPS // 5:,} for the probability of improvement), and the probability of "
        "improvement P(affective better than X) with its CI "
        "(0.5 = no difference; lower steps are better). The affective agent is pooled over its 9 ε labels. Where runs "
        "never found the path (censored), the IQM is the Kaplan-Meier distribution's (KM, with its bootstrap CI), or a "
        "lower bound (>=) where more than a quarter of the runs are censored above every event."
    )
    ctx.table("rliable", rliable_table(m), "IQM and probability of improvement (rliable)")
    profile_figure(m, str(ctx.figure("performance_profiles")))
    ctx.doc.img(
        ctx.figure("performance_profiles"),
        "Performance profiles of steps before the optimal path: the fraction of runs that need at most τ steps",
    )
