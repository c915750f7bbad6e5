"""
The reproducibility record: the exact command, the installed package's version and commit, a lock file of every
installed package's version, Python, OS, CPU and cores, whether the forensics ran, sha256 checksums of the run
tables, the wall time of each part, seeds.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import pandas as pd

import sb3_affect
from sb3_affect.study.launcher.folder_files import MAX_SWEEP_FILE_BYTES
from sb3_affect.study.launcher.regular_files import UnreadableFile, check_regular, open_regular, read_json
from sb3_affect.study.launcher.store import ResultsStore, StoreError
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.document import fmt
from sb3_affect.study.report.rendering.formats import with_separators
from sb3_affect.study.report.rendering.output_files import write_text

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


def commit(package_dir: Path | None = None) -> str:
    """
    The git commit of the installed sb3-affect (``+dirty`` for uncommitted changes), only when the package's own
    source folder sits at the top of an sb3-affect git checkout (an editable install); never the commit of another
    repository that happens to surround site-packages. Otherwise a phrase saying why there is none.
    """
    package = Path(package_dir or Path(sb3_affect.__file__).resolve().parent)
    root = package.parent

    def git(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10)

    try:
        top = git("rev-parse", "--show-toplevel")
        at_top = top.returncode == 0 and Path(top.stdout.strip()).resolve() == root.resolve()
        if not at_top or not (root / "pyproject.toml").exists():
            return "none (an installed package, not an sb3-affect git checkout)"
        sha = git("rev-parse", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return "unknown (git not available)"
    if sha.returncode != 0:
        return "unknown (git failed)"
    return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def lock_lines() -> list[str]:
    """Every installed distribution as ``name==version``, sorted (importlib.metadata): the run's lock file."""
    found = {}
    for dist in metadata.distributions():
        name = dist.metadata["Name"]
        if name:
            found[name.lower()] = f"{name}=={dist.version}"
    return [found[k] for k in sorted(found)]


def run_tables(root: Path) -> list[Path]:
    """
    The files holding the runs of a replicate (or results) folder: the chunks and run files that count (those a
    report reads: ``ResultsStore.checked_files``; the tuning's rounds included), the other studies' CSV tables.
    """

    files = {path for path in root.glob("*/*.csv") if "tables" not in path.parts}
    for path in files:  # a FIFO, a device or a link among them: one line naming it (``regular_files``)
        check_regular(path, root=root)
    launched = (path.parent for pattern in ("*/sweep.json", "tuning/round*/sweep.json") for path in root.glob(pattern))
    for folder in (root, *launched):
        if (folder / "runs").is_dir():
            try:
                checked = ResultsStore(folder).checked_files()
            except StoreError:  # a folder holding a file that does not count: its runs are not reported either
                continue
            files.update(checked.run_files)
            files.update(checked.chunk_files)
    return sorted(files)


