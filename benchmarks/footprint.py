"""
Install footprint and import time of the core wheel against sb3-contrib, each in a fresh venv.

Both venvs get the same torch first (``torch==2.13.0``, the CPU build the Makefile installs), then one of
``pip install dist/sb3_affect-*.whl`` (the core, no extras) or ``pip install sb3-contrib``. Prints the packages each
install added, the MB of its site-packages, and the import times (median of ``--repeats`` fresh interpreters) of
``from sb3_affect import EmotionCallback``, ``import sb3_contrib`` and ``import stable_baselines3``.

    python benchmarks/footprint.py --work /tmp/footprint [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TORCH = "torch==2.13.0"


def pip(venv: Path, *args: str) -> None:
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", *args], check=True)


def packages(venv: Path) -> set[str]:
    out = subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "list", "--format=freeze"], check=True,
                         capture_output=True, text=True).stdout
    return {line.split("==")[0].lower() for line in out.splitlines() if line}


def size_mb(venv: Path) -> float:
    site = next((venv / "lib").glob("python*/site-packages"))
    return sum(p.stat().st_size for p in site.rglob("*") if p.is_file() and not p.is_symlink()) / 1e6


def import_seconds(venv: Path, statement: str, repeats: int) -> float:
    times = []
    for _ in range(repeats + 1):  # the first one warms the file cache
        start = time.perf_counter()
        subprocess.run([str(venv / "bin" / "python"), "-c", statement], check=True, cwd="/")
        times.append(time.perf_counter() - start)
    return statistics.median(times[1:])


def self_times(venv: Path, statement: str) -> dict[str, int]:
    """``-X importtime``: each module's own import time (microseconds)."""
    err = subprocess.run([str(venv / "bin" / "python"), "-X", "importtime", "-c", statement], cwd="/", check=True,
                         capture_output=True, text=True).stderr
    times = {}
    for line in err.splitlines():
        if line.startswith("import time:") and "self [us]" not in line:
            parts = line.split("|")
            times[parts[2].strip()] = int(parts[0].split(":")[1])
    return times


def added_import_seconds(venv: Path, repeats: int) -> tuple[int, float]:
    """The modules ``from sb3_affect import EmotionCallback`` imports beyond ``import stable_baselines3``, and the
    median of their summed own import times (steadier than wall times on a busy machine)."""
    sums, count = [], 0
    for _ in range(repeats):
        base = self_times(venv, "import stable_baselines3")
        added = {m: t for m, t in self_times(venv, "from sb3_affect import EmotionCallback").items() if m not in base}
        sums.append(sum(added.values()) / 1e6)
        count = len(added)
    return count, statistics.median(sums)


def fresh(venv: Path) -> tuple[set[str], float]:
    subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True)
    pip(venv, TORCH)
    return packages(venv), size_mb(venv)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("--work", type=Path, required=True, help="folder for the wheel and the two venvs")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    work = args.work.resolve()
    dist = work / "dist"
    subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(dist), str(ROOT)], check=True,
                   capture_output=True)
    wheel = max(dist.glob("sb3_affect-*.whl"), key=lambda p: p.stat().st_mtime)
    results = {}
    for name, requirement in (("sb3-affect (core wheel)", str(wheel)), ("sb3-contrib", "sb3-contrib")):
        venv = work / ("venv-core" if name.startswith("sb3-affect") else "venv-contrib")
        before, mb_before = fresh(venv)
        pip(venv, requirement)
        after = packages(venv)
        added = sorted(after - before)
        results[name] = (venv, added, size_mb(venv), size_mb(venv) - mb_before)
        print(f"{name}: {len(added)} packages added to torch's {len(before)} ({', '.join(added)}); site-packages "
              f"{results[name][2]:.0f} MB in all, {results[name][3]:.0f} MB added", flush=True)
    core = results["sb3-affect (core wheel)"][0]
    contrib = results["sb3-contrib"][0]
    sb3 = import_seconds(core, "import stable_baselines3", args.repeats)
    affect = import_seconds(core, "from sb3_affect import EmotionCallback", args.repeats)
    contrib_time = import_seconds(contrib, "import sb3_contrib", args.repeats)
    print(f"import times (median of {args.repeats}): import stable_baselines3 {sb3:.2f} s; "
          f"from sb3_affect import EmotionCallback {affect:.2f} s ({affect - sb3:+.2f} s); import sb3_contrib "
          f"{contrib_time:.2f} s")
    count, seconds = added_import_seconds(core, args.repeats)
    print(f"from sb3_affect import EmotionCallback imports {count} modules beyond import stable_baselines3, "
          f"{seconds:.3f} s of import time (-X importtime, median of {args.repeats})")


if __name__ == "__main__":
    main()
