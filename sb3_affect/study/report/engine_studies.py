"""
The per-run tables of the studies: ``study`` reads a study's folder, a results folder of the launcher (the large-N
study, the reading and speed ablations, the long runs: experiments/large.yaml, ablation.yaml, speed_one.yaml,
long.yaml) or the table ``run_cells`` wrote.

``run_cells`` runs ``Cell``s through ``sb3_affect.engine.simulation.simulate`` (one call per chunk of seeds, no run files):
the per-task tuning and the tasks beyond the paper (moving and evading prey, mazes). Seeds are the launcher's
(``derive_seed(sweep, agent, point, replicate)``). Only per-run metrics are kept (``report.metrics.run_metrics``):
``DIR/<study>/runs.csv.gz`` and ``DIR/<study>/meta.json`` (seeds, episodes, wall time); a folder that already holds
them for the same study is reused.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.study.report import paper
from sb3_affect.study.report.output_files import cached_json, output_folder, replacing, write_text

PAPER_ENV = ("sb3_affect/GridPursuit-v0", {"size": 15, "start": [0, 0], "goal": [6, 6], "goal_reward": 100.0})
COMMON = {"learning_rate": 1.0, "gamma": 0.8, "q_init": 0.0}
AFFECT_DEFAULT = {"comparison": "literal", "act": "episode", "units": "cells"}
#: Agents of the studies' sweep files the sections name: the speed-matched ε-greedy of experiments/large.yaml, the
#: affective agent at 1 cell per decision of experiments/speed_one.yaml.
SPEED_AGENT = "speed-epsilon-greedy"
SPEED_ONE_AGENT = "affective-speed-1"
CHUNK = 50
#: Runs read at a time from a study's results folder (``folder_study``).
RUNS_PER_PART = 10_000


@dataclass(frozen=True)
class Cell:
    """
    One configuration run at many seeds.

    :param agent: the agent's name (the ``agent`` column)
    :param algo: class name or ``module:Class`` of a tabular agent
    :param kwargs: its constructor arguments
    :param labels: label columns of its runs (``epsilon``, ``task``, ...)
    :param sweep: the sweep name its seeds derive from
    :param point: the grid point its seeds derive from
    :param env_id: the env's registered id
    :param env_kwargs: the env's arguments
    """

    agent: str
    algo: str
    kwargs: dict[str, Any]
    labels: dict[str, Any]
    sweep: str
    point: dict[str, Any]
    env_id: str = PAPER_ENV[0]
    env_kwargs: dict[str, Any] = field(default_factory=lambda: dict(PAPER_ENV[1]))


def _chunk(job: tuple[Cell, list[int], int]) -> pd.DataFrame:
    from sb3_affect.engine.simulation import simulate
    from sb3_affect.study.launcher.schema import derive_seed
    from sb3_affect.study.report.metrics import EARLY, LATE, run_metrics

    cell, replicates, episodes = job
    seeds = [derive_seed(cell.sweep, cell.agent, cell.point, r) for r in replicates]
    frame = simulate(cell.algo, cell.kwargs, cell.env_id, cell.env_kwargs, seeds, episodes)
    bound = _capture_distance(cell.env_id, cell.env_kwargs)
    if bound is not None:  # moving prey: optimal = a capture within the prey's starting distance
        frame["optimal"] = ~frame.truncated.astype(bool) & (frame.cells <= bound)
    frame["replicate"] = frame.seed.map(dict(zip(seeds, replicates)))
    tag = "-".join(f"{v}" for v in cell.labels.values())
    frame["run_id"] = [f"{cell.agent}-{tag}-r{r}" for r in frame.replicate]
    frame["agent"] = cell.agent
    for key, value in cell.labels.items():
        frame[key] = value
    last = (max(episodes - 199, 1), episodes)  # the last 200 episodes of a long run
    return run_metrics(frame, windows=(EARLY, LATE) if last[0] <= LATE[0] else (EARLY, LATE, last))


def _capture_distance(env_id: str, env_kwargs: dict[str, Any]) -> int | None:
    if "MovingPursuit" not in env_id:
        return None
    from sb3_affect.study.report.baseline_summary import capture_distance

    return capture_distance({"env_id": env_id, "env_kwargs": env_kwargs})


def run_cells(
    folder: Path, cells: list[Cell], seeds: int, episodes: int = paper.EPISODES, workers: int | None = None
) -> tuple[pd.DataFrame, dict[str, Any]]:
    """
    Per-run metrics of every cell at ``seeds`` seeds (computed, or read back when ``folder`` holds this study).

    :param folder: where ``runs.csv.gz`` and ``meta.json`` go
    :param cells: the configurations
    :param seeds: seeds (replicates) per cell
    :param episodes: episodes per run
    :param workers: processes (default: usable CPUs)
    :return: one row per run (agent, labels, replicate, seed and ``run_metrics``' columns), and the meta data
    """
    if seeds < 1:
        raise ValueError(f"seeds={seeds} must be >= 1")
    folder = Path(folder)
    meta_path, table_path = folder / "meta.json", folder / "runs.csv.gz"
    key = json.dumps([[c.agent, c.algo, c.kwargs, c.labels, c.sweep, c.point, c.env_id, c.env_kwargs] for c in cells])
    meta = cached_json(meta_path)
    same = isinstance(meta, dict) and (meta.get("seeds"), meta.get("episodes"), meta.get("cells")) == (seeds, episodes, key)
    if same and table_path.exists():
        return pd.read_csv(table_path), meta
    output_folder(folder)
    jobs = [
        (cell, list(range(start, min(seeds, start + CHUNK))), episodes) for cell in cells for start in range(0, seeds, CHUNK)
    ]
    workers = workers or len(os.sched_getaffinity(0))
    start = time.perf_counter()
    if workers > 1 and len(jobs) > 1:
        from sb3_affect.kernel import warm_up

        warm_up()  # the forked workers share the kernels loaded (or, on a cold cache, compiled) once here
        with ProcessPoolExecutor(min(workers, len(jobs))) as pool:
            frames = list(pool.map(_chunk, jobs))
    else:
        frames = [_chunk(job) for job in jobs]
    table = pd.concat(frames, ignore_index=True)
    with replacing(table_path) as tmp:
        table.to_csv(tmp, index=False)
    seconds = time.perf_counter() - start
    meta = {"seeds": seeds, "episodes": episodes, "runs": len(table), "wall_seconds": seconds, "cells": key}
    write_text(meta_path, json.dumps(meta))
    return table, meta


def study(out_dir: Path, name: str) -> tuple[pd.DataFrame, dict[str, Any]] | None:
    """
    A study's per-run table and meta data from ``out_dir/<name>`` (None when there is none): a results folder of the
    launcher (``folder_study``), else the ``runs.csv.gz`` and ``meta.json`` of ``run_cells``.
    """
    folder = Path(out_dir) / name
    if (folder / "chunks").is_dir() or (folder / "runs").is_dir():
        return folder_study(folder)
    if not (folder / "meta.json").exists() or not (folder / "runs.csv.gz").exists():
        return None
    meta = cached_json(folder / "meta.json")
    if not isinstance(meta, dict):
        raise ValueError(f"{folder / 'meta.json'} is not a study's record (a JSON object); rerun `sb3-affect replicate`")
    return pd.read_csv(folder / "runs.csv.gz"), meta


def folder_study(folder: Path) -> tuple[pd.DataFrame, dict[str, Any]] | None:
    """
    The per-run table of a study run by the launcher into ``folder`` (None when it holds no finished run), as
    ``run_cells`` gives it: ``run_metrics`` of every run (read a part of the folder at a time; a run longer than the
    paper's 200 episodes also gets the window of its last 200), the label columns, ``replicate`` and ``seed``, run ids
    ``<agent>-<label values>-r<replicate>``, the rows in the order of the sweep's cells. Meta data: ``seeds`` (replicates
    per cell), ``episodes``, ``runs`` and ``wall_seconds`` (the runs' own seconds, summed over the workers).
    """
    from sb3_affect.study.launcher.store import ResultsStore
    from sb3_affect.study.report.metrics import EARLY, LATE, join_parts, load_results, run_metrics

    saved = ResultsStore(folder).saved_sweep()
    results = load_results(folder)
    if saved is None or not len(results.runs):
        return None
    sweep = saved["sweep"]
    episodes = int(sweep["episodes"])
    last = (max(episodes - 199, 1), episodes)
    windows = (EARLY, LATE) if last[0] <= LATE[0] else (EARLY, LATE, last)
    bound = _capture_distance(sweep["env"]["id"], dict(sweep["env"].get("kwargs") or {}))
    frames = []
    for runs, part in results.parts(results.columns, runs_per_part=RUNS_PER_PART):
        if bound is not None:  # moving prey: optimal = a capture within the prey's starting distance
            part["optimal"] = ~part.truncated.astype(bool) & (part.cells <= bound)
        frames.append(run_metrics(part, runs, windows))
    table = join_parts(frames)
    labels = _cell_labels(sweep)
    table = _in_cell_order(table, labels)
    meta = {
        "seeds": int(table.replicate.max()) + 1,
        "episodes": episodes,
        "runs": len(table),
        "wall_seconds": float(results.runs.wall_seconds.sum()),
    }
    return table, meta


def _cell_labels(sweep: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """``(agent, labels)`` of each cell of a saved sweep, in the sweep's order (agents, then their grid points)."""
    from itertools import product

    cells = []
    for agent in sweep["agents"]:
        grid = agent.get("grid") or {}
        for values in product(*grid.values()):
            cells.append((agent["name"], {**dict(zip(grid, values)), **(agent.get("labels") or {})}))
    return cells


def _in_cell_order(table: pd.DataFrame, cells: list[tuple[str, dict[str, Any]]]) -> pd.DataFrame:
    """
    ``table``'s rows in ``run_cells``' order (cell by cell, ``CHUNK`` replicates at a time, each chunk by run id) with its
    run ids and column order: the tables and resamples of the report see the same rows in the same places.
    """
    names = [key for _, labels in cells for key in labels if key in table.columns]
    names = list(dict.fromkeys(names))
    index = {(agent, *(labels.get(k) for k in names)): i for i, (agent, labels) in enumerate(cells)}
    keys = zip(table.agent.astype(str), *(table[k].tolist() for k in names))
    cell = [index.get(key, len(cells)) for key in keys]
    tags = ["-".join(str(labels[k]) for k in labels) for _, labels in cells] + [""]
    replicate = table.replicate.astype(int).tolist()
    table = table.assign(run_id=[f"{a}-{tags[c]}-r{r}" for a, c, r in zip(table.agent.astype(str), cell, replicate)])
    order = sorted(range(len(table)), key=lambda i: (cell[i], replicate[i] // CHUNK, table.run_id.iat[i]))
    table = table.iloc[order].reset_index(drop=True)
    first = ["run_id", "seed", "replicate", "agent", *names]
    table = table[first + [c for c in table.columns if c not in first]]
    for name in ("agent", *names):
        if isinstance(table[name].dtype, pd.CategoricalDtype):
            table[name] = table[name].astype(object)
    return table
