"""
The main job: the sweep files of ``PARTS`` through the launcher (the paper's protocol, the DQN comparison, the fair
baselines, the hunters, the large-N study, the reading and speed ablations, the long runs, the joy trace), ε tuned on
each task beyond the paper and those tasks with the tuned ε (static grid, moving and evading prey, mazes), the
replication forensics at a reduced size, then one report (the forensics section passed in from here: the report layer
does not import the forensics).
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: The folder of the sweep files; None: those installed with the package (``experiments/`` of the source tree).
EXPERIMENTS: Path | None = None
#: The sweeps of the main job, in order: (name of experiments/<name>.yaml and of the results folder, description).
PARTS = (
    ("paper", "the paper's protocol ({runs} runs)"),
    ("dqn", "SB3 DQN beside the tabular agents, equal seeds and budget ({runs} runs)"),
    ("baselines", "fair baselines beside both paper agents"),
    ("hunters", "two hunters on Kuremoto's pursuit problem"),
    ("hunters_moving", "two hunters, moving prey"),
    ("large", "large-N study: the paper's 18 cells and the speed-matched ε-greedy ({runs} runs)"),
    ("ablation", "reading ablation: the 8 readings of the appraisal x 9 ε ({runs} runs)"),
    ("speed_one", "speed ablation: the affective agent with speed fixed at 1 cell ({runs} runs)"),
    ("long", "long runs: both paper agents, runs of 2,000 episodes ({runs} runs)"),
    ("joy_trace", "joy trace: the paper's affective agent, each decision's emotion and act recorded ({runs} runs)"),
    ("minigrid", "the tabular agents on MiniGrid ({runs} runs)"),
)
#: Parts that need a package of an extra: (part, package, extra); without it the part is skipped with one line.
PART_PACKAGES = (("minigrid", "minigrid", "minigrid"),)
#: The parts sized by ``main``'s ``large_seeds`` (a cap on their seeds per cell) and ``engine_episodes`` (their
#: episodes per run; ``long``: 10 x as many); ``ablation`` by ``ablation_seeds``.
SIZED = ("large", "ablation", "speed_one", "long")
#: Seeds per agent and task beyond the paper (``report.beyond_tasks``), read when ``main`` runs.
BEYOND_SEEDS = 1000
#: Sizes for quick checks, read when ``main`` runs (None: the sweep files' own sizes and the paper's 200 episodes):
#: a cap on the seeds per cell of the ``SIZED`` parts (and of the tuning), the ablation's seeds, the episodes per run.
LARGE_SEEDS: int | None = None
ABLATION_SEEDS: int | None = None
ENGINE_EPISODES: int | None = None
#: Tuning seeds per ε value of the per-task tuning (``report.tuning``), disjoint from the evaluation's seeds.
TUNING_SEEDS = 200
#: The forensics' size inside the main job (``sb3-affect forensics`` alone defaults to 3 / 4 / 100).
FORENSICS = {"screen_reps": 2, "leaders": 4, "reps": 30}
#: The main job's wall time on 2 idle cores, as the help and the docs quote it (measured: see the README).
MINUTES = "about 6-9 minutes"
#: The studies after the sweeps: (results folder, description), for the help.
STUDIES = (
    (
        "tuning",
        f"ε of ε-greedy and speed-matched ε-greedy tuned on each task beyond the paper, {TUNING_SEEDS} seeds per value "
        "(engine)",
    ),
    ("beyond", f"static grid, moving and evading prey, mazes with the tuned ε, {BEYOND_SEEDS:,} seeds (engine)"),
    ("forensics", "the replication forensics at a reduced size: {screen_reps} screen and {reps} leader replications"),
)


def sweep_runs(path: Path) -> int | None:
    """
    How many runs an experiment file asks for: seeds x the grid points of each agent (read with yaml alone, so the
    help stays fast; the launcher's ``Sweep.run_configs`` gives the same count). None when it can not be read.
    """
    import math

    try:
        import yaml
    except ImportError:  # without the experiments extra the help gives no count (running a part says what to install)
        return None
    try:
        data = yaml.safe_load(Path(path).read_text())
        seeds = data["seeds"]
        agents = data["agents"].values() if isinstance(data["agents"], dict) else data["agents"]
        per_agent = [math.prod(len(v) for v in (agent.get("grid") or {}).values()) for agent in agents]
        tasks = len(data.get("tasks") or [None])
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return None
    return (len(seeds) if isinstance(seeds, list) else int(seeds)) * sum(per_agent) * tasks


def missing_package(part: str) -> str | None:
    """What to install when a part needs a package that is not installed (``PART_PACKAGES``), else None."""
    import importlib.util

    for name, package, extra in PART_PACKAGES:
        if name == part and importlib.util.find_spec(package) is None:
            return f"{package} is not installed: pip install \"sb3-affect[{extra}]\""
    return None


def sweeps_folder(experiments: Path | None = None) -> Path:
    """The folder of the sweep files: ``experiments``, else ``EXPERIMENTS``, else those installed with the package."""
    if experiments or EXPERIMENTS:
        return Path(experiments or EXPERIMENTS)  # type: ignore[arg-type]
    from importlib.resources import files  # (not the launcher's own helper: --help must not need the launcher's extra)

    return Path(str(files("sb3_affect.sweeps")))


def part_description(name: str, description: str, experiments: Path | None = None) -> str:
    """A part's description with its run count read from its experiment file (one source for that number)."""
    if "{runs}" not in description:
        return description
    runs = sweep_runs(sweeps_folder(experiments) / f"{name}.yaml")
    return description.format(runs=runs if runs is not None else "?")


def forensics_extra(folder: Path) -> Any:
    """The forensics section for ``build_report(extra_sections=...)`` (None when ``folder`` holds no results)."""
    from sb3_affect.study.forensics.section import has_results, report_section

    return report_section(folder) if has_results(folder) else None


def main(
    out_dir: Path = Path("runs"),
    workers: int | None = None,
    experiments: Path | None = None,
    large_seeds: int | None = None,
    ablation_seeds: int | None = None,
    beyond_seeds: int | None = None,
    engine_episodes: int | None = None,
    forensics: bool = True,
    command: str | None = None,
) -> Path:
    """
    Run the sweeps of ``PARTS`` into ``out_dir/<name>`` through the launcher (resuming what is there), the per-task
    tuning of ε into ``out_dir/tuning`` and the tasks beyond the paper with the tuned ε into ``out_dir/beyond``
    (reused when complete), the forensics into ``out_dir/forensics``, then write
    ``out_dir/report.md`` (and .html, tables/, figures/). Prints the wall time of each part.

    :param out_dir: the replicate folder
    :param workers: processes (default: usable CPUs)
    :param experiments: the folder holding the experiment files (default: the ones installed with the package)
    :param large_seeds: a cap on the seeds per cell of the ``SIZED`` parts and the tuning (default ``LARGE_SEEDS``;
        None: the sweep files' sizes)
    :param ablation_seeds: seeds per cell of the reading ablation (default ``ABLATION_SEEDS``; None: the file's)
    :param beyond_seeds: seeds per agent and task beyond the paper (default ``BEYOND_SEEDS``)
    :param engine_episodes: episodes per run of the ``SIZED`` parts (``long``: 10 x as many), the tuning and the tasks
        beyond the paper (default ``ENGINE_EPISODES``; None: the files' and the paper's 200; fewer for quick checks)
    :param forensics: run the replication forensics (size ``FORENSICS``) into ``out_dir/forensics``
    :param command: the command line to record (default: this process's)
    :return: the path of report.md
    """
    from sb3_affect.study.launcher import run_sweep
    from sb3_affect.study.report import build_report, paper
    from sb3_affect.study.report.beyond_tasks import beyond_cells
    from sb3_affect.study.report.engine_studies import run_cells
    from sb3_affect.study.report.tuning import run_tuning

    experiments = sweeps_folder(experiments)
    large_seeds = large_seeds or LARGE_SEEDS
    ablation_seeds = ablation_seeds or ABLATION_SEEDS
    beyond_seeds = beyond_seeds or BEYOND_SEEDS
    engine_episodes = engine_episodes or ENGINE_EPISODES
    out_dir = Path(out_dir)
    _refuse_a_sweep_folder(out_dir)
    record = _Record(out_dir)
    timings: dict[str, float] = {}
    for name, description in PARTS:
        path = experiments / f"{name}.yaml"
        overrides = _sized(name, path, large_seeds, ablation_seeds, engine_episodes) if name in SIZED else []
        description = part_description(name, description, experiments)
        missing = missing_package(name)
        if missing:
            print(f"== skipped: {description} ({missing})", flush=True)
            continue
        if overrides:
            description += f" [{', '.join(overrides)}]"
        print(f"== {description}: {path} -> {out_dir / name}", flush=True)
        summary = run_sweep(path, out_dir / name, workers=workers, overrides=overrides)
        key = f"{name} ({description})"
        timings[key] = record.part(key, summary.seconds, done_before=summary.skipped, todo=summary.total - summary.skipped)
        print(
            f"   {summary.finished} runs now, {summary.skipped} already done, {summary.failed} failed, "
            f"{summary.seconds:.1f} s",
            flush=True,
        )
    tuning_seeds = min(TUNING_SEEDS, large_seeds or TUNING_SEEDS)
    engine_episodes = engine_episodes or paper.EPISODES
    description = f"ε tuned per task beyond the paper, {tuning_seeds} seeds per value (engine)"
    print(f"== {description} -> {out_dir / 'tuning'}", flush=True)
    start = time.perf_counter()
    with _heartbeat(description):
        tuned, seconds = run_tuning(out_dir / "tuning", tuning_seeds, engine_episodes, beyond_seeds, workers=workers)
    # the rounds' own time (rounds read back keep theirs)
    timings[description] = record.set(description, seconds, time.perf_counter() - start)
    chosen = ", ".join(f"{agent} on {task}: {t.best:g}{'' if t.interior else ' (edge)'}" for (task, agent), t in tuned.items())
    print(f"   {timings[description]:.1f} s; chosen: {chosen}", flush=True)
    description = f"static grid, moving and evading prey, mazes, {beyond_seeds} seeds (engine)"
    print(f"== {description} -> {out_dir / 'beyond'}", flush=True)
    start = time.perf_counter()
    with _heartbeat(description):
        cells = beyond_cells({key: t.best for key, t in tuned.items()})
        table, meta = run_cells(out_dir / "beyond", cells, beyond_seeds, engine_episodes, workers=workers)
    own = time.perf_counter() - start
    timings[description] = record.set(description, float(meta.get("wall_seconds", own)), own)
    print(f"   {len(table)} runs, {own:.1f} s", flush=True)
    extra = []
    if forensics:
        from sb3_affect.study.forensics.analysis import run_forensics

        description = "replication forensics ({screen_reps} screen, {leaders} leaders x {reps} replications)"
        description = description.format(**FORENSICS)
        print(f"== {description} -> {out_dir / 'forensics'}", flush=True)
        start = time.perf_counter()
        with _heartbeat(description):
            run_forensics(
                out_dir / "forensics",
                screen_reps=FORENSICS["screen_reps"],
                leaders=FORENSICS["leaders"],
                reps=FORENSICS["reps"],
                workers=workers or len(_cpus()),
                progress=False,
            )
        timings[description] = record.set(description, time.perf_counter() - start)
        print(f"   {timings[description]:.1f} s", flush=True)
        section = forensics_extra(out_dir / "forensics")
        if section is not None:
            extra.append(section)
    start = time.perf_counter()
    report = build_report(out_dir, timings=timings, extra_sections=extra, command=command or " ".join(sys.argv))
    timings["report"] = time.perf_counter() - start
    record.finish(timings["report"])
    print("wall time: " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in timings.items()))
    print(f"report: {report} (and {report.with_suffix('.html')})")
    return report


