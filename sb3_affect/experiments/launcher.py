"""
Run a sweep: skip finished runs, execute the rest on a backend, store each result as it arrives.

Backends:

* ``local``: one forked process per run, at most ``workers`` at a time. A run that raises is recorded with its
  traceback; a worker that dies (``os._exit``, a signal, out of memory) is recorded as failed with its exit code,
  without touching the other runs. Ctrl-C stops every worker before the launcher exits; workers also die with the
  launcher if it is killed (Linux ``PR_SET_PDEATHSIG``).
* ``ray``: Ray core tasks (``pip install sb3-affect[ray]``), on the cluster at ``ray_address`` or on a local
  instance started for the sweep (dashboard off, bound to 127.0.0.1). Results are written by the driver only, so a
  retried task can not write twice.

Either way the driver is the only writer, and a run's result depends only on its config: the same seed gives the
same per-episode records on either backend.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
import re
import signal
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sb3_affect.experiments.runner import execute_run
from sb3_affect.experiments.schema import load_sweep
from sb3_affect.experiments.store import ResultsStore, run_id

Task = tuple[str, dict[str, Any], str | None]  # run id, config, log dir
OnResult = Callable[[str, dict[str, Any], dict[str, Any]], None]
OnFailure = Callable[[str, dict[str, Any], str], None]


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


def _die_with_parent() -> None:
    """Ask Linux to kill this worker when the launcher dies (best effort; no-op elsewhere)."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def _worker(config: dict[str, Any], log_dir: str | None, formats: tuple[str, ...], conn: Any, launcher: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the launcher decides what Ctrl-C does
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # and stops a worker with SIGTERM (not the launcher's handler)
    _die_with_parent()
    if os.getppid() != launcher:  # the launcher died before the line above took effect
        os._exit(1)
    try:
        message: tuple[str, Any] = ("ok", execute_run(config, log_dir, formats))
    except BaseException:
        message = ("error", traceback.format_exc())
    conn.send(message)
    conn.close()


def _describe_exit(code: int | None) -> str:
    if code is not None and code < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-code).name}"
    return f"exit code {code}"


def run_local(tasks: list[Task], workers: int, formats: tuple[str, ...], on_result: OnResult, on_failure: OnFailure) -> None:
    """Run ``tasks`` in forked worker processes, ``workers`` at a time."""
    from sb3_affect.kernel import warm_up

    warm_up()  # the compiled engine's kernels, loaded once here (no torch) instead of in every worker
    context = multiprocessing.get_context("fork")
    queue = deque(tasks)
    running: dict[str, tuple[Any, Any, dict[str, Any]]] = {}
    try:
        while queue or running:
            while queue and len(running) < workers:
                rid, config, log_dir = queue.popleft()
                receiver, sender = context.Pipe(duplex=False)
                args = (config, log_dir, formats, sender, os.getpid())
                process = context.Process(target=_worker, args=args, name=f"sb3-affect:{rid}")
                process.start()
                sender.close()
                running[rid] = (process, receiver, config)
            waitables = [r for _, r, _ in running.values()] + [p.sentinel for p, _, _ in running.values()]
            multiprocessing.connection.wait(waitables, timeout=1.0)
            for rid, (process, receiver, config) in list(running.items()):
                message = None
                if receiver.poll():
                    try:
                        message = receiver.recv()
                    except (EOFError, OSError):
                        message = None
                elif process.is_alive():
                    continue
                process.join(timeout=30)
                receiver.close()
                del running[rid]
                if message is None:
                    on_failure(
                        rid, config, f"the worker process died before returning a result ({_describe_exit(process.exitcode)})"
                    )
                elif message[0] == "ok":
                    on_result(rid, config, message[1])
                else:
                    on_failure(rid, config, message[1])
    finally:
        for process, _receiver, _ in running.values():
            if process.is_alive():
                process.terminate()
        for process, receiver, _ in running.values():
            process.join(timeout=3)
            if process.is_alive():
                process.kill()
                process.join()
            receiver.close()


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while starting child processes (they keep ignoring it); restore our handler afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _ray_execute(config: dict[str, Any], log_dir: str | None, formats: tuple[str, ...]) -> tuple[str, Any]:
    """A Ray task: ``("ok", result)`` or ``("error", traceback)`` (the same failure record as the local backend)."""
    try:
        return "ok", execute_run(config, log_dir, formats)
    except Exception:
        return "error", traceback.format_exc()


