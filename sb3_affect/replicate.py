"""The main job: the paper's protocol, the DQN comparison, the reading ablation, then one report."""

from __future__ import annotations

import time
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
PARTS = (
    ("paper", "the paper's protocol (360 runs)"),
    ("dqn", "SB3 DQN subset (20 runs)"),
    ("ablation", "reading ablation (1,440 runs)"),
    ("baselines", "fair baselines beside both paper agents (issue 7)"),
    ("hunters", "two hunters on Kuremoto's pursuit problem (issue 16)"),
    ("hunters_moving", "two hunters, moving prey (issue 16)"),
)


def main(out_dir: Path = Path("runs"), workers: int | None = None, experiments: Path | None = None) -> Path:
    """
    Run each of ``PARTS`` (``experiments/<name>.yaml``: paper, dqn, ablation, baselines, hunters, ...) into
    ``out_dir/<name>`` (resuming what is there), then write ``out_dir/report.md`` (and .html, tables/, figures/).
    Prints the wall time of each part.

    :param out_dir: the results folder
    :param workers: parallel runs (default: the number of CPUs)
    :param experiments: the folder holding the experiment files (default: the project's ``experiments/``)
    :return: the path of report.md
    """
    from sb3_affect.experiments import run_sweep
    from sb3_affect.report import build_report

    experiments = Path(experiments or EXPERIMENTS)
    out_dir = Path(out_dir)
    timings: list[tuple[str, float]] = []
    for name, description in PARTS:
        print(f"== {description}: {experiments / f'{name}.yaml'} -> {out_dir / name}", flush=True)
        summary = run_sweep(experiments / f"{name}.yaml", out_dir / name, workers=workers)
        timings.append((description, summary.seconds))
        print(
            f"   {summary.finished} runs now, {summary.skipped} already done, {summary.failed} failed, "
            f"{summary.seconds:.1f} s",
            flush=True,
        )
    start = time.perf_counter()
    report = build_report(out_dir)
    timings.append(("report", time.perf_counter() - start))
    print("wall time: " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in timings))
    print(f"report: {report} (and {report.with_suffix('.html')})")
    return report
