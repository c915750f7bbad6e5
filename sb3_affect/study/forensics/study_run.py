"""
The forensics a sweep file states (``study: forensics``, ``launcher.study_schema.ForensicsStudy``): its sizes, its
candidate grid and its protocol into ``run_forensics``, on the launcher's executor. ``sb3-affect run FILE``,
``sb3-affect forensics`` and the main job all run the forensics through ``run_study``.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING

from sb3_affect.study.forensics.analysis import run_forensics
from sb3_affect.study.forensics.candidates import CandidateSpace, Protocol

if TYPE_CHECKING:
    from sb3_affect.study.forensics.analysis import ForensicsResult
    from sb3_affect.study.forensics.candidates import CandidateSpace, Protocol
    from sb3_affect.study.launcher.study_schema import ForensicsStudy


def study_space(study: ForensicsStudy) -> CandidateSpace:
    """The candidate space of the file: the default space with the file's alphas and gammas."""

    return dataclasses.replace(CandidateSpace.default(), alphas=tuple(study.alphas), gammas=tuple(study.gammas))


def study_protocol(study: ForensicsStudy) -> Protocol:
    """The protocol of the file: the paper's, with the keys its ``protocol`` section gives."""

    given = study.protocol.model_dump(exclude_none=True)
    if "epsilons" in given:
        given["epsilons"] = tuple(given["epsilons"])
    return Protocol(**given)


def run_study(
    study: ForensicsStudy,
    out: str | Path,
    *,
    workers: int | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
    progress: bool = True,
) -> ForensicsResult:
    """
    Run the forensics of a sweep file into ``out`` (resumable: stored replications are skipped).

    :param workers: worker processes (default: the usable CPUs; Ray: tasks at a time on a private instance)
    :param backend: ``"local"`` (forked processes) or ``"ray"`` (Ray tasks)
    :param ray_address: the Ray cluster, HOST:PORT or ray://HOST:PORT (default: a private instance)
    :param ray_timeout: seconds to wait for the Ray cluster to answer
    :param progress: show progress bars
    """

    workers = workers or (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)
    return run_forensics(
        out,
        study_space(study),
        study_protocol(study),
        screen_reps=study.screen_reps,
        leaders=study.leaders,
        reps=study.reps,
        workers=workers,
        progress=progress,
        backend=backend,
        ray_address=ray_address,
        ray_timeout=ray_timeout,
    )


def summary_lines(study: ForensicsStudy, result: ForensicsResult, out: str | Path) -> list[str]:
    """What a run of the study prints: what it simulated, the best candidate, the unreached numbers, the section."""
    best = result.leaders.iloc[0]
    return [
        f"{study.name}: {result.simulated} replications simulated now, {result.reused} already done, "
        f"{result.seconds:.1f} s -> {out}",
        f"best candidate: {best.candidate} (posterior {best.posterior:.3g} among the leaders' candidates)",
        f"printed numbers no leading candidate reaches: {', '.join(result.unreached) or 'none'}",
        f"report section: {Path(out) / 'forensics.md'}",
    ]
