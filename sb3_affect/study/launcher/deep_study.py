"""
The deep study's runs (``study: deep``, ``sb3_affect.study.launcher.deep_schema``): for each task and agent, one *cell*,
its seeds cut into batches (``seeds_per_batch``), each batch trained by the public trainer ``sb3_affect.train_many``
and its greedy policies evaluated every ``eval_every`` env steps (``deep_batches``, ``deep_training``,
``deep_recording``). The batches run on the launcher's one executor: ``workers`` forked local processes (or this
process when ``workers`` is 1), or one Ray task per batch (``backend="ray"``); a batch's record is the same on either.

The driver is the only writer. A batch writes ``OUT/batches/<task>__<agent>/<index>.json`` as it finishes; when all
batches of a cell are there, their records are merged in seed order into ``OUT/cells/<task>__<agent>.json`` and the
batch files removed. A finished cell, and a finished batch of an unfinished one, is not run again: an interrupted
study (Ctrl-C, a lost node or cluster) resumes where it stopped. ``OUT/deep_study.json`` holds the validated study,
and a folder holding another study's is refused.

A cell whose agent ``replays`` another waits for that agent's cell on the same task and takes its random share,
averaged over seeds, part by part as its ε (``ReplayedEpsilonDQN``): the batches run in waves, each wave the batches
of the cells whose sources are done.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sb3_affect.study.launcher.deep_batches import DeepBatch, merge_batches, seed_batches
from sb3_affect.study.launcher.deep_schema import DeepStudy
from sb3_affect.study.launcher.launcher import run_ray
from sb3_affect.study.launcher.local_pool import run_local

#: The file naming the study a folder holds.
STUDY_FILE = "deep_study.json"
#: The folder of the finished cells.
CELLS = "cells"
#: The folder of the finished batches of unfinished cells.
BATCHES = "batches"
#: The executors a deep study runs on.
BACKENDS = ("local", "ray")


def cell_path(out: Path, task: str, agent: str) -> Path:
    return out / CELLS / f"{task}__{agent}.json"


def batch_path(out: Path, task: str, agent: str, index: int) -> Path:
    return out / BATCHES / f"{task}__{agent}" / f"{index}.json"


@dataclass
class DeepSummary:
    """What ``run_deep_study`` did: cells finished now and found done, batches run now, wall seconds, the folder."""

    name: str
    trained: int
    reused: int
    batches: int
    seconds: float
    out_dir: Path

    @property
    def total(self) -> int:
        return self.trained + self.reused


def replayed_epsilons(source: dict[str, Any]) -> list[float]:
    """A finished cell's random share, averaged over its seeds, per part of training (a part without decisions: 1)."""
    shares = np.asarray(source["random_share"], dtype=float)  # (seeds, parts); None read as NaN
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a part without decisions in any seed
        mean = np.nanmean(shares, axis=0)
    return [1.0 if math.isnan(value) else float(value) for value in mean]


