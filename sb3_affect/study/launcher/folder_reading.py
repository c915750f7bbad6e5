"""
Reading a results folder column-wise (the read side of ``ResultsStore``): one row per run from the chunks' footers
and the run files, and the episode columns as numpy arrays, without a Python object per episode.

A results folder of 180,000 runs of 200 episodes is 36 M episode rows: ``read_folder`` allocates each wanted column
once at its final size (int32 counts, bool flags, float64 otherwise; wider where a value needs it) and fills it
chunk by chunk, so its peak memory is the columns themselves plus one chunk. Rows come in one canonical order
whatever the layout and the batching: runs by run id, each run's episodes in the order stored (episode order).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
from numba import njit

from sb3_affect.study.launcher.chunks import BOOL_COLUMNS, INT_COLUMNS, META_KEY, checked_column, chunk_table
from sb3_affect.study.launcher.folder_files import DamagedFile, check_episode_count, guarded
from sb3_affect.study.launcher.regular_files import read_json
from sb3_affect.study.launcher.run_ids import RUN_COLUMNS, run_id


def column_dtype(column: str) -> type:
    """
    The dtype of an episode column once read: int32 counts, bool flags, float64 otherwise (NaN: not defined). A read
    that holds a count beyond int32's range reads that column as int64, one that holds a flag a run could not tell
    reads that flag as float64 with NaN there (``read_folder``): every value reads back as the engine gave it.
    """
    if column in INT_COLUMNS:
        return np.int32
    if column in BOOL_COLUMNS:
        return np.bool_
    return np.float64


def typed(column: str, values: list[Any]) -> np.ndarray:
    """
    A JSON episode column as the chunks' dtype (``chunks.checked_column``: counts int64, flags bool, or float64 with
    NaN when one is null: a run that can not tell, the rest float64 with NaN for null); a value that is none of these
    is a ValueError naming it.
    """
    if column in BOOL_COLUMNS or column in INT_COLUMNS:
        array, missing = checked_column(column, [np.nan if v is None else v for v in values])
        return array if missing is None else np.where(missing, np.nan, array)
    return np.asarray([np.nan if v is None else v for v in values], dtype=np.float64)


_INT32 = np.iinfo(np.int32)


def _room_for(target: np.ndarray, values: np.ndarray) -> np.ndarray:
    """
    ``target``, or a copy of it wide enough for ``values``: int64 for counts beyond int32's range, float64 for flags
    with NaN (a run that can not tell).
    """
    if target.dtype == np.bool_ and values.dtype.kind == "f":
        return target.astype(np.float64)
    wide = target.dtype == np.int32 and values.dtype.itemsize > 4 and len(values)
    if wide and (values.min() < _INT32.min or values.max() > _INT32.max):
        return target.astype(np.int64)
    return target


def run_row(rid: str, config: dict[str, Any], decisions: int | None, episodes: int, wall: float | None) -> dict[str, Any]:
    """One row of the run table from a run file's config and timings."""
    return {
        "run_id": rid,
        "agent": config["agent"],
        "algo": config["algo"],
        "seed": config["seed"],
        **config["labels"],
        "decisions": decisions,
        "episodes": episodes,
        "wall_seconds": wall,
        "max_timesteps": config.get("max_timesteps"),
    }


def _chunk_footer(path: Path, with_runs: bool) -> tuple[dict[str, Any], np.ndarray | None]:
    """A chunk's footer and (``with_runs``) its ``run`` column, opening the file once."""
    handle = pq.ParquetFile(path)
    meta = dict(json.loads((handle.schema_arrow.metadata or {})[META_KEY]))
    run = handle.read(columns=["run"]).column("run").to_numpy() if with_runs else None
    return meta, run


def file_parts(
    json_files: Sequence[Path], chunk_files: dict[Path, dict[str, Any]], runs_per_part: int | None
) -> list[tuple[list[Path], list[Path]]]:
    """
    The files of a folder in parts of about ``runs_per_part`` runs (whole chunks, counted from their footers; run
    files ``runs_per_part`` at a time), for ``read_folder`` one part at a time; None: one part of every file.
    """
    if runs_per_part is None:
        return [(list(json_files), list(chunk_files))]
    size = max(1, runs_per_part)
    parts: list[tuple[list[Path], list[Path]]] = [
        (list(json_files[i : i + size]), []) for i in range(0, len(json_files), size)
    ]
    part: list[Path] = []
    count = 0
    for path, meta in chunk_files.items():
        part.append(path)
        count += len(meta["runs"])
        if count >= size:
            parts.append(([], part))
            part, count = [], 0
    if part:
        parts.append(([], part))
    return parts or [([], [])]


