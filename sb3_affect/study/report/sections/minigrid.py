"""
The MiniGrid section of the tabular agents (experiments/minigrid.yaml, folder ``minigrid``), when its folder is present.
The deep agents' study (experiments/minigrid_dqn.yaml) has a section of its own: ``deep_minigrid``.

Per run, from its episode log: the success rate and the mean return over its last ``LAST_EPISODES`` episodes (a
success: an episode that ended at the goal, MiniGrid's reward > 0), and the env steps until its first success. Per
task and agent: rliable's interquartile mean with a 95% bootstrap CI over runs (the stratified bootstrap of one task),
the probability that the reference agent (the affective one) does better than each other agent with its CI, and the
emotion profile over training (the share of each emotion among the decisions of each fifth of the run's env steps).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
from rliable import metrics as rmetrics

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher.store import ResultsStore
from sb3_affect.study.report.estimation.bootstrap import (
    BETTER,
    EXPLORATORY_RULE,
    NOT_TOLD_APART,
    WORSE,
    bootstrap_improvement,
    bootstrap_iqm_cis,
    improvement_outcome,
)
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.reading.run_tables import load_results
from sb3_affect.study.report.rendering.document import fmt

#: The results folders of the sections: (folder, title, what it holds).
FOLDERS = (
    ("minigrid", "MiniGrid: the tabular agents", "the tabular agents on TabularMiniGrid (experiments/minigrid.yaml)"),
)
#: The episodes at the end of each run its success rate and return are read over.
LAST_EPISODES = 10
#: Training windows of the emotion profile (equal shares of the run's env steps).
WINDOWS = 5
#: The agent the probabilities of improvement compare with the others (when a folder has it).
REFERENCE = "affective"
#: Bootstrap resamples of the IQM CIs (the probability of improvement takes REPS // 5).
REPS = 1000
COLUMNS = ("episode", "decisions", "cells", "reward", "truncated", *EMOTION_NAMES)
#: The per-run scores: (column, label, higher is better).
SCORES = (("success", "success rate", True), ("return", "return", True), ("steps_to_success", "env steps to the first "
          "success", False))  # fmt: skip


def run_scores(episodes: pd.DataFrame) -> pd.DataFrame:
    """One row per run: agent, task, success rate and return over its last episodes, env steps to its first success."""
    e = episodes.sort_values(["run_id", "episode"], kind="stable")
    e = e.assign(success=(e.reward > 0) & ~e.truncated.astype(bool))
    rows = []
    for run_id, g in e.groupby("run_id", observed=True, sort=False):
        last = g.tail(LAST_EPISODES)
        steps = g.cells.cumsum().to_numpy()
        hits = np.flatnonzero(g.success.to_numpy())
        rows.append({
            "run_id": run_id, "agent": str(g.agent.iloc[0]), "task": str(g.task.iloc[0]) if "task" in g else "",
            "success": float(last.success.mean()), "return": float(last.reward.mean()),
            "steps_to_success": float(steps[hits[0]]) if len(hits) else math.nan,
        })  # fmt: skip
    return pd.DataFrame(rows)


def emotion_profile(episodes: pd.DataFrame) -> pd.DataFrame:
    """The share of each emotion per (task, agent, training window), pooled over the runs' decisions."""
    e = episodes.sort_values(["run_id", "episode"], kind="stable")
    steps = e.groupby("run_id", observed=True).cells.cumsum()
    total = e.groupby("run_id", observed=True).cells.transform("sum")
    window = np.minimum((WINDOWS * (steps - e.cells) / total.clip(lower=1)).astype(int), WINDOWS - 1) + 1
    task = e.task.astype(str) if "task" in e else pd.Series("", index=e.index)
    frame = pd.DataFrame({"task": task, "agent": e.agent.astype(str), "window": window})
    for name in EMOTION_NAMES:
        frame[name] = e[name].to_numpy(float)
    sums = frame.groupby(["task", "agent", "window"])[list(EMOTION_NAMES)].sum()
    counted = sums.sum(axis=1)
    return sums[counted > 0].div(counted[counted > 0], axis=0)


