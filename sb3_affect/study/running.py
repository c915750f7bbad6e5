"""
How a study file runs, whatever it describes: ``sb3-affect run FILE`` and each part of ``sb3-affect replicate`` run it
here, one way. A sweep of runs and the deep study go through the launcher's ``run_sweep`` as they are. The forensics
(a file with a ``forensics`` section) goes through ``run_sweep`` as well, with its stages planned by the forensics'
``stages.plan_stages``, since the launcher never imports the forensics, and its analysis follows. This is the one
place that asks which kind of study a file holds before it runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.sweep_file import load_sweep_file


class FileRun(NamedTuple):
    """What running a study file did: its runs (``SweepSummary``'s counts) and what to print of it."""

    seconds: float
    skipped: int  # runs the folder held already
    finished: int  # runs finished now
    failed: int  # runs that failed now (their records in DIR/failed/)
    lines: list[str]  # what the commands print of it


def run_file(path: str | Path, out: str | Path, overrides: tuple[str, ...] | list[str] = (), logs: str | None = None,
             **launcher: Any) -> FileRun:
    """
    Run the study file ``path`` (with its ``--set`` ``overrides``) into ``out``, resumed: ``run_sweep``'s ``launcher``
    arguments (workers, backend, ray_address, ray_timeout, progress); ``logs``: the SB3 logger formats of its runs
    (``--logs``: csv, tensorboard, ...).
    """
    study = load_sweep_file(path, overrides, build=False)
    if study.kind == "forensics":
        if logs:
            raise ValueError(f"--logs {logs}: the forensics study runs on the compiled engine and writes no SB3 logs")
        from sb3_affect.study.forensics.study_run import run_study, summary_lines  # (the report extra: the forensics only)

        result = run_study(path, out, overrides, **launcher)
        lines = summary_lines(study, result, out)
        return FileRun(result.seconds, result.reused, result.simulated, 0, lines)
    summary = run_sweep(path, out, overrides=[*overrides, *([f"logs=[{logs}]"] if logs else [])], **launcher)
    line = (f"{summary.name}: {summary.total} runs, {summary.skipped} already done, {summary.finished} finished now, "
            f"{summary.failed} failed, {summary.seconds:.1f} s -> {summary.out_dir}")  # fmt: skip
    if summary.failed:
        line += f"\nfailed runs and their tracebacks: {Path(out) / 'failed'}; rerun the same command to retry them"
    return FileRun(summary.seconds, summary.skipped, summary.finished, summary.failed, [line])
