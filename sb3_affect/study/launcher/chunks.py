"""
Chunks: the finished runs of one batch in one Parquet file (``DIR/chunks/<batch>.parquet``): a tabular batch's episodes
(``encode_chunk``), a deep batch's evaluations (``encode_evaluations``, its footer's ``kind``: ``evaluations``), or the
forensics' replications (``encode_summaries``, ``kind``: ``summaries``).

A chunk holds one row per episode: ``run`` (the run's index in the chunk) and every ``EPISODE_COLUMNS`` column (counts
as int64, flags as booleans, null where a run can not tell, the rest float64; written before counts were int64:
int32). Its Parquet key-value metadata (``sb3_affect``, JSON) holds what is per run or per batch::

    {"schema": 2, "batch": "<name>", "base": {run config, seed None, labels without replicate},
     "runs": [[run_id, seed, replicate, decisions], ...],
     "timings": {"wall_seconds": <the batch>, "pid": <the worker>}, "versions": {...}}

so the run ids of a whole results folder come from the files' footers alone, and a run's config is the base with its
seed and replicate filled in. A chunk is written by the driver in one atomic rename: it is whole or absent.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sb3_affect.core.episode_log import EPISODE_COLUMNS, FLAG_COLUMNS, INT_COLUMNS
from sb3_affect.study.launcher.run_ids import run_config

CHUNK_SCHEMA = 2
META_KEY = b"sb3_affect"
BOOL_COLUMNS = FLAG_COLUMNS


def arrow_array(values: np.ndarray, kind: Any, missing: np.ndarray | None = None) -> Any:
    """
    ``values`` as an Arrow array of type ``kind`` (``pa.int64()``, ``pa.int32()``, ``pa.float64()`` or ``pa.bool_()``)
    from its bytes: what ``pa.array(values.astype(...))`` gives, without importing pandas (``pa.array`` does on first
    use). ``missing``: where the values are null (flags a run can not tell); None: no nulls.
    """
    if kind == pa.bool_():
        data = np.packbits(np.asarray(values, dtype=bool), bitorder="little")  # Arrow's booleans: one bit each, LSB first
    else:
        dtype = {pa.int64(): np.int64, pa.int32(): np.int32}.get(kind, np.float64)
        data = np.ascontiguousarray(values, dtype=dtype)
    validity = None
    if missing is not None and missing.any():
        validity = pa.py_buffer(np.packbits(~np.asarray(missing, dtype=bool), bitorder="little"))
    return pa.Array.from_buffers(kind, len(values), [validity, pa.py_buffer(data)])


def checked_column(column: str, values: Any) -> tuple[np.ndarray, np.ndarray | None]:
    """
    An episode column as it is stored, or a one-line ValueError when a value would not read back as it is: counts
    (``INT_COLUMNS``) are integers (never NaN, infinite or fractional; int64), flags (``FLAG_COLUMNS``) true, false or
    NaN (a run that can not tell: stored as null, read back as NaN), the other columns numbers.

    :return: ``(values, missing)``: the values in their stored dtype and, for flags, where they are NaN (None: nowhere)
    """
    array = np.asarray(values)
    if column in INT_COLUMNS:
        if array.dtype.kind in "iub":
            return array.astype(np.int64, copy=False), None
        numbers = np.asarray(values, dtype=np.float64)
        bad = ~np.isfinite(numbers) | (numbers != np.round(numbers)) | (np.abs(numbers) >= 2.0**63)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"episode column {column!r}: row {row} holds {numbers[row]!r}, not a count; counts are integers"
            )
        return numbers.astype(np.int64), None
    if column in FLAG_COLUMNS:
        if array.dtype.kind == "b":
            return array, None
        numbers = np.asarray(values, dtype=np.float64)
        missing = np.isnan(numbers)
        bad = ~missing & (numbers != 0) & (numbers != 1)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ValueError(f"episode column {column!r}: row {row} holds {numbers[row]!r}, not a flag (true, false or NaN)")
        return numbers == 1, (missing if missing.any() else None)
    return np.asarray(values, dtype=np.float64), None


def chunk_bytes(arrays: dict[str, Any], meta: dict[str, Any]) -> bytes:
    """A chunk's Parquet bytes: its columns, and its footer ``meta`` as JSON under ``META_KEY``."""
    table = pa.table(arrays).replace_schema_metadata({META_KEY: json.dumps(meta, sort_keys=True).encode()})
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="lz4")  # fast to write and read; dictionary + RLE encoding does the rest
    return sink.getvalue()


