"""
The deep study's runs (``study: deep``, ``sb3_affect.study.launcher.deep_schema``): for each task and agent, one *cell*,
its seeds cut into batches (``seeds_per_batch``), each batch trained by the public trainer ``sb3_affect.train_many``
and its greedy policies evaluated every ``eval_every`` env steps (``deep_batches``, ``deep_training``,
``deep_recording``). The batches run on the launcher's one executor: ``workers`` forked local processes (or this
process when ``workers`` is 1), or one Ray task per batch (``backend="ray"``); a batch's record is the same on either.

The driver is the only writer, and holds the folder's lock while it runs (``folder_lock``: a second launcher is
refused in one line). A batch writes ``OUT/batches/<task>__<agent>/<index>.json`` as it finishes; when all batches of
a cell are there, their records are merged in seed order into ``OUT/cells/<task>__<agent>.json`` and the batch files
removed; each file through the one atomic writer (``regular_files.write_file``). A finished cell, and a finished batch
of an unfinished one, is not run again: an interrupted study (Ctrl-C, a kill, a lost node or cluster) resumes where it
stopped. A batch that raised or whose worker died leaves ``OUT/failed/<task>__<agent>__<index>.json`` (retried on
resume). A file counts only when it reads back as the record of its cell and seeds (``check_record``, under the
regular-files rule): the launcher moves every other file of ``cells/`` and ``batches/`` into ``OUT/damaged/`` and runs
its batches again; ``status`` names them; the report refuses the folder until a rerun has set them aside.
``OUT/deep_study.json`` holds the validated study; a folder holding another study, or another kind of study, is
refused.

A cell whose agent ``replays`` another waits for that agent's cell on the same task and takes its random share,
averaged over seeds, part by part as its ε (``ReplayedEpsilonDQN``): the batches run in waves, each wave the batches
of the cells whose sources are done.
"""

from __future__ import annotations

import contextlib
import json
import math
import numbers
import os
import time
import traceback
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher.deep_batches import DeepBatch, merge_batches, seed_batches, training
from sb3_affect.study.launcher.deep_schema import RECORD_ROWS, DeepStudy
from sb3_affect.study.launcher.launcher import run_ray
from sb3_affect.study.launcher.local_pool import run_local
from sb3_affect.study.launcher.regular_files import UnreadableFile, read_json
from sb3_affect.study.launcher.store import KIND_FILES, ResultsStore, StoreError, claim_kind, store_error, write_atomic

#: The file naming the study a folder holds.
STUDY_FILE = KIND_FILES["deep"]
#: The largest cell or batch record read (10,000 seeds x 1,000 evaluations of ten rows: about 1 GB; a cell of the
#: shipped study is under a megabyte).
MAX_RECORD_BYTES = 2**30
#: The rows every greedy evaluation fills (the others may be empty, None, where a part had no decision or emotion).
EVALUATED = ("success", "return")
#: The largest ``deep_study.json`` read.
MAX_STUDY_BYTES = 2**24
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


def check_record(record: Any, study: DeepStudy, task: str, agent: str, seeds: Sequence[int]) -> str | None:
    """
    Why ``record`` is not the record of ``seeds`` of the cell ``task`` x ``agent`` (a batch's, or merged a cell's) as
    ``deep_training.run_batch`` writes it, or None when it is: its rows (seeds, evaluations) of numbers or None.
    """
    if not isinstance(record, dict):
        return "is not a record of the deep study (a JSON object)"
    if record.get("task") != task or record.get("agent") != agent:
        return f"is not a record of {task} x {agent} (it says {record.get('task')!r} x {record.get('agent')!r})"
    if record.get("seeds") != list(seeds):
        return f"holds the seeds {record.get('seeds')!r}, not {list(seeds)}"
    evaluations = study.tasks[task].budget // study.eval_every
    emotions = record.get("emotions")
    tables = [(key, record.get(key)) for key in RECORD_ROWS]
    if emotions is not None:
        if not isinstance(emotions, dict) or sorted(emotions) != sorted(EMOTION_NAMES):
            return f"has emotions that are not one table per emotion ({', '.join(EMOTION_NAMES)})"
        tables += [(f"emotions.{name}", emotions[name]) for name in EMOTION_NAMES]
    for key, rows in tables:
        if not (isinstance(rows, list) and len(rows) == len(seeds)
                and all(isinstance(row, list) and len(row) == evaluations and all(_number(v) for v in row) for row in rows)):
            return f"has no {key} table of {len(seeds)} seeds x {evaluations} evaluations"
    for key in EVALUATED:  # every evaluation gives them (None, NaN or out of range: not the evaluation's)
        values = [v for row in record[key] for v in row]
        if not all(v is not None and math.isfinite(v) and (key != "success" or 0 <= v <= 1) for v in values):
            return f"has a {key} that no evaluation gives (empty, NaN or out of range)"
    first = record.get("first_success")
    if not (isinstance(first, list) and len(first) == len(seeds) and all(_number(v) for v in first)):
        return f"has no first_success of {len(seeds)} seeds"
    if not isinstance(record.get("seconds"), (int, float)) or isinstance(record.get("seconds"), bool):
        return "has no seconds"
    return None


