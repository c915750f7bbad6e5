"""
Which files of a results folder count as finished runs: each run file and chunk is read (a chunk: its footer) and
checked before its runs are counted as done.

A file counts when it can be read and has the shape the store writes (a *damaged* file does not), when its runs are
runs of the folder's sweep (a *foreign* file, copied in from another sweep, does not) and when no file before it
(in name order) already holds one of its runs (a *duplicate*, e.g. a copy of a chunk, does not). Each run's id is
recomputed from the config the file gives it (labels, seed, replicate): a file whose ids do not match its configs, that
lists a run twice, or a chunk not named after its batch does not count either. The launcher moves
every file that does not count into ``DIR/damaged/`` and reruns its runs; ``status`` names them; ``report`` refuses
to read a folder that holds one until a rerun has set it aside.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.study.launcher.chunks import EPISODES, EVALUATIONS, SUMMARIES, chunk_meta, evaluation_table, summary_rows
from sb3_affect.study.launcher.regular_files import UnreadableFile, check_regular, read_bytes
from sb3_affect.study.launcher.run_ids import base_run_ids, run_id, stored_matches


class DamagedFile(ValueError):
    """A run file or chunk that can not be read, or does not have the shape the store writes."""


#: The largest run file read: a run of the sweep files' most episodes (1,000,000), 32 characters a value and column.
MAX_RUN_FILE_BYTES = 1_000_000 * len(EPISODE_COLUMNS) * 32 + 2**20
#: The largest ``sweep.json`` (or copy) read: a list of a million seeds is about 11 MB.
MAX_SWEEP_FILE_BYTES = 64 * 2**20


def regular_file(path: Path, limit: int | None) -> None:
    """
    ``DamagedFile`` unless ``path`` is a regular file (``regular_files.check_regular``: not a FIFO, device, folder or
    link, which would block a reader or lead elsewhere) of at most ``limit`` bytes (None: any size).
    """
    try:
        check_regular(path, limit)
    except UnreadableFile as error:
        raise DamagedFile(error.reason) from None


_T = TypeVar("_T")
_REDO = "move it out of the folder, then rerun its sweep (the same `sb3-affect run` command) to run its runs again"


def guarded(path: Path, read: Callable[[Path], _T]) -> _T:
    """``read(path)``; a file whose data can not be read (past the checked footer) is a ``DamagedFile`` naming it."""
    try:
        return read(path)
    except OSError as error:
        if error.errno is not None:
            raise DamagedFile(f"{path}: can not be read ({error.strerror or error})") from None
        text = " ".join(str(error).split())  # pyarrow's errors of a garbled file (several lines)
        raise DamagedFile(f"{path}: damaged data ({type(error).__name__}: {text}); {_REDO}") from None
    except Exception as error:
        if not isinstance(error, (ValueError, KeyError, TypeError)) and not type(error).__module__.startswith("pyarrow"):
            raise
        text = " ".join(str(error).split())
        raise DamagedFile(f"{path}: damaged data ({type(error).__name__}: {text}); {_REDO}") from None


@dataclass
class FolderFiles:
    """
    The files of a results folder sorted out (see the module docstring).

    :param run_files: the run files that count, with the agent of their run
    :param chunk_files: the chunks that count, with their footer
    :param rejected: ``(path, why)`` of each file that does not count
    :param run_ids: the id of each counted run file's run (recomputed from its config; chunks: their footers' ids
        are replaced by the recomputed ones)
    :param episode_counts: each chunk's episodes per run (its ``run`` column counted), once a reader has read it
        (``reading.read_folder`` fills it and reads it back: a folder read several times counts them once)
    """

    run_files: dict[Path, str] = field(default_factory=dict)
    chunk_files: dict[Path, dict[str, Any]] = field(default_factory=dict)
    rejected: list[tuple[Path, str]] = field(default_factory=list)
    run_ids: dict[Path, str] = field(default_factory=dict)
    episode_counts: dict[Path, Any] = field(default_factory=dict, repr=False)

    def done_ids(self) -> set[str]:
        done = set(self.run_ids.values())
        for meta in self.chunk_files.values():
            done.update(run[0] for run in meta["runs"])
        return done

    def episode_chunks(self) -> dict[Path, dict[str, Any]]:
        """The chunks of episodes, each with its footer: not those of a deep study's evaluations or of the forensics'
        summaries (their footer's kind)."""
        return {path: meta for path, meta in self.chunk_files.items() if meta.get("kind") not in (EVALUATIONS, SUMMARIES)}

    def kinds(self) -> set[str]:
        """The kinds of records the files hold: ``EPISODES`` (run files, chunks of episodes), ``EVALUATIONS``,
        ``SUMMARIES``."""
        kinds = {str(meta["kind"]) if meta.get("kind") in (EVALUATIONS, SUMMARIES) else EPISODES
                 for meta in self.chunk_files.values()}
        return kinds | ({EPISODES} if self.run_files else set())


def check_run_file(path: Path) -> dict[str, Any]:
    """A run file's record, or ``DamagedFile`` saying what is wrong with it."""
    regular_file(path, MAX_RUN_FILE_BYTES)
    try:
        record = json.loads(read_bytes(path, MAX_RUN_FILE_BYTES))
    except OSError as error:
        raise DamagedFile(f"can not be read ({error.strerror or error})") from None
    except UnreadableFile as error:
        raise DamagedFile(error.reason) from None
    except (ValueError, UnicodeDecodeError) as error:
        raise DamagedFile(f"is not valid JSON ({error})") from None
    if not isinstance(record, dict):
        raise DamagedFile("is not a run record (a JSON object)")
    config, episodes = record.get("config"), record.get("episodes")
    if record.get("run_id") != path.stem:
        raise DamagedFile(f"names run {record.get('run_id')!r}, not the run of its file name")
    if not isinstance(config, dict) or not isinstance(config.get("agent"), str) or not isinstance(config.get("labels"), dict):
        raise DamagedFile("has no run config (config.agent, config.labels)")
    if not isinstance(episodes, dict) or not isinstance(episodes.get("episode"), list):
        raise DamagedFile("has no per-episode columns (episodes.episode)")
    lengths = {len(v) if isinstance(v, list) else -1 for v in episodes.values()}
    if len(lengths) != 1 or -1 in lengths:
        raise DamagedFile("has per-episode columns of different lengths")
    if record.get("status", "ok") != "ok":
        raise DamagedFile(f"has status {record.get('status')!r}, not 'ok'")
    check_episode_count(len(episodes["episode"]), config)
    return record


def check_episode_count(count: int, config: dict[str, Any]) -> None:
    """A run's episodes: the config's ``episodes`` (at most that many when ``max_timesteps`` may end it earlier)."""
    wanted = config.get("episodes")
    if not isinstance(wanted, int) or (count != wanted if config.get("max_timesteps") is None else count > wanted):
        raise DamagedFile(f"holds {count} episodes of a run, its config says episodes={wanted!r}")



def check_chunk(path: Path) -> dict[str, Any]:
    """A chunk's footer, or ``DamagedFile`` saying what is wrong with it (only the footer is read)."""
    regular_file(path, None)
    try:
        meta = chunk_meta(path)
    except OSError as error:
        if error.errno is not None:
            raise DamagedFile(f"can not be read ({error.strerror or error})") from None
        raise DamagedFile(f"is not a readable chunk ({type(error).__name__}: {' '.join(str(error).split())})") from None
    except Exception as error:  # pyarrow's ArrowInvalid (a truncated or garbled file), a footer without our key
        text = " ".join(str(error).split()) or type(error).__name__
        raise DamagedFile(f"is not a readable chunk ({type(error).__name__}: {text})") from None
    base, runs, timings = meta.get("base"), meta.get("runs"), meta.get("timings")
    if not isinstance(base, dict) or not isinstance(base.get("agent"), str) or not isinstance(base.get("labels"), dict):
        raise DamagedFile("has no run config in its footer (base.agent, base.labels)")
    if not isinstance(runs, list) or not all(
        isinstance(r, list) and len(r) == 4 and isinstance(r[0], str) and all(type(v) is int for v in r[1:]) for r in runs
    ):
        raise DamagedFile("has no run list in its footer (each run: [id, seed, replicate, decisions])")
    if not isinstance(timings, dict) or not isinstance(timings.get("wall_seconds"), (int, float)):
        raise DamagedFile("has no timings in its footer")
    if meta.get("batch") != path.stem:
        raise DamagedFile(f"holds batch {meta.get('batch')!r}, not the batch of its file name (a copy?)")
    if meta.get("kind") in (EVALUATIONS, SUMMARIES):  # a deep or forensics batch's few rows: read and checked whole
        try:
            (evaluation_table if meta["kind"] == EVALUATIONS else summary_rows)(path, meta)
        except Exception as error:
            if not isinstance(error, (OSError, ValueError, KeyError, TypeError)) and "pyarrow" not in type(error).__module__:
                raise
            raise DamagedFile(" ".join(str(error).split()) or type(error).__name__) from None
    return meta


def _recomputed(stored: list[str], ids: list[str]) -> list[str]:
    """The recomputed ``ids`` of a file's runs, or ``DamagedFile`` when a stored id is not its run's or one repeats."""
    for name, own in zip(stored, ids):
        if not stored_matches(name, own):
            raise DamagedFile(f"names run {name!r}, but its labels and seed give run {own!r}")
    if len(set(ids)) != len(ids):
        raise DamagedFile(f"lists run {next(i for i in ids if ids.count(i) > 1)!r} twice")
    return ids


def sort_files(
    run_files: list[Path],
    chunk_files: list[Path],
    belongs: Callable[[str, str], bool] | None,
) -> FolderFiles:
    """
    Check every file and sort them out.

    :param belongs: ``belongs(run_id, agent)``: whether a run is one of the folder's sweep (None: every run is)
    """
    files = FolderFiles()
    seen: set[str] = set()

    def accept(path: Path, ids: Collection[str], agent: str) -> bool:
        if belongs is not None and not all(belongs(rid, agent) for rid in ids):
            files.rejected.append((path, f"holds runs of another sweep (agent {agent!r})"))
            return False
        if seen.intersection(ids):
            files.rejected.append((path, "repeats runs another file already holds (a copy?)"))
            return False
        seen.update(ids)
        return True

    for path in run_files:
        try:
            record = check_run_file(path)
        except DamagedFile as error:
            files.rejected.append((path, str(error)))
            continue
        agent = record["config"]["agent"]
        try:
            (rid,) = _recomputed([path.stem], [run_id(record["config"])])
        except (DamagedFile, KeyError, TypeError) as error:
            files.rejected.append((path, str(error) if isinstance(error, DamagedFile) else "has an incomplete run config"))
            continue
        if accept(path, (rid,), agent):
            files.run_files[path] = agent
            files.run_ids[path] = rid
    for path in chunk_files:
        try:
            meta = check_chunk(path)
        except DamagedFile as error:
            files.rejected.append((path, str(error)))
            continue
        try:
            ids = base_run_ids(meta["base"], [(seed, replicate) for _, seed, replicate, _ in meta["runs"]])
            ids = _recomputed([run[0] for run in meta["runs"]], ids)
        except (DamagedFile, KeyError, TypeError) as error:
            files.rejected.append((path, str(error) if isinstance(error, DamagedFile) else "has an incomplete run config"))
            continue
        if accept(path, ids, meta["base"]["agent"]):
            for run, rid in zip(meta["runs"], ids):
                run[0] = rid
            files.chunk_files[path] = meta
    return files
