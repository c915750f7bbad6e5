"""
``sb3-affect run``, ``forensics`` and ``replicate`` with ``--backend ray``, in two processes: this one starts the same
command again as a child, the Ray driver, and waits for it.

Ray's core worker ends its driver at once (exit code 1, no Python exception, no ``finally``) when an IPC call to the
raylet it is connected to fails because that raylet has died, as it does when the cluster stops: the driver can then
neither say what happened nor take its name off the results folder's lock (the operating system releases the lock
itself). Whether Python sees the loss first (``ClusterLost``) or Ray ends the process first is a race inside Ray. So
the parent, which never imports Ray, does what the child could not. When the child has ended while the
``.lock.owner`` of ``DIR`` (or of a replication's part in it) still names it, the parent stops what is left of the
child's process group (the Ray instance it started, if any), removes that record and raises ``ClusterLost``, which
the CLI prints in one line (exit 130). A child that ends as itself has taken its name off the lock, and its exit code
is passed on. Ctrl-C and SIGTERM reach the child once, through the parent (the child has a process group of its own,
in the same session); on Linux the child gets SIGTERM if the parent dies.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from sb3_affect.study.launcher.folder_lock import OWNER_NAME, is_locked
from sb3_affect.study.launcher.ray_errors import ClusterLost, head_stopped_answering, host_port
from sb3_affect.study.launcher.regular_files import read_text

#: Set in the child's environment: the child is the driver and runs the sweep itself.
DRIVER_VARIABLE = "SB3_AFFECT_RAY_DRIVER"


def is_driver() -> bool:
    """Whether this process is the child that drives Ray."""
    return os.environ.get(DRIVER_VARIABLE) == "1"


def _end_with_parent() -> None:
    """In the child before it runs: SIGTERM when the parent dies (Linux's ``PR_SET_PDEATHSIG``; elsewhere nothing)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)


def _stop_group(group: int) -> None:
    """SIGTERM, then SIGKILL, to what is left of the dead child's process group (the Ray instance it started)."""
    for how, seconds in ((signal.SIGTERM, 10.0), (signal.SIGKILL, 5.0)):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                os.killpg(group, how)
            except ProcessLookupError:
                return
            time.sleep(0.2)


def _held_by(out: Path, pid: int) -> list[Path]:
    """The folders (``out`` and its sub-folders, a replication's parts) whose ``.lock.owner`` names ``pid``, unlocked."""
    if not out.is_dir():
        return []
    held = []
    for folder in [out, *(sub for sub in sorted(out.iterdir()) if sub.is_dir() and not sub.is_symlink())]:
        try:
            fields = read_text(folder / OWNER_NAME, 100).split()
        except (OSError, ValueError):
            continue
        if fields and fields[0] == str(pid) and not is_locked(folder):
            held.append(folder)
    return held


def run_as_child(argv: list[str], out: str | Path, address: str | None) -> int:
    """
    Run ``sb3-affect ARGV`` as a child driving Ray and wait for it: its exit code, or :class:`ClusterLost` when Ray
    ended it while it held the results folder ``out`` or one of its parts (the CLI reports it like Ctrl-C: exit 130).
    """
    child = subprocess.Popen(
        [sys.executable, "-m", "sb3_affect", *argv],
        env={**os.environ, DRIVER_VARIABLE: "1"},
        stdout=subprocess.PIPE,
        text=True,
        process_group=0,
        preexec_fn=_end_with_parent,
    )

    def pass_on(number: int, _frame: object) -> None:
        child.send_signal(number)

    forward = {how: signal.signal(how, pass_on) for how in (signal.SIGINT, signal.SIGTERM)}
    try:
        assert child.stdout is not None
        for line in child.stdout:  # its report through this process' stdout (its progress goes to the shared stderr)
            sys.stdout.write(line)
            sys.stdout.flush()
        code = child.wait()
    finally:
        for how, handler in forward.items():
            signal.signal(how, handler)
    held = _held_by(Path(out), child.pid)
    if not held:
        return code
    _stop_group(child.pid)
    for folder in held:
        with contextlib.suppress(OSError):
            (folder / OWNER_NAME).unlink()
    where = host_port(address) if address and not address.startswith("ray://") else None
    why = head_stopped_answering(*where) if where else None
    if why:
        raise ClusterLost.of(address, why)
    raise ClusterLost(f"the Ray driver (process {child.pid}) ended with exit code {code} while it held {held[0]}")
