"""
How ε is tuned on each task beyond the paper, for ε-greedy and the speed-matched ε-greedy, on seeds disjoint from the
evaluation seeds: the planning rule ``sb3_affect.study.replicate`` runs the tuning rounds with (``tune``), as pure
functions over the tables of its rounds; the report reads the rounds back with the same ``tune``
(``report.sections.tuning.load_tuning``).

Criterion: mean decisions per episode over the run (lower is better), each episode counted at most the sweep's
``max_episode_decisions``: a truncated episode's length is a lower bound, so the criterion is a restricted mean (the
mean of min(length, cap)), and the tuning curve counts the truncated episodes beside it. The grid
(experiments/tuning.yaml) is log-spaced; when the best value is at an edge of the values run, one more value one grid
step further out is run (``extension``), up to ``MAX_EXTENSIONS`` times and within ``RANGE``; a best value still at an
edge is reported as such, never as interior. The same tuning seeds serve every ε of a (task, agent), so the curve's
differences are paired (common random numbers). Results: ``DIR/round<k>/``, results folders of the launcher (the grid
first, then the extensions).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

#: The values an extension may try: ε in [1e-4, 1] (1: a uniform random walk).
RANGE = (1e-4, 1.0)
#: Extensions of the grid at most (one value each, one grid step beyond the edge the best value sits on).
MAX_EXTENSIONS = 3
CRITERION = "decisions_per_episode"


def extension(values: Iterable[float], best: float) -> float | None:
    """
    The next ε to run when ``best`` is at an edge of ``values``: one grid step (the ratio of the two edge values)
    beyond it, kept within ``RANGE``; None when ``best`` is inside, or at the end of ``RANGE``.
    """
    run = sorted(set(float(v) for v in values))
    if len(run) < 2:
        raise ValueError(f"a tuning curve needs at least 2 values, got {run}")
    if best not in run:
        raise ValueError(f"best={best} is not one of the values run {run}")
    if best == run[0] and run[0] > RANGE[0]:
        return float(f"{max(RANGE[0], run[0] * run[0] / run[1]):.3g}")
    if best == run[-1] and run[-1] < RANGE[1]:
        return float(f"{min(RANGE[1], run[-1] * run[-1] / run[-2]):.3g}")
    return None


def tuning_curve(runs: pd.DataFrame) -> pd.DataFrame:
    """
    Per ε (index, ascending): runs, mean decisions per episode with a normal 95% CI, mean cells per episode,
    truncated episodes, and the paired difference from the best ε (same seeds) with its 95% CI.

    :param runs: one row per run of one (task, agent): ``epsilon``, ``replicate`` and ``run_metrics``' columns
    """
    if not len(runs):
        raise ValueError("no tuning runs")
    groups = runs.groupby("epsilon")
    curve = pd.DataFrame(
        {
            "runs": groups.size(),
            "mean": groups[CRITERION].mean(),
            "se": groups[CRITERION].std(ddof=1) / np.sqrt(groups.size()),
            "cells": groups["cells_per_episode"].mean(),
            "truncated": groups["truncated"].sum().astype(int),
        }
    ).sort_index()
    curve.index = curve.index.astype(float)
    curve.index.name = "epsilon"
    best = best_value(curve)
    wide = runs.pivot_table(index="replicate", columns="epsilon", values=CRITERION)
    wide.columns = wide.columns.astype(float)
    diff = wide.sub(wide[best], axis=0)
    n = diff.notna().sum()
    half = 1.96 * diff.std(ddof=1) / np.sqrt(n)
    curve["vs best"] = diff.mean()
    curve["vs best low"] = curve["vs best"] - half
    curve["vs best high"] = curve["vs best"] + half
    curve.loc[best, ["vs best low", "vs best high"]] = 0.0
    return curve


@dataclass(frozen=True)
class Tuning:
    """
    One (task, agent) tuned.

    :param task: the task's label
    :param agent: the agent's name
    :param curve: ``tuning_curve`` of every value run
    :param best: the ε with the lowest mean decisions per episode
    :param interior: whether ``best`` lies strictly inside the values run
    :param added: the values run beyond the grid (the extensions), in the order run
    """

    task: str
    agent: str
    curve: pd.DataFrame
    best: float
    interior: bool
    added: tuple[float, ...]

    @property
    def within_noise(self) -> list[float]:
        """The values whose paired 95% CI of the difference from the best holds 0 (indistinguishable from it)."""
        c = self.curve
        return [float(e) for e in c.index if e != self.best and c.loc[e, "vs best low"] <= 0]

    @property
    def note(self) -> str:
        """Whether the best value is interior, and the extensions that made it so (or failed to)."""
        if self.added:
            grown = f"best at the edge of the grid, extended to {', '.join(eps_text(v) for v in self.added)}"
        else:
            grown = "best inside the grid" if self.interior else "best at the edge of the grid"
        if self.interior:
            return f"interior ({grown})"
        end = self.best in (RANGE[0], RANGE[1])
        text = f"not interior: {grown}; still at the edge" + (" of the range ε in [1e-4, 1]" if end else "")
        values = sorted(float(e) for e in self.curve.index)
        neighbour = values[1] if self.best == values[0] else values[-2]
        if neighbour in self.within_noise:
            text += f" (the curve is flat there: {eps_text(neighbour)} is indistinguishable from it)"
        return text


def choose(runs: pd.DataFrame, task: str, agent: str, grid: Sequence[float]) -> Tuning:
    """The best ε of one (task, agent) from its tuning runs (every round), and whether it is interior."""
    curve = tuning_curve(runs)
    best = best_value(curve)
    values = list(curve.index)
    interior = values[0] < best < values[-1]
    order = list(dict.fromkeys(float(e) for e in runs.epsilon))  # the order the values were run in
    added = tuple(e for e in order if not any(math.isclose(e, g) for g in grid))
    return Tuning(task, agent, curve, best, interior, added)


def choose_all(table: pd.DataFrame, grid: Sequence[float]) -> dict[tuple[str, str], Tuning]:
    """``choose`` for every (task, agent) of a table of tuning runs (``task``, ``agent``, ``epsilon`` columns)."""
    return {
        (str(task), str(agent)): choose(g, str(task), str(agent), grid)
        for (task, agent), g in table.groupby(["task", "agent"], sort=False)
    }


def tune(
    run_round: Callable[[int, dict[tuple[str, str], list[float]]], pd.DataFrame],
    keys: Iterable[tuple[str, str]],
    grid: Sequence[float],
) -> tuple[dict[tuple[str, str], Tuning], int]:
    """
    The tuning loop: run ``grid`` for every key, then, while a best value is at an edge of the values run, one more value
    beyond it (``extension``), at most ``MAX_EXTENSIONS`` rounds more.

    :param run_round: ``run_round(k, values)`` runs (or reads) round ``k`` (the ε values per (task, agent)) and returns
        its runs (``task``, ``agent``, ``epsilon``, ``replicate`` and ``run_metrics``' columns)
    :param keys: the (task, agent) pairs to tune
    :param grid: the first round's values
    :return: the tuning of each key, and the number of rounds run
    """
    pending: dict[tuple[str, str], list[float]] = {key: list(grid) for key in keys}
    tables = []
    choices: dict[tuple[str, str], Tuning] = {}
    for k in range(MAX_EXTENSIONS + 1):
        tables.append(run_round(k, pending))
        choices = choose_all(pd.concat(tables, ignore_index=True), grid)
        pending = {}
        for key, tuning in choices.items():
            nxt = extension(tuning.curve.index, tuning.best)
            if nxt is not None and nxt not in tuning.curve.index:
                pending[key] = [nxt]
        if not pending:
            break
    return choices, len(tables)


def round_values(table: pd.DataFrame) -> dict[tuple[str, str], list[float]]:
    """The ε values a round's table holds per (task, agent), in the order run."""
    values: dict[tuple[str, str], list[float]] = {}
    for task, agent, eps in zip(table.task.astype(str), table.agent.astype(str), table.epsilon.astype(float)):
        got = values.setdefault((task, agent), [])
        if eps not in got:
            got.append(eps)
    return values


def tuning_grid(sweep: Mapping[str, Any]) -> tuple[str, list[float]]:
    """The label a tuning sweep (experiments/tuning.yaml, saved in ``round0``) sweeps and its grid, one for every agent."""
    grids = [agent.get("grid") or {} for agent in sweep["agents"]]
    if any(len(grid) != 1 or grid != grids[0] for grid in grids):
        raise ValueError(f"a tuning sweep gives every agent one grid label with the same values, not {grids}")
    label, values = next(iter(grids[0].items()))
    return label, [float(v) for v in values]


def best_value(curve: pd.DataFrame) -> float:
    """The ε of the lowest mean (the smallest such ε on an exact tie)."""
    return float(curve.index.to_numpy(dtype=float)[int(np.argmin(curve["mean"].to_numpy(dtype=float)))])


def eps_text(value: float) -> str:
    """An ε as the tuning's tables and notes print it."""
    return f"{value:g}"
