"""
The deep study's section (a sweep file with a ``trainer``, run by the launcher, ``launcher.deep_batches``): read
through the results store (``ResultsStore.evaluations``) from each deep-study folder present (``FOLDERS`` of a
replicate folder, or the report's folder itself), never run.

The primary metric is the greedy policy's: each seed's Q-network, every ``evaluation.every`` env steps, acting greedily
for one episode on each of ``evaluation.episodes`` evaluation envs seeded apart from its training envs; its success rate and
mean return. Per run they are summarised as the area under the curve (the mean of its evaluations: the area under the
step curve divided by the budget) and the final value; per agent and task as the IQM over runs with a 95% bootstrap CI
(rliable's IQM, the percentile bootstrap of ``report.estimation.bootstrap``). Steps to the first training episode that
reached the goal are time-to-event data: a run that never reached it is censored at its budget (Kaplan-Meier,
lifelines). The number of seeds is checked by a power calculation for the final success rate, and one sentence per task
is computed from the CIs. Figures: the greedy success and return curves per task, the random share and the emotion
profile over training.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from rliable import metrics as rmetrics
from scipy import stats as sps

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher.deep_schema import STUDY_EVAL_EPISODES
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
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.rendering.figures import COLOURS, STYLES, distinct, save
from sb3_affect.study.report.sections.survival import km

#: Deep-study folders of a replicate folder, in the order their sections appear: the study, its tuning, its smoke size.
FOLDERS = ("minigrid_dqn", "minigrid_dqn_tuning", "deep_smoke")
#: The agent the others are compared with, when the study has it.
REFERENCE = "dqn-linear"
#: Seeds per cell the study's design asks for.
STUDY_SEEDS = 20
#: The power calculation: a two-sided test of two proportions at ALPHA with POWER, from BASE to TARGET final success.
ALPHA, POWER, BASE, TARGET = 0.05, 0.8, 0.5, 0.8
#: Bootstrap resamples of the IQM's CIs.
REPS = 2000
#: The per-run scores, as the IQM table shows them.
SCORES = (("auc_success", "success AUC"), ("final_success", "final success"), ("auc_return", "return AUC"),
          ("final_return", "final return"))  # fmt: skip


@dataclass
class DeepResults:
    """A deep-study folder read: the study's settings and one record per finished cell, in the study's order."""

    folder: Path
    study: dict[str, Any]
    cells: list[dict[str, Any]]

    @property
    def smoke(self) -> bool:
        """Fewer evaluation episodes than the study's: a check of the pipeline (the main job's version)."""
        return self.study["evaluation"]["episodes"] < STUDY_EVAL_EPISODES

    @property
    def few_seeds(self) -> bool:
        """Fewer seeds per cell than the study's: a tuning pass or a pilot."""
        return len(self.study["seeds"]) < STUDY_SEEDS


def load_deep(folder: Path) -> DeepResults:
    """
    The study and its finished cells (``ResultsStore.evaluations``), in the order of tasks, then agents; ``StoreError``
    naming the first file that does not count (a rerun sets it aside).
    """
    store = ResultsStore(folder)
    saved: dict[str, Any] = store.saved_sweep() or {}  # (deep_folders: there is one)
    tasks = saved["sweep"]["tasks"]  # (sweep.json sorts a mapping's keys: the file's order is its task_order)
    study = {**saved["sweep"], "tasks": {task: tasks[task] for task in saved.get("task_order") or tasks}}
    return DeepResults(folder, study, list(store.evaluations().values()))


def deep_folders(root: Path) -> list[Path]:
    """The deep-study folders a report of ``root`` shows: ``root`` itself, or those of ``FOLDERS`` in it."""
    if ResultsStore(root).study_kind() == "deep":
        return [root]
    return [root / name for name in FOLDERS if ResultsStore(root / name).study_kind() == "deep"]


# -- numbers -------------------------------------------------------------------------------------------------------------
def run_scores(results: DeepResults) -> pd.DataFrame:
    """One row per run: its task, agent, seed, the AUC and final value of greedy success and return, its first success."""
    rows = []
    for cell in results.cells:
        success = np.asarray(cell["success"], dtype=float)
        returns = np.asarray(cell["return"], dtype=float)
        for index, seed in enumerate(cell["seeds"]):
            first = cell["first_success"][index]
            greedy = np.flatnonzero(success[index] > 0)
            rows.append({
                "task": cell["task"], "agent": cell["agent"], "seed": seed, "budget": cell["budget"],
                "auc_success": success[index].mean(), "final_success": success[index, -1],
                "auc_return": returns[index].mean(), "final_return": returns[index, -1],
                "first_success": float(cell["budget"] if first is None else first), "reached": first is not None,
                "first_greedy": float(cell["eval_steps"][greedy[0]] if len(greedy) else cell["budget"]),
                "greedy_reached": bool(len(greedy)),
            })  # fmt: skip
    return pd.DataFrame(rows)


