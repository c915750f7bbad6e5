"""
The paper's claims judged on per-run metrics: direction, size with a 95% CI, the paper's test beside robust ones,
and one verdict per claim after Holm's correction over the whole family of tests.

``judge_all(m)`` takes one row per run (``report.metrics.run_metrics`` columns plus ``agent`` and ``epsilon``) and
returns the ``Judgement`` list; it uses analytic CIs (Welch / t intervals from scipy.stats) so it is cheap enough to
repeat on thousands of subsamples (the seed-count study).
"""

from __future__ import annotations

import gc
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import stats as sps
from statsmodels.stats.multitest import multipletests

from sb3_affect.report import paper
from sb3_affect.report.document import fmt

STANDARD, AFFECTIVE = "epsilon-greedy", "affective"
ALPHA = 0.05
#: "about 0.3" / "to 0.1" (Fig. 6) read as within this absolute distance.
ABOUT = 0.05


@dataclass
class Test:
    """One hypothesis test of the family: its name, raw p-value and Holm-adjusted p-value."""

    name: str
    p: float
    p_holm: float = math.nan


@dataclass
class Judgement:
    """
    One claim of the paper judged on our runs.

    :param key: the claim's key in ``paper.QUOTES``
    :param label: a short name (table row)
    :param paper: the paper's number(s) for it
    :param ours: our estimate with its 95% CI
    :param direction: whether our effect points the paper's way (None: the claim has no direction)
    :param size: whether the paper's size lies within our CI / tolerance (None: the claim states no size)
    :param tests: the tests of this claim (part of the Holm family)
    :param decide: the verdict from the judgement once the Holm-adjusted p-values are in
    """

    key: str
    label: str
    paper: str
    ours: str
    direction: bool | None
    size: bool | None
    tests: list[Test] = field(default_factory=list)
    decide: Callable[[Judgement], str] | None = None
    verdict: str = ""

    @property
    def quote(self) -> str:
        return paper.QUOTES[self.key.split(":")[0]][0]

    @property
    def source(self) -> str:
        return paper.QUOTES[self.key.split(":")[0]][1]


def _ci(x: np.ndarray) -> tuple[float, float, float]:
    x = x[~np.isnan(x)]
    if len(x) < 2:
        return (float(x.mean()) if len(x) else math.nan), math.nan, math.nan
    low, high = sps.t.interval(0.95, len(x) - 1, loc=x.mean(), scale=sps.sem(x)) if x.std() > 0 else (x.mean(),) * 2
    return float(x.mean()), float(low), float(high)


def _welch(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float]:
    """Mean of a - mean of b with the Welch 95% CI."""
    d = float(a.mean() - b.mean())
    if len(a) < 2 or len(b) < 2 or (a.std() == 0 and b.std() == 0):
        return d, d, d
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))  # Welch-Satterthwaite
    half = float(sps.t.ppf(0.975, df)) * math.sqrt(va + vb)
    return d, d - half, d + half


def _mwu(a: np.ndarray, b: np.ndarray, alternative: str = "two-sided") -> float:
    if len(a) == 0 or len(b) == 0 or (np.all(a == a[0]) and np.all(b == a[0])):
        return 1.0
    return float(sps.mannwhitneyu(a, b, alternative=alternative).pvalue)


def cell_means(m: pd.DataFrame, column: str) -> pd.DataFrame:
    """Per epsilon: mean, variance and count over runs of both paper agents (columns ``mean_<agent>`` ...)."""
    part = m[m.agent.isin([STANDARD, AFFECTIVE])]
    g = part.groupby(["epsilon", "agent"])[column]
    stats = pd.DataFrame({"mean": g.mean(), "var": g.var(ddof=1), "n": g.count()})
    out = pd.DataFrame(
        {
            f"{stat}_{agent}": stats[stat].xs(agent, level="agent")
            for stat in ("mean", "var", "n")
            for agent in (STANDARD, AFFECTIVE)
            if agent in set(part.agent)
        }
    )
    return out.dropna() if len(out.columns) == 6 else out.iloc[0:0]


def _mean_over_eps_diff(cells: pd.DataFrame) -> tuple[float, float, float]:
    """Mean over epsilons of (epsilon-greedy - affective) cell means, with a normal 95% CI (runs independent)."""
    d = cells[f"mean_{STANDARD}"] - cells[f"mean_{AFFECTIVE}"]
    var = (cells[f"var_{STANDARD}"] / cells[f"n_{STANDARD}"] + cells[f"var_{AFFECTIVE}"] / cells[f"n_{AFFECTIVE}"]).sum()
    se = math.sqrt(var) / len(cells) if len(cells) else math.nan
    return float(d.mean()), float(d.mean() - 1.96 * se), float(d.mean() + 1.96 * se)


