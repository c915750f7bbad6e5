"""
The results store: finished runs in Parquet chunks (one per batch) or JSON files (one per run), written atomically by
the driver only.

Layout of a results folder ``DIR``::

    DIR/sweep.json          the resolved sweep; a different sweep into DIR is refused
    DIR/chunks/<batch>.parquet  the finished runs of one batch: one row per episode (a deep batch: per evaluation,
                            a forensics batch: per ε cell), per-run data in the footer
    DIR/runs/<id>.json      one finished run executed on its own: config, per-episode columns, timings, versions
    DIR/chunks/.sweep, DIR/runs/.sweep  copies of sweep.json: deleting one file does not forget the sweep
    DIR/failed/<id>.json    a run that raised or whose worker died: config and traceback (retried on resume)
    DIR/damaged/            files set aside by the launcher (unreadable, of another sweep, copies); their runs rerun
    DIR/logs/<id>/          per-run SB3 logger output, when the sweep asks for it
    DIR/plan.json           a study run in stages (the forensics): the runs its stages planned so far, and whether
                            its last stage is among them (what ``progress`` counts)
    DIR/.lock, .lock.owner  the launcher's lock (``folder_lock``) and its pid

A run counts as done only when the file holding it reads back whole (``folder_files``).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pydantic import ValidationError

from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.study.launcher import folder_lock
from sb3_affect.study.launcher.chunks import chunk_records, evaluation_cells, summary_cells
from sb3_affect.study.launcher.folder_files import MAX_SWEEP_FILE_BYTES, FolderFiles, guarded, sort_files
from sb3_affect.study.launcher.old_forms import new_form
from sb3_affect.study.launcher.regular_files import read_json, write_file, write_files
from sb3_affect.study.launcher.run_ids import base_run_ids
from sb3_affect.study.launcher.schema import Sweep, kind_of

if TYPE_CHECKING:
    import pandas as pd

    from sb3_affect.study.launcher.schema import Cell

SCHEMA = 1
SWEEP_SCHEMA = 2


class StoreError(RuntimeError):
    """The results folder can not be used (busy, another sweep, not writable, full)."""


def cell_run_ids(cell: Cell) -> list[str]:
    """``run_id`` of every replicate of a cell (``run_ids.base_run_ids``)."""
    return base_run_ids(cell.base, [(seed, index) for index, seed in enumerate(cell.seeds)])


def write_atomic(path: Path, payload: dict[str, Any] | bytes) -> None:
    """
    ``regular_files.write_file`` of ``payload`` (a dict: as JSON), its folder made when missing; an OSError becomes a
    one-line ``StoreError``.
    """
    data = payload if isinstance(payload, bytes) else json.dumps(payload, sort_keys=True, indent=1).encode()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write_file(path, data)
    except OSError as error:
        raise store_error(path.parent, error) from None


def run_file(rid: str, config: dict[str, Any], result: dict[str, Any]) -> bytes:
    """
    The bytes of a finished run's file (``runs/<id>.json``) in compact JSON: what ``ResultsStore.write_run`` stores,
    encoded where the run ran (a worker) so that the launcher only writes it (``ResultsStore.write_run_files``).
    """
    payload = {"schema": SCHEMA, "run_id": rid, "config": config, "status": "ok", **result}
    return json.dumps(payload, sort_keys=True, separators=(",", ":")).encode()


def store_error(folder: Path, error: OSError) -> StoreError:
    if error.errno == errno.ENOSPC:
        return StoreError(f"{folder}: the disk is full; finished runs are kept, free space and rerun to resume")
    if error.errno in (errno.EACCES, errno.EROFS, errno.EPERM):
        return StoreError(f"{folder}: not writable ({error.strerror}); choose another --out or fix its permissions")
    return StoreError(f"{folder}: {error.strerror or error}")


IDENTITY_COPIES = ("chunks/.sweep", "runs/.sweep")
#: How a refusal names each kind of study: of a saved sweep (``schema.kind_of``), and a ``replicate`` folder of them.
KIND_NAMES = {"sweep": "a sweep", "deep": "a deep study", "forensics": "the replication forensics",
              "replication": "a replication"}  # fmt: skip
#: The record and the per-run folder of a deep study's and a forensics' folder of the layout before their runs went
#: into the store (refused, ``old_layout``).
OLD_LAYOUTS = {"deep": ("deep_study.json", "cells/"), "forensics": ("forensics.json", "summaries/")}


def folder_kind(root: Path) -> tuple[str, str] | None:
    """
    What ``root`` holds and the file that says so: ``"sweep"`` (every study: its sweep.json, a copy of it, or its runs'
    folder) or ``"replication"`` (a ``replicate`` folder: its sweep sub-folders), None when nothing; StoreError
    (``old_layout``) for a study of an earlier layout. Reads no file.
    """
    for kind, (record, _) in OLD_LAYOUTS.items():
        if os.path.lexists(root / record):
            raise StoreError(old_layout(root, kind))
    copies = [copy for copy in ("sweep.json", *IDENTITY_COPIES) if os.path.lexists(root / copy)]
    if copies:
        return "sweep", copies[0]
    for folder, pattern in (("chunks", "[!.]*.parquet"), ("runs", "[!.]*.json")):  # a sweep whose records are all gone
        if any((root / folder).glob(pattern)):
            return "sweep", f"{folder}/"
    parts = replication_parts(root)
    return ("replication", ", ".join(parts)) if parts else None


def old_layout(root: Path, kind: str) -> str:
    """The one line that refuses a deep study's or a forensics' folder of the layout before its runs went into the store."""
    return (f"{root} holds {KIND_NAMES[kind]} of an earlier layout ({', '.join(OLD_LAYOUTS[kind])}), which is "
            f"no longer read: rerun the study into a new folder, e.g. --out {root.parent / (root.name + '-new')}")


def claim_kind(root: Path, kind: str, suggestion: str) -> None:
    """
    Refuse (``StoreError``, one line) to run a study of ``kind`` into ``root`` when it holds another kind of study
    (``folder_kind``); ``suggestion``: the sub-folder the line proposes instead.
    """
    held = folder_kind(root)
    if held is not None and held[0] != kind:
        what = KIND_NAMES[kind].split(" ", 1)[1]
        raise StoreError(
            f"{root} holds {KIND_NAMES[held[0]]} ({held[1]}), which {KIND_NAMES[kind]} run into it would mix with; "
            f"give the {what} a folder of its own, e.g. --out {root / suggestion}"
        )


class ResultsStore:
    """A results folder (see the module docstring)."""

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        try:
            str(self.root.resolve()).encode("utf-8")
        except UnicodeEncodeError:  # pyarrow can not open such paths: every chunk would read as damaged
            raise StoreError(
                f"{str(self.root)!r}: a results folder's path must be valid UTF-8 (this one holds undecodable bytes); "
                "choose another --out"
            ) from None
        self.runs = self.root / "runs"
        self.chunks = self.root / "chunks"
        self._failed: set[str] | None = None  # failure records known to write_chunk (those it may have to remove)
        self.failed = self.root / "failed"
        self.damaged = self.root / "damaged"
        self.logs = self.root / "logs"

    # -- the sweep's identity ----------------------------------------------------------------------------------
    def saved_sweep(self) -> dict[str, Any] | None:
        """
        The resolved sweep run here: ``sweep.json``, or a copy of it when it was deleted, its sweep in the new form
        (``old_forms.new_form``); None when none is left.
        """
        for path in (self.root / "sweep.json", *(self.root / copy for copy in IDENTITY_COPIES)):
            try:
                saved = read_json(path, MAX_SWEEP_FILE_BYTES)
            except (OSError, ValueError):  # (DamagedFile: a ValueError)
                continue
            if isinstance(saved, dict) and isinstance(saved.get("sweep"), dict):
                try:
                    return {**saved, "sweep": new_form(saved["sweep"])}
                except ValidationError as error:
                    raise self._invalid(error) from None
        return None

    def study_kind(self) -> str | None:
        """The kind of study the saved sweep is (``schema.kind_of``: a sweep of runs, a deep study, the forensics); None
        when the folder holds no saved sweep (or is not a folder)."""
        saved = self.saved_sweep() if self.root.is_dir() else None
        return None if saved is None else kind_of(saved["sweep"])

    def _invalid(self, error: ValidationError) -> StoreError:
        """The one line saying the saved sweep does not validate (its first error)."""
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        return StoreError(f"{self.root / 'sweep.json'}: the saved sweep is not valid ({where}: {first['msg']})")

    # -- set-up ------------------------------------------------------------------------------------------------
    def prepare(self, resolved_sweep: dict[str, Any], run_ids: Collection[str] = ()) -> list[str]:
        """
        Create the folders, refuse a different sweep, save the resolved sweep (and its copies), clear stale temp
        files, and set aside every file that does not count (``folder_files``): its runs are not done.

        :param resolved_sweep: ``{"name", "sweep" (the validated file), ...}``; a folder holding another is refused
        :param run_ids: every run id of the sweep: a file holding another run is set aside (and, in a folder whose
            sweep records are all gone, means the folder holds another sweep: refused)
        :return: one line per file set aside (its path, why, where it went)
        """
        self.claim(resolved_sweep)
        try:
            for folder in (self.root, self.runs, self.chunks, self.failed):
                folder.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise store_error(self.root, error) from None
        refusal = (
            f"{self.root} already holds the results of a different sweep ({{name!r}}, or the same file with other "
            "settings); resume only with the same file and --set options, or use another --out"
        )
        previous = self.saved_sweep()
        wanted = set(run_ids)
        if previous is not None:
            same = _identity(previous) == _identity(resolved_sweep)
            if same and isinstance(previous.get("runs"), dict) and wanted:  # a folder of the one-file-per-run era
                same = set(previous["runs"]) == wanted
            if not same:
                raise StoreError(refusal.format(name=previous.get("name", "?")))
        files = self._check_files((lambda rid, agent: rid in wanted) if wanted else None)
        if previous is None and any("another sweep" in why for _, why in files.rejected):
            raise StoreError(refusal.format(name="its sweep.json is gone; its files name other runs"))
        for name in ("sweep.json", *IDENTITY_COPIES):
            path = self.root / name
            if previous is None or not path.exists():
                write_atomic(path, previous or resolved_sweep)
        for folder in (self.runs, self.chunks, self.failed):
            for stale in folder.glob(".tmp-*"):
                with contextlib.suppress(OSError):
                    stale.unlink()
        probe = self.runs / f".tmp-probe-{os.getpid()}"
        try:
            probe.write_text("")
            probe.unlink()
        except OSError as error:
            raise store_error(self.runs, error) from None
        return self.set_aside(files.rejected)

    def claim(self, resolved_sweep: dict[str, Any]) -> None:
        """
        Refuse (``StoreError``, one line) a folder of another kind of study (``claim_kind``), or whose saved sweep is of
        another kind than ``resolved_sweep`` (``schema.kind_of``: a deep study, a sweep of runs). Writes nothing.
        """
        claim_kind(self.root, "sweep", resolved_sweep["name"])
        previous = self.study_kind()
        if previous is not None and previous != kind_of(resolved_sweep["sweep"]):
            held, kind = KIND_NAMES[previous], KIND_NAMES[kind_of(resolved_sweep["sweep"])]
            raise StoreError(f"{self.root} holds {held} (sweep.json), which {kind} run into it would mix with; give the "
                             f"{kind.split(' ', 1)[1]} a folder of its own, e.g. --out {self.root / resolved_sweep['name']}")

    def set_aside(self, rejected: list[tuple[Path, str]]) -> list[str]:
        """Move each rejected file into ``DIR/damaged/`` (never over an earlier one); one line per file."""
        lines = []
        for path, why in rejected:
            try:
                self.damaged.mkdir(exist_ok=True)
                target = self.damaged / f"{path.parent.name}-{path.name}"
                count = 1
                while target.exists():
                    count += 1
                    target = self.damaged / f"{path.parent.name}-{path.stem}.{count}{path.suffix}"
                os.replace(path, target)
            except OSError as error:
                reason = error.strerror or error
                raise StoreError(f"{path} {why}, and can not be moved aside ({reason}); move it yourself") from None
            lines.append(f"{path} {why}: moved to {target}, its runs will be run again")
        return lines

    def lock_owner(self) -> int | None:
        """The pid of the live launcher holding the folder's lock, or None (nobody holds it)."""
        return folder_lock.recorded_owner(self.root) if folder_lock.is_locked(self.root) else None

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Hold the folder's lock while running (``folder_lock``); StoreError at once if another launcher holds it."""
        try:
            with folder_lock.hold(self.root):
                yield
        except folder_lock.FolderBusy as busy:
            raise StoreError(f"{self.root} is in use by another launcher ({busy}); wait for it or stop it first") from None
        except OSError as error:
            raise store_error(self.root, error) from None

    # -- writing -----------------------------------------------------------------------------------------------
    def write_run(self, rid: str, config: dict[str, Any], result: dict[str, Any]) -> None:
        payload = {"schema": SCHEMA, "run_id": rid, "config": config, "status": "ok", **result}
        write_atomic(self.runs / f"{rid}.json", payload)
        with contextlib.suppress(FileNotFoundError):
            (self.failed / f"{rid}.json").unlink()

    def write_run_files(self, files: Sequence[tuple[str, bytes]]) -> None:
        """
        Store many finished runs at once (``(run id, run_file bytes)``): every file written to a temporary name, the
        file system synced once (instead of once per file), then each renamed into place: a reader, even after a
        crash, sees each run's whole file or none.
        """
        try:
            write_files([(self.runs / f"{rid}.json", data) for rid, data in files])
        except OSError as error:
            raise store_error(self.runs, error) from None
        for rid, _ in files:
            with contextlib.suppress(FileNotFoundError):
                (self.failed / f"{rid}.json").unlink()

    def write_chunk(self, name: str, data: bytes, run_ids: Iterable[str]) -> None:
        """Store a batch's chunk (``chunks.encode_chunk``) and forget earlier failures of its runs."""
        write_atomic(self.chunks / f"{name}.parquet", data)
        if self._failed is None:
            self._failed = self.failed_ids()
        for rid in self._failed.intersection(run_ids):
            with contextlib.suppress(FileNotFoundError):
                (self.failed / f"{rid}.json").unlink()
            self._failed.discard(rid)

    def record_plan(self, run_ids: Iterable[str], final: bool) -> None:
        """
        ``plan.json`` of a study run in stages: ``run_ids`` (a wave just planned) beside the runs recorded before, and
        whether no stage is left to plan (``final``).
        """
        planned = self.plan()
        runs = set(run_ids) | (planned[0] if planned is not None else set())
        write_atomic(self.root / "plan.json", {"schema": SCHEMA, "runs": sorted(runs), "final": final})

    def plan(self) -> tuple[set[str], bool] | None:
        """The runs ``record_plan`` recorded and whether the plan is final; None when none is (a sweep of runs: all)."""
        try:
            record = read_json(self.root / "plan.json", MAX_SWEEP_FILE_BYTES)
            return set(record["runs"]), bool(record["final"])
        except (OSError, ValueError, KeyError, TypeError):  # none, or not readable: every run of the sweep counts
            return None

    def write_failure(self, rid: str, config: dict[str, Any], error: str) -> None:
        if self._failed is not None:
            self._failed.add(rid)
        write_atomic(
            self.failed / f"{rid}.json",
            {"schema": SCHEMA, "run_id": rid, "config": config, "status": "failed", "error": error},
        )

    # -- reading -----------------------------------------------------------------------------------------------
    def _check_files(self, belongs: Callable[[str, str], bool] | None) -> FolderFiles:
        """Every run file and chunk, read and sorted out (``folder_files.sort_files``)."""
        json_files = sorted(p for p in self.runs.glob("*.json") if not p.name.startswith("."))
        chunk_files = sorted(p for p in self.chunks.glob("*.parquet") if not p.name.startswith("."))
        return sort_files(json_files, chunk_files, belongs)

    def _sweep_runs(self) -> dict[str, str] | None:
        """Run id -> agent of every run of the saved sweep (its file validated without importing anything)."""
        resolved = self.saved_sweep()
        if resolved is None:
            return None
        if isinstance(resolved.get("runs"), dict):  # a folder written before chunks lists every run
            return {rid: c["agent"] for rid, c in resolved["runs"].items()}

        try:
            sweep = Sweep.validate_saved(resolved["sweep"])
        except ValidationError as error:
            raise self._invalid(error) from None
        runs: dict[str, str] = {}
        for cell in sweep.cells():
            runs.update(dict.fromkeys(cell_run_ids(cell), cell.base["agent"]))
        return runs

    def checked_files(self) -> FolderFiles:
        """The files that count, for ``results_parts``; StoreError naming the first that does not (a rerun sets it aside)."""
        runs = self._sweep_runs()
        files = self._check_files(None if runs is None else lambda rid, agent: runs.get(rid) == agent)
        if files.rejected:
            path, why = files.rejected[0]
            more = f" (and {len(files.rejected) - 1} more)" if len(files.rejected) > 1 else ""
            raise StoreError(
                f"{path} {why}{more}; rerun the sweep into {self.root} (the same `sb3-affect run` command) to move it "
                "to damaged/ and run its runs again"
            )
        return files

    def progress(self) -> tuple[str, dict[str, tuple[int, int, int]], list[tuple[Path, str]]]:
        """
        The saved sweep's name; per agent ``(runs, finished, failed)`` (failed: recorded and not finished since),
        counting only the runs of files that count (of a study run in stages: the runs its ``plan`` holds, beside those
        done); and ``(path, why)`` of each file that does not. Reads the chunks' footers and the run files, imports
        nothing the folder names. ``FileNotFoundError`` when no sweep was run here.
        """
        resolved = self.saved_sweep()
        if resolved is None:
            raise FileNotFoundError(f"{self.root / 'sweep.json'}: no sweep was run here")
        runs = self._sweep_runs() or {}
        files = self._check_files(lambda rid, agent: runs.get(rid) == agent)
        done_ids = files.done_ids()
        plan = self.plan()
        counted = runs if plan is None else {rid: agent for rid, agent in runs.items() if rid in plan[0] | done_ids}
        totals = {agent: 0 for agent in _agent_names(resolved)}
        for agent in counted.values():
            totals[agent] = totals.get(agent, 0) + 1
        done = {name: 0 for name in totals}
        for rid in done_ids:
            done[runs[rid]] += 1
        failed = {name: 0 for name in totals}
        for path in self.failed.glob("[!.]*.json"):
            if path.stem not in done_ids and path.stem in counted:
                failed[counted[path.stem]] += 1
        return resolved["name"], {name: (totals[name], done[name], failed[name]) for name in totals}, files.rejected

    def done_ids(self) -> set[str]:
        """Every finished run, in either layout (chunks: from their footers only), of the files that count."""
        return self._check_files(None).done_ids()

    def failed_ids(self) -> set[str]:
        return {p.stem for p in self.failed.glob("*.json") if not p.name.startswith(".")}

    def load_runs(self) -> list[dict[str, Any]]:
        """Every finished run as a record of the JSON layout (``run_id``, ``config``, ``episodes`` lists, ...): for
        small folders; large ones read ``runs_frame`` and ``results``."""
        files = self.checked_files()
        records = [{**guarded(p, read_json), "run_id": files.run_ids[p]} for p in files.run_files]
        for path, meta in files.episode_chunks().items():
            records.extend(guarded(path, lambda p, meta=meta: chunk_records(p, meta)))  # type: ignore[misc]
        return sorted((r for r in records if r.get("status", "ok") == "ok"), key=lambda r: r["run_id"])

    def evaluations(self) -> dict[tuple[str, str], dict[str, Any]]:
        """
        A deep study's finished cells ``(task, agent) -> record`` (``chunks.evaluation_cells``: its runs in seed
        order), in the order of the study's tasks, then agents, from the files that count; StoreError naming the first
        that does not (a rerun sets it aside).
        """
        cells = evaluation_cells(self.checked_files().chunk_files)
        saved = self.saved_sweep() or {"sweep": {}}
        tasks, agents = saved.get("task_order") or list(saved["sweep"].get("tasks", {})), saved["sweep"].get("agents", [])
        return {(task, agent["name"]): cells[task, agent["name"]] for task in tasks for agent in agents
                if (task, agent["name"]) in cells}  # fmt: skip

    def summaries(self) -> dict[tuple[str, str, int], tuple[dict[str, Any], bool]]:
        """
        The forensics' finished replications ``(simulation, stage, replication) -> (rows by ε, complete)``
        (``chunks.summary_cells``), from the files that count; StoreError naming the first that does not.
        """
        return summary_cells(self.checked_files().chunk_files)

    def runs_frame(self) -> pd.DataFrame:
        """
        One row per finished run (either layout; chunks: from their footers only): ``run_id``, ``agent``, ``algo``,
        ``seed``, one column per label (``replicate`` included), ``decisions`` (every decision of the run),
        ``episodes`` (finished episodes), ``wall_seconds`` (a batch's runs: their share of it), ``max_timesteps``.
        """
        return next(self._read(None))[0]

    def results(self, columns: Sequence[str] | None = None, seed: bool = True) -> tuple[pd.DataFrame, pd.DataFrame]:
        """
        Every finished run (either layout) as two tables, read column-wise (``launcher.folder_reading``): no Python object
        per episode, each column allocated once.

        :param columns: the episode columns wanted (default every ``EPISODE_COLUMNS`` column)
        :param seed: repeat each run's seed on its episode rows (int64; the run table has it anyway)
        :return: ``(runs_frame(), episodes)``; ``episodes`` has one row per episode: ``run_id``, ``agent``, ``seed``
            and one column per label (categoricals but ``seed``), then the episode columns (integers as int32, or int64
            when a count needs it; flags as bool, or float64 with NaN when a run could not tell; the rest float64); runs
            in run id order, each run's rows together in episode order
        """
        return next(self.results_parts(columns, seed))

    def results_parts(
        self,
        columns: Sequence[str] | None = None,
        seed: bool = True,
        agent: str | None = None,
        runs_per_part: int | None = None,
        files: FolderFiles | None = None,
        ordered: bool = False,
    ) -> Iterator[tuple[pd.DataFrame, pd.DataFrame]]:
        """
        ``results`` a part of the folder at a time: the runs of ``agent`` only (None: every agent), about
        ``runs_per_part`` runs a part (whole chunks; None: one part), each part as ``results`` gives it (its runs in
        run id order). A reader that reduces run by run holds one part at a time.

        :param files: the folder's files (``checked_files``), to check the folder once over several reads
        :param ordered: parts one after the other in run id order (``reading.ordered_file_parts``): the rows of all
            parts, in the order read, are the rows of one whole read
        """
        wanted = EPISODE_COLUMNS if columns is None else tuple(columns)
        for runs, episodes in self._read(wanted, seed, agent, runs_per_part, files, ordered):
            assert episodes is not None
            yield runs, episodes

    def _read(
        self,
        wanted: Sequence[str] | None,
        seed: bool = True,
        agent: str | None = None,
        runs_per_part: int | None = None,
        files: FolderFiles | None = None,
        ordered: bool = False,
    ) -> Iterator[tuple[pd.DataFrame, pd.DataFrame | None]]:
        """
        ``results_parts`` of the ``wanted`` episode columns (None: the run tables only, from the chunks' footers); the
        chunks of episodes only (``FolderFiles.episode_chunks``: a deep study's evaluations are read by ``evaluations``).
        """
        from sb3_affect.study.launcher import folder_reading  # (pandas: not on the launcher's path)

        files = self.checked_files() if files is None else files
        run_files = [path for path, owner in files.run_files.items() if agent is None or owner == agent]
        chunk_files = {
            p: meta for p, meta in files.episode_chunks().items() if agent is None or meta["base"]["agent"] == agent
        }
        split = folder_reading.ordered_file_parts if ordered else folder_reading.file_parts
        for json_part, chunk_part in split(run_files, chunk_files, runs_per_part):
            runs, data = folder_reading.read_folder(
                json_part, chunk_part, wanted, self.root, files.chunk_files, files.episode_counts
            )
            if wanted is None:
                yield runs, None
                continue
            named = [c for c in runs.columns if c not in folder_reading.RUN_COLUMNS]
            yield runs, folder_reading.episode_table(runs, data, ["run_id", "agent", *(["seed"] if seed else []), *named])


def replication_parts(root: Path) -> list[str]:
    """
    The sweep sub-folders of ``root`` when it holds a replication (``sb3-affect replicate``'s folder: marked by its
    ``replicate.json``, or, written before that record, by a ``paper/`` sweep), else [].
    """
    if not (root / "replicate.json").exists() and not (root / "paper" / "sweep.json").exists():
        return []
    try:
        return sorted(f"{p.name}/" for p in root.iterdir() if (p / "sweep.json").exists()) or ["replicate.json"]
    except OSError:
        return ["replicate.json"]


def _agent_names(resolved: dict[str, Any]) -> list[str]:
    agents = resolved["sweep"].get("agents") or []
    return [a["name"] for a in agents if isinstance(a, dict) and isinstance(a.get("name"), str)]


def _identity(resolved: Any) -> Any:
    """
    What must match to resume into a folder: the sweep's name and validated file minus settings that do not change
    results (logs). The runs follow from these (a folder written before chunks also lists them: compared apart).
    """
    if not isinstance(resolved, dict) or not isinstance(resolved.get("sweep"), dict):
        return resolved
    return {"name": resolved.get("name"), "sweep": {k: v for k, v in resolved["sweep"].items() if k != "logs"}}