def _number(value: Any) -> bool:
    return value is None or (isinstance(value, numbers.Real) and not isinstance(value, bool))


def _read_record(path: Path, study: DeepStudy, task: str, agent: str, seeds: Sequence[int]) -> tuple[Any, str | None]:
    """
    ``(record, None)`` when ``path`` holds the record of ``seeds`` of the cell (``check_record``, read under the
    regular-files rule), ``(None, None)`` when there is no file, ``(None, why)`` when it does not count.
    """
    if not os.path.lexists(path):
        return None, None
    try:
        record = read_json(path, MAX_RECORD_BYTES)
    except UnreadableFile as error:
        return None, error.reason
    why = check_record(record, study, task, agent, seeds)
    return (None, why) if why else (record, None)


@dataclass
class DeepFiles:
    """
    The files of a deep study's folder sorted out: the finished cells and the finished batches of unfinished cells
    (``(task, agent) -> record``, ``(task, agent, index) -> record``), ``(path, why)`` of each file that does not
    count (unreadable, not its cell's record, or not a file of the study), and the batch files of finished cells.
    """

    cells: dict[tuple[str, str], dict[str, Any]]
    batches: dict[tuple[str, str, int], dict[str, Any]]
    rejected: list[tuple[Path, str]]
    merged: list[Path] = field(default_factory=list)  # batches of finished cells (a launcher stopped as it merged)


def sort_files(out: Path, study: DeepStudy) -> DeepFiles:
    """Every file of ``OUT/cells/`` and ``OUT/batches/``, read and sorted out (``DeepFiles``). Writes nothing."""
    files = DeepFiles({}, {}, [])
    expected: set[Path] = set()
    batches = seed_batches(study)
    for task in study.tasks:
        for agent in study.agents:
            path = cell_path(out, task, agent.name)
            expected.add(path)
            record, why = _read_record(path, study, task, agent.name, study.seeds)
            if why:
                files.rejected.append((path, why))
            elif record is not None:
                files.cells[task, agent.name] = record
            for index, seeds in enumerate(batches):
                path = batch_path(out, task, agent.name, index)
                expected.add(path)
                record, why = _read_record(path, study, task, agent.name, seeds)
                if why:
                    files.rejected.append((path, why))
                elif record is not None and (task, agent.name) in files.cells:
                    files.merged.append(path)
                elif record is not None:
                    files.batches[task, agent.name, index] = record
    found = [*(out / CELLS).glob("*"), *(out / BATCHES).glob("*/*")]
    files.rejected += [(path, "is not a file of this deep study (no cell or batch of it has this name)")
                       for path in sorted(found) if path not in expected and not path.name.startswith(".tmp-")]
    return files


def _write(path: Path, data: dict[str, Any]) -> None:
    """A file of the folder, its keys in their order (the study's tasks, a record's emotions), atomically."""
    write_atomic(path, json.dumps(data, indent=1).encode())


def _claim_folder(study: DeepStudy, out: Path) -> None:
    """Write ``OUT/deep_study.json``, or refuse a folder that holds another study's results (one line)."""
    marker = out / STUDY_FILE
    data = study.model_dump(mode="json")
    if os.path.lexists(marker):
        try:
            saved = read_json(marker, MAX_STUDY_BYTES)
            same = DeepStudy.model_validate(saved).model_dump(mode="json") == data  # keys added since: their defaults
        except ValueError:  # (UnreadableFile and pydantic's ValidationError: ValueErrors)
            same = False
        if not same:
            raise StoreError(f"{out} holds the results of another deep study ({marker} differs): give another --out")
        return
    if any(path.name not in (".lock", ".lock.owner") for path in out.iterdir()):
        raise StoreError(f"{out} is not empty and holds no {STUDY_FILE}: give an empty or new folder")
    _write(marker, data)


def _clear_stale(out: Path) -> None:
    """Remove the temporary files a writer killed mid-write left (``regular_files.replacing``'s ``.tmp-*``)."""
    for stale in [*(out / CELLS).glob(".tmp-*"), *(out / BATCHES).glob("*/.tmp-*"), *(out / "failed").glob(".tmp-*")]:
        with contextlib.suppress(OSError):
            stale.unlink()


