"""
Report and status benchmarks at a given seed count: wall time and peak memory of ``sb3-affect report`` and
``sb3-affect status`` on a paper-protocol results folder, as a user runs them.

    python benchmarks/bench_report.py --seeds 1000                 # runs the sweep first (18,000 runs), then measures
    python benchmarks/bench_report.py --folder DIR                 # an existing results folder (only read)
    python benchmarks/bench_report.py --folder A --folder B        # several, e.g. 1,000 and 10,000 seeds

Each measure runs the command in a fresh process and records its wall time and peak resident memory
(``getrusage(RUSAGE_CHILDREN)`` of a wrapper process, the same figure as ``/usr/bin/time -v``); "load + metrics" is
``load_results`` + ``run_metrics`` alone. The report writes into the folder it is given, so it runs on a scratch
folder whose ``chunks/`` links to the measured one: the measured folder is never written. Results:
``benchmarks/results_report.csv``.

The report's target on the paper's protocol at 10,000 seeds (180,000 runs, 36 M episodes): <= 30 s and <= 1 GB peak
on 2 cores (``TARGET``); each report of a folder that large is marked met or missed. ``--repeat N`` measures each
command N times (every run is printed and written, not the best).
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
LOAD = (
    "import sys\n"
    "from sb3_affect.study.report.reading.run_tables import load_results, run_metrics\n"
    "results = load_results(sys.argv[1])\n"
    "run_metrics(results.episodes, results.runs)\n"
)


#: The report's target: (runs at least, wall seconds at most, peak MB at most).
TARGET = (180_000, 30.0, 1024.0)


def verdict(name: str, runs: int, result: dict[str, float]) -> str:
    """'met' / 'missed' for a report of a folder as large as the target's, else ''."""
    if name != "report" or runs < TARGET[0]:
        return ""
    return "met" if result["wall_s"] <= TARGET[1] and result["peak_mb"] <= TARGET[2] else "missed"


def measure(command: list[str]) -> dict[str, float]:
    """Wall seconds and peak MB of ``command`` in a fresh process."""
    done = subprocess.run([sys.executable, "-c", WRAPPER, *command], capture_output=True, text=True, check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if result["code"] != 0:
        raise RuntimeError(f"{' '.join(command)} exited with {result['code']}")
    return {"wall_s": round(result["wall"], 2), "peak_mb": round(result["peak_mb"], 1)}


def scratch_copy(folder: Path, work: Path) -> Path:
    """A folder the report may write into, reading ``folder``'s chunks through a link (and copies of the rest)."""
    target = work / f"report-{folder.name}"
    shutil.rmtree(target, ignore_errors=True)
    target.mkdir(parents=True)
    shutil.copy(folder / "sweep.json", target / "sweep.json")
    for name in ("runs", "failed"):
        if (folder / name).is_dir():
            shutil.copytree(folder / name, target / name)
        else:
            (target / name).mkdir()
    if (folder / "chunks").is_dir():
        (target / "chunks").symlink_to((folder / "chunks").resolve())
    return target


def runs_of(folder: Path) -> int:
    from sb3_affect.study.launcher.store import ResultsStore

    return sum(done for _, done, _ in ResultsStore(folder).progress()[1].values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, action="append", default=[], help="run the paper sweep at this many seeds")
    parser.add_argument("--folder", action="append", default=[], help="an existing paper results folder (read only)")
    parser.add_argument("--workers", type=int, default=2, help="workers of the sweeps --seeds runs")
    parser.add_argument("--keep", default=None, help="keep the scratch folders here (default: a temporary folder)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results_report.csv"))
    parser.add_argument("--repeat", type=int, default=1, help="measure each command this many times (every run kept)")
    args = parser.parse_args()
    if not args.seeds and not args.folder:
        parser.error("give --seeds N or --folder DIR (repeatable)")
    work = Path(args.keep or tempfile.mkdtemp(prefix="sb3-affect-bench-report-"))
    work.mkdir(parents=True, exist_ok=True)
    folders = [Path(f) for f in args.folder]
    for seeds in args.seeds:
        folder = work / f"paper-{seeds}"
        command = ["run", str(ROOT / "experiments" / "paper.yaml"), "--out", str(folder), "--set", f"seeds={seeds}"]
        subprocess.run([sys.executable, "-m", "sb3_affect", *command, "--workers", str(args.workers), "--no-progress"],
                       check=True, stdout=subprocess.DEVNULL)
        folders.append(folder)
    rows: list[dict[str, object]] = []
    for folder in folders:
        runs = runs_of(folder)
        scratch = scratch_copy(folder, work)
        for name, command in (
            ("status", [sys.executable, "-m", "sb3_affect", "status", str(folder)]),
            ("load_results + run_metrics", [sys.executable, "-c", LOAD, str(folder)]),
            ("report", [sys.executable, "-m", "sb3_affect", "report", str(scratch)]),
        ):
            for _ in range(max(1, args.repeat)):
                result = measure(command)
                target = verdict(name, runs, result)
                load = round(os.getloadavg()[0], 2)
                rows.append({"measure": name, "folder": str(folder), "runs": runs, **result, "load": load, "target": target})
                print(
                    f"{name:28s} {runs:>8,d} runs  {result['wall_s']:8.2f} s  peak {result['peak_mb']:8.1f} MB  "
                    f"load {load:5.2f}  {target and f'target (<= {TARGET[1]:.0f} s, <= {TARGET[2]:.0f} MB): {target}'}",
                    flush=True,
                )
    out = Path(args.out)
    with out.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=["measure", "folder", "runs", "wall_s", "peak_mb", "load", "target"])
        writer.writeheader()
        writer.writerows(rows)
    print(f"-> {out}")


if __name__ == "__main__":
    main()