def run_ray(
    tasks: list[Task],
    workers: int,
    formats: tuple[str, ...],
    on_result: OnResult,
    on_failure: OnFailure,
    address: str | None = None,
) -> None:
    """Run ``tasks`` as Ray core tasks; start (and stop) a local Ray instance unless one is running or given."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if not address:
        # A private single-machine instance: Ray rewrites 127.0.0.1 to the machine's address (and its gRPC servers then
        # listen on every interface) unless "clusters" are disabled, which Ray reads when it is first imported; with
        # this every Ray process listens on 127.0.0.1 only (checked with ``ss -ltnp`` in tests/test_experiments_ray.py).
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    try:
        import ray
    except ImportError:
        raise RuntimeError("the ray backend needs Ray: pip install 'sb3-affect[ray]'") from None
    started = False
    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            # Ctrl-C in a terminal sends SIGINT to the whole process group: the instance's processes inherit "ignore
            # SIGINT" from here, so that only this driver reacts (cancels the tasks and shuts the instance down).
            with _sigint_ignored():
                ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, _node_ip_address="127.0.0.1")
        started = True
    pending: dict[Any, tuple[str, dict[str, Any]]] = {}
    try:
        remote = ray.remote(num_cpus=1, max_retries=1)(_ray_execute)
        pending = {remote.remote(config, log_dir, formats): (rid, config) for rid, config, log_dir in tasks}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            rid, config = pending.pop(done[0])
            try:
                status, result = ray.get(done[0])
            except Exception as error:  # the worker died (after Ray's retry), or Ray could not run the task
                on_failure(rid, config, f"the Ray task failed: {type(error).__name__}: {_plain_text(str(error))}")
            else:
                if status == "ok":
                    on_result(rid, config, result)
                else:
                    on_failure(rid, config, result)
    finally:
        # Ctrl-C or an error: ``ray.shutdown`` ends this job, and Ray stops the job's tasks with it (and a local
        # instance we started). No ``ray.cancel(force=True)`` of the pending tasks: racing with tasks that are just
        # finishing, it crashes the driver inside Ray ("Tried to complete task that was not pending", Ray 2.60).
        # On an instance the caller started (``ray.init`` before ``run_sweep``), pending tasks finish unobserved.
        if started:
            ray.shutdown()


def _plain_text(text: str) -> str:
    """Ray's error messages without their terminal colour codes."""
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


def run_sweep(
    sweep_path: str | Path,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    overrides: tuple[str, ...] | list[str] = (),
    progress: bool = True,
) -> SweepSummary:
    """
    Run every run of a sweep file that ``out_dir`` does not already hold, and store the results.

    Rerunning the same command resumes: finished runs are skipped, failed ones retried.

    :param sweep_path: the experiment YAML
    :param out_dir: the results folder
    :param workers: parallel runs (default: the number of CPUs)
    :param backend: ``"local"`` (process pool) or ``"ray"``
    :param ray_address: a Ray cluster to connect to (ray backend; default: start a local instance)
    :param overrides: ``key=value`` assignments applied to the file before validation (``--set``)
    :param progress: show a progress bar
    """
    if backend not in ("local", "ray"):
        raise ValueError(f"backend={backend!r} is not supported; choose 'local' or 'ray'")
    workers = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()) or 1
    if workers < 1:
        raise ValueError(f"workers={workers} must be >= 1")
    start = time.perf_counter()
    sweep = load_sweep(sweep_path, tuple(overrides))
    configs = sweep.run_configs()
    ids = [run_id(c) for c in configs]
    resolved = {"name": sweep.name, "sweep": sweep.model_dump(mode="json"), "runs": dict(zip(ids, configs))}
    store = ResultsStore(out_dir)
    try:
        store.root.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        from sb3_affect.experiments.store import _store_error

        raise _store_error(store.root, error) from None
    with store.lock():
        store.prepare(resolved)
        done = store.done_ids()
        tasks: list[Task] = [
            (rid, config, str(store.logs / rid) if sweep.logs else None)
            for rid, config in zip(ids, configs)
            if rid not in done
        ]
        counts = {"finished": 0, "failed": 0}
        bar = _progress(len(configs), len(configs) - len(tasks), sweep.name, progress)

        def on_result(rid: str, config: dict[str, Any], result: dict[str, Any]) -> None:
            store.write_run(rid, config, result)
            counts["finished"] += 1
            bar.update(1)

        def on_failure(rid: str, config: dict[str, Any], error: str) -> None:
            store.write_failure(rid, config, error)
            counts["failed"] += 1
            bar.update(1)
            bar.set_postfix(failed=counts["failed"])

        try:
            formats = tuple(sweep.logs) or ("csv",)
            if not tasks:
                pass  # everything is done already: start no workers (nor a Ray instance)
            elif backend == "local":
                run_local(tasks, workers, formats, on_result, on_failure)
            else:
                run_ray(tasks, workers, formats, on_result, on_failure, address=ray_address)
        finally:
            bar.close()
    return SweepSummary(
        sweep.name,
        len(configs),
        len(configs) - len(tasks),
        counts["finished"],
        counts["failed"],
        time.perf_counter() - start,
        Path(out_dir),
    )


def _progress(total: int, initial: int, name: str, enabled: bool) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, initial=initial, desc=name, unit="run", disable=not enabled, dynamic_ncols=True)
