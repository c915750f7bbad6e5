"""The reproducibility record: commit, package versions, Python, OS, CPU and cores, wall time of each part, seeds."""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import pandas as pd

from sb3_affect.report.context import ReportContext
from sb3_affect.report.document import fmt

PACKAGES = (
    "sb3-affect",
    "stable-baselines3",
    "gymnasium",
    "torch",
    "numpy",
    "pandas",
    "scipy",
    "matplotlib",
    "rliable",
    "lifelines",
    "statsmodels",
    "adastop",
    "numba",
)


def commit() -> str:
    """The git commit of the installed source (with ``+dirty`` for uncommitted changes), or ``unknown``."""
    root = Path(__file__).resolve().parents[2]
    try:
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"], capture_output=True, text=True, timeout=10)  # noqa: E501
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    if sha.returncode != 0:
        return "unknown"
    return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def versions() -> dict[str, str]:
    out = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def record_section(ctx: ReportContext) -> None:
    ctx.doc.h("Reproducibility record")
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    ctx.doc.ul(
        [
            f"Commit: `{commit()}`",
            f"Python {platform.python_version()} ({platform.python_implementation()}); OS: {platform.platform()}",
            f"CPU: {cpu_model()}; cores: {os.cpu_count()} ({usable} usable by this process)",
            "Packages: " + ", ".join(f"{k} {v}" for k, v in versions().items()),
            "Seeds: the launcher derives each run's seed from (sweep, agent, grid point, replicate) with sha256 "
            "(`sb3_affect.experiments.schema.derive_seed`); every run file records its seed, and the engine studies use "
            "the same derivation (large-N: the paper sweep's, so its first 20 replicates are the paper protocol's runs). "
            "DQN: explicit seeds 0-4 for every agent. Same seed, same numbers.",
        ]
    )
    rows = {name: {"wall seconds": seconds} for name, seconds in ctx.timings.items()}
    for name in ("large", "ablation_engine", "beyond") if not rows else ():  # replicate's timings hold them already
        meta_path = ctx.root / name / "meta.json"
        if meta_path.exists():
            import json

            meta = json.loads(meta_path.read_text())
            rows[f"{name} (engine, {meta['seeds']} seeds per cell)"] = {"wall seconds": meta["wall_seconds"]}
    if rows:
        ctx.table("wall_times", pd.DataFrame.from_dict(rows, orient="index").rename_axis("part"), "Wall time of each part", 1)
        ctx.doc.p(
            "Wall times are of the run that produced this folder, on a machine shared with other jobs: they vary "
            f"between runs (total {fmt(sum(r['wall seconds'] for r in rows.values()), 1)} s)."
        )
