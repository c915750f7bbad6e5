"""
The results store: finished runs in Parquet chunks (one per batch) or JSON files (one per run), written atomically by
the driver only.

Layout of a results folder ``DIR``::

    DIR/sweep.json          the resolved sweep; a different sweep into DIR is refused
    DIR/chunks/<batch>.parquet  the finished runs of one batch: one row per episode, per-run data in the footer
    DIR/runs/<id>.json      one finished run executed on its own: config, per-episode columns, timings, versions
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
from collections.abc import Collection, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sb3_affect.episode_log import EPISODE_COLUMNS
from sb3_affect.experiments.chunks import chunk_meta, chunk_records

if TYPE_CHECKING:
    import pandas as pd

    from sb3_affect.experiments.schema import Cell

SCHEMA = 1
SWEEP_SCHEMA = 2


class StoreError(RuntimeError):
    """The results folder can not be used (busy, another sweep, not writable, full)."""


def run_id(config: dict[str, Any]) -> str:
    """Readable prefix + hash of the resolved config (the file name of the run)."""
    digest = hashlib.sha256(json.dumps(config, sort_keys=True).encode()).hexdigest()[:12]
    labels = "-".join(f"{k}{v}" for k, v in config["labels"].items() if k != "replicate")
    prefix = re.sub(r"[^A-Za-z0-9_.+-]+", "_", f"{config['agent']}-{labels}-s{config['seed']}".replace("--", "-"))
    return f"{prefix}-{digest}"


_SEED, _REPLICATE = 8_101_999_202_707_303, 8_101_999_202_707_404  # stand-ins no real config holds


def cell_run_ids(cell: Cell) -> list[str]:
    """
    ``run_id`` of every replicate of a cell, encoding its JSON once: the texts of its runs differ only in the seed and
    the replicate number (checked on the first replicate; falls back to ``run_id`` per run if anything differs).
    """
    probe = cell.config(0)
    probe["seed"], probe["labels"]["replicate"] = _SEED, _REPLICATE
    text = json.dumps(probe, sort_keys=True)
    prefix = run_id(probe).rsplit("-", 1)[0]
    seed, replicate = str(_SEED), str(_REPLICATE)
    ids = []
    if text.count(seed) == 1 and text.count(replicate) == 1 and prefix.count(seed) == 1 and replicate not in prefix:
        for index, value in enumerate(cell.seeds):
            digest = hashlib.sha256(text.replace(replicate, str(index)).replace(seed, str(value)).encode()).hexdigest()
            ids.append(f"{prefix.replace(seed, str(value))}-{digest[:12]}")
    if not ids or ids[0] != run_id(cell.config(0)):
        ids = [run_id(cell.config(index)) for index in range(len(cell.seeds))]
    return ids


def _write_atomic(path: Path, payload: dict[str, Any] | bytes) -> None:
    """Temp file in the same folder, fsync, rename: a reader sees the whole file or none."""
    data = payload if isinstance(payload, bytes) else json.dumps(payload, sort_keys=True, indent=1).encode()
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
    except OSError as error:
        raise _store_error(path.parent, error) from None
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException as error:  # a full disk, or Ctrl-C mid-write: never leave a partial file behind
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(error, OSError):
            raise _store_error(path.parent, error) from None
        raise


def run_file(rid: str, config: dict[str, Any], result: dict[str, Any]) -> bytes:
    """
    The bytes of a finished run's file (``runs/<id>.json``) in compact JSON: what ``ResultsStore.write_run`` stores,
    encoded where the run ran (a worker) so that the launcher only writes it (``ResultsStore.write_run_files``).
    """
    payload = {"schema": SCHEMA, "run_id": rid, "config": config, "status": "ok", **result}
    return json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()


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
        self.chunks = self.root / "chunks"
        self._failed: set[str] | None = None  # failure records known to write_chunk (those it may have to remove)
        self.failed = self.root / "failed"
        self.logs = self.root / "logs"

    # -- set-up ------------------------------------------------------------------------------------------------
    def prepare(self, resolved_sweep: dict[str, Any], run_ids: Collection[str] = ()) -> None:
        """
        Create the folders, refuse a different sweep, save the resolved sweep, clear stale temp files.

        :param resolved_sweep: ``{"name", "sweep" (the validated file), ...}``; a folder holding another is refused
        :param run_ids: every run id of the sweep, compared with the run list of a folder written before chunks
        """
        try:
            for folder in (self.root, self.runs, self.chunks, self.failed):
                folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise _store_error(self.root, error) from None
        saved = self.root / "sweep.json"
        if saved.exists():
            try:
                previous = json.loads(saved.read_text())
            except (OSError, ValueError):
                previous = None
            same = _identity(previous) == _identity(resolved_sweep)
            if same and isinstance(previous.get("runs"), dict) and run_ids:  # a folder of the one-file-per-run era
                same = set(previous["runs"]) == set(run_ids)
            if not same:
                name = (previous or {}).get("name", "?")
                raise StoreError(
                    f"{self.root} already holds the results of a different sweep ({name!r}, or the same file with "
                    "other settings); resume only with the same file and --set options, or use another --out"
                )
        else:
            _write_atomic(saved, resolved_sweep)
        for folder in (self.runs, self.chunks, self.failed):
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

    # -- writing -----------------------------------------------------------------------------------------------
    def write_run(self, rid: str, config: dict[str, Any], result: dict[str, Any]) -> None:
        payload = {"schema": SCHEMA, "run_id": rid, "config": config, "status": "ok", **result}
        _write_atomic(self.runs / f"{rid}.json", payload)
        with contextlib.suppress(FileNotFoundError):
            (self.failed / f"{rid}.json").unlink()

    def write_run_files(self, files: Sequence[tuple[str, bytes]]) -> None:
        """
        Store many finished runs at once (``(run id, run_file bytes)``): every file written to a temporary name, the
        file system synced once (instead of once per file), then each renamed into place: a reader, even after a
        crash, sees each run's whole file or none.
        """
        temporary = []
        try:
            for _, data in files:
                fd, tmp = tempfile.mkstemp(dir=self.runs, prefix=".tmp-", suffix=".json")
                temporary.append(tmp)
                with os.fdopen(fd, "wb") as handle:
                    handle.write(data)
            os.sync()
            for (rid, _), tmp in zip(files, temporary):
                os.replace(tmp, self.runs / f"{rid}.json")
                with contextlib.suppress(FileNotFoundError):
                    (self.failed / f"{rid}.json").unlink()
        except BaseException as error:  # a full disk, or Ctrl-C mid-write: never leave a partial file behind
            for tmp in temporary:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
            if isinstance(error, OSError):
                raise _store_error(self.runs, error) from None
            raise

    def write_chunk(self, name: str, data: bytes, run_ids: Iterable[str]) -> None:
        """Store a batch's chunk (``chunks.encode_chunk``) and forget earlier failures of its runs."""
        _write_atomic(self.chunks / f"{name}.parquet", data)
        if self._failed is None:
            self._failed = self.failed_ids()
        for rid in self._failed.intersection(run_ids):
            with contextlib.suppress(FileNotFoundError):
                (self.failed / f"{rid}.json").unlink()
            self._failed.discard(rid)

    def write_failure(self, rid: str, config: dict[str, Any], error: str) -> None:
        if self._failed is not None:
            self._failed.add(rid)
        _write_atomic(
            self.failed / f"{rid}.json",
            {"schema": SCHEMA, "run_id": rid, "config": config, "status": "failed", "error": error},
        )

    # -- reading -----------------------------------------------------------------------------------------------
    def _json_files(self) -> list[Path]:
        return sorted(p for p in self.runs.glob("*.json") if not p.name.startswith("."))

    def _chunk_files(self) -> list[Path]:
        return sorted(p for p in self.chunks.glob("*.parquet") if not p.name.startswith("."))

    def progress(self) -> tuple[str, dict[str, tuple[int, int, int]]]:
        """
        The saved sweep's name and, per agent, ``(runs, finished, failed)`` (failed: recorded and not finished since),
        from ``sweep.json``, the chunks' footers and the file names: no run's data is read. ``FileNotFoundError``
        when no sweep was run here.
        """
        resolved = json.loads((self.root / "sweep.json").read_text())
        listed = resolved.get("runs") if isinstance(resolved.get("runs"), dict) else None
        if listed is not None:  # a folder written before chunks lists every run
            totals: dict[str, int] = {}
            for config in listed.values():
                totals[config["agent"]] = totals.get(config["agent"], 0) + 1
        else:
            from sb3_affect.experiments.schema import Sweep

            sweep = Sweep.model_validate(resolved["sweep"])
            replicates = sweep.seeds if isinstance(sweep.seeds, int) else len(sweep.seeds)
            totals = {agent.name: len(agent.points()) * replicates for agent in sweep.agents}
        done = {name: 0 for name in totals}
        done_ids: set[str] = set()
        failures = list(self.failed.glob("[!.]*.json"))
        files = [p.stem for p in self._json_files()]
        for path in self._chunk_files():
            meta = chunk_meta(path)
            done[meta["base"]["agent"]] += len(meta["runs"])
            if failures:  # only to tell a failure since retried: no set of every run id otherwise
                done_ids.update(run[0] for run in meta["runs"])
        if files:
            agent_of = {rid: c["agent"] for rid, c in listed.items()} if listed is not None else self._agents_of_runs()
            for rid in files:
                if rid in agent_of:
                    done[agent_of[rid]] += 1
                    done_ids.add(rid)
        failed = {name: 0 for name in totals}
        for path in failures:
            if path.stem not in done_ids:
                with contextlib.suppress(OSError, ValueError, KeyError):
                    failed[json.loads(path.read_text())["config"]["agent"]] += 1
        return resolved["name"], {name: (totals[name], done[name], failed[name]) for name in totals}

    def _agents_of_runs(self) -> dict[str, str]:
        from sb3_affect.experiments.schema import Sweep

        resolved = json.loads((self.root / "sweep.json").read_text())
        runs: dict[str, str] = {}
        for cell in Sweep.model_validate(resolved["sweep"]).cells():
            runs.update(dict.fromkeys(cell_run_ids(cell), cell.base["agent"]))
        return runs

    def done_ids(self) -> set[str]:
        """Every finished run, in either layout (chunks: from their footers only)."""
        done = {p.stem for p in self._json_files()}
        for path in self._chunk_files():
            done.update(run[0] for run in chunk_meta(path)["runs"])
        return done

    def failed_ids(self) -> set[str]:
        return {p.stem for p in self.failed.glob("*.json") if not p.name.startswith(".")}

    def load_runs(self) -> list[dict[str, Any]]:
        """Every finished run as a record of the JSON layout (``run_id``, ``config``, ``episodes`` lists, ...): for
        small folders; large ones read ``runs_frame`` and ``episodes_frame``."""
        records = [json.loads(p.read_text()) for p in self._json_files()]
        for path in self._chunk_files():
            records.extend(chunk_records(path))
        return sorted((r for r in records if r.get("status", "ok") == "ok"), key=lambda r: r["run_id"])

    def runs_frame(self) -> pd.DataFrame:
        """
        One row per finished run (either layout; chunks: from their footers only): ``run_id``, ``agent``, ``algo``,
        ``seed``, one column per label (``replicate`` included), ``decisions`` (every decision of the run),
        ``episodes`` (finished episodes), ``wall_seconds`` (a batch's runs: their share of it), ``max_timesteps``.
        """
        from sb3_affect.experiments.reading import read_folder  # (pandas: not on the launcher's path)

        return read_folder(self._json_files(), self._chunk_files(), None, self.root)[0]

    def results(self, columns: Sequence[str] | None = None, seed: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
        """
        Every finished run (either layout) as two tables, read column-wise (``experiments.reading``): no Python object
        per episode, each column allocated once.

        :param columns: the episode columns wanted (default every ``EPISODE_COLUMNS`` column)
        :param seed: repeat each run's seed on its episode rows (int64; the run table has it anyway)
        :return: ``(runs_frame(), episodes)``; ``episodes`` has one row per episode: ``run_id``, ``agent``, ``seed``
            and one column per label (categoricals but ``seed``), then the episode columns (integers as int32, flags
            as bool, the rest float64); runs in run id order, each run's rows together in episode order
        """
        from sb3_affect.experiments.reading import RUN_COLUMNS, episode_table, read_folder

        runs, data = read_folder(
            self._json_files(), self._chunk_files(), EPISODE_COLUMNS if columns is None else tuple(columns), self.root
        )
        labels = [c for c in runs.columns if c not in RUN_COLUMNS]
        return runs, episode_table(runs, data, ["run_id", "agent", *(["seed"] if seed else []), *labels])

    def episodes_frame(self, columns: Sequence[str] | None = None) -> pd.DataFrame:
        """The episode table of ``results``."""
        return self.results(columns)[1]


def _identity(resolved: Any) -> Any:
    """
    What must match to resume into a folder: the sweep's name and validated file minus settings that do not change
    results (logs). The runs follow from these (a folder written before chunks also lists them: compared apart).
    """
    if not isinstance(resolved, dict) or not isinstance(resolved.get("sweep"), dict):
        return resolved
    return {"name": resolved.get("name"), "sweep": {k: v for k, v in resolved["sweep"].items() if k != "logs"}}


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
