"""
The main job: the paper's protocol and the DQN comparison through the launcher (run files), issue 7's fair baselines,
then the engine studies (large-N, reading ablation, moving and evading prey and mazes), then one report.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: The folder of the sweep files; None: those installed with the package (``experiments/`` of the source tree).
EXPERIMENTS: Path | None = None
#: Launcher sweeps: (name of experiments/<name>.yaml and of the results folder, description).
PARTS = (
    ("paper", "the paper's protocol (360 runs)"),
    ("dqn", "SB3 DQN beside the tabular agents, equal seeds and budget (35 runs)"),
    ("baselines", "fair baselines beside both paper agents (issue 7)"),
    ("hunters", "two hunters on Kuremoto's pursuit problem (issue 16)"),
    ("hunters_moving", "two hunters, moving prey (issue 16)"),
)
#: Sizes of the engine studies (seeds per cell; episodes per run), read when ``main`` runs.
LARGE_SEEDS, ABLATION_SEEDS, BEYOND_SEEDS, ENGINE_EPISODES = 1000, 20, 10, 200
#: Engine studies: (results folder, description), for the help.
STUDIES = (
    ("large", "the paper's 18 cells and the speed-matched ε-greedy at 1,000 seeds per cell (engine)"),
    ("ablation_engine", "the 8 readings of the appraisal x 9 ε x 20 seeds (engine)"),
    ("beyond", "moving prey, evading prey and mazes, 10 seeds (engine)"),
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
    :param experiments: the folder holding the experiment files (default: the ones installed with the package)
    :param large_seeds: seeds per cell of the large-N study (default ``LARGE_SEEDS``)
    :param ablation_seeds: seeds per cell of the reading ablation (default ``ABLATION_SEEDS``)
    :param beyond_seeds: seeds per agent and task beyond the paper (default ``BEYOND_SEEDS``)
    :param engine_episodes: episodes per run of the engine studies (default the paper's 200; fewer for quick checks)
    :return: the path of report.md
    """
    from sb3_affect.experiments import run_sweep
    from sb3_affect.experiments.sweep_file import shipped_sweeps_folder
    from sb3_affect.report import build_report
    from sb3_affect.report.ablation import ablation_cells
    from sb3_affect.report.baselines import beyond_cells
    from sb3_affect.report.largen import large_cells, run_cells

    experiments = Path(experiments or EXPERIMENTS or shipped_sweeps_folder())
    large_seeds = large_seeds or LARGE_SEEDS
    ablation_seeds = ablation_seeds or ABLATION_SEEDS
    beyond_seeds = beyond_seeds or BEYOND_SEEDS
    engine_episodes = engine_episodes or ENGINE_EPISODES
    out_dir = Path(out_dir)
    record = _Record(out_dir)
    timings: dict[str, float] = {}
    for name, description in PARTS:
        print(f"== {description}: {experiments / f'{name}.yaml'} -> {out_dir / name}", flush=True)
        summary = run_sweep(experiments / f"{name}.yaml", out_dir / name, workers=workers)
        key = f"{name} ({description})"
        timings[key] = record.part(key, summary.seconds, done_before=summary.skipped, todo=summary.total - summary.skipped)
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
        with _heartbeat(description):
            table, meta = run_cells(out_dir / name, cells, seeds, engine_episodes, workers=workers)
        seconds = time.perf_counter() - start
        # The study's own record of the run that computed it (a complete study is read back, not recomputed).
        timings[description] = record.set(description, float(meta.get("wall_seconds", seconds)))
        print(f"   {len(table)} runs, {seconds:.1f} s", flush=True)
    start = time.perf_counter()
    report = build_report(out_dir, timings=timings)
    timings["report"] = time.perf_counter() - start
    print("wall time: " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in timings.items()))
    print(f"report: {report} (and {report.with_suffix('.html')})")
    return report


#: Seconds between the lines an engine study prints while it runs (it has no progress bar of its own).
HEARTBEAT_SECONDS = 15.0


@contextlib.contextmanager
def _heartbeat(what: str, every: float | None = None) -> Iterator[None]:
    """Print ``still running: <what>, N s`` every ``every`` seconds while the block runs (a long silent step)."""
    interval = HEARTBEAT_SECONDS if every is None else every
    stop = threading.Event()
    start = time.perf_counter()

    def beat() -> None:
        while not stop.wait(interval):
            print(f"   still running: {what}, {time.perf_counter() - start:.0f} s", flush=True)

    thread = threading.Thread(target=beat, name="sb3-affect:heartbeat", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


class _Record:
    """
    ``OUT/replicate.json``: the wall time of each part over the runs that did its work, so that a resumed replicate
    reports the time the results took (a part finished earlier keeps its time; a part resumed adds the resume's). It
    also marks the folder as a replication, into which ``sb3-affect run`` refuses to write a sweep.
    """

    def __init__(self, out_dir: Path) -> None:
        out_dir.mkdir(parents=True, exist_ok=True)
        self.path = out_dir / "replicate.json"
        try:
            saved = json.loads(self.path.read_text())
        except (OSError, ValueError):
            saved = {}
        timings = saved.get("timings") if isinstance(saved, dict) else None
        self.timings: dict[str, Any] = dict(timings) if isinstance(timings, dict) else {}

    def part(self, key: str, seconds: float, done_before: int, todo: int) -> float:
        previous = self.timings.get(key)
        if not isinstance(previous, (int, float)):
            return self.set(key, seconds)
        if todo == 0:  # nothing left to do: the time is the earlier runs'
            return float(previous)
        return self.set(key, previous + seconds if done_before else seconds)

    def set(self, key: str, seconds: float) -> float:
        self.timings[key] = seconds
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        tmp.write_text(json.dumps({"timings": self.timings}, indent=1))
        tmp.replace(self.path)
        return seconds
