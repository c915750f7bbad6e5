"""
Units of work of the launcher: batches of tabular runs (one ``engine.simulate`` call each, stored as one chunk) and
single runs (``execute_run``, stored as one JSON file).

A run goes into a batch when ``simulate`` computes exactly what ``execute_run`` would: a tabular agent class of this
package on one of its envs without wrappers, stopped by the episode count alone (no ``max_timesteps``), without
per-run SB3 logs or a trace (``launcher.emotion_trace``: the Python loop). The runs of a batch share one cell (agent
and grid point: the same config but for seed and replicate). Team runs of the package's agents go into team batches
(``TeamBatch``: one worker runs them one after the other on the team kernel, each stored as its own run file), traced
runs into traced batches (``TracedBatch``: the same on the Python loop). Anything else (DQN, a user's class, ``--logs``,
wrappers) runs on its own, as before.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import socket
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from sb3_affect.core.registry import known_settings, resolve_class
from sb3_affect.engine.simulation import simulate_columns
from sb3_affect.study.launcher.chunks import encode_chunk
from sb3_affect.study.launcher.one_run import execute_run, package_env, package_versions
from sb3_affect.study.launcher.run_ids import readable, run_config
from sb3_affect.study.launcher.schema import is_tabular
from sb3_affect.study.launcher.store import run_file

#: The most runs one batch holds (bounds a worker's memory and the work a crash or Ctrl-C throws away).
MAX_BATCH = 2000
#: Batches per worker a sweep is at least cut into where it has the runs (load balance, progress steps).
BATCHES_PER_WORKER = 8


@dataclass(frozen=True)
class Batch:
    """
    Many runs of one cell, executed by one ``engine.simulate`` call and stored as one chunk.

    :param name: the chunk's file name (readable prefix + hash of its run ids)
    :param base: the cell's config with ``seed`` None and ``labels`` without ``replicate``
    :param runs: ``(run id, seed, replicate)`` of each run
    """

    name: str
    base: dict[str, Any]
    runs: tuple[tuple[str, int, int], ...]

    @property
    def size(self) -> int:
        return len(self.runs)

    def failures(self) -> list[tuple[str, dict[str, Any]]]:
        """``(run id, config)`` of every run: what a failed batch records."""
        return [(rid, run_config(self.base, seed, replicate)) for rid, seed, replicate in self.runs]

    def execute(self) -> dict[str, Any]:
        """Run the batch (in a worker): ``{"chunk": Parquet bytes, "run_ids": [...]}``."""
        start = time.perf_counter()
        seeds = list(dict.fromkeys(seed for _, seed, _ in self.runs))
        base = self.base
        algo, kwargs, env_id, env_kwargs = base["algo"], base["algo_kwargs"], base["env_id"], base["env_kwargs"]
        episodes = simulate_columns(algo, kwargs, env_id, env_kwargs, seeds, base["episodes"])  # no pandas on the kernel
        timings = {"wall_seconds": round(time.perf_counter() - start, 4), "pid": os.getpid(), "host": socket.gethostname()}
        versions = package_versions()
        chunk = encode_chunk(self.name, base, self.runs, episodes, timings, versions)
        return {"chunk": chunk, "run_ids": [rid for rid, _, _ in self.runs], "timings": timings, "versions": versions}


@dataclass(frozen=True)
class TeamBatch(Batch):
    """
    Many team runs of one cell (hunters on HunterPursuit), executed one after the other in one long-lived worker on the
    team kernel (``execute_run``'s compiled team path) and stored as one run file each, as single team runs are.
    """

    def execute(self) -> dict[str, Any]:
        """Run the batch (in a worker): ``{"files": [(run id, run file bytes), ...], ...}`` (``store.run_file``)."""
        start = time.perf_counter()
        files = []
        for rid, seed, replicate in self.runs:
            config = run_config(self.base, seed, replicate)
            files.append((rid, run_file(rid, config, execute_run(config))))
        timings = {"wall_seconds": round(time.perf_counter() - start, 4), "pid": os.getpid(), "host": socket.gethostname()}
        run_ids = [rid for rid, _, _ in self.runs]
        return {"files": files, "run_ids": run_ids, "timings": timings, "versions": package_versions()}


@dataclass(frozen=True)
class TracedBatch(TeamBatch):
    """
    Many traced runs of one cell (``trace: true``: the Python loop, ``launcher.emotion_trace``), executed one after the
    other in one long-lived worker by ``execute_run`` and stored as one run file each, as team batches are: SB3 and
    torch are imported once per worker, not once per run.
    """


@dataclass(frozen=True)
class Single:
    """
    One run executed on its own by ``execute_run`` (stored as one JSON file).

    :param run_id: the run's id
    :param config: the run config
    :param log_dir: where its SB3 logger writes (None: no logs)
    :param formats: the logger's output formats
    """

    run_id: str
    config: dict[str, Any]
    log_dir: str | None
    formats: tuple[str, ...] = ("csv",)

    @property
    def name(self) -> str:
        return self.run_id

    @property
    def size(self) -> int:
        return 1

    def failures(self) -> list[tuple[str, dict[str, Any]]]:
        return [(self.run_id, self.config)]

    def execute(self) -> dict[str, Any]:
        return execute_run(self.config, self.log_dir, self.formats)


Job = Batch | Single


class Work(Protocol):
    """
    A unit of work the executor runs (``launcher.executor``: ``local_pool.run_local`` or Ray tasks): a ``Batch`` (of
    any kind: a deep study's, the forensics'), a ``Single``. Only a ``Single`` gets a fresh process of its own; anything else
    runs in a long-lived worker, one unit after the other. ``execute`` returns the unit's result, with ``versions``
    and ``timings`` (``host``) for the Ray backend's check of a node's package versions.
    """

    @property
    def name(self) -> str: ...

    def execute(self) -> dict[str, Any]: ...


def batchable(base: dict[str, Any], logs: bool) -> bool:
    """Whether the runs of a cell can run as batches (see the module docstring)."""
    if logs or base.get("trace") or base.get("max_timesteps") is not None or not package_env(base["env_id"]):
        return False
    if base.get("env_wrappers"):  # ``simulate`` builds the bare env: a wrapped env's runs run on their own
        return False

    if known_settings(base["algo"]) is not None:  # the package's agents, known by name (not imported: no torch)
        return True
    try:
        return is_tabular(base["algo"]) and resolve_class(base["algo"]).__module__.split(".")[0] == "sb3_affect"
    except ValueError:
        return False


def team_batchable(base: dict[str, Any], logs: bool) -> bool:
    """Whether the team runs of a cell can run as team batches: every hunter one of the package's agents given settings."""
    if "team" not in base or logs or base.get("max_timesteps") is not None:
        return False

    for member in base["team"]:
        settings = known_settings(member["algo"])
        if settings is None or not set(member["kwargs"]) <= set(settings.names()):
            return False
    return True


def traced_batchable(base: dict[str, Any], logs: bool) -> bool:
    """Whether the runs of a cell can run as traced batches: traced runs without per-run SB3 logs."""
    return bool(base.get("trace")) and not logs


def batch_kind(base: dict[str, Any], logs: bool) -> type[Batch] | None:
    """The kind of batch the runs of a cell go into, or None: each run on its own (``Single``)."""
    if batchable(base, logs):
        return Batch
    if team_batchable(base, logs):
        return TeamBatch
    return TracedBatch if traced_batchable(base, logs) else None


def batch_size(runs: int, workers: int) -> int:
    """Runs per batch: about ``BATCHES_PER_WORKER`` batches per worker, at most ``MAX_BATCH`` runs each."""
    return max(1, min(MAX_BATCH, math.ceil(runs / (BATCHES_PER_WORKER * workers))))


def split_cell(
    base: dict[str, Any], runs: Sequence[tuple[str, int, int]], size: int, kind: type[Batch] = Batch
) -> list[Batch]:
    """Cut the runs still to do of one cell into near-equal batches (of ``kind``) of at most ``size`` runs."""
    count = math.ceil(len(runs) / size) if runs else 0
    batches = []
    for index in range(count):
        part = tuple(runs[index * len(runs) // count : (index + 1) * len(runs) // count])
        digest = hashlib.sha256("\n".join(rid for rid, _, _ in part).encode()).hexdigest()[:12]
        labels = "-".join(f"{k}{v}" for k, v in base["labels"].items())
        prefix = re.sub(r"[^A-Za-z0-9_.+-]+", "_", f"{base['agent']}-{labels}".strip("-").replace("--", "-"))
        batches.append(kind(f"{readable(prefix)}-n{len(part)}-{digest}", base, part))
    return batches
