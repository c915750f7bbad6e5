"""
Issue 7's comparison without the launcher: run the configs of ``sb3_affect.baselines.suite`` with a process pool
and write one JSON per run (the launcher's run-file format) under OUT/runs, then summarise.

    python experiments/baselines_run.py --tune --out runs/baselines-tuning --workers 2
    python experiments/baselines_run.py --out runs/baselines --workers 2
    python -m sb3_affect.report.baseline_summary runs/baselines
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor

from sb3_affect.baselines.suite import execute_to, report_configs, tuning_configs


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", required=True)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tune", action="store_true", help="run the tuning grid (separate seeds) instead")
    parser.add_argument("--tasks", default="static,moving,moving-7x7")
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    tasks = tuple(args.tasks.split(","))
    configs = list(tuning_configs()) if args.tune else list(report_configs(tasks, range(args.seeds)))
    start = time.perf_counter()
    with ProcessPoolExecutor(args.workers) as pool:
        for i, _ in enumerate(pool.map(execute_to, configs, [args.out] * len(configs), chunksize=4), 1):
            if i % 50 == 0 or i == len(configs):
                print(f"{i}/{len(configs)} runs, {time.perf_counter() - start:.0f} s", flush=True)


if __name__ == "__main__":
    main()
