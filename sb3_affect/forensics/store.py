"""
The forensics results folder: one small JSON file per finished (simulation, replication), written atomically.

Layout of ``DIR``::

    DIR/forensics.json                     the protocol (a different protocol into DIR is refused)
    DIR/summaries/<simulation>/r0000.json  one replication of one simulation: its per-epsilon ``cell_summary`` rows
    DIR/screen.csv, DIR/leaders.csv, ...   the analysis (rewritten by every run)

A rerun skips every replication already on disk: an interrupted run resumes where it stopped.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

from sb3_affect.experiments.store import StoreError, _write_atomic
from sb3_affect.forensics.candidates import Protocol, Simulation


class SummaryStore:
    """
    Read and write the per-replication summaries of a forensics folder.

    :param root: the folder (created when missing)
    :param protocol: the protocol its summaries belong to
    """

    def __init__(self, root: str | Path, protocol: Protocol) -> None:
        self.root = Path(root)
        self.protocol = protocol
        self.root.mkdir(parents=True, exist_ok=True)
        saved = self.root / "forensics.json"
        wanted = {"protocol": protocol.as_dict()}
        if saved.exists():
            found = json.loads(saved.read_text())
            if found.get("protocol") != wanted["protocol"]:
                raise StoreError(
                    f"{self.root} holds forensics of another protocol ({found.get('protocol')}); "
                    f"use another --out folder for {wanted['protocol']}"
                )
        else:
            _write_atomic(saved, wanted)

    def path(self, simulation: Simulation, replication: int) -> Path:
        return self.root / "summaries" / simulation.key / f"r{replication:04d}.json"

    def has(self, simulation: Simulation, replication: int) -> bool:
        return self.path(simulation, replication).exists()

    def write(self, simulation: Simulation, replication: int, cells: dict[float, dict[str, float]]) -> None:
        path = self.path(simulation, replication)
        path.parent.mkdir(parents=True, exist_ok=True)
        payload: dict[str, Any] = {
            "simulation": simulation.key,
            "replication": replication,
            "cells": {repr(float(eps)): row for eps, row in cells.items()},
        }
        _write_atomic(path, payload)

    def read(self, simulation: Simulation, replication: int) -> pd.DataFrame:
        """One replication's ``cell_summary`` rows, index: epsilon (sorted)."""
        payload = json.loads(self.path(simulation, replication).read_text())
        frame = pd.DataFrame.from_dict({float(k): v for k, v in payload["cells"].items()}, orient="index")
        return frame.sort_index()

    def replications(self, simulation: Simulation) -> list[int]:
        folder = self.root / "summaries" / simulation.key
        return sorted(int(p.stem[1:]) for p in folder.glob("r*.json")) if folder.is_dir() else []
