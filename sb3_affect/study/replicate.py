"""
The main job: the sweep files of ``PARTS`` through the launcher (the paper's protocol, the DQN comparison, the fair
baselines, the hunters, the large-N study, the reading and speed ablations, the long runs, the joy trace, MiniGrid,
the replication forensics at a reduced size: a study file whose replications run on the launcher's executor), then
through the launcher too ε tuned on each task beyond the paper (experiments/tuning.yaml, in rounds) and those tasks with
the tuned ε (experiments/beyond.yaml: static grid, moving and evading prey, mazes), then one report (the forensics
section passed in from here: the report layer does not import the forensics). Every part runs on the same backend,
local processes or Ray.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from sb3_affect.study.forensics.section import report_section
from sb3_affect.study.launcher import run_sweep
from sb3_affect.study.launcher.epsilon_tuning import round_values, tune, tuning_grid
from sb3_affect.study.launcher.folder_files import MAX_SWEEP_FILE_BYTES
from sb3_affect.study.launcher.regular_files import UnreadableFile, read_json, write_file
from sb3_affect.study.launcher.store import StoreError, claim_kind
from sb3_affect.study.launcher.sweep_file import load_sweep
from sb3_affect.study.report import build_report
from sb3_affect.study.report.reading.study_tables import folder_study
from sb3_affect.study.running import run_file
from sb3_affect.study.studies import (
    PARTS,
    SIZED,
    STUDIES,
    TUNED_PARTS,
    missing_package,
    part_description,
    shipped_sweeps_folder,
)

#: The folder of the sweep files; None: those installed with the package (``experiments/`` of the source tree).
EXPERIMENTS: Path | None = None
#: Sizes for quick checks, read when ``main`` runs (None: the sweep files' own sizes): a cap on the seeds per cell of
#: the ``SIZED`` parts and of the tuning, the ablation's seeds, a cap on the seeds per agent and task beyond the paper,
#: the episodes per run.
LARGE_SEEDS: int | None = None
ABLATION_SEEDS: int | None = None
BEYOND_SEEDS: int | None = None
ENGINE_EPISODES: int | None = None
#: Further ``--set`` overrides of a part by name, for quick checks (e.g. ``{"forensics": ["forensics.reps=2"]}``).
OVERRIDES: dict[str, list[str]] = {}


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
    backend: str = "local",
    ray_address: str | None = None,
) -> Path:
    """
    Run the sweep files of ``PARTS`` into ``out_dir/<name>`` (resuming what is there): the sweeps through the launcher,
    the forensics study on its executor; then those of ``TUNED_PARTS``: the per-task tuning of ε into
    ``out_dir/tuning/round<k>`` and the tasks beyond the paper with the tuned ε into ``out_dir/beyond``; then write
    ``out_dir/report.md`` (and .html, tables/, figures/). Prints the wall time of each part.

    :param out_dir: the replicate folder
    :param workers: processes (default: usable CPUs)
    :param experiments: the folder holding the experiment files (default: the ones installed with the package)
    :param large_seeds: a cap on the seeds per cell of the ``SIZED`` parts and the tuning (default ``LARGE_SEEDS``;
        None: the sweep files' sizes)
    :param ablation_seeds: seeds per cell of the reading ablation (default ``ABLATION_SEEDS``; None: the file's)
    :param beyond_seeds: a cap on the seeds per agent and task beyond the paper (default ``BEYOND_SEEDS``; None: the
        file's)
    :param engine_episodes: episodes per run of the ``SIZED`` parts (``long``: 10 x as many), the tuning and the tasks
        beyond the paper (default ``ENGINE_EPISODES``; None: the files'; fewer for quick checks)
    :param forensics: run the replication forensics (experiments/forensics.yaml) into ``out_dir/forensics``
    :param command: the command line to record (default: this process's)
    :param backend: where every part runs: ``"local"`` (processes) or ``"ray"`` (Ray tasks)
    :param ray_address: the Ray cluster of every part, HOST:PORT or ray://HOST:PORT (default: a private instance)
    :return: the path of report.md
    """

    experiments = experiments or EXPERIMENTS or shipped_sweeps_folder()
    large_seeds = large_seeds or LARGE_SEEDS
    ablation_seeds = ablation_seeds or ABLATION_SEEDS
    beyond_seeds = beyond_seeds or BEYOND_SEEDS
    engine_episodes = engine_episodes or ENGINE_EPISODES
    out_dir = Path(out_dir)
    claim_kind(out_dir, "replication", "replication")  # (its studies go in sub-folders: one in out_dir is a mix)
    record = _Record(out_dir)
    timings: dict[str, float] = {}
    executor: dict[str, Any] = {"workers": workers, "backend": backend, "ray_address": ray_address}
    for name, description in PARTS:
        if name == "forensics" and not forensics:
            continue
        path = experiments / f"{name}.yaml"
        overrides = _sized(name, path, large_seeds, ablation_seeds, engine_episodes) if name in SIZED else []
        overrides += OVERRIDES.get(name, [])
        description = part_description(name, description, experiments)
        missing = missing_package(name)
        if missing:
            print(f"== skipped: {description} ({missing})", flush=True)
            continue
        if overrides:
            description += f" [{', '.join(overrides)}]"
        print(f"== {description}: {path} -> {out_dir / name}", flush=True)
        key = f"{name} ({description})"
        timings[key] = _run_part(path, out_dir / name, overrides, key, record, executor)
    tuning, beyond = (experiments / f"{name}.yaml" for name, _ in TUNED_PARTS)
    tuning_sized = _capped(tuning, large_seeds, engine_episodes)
    beyond_sized = _capped(beyond, beyond_seeds, engine_episodes)
    _check_disjoint(tuning, tuning_sized, beyond, beyond_sized)
    description = f"ε tuned per task beyond the paper, {_seeds(tuning, tuning_sized)} seeds per value"
    print(f"== {description}: {tuning} -> {out_dir / 'tuning'}/round<k>", flush=True)
    tuned, summaries = tune_rounds(tuning, out_dir / "tuning", tuning_sized, **executor)
    timings[description] = record.part(
        description,
        sum(summary.seconds for summary in summaries),
        done_before=sum(summary.skipped for summary in summaries),
        todo=sum(summary.total - summary.skipped for summary in summaries),
    )
    chosen = ", ".join(
        f"{agent} on {task}: {t.best:g}{'' if t.interior else ' (edge)'}" for (task, agent), t in tuned.items()
    )
    print(f"   {len(summaries)} round(s), {timings[description]:.1f} s; chosen: {chosen}", flush=True)
    description = f"static grid, moving and evading prey, mazes, {_seeds(beyond, beyond_sized)} seeds"
    print(f"== {description}: {beyond} -> {out_dir / 'beyond'}", flush=True)
    summary = run_sweep(beyond, out_dir / "beyond", overrides=[*beyond_sized, *_tuned(beyond, tuned)], **executor)
    timings[description] = record.part(
        description, summary.seconds, done_before=summary.skipped, todo=summary.total - summary.skipped
    )
    print(f"   {summary.total} runs, {summary.skipped} already done, {summary.seconds:.1f} s", flush=True)
    start = time.perf_counter()
    extra = report_section(out_dir / "forensics")  # the forensics' section, when the folder holds its results
    report = build_report(out_dir, timings=timings, extra_sections=[extra] if extra is not None else [],
                          command=command or " ".join(sys.argv))
    timings["report"] = time.perf_counter() - start
    total = record.finish(timings["report"])
    print("wall time: " + ", ".join(f"{name} {seconds:.1f} s" for name, seconds in timings.items()))
    print(f"report step {timings['report']:.1f} s, total {total:.1f} s (both in {record.path})")
    print(f"report: {report} (and {report.with_suffix('.html')})")
    return report


def _run_part(path: Path, folder: Path, overrides: list[str], key: str, record: _Record, executor: dict[str, Any]) -> float:
    """
    Run one part's study file into ``folder`` on ``executor`` (``run_sweep``'s workers, backend, ray_address), as
    ``sb3-affect run`` runs it (``running.run_file``). Prints what it did.

    :return: the part's time as ``record`` keeps it under ``key``
    """
    done = run_file(path, folder, overrides, **executor)
    print(f"   {done.finished} runs now, {done.skipped} already done, {done.failed} failed, {done.seconds:.1f} s", flush=True)
    return record.part(key, done.seconds, done_before=done.skipped, todo=done.finished + done.failed)


def tune_rounds(
    path: Path, folder: Path, overrides: list[str], workers: int | None = None, **executor: Any
) -> tuple[dict[tuple[str, str], Any], list[Any]]:
    """
    The per-task tuning (``launcher.epsilon_tuning.tune``) through the launcher: the sweep file ``path`` into
    ``folder/round0``, then each extension round's values into ``folder/round<k>`` (the file's agents that still need a
    value, each on those tasks only: ``grid_by_task``). Finished rounds are resumed (nothing left to run).

    :param overrides: ``--set`` overrides of every round (its size)
    :param executor: ``run_sweep``'s ``backend`` and ``ray_address``
    :return: the tuning of each (task, agent), and the launcher's summary of each round
    """

    data = yaml.safe_load(Path(path).read_text())
    agents = data["agents"]
    label, grid = tuning_grid(data)
    summaries = []

    def run_round(k: int, values: dict[tuple[str, str], list[float]]) -> Any:
        round_agents = []
        for agent in agents:
            by_task = {task: {label: eps} for (task, name), eps in values.items() if name == agent["name"]}
            if by_task:
                round_agents.append({**{key: v for key, v in agent.items() if key != "grid"}, "grid_by_task": by_task})
        extra = [f"agents={json.dumps(round_agents)}"] if k else []
        summaries.append(run_sweep(path, folder / f"round{k}", workers=workers, overrides=[*overrides, *extra], **executor))
        found = folder_study(folder / f"round{k}")
        if found is None or round_values(found[0]) != values:
            raise RuntimeError(f"{folder / f'round{k}'} does not hold every run of the round ({summaries[-1].failed} failed)")
        return found[0]

    choices, _ = tune(run_round, [(task, agent["name"]) for task in data["tasks"] for agent in agents], grid)
    return choices, summaries


def _tuned(path: Path, tuned: dict[tuple[str, str], Any]) -> list[str]:
    """The ``--set`` overrides that give each agent of sweep file ``path`` tuned in ``tuned`` its ε on each task."""
    agents = yaml.safe_load(Path(path).read_text())["agents"]
    overrides = []
    for i, agent in enumerate(agents):
        by_task = {task: {"epsilon": [t.best]} for (task, name), t in tuned.items() if name == agent["name"]}
        if by_task:
            overrides.append(f"agents.{i}.grid_by_task={json.dumps(by_task)}")
    return overrides


def _check_disjoint(tuning: Path, tuning_sized: list[str], beyond: Path, beyond_sized: list[str]) -> None:
    """Refuse a tuning whose seeds for a task and agent are also evaluation seeds of that task and agent."""

    seeds: dict[tuple[Any, ...], set[int]] = {}
    for cell in load_sweep(tuning, tuning_sized, build=False).cells():
        seeds.setdefault((cell.base["agent"], cell.base["labels"].get("task")), set()).update(cell.seeds)
    for cell in load_sweep(beyond, beyond_sized, build=False).cells():
        shared = seeds.get((cell.base["agent"], cell.base["labels"].get("task")), set()) & set(cell.seeds)
        if shared:
            raise ValueError(f"{tuning} and {beyond} share seeds of {cell.base['agent']}: {sorted(shared)[:5]}")


def _capped(path: Path, seeds: int | None, episodes: int | None) -> list[str]:
    """The ``--set`` overrides of a sweep file for a quick check: its seeds capped at ``seeds``, its episodes ``episodes``."""
    data = yaml.safe_load(path.read_text())
    overrides = [] if seeds is None else [f"seeds={min(int(data['seeds']), seeds)}"]
    return overrides + ([] if episodes is None else [f"episodes={episodes}"])


def _seeds(path: Path, overrides: list[str]) -> int:
    """The seeds per cell of sweep file ``path`` under ``overrides`` (``_capped``)."""
    given = [int(o.split("=", 1)[1]) for o in overrides if o.startswith("seeds=")]
    return given[-1] if given else int(yaml.safe_load(path.read_text())["seeds"])


def _sized(
    name: str, path: Path, large_seeds: int | None, ablation_seeds: int | None, episodes: int | None
) -> list[str]:
    """
    The ``--set`` overrides of a ``SIZED`` part for a quick check: its seeds capped at ``ablation_seeds`` (``ablation``)
    or ``large_seeds`` (the others), its episodes ``episodes`` (``long``: 10 x as many). None: the file's own size.
    """
    size = next((study.size for study in STUDIES if study.name == name), None)
    cap = ablation_seeds if size == "ablation" else large_seeds
    return _capped(path, cap, None if episodes is None else episodes * (10 if size == "long" else 1))


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
            saved = read_json(self.path, MAX_SWEEP_FILE_BYTES)
        except UnreadableFile as error:
            if error.reason != "does not exist":
                raise StoreError(f"{error}; {self.path.name} is the record replicate writes: move it away") from None
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

    def finish(self, report_seconds: float) -> float:
        """Record this run's report step and its total wall time; the total."""
        self.runs[-1]["report"] = report_seconds
        self.runs[-1]["total"] = time.perf_counter() - self.start
        self._write()
        return float(self.runs[-1]["total"])

    def _write(self) -> None:
        write_file(self.path, json.dumps({"timings": self.timings, "runs": self.runs}, indent=1))

