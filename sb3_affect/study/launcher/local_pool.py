"""
The ``local`` backend: jobs in forked worker processes, at most ``workers`` at a time.

A batch (``batches.Batch``: one ``engine.simulate`` call, a pure function of its config), or any other unit of work
that is not a single run (``batches.Work``: a deep study's or the forensics' batch), runs in a long-lived worker, which
is forked once and then takes unit after unit over a pipe: the fork, and the copy-on-write and page faults that follow
it, are paid once per worker instead of once per unit. A single run (``batches.Single``: DQN, a user's class, a run
with logs) keeps a fresh process of its own, as it always had, so nothing one run leaves in a process
(global random states, warnings filters, registered envs, torch settings) can reach another; the process exits
after that one run.

A job that raises is recorded with its traceback (for each of its runs); a worker that dies (``os._exit``, a signal,
out of memory) is recorded as failed with its exit code, for the job it was running only, and a new worker takes the
next job. Ctrl-C stops every worker before the launcher exits; workers also die with the launcher if it is killed
(Linux ``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import os
import signal
import traceback
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from sb3_affect.kernel import warm_up
from sb3_affect.study.launcher.batches import Batch, Single, Work
from sb3_affect.study.launcher.one_run import package_versions
from sb3_affect.study.launcher.signals import STOP_SIGNALS, worker_signals

W = TypeVar("W", bound=Work)
OnResult = Callable[[W, dict[str, Any]], None]
OnFailure = Callable[[W, str], None]

def _execute(job: Work) -> tuple[str, Any]:
    try:
        return "ok", job.execute()
    except BaseException:
        return "error", traceback.format_exc()


def _worker(first: Work, conn: Any, launcher: int) -> None:
    """A worker's life: ``first``, then (a long-lived worker) every job the launcher sends, until it sends None."""
    worker_signals(launcher)  # Ctrl-C is the launcher's; its SIGTERM stops the worker; the worker dies with it
    job: Work | None = first
    while job is not None:
        conn.send(_execute(job))
        if isinstance(job, Single):
            break  # a single run's process ends with it
        try:
            job = conn.recv()
        except (EOFError, OSError):  # the launcher has gone
            break
    conn.close()


def describe_exit(code: int | None) -> str:
    """How a worker process ended, for its failure record (``killed by SIGKILL``, ``exit code 3``)."""
    if code is not None and code < 0:
        with contextlib.suppress(ValueError):
            return f"killed by {signal.Signals(-code).name}"
    return f"exit code {code}"


def preload(jobs: Sequence[Work]) -> None:
    """
    Load here, once, what every forked worker would otherwise load again: every kernel of the compiled engine (no torch),
    ``simulate``, the Parquet writer and the package versions the chunks record (no pandas: the chunks are written
    from NumPy arrays).
    """
    if not any(isinstance(job, Batch) for job in jobs):
        return
    warm_up()
    package_versions()


@dataclass
class _Worker(Generic[W]):
    """A worker process, the launcher's end of its pipe and the job it is running (None: idle, a long-lived worker)."""

    process: Any
    conn: Any
    job: W | None


def run_local(jobs: Sequence[W], workers: int, on_result: OnResult[W], on_failure: OnFailure[W]) -> None:
    """
    Run ``jobs`` in forked worker processes, ``workers`` at a time (see the module's docstring): any ``Work``, a
    ``Single`` in a process of its own, anything else in long-lived workers.
    """
    preload(jobs)
    context = multiprocessing.get_context("fork")
    queue = deque(jobs)
    pool: list[_Worker[W]] = []

    def start(job: W) -> None:
        mine, theirs = context.Pipe(duplex=True)
        process = context.Process(target=_worker, args=(job, theirs, os.getpid()), name=f"sb3-affect:{job.name}")
        # Ctrl-C or SIGTERM during the fork would be swallowed by an at-fork hook ("Exception ignored"): hold them
        # until the fork is done, then they stop the launcher as anywhere else.
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
        try:
            process.start()
            theirs.close()
            pool.append(_Worker(process, mine, job))
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)

    def retire(worker: _Worker[W]) -> None:
        pool.remove(worker)
        with contextlib.suppress(OSError):
            worker.conn.send(None)  # (a batch worker waits for its next job; a single run's worker has exited)
        worker.process.join(timeout=30)
        worker.conn.close()

    try:
        while queue or any(worker.job is not None for worker in pool):
            for worker in [w for w in pool if w.job is None]:  # idle long-lived workers: the next job, or retire
                if queue and not isinstance(queue[0], Single):
                    worker.job = queue.popleft()
                    try:
                        worker.conn.send(worker.job)
                    except OSError:  # it died while idle: the job goes back, the death is found below
                        queue.appendleft(worker.job)
                        worker.job = None
                        retire(worker)
                else:
                    retire(worker)  # a single run needs a process of its own (or there is nothing left to do)
            while queue and len(pool) < workers:
                start(queue.popleft())
            busy = [w for w in pool if w.job is not None]
            multiprocessing.connection.wait([w.conn for w in busy] + [w.process.sentinel for w in busy], timeout=1.0)
            for worker in busy:
                job = worker.job
                assert job is not None
                message = None
                if worker.conn.poll():
                    try:
                        message = worker.conn.recv()
                    except (EOFError, OSError):
                        message = None
                elif worker.process.is_alive():
                    continue
                if message is None:  # it died before returning the job's result
                    pool.remove(worker)
                    worker.process.join(timeout=30)
                    worker.conn.close()
                    how = describe_exit(worker.process.exitcode)
                    on_failure(job, f"the worker process died before returning a result ({how})")
                    continue
                worker.job = None
                if isinstance(job, Single):
                    retire(worker)
                if message[0] == "ok":
                    on_result(job, message[1])
                else:
                    on_failure(job, message[1])
    finally:
        for worker in pool:
            if worker.process.is_alive():
                worker.process.terminate()
        for worker in pool:
            worker.process.join(timeout=3)
            if worker.process.is_alive():
                worker.process.kill()
                worker.process.join()
            worker.conn.close()