def _write_json(path: Path, data: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    os.replace(tmp, path)


def _read_json(path: Path) -> Any:
    """A results file of the folder (regular files only: a symlink is not followed), or None when absent or unreadable."""
    if not path.is_file() or path.is_symlink():
        return None
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _claim_folder(study: DeepStudy, out: Path) -> None:
    """Write ``OUT/deep_study.json``, or refuse a folder that holds another study's results (one line)."""
    marker = out / STUDY_FILE
    data = study.model_dump(mode="json")
    if marker.is_file() and not marker.is_symlink():
        saved = _read_json(marker)
        try:
            same = DeepStudy.model_validate(saved).model_dump(mode="json") == data  # keys added since: their defaults
        except ValueError:
            same = False
        if not same:
            raise ValueError(f"{out} holds the results of another deep study ({marker} differs): give another --out")
        return
    if out.exists() and any(out.iterdir()):
        raise ValueError(f"{out} is not empty and holds no {STUDY_FILE}: give an empty or new folder")
    _write_json(marker, data)


def _finished_batch(out: Path, task: str, agent: str, index: int, seeds: tuple[int, ...]) -> dict[str, Any] | None:
    record = _read_json(batch_path(out, task, agent, index))
    return record if isinstance(record, dict) and record.get("seeds") == list(seeds) else None


def _print(line: str) -> None:
    print(line, flush=True)


def run_deep_study(
    study: DeepStudy,
    out: Path,
    workers: int | None = 1,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
    log: Callable[[str], None] | None = None,
) -> DeepSummary:
    """
    Run every batch of ``study`` not yet in ``out`` (tasks x agents, each cell's seeds in batches) on the executor.

    :param workers: local processes (None: the usable CPUs; 1: in this process), or at most this many Ray tasks at a time
    :param backend: ``"local"`` or ``"ray"`` (one Ray task per batch)
    :param ray_address: the Ray cluster (default: a private instance of ``workers`` CPUs)
    :param ray_timeout: seconds to wait for the Ray cluster to answer
    :param log: where one line per finished batch and per finished cell goes (default: printed at once)
    """
    if log is None:
        log = _print
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r} is not supported; choose {' or '.join(map(repr, BACKENDS))}")
    out = Path(out)
    _claim_folder(study, out)
    start = time.perf_counter()
    cap = workers
    workers = workers or len(os.sched_getaffinity(0))
    batches = seed_batches(study)
    names = [agent.name for agent in study.agents]
    done = {(task, name) for task in study.tasks for name in names if cell_path(out, task, name).is_file()}
    reused = len(done)
    todo = [(task, index) for task in study.tasks for index, name in enumerate(names) if (task, name) not in done]
    data = study.model_dump(mode="json")
    counts = {"cells": 0, "batches": 0}
    failures: list[str] = []

    def jobs_of(task: str, index: int) -> list[DeepBatch]:
        source = study.agents[index].replays
        epsilons = None
        if source is not None:
            epsilons = tuple(replayed_epsilons(json.loads(cell_path(out, task, source).read_text())))
        return [DeepBatch(data, task, index, k, seeds, epsilons) for k, seeds in enumerate(batches)
                if _finished_batch(out, task, names[index], k, seeds) is None]

    def finish_cell(task: str, name: str) -> None:
        records = [_finished_batch(out, task, name, k, seeds) for k, seeds in enumerate(batches)]
        if any(record is None for record in records):
            return
        cell = merge_batches(records)  # type: ignore[arg-type]
        _write_json(cell_path(out, task, name), cell)
        for k in range(len(batches)):
            batch_path(out, task, name, k).unlink()
        with contextlib.suppress(OSError):  # (a file the folder holds besides the batches stays)
            batch_path(out, task, name, 0).parent.rmdir()
        done.add((task, name))
        counts["cells"] += 1
        final = [row[-1] for row in cell["success"] if row and row[-1] is not None]
        log(f"   {task} {name}: {len(cell['seeds'])} seeds, final greedy success "
            f"{np.mean(final) if final else math.nan:.2f}, {cell['seconds']:.1f} CPU s")

    def on_result(job: DeepBatch, result: dict[str, Any]) -> None:
        name = names[job.agent]
        _write_json(batch_path(out, job.task, name, job.index), result["record"])
        counts["batches"] += 1
        log(f"   {job.task} {name}: batch {job.index + 1}/{len(batches)} (seeds {', '.join(map(str, job.seeds))}) done")
        finish_cell(job.task, name)

    def on_failure(job: DeepBatch, error: str) -> None:
        failures.append(f"{job.name}: {error}")

    while todo:
        wave = [cell for cell in todo if study.agents[cell[1]].replays in (None, *(n for t, n in done if t == cell[0]))]
        if not wave:  # (the schema puts a replayed agent before its replay: only a failed source leaves this)
            raise RuntimeError(f"the cells {todo} wait for cells that did not finish")
        todo = [cell for cell in todo if cell not in wave]
        jobs = [job for task, index in wave for job in jobs_of(task, index)]
        for task, index in wave:  # a cell whose batches were all done before an interruption
            if not any(job.task == task and job.agent == index for job in jobs):
                finish_cell(task, names[index])
        if not jobs:
            continue  # (no Ray instance nor worker started for nothing)
        if backend == "ray":
            run_ray(jobs, workers, on_result, on_failure, ray_address, cap=cap, timeout=ray_timeout)
        elif workers == 1:
            for job in jobs:
                on_result(job, job.execute())
        else:
            run_local(jobs, workers, on_result, on_failure)
        if failures:
            raise RuntimeError(f"{len(failures)} batches of the deep study failed (the finished ones are kept; "
                               f"rerun to retry): the first: {failures[0]}")
    return DeepSummary(study.name, counts["cells"], reused, counts["batches"], time.perf_counter() - start, out)


def deep_status(out: Path) -> list[str]:
    """``sb3-affect status`` of a deep study's folder: cells done of planned, and each cell's batches done."""
    study = DeepStudy.model_validate(_read_json(out / STUDY_FILE))
    batches = seed_batches(study)
    lines, done_cells = [], 0
    for task in study.tasks:
        for agent in study.agents:
            if cell_path(out, task, agent.name).is_file():
                done_cells += 1
                state = f"done ({len(study.seeds)} seeds)"
            else:
                finished = sum(_finished_batch(out, task, agent.name, k, seeds) is not None for k, seeds in enumerate(batches))
                state = f"{finished}/{len(batches)} batches done" if finished else "not started"
            lines.append(f"  {task:16s} {agent.name:24s} {state}")
    planned = len(study.tasks) * len(study.agents)
    return [f"deep study {study.name!r} in {out}: {done_cells}/{planned} cells done (task x agent, "
            f"{len(study.seeds)} seeds each in {len(batches)} batch{'es' if len(batches) > 1 else ''})", *lines]
