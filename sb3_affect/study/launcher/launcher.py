"""
Run a sweep: skip finished runs, execute the rest on a backend, store each result as it arrives.

The runs are cut into jobs (``batches``): tabular runs of this package's agents on its envs go in batches of one
cell each (one ``engine.simulate`` call, stored as one Parquet chunk), the deep study's runs (a sweep with a
``trainer``) in deep batches of one cell each (``deep_batches``: seeds trained together by ``train_many``, their
evaluations stored as one chunk), the forensics' replications (a sweep with ``forensics``) in the batches its
``stages`` plan (``forensics.stages``: stage after stage, each a wave), any other run is a job of its own (one JSON
file). Import and scheduling costs are paid once per job, the fork once per worker. A cell whose agent replays
another's random share waits for that agent's cell on the same task: the jobs run in waves, each wave the jobs whose
sources are done (``plan_jobs``).

Backends:

* ``local`` (``local_pool``): forked worker processes, at most ``workers`` at a time; a worker runs batch after
  batch, a single run gets a fresh process of its own. A job that raises is recorded with its traceback (for each of
  its runs); a worker that dies (``os._exit``, a signal, out of memory) is recorded as failed with its exit code, for
  its job only. Ctrl-C stops every worker before the launcher exits; workers also die with the launcher if it is
  killed (Linux ``PR_SET_PDEATHSIG``).
* ``ray``: one Ray core task per job (``pip install sb3-affect[ray]``), on the cluster at ``ray_address`` (the code
  shipped with the job, node versions checked, at most ``workers`` tasks at a time if given; see ``ray_cluster``) or on
  a private instance started for the sweep (dashboard off, bound to 127.0.0.1). Results and logs are written by the
  driver only, so a retried task can not write twice.

Either way the driver is the only writer, and a run's result depends only on its config: the same seed gives the
same per-episode records on either backend.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import sys
import time
import traceback
from collections.abc import Callable, Collection, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from sb3_affect.core.extras import require_extra
from sb3_affect.study.launcher.batches import (
    Batch,
    Job,
    Single,
    TeamBatch,
    Work,
    batch_kind,
    batch_size,
    split_cell,
)
from sb3_affect.study.launcher.deep_batches import DeepBatch, replayed_epsilons, training
from sb3_affect.study.launcher.local_pool import OnFailure, OnResult, run_local
from sb3_affect.study.launcher.one_run import package_versions
from sb3_affect.study.launcher.schema import Cell, SweepError
from sb3_affect.study.launcher.store import SWEEP_SCHEMA, ResultsStore, cell_run_ids, store_error
from sb3_affect.study.launcher.sweep_file import load_sweep

#: A study's own planner of its waves (the forensics' ``stages.plan_stages``): ``stages(study, cells, cell_ids, store,
#: workers, tried)``, the next wave's jobs ([]: none now).
Stages = Callable[..., list[Job]]


@dataclass
class SweepSummary:
    """What a call to ``run_sweep`` did."""

    name: str
    total: int
    skipped: int
    finished: int
    failed: int
    seconds: float
    out_dir: Path


def _ray_batch(job: Work) -> tuple[str, Any]:
    """A Ray task running a batch (any ``Work``): ``("ok", result)`` or ``("error", traceback)`` (as on the local backend)."""
    try:
        return "ok", job.execute()
    except Exception:
        return "error", traceback.format_exc()


#: An executor's one call: run ``jobs``, handing each outcome to ``on_result`` or ``on_failure`` (``executor``).
Execute = Callable[[Sequence[Job], OnResult[Job], OnFailure[Job]], None]


@contextlib.contextmanager
def executor(
    backend: str, workers: int, address: str | None = None, cap: int | None = None, timeout: float = 60.0
) -> Iterator[Execute]:
    """
    The one executor of a launch, started once for all its waves: ``local`` (``local_pool.run_local``: at most
    ``workers`` forked workers a wave) or ``ray``: the jobs as Ray core tasks on the cluster at ``address`` (at most
    ``cap`` at a time), or on a private instance of ``workers`` CPUs started here and stopped on leaving; connection,
    shipping the code, version checks and a lost cluster are handled in :mod:`sb3_affect.study.launcher.ray_cluster`.
    A batch (or any other ``Work``) is one task (its ``execute``), a lone run one ``ray_cluster.execute_task``.
    """
    if backend == "local":
        yield lambda jobs, on_result, on_failure: run_local(jobs, workers, on_result, on_failure)
        return
    require_extra("ray", "the ray backend")
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if not address:
        # A private single-machine instance: Ray rewrites 127.0.0.1 to the machine's address (and its gRPC servers then
        # listen on every interface) unless "clusters" are disabled, which Ray reads when it is first imported (here,
        # with ray_cluster): every Ray process then listens on 127.0.0.1 only (``ss -ltnp`` in test_experiments_ray.py).
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    import sb3_affect.study.launcher.ray_cluster as ray_cluster  # (the ray extra; after the environment Ray reads)

    with ray_cluster.connect(address, workers, timeout) as session:
        ours = package_versions() if address else None
        remote = session.ray.remote(num_cpus=1, max_retries=1)(ray_cluster.execute_task)
        remote_batch = session.ray.remote(num_cpus=1, max_retries=1)(_ray_batch)

        def execute(jobs: Sequence[Job], on_result: OnResult[Job], on_failure: OnFailure[Job]) -> None:
            def submit(job: Job) -> Any:
                if isinstance(job, Single):
                    return remote.remote(job.config, job.log_dir, job.formats)
                return remote_batch.remote(job)

            def on_value(job: Job, value: tuple[Any, ...]) -> None:
                if value[0] != "ok":
                    on_failure(job, value[1])
                    return
                result = value[1]
                differences = ray_cluster.version_differences(ours, result["versions"]) if ours else []
                if differences:  # a node that joined after the check
                    host = result["timings"].get("host")
                    on_failure(job, f"ran on {host} with other package versions: {', '.join(differences)}")
                    return
                if isinstance(job, Single) and job.log_dir is not None:
                    ray_cluster.write_logs(job.log_dir, value[2])
                on_result(job, result)

            def on_error(job: Job, error: BaseException) -> None:  # the worker died (after Ray's retry), or Ray failed
                on_failure(job, f"the Ray task failed: {type(error).__name__}: {ray_cluster.plain_text(str(error))}")

            session.run(list(jobs), submit, on_value, on_error, cap=cap)

        yield execute


def run_sweep(
    sweep_path: str | Path,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
    overrides: tuple[str, ...] | list[str] = (),
    progress: bool = True,
    stages: Stages | None = None,
) -> SweepSummary:
    """
    Run every run of a sweep file that ``out_dir`` does not already hold, and store the results.

    Rerunning the same command resumes: finished runs are skipped, failed ones retried.

    :param sweep_path: the experiment YAML
    :param out_dir: the results folder
    :param workers: parallel runs (default: the number of CPUs; on a Ray cluster: as many as its CPUs allow)
    :param backend: ``"local"`` (process pool) or ``"ray"``
    :param ray_address: a Ray cluster to connect to (ray backend; default: start a local instance)
    :param ray_timeout: seconds to wait for the Ray cluster to answer before giving up with a message
    :param overrides: ``key=value`` assignments applied to the file before validation (``--set``)
    :param progress: show a progress bar
    :param stages: the planner of a study run in stages (the forensics': ``forensics.stages.plan_stages``)
    """
    if backend not in ("local", "ray"):
        raise ValueError(f"backend={backend!r} is not supported; choose 'local' or 'ray'")
    cap = workers  # a share of a Ray cluster: only when asked for
    workers = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()) or 1
    if workers < 1:
        raise ValueError(f"workers={workers} must be >= 1")
    start = time.perf_counter()
    sweep = load_sweep(sweep_path, tuple(overrides), deep=True)
    if sweep.kind != "forensics":
        stages = None  # (a sweep of runs, the deep study: planned by plan_jobs itself)
    elif stages is None:
        raise SweepError(f"{sweep_path}: the forensics runs in stages: pass stages=forensics.stages.plan_stages, or run "
                         f"it with `sb3-affect run {sweep_path} --out DIR`")
    else:
        stages = functools.partial(stages, sweep)
    cells = sweep.cells()
    cell_ids = [cell_run_ids(cell) for cell in cells]
    total = sum(len(ids) for ids in cell_ids)
    resolved = {"schema": SWEEP_SCHEMA, "name": sweep.name, "sweep": sweep.model_dump(mode="json"), "total_runs": total}
    if sweep.tasks:  # the file's order of the tasks (sweep.json sorts them)
        resolved["task_order"] = list(sweep.tasks)
    store = ResultsStore(out_dir)
    store.claim(resolved)  # (before the lock file: a folder of another kind is left as it was)
    if sweep.kind == "deep":  # every agent built once, the memory estimated: before the folder is claimed
        batches = sum(math.ceil(len(cell.seeds) / (cell.batch_size or 1)) for cell in cells)
        training().check_study(sweep, 1 if backend == "ray" else min(workers, batches))  # (Ray: one a node)
    try:
        store.root.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise store_error(store.root, error) from None
    with store.lock():
        for line in store.prepare(resolved, [rid for ids in cell_ids for rid in ids]):
            print(f"sb3-affect: {line}", file=sys.stderr, flush=True)
        done = store.done_ids()
        jobs = plan_jobs(cells, cell_ids, store, workers, sweep.logs, done=done, stages=stages)
        # A study run in stages runs the runs its stages ask for, not every run its cells could hold (the forensics
        # replicates its leaders only): its total is the runs done and those of each wave planned so far.
        planned = total if stages is None else len(done) + sum(job.size for job in jobs)
        if stages is not None:
            store.record_plan((rid for job in jobs for rid in _ids(job)), final=not jobs)
        counts = {"finished": 0, "failed": 0}
        bar = _progress(planned, len(done), sweep.name, progress)
        tried: set[str] = set()  # the runs of this launch's jobs: a failed one waits for the next launch

        def on_result(job: Job, result: dict[str, Any]) -> None:
            if isinstance(job, TeamBatch):
                store.write_run_files(result["files"])
            elif isinstance(job, Batch):
                store.write_chunk(job.name, result["chunk"], result["run_ids"])
            else:
                store.write_run(job.run_id, job.config, result)
            counts["finished"] += job.size
            bar.update(job.size)

        def on_failure(job: Job, error: str) -> None:
            for rid, config in job.failures():
                store.write_failure(rid, config, error)
            counts["failed"] += job.size
            bar.update(job.size)
            bar.set_postfix(failed=counts["failed"])

        execute: Execute | None = None
        try:
            with contextlib.ExitStack() as started:
                while jobs:  # (nothing to do: no workers, nor a Ray instance, started)
                    tried.update(rid for job in jobs for rid in _ids(job))
                    if execute is None:  # (the first wave: one executor, one Ray instance, for every wave)
                        execute = started.enter_context(executor(backend, workers, ray_address, cap, ray_timeout))
                    execute(jobs, on_result, on_failure)
                    waves = stages is not None or any(cell.base.get("replays") for cell in cells)  # (a sweep of runs: one)
                    jobs = plan_jobs(cells, cell_ids, store, workers, sweep.logs, tried, stages=stages) if waves else []
                    if stages is not None:  # (no wave left: every stage planned, unless a failed unit holds one back)
                        store.record_plan((rid for job in jobs for rid in _ids(job)), final=not jobs and not counts["failed"])
                        planned += sum(job.size for job in jobs)
                        bar.total = planned
                        bar.refresh()
        finally:
            bar.close()
    seconds = time.perf_counter() - start
    return SweepSummary(sweep.name, planned, len(done), counts["finished"], counts["failed"], seconds, Path(out_dir))


def _ids(job: Job) -> list[str]:
    return [job.run_id] if isinstance(job, Single) else [rid for rid, _, _ in job.runs]


def plan_jobs(
    cells: list[Cell],
    cell_ids: list[list[str]],
    store: ResultsStore,
    workers: int,
    logs: list[str],
    tried: Collection[str] = (),
    done: set[str] | None = None,
    stages: Stages | None = None,
) -> list[Job]:
    """
    The jobs of the runs ``store`` does not hold yet (nor ``tried``): batches of the cells that can run as batches (at
    most ``batch_size`` runs each, or the cell's own ``batch_size``), deep batches of the deep study's cells whose
    ``replays`` source is done (a cell waiting for its source: no job yet), one job per run for the others (with its
    log folder when ``logs`` asks for one). ``done``: the store's finished runs, when already read. A study run in
    ``stages`` (the forensics) is planned by them, its study bound: the next stage's jobs.
    """
    if stages is not None:
        return stages(cells, cell_ids, store, workers, tried)
    done = store.done_ids() if done is None else done
    formats = tuple(logs) or ("csv",)
    todo = [[(rid, cell.seeds[i], i) for i, rid in enumerate(ids) if rid not in done and rid not in tried]
            for cell, ids in zip(cells, cell_ids)]  # fmt: skip
    kinds = [DeepBatch if cell.base.get("study") == "deep" else batch_kind(cell.base, bool(logs)) for cell in cells]
    size = batch_size(sum(len(runs) for runs, kind in zip(todo, kinds) if kind is not None), workers)
    finished = {(cell.base["labels"].get("task"), cell.base["agent"]): set(ids) <= done
                for cell, ids, kind in zip(cells, cell_ids, kinds) if kind is DeepBatch}  # (what a replaying cell waits for)
    sources: dict[tuple[str, str], dict[str, Any]] | None = None
    jobs: list[Job] = []
    for cell, runs, kind in zip(cells, todo, kinds):
        if kind is None:
            jobs.extend(
                Single(rid, cell.config(i), str(store.logs / rid) if logs else None, formats) for rid, _, i in runs
            )
            continue
        batches = split_cell(cell.base, runs, cell.batch_size or size, kind)
        task, replays = cell.base["labels"].get("task"), cell.base.get("replays")
        if runs and replays is not None:
            if not finished[task, replays]:
                continue  # the next wave's
            sources = store.evaluations() if sources is None else sources
            epsilons = tuple(replayed_epsilons(sources[task, replays]))
            batches = [DeepBatch(batch.name, batch.base, batch.runs, epsilons) for batch in batches]
        jobs.extend(batches)
    return jobs


class _NoProgress:
    """The progress bar's methods, doing nothing (``--no-progress``)."""

    def update(self, n: int = 1) -> None:
        pass

    def set_postfix(self, **kwargs: Any) -> None:
        pass

    def close(self) -> None:
        pass

    def refresh(self) -> None:
        pass


def _progress(total: int, initial: int, name: str, enabled: bool) -> Any:
    if not enabled:
        return _NoProgress()

    return tqdm(total=total, initial=initial, desc=name, unit="run", disable=not enabled, dynamic_ncols=True)
