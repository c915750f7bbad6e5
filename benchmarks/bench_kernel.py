"""
Per-cell ``simulate`` throughput of the compiled kernel: decisions per second of ``engine.simulate`` on one
core, for the three kinds of cell of the paper protocol (``experiments/paper.yaml``: GridPursuit 15 x 15, 200
episodes per run) - epsilon-greedy Q-learning at epsilon 0.1 (short episodes) and 0.9 (long, mostly random) and the
affective agent (the known map and the power fit on every decision).

    python benchmarks/bench_kernel.py                     # 2000 seeds per cell, median of 3, CSV beside this file
    python benchmarks/bench_kernel.py --seeds 1000 --repeats 5

The 10,000-seed protocol (180,000 runs, about 1.9 G decisions) needs about 17 M decisions/s per core on average
across its cells to finish within 60 s on two cores. Each figure is the median over repeats; ``simulate`` includes
building one template model and the result table (a few ms per call).
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import sb3_affect
from sb3_affect.engine.simulation import simulate

ENV_ID = "sb3_affect/GridPursuit-v0"
ENV_KWARGS: dict[str, Any] = {"size": 15, "start": [0, 0], "goal": [6, 6], "goal_reward": 100.0}
PAPER = {"learning_rate": 1.0, "gamma": 0.8, "q_init": 0.0}
CELLS: list[tuple[str, str, dict[str, Any]]] = [
    ("QLearning eps=0.1", "QLearning", {**PAPER, "exploration_rate": 0.1}),
    ("QLearning eps=0.9", "QLearning", {**PAPER, "exploration_rate": 0.9}),
    ("AffectQ (paper reading)", "AffectQ", {**PAPER, "comparison": "literal", "act": "episode", "units": "cells"}),
]


def cell_rate(algo: str, kwargs: dict[str, Any], seeds: int) -> tuple[float, int]:
    """
    Decisions per CPU second of one ``simulate`` call over ``seeds`` seeds (200 episodes each), and its decisions.
    CPU time (``time.process_time``) rather than wall time: on a shared machine it is what this process got, so the
    figure approximates an idle core's (the kernel is single-threaded).
    """
    start = time.process_time()
    rows = simulate(algo, kwargs, ENV_ID, ENV_KWARGS, range(seeds), 200, engine="compiled")
    seconds = time.process_time() - start
    decisions = int(rows["decisions"].sum())
    return decisions / seconds, decisions


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=2000, help="runs per cell and measurement")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--csv", type=Path, default=Path(__file__).with_name("results_kernel.csv"))
    args = parser.parse_args(argv)
    for _, algo, kwargs in CELLS:  # load (or compile) the kernels before timing them
        simulate(algo, kwargs, ENV_ID, ENV_KWARGS, [0], 1, engine="compiled")
    rows = []
    for name, algo, kwargs in CELLS:
        measured = [cell_rate(algo, kwargs, args.seeds) for _ in range(args.repeats)]
        rate = statistics.median(r for r, _ in measured)
        per_run = measured[0][1] / args.seeds
        rows.append((name, rate, per_run))
    print(f"sb3-affect {sb3_affect.__version__} | Python {platform.python_version()} | {os.cpu_count()} cores")
    print(f"simulate, {args.seeds} seeds x 200 episodes per cell, median of {args.repeats}, load {os.getloadavg()[0]:.2f}")
    for name, rate, per_run in rows:
        print(f"{name:<26} {rate / 1e6:8.2f} M decisions/CPU-s   ({per_run:,.0f} decisions per run)")
    with args.csv.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["cell", "decisions_per_cpu_s", "decisions_per_run", "seeds", "repeats"])
        for name, rate, per_run in rows:
            writer.writerow([name, f"{rate:.0f}", f"{per_run:.1f}", args.seeds, args.repeats])
    return 0


if __name__ == "__main__":
    sys.exit(main())