def encode_chunk(
    name: str,
    base: dict[str, Any],
    runs: Sequence[tuple[str, int, int]],
    episodes: Any,
    timings: dict[str, Any],
    versions: dict[str, str],
) -> bytes:
    """
    The Parquet bytes of a chunk.

    :param name: the batch's name
    :param base: the batch's base config (seed None, labels without replicate)
    :param runs: ``(run id, seed, replicate)`` of each run
    :param episodes: ``simulate``'s table for the batch's distinct seeds, in order of first use: a ``seed`` column and
        every ``EPISODE_COLUMNS`` column, each seed's rows together (a DataFrame, or ``{column: array}``)
    :param timings: the batch's wall time and worker pid
    :param versions: package versions
    """
    seeds = np.asarray(episodes["seed"])
    starts = np.flatnonzero(np.r_[True, seeds[1:] != seeds[:-1]]) if len(seeds) else np.zeros(0, dtype=np.int64)
    ends = np.r_[starts[1:], len(seeds)].astype(np.int64)
    block = {int(seeds[start]): i for i, start in enumerate(starts)}
    order = list(dict.fromkeys(seed for _, seed, _ in runs))
    if list(block) != order or len(block) != len(starts):
        raise ValueError(f"batch {name}: the episode table's seeds {list(block)[:5]}... are not the batch's {order[:5]}...")
    distinct = len(order) == len(runs)  # no seed used twice: the table's rows are already in the runs' order
    take = None if distinct else np.concatenate([np.arange(starts[block[seed]], ends[block[seed]]) for _, seed, _ in runs])
    lengths = np.array([ends[block[seed]] - starts[block[seed]] for _, seed, _ in runs], dtype=np.int64)
    decisions = np.asarray(episodes["decisions"], dtype=np.int64)
    totals = [int(decisions[starts[block[seed]] : ends[block[seed]]].sum()) for _, seed, _ in runs]
    arrays: dict[str, Any] = {"run": arrow_array(np.repeat(np.arange(len(runs), dtype=np.int32), lengths), pa.int32())}
    for column in EPISODE_COLUMNS:
        try:
            values, missing = checked_column(column, episodes[column])
        except ValueError as error:
            raise ValueError(f"batch {name}: {error}") from None
        values = values if take is None else values[take]
        missing = missing if take is None or missing is None else missing[take]
        kind = pa.int64() if column in INT_COLUMNS else pa.bool_() if column in BOOL_COLUMNS else pa.float64()
        arrays[column] = arrow_array(values, kind, missing)
    meta = {
        "schema": CHUNK_SCHEMA,
        "batch": name,
        "base": base,
        "runs": [[rid, seed, replicate, total] for (rid, seed, replicate), total in zip(runs, totals)],
        "timings": timings,
        "versions": versions,
    }
    return chunk_bytes(arrays, meta)


def chunk_meta(path: Path) -> dict[str, Any]:
    """The per-run and per-batch data of a chunk (its footer only)."""
    metadata = pq.read_metadata(path).metadata or {}  # the file's key-value metadata, no schema conversion
    return dict(json.loads(metadata[META_KEY]))


