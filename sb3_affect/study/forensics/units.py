"""
The forensics' unit of work, a batch kind of the launcher (``launcher.plan_jobs`` with ``stages.plan_stages``): some
replications of one simulation under the protocol (a cell of ``ForensicsSpec.cells``), each a ``cell_summary`` per ε,
stored as one chunk of summaries (``chunks.encode_summaries``). It runs on the launcher's one executor, a long-lived
local worker or one Ray task; its rows depend only on the simulation, the protocol and the replication: the same on
either backend, and in any batch.
"""

from __future__ import annotations

import os
import socket
import time
from dataclasses import dataclass
from typing import Any

from sb3_affect.engine.simulation import simulate
from sb3_affect.study.forensics.statistics import cell_summary
from sb3_affect.study.launcher.batches import Batch
from sb3_affect.study.launcher.chunks import encode_summaries
from sb3_affect.study.launcher.forensics_candidates import STEP_UNITS, Protocol, Simulation
from sb3_affect.study.launcher.one_run import package_versions

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


def base_simulation(base: dict[str, Any]) -> Simulation:
    """The simulation of a forensics cell's base config (``ForensicsSpec.cells``)."""
    return Simulation(**base["simulation"])


def base_protocol(base: dict[str, Any]) -> Protocol:
    """The protocol of a forensics cell's base config."""
    given = dict(base["protocol"])
    return Protocol(**{**given, "epsilons": tuple(given["epsilons"])})


@dataclass(frozen=True)
class ForensicsBatch(Batch):
    """A ``Batch`` of a forensics cell: replications of one simulation (``stop_above``: the pre-screen's early stop)."""

    stop_above: float | None = None

    def execute(self) -> dict[str, Any]:
        """Simulate the batch's replications (in a worker): ``{"chunk": Parquet bytes, "run_ids": [...]}``."""
        start = time.perf_counter()
        simulation, protocol = base_simulation(self.base), base_protocol(self.base)
        results = [simulate_unit((simulation, replicate), protocol, self.stop_above)[1:] for _, _, replicate in self.runs]
        timings = {"wall_seconds": round(time.perf_counter() - start, 4), "pid": os.getpid(), "host": socket.gethostname()}
        versions = package_versions()
        cells, complete = [cells for cells, _ in results], [done for _, done in results]
        chunk = encode_summaries(self.name, self.base, self.runs, cells, complete, timings, versions)
        return {"chunk": chunk, "run_ids": [rid for rid, _, _ in self.runs], "timings": timings, "versions": versions}
