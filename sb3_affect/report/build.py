"""``build_report``: the replication report from results folders (paper sweep, optionally DQN and ablation)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.report import figures, paper
from sb3_affect.report.document import Document, fmt
from sb3_affect.report.metrics import load_results, profile, run_metrics, window_mean
from sb3_affect.report.stats import bootstrap_ci, bootstrap_improvement, paired_ttest_table
from sb3_affect.report.verdict import Claim, verdict

STANDARD, AFFECTIVE = "epsilon-greedy", "affective"
WINDOWS = ((1, 10), (21, 40), (181, 200))
#: Issue 7 results folders a replicate folder may hold (experiments/baselines*.yaml), shown in their own section.
BASELINE_FOLDERS = ("baselines", "baselines_moving7", "baselines_moving")
#: Issue 16 results folders (experiments/hunters*.yaml): two hunters, and the two emotion models side by side.
HUNTER_FOLDERS = ("hunters", "hunters_moving")


def _layout(run_dir: Path) -> tuple[Path, Path | None, Path | None]:
    """A replicate folder (paper/, dqn/, ablation/) or a single results folder (holding runs/, chunks/ or both)."""
    if not (run_dir / "runs").is_dir() and (run_dir / "paper" / "runs").is_dir():
        dqn = run_dir / "dqn"
        ablation = run_dir / "ablation"
        return run_dir / "paper", dqn if (dqn / "runs").is_dir() else None, ablation if (ablation / "runs").is_dir() else None
    if not (run_dir / "runs").is_dir():
        raise FileNotFoundError(f"{run_dir} holds no results: expected {run_dir / 'runs'} (or paper/runs from replicate)")
    return run_dir, None, None


def build_report(
    run_dir: Path, out: Path | None = None, dqn_dir: Path | None = None, ablation_dir: Path | None = None
) -> Path:
    """
    Write ``report.md``, ``report.html`` (self-contained), ``tables/*.csv`` and ``figures/*.png``.

    :param run_dir: a results folder of the paper sweep, or a ``replicate`` folder holding paper/, dqn/, ablation/
    :param out: where to write (default: ``run_dir``)
    :param dqn_dir: results of experiments/dqn.yaml (default: ``run_dir/dqn`` when present)
    :param ablation_dir: results of experiments/ablation.yaml (default: ``run_dir/ablation`` when present)
    :return: the path of report.md
    """
    run_dir = Path(run_dir)
    paper_dir, found_dqn, found_ablation = _layout(run_dir)
    dqn_dir = dqn_dir or found_dqn
    ablation_dir = ablation_dir or found_ablation
    out = Path(out or run_dir)
    (out / "tables").mkdir(parents=True, exist_ok=True)
    (out / "figures").mkdir(parents=True, exist_ok=True)

    runs, episodes = load_results(paper_dir)
    if episodes.empty:
        raise ValueError(f"{paper_dir / 'runs'} holds no finished runs")
    metrics = run_metrics(episodes, runs)
    doc = Document("Q-Learning with Basic Emotions: replication report")
    ctx = _Context(doc, out, episodes, metrics)
    ctx.overview(paper_dir)
    claims: list[Claim] = []
    if {STANDARD, AFFECTIVE} <= set(metrics.agent) and "epsilon" in metrics.columns:
        claims += ctx.table_iv()
        claims += ctx.table_v()
        ctx.figures_3_4()
        claims += ctx.optimal_path()
        claims += ctx.profile_section()
        ctx.learning_curves()
        claims += ctx.robust_statistics()
    else:
        doc.p(
            f"The paper's comparison needs both agents `{STANDARD}` and `{AFFECTIVE}` with an `epsilon` label; "
            f"this folder has agents {sorted(metrics.agent.unique())}: only the summary below is shown."
        )
        ctx.table("agents", _agent_summary(metrics), "Per-agent summary (means over runs)")
    verdict(doc, claims)
    if ablation_dir is not None:
        ctx.ablation(ablation_dir)
    else:
        doc.h("Reading ablation")
        doc.p("Skipped: no ablation results (run experiments/ablation.yaml, or `sb3-affect replicate`).")
    if dqn_dir is not None:
        ctx.dqn(dqn_dir)
    else:
        doc.h("DQN on the same task")
        doc.p("Skipped: no DQN results (run experiments/dqn.yaml, or `sb3-affect replicate`).")
    baseline_dirs = [run_dir / name for name in BASELINE_FOLDERS if (run_dir / name / "runs").is_dir()]
    if baseline_dirs:
        from sb3_affect.report.baselines import baselines_section

        doc.md(baselines_section(baseline_dirs))
    hunter_dirs = [run_dir / name for name in HUNTER_FOLDERS if (run_dir / name / "runs").is_dir()]
    if "team" in episodes.columns or "capturer" in episodes.columns:  # a single folder of team runs
        hunter_dirs.append(paper_dir)
    if hunter_dirs:
        from sb3_affect.report.emotion_models import emotion_models_section
        from sb3_affect.report.hunters import hunters_section

        for section in (hunters_section, emotion_models_section):
            text, images = section(hunter_dirs, out)
            doc.md(text)
            for path, caption in images:
                doc.img(path, caption)
    ctx.definitions()
    md = out / "report.md"
    md.write_text(doc.markdown(out))
    (out / "report.html").write_text(doc.html())
    return md


def _value(table: pd.DataFrame, row: str, column: str = "Variable 1") -> float:
    return float(table.at[row, column])  # type: ignore[arg-type]


def _with_ci(estimate: tuple[float, float, float], digits: int = 2) -> str:
    return f"{fmt(estimate[0], digits)} [{fmt(estimate[1], digits)}, {fmt(estimate[2], digits)}]"


def _agent_summary(metrics: pd.DataFrame) -> pd.DataFrame:
    keys = [k for k in ("agent", "epsilon") if k in metrics.columns]
    summary = metrics.groupby(keys).agg(
        runs=("run_id", "count"),
        decisions_per_episode=("decisions_per_episode", "mean"),
        cells_per_episode=("cells_per_episode", "mean"),
        first_optimal=("first_optimal", "mean"),
        never_optimal=("censored", "sum"),
        decisions_before_optimal=("decisions_before_optimal", "mean"),
        truncated_episodes=("truncated", "sum"),
    )
    return summary


class _Context:
    def __init__(self, doc: Document, out: Path, episodes: pd.DataFrame, metrics: pd.DataFrame) -> None:
        self.doc, self.out, self.episodes, self.metrics = doc, out, episodes, metrics

    def table(self, name: str, frame: pd.DataFrame, caption: str, digits: int = 2) -> None:
        frame.to_csv(self.out / "tables" / f"{name}.csv")
        self.doc.table(frame, caption + f" (tables/{name}.csv)", digits)

    def figure(self, name: str) -> Path:
        return self.out / "figures" / f"{name}.png"

    def agent(self, name: str) -> pd.DataFrame:
        return self.metrics[self.metrics.agent == name]

    # -- sections -------------------------------------------------------------------------------------------------
    def overview(self, paper_dir: Path) -> None:
        m = self.metrics
        runs = m.groupby("agent").run_id.count().to_dict()
        episodes = int(m.episodes.max())
        eps = sorted(m.epsilon.unique()) if "epsilon" in m.columns else []
        self.doc.p(
            f"Results folder `{paper_dir}`: {len(m)} runs ({', '.join(f'{a}: {n}' for a, n in runs.items())}), "
            f"up to {episodes} episodes each, epsilon values {', '.join(fmt(e, 1) for e in eps) or 'none'}. "
            "A *step* is one decision (one unit of time), as in the paper; *cells* are one-cell moves (the affective "
            "agent moves 0, 1 or 2 cells per decision). The paper's numbers are as it prints them; every other number "
            "is computed "
            "from the run files by `sb3-affect report`."
        )
        truncated = int(m.truncated.sum())
        self.doc.p(f"Episodes truncated by the safety cap (20,000 decisions): {truncated}.")

    def _per_epsilon(self, column: str, how: str = "mean") -> pd.DataFrame:
        m = self.metrics
        grouped = m[m.agent.isin([STANDARD, AFFECTIVE])].groupby(["epsilon", "agent"])[column]
        table = (grouped.sum() if how == "sum" else grouped.mean()).unstack("agent")
        return table[[STANDARD, AFFECTIVE]]

    def _ttest_beside_paper(self, ours: pd.DataFrame, theirs: dict[str, tuple[float, float]]) -> pd.DataFrame:
        table = ours.rename(columns={"Variable 1": "ε-greedy (ours)", "Variable 2": "affective (ours)"})
        table["ε-greedy (paper)"] = [theirs.get(r, (math.nan, math.nan))[0] for r in table.index]
        table["affective (paper)"] = [theirs.get(r, (math.nan, math.nan))[1] for r in table.index]
        table.index.name = "t-Test: Paired Two Sample for Means"
        return table

    def table_iv(self) -> list[Claim]:
        self.doc.h("Table IV: steps per episode")
        per_eps = self._per_epsilon("decisions_per_episode")
        ttest = paired_ttest_table(per_eps[STANDARD], per_eps[AFFECTIVE])
        self.table(
            "table_iv_inputs",
            per_eps.rename_axis("epsilon"),
            "Mean steps (decisions) per episode per epsilon, over runs and episodes",
        )
        self.table(
            "table_iv",
            self._ttest_beside_paper(ttest, paper.TABLE_IV),
            "Table IV: paired t-test over the 9 epsilon values, ε-greedy = Variable 1",
        )
        self.ttest_iv = ttest
        p_two = _value(ttest, "P(T<=t) two-tail")
        claim = Claim(
            "Table IV: no significant difference in mean steps per episode (paper: 67.02 vs 56.28, P two-tail 0.44)",
            bool(p_two > 0.05),
            f"ours: {fmt(_value(ttest, 'Mean'))} vs {fmt(_value(ttest, 'Mean', 'Variable 2'))} steps per episode, "
            f"t = {fmt(_value(ttest, 't Stat'))}, P two-tail = {fmt(p_two, 3)}",
        )
        return [claim]

    def table_v(self) -> list[Claim]:
        self.doc.h("Table V: total steps before the optimal path is found")
        sums = self._per_epsilon("decisions_before_optimal", "sum")
        means = self._per_epsilon("decisions_before_optimal", "mean")
        runs = int(self.agent(AFFECTIVE).groupby("epsilon").run_id.count().max())
        self.doc.p(
            f"The paper's Table V values (~1e5) look like sums over the {runs} simulations of each epsilon "
            "(see Definitions in the docs), so the spreadsheet layout is computed on the sums; the same test on per-run "
            "means follows. Runs that never find the optimal path contribute all their steps (censored)."
        )
        inputs = pd.concat({"sum over runs": sums, "per-run mean": means}, axis=1)
        inputs.columns = pd.Index([f"{pair[1]} ({pair[0]})" for pair in inputs.columns.to_list()])
        self.table("table_v_inputs", inputs.rename_axis("epsilon"), "Steps (decisions) before the optimal path, per epsilon")
        ttest = paired_ttest_table(sums[STANDARD], sums[AFFECTIVE])
        self.table(
            "table_v", self._ttest_beside_paper(ttest, paper.TABLE_V), "Table V (sums over runs), ε-greedy = Variable 1"
        )
        ttest_mean = paired_ttest_table(means[STANDARD], means[AFFECTIVE])
        self.table("table_v_per_run_mean", self._ttest_beside_paper(ttest_mean, {}), "Table V on per-run means")
        mean_std, mean_aff = _value(ttest, "Mean"), _value(ttest, "Mean", "Variable 2")
        p_one = _value(ttest, "P(T<=t) one-tail")
        claim = Claim(
            "Table V: the affective agent needs significantly fewer steps before finding the optimal path "
            "(paper: 110,190 vs 99,358, P one-tail 0.01)",
            bool(mean_aff < mean_std and p_one < 0.05),
            f"ours (sums over runs): {fmt(mean_std)} vs {fmt(mean_aff)}, t = {fmt(_value(ttest, 't Stat'))}, "
            f"P one-tail = {fmt(p_one, 3)}",
        )
        self.sums_v = sums
        return [claim]

    def figures_3_4(self) -> None:
        self.doc.h("Figures 3 and 4")
        f3 = figures.metric_vs_epsilon(
            self.metrics,
            "decisions_per_episode",
            "steps (decisions) per episode",
            "Fig. 3: steps per episode vs epsilon",
            self.figure("fig3_steps_per_episode"),
        )
        self.doc.img(f3, "Fig. 3: mean steps per episode against epsilon; band: bootstrap 95% CI over runs; dots: runs")
        f4 = figures.metric_vs_epsilon(
            self.metrics,
            "decisions_before_optimal",
            "steps before the optimal path (per run)",
            "Fig. 4: steps before the optimal path vs epsilon",
            self.figure("fig4_steps_before_optimal"),
            log=True,
        )
        self.doc.img(
            f4,
            "Fig. 4: steps before the optimal path is found, per run (the paper's totals are x runs); band: bootstrap 95% CI",
        )

    def crossover_claims(self) -> list[Claim]:
        per_eps = self._per_epsilon("decisions_per_episode")
        better_std = per_eps[STANDARD] < per_eps[AFFECTIVE]
        low = [e for e in per_eps.index if e < 0.45]
        high = [e for e in per_eps.index if e > 0.65]
        aff_wins = [fmt(e, 1) for e in per_eps.index if not better_std[e]]
        claim3 = Claim(
            "Fig. 3: the standard agent takes fewer steps per episode below epsilon 0.5 and more above 0.6",
            bool(all(better_std[e] for e in low) and all(not better_std[e] for e in high)),
            f"ours: the affective agent takes fewer steps at epsilon {', '.join(aff_wins) or 'none'}",
        )
        sums = self.sums_v
        aff_fewer = [e for e in sums.index if sums.loc[e, AFFECTIVE] < sums.loc[e, STANDARD]]
        exceptions = [fmt(e, 1) for e in sums.index if e not in aff_fewer]
        claim4 = Claim(
            "Fig. 4: the affective agent needs fewer steps before the optimal path at every epsilon except 0.7",
            bool(exceptions == ["0.7"] or (len(exceptions) <= 1 and len(aff_fewer) >= 8)),
            f"ours: fewer at {len(aff_fewer)} of {len(sums)} epsilons; not fewer at {', '.join(exceptions) or 'none'}",
        )
        return [claim3, claim4]

    def optimal_path(self) -> list[Claim]:
        self.doc.h("Episodes until the optimal path is found")
        m = self.metrics[self.metrics.agent.isin([STANDARD, AFFECTIVE])]
        rows = {}
        for (agent, eps), group in m.groupby(["agent", "epsilon"]):
            rows[(agent, eps)] = self._optimal_row(group)
        for agent in (STANDARD, AFFECTIVE):
            rows[(agent, "all")] = self._optimal_row(m[m.agent == agent])
        table = pd.DataFrame.from_dict(rows, orient="index")
        table.index = [f"{a} @ {fmt(e, 1) if e != 'all' else 'all'}" for a, e in table.index]
        table.index.name = "agent @ epsilon"
        self.table(
            "optimal_path",
            table,
            "First episode with an optimal (12-cell) path; first episode after which the "
            "greedy policy stays optimal; means over the runs that reached it",
        )
        aff = m[m.agent == AFFECTIVE]
        point, low, high = bootstrap_ci(aff.first_optimal.dropna().to_numpy())
        censored = int(aff.censored.sum())
        claim = Claim(
            "The affective agent finds the optimal path after 27.35 episodes on average",
            bool(low <= paper.EPISODES_TO_OPTIMAL <= high),
            f"ours: {fmt(point)} episodes (95% CI {fmt(low)} to {fmt(high)}; {censored} of {len(aff)} runs never found it)",
        )
        return [*self.crossover_claims(), claim]

    @staticmethod
    def _optimal_row(group: pd.DataFrame) -> dict[str, Any]:
        first = group.first_optimal.dropna()
        greedy = group.greedy_optimal_from.dropna()
        return {
            "runs": len(group),
            "first optimal episode (mean)": first.mean() if len(first) else math.nan,
            "median": first.median() if len(first) else math.nan,
            "never found": int(group.censored.sum()),
            "greedy optimal from (mean)": greedy.mean() if len(greedy) else math.nan,
            "greedy never stays optimal": int(group.greedy_optimal_from.isna().sum()),
        }

    def profile_section(self) -> list[Claim]:
        self.doc.h("Figures 5 and 6: emotion profile and equivalent epsilon")
        aff = self.episodes[self.episodes.agent == AFFECTIVE]
        prof = profile(aff)
        prof.to_csv(self.out / "tables" / "profile_per_episode.csv")
        f5 = figures.emotion_profile(prof, self.figure("fig5_emotion_profile"))
        silent = [e for e in ("joy", "sadness", "fear", "anger") if float(prof[f"{e}_mean"].max()) == 0.0]
        note = f" ({' and '.join(silent)} never occur: their lines lie on 0)" if silent else ""
        self.doc.img(f5, f"Fig. 5: fraction of decisions in each emotion, per episode, mean over the affective runs{note}")
        f6 = figures.equivalent_epsilon(prof, self.figure("fig6_equivalent_epsilon"))
        self.doc.img(f6, "Fig. 6: equivalent epsilon (fraction of random-direction decisions) per episode")
        rows = {}
        for first, last in WINDOWS:
            rows[f"episodes {first}-{last}"] = {
                name: window_mean(prof, name, first, last)
                for name in ("joy", "sadness", "fear", "anger", "equivalent_epsilon")
            }
        table = pd.DataFrame.from_dict(rows, orient="index")
        table.index.name = "window"
        self.table("profile_windows", table, "Per-episode fractions, mean over runs and over the episodes of each window", 3)
        early, late = rows["episodes 1-10"], rows["episodes 181-200"]
        last_episode = int(prof.index.max())
        late_key = "episodes 181-200"
        if last_episode < 181:
            late = {
                k: window_mean(prof, k, max(1, last_episode - 19), last_episode)
                for k in ("joy", "sadness", "fear", "anger", "equivalent_epsilon")
            }
            late_key = f"episodes {max(1, last_episode - 19)}-{last_episode}"
        emotions = ("joy", "sadness", "fear", "anger")
        dominant_early = max(emotions, key=lambda e: early[e])
        dominant_late = max(emotions, key=lambda e: late[e])
        claims = [
            Claim(
                "Fig. 6: the equivalent epsilon starts high (~0.3) and falls towards 0.1",
                bool(abs(early["equivalent_epsilon"] - 0.3) <= 0.1 and abs(late["equivalent_epsilon"] - 0.1) <= 0.05),
                f"ours: {fmt(early['equivalent_epsilon'], 3)} in episodes 1-10, "
                f"{fmt(late['equivalent_epsilon'], 3)} in {late_key}",
            ),
            Claim(
                "Fig. 5: joy dominates early, anger later",
                dominant_early == "joy" and dominant_late == "anger",
                f"ours: dominant emotion {dominant_early} in episodes 1-10 ({fmt(early[dominant_early], 3)}), "
                f"{dominant_late} in {late_key} ({fmt(late[dominant_late], 3)}); sadness and fear "
                f"{fmt(late['sadness'] + late['fear'], 3)}",
            ),
        ]
        return claims

    def learning_curves(self) -> None:
        self.doc.h("Learning curves")
        e = self.episodes
        groups = [
            (f"ε-greedy ε={fmt(eps, 1)}", e[(e.agent == STANDARD) & (e.epsilon == eps)])
            for eps in sorted(e[e.agent == STANDARD].epsilon.unique())
        ]
        groups.append((AFFECTIVE, e[e.agent == AFFECTIVE]))
        path = figures.learning_curves(e, self.figure("learning_curves"), "Steps per episode over episodes", groups)
        self.doc.img(path, "Decisions per episode over episodes: median over runs and quartile band (log scale)")

    def robust_statistics(self) -> list[Claim]:
        self.doc.h("Statistics that do not rest on pairing over epsilon")
        self.doc.p(
            "Per-run metrics; point estimates with percentile-bootstrap 95% CIs (2,000 resamples of runs, seeded): "
            "interquartile mean (IQM, the mean of the middle 50% of runs) and mean, per agent, and the probability of "
            "improvement P(affective better than ε-greedy) = P(X_aff < X_std) + P(tie)/2 over pairs of runs "
            "(0.5 = no difference). Lower is better for every metric here. `greedy_optimal_from` measures the learned "
            "policy rather than the path walked: an ε-greedy agent whose greedy policy is already optimal still rarely "
            "walks 12 greedy moves in a row at high ε, which the paper's 'optimal path found' counts against it."
        )
        m = self.metrics.copy()
        # a run whose greedy policy never stays optimal counts as one episode past its end (censored, worst rank)
        m["greedy_optimal_from"] = m.greedy_optimal_from.fillna(m.episodes + 1)
        columns = (
            "decisions_per_episode",
            "cells_per_episode",
            "decisions_before_optimal",
            "cells_before_optimal",
            "greedy_optimal_from",
        )
        claims = []
        rows = {}
        for eps in [*sorted(m.epsilon.unique()), "all"]:
            part = m if eps == "all" else m[m.epsilon == eps]
            std, aff = part[part.agent == STANDARD], part[part.agent == AFFECTIVE]
            for column in columns:
                s_iqm = bootstrap_ci(std[column].to_numpy(), "iqm")
                a_iqm = bootstrap_ci(aff[column].to_numpy(), "iqm")
                poi = bootstrap_improvement(aff[column].to_numpy(), std[column].to_numpy())
                rows[(fmt(eps, 1) if eps != "all" else "all", column)] = {
                    "ε-greedy IQM [95% CI]": _with_ci(s_iqm),
                    "affective IQM [95% CI]": _with_ci(a_iqm),
                    "P(affective better) [95% CI]": _with_ci(poi, 3),
                }
                if eps == "all":
                    verdict_word = "better" if poi[1] > 0.5 else "worse" if poi[2] < 0.5 else "no clear difference"
                    claims.append(
                        Claim(
                            f"Robust check ({column.replace('_', ' ')}, all epsilons pooled): affective better than ε-greedy",
                            bool(poi[1] > 0.5),
                            f"P(affective better) = {fmt(poi[0], 3)} (95% CI {fmt(poi[1], 3)} to {fmt(poi[2], 3)}): "
                            f"{verdict_word}; IQM {fmt(a_iqm[0])} vs {fmt(s_iqm[0])}",
                        )
                    )
        table = pd.DataFrame.from_dict(rows, orient="index")
        table.index = [f"{e} / {c}" for e, c in table.index]
        table.index.name = "epsilon / metric"
        self.table("robust_statistics", table, "IQM with bootstrap 95% CI, and probability of improvement")
        return claims

    # -- ablation and DQN -------------------------------------------------------------------------------------------
    def ablation(self, ablation_dir: Path) -> None:
        from sb3_affect.report.ablation import rank_readings

        self.doc.h("Reading ablation: which reading of the appraisal comes closest to the paper")
        episodes = load_results(ablation_dir)[1]
        if episodes.empty:
            self.doc.p(f"Skipped: {ablation_dir} holds no finished runs.")
            return
        ranking, measure = rank_readings(episodes)
        self.doc.p(measure)
        self.table("ablation_ranking", ranking.set_index("reading"), "Readings ranked by distance (closest first)", 3)
        path = figures.ablation_bars(ranking, self.figure("ablation_distance"))
        self.doc.img(path, "Distance of each reading to the paper's numbers and profile")
        best = ranking.iloc[0]
        readings = ranking.reading.tolist()
        default = "literal / episode / cells"
        place = str(readings.index(default) + 1) if default in readings else "n/a"
        self.doc.p(
            f"Closest reading: **{best.reading}** (distance {fmt(best.distance, 3)}). The default preset "
            f"({default}) ranks {place} of {len(ranking)}."
        )

    def dqn(self, dqn_dir: Path) -> None:
        self.doc.h("DQN on the same task")
        runs, episodes = load_results(dqn_dir)
        if episodes.empty:
            self.doc.p(f"Skipped: {dqn_dir} holds no finished runs.")
            return
        metrics = run_metrics(episodes, runs)
        metrics["wall_seconds"] = metrics.run_id.map(runs.set_index("run_id").wall_seconds)
        budget = {agent: None if pd.isna(cap) else int(cap) for agent, cap in zip(runs.agent, runs.max_timesteps)}
        rows = {}
        for keys, group in metrics.groupby(["agent", "epsilon"] if "epsilon" in metrics.columns else ["agent"], dropna=False):
            keys = keys if isinstance(keys, tuple) else (keys,)
            eps = keys[1] if len(keys) > 1 else None
            label = str(keys[0]) + (f" ε={fmt(eps, 1)}" if isinstance(eps, float) and not math.isnan(eps) else "")
            rows[label] = self._dqn_row(group)
        tabular = self.metrics
        for eps in sorted(metrics.epsilon.dropna().unique()) if "epsilon" in metrics.columns else []:
            part = tabular[(tabular.agent == STANDARD) & (tabular.epsilon == eps)]
            if len(part):
                rows[f"tabular ε-greedy ε={fmt(eps, 1)}"] = self._dqn_row(part)
        if len(tabular[tabular.agent == AFFECTIVE]):
            rows["tabular affective (all)"] = self._dqn_row(tabular[tabular.agent == AFFECTIVE])
        table = pd.DataFrame.from_dict(rows, orient="index")
        table.index.name = "agent"
        caps = ", ".join(f"{a}: {fmt(b) if b else 'none'}" for a, b in budget.items())
        self.doc.p(
            "SB3's DQN (MLP on one-hot cells, gamma 0.8, through the same launcher and the same episode-log columns via "
            f"`EmotionCallback`), stopped at 200 episodes or its step cap ({caps}). Budget: the tabular agents get "
            "200 episodes however many steps those take; DQN gets at most the step cap, so its late episodes may be "
            "missing (see 'episodes'). Its wall time per run is in the table: DQN pays a network update every 4 steps."
        )
        self.table("dqn", table, "DQN beside the tabular agents (means over runs)")
        groups: list[tuple[str, pd.DataFrame]] = []
        for agent_name, group in episodes.groupby("agent"):
            label = f"{agent_name!s}"
            if "epsilon" in group and group.epsilon.notna().any():
                for eps, sub in group.groupby("epsilon"):
                    groups.append((f"{label} ε={fmt(eps, 1)}", sub))
            else:
                groups.append((label, group))
        e = self.episodes
        groups.append(("tabular ε-greedy ε=0.1", e[(e.agent == STANDARD) & (e.epsilon == 0.1)]))
        groups.append((AFFECTIVE, e[e.agent == AFFECTIVE]))
        path = figures.learning_curves(episodes, self.figure("dqn_learning_curves"), "DQN vs tabular agents", groups)
        self.doc.img(
            path, "Decisions per episode: DQN (constant epsilon and SB3's default schedule) beside the tabular agents"
        )

    @staticmethod
    def _dqn_row(group: pd.DataFrame) -> dict[str, Any]:
        first = group.first_optimal.dropna()
        return {
            "runs": len(group),
            "episodes": group.episodes.mean(),
            "decisions per episode": group.decisions_per_episode.mean(),
            "first optimal episode": first.mean() if len(first) else math.nan,
            "never optimal": int(group.censored.sum()),
            "steps before optimal": group.decisions_before_optimal.mean(),
            "total steps": group.total_decisions.mean(),
            "wall s per run": group.wall_seconds.mean() if "wall_seconds" in group else math.nan,
        }

    def definitions(self) -> None:
        self.doc.h("Definitions")
        self.doc.p(
            "Steps per episode: mean decisions per episode. Optimal path: an episode whose path from start to goal is a "
            "shortest path (12 cells). Steps before the optimal path: decisions summed over the episodes before the "
            "first optimal one (all decisions for runs that never find it: censored). Greedy optimal from: the first "
            "episode after which every greedy choice from the start walks a shortest path until the end of the run. "
            "Equivalent epsilon: fraction of decisions whose direction was random (joy). Emotion profile: fraction of "
            "decisions in each emotion. Per-episode fractions are averaged over runs (docs: Definitions)."
        )


def summary_numbers(run_dir: Path) -> dict[str, float]:
    """A few headline numbers (for notes and tests)."""
    metrics = run_metrics(load_results(Path(run_dir))[1])
    return {
        f"{agent} decisions_per_episode": float(group.decisions_per_episode.mean())
        for agent, group in metrics.groupby("agent")
    } | {"runs": float(len(metrics)), "censored": float(np.sum(metrics.censored))}
