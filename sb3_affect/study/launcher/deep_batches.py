"""
The deep study's unit of work, a batch kind of the launcher (``launcher.plan_jobs``): some seeds of one cell (task x
agent, ``Sweep.deep_cells``) trained together by the public trainer ``sb3_affect.train_many`` and evaluated every
``evaluation.every`` env steps (``deep_training``, ``deep_recording``), stored as one chunk of evaluations
(``chunks.encode_evaluations``). It runs on the launcher's one executor, a long-lived local worker or one Ray task; its
rows depend only on the cell and its seeds: the same on either backend, and in any batch.

A cell whose agent ``replays`` another waits for that agent's cell on the same task: its ε, part by part, is the
source's random share averaged over seeds (``replayed_epsilons``; ``ReplayedEpsilonDQN``).
"""

from __future__ import annotations

import math
import os
import socket
import time
import warnings
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np

from sb3_affect.study.launcher.batches import Batch
from sb3_affect.study.launcher.chunks import encode_evaluations
from sb3_affect.study.launcher.one_run import package_versions


def training() -> ModuleType:
    """``deep_training``, imported where a batch runs or a study is checked before it runs (it imports torch)."""
    from sb3_affect.study.launcher import deep_training  # (torch: only where a deep study runs)

    return deep_training


def replayed_epsilons(source: dict[str, Any]) -> list[float]:
    """A finished cell's random share, averaged over its seeds, per part of training (a part without decisions: 1)."""
    shares = np.asarray(source["random_share"], dtype=float)  # (seeds, parts); None read as NaN
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a part without decisions in any seed
        mean = np.nanmean(shares, axis=0)
    return [1.0 if math.isnan(value) else float(value) for value in mean]


@dataclass(frozen=True)
class DeepBatch(Batch):
    """A ``Batch`` of a deep cell (its ``base``: ``Sweep.deep_cells``), with the ε a replaying agent takes."""

    epsilons: tuple[float, ...] | None = None

    def execute(self) -> dict[str, Any]:
        """Train and evaluate the batch (in a worker): ``{"chunk": Parquet bytes, "run_ids": [...]}``."""
        start = time.perf_counter()
        seeds = [seed for _, seed, _ in self.runs]
        record = training().run_batch(self.base, seeds, self.epsilons)
        timings = {"wall_seconds": round(time.perf_counter() - start, 4), "cpu_seconds": record["seconds"],
                   "pid": os.getpid(), "host": socket.gethostname()}  # fmt: skip
        versions = package_versions()
        chunk = encode_evaluations(self.name, self.base, self.runs, record, timings, versions, self.epsilons)
        return {"chunk": chunk, "run_ids": [rid for rid, _, _ in self.runs], "timings": timings, "versions": versions}
