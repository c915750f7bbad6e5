"""
``sb3-affect status`` of a forensics folder: one line from its results store (no analysis, no SciPy: the launcher's
modules only).
"""

from __future__ import annotations

from pathlib import Path

from sb3_affect.study.launcher.regular_files import read_json
from sb3_affect.study.launcher.schema import PRESCREEN
from sb3_affect.study.launcher.store import ResultsStore

#: The largest ``run.json`` read (the analysis' sizes and findings: a few kB).
MAX_RUN_BYTES = 2**20


def folder_status(root: str | Path) -> str:
    """
    One line on how far a forensics folder is: the replications stored (and stopped early), of how many simulations,
    those that failed, and the sizes of the last analysis written (``run.json``). Reads only; writes nothing.
    """
    store = ResultsStore(root)
    rows = store.summaries()
    complete = sum(1 for _, done in rows.values() if done)
    simulations = len({simulation for simulation, _, _ in rows})
    stopped = sum(1 for (_, stage, _), (_, done) in rows.items() if stage == PRESCREEN and not done)
    line = (
        f"forensics in {store.root}: {complete} replications stored ({stopped} more stopped early in the pre-screen) "
        f"of {simulations} simulations"
    )
    failed = len(store.failed_ids() - store.done_ids())
    if failed:
        line += f", {failed} failed (in {store.failed}; the next run retries them)"
    try:
        run = read_json(store.root / "run.json", MAX_RUN_BYTES)
        sizes = f"{run['screen_reps']} screen, {run['leaders']} leaders x {run['reps']} replications"
    except (OSError, ValueError, KeyError, TypeError):
        return f"{line}; no analysis written yet (rerun the same command to resume)"
    return f"{line}; analysis of {sizes} in {store.root / 'forensics.md'}"
