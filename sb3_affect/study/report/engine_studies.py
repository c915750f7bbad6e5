"""
Studies run through ``sb3_affect.engine.simulation.simulate`` (one call per chunk of seeds, no run files): the large-N study
(the paper's 18 cells and the speed-matched epsilon-greedy at many seeds per cell), the reading ablation, and the
tasks beyond the paper (moving and evading prey, mazes).

Seeds are the launcher's (``derive_seed(sweep, agent, point, replicate)``): the large-N study uses the paper sweep's,
so its replicates 0-19 are the very runs of experiments/paper.yaml, and replicate r is the same run whatever the seed
count. Only per-run metrics are kept (``report.metrics.run_metrics``): ``DIR/<study>/runs.csv.gz`` and
``DIR/<study>/meta.json`` (seeds, episodes, wall time); a folder that already holds them for the same study is reused.
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
SPEED_AGENT = "speed-epsilon-greedy"
#: The speed-matched epsilon-greedy (a fair baseline): the tuned epsilon 0.01, 1 or 2 cells per decision.
SPEED_KWARGS = {"exploration_rate": 0.01, "speeds": [1, 2]}
#: The speed ablation: the affective agent with every emotion's speed fixed at 1 cell (Table III's directions kept).
SPEED_ONE_AGENT = "affective-speed-1"
SPEED_ONE_TABLE = {"joy": [True, [1]], "sadness": [False, [1]], "fear": [False, [1]], "anger": [False, [1]]}
#: Episodes per run of the long-run study (the paper's "in the long run", tested directly).
LONG_EPISODES = 2000
CHUNK = 50


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


def large_cells() -> list[Cell]:
    """The large-N study: both paper agents at every epsilon, and the speed-matched epsilon-greedy."""
    out = [
        Cell("epsilon-greedy", "QLearning", {**COMMON, "exploration_rate": eps}, {"epsilon": eps}, "paper", {"epsilon": eps})
        for eps in paper.EPSILONS
    ]
    out += [
        Cell("affective", "AffectQ", {**COMMON, **AFFECT_DEFAULT}, {"epsilon": eps}, "paper", {"epsilon": eps})
        for eps in paper.EPSILONS
    ]
    out.append(
        Cell(
            SPEED_AGENT, "sb3_affect.agents.baselines:SpeedEpsilonGreedy", {**COMMON, **SPEED_KWARGS}, {"epsilon": 0.01},
            "large", {}
        ),
    )
    return out


def speed_one_cells() -> list[Cell]:
    """The speed ablation: AffectQ with every speed fixed at 1 cell, at every ε label (seeds of its own)."""
    kwargs = {**COMMON, **AFFECT_DEFAULT, "behaviour_table": SPEED_ONE_TABLE}
    return [
        Cell(SPEED_ONE_AGENT, "AffectQ", kwargs, {"epsilon": eps}, "speed-one", {"epsilon": eps}) for eps in paper.EPSILONS
    ]


def long_cells() -> list[Cell]:
    """The long-run study: both paper agents at every ε (seeds of its own; run with ``LONG_EPISODES`` episodes)."""
    return [
        Cell(cell.agent, cell.algo, cell.kwargs, cell.labels, "long", cell.point)
        for cell in large_cells()
        if cell.agent != SPEED_AGENT
    ]


def _kwargs(kwargs: dict[str, Any]) -> dict[str, Any]:
    """A cell's kwargs for the engine: a behaviour table by emotion name becomes one keyed by ``Emotion``."""
    table = kwargs.get("behaviour_table")
    if not isinstance(table, dict) or not table or not all(isinstance(k, str) for k in table):
        return kwargs
    from sb3_affect.core.behaviour import Behaviour
    from sb3_affect.core.emotions import Emotion

    converted = {
        Emotion[name.upper()]: Behaviour(bool(r), tuple(int(k) for k in speeds)) for name, (r, speeds) in table.items()
    }
    return {**kwargs, "behaviour_table": converted}


def _chunk(job: tuple[Cell, list[int], int]) -> pd.DataFrame:
    from sb3_affect.engine.simulation import simulate
    from sb3_affect.study.launcher.schema import derive_seed
    from sb3_affect.study.report.metrics import EARLY, LATE, run_metrics

    cell, replicates, episodes = job
    seeds = [derive_seed(cell.sweep, cell.agent, cell.point, r) for r in replicates]
    frame = simulate(cell.algo, _kwargs(cell.kwargs), cell.env_id, cell.env_kwargs, seeds, episodes)
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
    """A study's per-run table and meta data from ``out_dir/<name>`` (None when there is none)."""
    folder = Path(out_dir) / name
    if not (folder / "meta.json").exists() or not (folder / "runs.csv.gz").exists():
        return None
    meta = cached_json(folder / "meta.json")
    if not isinstance(meta, dict):
        raise ValueError(f"{folder / 'meta.json'} is not a study's record (a JSON object); rerun `sb3-affect replicate`")
    return pd.read_csv(folder / "runs.csv.gz"), meta


def large_meta(out_dir: Path) -> dict[str, Any] | None:
    """``meta.json`` of the large-N study in ``out_dir`` (None when there is none)."""
    found = study(out_dir, "large")
    return found[1] if found else None