def ordered_file_parts(
    json_files: Sequence[Path], chunk_files: dict[Path, dict[str, Any]], runs_per_part: int | None
) -> list[tuple[list[Path], list[Path]]]:
    """
    ``file_parts`` whose runs follow each other in run id order: every run of a part comes after every run of the
    parts before it (a part read by ``read_folder`` is in run id order, so the parts one after the other are too).

    Files whose run ids interleave (the chunks of one cell: seeds drawn at random) are kept in one part; parts hold
    about ``runs_per_part`` runs (whole groups of such files; None: one part). From the chunks' footers and the run
    files' names (``runs/<run id>.json``) alone.
    """
    spans: list[tuple[str, str, Path, int]] = [(path.stem, path.stem, path, 1) for path in json_files]
    for path, meta in chunk_files.items():
        ids = [run[0] for run in meta["runs"]]
        if ids:
            spans.append((min(ids), max(ids), path, len(ids)))
    spans.sort(key=lambda span: (span[0], span[1]))
    parts: list[tuple[list[Path], list[Path]]] = []
    top, count = "", 0
    for first, last, path, runs in spans:
        full = runs_per_part is not None and count >= max(1, runs_per_part)
        if not parts or (full and first > top):  # a new part: the current one is full and no run id of it comes later
            parts.append(([], []))
            count = 0
        parts[-1][0 if path.suffix == ".json" else 1].append(path)
        top, count = max(top, last), count + runs
    return parts or [([], [])]


def read_folder(
    json_files: Sequence[Path],
    chunk_files: Sequence[Path],
    columns: Sequence[str] | None,
    root: Path,
    footers: Mapping[Path, dict[str, Any]] | None = None,
    episode_counts: dict[Path, np.ndarray] | None = None,
) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """
    The run table of a results folder and (unless ``columns`` is None) its episode columns.

    :param json_files: the run files (``DIR/runs/*.json``)
    :param chunk_files: the chunks (``DIR/chunks/*.parquet``)
    :param columns: the episode columns wanted, or None for the run table only (chunks: footers only)
    :param root: the folder (for error messages)
    :param footers: the chunks' footers when already read and checked (``FolderFiles.chunk_files``, their run ids
        recomputed): not parsed again
    :param episode_counts: each chunk's episodes per run once counted (``FolderFiles.episode_counts``): with
        ``footers``, a chunk counted before is not read for them again; the chunks counted here are added
    :return: ``(runs, data)``: ``runs`` one row per finished run sorted by run id (``RUN_COLUMNS`` and the labels);
        ``data`` the episode columns and ``run`` (int32, the row in ``runs``), each run's rows together
    """
    rows: list[dict[str, Any]] = []
    json_parts: list[dict[str, np.ndarray]] = []
    json_counts: list[int] = []
    for path in json_files:
        record = guarded(path, read_json)
        if record.get("status", "ok") != "ok":
            continue
        config, episodes, timings = record["config"], record["episodes"], record.get("timings", {})
        count = len(episodes["episode"])
        rows.append(run_row(run_id(config), config, timings.get("decisions"), count, timings.get("wall_seconds")))
        json_counts.append(count)
        if columns is not None:
            json_parts.append(guarded(path, lambda p, e=episodes: {c: typed(c, e[c]) for c in columns}))  # type: ignore[misc]
    frames = [pd.DataFrame(rows)] if rows else []
    lengths = [np.array(json_counts, dtype=np.int64)]
    chunks: list[tuple[Path, int, np.ndarray]] = []  # (file, its first run's row in the read order, run starts)
    total = len(rows)
    for path in chunk_files:
        run: np.ndarray | None
        known = None
        if footers is not None and path in footers:
            known = None if episode_counts is None or columns is None else episode_counts.get(path)
            meta = footers[path]
            run = None if known is not None or columns is None else guarded(path, lambda p: chunk_table(p, ())["run"])
        else:
            meta, run = guarded(path, lambda p: _chunk_footer(p, columns is not None))
        base, count = meta["base"], len(meta["runs"])
        ids, seeds, replicates, decisions = (list(values) for values in zip(*meta["runs"])) if count else ([],) * 4
        episodes_per_run: Any = base["episodes"]  # the footer only: the batch's episode budget
        if run is not None:
            if np.any(np.diff(run) < 0):
                raise ValueError(f"{root}: a run's episodes are not stored together in {path.name}")
            if len(run) and (run[0] < 0 or run[-1] >= count):
                bad = run[-1] if run[0] >= 0 else run[0]
                raise ValueError(f"{path}: its run column holds run {bad}, not one of the {count} runs of its footer")
            known = np.bincount(run, minlength=count).astype(np.int64)
            for index, episodes in enumerate(known.tolist()):
                try:
                    check_episode_count(episodes, base)
                except DamagedFile as error:
                    raise ValueError(f"{path}: run {ids[index]!r} {error}") from None
        if known is not None:
            per_run = known
            if episode_counts is not None and footers is not None and path in footers:
                episode_counts[path] = per_run
            episodes_per_run = per_run
            lengths.append(per_run)
            chunks.append((path, total, np.r_[0, np.cumsum(per_run)[:-1]]))
        frames.append(
            pd.DataFrame(
                {
                    "run_id": ids,
                    "agent": base["agent"],
                    "algo": base["algo"],
                    "seed": seeds,
                    **base["labels"],
                    "replicate": replicates,
                    "decisions": decisions,
                    "episodes": episodes_per_run,
                    "wall_seconds": meta["timings"]["wall_seconds"] / max(1, count),
                    "max_timesteps": [base.get("max_timesteps")] * count,
                },
                index=pd.RangeIndex(count),
            )
        )
        total += count
    runs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=list(RUN_COLUMNS))
    order = np.argsort(runs["run_id"].to_numpy(dtype=object), kind="stable") if total else np.zeros(0, np.int64)
    runs = runs.iloc[order].reset_index(drop=True)
    if columns is None:
        return runs, {}
    counts = np.concatenate(lengths) if total else np.zeros(0, np.int64)
    sorted_counts = counts[order]
    rank = np.empty(total, dtype=np.int64)
    rank[order] = np.arange(total)
    start = np.r_[0, np.cumsum(sorted_counts)[:-1]].astype(np.int64)[rank]  # each run's first row, in read order
    size = int(counts.sum())
    data: dict[str, np.ndarray] = {"run": np.repeat(np.arange(total, dtype=np.int32), sorted_counts)}
    for column in columns:
        data[column] = np.empty(size, dtype=column_dtype(column))
    for index, part in enumerate(json_parts):
        rows_of_run = slice(start[index], start[index] + counts[index])
        for column in columns:
            data[column] = _room_for(data[column], part[column])
            data[column][rows_of_run] = part[column]
    for path, first, run_starts in chunks:
        table = guarded(path, lambda p: chunk_table(p, columns))
        run = table.pop("run")
        n_runs = len(run_starts)
        if not _fits(run, run_starts, counts[first : first + n_runs]):
            raise ValueError(f"{root}: the rows of {path.name} are not those its runs were counted with")
        for column in columns:
            values = table.pop(column)
            data[column] = _room_for(data[column], values)
            _place(data[column], values, run, start[first : first + n_runs], run_starts)
    return runs, data


