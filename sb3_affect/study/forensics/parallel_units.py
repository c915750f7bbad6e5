"""Simulate (simulation, replication) units in parallel worker processes, with a progress bar; resumable."""

from __future__ import annotations

import multiprocessing as mp
import os
import sys
from collections.abc import Iterable, Mapping

from sb3_affect.study.forensics.candidates import STEP_UNITS, Protocol, Simulation
from sb3_affect.study.forensics.statistics import cell_summary
from sb3_affect.study.forensics.unit_files import SummaryStore

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
    from sb3_affect.engine.simulation import simulate

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


def _init_worker(driver: int) -> None:
    import torch

    from sb3_affect.study.launcher.signals import worker_signals

    worker_signals(driver)  # Ctrl-C is the driver's (it terminates the pool), whose SIGTERM ends a worker at once
    torch.set_num_threads(1)


def _warm_up(units: list[Unit], protocol: Protocol) -> None:
    """One one-episode run of each agent in the driver: compiled code is loaded once, and the forked workers share it."""
    from sb3_affect.engine.simulation import simulate

    for simulation in dict.fromkeys(sim for sim, _ in units):
        if simulation.algo not in {s.algo for s in _warmed}:
            simulate(simulation.algo, simulation.algo_kwargs(0.5), protocol.env_id, protocol.env_kwargs, [0], 1)
            _warmed.append(simulation)


_warmed: list[Simulation] = []


def _work(args: tuple[Unit, Protocol, float | None]) -> tuple[Unit, dict[float, dict[str, float]], bool]:
    return simulate_unit(*args)


def run_units(
    store: SummaryStore,
    units: Iterable[Unit],
    workers: int = 2,
    progress: bool = True,
    desc: str = "simulating",
    stop_above: Mapping[Simulation, float] | None = None,
) -> int:
    """
    Simulate every unit not yet in ``store`` and write each one as soon as it finishes (the driver is the only
    writer). Returns how many were simulated now.

    :param store: the results folder
    :param units: (simulation, replication) pairs; those already stored are skipped
    :param workers: worker processes (1: in this process)
    :param progress: show a tqdm progress bar
    :param desc: the bar's label
    :param stop_above: per simulation, ``simulate_unit``'s early stop (a stopped replication is stored as partial and
        counts as done only for callers that also pass ``stop_above``)
    """
    from tqdm.auto import tqdm

    partial_ok = stop_above is not None
    todo = [u for u in dict.fromkeys(units) if not store.has(*u, partial_ok=partial_ok)]
    if not todo:
        return 0
    if workers > 1:
        _warm_up(todo, store.protocol)
    bar = tqdm(total=len(todo), desc=desc, unit="replication", disable=not progress, dynamic_ncols=True)
    tasks = [(u, store.protocol, (stop_above or {}).get(u[0])) for u in todo]
    try:
        if workers <= 1:
            for task in tasks:
                unit, cells, complete = _work(task)
                store.write(*unit, cells, complete)
                bar.update()
        else:
            # fork (Linux): the workers are the driver's children, so PR_SET_PDEATHSIG ends them if it is killed
            context = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
            with context.Pool(workers, initializer=_init_worker, initargs=(os.getpid(),)) as pool:
                for unit, cells, complete in pool.imap_unordered(_work, tasks):
                    store.write(*unit, cells, complete)
                    bar.update()
    finally:
        bar.close()
    return len(todo)