def sha256(path: Path, root: Path | None = None) -> str:
    """The sha256 of a regular file (inside ``root`` when given: ``regular_files``)."""
    digest = hashlib.sha256()
    with open_regular(path, root=root) as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


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
    lock = ctx.out / "packages.lock"
    write_text(lock, "\n".join(lock_lines()) + "\n")
    tables = run_tables(ctx.root)
    checksums = ctx.out / "checksums.sha256"
    write_text(checksums, "".join(f"{sha256(path, ctx.root)}  {path.relative_to(ctx.root).as_posix()}\n" for path in tables))
    try:
        version = metadata.version("sb3-affect")
    except metadata.PackageNotFoundError:
        version = "not installed"
    ctx.doc.ul(
        [
            f"Command: `{ctx.command or 'not recorded (the report was built by a library call)'}`",
            f"sb3-affect {version}; commit: `{commit()}`",
            f"Python {platform.python_version()} ({platform.python_implementation()}); OS: {platform.platform()}",
            f"CPU: {cpu_model()}; cores: {os.cpu_count()} ({usable} usable by this process)",
            "Packages: " + ", ".join(f"{k} {v}" for k, v in versions().items())
            + f"; every installed package's version: `{lock.name}` ({len(lock_lines())} packages)",
            "Replication forensics: " + str(ctx.cache.get("forensics", "not run (`sb3-affect forensics` was not part of "
                                                             "this run; `make replicate` runs it)")),
            f"Checksums: sha256 of the {len(tables):,} run tables (run files, Parquet chunks, study tables) in "
            f"`{checksums.name}` (check with `sha256sum -c {checksums.name}` from {ctx.root})",
            "Seeds: the launcher derives each run's seed from (sweep, agent, grid point, replicate) with sha256 "
            "(`sb3_affect.study.launcher.schema.derive_seed`); every run file records its seed, and the engine studies use "
            "the same derivation (large-N: the paper sweep's, so its first 20 replicates are the paper protocol's runs). "
            "DQN: explicit seeds 0-4 for every agent. Same seed, same numbers.",
        ]
    )
    runs = replicate_runs(ctx.root)
    rows = {
        with_separators(name): {"wall seconds": seconds, "computed in": computed_in(runs, name, seconds)}
        for name, seconds in ctx.timings.items()
    }
    if rows:
        ctx.table(
            "wall_times",
            pd.DataFrame.from_dict(rows, orient="index").rename_axis("part"),
            "The results' time: each part's wall time in the run of `replicate` that computed it (a part a later run "
            "read back keeps the time of the run that computed it); the text quotes these times",
            1,
        )
        ctx.doc.p(
            "Wall times on a machine shared with other jobs vary between runs (the parts above sum to "
            f"{fmt(sum(ctx.timings.values()), 1)} s"
            + (f", over {len(runs)} runs of `replicate` into this folder: each run's own times below" if len(runs) > 1
               else "")
            + ")."
        )
    if runs:
        ctx.table(
            "wall_times_by_run",
            runs_table(runs),
            "Each run of `replicate` into this folder with its own times (seconds; a part read back from an earlier run "
            "takes little). The report step and the total of a run are recorded in `replicate.json` (`runs`: "
            "`report`, `total`) and printed once it ends, so the run writing this report shows none yet; a report "
            "built again from the folder (`sb3-affect report`) shows them",
            1,
        )


def computed_in(runs: list[dict], part: str, seconds: float) -> str:
    """The run of ``replicate`` (its number and start) whose time of ``part`` is the results' time."""
    for number, run in enumerate(runs, 1):
        if run["parts"].get(part) == seconds:
            return f"run {number} ({run.get('started', '?')})"
    return "not recorded"


def part_time(ctx: ReportContext, name: str, meta: dict | None = None) -> str:
    """
    A part's time as the record tabulates it: its wall seconds in the run of ``replicate`` that computed it (the
    record's table), else the runs' own seconds summed over the workers (``meta``), labelled as such.
    """
    for part, seconds in ctx.timings.items():
        if part.split(" (")[0] == name:
            return f"{fmt(seconds, 1)} s of wall time, the record's time of the part"
    runs = replicate_runs(ctx.root)
    for number, run in reversed(list(enumerate(runs, 1))):
        for part, seconds in run["parts"].items():
            if str(part).split(" (")[0] == name and isinstance(seconds, (int, float)):
                return f"{fmt(float(seconds), 1)} s of wall time in run {number} of `replicate` (the record)"
    if meta and "wall_seconds" in meta:
        return f"{fmt(float(meta['wall_seconds']), 1)} s of the runs' own time summed over the workers"
    return "time not recorded"


def replicate_runs(root: Path) -> list[dict]:
    """The runs of ``replicate`` recorded in ``root/replicate.json`` (none for a folder it did not write)."""
    try:
        saved = read_json(Path(root) / "replicate.json", MAX_SWEEP_FILE_BYTES)
    except UnreadableFile as error:  # missing, or cut short by a kill: no runs recorded; anything else: one line
        if error.reason == "does not exist" or error.reason.startswith("is not valid JSON"):
            return []
        raise
    runs = saved.get("runs") if isinstance(saved, dict) else None
    return [r for r in runs if isinstance(r, dict) and isinstance(r.get("parts"), dict)] if isinstance(runs, list) else []


def runs_table(runs: list[dict]) -> pd.DataFrame:
    """
    One column per run (its number and start), one row per part, then its report step and its total (rows no run
    has recorded yet are left out).
    """
    columns = {}
    for number, run in enumerate(runs, 1):
        column = {str(k): float(v) for k, v in run["parts"].items()}
        for key in ("report", "total"):
            column[key] = float(run[key]) if isinstance(run.get(key), (int, float)) else float("nan")
        columns[f"run {number} ({run.get('started', '?')})"] = column
    table = pd.DataFrame(columns)
    order = [k for k in table.index if k not in ("report", "total")]
    order += [k for k in ("report", "total") if table.loc[k].notna().any()]
    table = table.loc[order]
    table.index = [with_separators(str(k)) for k in table.index]
    return table.rename_axis("part")
