"""
The results store: one JSON file per finished run, written atomically by the driver only.

Layout of a results folder ``DIR``::

    DIR/sweep.json          the resolved sweep (every run config); a different sweep into DIR is refused
    DIR/runs/<id>.json      one finished run: config, per-episode columns, timings, package versions
    DIR/failed/<id>.json    a run that raised or whose worker died: config and traceback (retried on resume)
    DIR/logs/<id>/          per-run SB3 logger output, when the sweep asks for it
    DIR/.lock               the pid (and start time) of the launcher using DIR
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

SCHEMA = 1


class StoreError(RuntimeError):
    """The results folder can not be used (busy, another sweep, not writable, full)."""


def run_id(config: dict[str, Any]) -> str:
    """Readable prefix + hash of the resolved config (the file name of the run)."""
    digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
    labels = "-".join(f"{k}{v}" for k, v in config["labels"].items() if k != "replicate")
    prefix = re.sub(r"[^A-Za-z0-9_.+-]+", "_", f"{config['agent']}-{labels}-s{config['seed']}".replace("--", "-"))
    return f"{prefix}-{digest}"


def _write_atomic(path: Path, payload: dict[str, Any]) -> None:
    """Temp file in the same folder, fsync, rename: a reader sees the whole file or none."""
    text = json.dumps(payload, sort_keys=True, indent=1)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".json")
    except OSError as error:
        raise _store_error(path.parent, error) from None
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as error:  # a full disk, or Ctrl-C mid-write: never leave a partial file behind
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(error, OSError):
            raise _store_error(path.parent, error) from None
        raise


def _store_error(folder: Path, error: OSError) -> StoreError:
    if error.errno == errno.ENOSPC:
        return StoreError(f"{folder}: the disk is full; finished runs are kept, free space and rerun to resume")
    if error.errno in (errno.EACCES, errno.EROFS, errno.EPERM):
        return StoreError(f"{folder}: not writable ({error.strerror}); choose another --out or fix its permissions")
    return StoreError(f"{folder}: {error.strerror or error}")


class ResultsStore:
    """A results folder (see the module docstring)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.runs = self.root / "runs"
        self.failed = self.root / "failed"
        self.logs = self.root / "logs"

    # -- set-up ------------------------------------------------------------------------------------------------
    def prepare(self, resolved_sweep: dict[str, Any]) -> None:
        """Create the folders, refuse a different sweep, save the resolved sweep, clear stale temp files."""
        try:
            for folder in (self.root, self.runs, self.failed):
                folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise _store_error(self.root, error) from None
        saved = self.root / "sweep.json"
        if saved.exists():
            try:
                previous = json.loads(saved.read_text())
            except (OSError, ValueError):
                previous = None
            if _identity(previous) != _identity(resolved_sweep):
                name = (previous or {}).get("name", "?")
                raise StoreError(
                    f"{self.root} already holds the results of a different sweep ({name!r}, or the same file with "
                    "other settings); resume only with the same file and --set options, or use another --out"
                )
        else:
            _write_atomic(saved, resolved_sweep)
        for folder in (self.runs, self.failed):
            for stale in folder.glob(".tmp-*"):
                with contextlib.suppress(OSError):
                    stale.unlink()
        probe = self.runs / f".tmp-probe-{os.getpid()}"
        try:
            probe.write_text("")
            probe.unlink()
        except OSError as error:
            raise _store_error(self.runs, error) from None

    def lock_owner(self) -> int | None:
        """The pid of the live launcher holding ``DIR/.lock``, or None (no lock, or a stale one)."""
        try:
            fields = (self.root / ".lock").read_text().split()
        except OSError:
            return None
        try:
            pid = int(fields[0])
        except (IndexError, ValueError):
            return None
        if not _alive(pid):
            return None
        # A recorded start time that differs: the launcher died and its pid was reused by another process.
        if len(fields) > 1 and _start_time(pid) not in (None, fields[1]):
            return None
        return pid

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """
        Hold ``DIR/.lock`` (our pid and start time) while running; a lock whose launcher is gone is stale and taken over.
        """
        path = self.root / ".lock"
        mine = f"{os.getpid()} {_start_time(os.getpid()) or ''}".strip()
        for _ in range(3):
            try:
                fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                pid = self.lock_owner()
                if pid is not None:
                    raise StoreError(
                        f"{self.root} is in use by another launcher (pid {pid}); wait for it or stop it first"
                    ) from None
                with contextlib.suppress(FileNotFoundError):
                    path.unlink()  # stale: its launcher is gone
                continue
            except OSError as error:
                raise _store_error(self.root, error) from None
            with os.fdopen(fd, "w") as handle:
                handle.write(mine)
            break
        else:  # pragma: no cover - a race with another launcher taking the stale lock first
            raise StoreError(f"{self.root} is in use by another launcher")
        try:
            yield
        finally:
            with contextlib.suppress(OSError):
                if path.read_text().strip() == mine:
                    path.unlink()

    # -- runs --------------------------------------------------------------------------------------------------
    def done_ids(self) -> set[str]:
        return {p.stem for p in self.runs.glob("*.json") if not p.name.startswith(".")}

    def failed_ids(self) -> set[str]:
        return {p.stem for p in self.failed.glob("*.json") if not p.name.startswith(".")}

    def write_run(self, rid: str, config: dict[str, Any], result: dict[str, Any]) -> None:
        payload = {"schema": SCHEMA, "run_id": rid, "config": config, "status": "ok", **result}
        _write_atomic(self.runs / f"{rid}.json", payload)
        with contextlib.suppress(FileNotFoundError):
            (self.failed / f"{rid}.json").unlink()

    def write_failure(self, rid: str, config: dict[str, Any], error: str) -> None:
        _write_atomic(
            self.failed / f"{rid}.json",
            {"schema": SCHEMA, "run_id": rid, "config": config, "status": "failed", "error": error},
        )

    def load_runs(self) -> list[dict[str, Any]]:
        return [json.loads(p.read_text()) for p in sorted(self.runs.glob("*.json")) if not p.name.startswith(".")]


def _identity(resolved: Any) -> Any:
    """What must match to resume into a folder: the resolved sweep minus settings that do not change results (logs)."""
    if not isinstance(resolved, dict) or not isinstance(resolved.get("sweep"), dict):
        return resolved
    return {**resolved, "sweep": {k: v for k, v in resolved["sweep"].items() if k != "logs"}}


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _start_time(pid: int) -> str | None:
    """When ``pid`` started (clock ticks since boot, Linux ``/proc``), to tell a reused pid from the launcher's."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None
