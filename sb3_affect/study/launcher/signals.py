"""
Signals of the study's long commands, in one place: the CLI, the launcher, the Ray backend and the forensics share them.

- A driver (``sb3-affect run``, ``replicate``, ``forensics``) stops on SIGTERM (``kill``, a batch scheduler) as on
  Ctrl-C: ``stop_on_sigterm`` makes SIGTERM raise ``Terminated``, a ``KeyboardInterrupt``; the command exits 143.
- While it starts child processes it ignores SIGINT (``sigint_ignored``): the children inherit "ignore SIGINT", so a
  Ctrl-C in the terminal, sent to the whole process group, reaches only the driver, which stops them.
- A worker (``worker_signals``) ignores SIGINT, ends at once on SIGTERM and dies with its driver (Linux).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import threading
from collections.abc import Iterator

#: The signals a driver blocks around a fork, so that a new worker does not run the driver's handlers.
STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch scheduler): stop like Ctrl-C, workers first, then exit 143."""


def _on_sigterm(signum: int, frame: object) -> None:
    raise Terminated()


def stop_on_sigterm() -> None:
    """Make SIGTERM raise ``Terminated`` in this process (only the main thread can set a handler; elsewhere: nothing)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _on_sigterm)


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while starting child processes (they keep ignoring it); restore our handler afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def die_with_parent() -> None:
    """Ask Linux to kill this process when its parent dies (best effort; no-op elsewhere)."""
    with contextlib.suppress(Exception):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def worker_signals(parent: int | None = None) -> None:
    """
    A worker's signals: the driver decides what Ctrl-C does (SIGINT ignored), the driver's SIGTERM ends the worker at
    once, even mid-kernel (default action), and the worker does not outlive its driver. ``parent``: the driver's pid;
    if it died before the worker could ask to die with it, the worker exits now.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    die_with_parent()
    if parent is not None and os.getppid() != parent:
        os._exit(1)
