"""
How much evidence: the headline tables at the large-N seed count beside the paper's 20, each verdict at 5, 10, 20,
50, 100 and 1,000 seeds per cell, how many seeds each claim needs (subsampling), and AdaStop's adaptive test.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sb3_affect.report import claims, paper
from sb3_affect.report.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.report.document import fmt
from sb3_affect.report.stats import paired_ttest_table
from sb3_affect.report.tables import DEFINITIONS, per_epsilon

SEED_COUNTS = (5, 10, 20, 50, 100, 1000)
#: Subsample sizes of the "seeds needed" search, repetitions per size, and the agreement it asks for.
NEEDED_GRID = (5, 10, 20, 50, 100, 200, 500)
REPETITIONS = 10
AGREEMENT = 0.8


def subset(large: pd.DataFrame, n: int) -> pd.DataFrame:
    """The first ``n`` replicates of every cell (replicate r is the same run at any seed count)."""
    return large[large.replicate < n]


def sensitivity(large: pd.DataFrame, counts: tuple[int, ...] = SEED_COUNTS) -> pd.DataFrame:
    """Verdict of each claim at each seed count (first n replicates per cell)."""
    available = int(large.groupby(["agent", "epsilon"]).size().min())
    columns = {}
    labels: list[str] = []
    for n in counts:
        if n > available:
            continue
        judged = claims.judge_all(subset(large, n))
        labels = [j.label for j in judged]
        columns[f"{n} seeds"] = [claims.verdict_word(j.verdict) for j in judged]
    table = pd.DataFrame(columns, index=pd.Index(labels, name="claim"))
    return table


def seeds_needed(
    large: pd.DataFrame, grid: tuple[int, ...] = NEEDED_GRID, repetitions: int = REPETITIONS, seed: int = 0
) -> pd.DataFrame:
    """
    For each claim, the smallest seed count whose random subsamples (``repetitions`` per size, seeded) reach the
    full-sample verdict (its first words) at least ``AGREEMENT`` of the time.
    """
    available = int(large.groupby(["agent", "epsilon"]).size().min())
    full = claims.judge_all(large)
    target = {j.label: claims.verdict_word(j.verdict) for j in full}
    rng = np.random.default_rng(seed)
    agreement: dict[int, dict[str, float]] = {}
    for n in grid:
        if n >= available:
            continue
        hits = dict.fromkeys(target, 0)
        for _ in range(repetitions):
            chosen = rng.choice(available, size=n, replace=False)
            judged = claims.judge_all(large[large.replicate.isin(chosen)])
            for j in judged:
                hits[j.label] += claims.verdict_word(j.verdict) == target[j.label]
        agreement[n] = {k: v / repetitions for k, v in hits.items()}
    rows = {}
    for label, word in target.items():
        enough = [n for n in sorted(agreement) if agreement[n][label] >= AGREEMENT]
        rows[label] = {
            f"verdict at {available} seeds": word,
            **{f"agreement at {n}": agreement[n][label] for n in sorted(agreement)},
            "seeds needed": enough[0] if enough else f"> {max(agreement) if agreement else 0}",
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "claim"
    return table


def adastop_table(large: pd.DataFrame, column: str, n: int = 5, max_interims: int = 20, seed: int = 0) -> pd.DataFrame:
    """
    AdaStop (adastop package): affective against ε-greedy at each ε on ``column``, feeding ``n`` new runs per agent
    per interim (in replicate order) until each comparison is decided or ``max_interims`` are spent.
    """
    from adastop import MultipleAgentsComparator

    available = int(large.groupby(["agent", "epsilon"]).size().min())
    interims = max(1, min(max_interims, available // n))
    names = [AFFECTIVE] + [f"{STANDARD} {eps:.1f}" for eps in paper.EPSILONS]
    data = {AFFECTIVE: large[(large.agent == AFFECTIVE)].sort_values("replicate")[column].to_numpy(float)}
    for eps in paper.EPSILONS:
        part = large[(large.agent == STANDARD) & np.isclose(large.epsilon, eps)].sort_values("replicate")
        data[f"{STANDARD} {eps:.1f}"] = part[column].to_numpy(float)
    comparator = MultipleAgentsComparator(
        n=n, K=interims, B=2000, comparisons=np.array([(0, i) for i in range(1, len(names))]), alpha=0.05, seed=seed
    )
    decided_at: dict[str, int] = {}
    for k in range(interims):
        comparator.partial_compare({name: data[name][: (k + 1) * n] for name in names}, verbose=False)
        for key, decision in comparator.decisions.items():
            if decision != "continue" and key not in decided_at:
                decided_at[key] = (k + 1) * n
        if comparator.is_finished:
            break
    rows = {}
    for i, name in enumerate(names[1:], start=1):
        key = str(np.array([0, i]))
        decision = comparator.decisions.get(key, "undecided")
        rows[f"affective vs {name}"] = {
            "decision (affective is ... than ε-greedy)": "undecided" if decision == "continue" else decision,
            "runs per agent when decided": decided_at.get(key, f"> {interims * n}"),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = f"comparison ({column})"
    return table


def headline_tables(large: pd.DataFrame, m: pd.DataFrame) -> pd.DataFrame:
    """Table IV and both Table V spreadsheets at the large-N count beside the paper protocol and the paper."""
    rows = {}
    n_large = int(large.groupby(["agent", "epsilon"]).size().min())
    n_paper = int(m.groupby(["agent", "epsilon"]).run_id.count().min())
    specs = [("Table IV", "decisions_per_episode", paper.TABLE_IV_PRINTED, 1.0)]
    specs += [
        (f"Table V ({label.split(':')[0]}, per 20 runs)", column, paper.TABLE_V_PRINTED, 20.0) for column, label in DEFINITIONS
    ]
    for name, column, printed, scale in specs:
        for data, n in ((m, n_paper), (large, n_large)):
            per_eps = per_epsilon(data, column) * scale
            t = paired_ttest_table(per_eps[STANDARD], per_eps[AFFECTIVE])
            rows[(name, f"ours, {n} seeds")] = {
                "ε-greedy mean": t.at["Mean", "Variable 1"],
                "affective mean": t.at["Mean", "Variable 2"],
                "ε-greedy variance": t.at["Variance", "Variable 1"],
                "affective variance": t.at["Variance", "Variable 2"],
                "Pearson r": t.at["Pearson Correlation", "Variable 1"],
                "t Stat": t.at["t Stat", "Variable 1"],
                "P one-tail": t.at["P(T<=t) one-tail", "Variable 1"],
                "P two-tail": t.at["P(T<=t) two-tail", "Variable 1"],
            }
        rows[(name, "paper, as printed")] = {
            "ε-greedy mean": printed["Mean"][0],
            "affective mean": printed["Mean"][1],
            "ε-greedy variance": printed["Variance"][0],
            "affective variance": printed["Variance"][1],
            "Pearson r": printed["Pearson Correlation"][0],
            "t Stat": printed["t Stat"][0],
            "P one-tail": printed["P(T<=t) one-tail"][0],
            "P two-tail": printed["P(T<=t) two-tail"][0],
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index = [f"{a}: {b}" for a, b in table.index]
    table.index.name = "table: source"
    return table


def evidence_section(ctx: ReportContext) -> None:
    ctx.doc.h("How much evidence: seed counts")
    large = ctx.large
    if large is None or ctx.verdict_refusal():
        ctx.doc.p(
            "Skipped: no large-N study in this folder (`sb3-affect replicate` runs it through the engine), or too few "
            "runs for a verdict."
        )
        return
    n_large = int(large.groupby(["agent", "epsilon"]).size().min())
    meta = ctx.large_meta or {}
    ctx.doc.p(
        f"The large-N study runs the paper's 18 cells and the speed-matched ε-greedy at {n_large} seeds per cell "
        f"({len(large)} runs of {meta.get('episodes', 200)} episodes, through `sb3_affect.engine.simulate`, "
        f"{fmt(meta.get('wall_seconds', math.nan), 1)} s). Seeds are the launcher's, so its first 20 replicates per "
        "cell are the runs of the paper protocol above."
    )
    ctx.table(
        "headline_tables",
        headline_tables(large, ctx.metrics),
        f"Tables IV and V at {n_large} seeds per cell beside the paper's protocol and the paper's printed numbers",
        4,
    )
    sens = sensitivity(large)
    ctx.table(
        "seed_sensitivity",
        sens,
        "Each verdict (its first words; the full verdicts are in the verdict table) at 5 to 1,000 seeds per cell "
        "(the first n replicates of each cell)",
    )
    needed = seeds_needed(large)
    ctx.table(
        "seeds_needed",
        needed,
        f"Seeds per cell each claim needs: share of {REPETITIONS} random subsamples (seeded) whose verdict matches the "
        f"{n_large}-seed verdict; 'seeds needed' is the smallest count reaching {AGREEMENT:.0%}",
        2,
    )
    ctx.doc.p(
        "Seeds needed is a documented alternative to a power analysis: for each seed count, draw random subsets of "
        "the runs of every cell, rerun the whole verdict (Holm correction included) and count how often it agrees "
        f"with the verdict at {n_large} seeds. AdaStop (below, the adastop package: an adaptive, sequential "
        "permutation test with early stopping, alpha = 0.05) answers the same question for single comparisons: it adds "
        "5 runs per agent at a time and stops when every comparison is decided."
    )
    for column in ("decisions_before_optimal", "decisions_per_episode"):
        try:
            table = adastop_table(large, column)
        except Exception as error:  # an optional analysis: say why it is missing
            ctx.doc.p(f"AdaStop on {column}: not available ({type(error).__name__}: {error}).")
            continue
        ctx.table(f"adastop_{column}", table, f"AdaStop: affective against ε-greedy on {column.replace('_', ' ')}")