def chunk_table(path: Path, columns: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """``run`` and the episode columns of a chunk as numpy arrays (``columns``: a subset of ``EPISODE_COLUMNS``)."""
    wanted = ["run", *(EPISODE_COLUMNS if columns is None else columns)]
    table = pq.ParquetFile(path).read(columns=wanted)  # not ``read_table``: its dataset set-up costs ms a file
    out = {}
    for name in wanted:
        column = table.column(name)
        if column.null_count and name in BOOL_COLUMNS:  # flags a run could not tell: NaN, as the engine gave them
            column = column.cast(pa.float64())
        elif column.null_count:
            raise ValueError(f"column {name!r} holds {column.null_count} nulls; only flags may")
        out[name] = column.to_numpy()
    return out


def _plain(value: Any) -> Any:
    value = value.item() if hasattr(value, "item") else value
    return None if isinstance(value, float) and math.isnan(value) else value


def chunk_records(path: Path, meta: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """
    The runs of a chunk as run records of the JSON layout (``config``, ``episodes`` lists, ``timings``, ...).

    :param meta: its footer when already read and checked (``folder_files``); None: read here
    """
    meta = chunk_meta(path) if meta is None else meta
    table = chunk_table(path)
    bounds = np.searchsorted(table["run"], np.arange(len(meta["runs"]) + 1))
    share = round(meta["timings"]["wall_seconds"] / max(1, len(meta["runs"])), 6)
    records = []
    for index, (rid, seed, replicate, decisions) in enumerate(meta["runs"]):
        rows = slice(bounds[index], bounds[index + 1])
        episodes = {column: [_plain(v) for v in table[column][rows].tolist()] for column in sorted(EPISODE_COLUMNS)}
        for column in BOOL_COLUMNS:  # (a chunk holding NaN flags gives them as floats)
            episodes[column] = [None if v is None else bool(v) for v in episodes[column]]
        records.append(
            {
                "schema": CHUNK_SCHEMA,
                "run_id": rid,
                "config": run_config(meta["base"], seed, replicate),
                "status": "ok",
                "episodes": episodes,
                "timings": {**meta["timings"], "wall_seconds": share, "decisions": decisions, "batch": meta["batch"]},
                "versions": meta["versions"],
            }
        )
    return records


#: The per-seed rows of a deep batch's evaluations, ``(seeds, evaluations)`` each (``deep_training.run_batch``).
EVALUATION_ROWS = ("success", "return", "random_share", "train_episodes", "train_successes")
#: A chunk of evaluations (the deep study's batches) says so in its footer's ``kind``; one of episodes says no kind.
EVALUATIONS = "evaluations"
#: The kind of record of a run file or a chunk whose footer says no ``kind``: one row per episode.
EPISODES = "episodes"


def encode_evaluations(
    name: str,
    base: dict[str, Any],
    runs: Sequence[tuple[str, int, int]],
    record: dict[str, Any],
    timings: dict[str, Any],
    versions: dict[str, str],
    epsilons: Sequence[float] | None,
) -> bytes:
    """
    The Parquet bytes of a chunk of evaluations: one row per run and evaluation, ``run``, ``step`` (the env steps
    trained), every ``EVALUATION_ROWS`` row and, for an affective agent, ``emotion.<name>`` (NaN: no decision or emotion
    in that part); the footer as ``encode_chunk``'s (each run's decisions: the budget) with ``kind``, each run's
    ``first_success`` (None: never) and the ``epsilons`` a replaying agent took.
    """
    seeds, evaluations = len(runs), base["budget"] // base["eval_every"]
    tables = {key: record[key] for key in EVALUATION_ROWS}
    tables.update({f"emotion.{key}": table for key, table in (record["emotions"] or {}).items()})
    arrays: dict[str, Any] = {
        "run": arrow_array(np.repeat(np.arange(seeds, dtype=np.int32), evaluations), pa.int32()),
        "step": arrow_array(np.tile(base["eval_every"] * np.arange(1, evaluations + 1), seeds), pa.int64()),
    }
    for key, table in tables.items():
        values = np.asarray(table, dtype=np.float64)
        if values.shape != (seeds, evaluations):
            raise ValueError(f"batch {name}: {key} has the shape {values.shape}, not {seeds} x {evaluations} evaluations")
        arrays[key] = arrow_array(values.ravel(), pa.float64())
    meta = {
        "schema": CHUNK_SCHEMA, "kind": EVALUATIONS, "batch": name, "base": base,
        "runs": [[rid, seed, replicate, base["budget"]] for rid, seed, replicate in runs],
        "first_success": list(record["first_success"]), "epsilons": None if epsilons is None else list(epsilons),
        "timings": timings, "versions": versions,
    }  # fmt: skip
    return chunk_bytes(arrays, meta)


def evaluation_table(path: Path, meta: dict[str, Any]) -> dict[str, np.ndarray]:
    """
    A chunk of evaluations' rows ``(runs, evaluations)`` by column, or a ``ValueError`` saying why they are not the
    rows its footer describes: every run's evaluations in order, a success rate in [0, 1] and a finite return in each.
    """
    base, runs = meta["base"], len(meta["runs"])
    evaluations = base["budget"] // base["eval_every"]
    table = pq.ParquetFile(path).read()
    columns = {name: table.column(name).to_numpy() for name in table.column_names}
    missing = [key for key in ("run", "step", *EVALUATION_ROWS) if key not in columns]
    if missing or table.num_rows != runs * evaluations:
        raise ValueError(f"holds {table.num_rows} rows without {missing} or not {runs} runs x {evaluations} evaluations")
    steps = np.tile(base["eval_every"] * np.arange(1, evaluations + 1), runs)
    in_order = np.array_equal(columns["run"], np.repeat(np.arange(runs), evaluations))
    if not (in_order and np.array_equal(columns["step"], steps)):
        raise ValueError("does not hold each run's evaluations in order")
    success, returns = columns["success"], columns["return"]
    if not (np.isfinite(success).all() and ((success >= 0) & (success <= 1)).all() and np.isfinite(returns).all()):
        raise ValueError("has a success or return that no evaluation gives (empty, NaN or out of range)")
    if not (isinstance(meta.get("first_success"), list) and len(meta["first_success"]) == runs):
        raise ValueError(f"has no first_success of its {runs} runs in its footer")
    return {name: values.reshape(runs, evaluations) for name, values in columns.items() if name not in ("run", "step")}


def _rows(values: np.ndarray) -> list[list[float | None]]:
    return [[None if math.isnan(v) else v for v in row] for row in values.tolist()]


def evaluation_cells(chunks: dict[Path, dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
    """
    The chunks of evaluations of a folder (path -> footer, checked) as one record per cell ``(task, agent)``: its runs
    in replicate order, each row a list per run (None where a part had no decision or emotion), the cell's settings.
    """
    parts: dict[tuple[str, str], list[tuple[int, int, dict[str, Any], dict[str, np.ndarray]]]] = {}
    for path, meta in chunks.items():
        if meta.get("kind") == EVALUATIONS:
            table = evaluation_table(path, meta)
            key = (meta["base"]["labels"]["task"], meta["base"]["agent"])
            for index, (_, _, replicate, _) in enumerate(meta["runs"]):
                parts.setdefault(key, []).append((replicate, index, meta, table))
    cells = {}
    for (task, agent), runs in parts.items():
        runs.sort(key=lambda run: run[0])
        metas = [meta for _, _, meta, _ in runs]
        base = metas[0]["base"]
        tables = {name: _rows(np.stack([table[name][index] for _, index, _, table in runs])) for name in runs[0][3]}
        emotions = {name.removeprefix("emotion."): rows for name, rows in tables.items() if name.startswith("emotion.")}
        cells[task, agent] = {
            "task": task, "agent": agent, "algo": base["algo"], "env_id": base["env_id"], "budget": base["budget"],
            "seeds": [meta["runs"][index][1] for _, index, meta, _ in runs], "eval_every": base["eval_every"],
            "eval_episodes": base["eval_episodes"], "count_bonus": base["count_bonus"], "epsilons": metas[0]["epsilons"],
            "eval_steps": [base["eval_every"] * (k + 1) for k in range(base["budget"] // base["eval_every"])],
            **{name: tables[name] for name in EVALUATION_ROWS}, "emotions": emotions or None,
            "first_success": [meta["first_success"][index] for _, index, meta, _ in runs],
            "seconds": sum({meta["batch"]: meta["timings"]["cpu_seconds"] for meta in metas}.values()),
        }  # fmt: skip
    return cells


#: A chunk of the forensics' replications (``forensics.units.ForensicsBatch``) says so in its footer's ``kind``.
SUMMARIES = "summaries"


def encode_summaries(
    name: str,
    base: dict[str, Any],
    runs: Sequence[tuple[str, int, int]],
    cells: Sequence[dict[float, dict[str, float]]],
    complete: Sequence[bool],
    timings: dict[str, Any],
    versions: dict[str, str],
) -> bytes:
    """
    The Parquet bytes of a chunk of the forensics' replications: one row per run and ε cell, ``run``, ``epsilon`` and
    each of the cell's sums (``forensics.statistics.cell_summary``, float64); the footer as ``encode_chunk``'s (each
    run's decisions: 0) with ``kind`` and each run's ``complete`` (False: a pre-screen replication stopped early).
    """
    keys = sorted({key for run in cells for row in run.values() for key in row})
    index = [(number, float(eps)) for number, run in enumerate(cells) for eps in sorted(run)]
    arrays: dict[str, Any] = {
        "run": arrow_array(np.array([number for number, _ in index], dtype=np.int32), pa.int32()),
        "epsilon": arrow_array(np.array([eps for _, eps in index], dtype=np.float64), pa.float64()),
    }
    for key in keys:
        arrays[key] = arrow_array(np.array([cells[n][e][key] for n, e in index], dtype=np.float64), pa.float64())
    meta = {
        "schema": CHUNK_SCHEMA, "kind": SUMMARIES, "batch": name, "base": base,
        "runs": [[rid, seed, replicate, 0] for rid, seed, replicate in runs], "complete": [bool(c) for c in complete],
        "timings": timings, "versions": versions,
    }  # fmt: skip
    return chunk_bytes(arrays, meta)


def summary_rows(path: Path, meta: dict[str, Any]) -> list[tuple[dict[str, np.ndarray], bool]]:
    """
    A chunk of replications' rows, per run (in the footer's order): ``{column: values by ε}`` with ``epsilon``, and
    whether the run is complete; or a ``ValueError`` saying why they are not the rows its footer describes.
    """
    runs, complete = len(meta["runs"]), meta.get("complete")
    if not (isinstance(complete, list) and len(complete) == runs and all(isinstance(c, bool) for c in complete)):
        raise ValueError(f"has no complete flag of its {runs} runs in its footer")
    table = pq.ParquetFile(path).read()
    columns = {name: table.column(name).to_numpy() for name in table.column_names}
    if "run" not in columns or "epsilon" not in columns or len(columns) < 3:
        raise ValueError("holds no run, epsilon and summary columns")
    if not all(np.isfinite(values).all() for name, values in columns.items() if name != "run"):
        raise ValueError("has a cell summary that is not a finite number")
    out = []
    for number in range(runs):
        rows = columns["run"] == number
        if not rows.any() or not np.all(np.diff(columns["epsilon"][rows]) > 0):
            raise ValueError(f"does not hold run {number}'s ε cells in order")
        out.append(({name: values[rows] for name, values in columns.items() if name != "run"}, complete[number]))
    return out


def summary_cells(chunks: dict[Path, dict[str, Any]]) -> dict[tuple[str, str, int], tuple[dict[str, np.ndarray], bool]]:
    """
    The chunks of replications of a folder (path -> footer, checked): ``(simulation, stage, replication) -> (rows,
    complete)`` (``summary_rows``).
    """
    cells = {}
    for path, meta in chunks.items():
        if meta.get("kind") == SUMMARIES:
            base = meta["base"]
            for (_, _, replicate, _), rows in zip(meta["runs"], summary_rows(path, meta)):
                cells[base["agent"], base["labels"]["stage"], replicate] = rows
    return cells