def iqm_table(scores: pd.DataFrame, order: list[str]) -> pd.DataFrame:
    """IQM over runs with its 95% bootstrap CI, per task and agent, for each score of ``SCORES``."""
    rows = []
    for (task, agent), runs in scores.groupby(["task", "agent"], sort=False):
        row: dict[str, Any] = {"task": task, "agent": agent, "runs": len(runs)}
        for column, label in SCORES:
            values = runs[column].to_numpy(float)
            ((_, low, high),) = bootstrap_iqm_cis([values], n_boot=REPS)
            row[label], row[f"{label} low"], row[f"{label} high"] = float(rmetrics.aggregate_iqm(values[:, None])), low, high
        rows.append(row)
    table = pd.DataFrame(rows)
    if len(table):  # the study's order: its tasks, then its agents
        tasks = list(dict.fromkeys(scores.task))
        agents = table.agent.map(lambda agent: order.index(agent) if agent in order else len(order))
        rank = table.task.map(tasks.index) * (len(order) + 1) + agents
        table = table.iloc[np.argsort(rank.to_numpy(), kind="stable")]
    return table.set_index(["task", "agent"])


#: The two clocks of the first success: (column of the run's step, column of whether it happened, what it is).
CLOCKS = (("first_success", "reached", "training episode (behaviour policy, warm-up included)"),
          ("first_greedy", "greedy_reached", "greedy evaluation (the first with a success)"))  # fmt: skip


def first_success_table(scores: pd.DataFrame) -> pd.DataFrame:
    """
    Env steps to the first success on each clock (``CLOCKS``): runs, reached, censored, Kaplan-Meier median (95% CI),
    RMST up to the budget; a run that never succeeded is censored at its budget.
    """
    rows = []
    for column, happened, clock in CLOCKS:
        for (task, agent), runs in scores.groupby(["task", "agent"], sort=False):
            horizon = float(runs.budget.max())
            estimate = km(runs[column].to_numpy(), runs[happened].to_numpy(), horizon)

            def shown(value: float, horizon: float = horizon) -> str:
                return f"> {fmt(horizon)}" if math.isinf(value) or math.isnan(value) else fmt(value)

            rows.append({
                "first success of": clock, "task": task, "agent": agent, "runs": len(runs),
                "reached": int(runs[happened].sum()), "censored": int((~runs[happened]).sum()),
                "KM median": shown(estimate["median"]),
                "median 95% CI": f"[{shown(estimate['median_low'])}, {shown(estimate['median_high'])}]",
                "RMST": estimate["rmst"],
            })  # fmt: skip
    return pd.DataFrame(rows).set_index(["first success of", "task", "agent"])


def seeds_needed(alpha: float = ALPHA, power: float = POWER, base: float = BASE, target: float = TARGET) -> int:
    """Runs per agent for a two-sided test of two proportions (Cohen's h, normal approximation) to detect base -> target."""
    h = abs(2 * math.asin(math.sqrt(target)) - 2 * math.asin(math.sqrt(base)))
    z = sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)
    return math.ceil((z / h) ** 2)


def detectable(n: int, alpha: float = ALPHA, power: float = POWER, base: float = BASE) -> float:
    """The final success rate above ``base`` that ``n`` runs per agent detect with ``power`` (the inverse of the above)."""
    z = sps.norm.ppf(1 - alpha / 2) + sps.norm.ppf(power)
    angle = 2 * math.asin(math.sqrt(base)) + z / math.sqrt(n)
    return 1.0 if angle >= math.pi else math.sin(angle / 2) ** 2


def power_sentence(n: int) -> str:
    needed = seeds_needed()
    return (
        f"Power: to detect a final greedy success rate of {TARGET:g} against {BASE:g} (two-sided test of two proportions, "
        f"alpha = {ALPHA:g}, power {POWER:g}, Cohen's h) needs {needed} runs per agent and task; this study has {n}, which "
        f"detects {fmt(detectable(n))} against {BASE:g} with that power"
        + ("." if n >= needed else ": fewer runs than that calculation asks for.")
    )


def shown_iqm(table: pd.DataFrame) -> pd.DataFrame:
    """The IQM table as the report shows it: each score with its CI as one "[low, high]" column."""
    shown = table[["runs"]].copy()
    for _, label in SCORES:
        shown[label] = table[label]
        bounds = zip(table[f"{label} low"], table[f"{label} high"])
        shown[f"{label} CI"] = [f"[{fmt(low)}, {fmt(high)}]" for low, high in bounds]
    return shown.reset_index().set_index("task")


