"""
Simulate (simulation, replication) units on the launcher's executor (local worker processes or Ray tasks, as a sweep's
runs), with a progress bar; resumable.
"""

from __future__ import annotations

import contextlib
import socket
import traceback
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from tqdm.auto import tqdm

from sb3_affect.engine.simulation import simulate
from sb3_affect.study.forensics.candidates import STEP_UNITS, Protocol, Simulation
from sb3_affect.study.forensics.statistics import cell_summary
from sb3_affect.study.forensics.unit_files import SummaryStore
from sb3_affect.study.launcher.launcher import run_ray
from sb3_affect.study.launcher.local_pool import run_local
from sb3_affect.study.launcher.one_run import package_versions
from sb3_affect.study.launcher.store import ResultsStore

Unit = tuple[Simulation, int]


def simulate_unit(
    unit: Unit, protocol: Protocol, stop_above: float | None = None
) -> tuple[Unit, dict[float, dict[str, float]], bool]:
    """
    One replication of one simulation under the protocol: a ``cell_summary`` per epsilon, and whether it is complete.

    :param unit: (simulation, replication)
    :param protocol: the protocol
    :param stop_above: stop after the epsilon cell where the sum over the cells so far of the mean steps per episode
        exceeds this in both step units (steps are never negative, so the mean over all cells will exceed it divided by
        the number of cells whatever the other cells give); None: never stop early
    """

    simulation, replication = unit
    cells = {}
    for epsilon in protocol.epsilons:
        log = simulate(
            simulation.algo,
            simulation.algo_kwargs(epsilon),
            protocol.env_id,
            protocol.env_kwargs,
            protocol.seed_list(simulation, replication, epsilon),
            protocol.episodes,
        )
        cells[float(epsilon)] = cell_summary(log)
        if stop_above is None or len(cells) == len(protocol.epsilons):
            continue
        if all(sum(c[step] / c["n"] for c in cells.values()) > stop_above for step in STEP_UNITS):
            return unit, cells, False
    return unit, cells, True


@dataclass(frozen=True)
class UnitJob:
    """One (simulation, replication) unit as a unit of work of the launcher's executors (``launcher.batches.Work``)."""

    unit: Unit
    protocol: Protocol
    stop_above: float | None = None

    @property
    def name(self) -> str:
        simulation, replication = self.unit
        return f"forensics:{simulation.algo}:{replication}"

    def execute(self) -> dict[str, Any]:
        """``simulate_unit`` of the unit: its cells and whether it is complete (with the versions and host it ran on)."""

        _, cells, complete = simulate_unit(self.unit, self.protocol, self.stop_above)
        host = {"host": socket.gethostname()}
        return {"cells": cells, "complete": complete, "versions": package_versions(), "timings": host}


def _warm_up(units: list[Unit], protocol: Protocol) -> None:
    """One one-episode run of each agent in the driver: compiled code is loaded once, and the forked workers share it."""

    for simulation in dict.fromkeys(sim for sim, _ in units):
        if simulation.algo not in {s.algo for s in _warmed}:
            simulate(simulation.algo, simulation.algo_kwargs(0.5), protocol.env_id, protocol.env_kwargs, [0], 1)
            _warmed.append(simulation)


_warmed: list[Simulation] = []


def run_units(
    store: SummaryStore,
    units: Iterable[Unit],
    workers: int = 2,
    progress: bool = True,
    desc: str = "simulating",
    stop_above: Mapping[Simulation, float] | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
) -> int:
    """
    Simulate every unit not yet in ``store`` and write each one as soon as it finishes (the driver is the only
    writer), on the launcher's executor: ``workers`` local processes, or Ray tasks, as a sweep's runs. Returns how many
    were simulated now.

    :param store: the results folder
    :param units: (simulation, replication) pairs; those already stored are skipped
    :param workers: worker processes (1 and the local backend: in this process)
    :param progress: show a tqdm progress bar
    :param desc: the bar's label
    :param stop_above: per simulation, ``simulate_unit``'s early stop (a stopped replication is stored as partial and
        counts as done only for callers that also pass ``stop_above``)
    :param backend: ``"local"`` (forked processes) or ``"ray"`` (``launcher.run_ray``)
    :param ray_address: the Ray cluster (default: a private instance of ``workers`` CPUs)
    :param ray_timeout: seconds to wait for the Ray cluster to answer
    """
    partial_ok = stop_above is not None
    todo = [u for u in dict.fromkeys(units) if not store.has(*u, partial_ok=partial_ok)]
    if not todo:
        return 0
    bar = tqdm(total=len(todo), desc=desc, unit="replication", disable=not progress, dynamic_ncols=True)
    jobs = [UnitJob(u, store.protocol, (stop_above or {}).get(u[0])) for u in todo]
    failures: list[str] = []

    records = ResultsStore(store.root)

    def on_result(job: UnitJob, result: dict[str, Any]) -> None:
        store.write(*job.unit, result["cells"], result["complete"])
        with contextlib.suppress(FileNotFoundError):
            (records.failed / f"{store.failure_id(*job.unit)}.json").unlink()
        bar.update()

    def on_failure(job: UnitJob, error: str) -> None:
        simulation, replication = job.unit
        records.write_failure(store.failure_id(*job.unit), {"simulation": simulation.key, "replication": replication},
                              error)
        failures.append(f"{job.name}: {error}")
        bar.update()

    try:
        if backend == "ray":

            run_ray(jobs, workers, on_result, on_failure, ray_address, timeout=ray_timeout)
        elif workers <= 1:
            for job in jobs:
                try:
                    result = job.execute()
                except Exception:  # recorded as a worker's failure is (KeyboardInterrupt passes)
                    on_failure(job, traceback.format_exc())
                    continue
                on_result(job, result)
        else:

            _warm_up(todo, store.protocol)
            run_local(jobs, workers, on_result, on_failure)
    finally:
        bar.close()
    if failures:
        raise RuntimeError(f"{len(failures)} of {len(jobs)} units failed (the others are kept; tracebacks in "
                           f"{records.failed}); the first: {failures[0]}")
    return len(todo)
