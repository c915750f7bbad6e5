"""
The forensics results folder: one small JSON file per finished (simulation, replication), written atomically.

Layout of ``DIR``::

    DIR/forensics.json                     the protocol (a different protocol into DIR is refused)
    DIR/summaries/<simulation>/r0000.json  one replication of one simulation: its per-epsilon ``cell_summary`` rows
    DIR/summaries/<simulation>/r0000.partial.json  a pre-screen replication stopped early (the simulation is rejected)
    DIR/screen.csv, DIR/leaders.csv, ...   the analysis (rewritten by every run)
    DIR/failed/<simulation>__r0000.json    a replication that raised or whose worker died (retried on resume)
    DIR/damaged/                           summaries that did not read back, set aside (their replications rerun)
    DIR/.lock, .lock.owner                 the launcher's lock, as a sweep's folder

A rerun skips every replication already on disk that reads back as a summary: an interrupted run resumes where it
stopped; a summary that does not read back (empty, garbage, a link) is moved to ``DIR/damaged/`` and simulated again.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.study.forensics.candidates import Protocol, Simulation
from sb3_affect.study.launcher.regular_files import UnreadableFile, read_json
from sb3_affect.study.launcher.store import (
    FORENSICS_FILE,
    ResultsStore,
    StoreError,
    claim_kind,
    store_error,
    write_atomic,
)

#: The file that marks a forensics folder and holds its protocol.
PROTOCOL_FILE = FORENSICS_FILE
#: The largest summary or protocol file read (a replication's summary is a few kB).
MAX_SUMMARY_BYTES = 2**20
_REDO = "move it out of the folder and rerun the same command to simulate it again"


class SummaryStore:
    """
    Read and write the per-replication summaries of a forensics folder.

    :param root: the folder (created when missing; a replication's or a sweep's folder is refused)
    :param protocol: the protocol its summaries belong to
    """

    def __init__(self, root: str | Path, protocol: Protocol) -> None:
        self.root = Path(root)
        self.protocol = protocol
        claim_kind(self.root, "forensics", "forensics")
        try:
            self.root.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise store_error(self.root, error) from None
        saved = self.root / PROTOCOL_FILE
        wanted = {"protocol": protocol.as_dict()}
        if saved.exists() or saved.is_symlink():
            try:
                found = read_json(saved, MAX_SUMMARY_BYTES)
            except UnreadableFile as error:
                raise StoreError(f"{error}; a forensics folder's protocol record must be the JSON it wrote") from None
            if not isinstance(found, dict) or found.get("protocol") != wanted["protocol"]:
                found = found.get("protocol") if isinstance(found, dict) else found
                raise StoreError(
                    f"{self.root} holds forensics of another protocol ({found}); "
                    f"use another --out folder for {wanted['protocol']}"
                )
        else:
            write_atomic(saved, wanted)

    @contextlib.contextmanager
    def lock(self) -> Iterator[None]:
        """Hold the folder's lock while running, as a sweep's launcher does (StoreError at once when it is taken)."""
        with ResultsStore(self.root).lock():
            yield

    def path(self, simulation: Simulation, replication: int, complete: bool = True) -> Path:
        name = f"r{replication:04d}.json" if complete else f"r{replication:04d}.partial.json"
        return self.root / "summaries" / simulation.key / name

    def has(self, simulation: Simulation, replication: int, partial_ok: bool = False) -> bool:
        """
        Whether the replication is stored (complete; or stopped early too, with ``partial_ok``). A file that does not
        read back as a summary is moved to ``DIR/damaged/`` (one line on stderr): its replication is not stored.
        """
        paths = [self.path(simulation, replication)] + ([self.path(simulation, replication, False)] if partial_ok else [])
        for path in paths:
            if not os.path.lexists(path):
                continue
            why = _read_summary(path)
            if isinstance(why, str):
                for line in ResultsStore(self.root).set_aside([(path, why)]):
                    print(f"sb3-affect: {line}", file=sys.stderr, flush=True)
                continue
            return True
        return False

    def failure_id(self, simulation: Simulation, replication: int) -> str:
        """A replication's name in ``DIR/failed/``."""
        return f"{simulation.key}__r{replication:04d}"

    def write(
        self, simulation: Simulation, replication: int, cells: dict[float, dict[str, float]], complete: bool = True
    ) -> None:
        path = self.path(simulation, replication, complete)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise store_error(path.parent, error) from None
        payload: dict[str, Any] = {
            "simulation": simulation.key,
            "replication": replication,
            "complete": complete,
            "cells": {repr(float(eps)): row for eps, row in cells.items()},
        }
        write_atomic(path, payload)

    def read(self, simulation: Simulation, replication: int, partial_ok: bool = False) -> pd.DataFrame:
        """One replication's ``cell_summary`` rows, index: epsilon (sorted); with ``partial_ok`` maybe fewer cells."""
        path = self.path(simulation, replication)
        if partial_ok and not path.exists():
            path = self.path(simulation, replication, complete=False)
        rows = _read_summary(path)
        if isinstance(rows, str):
            raise StoreError(f"{path}: {rows}; {_REDO}")
        return rows

    def replications(self, simulation: Simulation) -> list[int]:
        """The complete replications stored for a simulation."""
        folder = self.root / "summaries" / simulation.key
        return sorted(int(p.stem[1:]) for p in folder.glob("r[0-9][0-9][0-9][0-9].json")) if folder.is_dir() else []


def _read_summary(path: Path) -> pd.DataFrame | str:
    """A summary file's ``cell_summary`` rows, index: epsilon (sorted), or why it is not a summary."""
    try:
        payload = read_json(path, MAX_SUMMARY_BYTES)
    except UnreadableFile as error:
        return error.reason
    cells = payload.get("cells") if isinstance(payload, dict) else None
    try:
        if not isinstance(cells, dict) or not cells:
            raise ValueError("no cells")
        rows = {float(k): v for k, v in cells.items()}
        if not all(isinstance(v, dict) and math.isfinite(k) for k, v in rows.items()):
            raise ValueError("a cell is not a row")
        frame = pd.DataFrame.from_dict(rows, orient="index")
    except (ValueError, TypeError):
        return "is not a replication's summary (no per-epsilon cells)"
    return frame.sort_index()


def folder_status(root: str | Path) -> str:
    """
    One line on how far a forensics folder is: the replications stored (and stopped early), of how many simulations,
    those that failed, and the sizes of the last analysis written (``run.json``). Reads only; writes nothing.
    """
    root = Path(root)
    summaries = root / "summaries"
    folders = [p for p in summaries.iterdir() if p.is_dir()] if summaries.is_dir() else []
    complete = sum(1 for folder in folders for _ in folder.glob("r[0-9][0-9][0-9][0-9].json"))
    partial = sum(1 for folder in folders for _ in folder.glob("r[0-9][0-9][0-9][0-9].partial.json"))
    line = (
        f"forensics in {root}: {complete} replications stored ({partial} more stopped early in the pre-screen) "
        f"of {len(folders)} simulations"
    )
    failed = sum(1 for _ in (root / "failed").glob("[!.]*.json"))
    if failed:
        line += f", {failed} failed (in {root / 'failed'}; the next run retries them)"
    try:
        run = read_json(root / "run.json", MAX_SUMMARY_BYTES)
        sizes = f"{run['screen_reps']} screen, {run['leaders']} leaders x {run['reps']} replications"
    except (OSError, ValueError, KeyError, TypeError):
        return f"{line}; no analysis written yet (rerun the same command to resume)"
    return f"{line}; analysis of {sizes} in {root / 'forensics.md'}"
