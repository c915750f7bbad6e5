"""
Run a sweep: skip finished runs, execute the rest on a backend, store each result as it arrives.

Backends:

* ``local``: one forked process per run, at most ``workers`` at a time. A run that raises is recorded with its
  traceback; a worker that dies (``os._exit``, a signal, out of memory) is recorded as failed with its exit code,
  without touching the other runs. Ctrl-C stops every worker before the launcher exits; workers also die with the
  launcher if it is killed (Linux ``PR_SET_PDEATHSIG``).
* ``ray``: Ray core tasks (``pip install sb3-affect[ray]``), on the cluster at ``ray_address`` (the code shipped with
  the job, node versions checked, at most ``workers`` tasks at a time if given; see ``ray_cluster``) or on a private
  instance started for the sweep (dashboard off, bound to 127.0.0.1). Results and logs are written by the driver only,
  so a retried task can not write twice.

Either way the driver is the only writer, and a run's result depends only on its config: the same seed gives the
same per-episode records on either backend.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
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


def run_ray(
    tasks: list[Task],
    workers: int,
    formats: tuple[str, ...],
    on_result: OnResult,
    on_failure: OnFailure,
    address: str | None = None,
    cap: int | None = None,
    timeout: float = 60.0,
) -> None:
    """
    Run ``tasks`` as Ray core tasks on the cluster at ``address`` (at most ``cap`` at a time), or on a private instance
    of ``workers`` CPUs started and stopped here; connection, shipping the code, version checks and a lost cluster are
    handled in :mod:`sb3_affect.experiments.ray_cluster`.
    """
    from sb3_affect.experiments import ray_cluster
    from sb3_affect.experiments.runner import package_versions

    with ray_cluster.connect(address, workers, timeout) as session:
        ours = package_versions() if address else None
        remote = session.ray.remote(num_cpus=1, max_retries=1)(ray_cluster.execute_task)

        def on_value(task: Task, value: tuple[Any, ...]) -> None:
            rid, config, log_dir = task
            if value[0] != "ok":
                on_failure(rid, config, value[1])
                return
            _, result, logs = value
            differences = ray_cluster.version_differences(ours, result["versions"]) if ours else []
            if differences:  # a node that joined after the check
                host = result["timings"].get("host")
                on_failure(rid, config, f"ran on {host} with other package versions: {', '.join(differences)}")
                return
            if log_dir is not None:
                ray_cluster.write_logs(log_dir, logs)
            on_result(rid, config, result)

        def on_error(task: Task, error: BaseException) -> None:  # the worker died (after Ray's retry), or Ray failed
            text = ray_cluster.plain_text(str(error))
            on_failure(task[0], task[1], f"the Ray task failed: {type(error).__name__}: {text}")

        session.run(tasks, lambda task: remote.remote(task[1], task[2], formats), on_value, on_error, cap=cap)


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
    """
    if backend not in ("local", "ray"):
        raise ValueError(f"backend={backend!r} is not supported; choose 'local' or 'ray'")
    cap = workers  # a share of a Ray cluster: only when asked for
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
                run_ray(tasks, workers, formats, on_result, on_failure, ray_address, cap=cap, timeout=ray_timeout)
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
