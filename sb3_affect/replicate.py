"""
The main job: the paper's protocol and the DQN comparison through the launcher (run files), issue 7's fair baselines,
then the engine studies (large-N, reading ablation, moving and evading prey and mazes), then one report.
"""

from __future__ import annotations

import time
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
#: Launcher sweeps: (name of experiments/<name>.yaml and of the results folder, description).
PARTS = (
    ("paper", "the paper's protocol (360 runs)"),
    ("dqn", "SB3 DQN beside the tabular agents, equal seeds and budget (35 runs)"),
    ("baselines", "fair baselines beside both paper agents (issue 7)"),
    ("hunters", "two hunters on Kuremoto's pursuit problem (issue 16)"),
    ("hunters_moving", "two hunters, moving prey (issue 16)"),
)
#: Sizes of the engine studies (seeds per cell; episodes per run), read when ``main`` runs.
LARGE_SEEDS, ABLATION_SEEDS, BEYOND_SEEDS, ENGINE_EPISODES = 1000, 20, 1000, 200
#: Engine studies: (results folder, description), for the help.
STUDIES = (
    ("large", "the paper's 18 cells and the speed-matched ε-greedy at 1,000 seeds per cell (engine)"),
    ("ablation_engine", "the 8 readings of the appraisal x 9 ε x 20 seeds (engine)"),
    ("beyond", "moving prey, evading prey and mazes, 1,000 seeds (engine)"),
)


def main(
    out_dir: Path = Path("runs"),
    workers: int | None = None,
    experiments: Path | None = None,
    large_seeds: int | None = None,
    ablation_seeds: int | None = None,
    beyond_seeds: int | None = None,
    engine_episodes: int | None = None,
) -> Path:
    """
    Run the sweeps of ``SWEEPS`` into ``out_dir/<name>`` (resuming what is there) and the engine studies into
    ``out_dir/large``, ``out_dir/ablation_engine`` and ``out_dir/beyond`` (reused when complete), then write
    ``out_dir/report.md`` (and .html, tables/, figures/). Prints the wall time of each part.

    :param out_dir: the replicate folder
    :param workers: processes (default: usable CPUs)
    :param experiments: the folder holding the experiment files (default: the project's ``experiments/``)
    :param large_seeds: seeds per cell of the large-N study (default ``LARGE_SEEDS``)
    :param ablation_seeds: seeds per cell of the reading ablation (default ``ABLATION_SEEDS``)
    :param beyond_seeds: seeds per agent and task beyond the paper (default ``BEYOND_SEEDS``)
    :param engine_episodes: episodes per run of the engine studies (default the paper's 200; fewer for quick checks)
    :return: the path of report.md
    """
    from sb3_affect.experiments import run_sweep
    from sb3_affect.report import build_report
    from sb3_affect.report.ablation import ablation_cells
    from sb3_affect.report.baselines import beyond_cells
    from sb3_affect.report.largen import large_cells, run_cells

    experiments = Path(experiments or EXPERIMENTS)
    experiments = Path(experiments or EXPERIMENTS)
    large_seeds = large_seeds or LARGE_SEEDS
    ablation_seeds = ablation_seeds or ABLATION_SEEDS
    beyond_seeds = beyond_seeds or BEYOND_SEEDS
    engine_episodes = engine_episodes or ENGINE_EPISODES
    out_dir = Path(out_dir)
    timings: dict[str, float] = {}
    for name, description in PARTS:
        print(f"== {description}: {experiments / f'{name}.yaml'} -> {out_dir / name}", flush=True)
        summary = run_sweep(experiments / f"{name}.yaml", out_dir / name, workers=workers)
        timings[f"{name} ({description})"] = summary.seconds
        print(
            f"   {summary.finished} runs now, {summary.skipped} already done, {summary.failed} failed, "
            f"{summary.seconds:.1f} s",
            flush=True,
        )
    studies = (
        ("large", f"large-N study, {large_seeds} seeds per cell (engine)", large_cells(), large_seeds),
        ("ablation_engine", f"reading ablation, {ablation_seeds} seeds per cell (engine)", ablation_cells(), ablation_seeds),
        ("beyond", f"moving and evading prey, mazes, {beyond_seeds} seeds (engine)", beyond_cells(), beyond_seeds),
    )
    for name, description, cells, seeds in studies:
        print(f"== {description} -> {out_dir / name}", flush=True)
        start = time.perf_counter()
        table, _ = run_cells(out_dir / name, cells, seeds, engine_episodes, workers=workers)
        timings[description] = time.perf_counter() - start
        print(f"   {len(table)} runs, {timings[description]:.1f} s", flush=True)
    start = time.perf_counter()
    report = build_report(out_dir, timings=timings)
    timings["report"] = time.perf_counter() - start
    print("wall time: " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in timings.items()))
    print(f"report: {report} (and {report.with_suffix('.html')})")
    return report