def _sized(
    name: str, path: Path, large_seeds: int | None, ablation_seeds: int | None, episodes: int | None
) -> list[str]:
    """
    The ``--set`` overrides of a ``SIZED`` part for a quick check: its seeds capped at ``ablation_seeds`` (``ablation``)
    or ``large_seeds`` (the others), its episodes ``episodes`` (``long``: 10 x as many). None: the file's own size.
    """
    import yaml

    data = yaml.safe_load(path.read_text())
    cap = ablation_seeds if name == "ablation" else large_seeds
    overrides = [] if cap is None else [f"seeds={min(int(data['seeds']), cap)}"]
    if episodes is not None:
        overrides.append(f"episodes={episodes * (10 if name == 'long' else 1)}")
    return overrides


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


def _refuse_a_sweep_folder(out_dir: Path) -> None:
    """A replication's folder holds its sweeps in sub-folders: one that holds a sweep itself is refused (a mix)."""
    from sb3_affect.study.launcher.store import ResultsStore, StoreError

    store = ResultsStore(out_dir)
    saved = store.saved_sweep()
    if saved is not None or any(store.chunks.glob("[!.]*.parquet")) or any(store.runs.glob("[!.]*.json")):
        name = saved.get("name", "?") if saved is not None else "?"
        raise StoreError(
            f"{out_dir} holds the results of sweep {name!r}, which a replication would mix with; give the replication "
            f"a folder of its own, e.g. --out {out_dir / 'replication'}"
        )


