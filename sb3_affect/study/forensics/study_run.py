"""
The forensics a sweep file states (its ``forensics`` section, ``launcher.schema.ForensicsSpec``): its stages run by the
launcher (``run_sweep`` with ``stages.plan_stages``, on its executor, stored by its ``ResultsStore``), then scored
(``analysis.analyse``). ``sb3-affect run FILE``, ``sb3-affect forensics`` and the main job all run it through
``run_study``.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import TYPE_CHECKING

from sb3_affect.engine.simulation import simulate
from sb3_affect.study.forensics.analysis import analyse
from sb3_affect.study.forensics.stages import plan_stages
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.forensics_candidates import Simulation
from sb3_affect.study.launcher.schema import ForensicsSpec, Sweep
from sb3_affect.study.launcher.store import StoreError
from sb3_affect.study.launcher.sweep_file import load_sweep_file

if TYPE_CHECKING:
    import numpy as np

    from sb3_affect.study.forensics.analysis import ForensicsResult


def run_study(
    path: str | Path,
    out: str | Path,
    overrides: tuple[str, ...] | list[str] = (),
    *,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
    progress: bool = True,
    printed: np.ndarray | None = None,
) -> ForensicsResult:
    """
    Run the forensics of a sweep file (with its ``--set`` ``overrides``) into ``out``, resumable: stored replications
    are skipped. The launcher's arguments are ``run_sweep``'s; ``printed``: the numbers to explain (default: the
    paper's). StoreError when some replications failed (the others are kept; a rerun retries them).
    """
    study = load_sweep_file(path, overrides, build=False)
    if study.forensics is None:
        raise ValueError(f"{path} is not a forensics study file (a sweep with a forensics section)")
    if backend == "local":
        _warm_up(study.forensics)
    stages = functools.partial(plan_stages, printed=printed)
    summary = run_sweep(path, out, workers=workers, backend=backend, ray_address=ray_address, ray_timeout=ray_timeout,
                        overrides=overrides, progress=progress, stages=stages)  # fmt: skip
    if summary.failed:
        raise StoreError(f"{summary.failed} replications failed (the others are kept; tracebacks in {Path(out) / 'failed'});"
                         " rerun the same command to retry them")  # fmt: skip
    result = analyse(study.forensics, out, printed, summary.seconds)
    result.simulated, result.reused = summary.finished, summary.skipped
    return result


def _warm_up(study: ForensicsSpec) -> None:
    """One one-episode run of each agent in the driver: compiled code is loaded once, and every stage's forked workers
    share it."""
    space, protocol = study.space(), study.paper_protocol()
    first: dict[str, Simulation] = {}
    for simulation in space.standard_simulations() + space.affective_simulations():
        first.setdefault(simulation.algo, simulation)
    for simulation in first.values():
        simulate(simulation.algo, simulation.algo_kwargs(0.5), protocol.env_id, protocol.env_kwargs, [0], 1)


def summary_lines(study: Sweep, result: ForensicsResult, out: str | Path) -> list[str]:
    """What a run of the study prints: what it simulated, the best candidate, the unreached numbers, the section."""
    best = result.leaders.iloc[0]
    return [
        f"{study.name}: {result.simulated} replications simulated now, {result.reused} already done, "
        f"{result.seconds:.1f} s -> {out}",
        f"best candidate: {best.candidate} (posterior {best.posterior:.3g} among the leaders' candidates)",
        f"printed numbers no leading candidate reaches: {', '.join(result.unreached) or 'none'}",
        f"report section: {Path(out) / 'forensics.md'}",
    ]