def _paired(a: pd.Series, b: pd.Series, alternative: str) -> list[Test]:
    """The spreadsheet's paired t-test over epsilons, Wilcoxon signed-rank, and the paired t-test on logs."""
    side = {"two-sided": "two-tailed", "greater": "one-tailed"}[alternative]
    tests = [Test(f"paired t over the {len(a)} epsilons ({side}, the paper's test)", float(sps.ttest_rel(a, b, alternative=alternative).pvalue))]  # noqa: E501
    diff = a - b
    wil = float(sps.wilcoxon(a, b, alternative=alternative).pvalue) if (diff != 0).any() else 1.0
    tests.append(Test(f"Wilcoxon signed-rank over the epsilons ({side})", wil))
    if (a > 0).all() and (b > 0).all():
        tests.append(Test(f"paired t on log values ({side})", float(sps.ttest_rel(np.log(a), np.log(b), alternative=alternative).pvalue)))  # noqa: E501
    return tests


def _ci_text(est: tuple[float, float, float], digits: int = 2) -> str:
    return f"{fmt(est[0], digits)} [{fmt(est[1], digits)}, {fmt(est[2], digits)}]"


def _significant(test: Test) -> bool:
    return bool(test.p_holm < ALPHA)


def judge_table_iv(m: pd.DataFrame) -> Judgement:
    cells = cell_means(m, "decisions_per_episode")
    est = _mean_over_eps_diff(cells)
    paper_diff = paper.TABLE_IV["Mean"][0] - paper.TABLE_IV["Mean"][1]
    j = Judgement(
        "table_iv",
        "Table IV: no significant difference in steps per episode",
        f"67.02 vs 56.28 (difference {fmt(paper_diff)}), P two-tail 0.44",
        f"{fmt(cells[f'mean_{STANDARD}'].mean())} vs {fmt(cells[f'mean_{AFFECTIVE}'].mean())}; difference "
        + _ci_text(est),
        direction=est[0] > 0,
        size=est[1] <= paper_diff <= est[2],
        tests=_paired(cells[f"mean_{STANDARD}"], cells[f"mean_{AFFECTIVE}"], "two-sided"),
    )

    def decide(j: Judgement) -> str:
        none_sig = not any(_significant(t) for t in j.tests)
        if none_sig and j.size:
            return "reproduced"
        if none_sig:
            return "reproduced (no significant difference), size differs"
        return "not reproduced: significant difference"

    j.decide = decide
    return j


def _per_epsilon(
    m: pd.DataFrame, column: str, name: str, reference: np.ndarray | None = None
) -> tuple[dict[float, tuple[float, float, float]], dict[float, Test]]:
    """Per ε: ε-greedy minus affective (or minus ``reference``) mean of ``column`` with its Welch CI, and a U test."""
    diffs: dict[float, tuple[float, float, float]] = {}
    tests: dict[float, Test] = {}
    part = m[m.agent.isin([STANDARD, AFFECTIVE])]
    cells = {(str(k[0]), float(k[1])): g[column].to_numpy(float) for k, g in part.groupby(["agent", "epsilon"])}  # type: ignore[arg-type]
    empty = np.array([])
    for eps in sorted(e for agent, e in cells if agent == STANDARD):
        a = cells[(STANDARD, eps)]
        b = reference if reference is not None else cells.get((AFFECTIVE, eps), empty)
        if len(a) and len(b):
            diffs[eps] = _welch(a, b)
            tests[eps] = Test(f"Mann-Whitney U at ε = {fmt(eps, 1)}{name} (two-sided)", _mwu(a, b))
    return diffs, tests


