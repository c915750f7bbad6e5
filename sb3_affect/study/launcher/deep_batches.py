"""
The deep study's unit of work: a *batch*, some seeds of one cell (task x agent) trained together by the public
trainer ``sb3_affect.train_many`` and evaluated every ``eval_every`` env steps (``deep_training``, ``deep_recording``). A
batch is a ``batches.Work``, so the launcher's one executor runs it: a long-lived local worker process, or one Ray task.
Its record depends only on the study, the cell and its seeds: the same on either backend, and in any batch.
``merge_batches`` joins a cell's batches in seed order into the cell's record (what a record holds: ``deep_training``).
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import Any

from sb3_affect.study.launcher.deep_schema import RECORD_ROWS, DeepStudy
from sb3_affect.study.launcher.one_run import package_versions


def training() -> ModuleType:
    """``deep_training``, imported where a batch runs or a study is checked before it runs (it imports torch)."""
    from sb3_affect.study.launcher import deep_training  # (torch: only where a deep study runs)

    return deep_training


def seed_batches(study: DeepStudy) -> list[tuple[int, ...]]:
    """The study's seeds cut into batches of ``seeds_per_batch`` (all in one when not given), in the file's order."""
    size = study.seeds_per_batch or len(study.seeds)
    return [tuple(study.seeds[i:i + size]) for i in range(0, len(study.seeds), size)]


def merge_batches(records: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """A cell's record from its batches' records, in seed order (``seconds``: the batches' CPU seconds, summed)."""
    first = records[0]
    merged = dict(first)
    for key in (*RECORD_ROWS, "seeds", "first_success"):
        merged[key] = [value for record in records for value in record[key]]
    if first["emotions"] is not None:
        merged["emotions"] = {name: [row for record in records for row in record["emotions"][name]]
                              for name in first["emotions"]}  # fmt: skip
    merged["seconds"] = sum(record["seconds"] for record in records)
    return merged


@dataclass(frozen=True)
class DeepBatch:
    """
    One batch as a unit of work of the launcher's executors (``batches.Work``): the study (as its file's data), the
    task, the agent's index, the batch's index and seeds, and the ε a replaying agent takes.
    """

    study: dict[str, Any]
    task: str
    agent: int
    index: int
    seeds: tuple[int, ...]
    epsilons: tuple[float, ...] | None = None

    @property
    def name(self) -> str:
        return f"deep:{self.task}:{self.study['agents'][self.agent]['name']}:{self.index}"

    def execute(self) -> dict[str, Any]:
        """``deep_training.run_batch`` of this batch, with the package versions and the host that ran it."""
        study = DeepStudy.model_validate(self.study)
        record = training().run_batch(study, self.task, study.agents[self.agent], self.seeds, self.epsilons)
        return {"record": record, "versions": package_versions(), "timings": {"host": socket.gethostname()}}