def score_table(scores: pd.DataFrame, reference: str | None) -> pd.DataFrame:
    """IQM [95% CI] of each score and P(reference better) [95% CI], per task and agent; success and return as text."""
    rows = {}
    for (task, agent), g in scores.groupby(["task", "agent"], sort=True):
        values = [g[column].to_numpy(float) for column, _, _ in SCORES]
        cis = bootstrap_iqm_cis(values, n_boot=REPS, seed=0)
        row: dict[str, object] = {"runs": len(g)}
        for (column, label, higher), data, (_, low, high) in zip(SCORES, values, cis):
            found = data[~np.isnan(data)]
            point = float(rmetrics.aggregate_iqm(found[:, None])) if len(found) else math.nan
            digits = 0 if column == "steps_to_success" else 2
            row[f"IQM {label} [95% CI]"] = f"{fmt(point, digits)} [{fmt(low, digits)}, {fmt(high, digits)}]"
            if column == "steps_to_success":
                row["runs without a success"] = int(np.isnan(data).sum())
            mine = scores[(scores.task == task) & (scores.agent == reference)][column].to_numpy(float)
            if reference is not None and agent != reference and len(mine) and len(found):
                p, lo, hi = bootstrap_improvement(mine[~np.isnan(mine)], found, REPS // 5, seed=0, lower_is_better=not higher)
                row[f"P({reference} better), {label}"] = f"{fmt(p, 2)} [{fmt(lo, 2)}, {fmt(hi, 2)}]"
        rows[(task, agent)] = row
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index.names = ["task", "agent"]
    return table.reset_index().set_index("agent")


def verdict(scores: pd.DataFrame, reference: str | None = REFERENCE) -> list[str]:
    """
    One sentence per task: what the rule allows on the success rate and on the return (``EXPLORATORY_RULE``: the
    reference agent better than, worse than, or not told apart from each other agent), then the IQMs; and why two
    agents' first successes coincide run by run where they do.
    """
    out = []
    for key, t in scores.groupby("task", sort=True):
        task = str(key)
        where = f"On {task}" if task else "Here"
        seeds = int(t.groupby("agent").size().min())
        iqm = {str(a): float(rmetrics.aggregate_iqm(g.success.to_numpy(float)[:, None])) for a, g in t.groupby("agent")}
        listing = "; ".join(f"{a} {fmt(v, 2)}" for a, v in sorted(iqm.items(), key=lambda kv: -kv[1]))
        if not reference or not (t.agent == reference).any():
            out.append(f"{where} ({seeds} seeds per agent), IQM success rates: {listing}; no reference agent to compare.")
            continue
        said = []
        for column, label in (("success", "success rate"), ("return", "return")):
            mine = t[t.agent == reference][column].to_numpy(float)
            found: dict[str, list[str]] = {BETTER: [], WORSE: [], NOT_TOLD_APART: []}
            for agent, g in t[t.agent != reference].groupby("agent", sort=True):
                _, low, high = bootstrap_improvement(mine, g[column].to_numpy(float), REPS // 5, seed=0, lower_is_better=False)
                found[improvement_outcome(low, high)].append(str(agent))
            parts = [f"{reference} better than {', '.join(found[BETTER])}" if found[BETTER] else "",
                     f"worse than {', '.join(found[WORSE])}" if found[WORSE] else "",
                     f"not told apart from {', '.join(found[NOT_TOLD_APART])}" if found[NOT_TOLD_APART] else ""]  # fmt: skip
            said.append(f"on the {label}, {'; '.join(p for p in parts if p)}")
        out.append(
            f"{where}, {seeds} seeds per agent allow this {'; '.join(said)} (the rule: {EXPLORATORY_RULE}). IQM success "
            f"rates over the last {LAST_EPISODES} episodes: {listing}."
        )
        out += twin_sentences(t)
    return out


def twin_sentences(t: pd.DataFrame) -> list[str]:
    """Agents whose env steps to the first success are equal run by run, and why (same seeds, all-zero Q-values)."""
    out = []
    agents = sorted(t.agent.unique())
    for i, a in enumerate(agents):
        for b in agents[i + 1 :]:
            left = t[t.agent == a].sort_values("run_id").steps_to_success.to_numpy(float)
            right = t[t.agent == b].sort_values("run_id").steps_to_success.to_numpy(float)
            if len(left) == len(right) and len(left) and np.array_equal(left, right, equal_nan=True):
                out.append(
                    f"{a} and {b} take the same env steps to their first success in every run: until the goal is first "
                    "reached every Q-value is 0, so a greedy move is a tie broken at random and draws the same move as "
                    "a random one; with the same seeds both behaviour tables walk the same path up to that success."
                )
    return out


def minigrid_sections(ctx: ReportContext) -> None:
    """A section for each MiniGrid results folder present (``FOLDERS``), and where the missing ones would come from."""
    for name, title, holds in FOLDERS:
        if name in ctx.folders:
            minigrid_section(ctx, name, title, holds)
    if "minigrid" in ctx.folders and ResultsStore(ctx.root / "minigrid_dqn").study_kind() != "deep":
        ctx.doc.p(
            "The deep study (DQN, AffectDQN and their controls on MiniGrid) is not part of this folder: "
            "`make replicate` runs it at smoke size only. `sb3-affect run experiments/minigrid_dqn.yaml --out "
            "DIR/minigrid_dqn`, then `sb3-affect report DIR`, adds its section."
        )


def minigrid_section(ctx: ReportContext, name: str, title: str, holds: str) -> None:
    results = load_results(ctx.folders[name], columns=COLUMNS)
    ctx.doc.h(title)
    if results.episodes.empty:
        ctx.doc.p(f"Skipped: {ctx.folders[name]} holds no finished runs.")
        return
    episodes = results.episodes
    scores = run_scores(episodes)
    reference = REFERENCE if (scores.agent == REFERENCE).any() else None
    runs = results.runs
    budget = runs.max_timesteps.dropna()
    ctx.doc.p(
        f"{len(scores)} runs of {holds}, {len(set(runs.seed))} seeds per agent and task"
        + (f", {fmt(int(budget.max()))} steps each" if len(budget) else "")
        + f". Success rate and return: over each run's last {LAST_EPISODES} episodes (a success ends at the goal; "
        "MiniGrid's return is 1 - 0.9 x steps / max steps there, 0 otherwise). IQM: rliable's interquartile mean over "
        f"runs, with a 95% bootstrap CI ({REPS:,} resamples of runs within each task)"
        + (
            f"; P({reference} better): the probability that a run of {reference} scores better than a run of the agent "
            "(ties count half), with its bootstrap CI."
            if reference
            else "."
        )
    )
    ctx.table(f"{name}_scores", score_table(scores, reference), f"{title}: scores per task and agent")
    for sentence in verdict(scores, reference):
        ctx.doc.p(sentence)
    profile = emotion_profile(episodes)
    if len(profile):
        shown = profile.reset_index()
        shown["window"] = shown.window.map(lambda w: f"{w}/{WINDOWS}")
        ctx.table(
            f"{name}_emotions", shown.set_index("agent"),
            f"{title}: the share of each emotion among the decisions of each fifth of training (pooled over runs)",
        )  # fmt: skip
