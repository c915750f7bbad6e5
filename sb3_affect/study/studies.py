"""
The list of studies of the main job (``sb3-affect replicate``), in the order it runs them: each study's sweep file
(``experiments/<name>.yaml``, its results in ``OUT/<name>``), what the log and ``--help`` say of it (sizes read from the
file: ``{runs}``, or any top-level key of it), how ``replicate``'s quick-check sizes cut it down, the extra whose package it
needs. ``replicate`` runs this list and ``replicate --help`` prints it. To add a study: its sweep file and one entry here
(plus its section module, if it has one, placed in the report's one list of sections: ``report.build.REPORT``).

Nothing here imports the rest of the study: ``--help`` reads this list without the study's extras installed.
"""

from __future__ import annotations

import importlib.util
import math
from importlib.resources import files
from pathlib import Path
from typing import Any, NamedTuple

try:  # the experiments extra: without it the help gives no run counts or sizes (running a part says what to install)
    import yaml
except ImportError:  # pragma: no cover - the extra is installed in the tests
    yaml = None  # type: ignore[assignment]


class Study(NamedTuple):
    """One study of the main job."""

    name: str  # experiments/<name>.yaml and the results folder OUT/<name>
    description: str  # for the log and --help: {runs} and the file's top-level keys are filled in from the file
    size: str | None = None  # the quick-check size that cuts it down (``replicate.main``'s large_seeds and
    # engine_episodes: "large"; "long": 10 x the episodes; ablation_seeds: "ablation"; beyond_seeds: "beyond")
    extra: tuple[str, str] | None = None  # (package, extra) it needs: without it the study is skipped with one line
    tuned: bool = False  # run after the others, with ε tuned per task (the tuning's rounds, then the tasks beyond)


#: The studies of the main job, in order (``tuned`` ones last: the tuning, then the tasks beyond the paper).
STUDIES: tuple[Study, ...] = (
    Study("paper", "the paper's protocol ({runs} runs)"),
    Study("dqn", "SB3 DQN beside the tabular agents, equal seeds and budget ({runs} runs)"),
    Study("baselines", "fair baselines beside both paper agents"),
    Study("hunters", "two hunters on Kuremoto's pursuit problem"),
    Study("hunters_moving", "two hunters, moving prey"),
    Study("large", "large-N study: the paper's 18 cells and the speed-matched ε-greedy ({runs} runs)", size="large"),
    Study("ablation", "reading ablation: the 8 readings of the appraisal x 9 ε ({runs} runs)", size="ablation"),
    Study("speed_one", "speed ablation: the affective agent with speed fixed at 1 cell ({runs} runs)", size="large"),
    Study("long", "long runs: both paper agents, runs of 2,000 episodes ({runs} runs)", size="long"),
    Study("joy_trace", "joy trace: the paper's affective agent, each decision's emotion and act recorded ({runs} runs)"),
    Study("minigrid", "the tabular agents on MiniGrid ({runs} runs)", extra=("minigrid", "minigrid")),
    Study("deep_smoke", "the deep study at smoke size: {name}, greedy policies evaluated every {evaluation_every} env steps",
          extra=("minigrid", "minigrid")),
    Study("forensics", "replication forensics: {forensics_screen_reps} screen, {forensics_leaders} leaders x "
          "{forensics_reps} replications"),
    Study("tuning", "ε of ε-greedy and speed-matched ε-greedy tuned on each task beyond the paper: the grid ({runs} runs) "
          "in round0/, then one value further out where the best sits at an edge (round1/, ...)", size="large", tuned=True),
    Study("beyond", "static grid, moving and evading prey, mazes, with the tuned ε ({runs} runs)", size="beyond", tuned=True),
)  # fmt: skip

#: The sweeps of the main job before the tuning, in order: (name of experiments/<name>.yaml and of the results folder,
#: description).
PARTS = tuple((study.name, study.description) for study in STUDIES if not study.tuned)
#: The sweeps after ``PARTS``, in order: the tuning (its rounds in ``OUT/tuning/round<k>``), then the tasks beyond the
#: paper with the tuned ε.
TUNED_PARTS = tuple((study.name, study.description) for study in STUDIES if study.tuned)
#: Parts that need a package of an extra: (part, package, extra); without it the part is skipped with one line.
PART_PACKAGES = tuple((study.name, *study.extra) for study in STUDIES if study.extra)
#: The parts that ``replicate``'s quick-check sizes cut down (``Study.size``), the tuned ones aside.
SIZED = tuple(study.name for study in STUDIES if study.size and not study.tuned)
#: The main job's wall time on 2 idle cores, as the help and the docs quote it (measured: see the README).
MINUTES = "about 5-9 minutes"


def shipped_sweeps_folder() -> Path:
    """The folder of the sweep files installed with the package (``experiments/`` of the source tree)."""
    return Path(str(files("sb3_affect.sweeps")))


def missing_package(part: str) -> str | None:
    """What to install when a part needs a package that is not installed (``PART_PACKAGES``), else None."""
    for name, package, extra in PART_PACKAGES:
        if name == part and importlib.util.find_spec(package) is None:
            return f"{package} is not installed: pip install \"sb3-affect[{extra}]\""
    return None


def sweep_runs(path: Path) -> int | None:
    """
    How many runs an experiment file asks for: seeds x the grid points of each agent on each task (read with yaml
    alone, so the help stays fast; the launcher's ``Sweep.run_configs`` gives the same count). None when it can not be
    read.
    """
    if yaml is None:
        return None
    try:
        data = yaml.safe_load(Path(path).read_text())
        seeds = data["seeds"]
        agents = data["agents"].values() if isinstance(data["agents"], dict) else data["agents"]
        tasks = len(data.get("tasks") or [None])
        grids = [(agent["grid_by_task"].values(), 1) if "grid_by_task" in agent else ([agent.get("grid") or {}], tasks)
                 for agent in agents]  # fmt: skip
        per_agent = [sum(math.prod(len(v) for v in grid.values()) for grid in each) * times for each, times in grids]
    except (OSError, yaml.YAMLError, KeyError, TypeError, AttributeError):
        return None
    return (len(seeds) if isinstance(seeds, list) else int(seeds)) * sum(per_agent)


def part_description(name: str, description: str, experiments: Path | None = None) -> str:
    """
    A part's description with its sizes read from its sweep file in ``experiments`` (default: the shipped ones; one
    source for those numbers): ``{runs}`` (a sweep's run count), any top-level key of the file and any key of its
    sections as ``{section_key}`` (the forensics' ``{forensics_reps}``); "?" where the file can not be read.
    """
    if "{" not in description:
        return description
    path = (experiments or shipped_sweeps_folder()) / f"{name}.yaml"
    values: dict[str, Any] = {}
    try:
        data = None if yaml is None else yaml.safe_load(path.read_text())  # (without the experiments extra: no sizes)
        values.update(data if isinstance(data, dict) else {})
        values.update({f"{name}_{key}": value for name, section in values.copy().items() if isinstance(section, dict)
                       for key, value in section.items()})  # fmt: skip
    except (OSError, ValueError):
        pass
    if "{runs}" in description:
        values["runs"] = sweep_runs(path)
    return description.format_map(_Unknown({key: value for key, value in values.items() if value is not None}))


class _Unknown(dict[str, Any]):
    """``str.format_map`` values that give "?" for a key they do not hold."""

    def __missing__(self, key: str) -> str:
        return "?"