class _Record:
    """
    ``OUT/replicate.json``: the wall time of each part over the runs that did its work, so that a resumed replicate
    reports the time the results took (a part finished earlier keeps its time; a part resumed adds the resume's), and
    each run's own times (``runs``: when it started, the seconds each part took in that run, its report step and its
    total), so that a number can be traced to the run it comes from. It also marks the folder as a replication, into
    which ``sb3-affect run`` refuses to write a sweep.
    """

    def __init__(self, out_dir: Path) -> None:
        out_dir.mkdir(parents=True, exist_ok=True)
        self.path = out_dir / "replicate.json"
        try:
            saved = json.loads(self.path.read_text())
        except (OSError, ValueError):
            saved = {}
        saved = saved if isinstance(saved, dict) else {}
        timings, runs = saved.get("timings"), saved.get("runs")
        self.timings: dict[str, Any] = dict(timings) if isinstance(timings, dict) else {}
        self.runs: list[dict[str, Any]] = [r for r in runs if isinstance(r, dict)] if isinstance(runs, list) else []
        self.start = time.perf_counter()
        started = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
        self.runs.append({"started": started, "parts": {}})

    def part(self, key: str, seconds: float, done_before: int, todo: int) -> float:
        previous = self.timings.get(key)
        if not isinstance(previous, (int, float)):
            return self.set(key, seconds, seconds)
        if todo == 0:  # nothing left to do: the time is the earlier runs'
            return self.set(key, float(previous), seconds)
        return self.set(key, previous + seconds if done_before else seconds, seconds)

    def set(self, key: str, seconds: float, own: float | None = None) -> float:
        """The results' time of part ``key``; ``own``: the seconds it took in this run (default ``seconds``)."""
        self.timings[key] = seconds
        self.runs[-1]["parts"][key] = seconds if own is None else own
        self._write()
        return seconds

    def finish(self, report_seconds: float) -> None:
        """This run's report step and its total wall time."""
        self.runs[-1]["report"] = report_seconds
        self.runs[-1]["total"] = time.perf_counter() - self.start
        self._write()

    def _write(self) -> None:
        tmp = self.path.with_name(f".{self.path.name}.tmp")
        tmp.write_text(json.dumps({"timings": self.timings, "runs": self.runs}, indent=1))
        tmp.replace(self.path)


def _cpus() -> set[int]:
    import os

    return os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else set(range(os.cpu_count() or 1))