def comparison(scores: pd.DataFrame, task: str, agent: str, other: str, column: str = "auc_success") -> str | None:
    """
    ``EXPLORATORY_RULE`` on ``column``'s per-run values: ``agent`` better than, worse than, or not told apart from
    ``other`` on ``task`` (None: one of them has no runs there).
    """
    mine, theirs = (scores[(scores.task == task) & (scores.agent == name)][column].to_numpy(float) for name in (agent, other))
    if not len(mine) or not len(theirs):
        return None
    _, low, high = bootstrap_improvement(mine, theirs, REPS // 5, seed=0, lower_is_better=False)
    return improvement_outcome(low, high)


def verdict(scores: pd.DataFrame, study: dict[str, Any]) -> list[str]:
    """One sentence per task, by the rule of every exploratory section on the per-run greedy success AUC: each agent
    against the reference, each replay control against the agent it replays."""
    out = []
    agents = [agent["name"] for agent in study["agents"]]
    words = {BETTER: "above", WORSE: "below", NOT_TOLD_APART: "not told apart from"}
    for task in list(dict.fromkeys(scores.task)) if len(scores) else []:
        parts = []
        if REFERENCE in agents:
            groups: dict[str, list[str]] = {BETTER: [], WORSE: [], NOT_TOLD_APART: []}
            for agent in agents:
                found = comparison(scores, task, agent, REFERENCE) if agent != REFERENCE else None
                if found:
                    groups[found].append(agent)
            said = [f"{', '.join(groups[k])} {words[k]}{' it' if k == NOT_TOLD_APART else ''}" for k in groups if groups[k]]
            if said:
                parts.append(f"against {REFERENCE}: " + "; ".join(said))
        for agent in study["agents"]:
            if agent.get("replays"):
                found = comparison(scores, task, agent["name"], agent["replays"])
                if found:
                    parts.append(f"{agent['name']} (the same amount of randomness, uniform in time) {words[found]} "
                                 f"{agent['replays']}")
        if parts:
            out.append(f"On {task}, by the greedy success AUC per run (the rule: {EXPLORATORY_RULE}): "
                       + "; ".join(parts) + ".")
    return out


# -- figures -------------------------------------------------------------------------------------------------------------
def _agent_styles(agents: list[str]) -> dict[str, tuple[Any, str]]:
    palette = distinct(len(agents))
    return {agent: (COLOURS.get(agent, palette[i]), STYLES[i % len(STYLES)]) for i, agent in enumerate(agents)}


def _curves(results: DeepResults, key: str) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """(task, agent) -> (eval steps, the mean over seeds of ``key`` at each evaluation)."""
    out = {}
    for cell in results.cells:
        values = np.asarray(cell[key], dtype=float)
        with np.errstate(invalid="ignore"):
            out[(cell["task"], cell["agent"])] = (np.asarray(cell["eval_steps"]), np.nanmean(values, axis=0))
    return out


def curves_figure(results: DeepResults, key: str, ylabel: str, path: Path) -> Path:
    """One panel per task: ``key`` (mean over seeds) against env steps, one line per agent."""
    tasks = list(results.study["tasks"])
    agents = [agent["name"] for agent in results.study["agents"]]
    styles = _agent_styles(agents)
    fig, axes = plt.subplots(1, len(tasks), figsize=(4.2 * len(tasks), 3.6), squeeze=False)
    curves = _curves(results, key)
    for ax, task in zip(axes[0], tasks):
        for agent in agents:
            if (task, agent) in curves:
                steps, mean = curves[(task, agent)]
                colour, style = styles[agent]
                ax.plot(steps, mean, color=colour, ls=style, lw=1.4, label=agent)
        ax.set_title(task)
        ax.set_xlabel("env steps")
        ax.set_ylabel(ylabel)
    axes[0][0].legend(fontsize=6)
    return save(fig, path)


def emotions_figure(results: DeepResults, path: Path) -> Path | None:
    """The emotion profile over training: per task and affective agent, each emotion's share of the env steps."""
    cells = [cell for cell in results.cells if cell.get("emotions")]
    if not cells:
        return None
    tasks = list(dict.fromkeys(cell["task"] for cell in cells))  # a row per task, a column per affective agent
    agents = list(dict.fromkeys(cell["agent"] for cell in cells))
    fig, axes = plt.subplots(len(tasks), len(agents), figsize=(3.2 * len(agents), 2.6 * len(tasks)), squeeze=False)
    for row in axes:
        for ax in row:
            ax.set_visible(False)
    for cell in cells:
        ax = axes[tasks.index(cell["task"])][agents.index(cell["agent"])]
        ax.set_visible(True)
        steps = np.asarray(cell["eval_steps"])
        for name in EMOTION_NAMES:
            with np.errstate(invalid="ignore"):
                share = np.nanmean(np.asarray(cell["emotions"][name], dtype=float), axis=0)
            ax.plot(steps, share, color=COLOURS[name], label=name)
        ax.set_ylim(0, 1)
        ax.set_title(f"{cell['task']}: {cell['agent']}", fontsize=8)
        ax.set_xlabel("env steps")
        ax.xaxis.set_major_formatter(lambda x, _: f"{x / 1000:g}k")
    axes[0][0].set_ylabel("share of env steps (mean over seeds)")
    axes[0][0].legend(fontsize=6)
    return save(fig, path)


# -- the section ---------------------------------------------------------------------------------------------------------
def deep_minigrid_section(ctx: ReportContext) -> None:
    """A section for each deep-study folder found (``deep_folders``)."""
    for folder in deep_folders(ctx.root):
        deep_section(ctx, load_deep(folder))


def deep_section(ctx: ReportContext, results: DeepResults) -> None:
    study, name = results.study, results.folder.name
    n, n_eval, trainer = len(study["seeds"]), study["evaluation"]["episodes"], study["trainer"]
    ctx.doc.h(f"Deep agents on MiniGrid, greedy policies{' (smoke size)' if results.smoke else ''}: {name}/")
    if results.smoke:
        ctx.doc.p(
            f"Smoke size: {n} seeds per cell and {n_eval} evaluation episodes, below the study's design "
            f"({STUDY_SEEDS} seeds, {STUDY_EVAL_EPISODES} episodes): these numbers show the pipeline works end to end, "
            "they do not answer whether the emotions help. The study itself: experiments/minigrid_dqn.yaml."
        )
    elif results.few_seeds:
        ctx.doc.p(f"{n} seeds per cell, fewer than the study's {STUDY_SEEDS}: a tuning pass or a pilot, whose CIs are wide.")
    if not results.cells:
        ctx.doc.p(f"Skipped: {results.folder} holds no finished cells.")
        return
    budgets = ", ".join(f"{task} {fmt(spec['total_timesteps'])}" for task, spec in study["tasks"].items())
    ctx.doc.p(
        f"{len(results.cells)} cells (task x agent) of {n} seeds, {trainer['n_envs']} training envs per seed, "
        f"{trainer['obs']} observations, {trainer['vec_env']} envs; budgets in env steps: {budgets}. Every "
        f"{fmt(study['evaluation']['every'])} "
        f"env steps each seed's greedy policy plays one episode on each of {n_eval} evaluation envs of its own; success "
        "is reaching the goal, return is MiniGrid's (1 - 0.9 x steps / max steps at the goal, else 0), without any "
        "exploration bonus. AUC: the mean of a run's evaluations; IQM (rliable's interquartile mean) over runs with a "
        f"95% percentile bootstrap CI ({REPS} resamples of the runs)."
    )
    ctx.doc.p(power_sentence(n))
    scores = run_scores(results)
    order = [agent["name"] for agent in study["agents"]]
    table = iqm_table(scores, order)
    caption = "Greedy success and return per task and agent: IQM over runs [95% CI]"
    ctx.table(f"{name}_iqm", shown_iqm(table), caption)
    for sentence in verdict(scores, study):
        ctx.doc.p(sentence)
    ctx.doc.img(curves_figure(results, "success", "greedy success (mean over seeds)", ctx.figure(f"{name}_success")),
                "Greedy success against env steps, per task (mean over seeds)")
    ctx.doc.img(curves_figure(results, "return", "greedy return (mean over seeds)", ctx.figure(f"{name}_return")),
                "Greedy return against env steps, per task (mean over seeds)")
    ctx.table(
        f"{name}_first_success", first_success_table(scores).reset_index().set_index("first success of"),
        "Env steps to the first success, of a training episode and of the greedy policy: runs that never succeeded are "
        "censored at the budget (Kaplan-Meier median with its 95% CI; RMST: the mean restricted to the budget)",
    )  # fmt: skip
    ctx.doc.img(curves_figure(results, "random_share", "random share (mean over seeds)", ctx.figure(f"{name}_random")),
                "Share of random decisions since the previous evaluation (ε for DQN; after learning_starts)")
    emotions = emotions_figure(results, ctx.figure(f"{name}_emotions"))
    if emotions is not None:
        ctx.doc.img(emotions, "The emotion profile over training: each emotion's share of the env steps since the "
                    "previous evaluation (mean over seeds)")
