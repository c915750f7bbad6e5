"""
The lock of a results folder: one launcher at a time writes into ``DIR``.

The lock is an operating-system lock (``filelock``: ``flock`` on Linux and macOS) on ``DIR/.lock``, held by the open
file itself: the kernel releases it when the launcher exits, however it dies, so there is no stale lock to take over
and no window in which two launchers can both believe they hold it. The lock file is never deleted (deleting it
would let a second launcher lock a new file of the same name). Beside it ``DIR/.lock.owner`` records the holder's
pid and start time, for ``status`` and for the message a refused launcher prints.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from filelock import FileLock, Timeout

from sb3_affect.study.launcher.regular_files import read_text, write_file

LOCK_NAME = ".lock"
OWNER_NAME = ".lock.owner"


class FolderBusy(RuntimeError):
    """Another launcher holds the folder's lock."""


def start_time(pid: int) -> str | None:
    """When ``pid`` started (clock ticks since boot, Linux ``/proc``), to tell a reused pid from the launcher's."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def recorded_owner(root: Path) -> int | None:
    """The pid ``DIR/.lock.owner`` names, if it is a live process that started when the record says."""
    try:
        fields = read_text(root / OWNER_NAME, 100).split()
        pid = int(fields[0])
    except (OSError, IndexError, ValueError):  # (UnreadableFile: a ValueError)
        return None
    if pid <= 0 or not _alive(pid):
        return None
    if len(fields) > 1 and start_time(pid) not in (None, fields[1]):
        return None
    return pid


def is_locked(root: Path) -> bool:
    """Whether a launcher holds ``DIR``'s lock now (a folder that can not be probed: its owner record decides)."""
    path = root / LOCK_NAME
    if not path.exists():
        return False
    probe = FileLock(str(path), timeout=0, thread_local=False)
    try:
        probe.acquire()
    except Timeout:
        return True
    except OSError:  # a read-only folder or lock file: fall back on the recorded pid
        return recorded_owner(root) is not None
    probe.release()
    return False


@contextlib.contextmanager
def hold(root: Path) -> Iterator[None]:
    """
    Hold ``DIR``'s lock for the block; ``FolderBusy`` at once if another launcher holds it. ``OSError`` when the
    folder does not let us create the lock file.
    """
    lock = FileLock(str(root / LOCK_NAME), timeout=0, thread_local=False)
    try:
        lock.acquire()
    except Timeout:
        pid = recorded_owner(root)
        raise FolderBusy(f"pid {pid}" if pid is not None else "a process that has not recorded its pid yet") from None
    owner = root / OWNER_NAME
    mine = f"{os.getpid()} {start_time(os.getpid()) or ''}".strip()
    try:
        write_file(owner, mine)
    except OSError:
        lock.release()
        raise
    try:
        yield
    finally:
        with contextlib.suppress(OSError, ValueError):
            if read_text(owner, 100).strip() == mine:
                owner.unlink()
        lock.release()
