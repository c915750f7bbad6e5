"""
The first optimal episode as time-to-event data: Kaplan-Meier estimates (lifelines) for every (agent, epsilon) cell,
on two clocks (episodes, and decisions before the optimal path), with censored runs (never found it) treated the
same way everywhere: censored at the end of the run.
"""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from lifelines import KaplanMeierFitter
from lifelines.statistics import logrank_test
from lifelines.utils import median_survival_times, restricted_mean_survival_time

from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.rendering.document import fmt, pval, sig
from sb3_affect.study.report.rendering.figures import COLOURS, STYLES, distinct, save


def km(durations: np.ndarray, observed: np.ndarray, horizon: float) -> dict[str, float]:
    """Kaplan-Meier median (95% CI) and restricted mean up to ``horizon`` of one sample."""
    fitter = KaplanMeierFitter().fit(durations, event_observed=observed)
    ci = median_survival_times(fitter.confidence_interval_)
    low, high = (float(v) for v in ci.iloc[0]) if len(ci) else (math.nan, math.nan)
    return {
        "median": float(fitter.median_survival_time_),
        "median_low": low,
        "median_high": high,
        "rmst": float(restricted_mean_survival_time(fitter, t=horizon)),
    }


def _reached(value: float, horizon: float, digits: int = 1) -> str:
    """A KM quantile, or "> horizon" when the curve never falls that far (more than half the runs censored)."""
    return f"> {fmt(horizon, 0)}" if math.isinf(value) else fmt(value, digits)


def km_table(m: pd.DataFrame) -> pd.DataFrame:
    """Per (agent, epsilon): runs, censored runs, KM medians of the first optimal episode and of decisions before it."""
    rows = {}
    horizon = float(m.episodes.max())
    for key, g in m.groupby(["agent", "epsilon"]):
        agent, eps = str(key[0]), float(key[1])  # type: ignore[arg-type]
        observed = ~g.censored.to_numpy(bool)
        episodes = g.first_optimal.fillna(g.episodes).to_numpy(float)
        decisions = g.decisions_before_optimal.to_numpy(float)
        e = km(episodes, observed, horizon)
        d = km(decisions, observed, float(decisions.max()))
        rows[f"{agent} @ {fmt(eps, 1)}"] = {
            "runs": len(g),
            "censored": int((~observed).sum()),
            "first optimal episode: KM median [95% CI]": f"{_reached(e['median'], horizon)} "
            f"[{_reached(e['median_low'], horizon)}, {_reached(e['median_high'], horizon)}]",
            f"restricted mean to {int(horizon)}": e["rmst"],
            "mean over runs that found it": g.first_optimal.mean(),
            "decisions before it: KM median": _reached(d["median"], float(decisions.max()), 0),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "agent @ ε"
    return table


def km_figure(m: pd.DataFrame, path: str, title: str) -> str:
    """Fraction of runs that have not yet found the optimal path, per episode (KM curves with 95% bands)."""
    fig, ax = plt.subplots(figsize=(8.6, 4.2))
    values = sorted(m[m.agent == STANDARD].epsilon.unique())
    ticks = {"marker": "|", "ms": 9, "mew": 1.4}
    palette = distinct(len(values))
    for i, eps in enumerate(values):
        g = m[(m.agent == STANDARD) & (m.epsilon == eps)]
        label = f"ε-greedy {eps:.1f}"
        fitter = KaplanMeierFitter().fit(g.first_optimal.fillna(g.episodes), ~g.censored.astype(bool), label=label)
        fitter.plot_survival_function(
            ax=ax, ci_show=False, color=palette[i], lw=1.3, ls=STYLES[i % len(STYLES)], show_censors=True, censor_styles=ticks
        )
    g = m[m.agent == AFFECTIVE]
    fitter = KaplanMeierFitter().fit(g.first_optimal.fillna(g.episodes), ~g.censored.astype(bool), label="affective (all ε)")
    fitter.plot_survival_function(
        ax=ax, ci_show=True, color=COLOURS[AFFECTIVE], lw=2.2, show_censors=True, censor_styles={**ticks, "ms": 14}
    )
    horizon = float(m.episodes.max())
    ax.set_xlim(0, horizon * 1.04)  # the censoring ticks sit at the last episode: inside the frame, not on it
    ax.set_xlabel("episode")
    ax.set_ylabel("runs without an optimal path yet (KM)")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the curves, never over them
    return str(save(fig, path))


def survival_section(ctx: ReportContext) -> None:
    """Kaplan-Meier section (the paper sweep, and the large-N study when present)."""
    ctx.doc.h("The first optimal episode as time-to-event data")
    ctx.doc.p(
        "A run that never walks an optimal path in its 200 episodes is censored: we know only that its first optimal "
        "episode is later than 200. Every estimate below treats it so (Kaplan-Meier, lifelines): medians with 95% CIs, "
        "the restricted mean up to the last episode, and a log-rank test; Table V keeps the paper's convention (a "
        "censored run contributes all its steps, a lower bound), and Fig. 4 marks censored runs."
    )
    m = ctx.metrics[ctx.metrics.agent.isin([STANDARD, AFFECTIVE])]
    if not ctx.has_paper_agents or m.empty:
        ctx.doc.p("Skipped: both paper agents are needed.")
        return
    sources = [("paper", m, "the paper's protocol")]
    if ctx.large is not None:
        sources.append(("large", ctx.large[ctx.large.agent.isin([STANDARD, AFFECTIVE])], "the large-N study"))
    for name, data, label in sources:
        seeds = int(data.groupby(["agent", "epsilon"]).size().min())
        ctx.table(f"kaplan_meier_{name}", km_table(data), f"Kaplan-Meier, {label} ({seeds:,} runs per cell)", 1)
        aff = data[data.agent == AFFECTIVE]
        std = data[data.agent == STANDARD]
        test = logrank_test(
            std.first_optimal.fillna(std.episodes),
            aff.first_optimal.fillna(aff.episodes),
            ~std.censored.astype(bool),
            ~aff.censored.astype(bool),
        )
        ctx.doc.p(
            f"Log-rank test, affective (all ε pooled) against ε-greedy (all ε pooled), {label}: "
            f"statistic {sig(float(test.test_statistic))}, p {pval(float(test.p_value))}. "
            f"Censored runs: affective {int(aff.censored.sum()):,} of {len(aff):,}, ε-greedy {int(std.censored.sum()):,} of "
            f"{len(std):,}."
        )
    path = km_figure(m, str(ctx.figure("kaplan_meier")), "Runs still without an optimal path (paper protocol)")
    ctx.doc.img(
        ctx.figure("kaplan_meier"),
        "Kaplan-Meier curves: the fraction of runs that have not yet walked an optimal path, per episode; "
        "ticks: censored runs; band: 95% CI (affective)",
    )
    del path