@njit(cache=True, nogil=True)
def _fits(run: np.ndarray, run_starts: np.ndarray, counts: np.ndarray) -> bool:
    """Whether each row ``i`` of a chunk lies in its run's rows: ``run_starts[run[i]] <= i < run_starts + counts``."""
    for i in range(len(run)):
        r = run[i]
        if r < 0 or r >= len(run_starts) or i < run_starts[r] or i >= run_starts[r] + counts[r]:
            return False
    return True


@njit(cache=True, nogil=True)
def _place(target: np.ndarray, values: np.ndarray, run: np.ndarray, runs_start: np.ndarray, run_starts: np.ndarray) -> None:
    """
    ``target[runs_start[run] + (i - run_starts[run])] = values``, row by row (``_fits``): a chunk's rows (run
    ``run[i]``, whose rows start at ``run_starts[run]`` in the chunk) moved to their runs' rows in the read order.
    """
    for i in range(len(run)):
        r = run[i]
        target[runs_start[r] + (i - run_starts[r])] = values[i]


def episode_table(runs: pd.DataFrame, data: dict[str, np.ndarray], run_columns: Sequence[str]) -> pd.DataFrame:
    """
    One row per episode: ``run_columns`` of each row's run (categoricals, but ``seed``), then the episode columns.

    Consumes ``data`` (each column is moved into the frame, so the peak is the table plus one column).
    """
    run = data.pop("run")
    frame = pd.DataFrame(index=pd.RangeIndex(len(run)))
    for key in run_columns:
        values = runs[key]
        if key == "seed":
            frame[key] = values.to_numpy()[run]
        elif key == "run_id" and values.is_unique:  # sorted and unique: the run's row is its code
            frame[key] = pd.Categorical.from_codes(run, categories=pd.Index(values.to_numpy()))
        else:
            categories = pd.Categorical(values)
            frame[key] = pd.Categorical.from_codes(categories.codes[run], categories=categories.categories)
    for name in list(data):
        frame[name] = data.pop(name)
    return frame