def judge_fig3(m: pd.DataFrame) -> Judgement:
    diffs, tests = _per_epsilon(m, "decisions_per_episode", "")
    low = [d[0] for e, d in diffs.items() if e < 0.45]
    high = [d[0] for e, d in diffs.items() if e > 0.65]
    point = sorted((e, d[0] > 0) for e, d in diffs.items())
    cross = [f"{fmt(a, 1)}-{fmt(b, 1)}" for (a, sa), (b, sb) in itertools.pairwise(point) if sa != sb]
    j = Judgement(
        "fig3",
        "Fig. 3: crossover, ε-greedy better below ε 0.5, affective better above 0.6",
        "crossover between ε = 0.5 and 0.6",
        "ε-greedy minus affective steps per episode: "
        + "; ".join(f"ε {fmt(e, 1)}: {_ci_text(d, 1)}" for e, d in diffs.items())
        + f". Point estimates change sign between ε {', '.join(cross) or 'none'}",
        direction=bool(all(x < 0 for x in low) and all(x > 0 for x in high)) if low and high else None,
        size=None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        sign = {e: (1 if d[0] > 0 else -1) if _significant(tests[e]) else 0 for e, d in diffs.items()}
        signs = [sign[e] for e in sorted(sign) if sign[e] != 0]
        changes = sum(1 for x, y in itertools.pairwise(signs) if x != y)
        if changes == 1 and signs[0] < 0:
            last_neg = max(e for e in sign if sign[e] < 0)
            first_pos = min(e for e in sign if sign[e] > 0)
            where = f"significant differences change sign between ε {fmt(last_neg, 1)} and {fmt(first_pos, 1)}"
            if last_neg >= 0.4 and first_pos <= 0.7:
                return f"reproduced: a crossover, {where}"
            return f"crossover reproduced, shifted: {where} (paper: 0.5-0.6)"
        if not signs:
            return "not reproduced: no significant difference at any ε"
        return "not reproduced: " + ("affective better everywhere it differs" if min(signs) > 0 else "no single crossover")

    j.decide = decide
    return j


def judge_table_v(m: pd.DataFrame, column: str = "decisions_before_optimal", definition: str = "walked") -> Judgement:
    cells = cell_means(m, column)
    est = _mean_over_eps_diff(cells)
    runs = paper.SEEDS_PER_CELL
    scaled = (est[0] * runs, est[1] * runs, est[2] * runs)
    paper_diff = paper.TABLE_V["Mean"][0] - paper.TABLE_V["Mean"][1]
    j = Judgement(
        f"table_v:{definition}",
        f"Table V ({definition} definition): affective needs significantly fewer steps",
        f"110190.20 vs 99357.56 per 20 runs (difference {fmt(paper_diff)}), P one-tail 0.01",
        f"{fmt(cells[f'mean_{STANDARD}'].mean() * runs)} vs {fmt(cells[f'mean_{AFFECTIVE}'].mean() * runs)} per 20 runs; "
        f"difference {_ci_text(scaled, 0)}",
        direction=est[0] > 0,
        size=scaled[1] <= paper_diff <= scaled[2],
        tests=_paired(cells[f"mean_{STANDARD}"], cells[f"mean_{AFFECTIVE}"], "greater"),
    )

    def decide(j: Judgement) -> str:
        sig = _significant(j.tests[0])
        robust = sum(_significant(t) for t in j.tests[1:])
        if j.direction and sig and j.size:
            return "reproduced"
        if j.direction and sig:
            return "direction reproduced (significant), size differs"
        if j.direction and robust:
            return "direction reproduced; the paper's t-test not significant, a robust test is"
        if j.direction:
            return "not reproduced: same direction, not significant"
        return "not reproduced: opposite direction"

    j.decide = decide
    return j


def judge_fig4(m: pd.DataFrame, column: str = "decisions_before_optimal", definition: str = "walked") -> Judgement:
    diffs, tests = _per_epsilon(m, column, f", {definition}")
    fewer = [e for e, d in diffs.items() if d[0] > 0]
    j = Judgement(
        f"fig4:{definition}",
        f"Fig. 4 ({definition} definition): affective needs fewer steps at every ε but 0.7",
        "fewer at 8 of 9 ε (all but 0.7)",
        f"affective fewer (point estimate) at {len(fewer)} of {len(diffs)} ε: {', '.join(fmt(e, 1) for e in fewer) or 'none'}",
        direction=len(fewer) >= len(diffs) - 1 if diffs else None,
        size=None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        aff = [e for e, d in diffs.items() if _significant(tests[e]) and d[0] > 0]
        std = [e for e, d in diffs.items() if _significant(tests[e]) and d[0] < 0]
        text = (
            f"affective significantly fewer at ε {', '.join(fmt(e, 1) for e in aff) or 'none'}; "
            f"significantly more at {', '.join(fmt(e, 1) for e in std) or 'none'}"
        )
        if len(aff) >= len(diffs) - 1 and not std:
            return "reproduced: " + text
        if aff and len(aff) > len(std):
            return "partly reproduced: " + text
        return "not reproduced: " + text

    j.decide = decide
    return j


def judge_episodes_to_optimal(m: pd.DataFrame) -> Judgement:
    """27.35 episodes: the Kaplan-Meier restricted mean (lifelines) of the first optimal episode, censored runs kept."""
    from lifelines import KaplanMeierFitter

    aff = m[m.agent == AFFECTIVE]
    horizon = float(aff.episodes.max())
    observed = ~aff.censored.to_numpy(bool)
    durations = aff.first_optimal.fillna(aff.episodes).to_numpy(float)
    fitter = KaplanMeierFitter().fit(durations, event_observed=observed)
    sf = fitter.survival_function_.iloc[:, 0]
    times = np.append(sf.index.to_numpy(float), horizon)
    times = np.clip(times, 0.0, horizon)
    rmst = float(np.sum(sf.to_numpy(float) * np.diff(times)))  # the area under lifelines' KM step function up to t
    se = float(np.std(np.minimum(durations, horizon), ddof=1)) / math.sqrt(len(aff))  # exact without censoring
    est = (float(rmst), float(rmst) - 1.96 * se, float(rmst) + 1.96 * se)
    z = (est[0] - paper.EPISODES_TO_OPTIMAL) / se if se > 0 else math.inf
    censored = int((~observed).sum())
    test = Test("z-test of the KM restricted mean against 27.35 (two-sided)", float(2 * sps.norm.sf(abs(z))))
    j = Judgement(
        "episodes_to_optimal",
        "27.35 episodes until the optimal path (affective)",
        "27.35",
        f"{_ci_text(est)} (Kaplan-Meier restricted mean to episode {int(horizon)}; {censored} of {len(aff)} runs "
        f"censored; median {fmt(float(fitter.median_survival_time_), 1)})",
        direction=None,
        size=bool(est[1] <= paper.EPISODES_TO_OPTIMAL <= est[2]),
        tests=[test],
    )
    j.decide = lambda j: "reproduced" if not _significant(j.tests[0]) else (
        "not reproduced: " + ("fewer" if est[0] < paper.EPISODES_TO_OPTIMAL else "more") + " episodes"
    )
    return j


def judge_fig5(m: pd.DataFrame, weighted: bool) -> Judgement:
    aff = m[m.agent == AFFECTIVE]
    suffix = "_weighted" if weighted else ""
    early = (aff[f"joy_1_10{suffix}"] - aff[f"anger_1_10{suffix}"]).to_numpy(float)
    late = (aff[f"anger_181_200{suffix}"] - aff[f"joy_181_200{suffix}"]).to_numpy(float)
    e_est, l_est = _ci(early), _ci(late)
    name = "decision-weighted" if weighted else "mean of per-episode fractions"
    tests = [
        Test(f"Wilcoxon: joy > anger in episodes 1-10, {name}", _one_sample(early)),
        Test(f"Wilcoxon: anger > joy in episodes 181-200, {name}", _one_sample(late)),
    ]
    j = Judgement(
        f"fig5:{'weighted' if weighted else 'mean'}",
        f"Fig. 5 ({name}): joy dominant early, anger later",
        "joy dominant early, anger later (no numbers printed)",
        f"joy - anger in episodes 1-10: {_ci_text(e_est, 3)}; anger - joy in 181-200: {_ci_text(l_est, 3)}",
        direction=bool(e_est[0] > 0 and l_est[0] > 0),
        size=None,
        tests=tests,
    )

    def decide(j: Judgement) -> str:
        joy_early = _significant(j.tests[0]) and e_est[0] > 0
        anger_late = _significant(j.tests[1]) and l_est[0] > 0
        if joy_early and anger_late:
            return "reproduced"
        if joy_early:
            return "partly: joy dominates early, but " + ("joy" if l_est[0] < 0 else "neither") + " dominates late"
        if anger_late:
            return "partly: anger dominates late, not joy early"
        return "not reproduced"

    j.decide = decide
    return j


def _one_sample(x: np.ndarray) -> float:
    x = x[~np.isnan(x)]
    if len(x) == 0 or not (x != 0).any():
        return 1.0
    return float(sps.wilcoxon(x, alternative="greater").pvalue)


def judge_fig6(m: pd.DataFrame) -> Judgement:
    aff = m[m.agent == AFFECTIVE]
    early, late = aff.eqeps_1_10.to_numpy(float), aff.eqeps_181_200.to_numpy(float)
    e_est, l_est = _ci(early), _ci(late)
    size = abs(e_est[0] - paper.EQUIVALENT_EPSILON_EARLY) <= ABOUT and abs(l_est[0] - paper.EQUIVALENT_EPSILON_LATE) <= ABOUT
    j = Judgement(
        "fig6",
        "Fig. 6: equivalent ε about 0.3 early, falling to 0.1",
        "about 0.3 early, 0.1 near the end",
        f"episodes 1-10: {_ci_text(e_est, 3)}; 181-200: {_ci_text(l_est, 3)} (mean of per-episode fractions)",
        direction=bool(e_est[0] > l_est[0]),
        size=bool(size),
        tests=[Test("Wilcoxon signed-rank per run: episodes 1-10 > 181-200", _one_sample(early - late))],
    )

    def decide(j: Judgement) -> str:
        falls = _significant(j.tests[0]) and bool(j.direction)
        if falls and j.size:
            return "reproduced"
        if falls:
            return f"direction reproduced (it falls), levels differ (tolerance ±{ABOUT})"
        return "not reproduced"

    j.decide = decide
    return j


def judge_long_run(m: pd.DataFrame) -> Judgement:
    aff = m[m.agent == AFFECTIVE].decisions_181_200.to_numpy(float)
    diffs, tests = _per_epsilon(m, "decisions_181_200", ", episodes 181-200", reference=aff)
    j = Judgement(
        "long_run",
        "Long run: the affective agent takes fewer steps than the standard agent",
        "no numbers printed",
        f"steps per episode in episodes 181-200: affective {fmt(float(np.mean(aff)))}; ε-greedy minus affective "
        + ", ".join(f"ε {fmt(e, 1)}: {_ci_text(d, 1)}" for e, d in diffs.items()),
        direction=all(d[0] > 0 for d in diffs.values()),
        size=None,
        tests=list(tests.values()),
    )

    def decide(j: Judgement) -> str:
        sig_low = [e for e, d in diffs.items() if _significant(tests[e]) and d[0] > 0]
        sig_high = [e for e, d in diffs.items() if _significant(tests[e]) and d[0] < 0]
        text = (
            f"affective significantly lower at ε {', '.join(fmt(e, 1) for e in sig_low) or 'none'}, "
            f"higher at {', '.join(fmt(e, 1) for e in sig_high) or 'none'}"
        )
        if not sig_high and sig_low:
            return "reproduced: " + text
        if sig_low:
            return "partly reproduced: " + text
        return "not reproduced: " + text

    j.decide = decide
    return j


def judge_four_emotions(m: pd.DataFrame) -> Judgement:
    aff = m[m.agent == AFFECTIVE]
    share = float((aff[["sadness_1_10", "fear_1_10", "sadness_181_200", "fear_181_200"]].to_numpy(float)).max())
    j = Judgement(
        "four_emotions",
        "Four emotions shape behaviour (sadness and fear included)",
        "all four emotions in Fig. 5",
        f"largest per-run fraction of sadness or fear in episodes 1-10 and 181-200: {fmt(share, 3)}",
        direction=share > 0,
        size=None,
    )
    j.decide = lambda j: (
        "not reproduced: sadness and fear never occur (Table II as printed, with exp1 = max(norm, elapsed))"
        if not j.direction
        else "reproduced"
    )
    return j


def judge_all(m: pd.DataFrame) -> list[Judgement]:
    """Every claim judged on ``m`` (one row per run), Holm-corrected over all the tests, verdicts filled in."""
    judgements = [
        judge_table_iv(m),
        judge_fig3(m),
        judge_table_v(m, "decisions_before_optimal", "walked"),
        judge_table_v(m, "decisions_to_greedy_optimal", "greedy"),
        judge_fig4(m, "decisions_before_optimal", "walked"),
        judge_fig4(m, "decisions_to_greedy_optimal", "greedy"),
        judge_episodes_to_optimal(m),
        judge_fig5(m, weighted=False),
        judge_fig5(m, weighted=True),
        judge_fig6(m),
        judge_long_run(m),
        judge_four_emotions(m),
    ]
    holm(judgements)
    for j in judgements:
        j.verdict = j.decide(j) if j.decide else ""
    return judgements


def holm(judgements: list[Judgement]) -> int:
    """Holm's step-down correction over every test of every judgement (in place); returns the family size."""
    tests = [t for j in judgements for t in j.tests]
    pvalues = np.array([t.p if not math.isnan(t.p) else 1.0 for t in tests])
    if len(tests):
        gc.freeze()  # statsmodels' Holm branch calls gc.collect(): keep it from scanning the whole heap each time
        try:
            adjusted = multipletests(pvalues, alpha=ALPHA, method="holm")[1]
        finally:
            gc.unfreeze()
        for t, p in zip(tests, adjusted):
            t.p_holm = float(p)
    return len(tests)


def verdict_word(verdict: str) -> str:
    """The verdict's first words (``reproduced``, ``partly``, ``not reproduced`` ...), for compact tables."""
    return verdict.split(":")[0].split(";")[0].split(" (")[0]
