"""
The fair-baselines report section: every agent ranked on decisions per episode, cells per episode and steps before the
optimal path (bootstrap 95% CIs), on the static task and on moving prey, and the personalities' emotion profiles.

The numbers come from ``report.reading.baseline_ranks`` (definitions there and in docs/beyond_the_paper.md); this module
only assembles the markdown, so the report build can add it::

    from sb3_affect.study.report.sections.beyond import baselines_section
    text = baselines_section(["runs/baselines", "runs/baselines_moving7", "runs/baselines_moving"])
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from sb3_affect.study.report.estimation.bootstrap import bootstrap_ci
from sb3_affect.study.report.reading.baseline_ranks import (
    clearly_better,
    emotion_profile,
    focus_ranks,
    markdown,
    profile_markdown,
    summarise,
)
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.reading.run_tables import load_run_records
from sb3_affect.study.report.reading.study_tables import episode_cap, study
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.sections.reproducibility import part_time
from sb3_affect.study.report.sections.tuning import tuning_section

__all__ = ["baselines_section", "beyond_section"]

#: Fair-baselines results folders a replicate folder may hold (experiments/baselines*.yaml).
BASELINE_FOLDERS = ("baselines", "baselines_moving7", "baselines_moving")

INTRO = (
    "The paper's baseline is epsilon-greedy averaged over epsilon 0.1 to 0.9. Here every agent runs on the same seeds "
    "beside tuned baselines (epsilon, temperature and UCB coefficient chosen on separate seeds), a decaying epsilon, "
    "optimistic initial values, and epsilon-greedy moving 1 or 2 cells a decision like the affective agent. Means over "
    "runs with percentile-bootstrap 95% confidence intervals; ranked by decisions per episode. On moving prey, optimal "
    "means a capture within the prey's starting distance (docs/beyond_the_paper.md)."
)


def baselines_section(
    run_dirs: Sequence[str | Path],
    title: str = "Beyond the paper: fair baselines and moving prey",
    ranks: dict[str, tuple[int, int, int]] | None = None,
    ranks_before: dict[str, tuple[int, int, int]] | None = None,
) -> str:
    """
    The section as markdown (empty string when none of ``run_dirs`` holds runs).

    :param ranks: filled with the affective agent's rank on decisions per episode per task, the number of agents
        and how many of them are ahead with non-overlapping 95% CIs (``focus_ranks``, ``clearly_better``)
    :param ranks_before: the same on steps before the optimal path (Table V's metric)
    """
    records = [record for folder in run_dirs if Path(folder).exists() for record in load_run_records(folder)]
    if not records:
        return ""
    summary = summarise(records)
    for found, metric in ((ranks, "decisions_per_episode"), (ranks_before, "steps_before_optimal")):
        if found is not None:
            ahead = clearly_better(summary, metric=metric)
            found.update({task: (*rank, ahead.get(task, 0)) for task, rank in focus_ranks(summary, metric=metric).items()})
    text = f"## {title}\n\n{INTRO}\n\n{markdown(summary)}"
    profile = emotion_profile(records)
    if len(profile):
        text += "\nPersonalities (a bias on the appraisal's norm: optimistic 0.8, pessimistic 1.25). " + profile_markdown(
            profile
        )
    return text


def ci_text(values: np.ndarray, digits: int = 1) -> str:
    """``values``' mean and bootstrap 95% CI, ``mean [low, high]`` ("" when there are none)."""
    point, low, high = bootstrap_ci(values)
    return "" if math.isnan(point) else f"{fmt(point, digits)} [{fmt(low, digits)}, {fmt(high, digits)}]"


def agent_names(m: pd.DataFrame) -> pd.Series:
    """Each run's agent as the report names it: a tuned agent with its ε, ``epsilon-greedy, tuned ε (0.05)``."""
    if "epsilon" not in m.columns:
        return m.agent.astype(str)
    eps = pd.to_numeric(m.epsilon, errors="coerce")
    return pd.Series([f"{a} ({e:g})" if e == e else str(a) for a, e in zip(m.agent, eps)], index=m.index, name="agent")


def beyond_table(m: pd.DataFrame) -> pd.DataFrame:
    rows = {}
    m = m.assign(agent=agent_names(m))
    for (task, agent), g in m.groupby(["task", "agent"], sort=False):
        rows[(task, agent)] = {
            "runs": len(g),
            "decisions per episode [95% CI]": ci_text(g.decisions_per_episode.to_numpy(float)),
            "cells per episode": g.cells_per_episode.mean(),
            "first optimal episode (mean of found)": g.first_optimal.mean(),
            "never optimal": int(g.censored.sum()),
            "truncated episodes": int(g.truncated.sum()),
            "decisions before optimal [95% CI]": ci_text(g.decisions_before_optimal.to_numpy(float), 0),
            "joy share of decisions, episodes 181-200": g.joy_181_200_weighted.mean(),
        }
    table = pd.DataFrame.from_dict(rows, orient="index")
    table.index = [f"{t} / {a}" for t, a in table.index]
    table.index.name = "task / agent"
    return table


def beyond_section(ctx: ReportContext) -> None:
    """The static grid, moving and evading prey and mazes with ε tuned per task (experiments/beyond.yaml), then the fair
    baselines."""
    ctx.doc.h("Beyond the paper: moving prey, evading prey, mazes and fair baselines")
    found = study(ctx.root, "beyond")
    if found is None:
        ctx.doc.p("No moving-prey, evading-prey or maze results in this folder (`sb3-affect replicate` runs them).")
    else:
        m, meta = found
        tuned = "epsilon" in m.columns and m.epsilon.notna().any()
        cap = episode_cap(meta["sweep"])
        ctx.doc.p(
            f"Each task, {meta['seeds']:,} seeds per agent, {meta['episodes']} episodes (launcher runs in "
            f"{ctx.root / 'beyond'}; {part_time(ctx, 'beyond', meta)}). Static grid: the paper's "
            "task (15 x 15, goal at (6, 6)). Moving prey: the hunter "
            "starts at (0, 0), the prey at (3, 3) and moves after every cell the hunter moves, with probability 0.5, at "
            "random or away from the hunter (evading): once per cell, so a 2-cell decision gives the prey two chances to "
            "move; optimal means a capture within the prey's starting distance. Mazes: shipped maps `wall` (shortest "
            f"path 24) and `rooms` (21), static goal. Episodes are cut at {cap or 0:,} decisions: a truncated "
            "episode's length is a lower bound, so where a row has truncated episodes its means are restricted means, "
            "lower bounds of the uncapped means (counted in the table). "
            + (
                "ε-greedy and the speed-matched ε-greedy run with the ε tuned on each task (the value in "
                "brackets); ε-greedy 0.1 is the paper's kind of baseline. "
                if tuned
                else "This folder's ε-greedy agents were not tuned per task. "
            )
            + "Means over runs with bootstrap 95% CIs; lower is better; ranked in decisions (time) and in cells "
            "(distance)."
        )
        ctx.table("beyond", beyond_table(m), "Tasks beyond the paper")
        ranks = []
        for task, g in m.assign(agent=agent_names(m)).groupby("task", sort=False):
            parts = []
            for column, unit in (("decisions_per_episode", "decisions"), ("cells_per_episode", "cells")):
                means = g.groupby("agent")[column].mean().sort_values()
                place = list(means.index).index("affective") + 1 if "affective" in means.index else 0
                parts.append(
                    f"fewest {unit} per episode {means.index[0]} ({fmt(float(means.iloc[0]), 1)}), affective ranks "
                    f"{place} of {len(means)} ({fmt(float(means.get('affective', math.nan)), 1)})"
                )
            truncated = g.groupby("agent").truncated.sum()
            truncated = truncated[truncated > 0]
            note = (
                " (truncated episodes, means are lower bounds: "
                + ", ".join(f"{agent} {int(n):,}" for agent, n in truncated.items())
                + ")"
                if len(truncated)
                else ""
            )
            ranks.append(f"{task}: " + "; in cells: ".join(parts) + note)
        ctx.doc.ul(ranks)
        tuning_section(ctx, m)
    dirs = [ctx.root / name for name in BASELINE_FOLDERS if (ctx.root / name / "runs").is_dir()]
    if dirs:
        title = "Fair baselines: tuned, decaying, optimistic and speed-matched agents"
        places: dict[str, tuple[int, int, int]] = {}
        before: dict[str, tuple[int, int, int]] = {}
        ctx.doc.md(baselines_section(dirs, title=title, ranks=places, ranks_before=before).replace("## ", "### ", 1))
        ctx.cache["baseline ranks"] = places
        ctx.cache["baseline ranks before optimal"] = before