def _print(line: str) -> None:
    print(line, flush=True)


def batch_id(task: str, agent: str, index: int) -> str:
    """A batch's name in ``OUT/failed/``."""
    return f"{task}__{agent}__{index}"


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
    Run every batch of ``study`` not yet in ``out`` (tasks x agents, each cell's seeds in batches) on the executor,
    holding the folder's lock (``StoreError`` at once when another launcher holds it).

    :param workers: local processes (None: the usable CPUs; 1: in this process), or at most this many Ray tasks at a time
    :param backend: ``"local"`` or ``"ray"`` (one Ray task per batch)
    :param ray_address: the Ray cluster (default: a private instance of ``workers`` CPUs)
    :param ray_timeout: seconds to wait for the Ray cluster to answer
    :param log: where one line per finished batch, per finished cell and per file set aside goes (default: printed)
    """
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r} is not supported; choose {' or '.join(map(repr, BACKENDS))}")
    out = Path(out)
    claim_kind(out, "deep", study.name)
    planned = len(seed_batches(study)) * len(study.tasks) * len(study.agents)
    at_once = 1 if backend == "ray" else min(workers or len(os.sched_getaffinity(0)), planned)  # (Ray: one a node)
    training().check_study(study, at_once)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise store_error(out, error) from None
    store = ResultsStore(out)
    with store.lock():
        _claim_folder(study, out)
        _clear_stale(out)
        files = sort_files(out, study)
        for line in store.set_aside(files.rejected):
            (log or _print)(line)
        for path in files.merged:
            path.unlink()
            with contextlib.suppress(OSError):  # (a file the folder holds besides the batches stays)
                path.parent.rmdir()
        return _run(study, out, store, files, workers, backend, ray_address, ray_timeout, log or _print)


def _run(
    study: DeepStudy,
    out: Path,
    store: ResultsStore,
    files: DeepFiles,
    workers: int | None,
    backend: str,
    ray_address: str | None,
    ray_timeout: float,
    log: Callable[[str], None],
) -> DeepSummary:
    """``run_deep_study`` in a claimed and locked folder whose files that count are ``files``."""
    start = time.perf_counter()
    cap = workers
    workers = workers or len(os.sched_getaffinity(0))
    batches = seed_batches(study)
    names = [agent.name for agent in study.agents]
    cells, finished = files.cells, files.batches
    reused = len(cells)
    todo = [(task, index) for task in study.tasks for index, name in enumerate(names) if (task, name) not in cells]
    data = study.model_dump(mode="json")
    counts = {"cells": 0, "batches": 0}
    failures: list[str] = []

    def jobs_of(task: str, index: int) -> list[DeepBatch]:
        source = study.agents[index].replays
        epsilons = None if source is None else tuple(replayed_epsilons(cells[task, source]))
        return [DeepBatch(data, task, index, k, seeds, epsilons) for k, seeds in enumerate(batches)
                if (task, names[index], k) not in finished]

    def finish_cell(task: str, name: str) -> None:
        records = [finished.get((task, name, k)) for k in range(len(batches))]
        if any(record is None for record in records):
            return
        cell = merge_batches(records)  # type: ignore[arg-type]
        _write(cell_path(out, task, name), cell)
        for k in range(len(batches)):
            batch_path(out, task, name, k).unlink()
            del finished[task, name, k]
        with contextlib.suppress(OSError):  # (a file the folder holds besides the batches stays)
            batch_path(out, task, name, 0).parent.rmdir()
        cells[task, name] = cell
        counts["cells"] += 1
        final = [row[-1] for row in cell["success"] if row and row[-1] is not None]
        log(f"   {task} {name}: {len(cell['seeds'])} seeds, final greedy success "
            f"{np.mean(final) if final else math.nan:.2f}, {cell['seconds']:.1f} CPU s")

    def on_result(job: DeepBatch, result: dict[str, Any]) -> None:
        name = names[job.agent]
        _write(batch_path(out, job.task, name, job.index), result["record"])
        finished[job.task, name, job.index] = result["record"]
        with contextlib.suppress(FileNotFoundError):
            (store.failed / f"{batch_id(job.task, name, job.index)}.json").unlink()
        counts["batches"] += 1
        log(f"   {job.task} {name}: batch {job.index + 1}/{len(batches)} (seeds {', '.join(map(str, job.seeds))}) done")
        finish_cell(job.task, name)

    def on_failure(job: DeepBatch, error: str) -> None:
        name = names[job.agent]
        store.write_failure(batch_id(job.task, name, job.index),
                            {"task": job.task, "agent": name, "seeds": list(job.seeds)}, error)
        failures.append(f"{job.name}: {error.strip().splitlines()[-1] if error.strip() else error}")

    def run_jobs(jobs: list[DeepBatch]) -> None:
        if backend == "ray":
            run_ray(jobs, workers, on_result, on_failure, ray_address, cap=cap, timeout=ray_timeout)
        elif workers == 1:
            for job in jobs:
                try:
                    result = job.execute()
                except (KeyboardInterrupt, StoreError):
                    raise
                except Exception:
                    on_failure(job, traceback.format_exc())
                    continue
                on_result(job, result)
        else:
            run_local(jobs, workers, on_result, on_failure)

    while todo:
        wave = [cell for cell in todo if study.agents[cell[1]].replays in (None, *(n for t, n in cells if t == cell[0]))]
        if not wave:  # (the schema puts a replayed agent before its replay: only a failed source leaves this)
            break
        todo = [cell for cell in todo if cell not in wave]
        jobs = [job for task, index in wave for job in jobs_of(task, index)]
        for task, index in wave:  # a cell whose batches were all done before an interruption
            if not any(job.task == task and job.agent == index for job in jobs):
                finish_cell(task, names[index])
        if jobs:  # (no Ray instance nor worker started for nothing)
            run_jobs(jobs)
    if failures or todo:
        waiting = f"; {len(todo)} cells wait for them" if todo else ""
        first = f": the first: {failures[0]}" if failures else ""
        raise StoreError(f"{len(failures)} batches of the deep study failed{waiting} (the finished ones are kept; "
                         f"tracebacks in {store.failed}; rerun to retry){first}")
    return DeepSummary(study.name, counts["cells"], reused, counts["batches"], time.perf_counter() - start, out)


def saved_study(out: Path) -> tuple[dict[str, Any], DeepStudy]:
    """The study a deep study's folder holds: its file's data and the validated study; ``StoreError`` (one line)."""
    try:
        data = read_json(out / STUDY_FILE, MAX_STUDY_BYTES)
        return data, DeepStudy.model_validate(data)
    except ValueError as error:  # (UnreadableFile and pydantic's ValidationError: ValueErrors)
        raise StoreError(f"{out / STUDY_FILE} is not a valid deep study ({' '.join(str(error).split())[:200]}); "
                         "rerun `sb3-affect run FILE --out DIR` into a new folder") from None


def deep_status(out: Path) -> list[str]:
    """
    ``sb3-affect status`` of a deep study's folder: cells done of planned, each cell's batches done, failed batches,
    the files that do not count and the launcher running. Reads only; ``StoreError`` when its study is unreadable.
    """
    study = saved_study(out)[1]
    batches = seed_batches(study)
    files = sort_files(out, study)
    store = ResultsStore(out)
    failed = {p.stem for p in store.failed.glob("[!.]*.json")}
    lines = []
    for task in study.tasks:
        for agent in study.agents:
            if (task, agent.name) in files.cells:
                state = f"done ({len(study.seeds)} seeds)"
            else:
                done = sum((task, agent.name, k) in files.batches for k in range(len(batches)))
                state = f"{done}/{len(batches)} batches done" if done else "not started"
                missed = sum(batch_id(task, agent.name, k) in failed for k in range(len(batches)))
                state += f", {missed} failed" if missed else ""
            lines.append(f"  {task:16s} {agent.name:24s} {state}")
    for path, why in files.rejected:
        lines.append(f"  not counted: {path} {why}; the next run moves it to damaged/ and runs its batches again")
    owner = store.lock_owner()
    if owner is not None:
        lines.append(f"  in use by launcher pid {owner} (running)")
    planned = len(study.tasks) * len(study.agents)
    return [f"deep study {study.name!r} in {out}: {len(files.cells)}/{planned} cells done (task x agent, "
            f"{len(study.seeds)} seeds each in {len(batches)} batch{'es' if len(batches) > 1 else ''})", *lines]


def read_cells(out: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """
    A deep study's folder as the report reads it: its study (the file's data) and its finished cells, in the order of
    tasks, then agents; ``StoreError`` naming the first file that does not count (a rerun sets it aside).
    """
    data, study = saved_study(out)
    files = sort_files(out, study)
    if files.rejected:
        path, why = files.rejected[0]
        more = f" (and {len(files.rejected) - 1} more)" if len(files.rejected) > 1 else ""
        raise StoreError(f"{path} {why}{more}; rerun the study into {out} (the same `sb3-affect run` command) to move "
                         "it to damaged/ and run its batches again")
    cells = [files.cells[task, agent.name] for task in study.tasks for agent in study.agents
             if (task, agent.name) in files.cells]
    return data, cells
