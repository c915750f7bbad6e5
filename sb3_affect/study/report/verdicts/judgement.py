"""
``Judgement``: one claim of the paper judged on our runs, and the per-cell reductions the claims share (per-ε
comparisons, means over the 9 ε values, sizes against the paper's 20-seed protocol).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from sb3_affect.study.report.rendering.document import fmt, sig
from sb3_affect.study.report.verdicts import paper_numbers as paper
from sb3_affect.study.report.verdicts.inference import Estimate, Test, predictive, welch, z_estimate

STANDARD, AFFECTIVE = "epsilon-greedy", "affective"


@dataclass
class Judgement:
    """
    One claim of the paper judged on our runs.

    :param key: the claim's key in ``paper.QUOTES`` (``key:variant`` for variants)
    :param label: a short name (table row)
    :param paper: the paper's number(s) for it
    :param ours: our estimate in decisions (time) with its 95% CI
    :param cells: the same in cells (distance), where the claim counts steps ("" otherwise)
    :param direction: whether our effect points the paper's way (None: the claim has no direction)
    :param size: whether the paper's number lies within the 95% predictive interval of the same statistic at the
        paper's 20 seeds per cell (None: the claim states no number)
    :param ratio: the paper's number over ours (None: no number)
    :param bound: "lower" when our number is a lower bound (censored runs), so the ratio is an upper bound
    :param tests: the claim's family of tests (Holm-corrected within the claim)
    :param primary: the paper's own test, judged on its raw p-value as the paper did (None: the paper ran none)
    :param equivalence: an equivalence test (TOST), judged on its raw p-value outside the Holm family of difference
        tests (it asks another question: equivalence, not difference)
    :param seed_dependent: False when the outcome is fixed by the design (the 9 ε values), not by the seed count
    :param decide: the verdict from the judgement once the Holm-adjusted p-values are in
    :param verdict: the verdict, counting steps as decisions (time)
    :param cells_verdict: the same rule's verdict counting steps as cells (distance), for claims that count steps
    :param qualifier: what the report says before the verdict, e.g. that it changes with the windows read
    """

    key: str
    label: str
    paper: str
    ours: str
    cells: str = ""
    direction: bool | None = None
    size: bool | None = None
    ratio: float | None = None
    bound: str = ""
    tests: list[Test] = field(default_factory=list)
    primary: Test | None = None
    equivalence: Test | None = None
    seed_dependent: bool = True
    decide: Callable[[Judgement], str] | None = None
    verdict: str = ""
    cells_verdict: str = ""
    qualifier: str = ""

    @property
    def quote(self) -> str:
        return paper.QUOTES[self.key.split(":")[0]][0]

    @property
    def source(self) -> str:
        return paper.QUOTES[self.key.split(":")[0]][1]


def seeds_per_cell(m: pd.DataFrame) -> int:
    """The fewest runs of any (agent, ε) cell of the paper's two agents."""
    part = m[m.agent.isin([STANDARD, AFFECTIVE])]
    if not len(part):
        return 0
    codes = pd.MultiIndex.from_arrays([part.agent.to_numpy(), part.epsilon.to_numpy()])
    return int(pd.Series(1, index=codes).groupby(level=[0, 1]).size().min())


def cell_means(m: pd.DataFrame, column: str) -> pd.DataFrame:
    """Per epsilon: mean, variance and count over runs of both paper agents (columns ``mean_<agent>`` ...)."""
    if column not in m.columns:
        return pd.DataFrame()
    part = m[m.agent.isin([STANDARD, AFFECTIVE])]
    values = part[column].to_numpy(float)
    keep = ~np.isnan(values)
    frame = pd.DataFrame({"agent": part.agent.to_numpy()[keep], "epsilon": part.epsilon.to_numpy()[keep], "v": values[keep]})
    stats = frame.groupby(["agent", "epsilon"]).v.agg(["mean", "var", "count"]).rename(columns={"count": "n"})
    wide = stats.unstack(level=0)
    out = pd.DataFrame(
        {f"{stat}_{agent}": wide[(stat, agent)] for stat in ("mean", "var", "n") for agent in (STANDARD, AFFECTIVE)
         if (stat, agent) in wide.columns}
    )
    out.index.name = "epsilon"
    return out.dropna() if len(out.columns) == 6 else out.iloc[0:0]


def over_eps(cells: pd.DataFrame, agent: str) -> Estimate:
    """An agent's mean over the ε values of its cell means, with a normal 95% CI (runs independent)."""
    if not len(cells):
        return Estimate(math.nan, math.nan, math.nan)
    se = math.sqrt((cells[f"var_{agent}"] / cells[f"n_{agent}"]).sum()) / len(cells)
    return z_estimate(float(cells[f"mean_{agent}"].mean()), se)


def diff_over_eps(cells: pd.DataFrame) -> Estimate:
    """Mean over epsilons of (epsilon-greedy - affective) cell means, with a normal 95% CI (runs independent)."""
    if not len(cells):
        return Estimate(math.nan, math.nan, math.nan)
    d = cells[f"mean_{STANDARD}"] - cells[f"mean_{AFFECTIVE}"]
    var = (cells[f"var_{STANDARD}"] / cells[f"n_{STANDARD}"] + cells[f"var_{AFFECTIVE}"] / cells[f"n_{AFFECTIVE}"]).sum()
    return z_estimate(float(d.mean()), math.sqrt(var) / len(cells))


def per_epsilon(
    m: pd.DataFrame, column: str, name: str, reference: np.ndarray | None = None
) -> tuple[dict[float, Estimate], dict[float, Test]]:
    """
    Per ε: ε-greedy minus affective (or minus ``reference``) mean of ``column`` with its Welch 95% CI, and the Welch
    t-test that goes with it (one method for the interval and the test).
    """
    diffs: dict[float, Estimate] = {}
    tests: dict[float, Test] = {}
    if column not in m.columns:
        return diffs, tests
    part = m[m.agent.isin([STANDARD, AFFECTIVE])]
    cells = {(str(k[0]), float(k[1])): g[column].to_numpy(float) for k, g in part.groupby(["agent", "epsilon"])}  # type: ignore[arg-type]
    empty = np.array([])
    for eps in sorted(e for agent, e in cells if agent == STANDARD):
        a = cells[(STANDARD, eps)]
        b = reference if reference is not None else cells.get((AFFECTIVE, eps), empty)
        a, b = a[~np.isnan(a)], b[~np.isnan(b)]
        if len(a) and len(b):
            diffs[eps], p = welch(a, b)
            tests[eps] = Test(f"Welch t at ε = {fmt(eps, 1)}{name} (two-sided)", p)
    return diffs, tests


def size_against_paper(
    est: Estimate, printed: float, n_ours: int, n_paper: int = paper.SEEDS_PER_CELL, unit: str = "seeds per cell"
) -> tuple[bool, float, str]:
    """
    Whether ``printed`` lies within the 95% predictive interval of ``est`` at the paper's ``n_paper`` (seeds per cell,
    or runs: ``unit``); the ratio printed / ours; a phrase naming the interval.
    """
    low, high = predictive(est, n_ours, n_paper)
    inside = bool(low <= printed <= high)
    ratio = printed / est.value if est.value else math.nan
    name = f"{n_paper}-seed predictive interval" if unit == "seeds per cell" else f"predictive interval at {n_paper} {unit}"
    return inside, ratio, f"{name} [{sig(low)}, {sig(high)}]"


def eps_list(values: list[float]) -> str:
    return ", ".join(fmt(e, 1) for e in sorted(values)) or "none"
