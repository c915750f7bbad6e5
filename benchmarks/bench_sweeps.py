"""
Launcher and results-store benchmarks: whole sweeps through the ``sb3-affect`` command, as a user runs them.

    python benchmarks/bench_sweeps.py                    # paper (cold and warm compile cache), ablation, 10,000 seeds
    python benchmarks/bench_sweeps.py --seeds 1000       # the large sweep with fewer seeds per cell
    python benchmarks/bench_sweeps.py --skip-large       # paper and ablation only

Each measure runs the command in a fresh process and records its wall time and the peak resident memory of the
largest process it started (the launcher or one worker: ``getrusage(RUSAGE_CHILDREN)`` of a wrapper process).
"Cold" points numba's on-disk cache (``NUMBA_CACHE_DIR``) at an empty folder, so every kernel compiles; "warm" runs
again with that cache filled. Results: ``benchmarks/results_sweeps.csv``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WRAPPER = (
    "import json, resource, subprocess, sys, time\n"
    "start = time.perf_counter()\n"
    "code = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL).returncode\n"
    "wall = time.perf_counter() - start\n"
    "peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024\n"
    "print(json.dumps({'code': code, 'wall': wall, 'peak_mb': peak}))\n"
)


def measure(args: list[str], cache: Path) -> dict[str, float]:
    """Wall seconds and peak MB (largest process) of ``sb3-affect ARGS`` in a fresh process."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    command = [sys.executable, "-c", WRAPPER, sys.executable, "-m", "sb3_affect", *args]
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if result["code"] != 0:
        raise RuntimeError(f"sb3-affect {' '.join(args)} exited with {result['code']}")
    return {"wall_s": round(result["wall"], 2), "peak_mb": round(result["peak_mb"], 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10_000, help="seeds per cell of the large paper sweep")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--skip-large", action="store_true", help="only the paper and ablation sweeps")
    parser.add_argument("--keep", default=None, help="keep the results folders here (default: a temporary folder)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results_sweeps.csv"))
    args = parser.parse_args()
    work = Path(args.keep or tempfile.mkdtemp(prefix="sb3-affect-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    cache = work / "numba-cache"
    shutil.rmtree(cache, ignore_errors=True)
    workers = ["--workers", str(args.workers), "--no-progress"]
    paper, ablation = str(ROOT / "experiments" / "paper.yaml"), str(ROOT / "experiments" / "ablation.yaml")
    rows: list[dict[str, object]] = []

    def record(name: str, runs: int, command: list[str]) -> None:
        result = measure(command, cache)
        rows.append({"measure": name, "runs": runs, **result})
        print(f"{name:44s} {runs:>8,d} runs  {result['wall_s']:8.2f} s  peak {result['peak_mb']:8.1f} MB", flush=True)

    record("paper.yaml, cold compile cache", 360, ["run", paper, "--out", str(work / "paper-cold"), *workers])
    record("paper.yaml, warm compile cache", 360, ["run", paper, "--out", str(work / "paper-warm"), *workers])
    record("ablation.yaml, warm", 1440, ["run", ablation, "--out", str(work / "ablation"), *workers])
    if not args.skip_large:
        large = work / f"paper-{args.seeds}"
        runs = 18 * args.seeds
        command = ["run", paper, "--out", str(large), "--set", f"seeds={args.seeds}", *workers]
        record(f"paper.yaml --set seeds={args.seeds}, warm", runs, command)
        record("status of it", runs, ["status", str(large)])
        record("report of it", runs, ["report", str(large)])
    out = Path(args.out)
    with out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=["measure", "runs", "wall_s", "peak_mb"])
        writer.writeheader()
        writer.writerows(rows)
    print(f"-> {out}" + ("" if args.keep else f" (results folders in {work}, removed)"))
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
