"""
How much evidence (appendix): the headline tables at the large-N seed count beside the paper's 20, each verdict at
5, 10, 20, 50, 100 and 1,000 seeds per cell, the power of the paper's 20-seed protocol (200 random subsamples), and
AdaStop's adaptive test.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sb3_affect.study.report.estimation.bootstrap import paired_ttest_table
from sb3_affect.study.report.reading.context import AFFECTIVE, STANDARD, ReportContext
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.sections.paper_tables import DEFINITIONS, per_epsilon
from sb3_affect.study.report.sections.reproducibility import part_time
from sb3_affect.study.report.sections.verdict import judged
from sb3_affect.study.report.verdicts import claims
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.censoring import censored_runs, marked

SEED_COUNTS = (5, 10, 20, 50, 100, 1000)
#: Random subsamples of the power study (at the paper's 20 seeds per cell), and the agreement called "usually".
REPETITIONS = 200
AGREEMENT = 0.8
#: The subsamples are drawn from this many seeded random streams (seeds ``seed``, ``seed + 1``, ...), near-equal
#: shares of ``REPETITIONS`` each: the power study's numbers depend on it, not on the machine's CPUs.
STREAMS = 2


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
        judged = claims.judge_all(subset(large, n), cells=False)
        labels = [j.label for j in judged]
        columns[f"{n:,} seeds"] = [claims.verdict_word(j.verdict) for j in judged]
    table = pd.DataFrame(columns, index=pd.Index(labels, name="claim"))
    return table


def _agreement(
    large: pd.DataFrame, target: dict[str, tuple[str, ...]], n: int, repetitions: int, seed: int
) -> dict[str, list[int]]:
    """
    How many random ``n``-seed subsamples reach each claim's target verdict words (by key): ``repetitions`` of them,
    drawn from ``STREAMS`` seeded streams (``seed``, ``seed + 1``, ...).
    """
    available = int(large.replicate.max()) + 1
    hits = {key: [0] * len(words) for key, words in target.items()}
    streams = max(1, min(STREAMS, repetitions))
    for stream in range(streams):
        rng = np.random.default_rng(seed + stream)
        for _ in range(repetitions // streams + (stream < repetitions % streams)):
            chosen = rng.choice(available, size=n, replace=False)
            for j in claims.judge_all(large[large.replicate.isin(chosen)], cells=False):
                word = claims.verdict_word(j.verdict)
                for i, wanted in enumerate(target.get(j.key, ())):
                    hits[j.key][i] += word == wanted
    return hits


def seeds_needed(
    large: pd.DataFrame,
    n: int = paper.SEEDS_PER_CELL,
    repetitions: int = REPETITIONS,
    seed: int = 0,
    full: list[claims.Judgement] | None = None,
    protocol: list[claims.Judgement] | None = None,
) -> pd.DataFrame:
    """
    The power of the paper's ``n``-seed protocol for each claim: the share of ``repetitions`` random ``n``-seed
    subsamples of the large-N runs (seeded: ``_agreement``) whose verdict (its first words) is the
    full-sample verdict, and (given ``protocol``, the verdicts of the paper protocol's own runs) the share whose verdict
    is the protocol's. Claims whose outcome is fixed by the design (the 9 ε values), not by seeds, say so.
    """
    available = int(large.groupby(["agent", "epsilon"]).size().min())
    full = full if full is not None else claims.judge_all(large)
    # by key: a claim's label may name its data (the long run's window), its key does not
    own = {j.key: claims.verdict_word(j.verdict) for j in protocol or []}
    target = {j.key: (claims.verdict_word(j.verdict), *((own[j.key],) if j.key in own else ())) for j in full}
    hits = _agreement(large, target, n, repetitions if n < available else 0, seed)
    rows = {}
    for j in full:
        shares = [count / repetitions if n < available and j.seed_dependent else math.nan for count in hits[j.key]]
        share = shares[0]
        rows[j.label] = {
            f"verdict at {available:,} seeds": target[j.key][0],
            f"share of {repetitions} {n}-seed subsamples with that verdict": share,
            "reading": (
                "fixed by the design (the 9 ε values), not by the seed count"
                if not j.seed_dependent
                else ("a 20-seed replication would usually agree" if share >= AGREEMENT else "a 20-seed replication "
                      "would agree more often than not" if share >= 0.5 else "a 20-seed replication would usually disagree")
            ),
        }
        if protocol is not None:
            rows[j.label][f"verdict of the paper protocol's {n:,} seeds"] = own.get(j.key, "")
            rows[j.label][f"share of the {n}-seed subsamples with the protocol's verdict"] = (
                shares[1] if len(shares) > 1 else math.nan
            )
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.name = "claim"
    return table


def adastop_table(large: pd.DataFrame, column: str, n: int = 5, max_interims: int = 20, seed: int = 0) -> pd.DataFrame:
    """
    AdaStop (adastop package): affective against ε-greedy at each ε on ``column``, feeding ``n`` new runs per agent
    per interim (in replicate order) until each comparison is decided or ``max_interims`` are spent.
    """
    from adastop import MultipleAgentsComparator  # (2.5 s to import, for this test only: not on every report import)

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
            bound = {a: ">=" if censored_runs(data[data.agent == a], column) else "" for a in (STANDARD, AFFECTIVE)}
            rows[(name, f"ours, {n:,} seeds")] = {
                "ε-greedy mean": marked(fmt(float(str(t.at["Mean", "Variable 1"]))), bound[STANDARD]),
                "affective mean": marked(fmt(float(str(t.at["Mean", "Variable 2"]))), bound[AFFECTIVE]),
                "ε-greedy variance": t.at["Variance", "Variable 1"],
                "affective variance": t.at["Variance", "Variable 2"],
                "Pearson r": t.at["Pearson Correlation", "Variable 1"],
                "t Stat": t.at["t Stat", "Variable 1"],
                "P one-tail": t.at["P(T<=t) one-tail", "Variable 1"],
                "P two-tail": t.at["P(T<=t) two-tail", "Variable 1"],
            }
        rows[(name, "paper, as printed")] = {
            "ε-greedy mean": fmt(printed["Mean"][0]),
            "affective mean": fmt(printed["Mean"][1]),
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
            "Skipped: no large-N study in this folder (`sb3-affect replicate` runs experiments/large.yaml), or too few "
            "runs for a verdict."
        )
        return
    n_large = int(large.groupby(["agent", "epsilon"]).size().min())
    meta = ctx.large_meta or {}
    ctx.doc.p(
        f"The large-N study runs the paper's 18 cells and the speed-matched ε-greedy at {n_large:,} seeds per cell "
        f"({len(large):,} runs of {meta.get('episodes', 200):,} episodes: experiments/large.yaml through the launcher; "
        f"{part_time(ctx, 'large', meta)}). The paper's agents take the paper "
        "sweep's seeds, so their first 20 replicates per cell are the runs of the paper protocol above."
    )
    ctx.table(
        "headline_tables",
        headline_tables(large, ctx.metrics),
        f"Tables IV and V at {n_large:,} seeds per cell beside the paper's protocol and the paper's printed numbers",
        2,
    )
    sens = sensitivity(large)
    ctx.table(
        "seed_sensitivity",
        sens,
        "Each verdict (its first words; the full verdicts are in the verdict table) at 5 to 1,000 seeds per cell "
        "(the first n replicates of each cell)",
    )

    _main, _n, protocol, _n_protocol = judged(ctx)
    needed = seeds_needed(large, full=ctx.judgements or None, protocol=protocol)
    ctx.cache["seeds needed"] = needed
    ctx.table(
        "seeds_needed",
        needed,
        f"Power of the paper's protocol: share of {REPETITIONS} random {paper.SEEDS_PER_CELL}-seed subsamples (seeded) "
        f"whose verdict matches the {n_large:,}-seed verdict (the long run: episodes 181-200 of these 200-episode "
        "runs, not the long runs the verdict uses)",
        2,
    )
    ctx.doc.p(
        f"The power study replaces a formula by simulation: {REPETITIONS} times, draw {paper.SEEDS_PER_CELL} of the "
        f"{n_large:,} runs of every cell, rerun the whole verdict (Holm correction included) and count how often it "
        f"agrees with the verdict at {n_large:,} seeds; its first {paper.SEEDS_PER_CELL} replicates are the paper "
        "protocol's own runs (the verdict table's last column). A claim whose outcome is fixed by the 9 ε values "
        "(the paper's paired t-test over them) has no seed count. AdaStop (below, the adastop package: an adaptive, "
        "sequential permutation test with early stopping, alpha = 0.05) answers the same question for single "
        "comparisons: it adds 5 runs per agent at a time and stops when every comparison is decided."
    )
    for column in ("decisions_before_optimal", "decisions_per_episode"):
        try:
            table = adastop_table(large, column)
        except Exception as error:  # an optional analysis: say why it is missing
            ctx.doc.p(f"AdaStop on {column}: not available ({type(error).__name__}: {error}).")
            continue
        ctx.table(f"adastop_{column}", table, f"AdaStop: affective against ε-greedy on {column.replace('_', ' ')}")
