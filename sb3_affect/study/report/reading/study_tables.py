"""
The per-run tables of the studies run by the launcher that the report reads as one table each (the large-N study, the
reading and speed ablations, the long runs, the tuning rounds and the tasks beyond the paper: experiments/large.yaml,
ablation.yaml, speed_one.yaml, long.yaml, tuning.yaml, beyond.yaml): ``study`` / ``folder_study`` give each run's
metrics (``run_tables.run_metrics``), its labels, replicate and seed, in the order the report's resamples expect.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.study.launcher.schema import Sweep
from sb3_affect.study.launcher.store import ResultsStore
from sb3_affect.study.report.reading.baseline_ranks import capture_distance
from sb3_affect.study.report.reading.run_tables import EARLY, LATE, join_parts, load_results, run_metrics

COMMON = {"learning_rate": 1.0, "gamma": 0.8, "q_init": 0.0}
AFFECT_DEFAULT = {"comparison": "literal", "act": "episode", "units": "cells"}
#: Agents of the studies' sweep files the sections name: the speed-matched ε-greedy of experiments/large.yaml, the
#: affective agent at 1 cell per decision of experiments/speed_one.yaml.
SPEED_AGENT = "speed-epsilon-greedy"
SPEED_ONE_AGENT = "affective-speed-1"
#: The rows' order: cell by cell, this many replicates at a time, each block by run id (the order the report's tables
#: and resamples have always had: a bootstrap draws rows by position).
CHUNK = 50
#: Runs read at a time from a study's results folder (``folder_study``).
RUNS_PER_PART = 10_000


def _capture_distance(env_id: str, env_kwargs: dict[str, Any]) -> int | None:
    if "MovingPursuit" not in env_id:
        return None

    return capture_distance({"env_id": env_id, "env_kwargs": env_kwargs})


def episode_cap(sweep: dict[str, Any]) -> int | None:
    """The ``max_episode_decisions`` every agent of a saved sweep shares (None: not one value for all)."""
    caps = {(agent.get("kwargs") or {}).get("max_episode_decisions") for agent in sweep["agents"]}
    cap = caps.pop() if len(caps) == 1 else None
    return int(cap) if isinstance(cap, int) else None


def study(out_dir: Path, name: str) -> tuple[pd.DataFrame, dict[str, Any]] | None:
    """A study's per-run table and meta data from the launcher's results folder ``out_dir/<name>`` (``folder_study``)."""
    folder = Path(out_dir) / name
    if not (folder / "chunks").is_dir() and not (folder / "runs").is_dir():
        return None
    return folder_study(folder)


def folder_study(folder: Path) -> tuple[pd.DataFrame, dict[str, Any]] | None:
    """
    The per-run table of a study run by the launcher into ``folder`` (None when it holds no finished run):
    ``run_metrics`` of every run (read a part of the folder at a time; a run longer than the paper's 200 episodes also
    gets the window of its last 200; on moving prey, optimal is a capture within the prey's starting distance and the
    greedy policy never walks a shortest path), the
    label columns (``task`` first), ``replicate`` and ``seed``, run ids ``<agent>-<label values>-r<replicate>``, the rows
    in the order of the sweep's cells (``CHUNK``). Meta data: ``seeds`` (replicates per cell), ``episodes``, ``runs``,
    ``wall_seconds`` (the runs' own seconds, summed over the workers) and ``sweep`` (the sweep file as saved).
    """

    saved = ResultsStore(folder).saved_sweep()
    results = load_results(folder)
    if saved is None or not len(results.runs):
        return None
    sweep = saved["sweep"]
    episodes = int(sweep["episodes"])
    last = (max(episodes - 199, 1), episodes)
    windows = (EARLY, LATE) if last[0] <= LATE[0] else (EARLY, LATE, last)
    envs = sweep.get("tasks") or {None: sweep["env"]}
    bounds = {task: _capture_distance(env["id"], dict(env.get("kwargs") or {})) for task, env in envs.items()}
    frames = []
    for runs, part in results.parts(results.columns, runs_per_part=RUNS_PER_PART):
        if any(bound is not None for bound in bounds.values()):  # moving prey: optimal = a capture within the distance
            tasks = part.task.astype(object) if "task" in part.columns else pd.Series(None, index=part.index, dtype=object)
            bound = tasks.map(bounds).astype(float)
            moving = bound.notna()
            part["optimal"] = part.optimal.where(~moving, ~part.truncated.astype(bool) & (part.cells <= bound))
            # no fixed goal, so no greedy path to walk: undefined in the engine (NaN), stored as a flag by the launcher
            part["greedy_optimal"] = part.greedy_optimal.where(~moving, False)
        frames.append(run_metrics(part, runs, windows))
    table = join_parts(frames)
    labels = _cell_labels(sweep, saved.get("task_order"))
    table = _in_cell_order(table, labels)
    meta = {
        "seeds": int(table.replicate.max()) + 1,
        "episodes": episodes,
        "runs": len(table),
        "wall_seconds": float(results.runs.wall_seconds.sum()),
        "sweep": sweep,
    }
    return table, meta


def _cell_labels(sweep: dict[str, Any], task_order: Any = None) -> list[tuple[str, dict[str, Any]]]:
    """
    ``(agent, labels)`` of each cell of a saved sweep, in the sweep's order (tasks, agents, grid points), task first.

    :param task_order: the tasks in the file's order (the launcher saves it beside the sweep, whose keys are sorted)
    """

    tasks = sweep.get("tasks") or {}
    if isinstance(task_order, list) and sorted(map(str, task_order)) == sorted(tasks):
        sweep = {**sweep, "tasks": {task: tasks[task] for task in task_order}}
    cells = []
    for cell in Sweep.validate_saved(sweep).cells():
        labels = dict(cell.base["labels"])
        task = {"task": labels.pop("task")} if "task" in labels else {}
        cells.append((cell.base["agent"], {**task, **labels}))
    return cells


def _in_cell_order(table: pd.DataFrame, cells: list[tuple[str, dict[str, Any]]]) -> pd.DataFrame:
    """
    ``table``'s rows in the cells' order (cell by cell, ``CHUNK`` replicates at a time, each block by run id) with the
    run ids and column order the report's tables have always had: its tables and resamples see the same rows in the
    same places. A label a cell does not have (a fixed agent's ``epsilon`` beside tuned agents) reads as missing.
    """
    names = [key for _, labels in cells for key in labels if key in table.columns]
    names = list(dict.fromkeys(names))
    index = {(agent, *(labels.get(k) for k in names)): i for i, (agent, labels) in enumerate(cells)}
    keys = zip(table.agent.astype(str), *([None if v != v else v for v in table[k].tolist()] for k in names))
    cell = [index.get(key, len(cells)) for key in keys]
    tags = ["-".join(str(labels[k]) for k in labels) for _, labels in cells] + [""]
    replicate = table.replicate.astype(int).tolist()
    table = table.assign(run_id=[f"{a}-{tags[c]}-r{r}" for a, c, r in zip(table.agent.astype(str), cell, replicate)])
    order = sorted(range(len(table)), key=lambda i: (cell[i], replicate[i] // CHUNK, table.run_id.iat[i]))
    table = table.iloc[order].reset_index(drop=True)
    first = ["run_id", "seed", "replicate", "agent", *(k for k in cells[0][1] if k in names)] if cells else ["run_id"]
    later = [k for k in names if k not in first]  # labels the first cell lacks come last (as the cells' tables joined)
    table = table[first + [c for c in table.columns if c not in first and c not in later] + later]
    for name in ("agent", *names):
        if isinstance(table[name].dtype, pd.CategoricalDtype):
            table[name] = table[name].astype(object)
    return table
