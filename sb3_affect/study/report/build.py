"""
``build_report``: the replication report from a results folder (the paper sweep) or a ``replicate`` folder
(paper/, dqn/, ablation/, baselines*/, beyond/, large/, minigrid*/, ...), or a deep study's folder.

The report is the one list ``REPORT`` of section functions, each ``section(ctx: ReportContext) -> None`` adding its
blocks to ``ctx.doc`` (see ``report.reading.context``), in order: the main text, then each appendix page (a ``part``
starts one). To add a section, write the function in its own module and put it in ``REPORT`` where it should stand (or
pass ``sections=`` to ``build_report``); a layer above the report (the forensics, wired by ``sb3_affect.study.replicate``)
passes its own with ``extra_sections=``, placed at ``extra_slot`` (on a page of its own). Every folder is read one way
(``load_results``); the records it holds choose the sections: a folder without paper runs (a deep study's, whose
chunks hold evaluations) gives only the sections of ``WITHOUT_PAPER_RUNS``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from pathlib import Path

import gymnasium as gym
import pandas as pd

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect.core.settings import TabularSettings
from sb3_affect.study.launcher.chunks import EPISODES
from sb3_affect.study.launcher.one_run import package_env
from sb3_affect.study.launcher.store import ResultsStore
from sb3_affect.study.report.reading import study_tables as engine_studies
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.reading.episode_scan import scan
from sb3_affect.study.report.reading.run_tables import EARLY_WINDOWS, LATE_WINDOWS, load_results
from sb3_affect.study.report.rendering.document import MAIN_PAGE, Document, fmt
from sb3_affect.study.report.rendering.output_files import output_folder, write_text
from sb3_affect.study.report.sections.ablation import ablation_section
from sb3_affect.study.report.sections.abstract import abstract_section
from sb3_affect.study.report.sections.beyond import beyond_section
from sb3_affect.study.report.sections.deep_minigrid import deep_minigrid_section
from sb3_affect.study.report.sections.dqn import dqn_section, learning_curves_section
from sb3_affect.study.report.sections.emotion_models import emotion_models_sections
from sb3_affect.study.report.sections.evidence import evidence_section
from sb3_affect.study.report.sections.hunters import hunters_sections
from sb3_affect.study.report.sections.lead_sources import lead_section
from sb3_affect.study.report.sections.limitations import limitations_section
from sb3_affect.study.report.sections.main_finding import main_finding_section
from sb3_affect.study.report.sections.mechanism import fig5_section, mechanism_section
from sb3_affect.study.report.sections.minigrid import FOLDERS as MINIGRID_FOLDERS
from sb3_affect.study.report.sections.minigrid import minigrid_sections
from sb3_affect.study.report.sections.paper_tables import figures_3_4_section, table_iv_section, table_v_section
from sb3_affect.study.report.sections.project_checks import checks_section
from sb3_affect.study.report.sections.protocol_draw import protocol_draw_section
from sb3_affect.study.report.sections.readings import readings_section
from sb3_affect.study.report.sections.reproducibility import record_section
from sb3_affect.study.report.sections.speed_ablation import speed_one_section, speed_table_section
from sb3_affect.study.report.sections.survival import survival_section
from sb3_affect.study.report.sections.verdict import tests_section, verdict_section
from sb3_affect.study.report.sections.window_verdicts import windows_section
from sb3_affect.study.studies import STUDIES

Section = Callable[[ReportContext], None]
#: Sub-folders of a replicate folder the sections may read (``ctx.folders[name]``): every study's (``studies.STUDIES``)
#: besides the paper's, the MiniGrid sections' and the folders of earlier baselines sweeps.
FOLDERS = tuple(dict.fromkeys((
    "dqn", "ablation", "baselines", "baselines_moving7", "baselines_moving", "beyond", "hunters", "hunters_moving",
    *(name for name, _, _ in MINIGRID_FOLDERS), *(study.name for study in STUDIES if study.name != "paper"),
)))  # fmt: skip


def overview_section(ctx: ReportContext) -> None:
    m = ctx.metrics
    ctx.doc.h("Overview")
    runs = m.groupby("agent").run_id.count().to_dict()
    eps = sorted(m.epsilon.dropna().unique()) if "epsilon" in m.columns else []
    ctx.doc.p(
        f"Results folder `{ctx.paper.folder}`: {len(m)} runs ({', '.join(f'{a}: {n}' for a, n in runs.items())}), "
        f"up to {int(m.episodes.max())} episodes each, ε values {', '.join(fmt(e, 1) for e in eps) or 'none'}. "
        "A *step* is one decision (one unit of time; the paper's Sec. IV also calls a cell moved a step); *cells* are "
        "one-cell moves (the affective agent moves 1 or 2 cells per decision under the verdict's reading; 0 needs an "
        "emotion that reading never produces). The paper's numbers are quoted verbatim with their table, figure or "
        "section; every other number is computed from the run files by `sb3-affect report`."
    )
    refusal = ctx.verdict_refusal()
    if refusal:
        ctx.doc.p(f"**Too few runs for a verdict**: {refusal}. The tables below are descriptive only.")
    cap, shortest = task_facts(ctx.paper.folder)
    ctx.cache["shortest path"] = shortest
    cap_text = f"{cap:,} decisions" if cap else "the agents' cap"
    ctx.doc.p(f"Episodes truncated by the safety cap ({cap_text}): {int(m.truncated.sum())}.")


def task_facts(folder: Path) -> tuple[int | None, int | None]:
    """The safety cap on an episode's decisions and the task's shortest path in cells, from the sweep's own file."""

    saved = ResultsStore(folder).saved_sweep()
    if saved is None:
        return None, None
    sweep = saved["sweep"]
    default = TabularSettings.max_episode_decisions
    caps = {int(a.get("kwargs", {}).get("max_episode_decisions", default)) for a in sweep["agents"]}
    shortest = None
    if not package_env(sweep["env"].get("id")):  # only the package's own envs are built: a folder's id is never imported
        return (caps.pop() if len(caps) == 1 else None), None
    try:
        env = gym.make(sweep["env"]["id"], **sweep["env"].get("kwargs", {}))
        length = getattr(env.unwrapped, "shortest_path_length", None)
        shortest = None if length is None else int(length)
        env.close()
    except Exception:  # an env the report can not build: the fact is left out, not guessed
        shortest = None
    return (caps.pop() if len(caps) == 1 else None), shortest


def _if_paper_agents(section: Section) -> Section:
    @functools.wraps(section)
    def wrapped(ctx: ReportContext) -> None:
        if ctx.has_paper_agents:
            section(ctx)

    return wrapped


def agents_section(ctx: ReportContext) -> None:
    if ctx.has_paper_agents:
        return
    ctx.doc.p(
        "The paper's comparison needs both agents `epsilon-greedy` and `affective` with an `epsilon` label; this folder "
        f"has agents {sorted(ctx.metrics.agent.unique())}: only the summary below is shown."
    )
    summary = ctx.metrics.groupby([k for k in ("agent", "epsilon") if k in ctx.metrics.columns]).agg(
        runs=("run_id", "count"),
        decisions_per_episode=("decisions_per_episode", "mean"),
        first_optimal=("first_optimal", "mean"),
        never_optimal=("censored", "sum"),
        decisions_before_optimal=("decisions_before_optimal", "mean"),
    )
    ctx.table("agents", summary, "Per-agent summary (means over runs)")




def definitions_section(ctx: ReportContext) -> None:
    ctx.doc.h("Definitions")
    shortest = ctx.cache.get("shortest path")
    ctx.doc.ul(
        [
            "Steps per episode: mean decisions per episode.",
            "Optimal path (walked): an episode whose path from start to goal is a shortest path"
            + (f" ({shortest} cells on this task)." if shortest else "."),
            "Steps before the optimal path (walked): decisions summed over the episodes before the first optimal one "
            "(all decisions for runs that never find it: censored).",
            "Greedy stays optimal from: the first episode after which every greedy choice from the start walks a shortest "
            "path until the end of the run; steps until then: decisions of episodes 1 to that one.",
            "Equivalent ε: fraction of decisions whose direction was random (joy), per episode.",
            "The appraisal: norm, the power-law fit of past episode lengths at this episode; exp1 = max(norm, elapsed), "
            "the paper's \"initially equal to the average value, and increments every step past the average\" (not "
            "the steps of the last episode); act = elapsed + the shortest known remaining path.",
            "Emotion shares (the joy share, for example), four estimators, each number tagged with its name: *mean of "
            "per-episode fractions* (each episode counts once); *decision-weighted per run* (each run's decisions "
            "pooled in the window, then averaged over runs: the verdict's Fig. 5 and four-emotions rows and the "
            "readings table); *decision-weighted, pooled per episode* (each episode number's decisions pooled over "
            "runs, then averaged over the window's episodes: Fig. 5's right panel and the profile windows table); "
            "*fully pooled* (every decision of every run in the window: the mechanism section).",
        ]
    )


def part(name: str, title: str, heading: str = "") -> Section:
    """A section that starts the page ``name`` (an appendix of its own, linked from the main text; ``Document.part``)."""

    def start(ctx: ReportContext) -> None:
        ctx.doc.part(name, title)
        if heading:
            ctx.doc.p(heading)

    start.__name__ = f"part_{name}"
    return start


def extra_slot(ctx: ReportContext) -> None:
    """Where ``build_report(extra_sections=...)`` places the sections of layers above the report (a no-op itself)."""


#: The page the sections of layers above the report start (``build_report(extra_sections=...)``: the forensics).
EXTRA_PART = part("appendix-forensics", "Appendix C: replication forensics")

#: The report in order: the main text, what a referee reads in one sitting (``report.md``), then the appendix pages,
#: each started by a ``part``. The one list of the report's sections.
REPORT: list[Section] = [
    abstract_section,
    overview_section,
    agents_section,
    verdict_section,
    main_finding_section,
    lead_section,
    speed_one_section,
    mechanism_section,
    limitations_section,
    part(
        "appendix-paper",
        "Appendix A: the paper's tables and figures, the readings, time to the optimal path",
        "The paper's Tables IV and V and Figs. 3-6 beside ours, the verdict under every reading of the appraisal, the "
        "windows of Figs. 5 and 6, the first optimal episode as time-to-event data and the learning curves.",
    ),
    readings_section,
    windows_section,
    fig5_section,
    _if_paper_agents(table_iv_section),
    _if_paper_agents(table_v_section),
    _if_paper_agents(figures_3_4_section),
    survival_section,
    learning_curves_section,
    part(
        "appendix-checks",
        "Appendix B: the project's checks and the studies beyond the paper",
        "The speed ablation in full, the protocol's draw against the large-N blocks, rliable's measures and the "
        "performance profiles, tasks beyond the paper and fair baselines, two hunters, MiniGrid and the reading ablation.",
    ),
    speed_table_section,
    protocol_draw_section,
    checks_section,
    beyond_section,
    hunters_sections,
    minigrid_sections,
    deep_minigrid_section,
    ablation_section,
    extra_slot,
    part(
        "appendix-record",
        "Appendix D: the verdict's tests, seed counts, DQN, the second emotion model, the record and the definitions",
        "The long tables behind the verdict: every test with raw and Holm-adjusted p-values, the seed-count study, "
        "AdaStop, DQN, the second emotion model, the reproducibility record and the definitions.",
    ),
    tests_section,
    evidence_section,
    dqn_section,
    emotion_models_sections,
    record_section,
    definitions_section,
]
#: The sections of ``REPORT`` that read no paper runs (each finds its own folders through the store): the only ones a
#: folder without paper runs gives (a deep study's own folder: its section alone).
WITHOUT_PAPER_RUNS = frozenset({deep_minigrid_section})


def _layout(run_dir: Path) -> tuple[Path, dict[str, Path]]:
    """The paper sweep's folder and the other results folders of a replicate folder (or a single results folder)."""
    if not (run_dir / "runs").is_dir() and (run_dir / "paper" / "runs").is_dir():
        folders = {name: run_dir / name for name in FOLDERS if (run_dir / name / "runs").is_dir()}
        return run_dir / "paper", folders
    if not (run_dir / "runs").is_dir():
        raise FileNotFoundError(f"{run_dir} holds no results: expected {run_dir / 'runs'} (or paper/runs from replicate)")
    return run_dir, {}


def folder_notes(folders: Sequence[Path]) -> list[str]:
    """
    One line per results folder whose sweep is not complete (the report covers the runs it holds); ``ValueError``
    when a launcher is still writing one (its runs would change under the report).
    """

    notes = []
    for folder in folders:
        store = ResultsStore(folder)
        owner = store.lock_owner()
        if owner is not None:
            raise ValueError(f"{folder} is in use by a launcher (pid {owner}) still running its sweep; report when it is done")
        try:
            name, counts, _ = store.progress()
        except FileNotFoundError:
            continue
        total, done = sum(c[0] for c in counts.values()), sum(c[1] for c in counts.values())
        if done < total:
            notes.append(f"Incomplete: {folder} holds {done:,} of the {total:,} runs of sweep {name!r} (reported here).")
    return notes


def build_report(
    run_dir: Path,
    out: Path | None = None,
    dqn_dir: Path | None = None,
    ablation_dir: Path | None = None,
    sections: Sequence[Section] | None = None,
    timings: dict[str, float] | None = None,
    extra_sections: Sequence[Section] = (),
    command: str = "",
) -> Path:
    """
    Write ``report.md``, ``report.html`` (self-contained), ``tables/*.csv`` and ``figures/*.png``.

    :param run_dir: a results folder of the paper sweep, or a ``replicate`` folder holding paper/, dqn/, ..., or a deep
        study's folder (no paper runs: the sections of ``WITHOUT_PAPER_RUNS`` alone)
    :param out: where to write (default: ``run_dir``)
    :param dqn_dir: results of experiments/dqn.yaml (default: ``run_dir/dqn`` when present)
    :param ablation_dir: results of experiments/ablation.yaml (default: ``run_dir/ablation`` when present)
    :param sections: the sections in order (default: ``REPORT``, ``extra_sections`` at its ``extra_slot``)
    :param timings: wall seconds of each part of the run that produced the folder (reproducibility record)
    :param extra_sections: sections from layers above the report (e.g. the forensics), placed before the appendix;
        each may set ``ctx.cache["forensics"]`` to say what it included (reproducibility record)
    :param command: the command line that produced the folder (reproducibility record)
    :return: the path of report.md
    """
    run_dir = Path(run_dir)
    paper_dir, folders = _layout(run_dir)
    if dqn_dir is not None:
        folders["dqn"] = Path(dqn_dir)
    if ablation_dir is not None:
        folders["ablation"] = Path(ablation_dir)
    notes = folder_notes([paper_dir, *folders.values()])
    out = Path(out or run_dir)
    output_folder(out / "tables")
    output_folder(out / "figures")
    results = load_results(paper_dir)
    held = results.kinds  # what the folder's records allow: paper runs (episodes), a deep study's evaluations
    paper = EPISODES in held
    if not held or (paper and not int(results.runs.episodes.sum())):
        raise ValueError(f"{paper_dir / 'runs'} holds no finished runs")
    found = scan(results, (*EARLY_WINDOWS, *LATE_WINDOWS)) if paper else None  # one pass over the episode rows, by parts
    large, meta = engine_studies.study(run_dir, "large") or (None, None)
    title = "Q-Learning with Basic Emotions: a replication study" if paper else f"Deep agents on MiniGrid: {run_dir.name}"
    ctx = ReportContext(
        Document(title),
        out,
        run_dir,
        results,
        found.metrics if found is not None else pd.DataFrame(),
        folders=folders,
        large=large,
        large_meta=meta,
        timings=dict(timings or {}),
        command=command,
        cache={"scan": found} if found is not None else {},
    )
    del found
    for note in notes:
        ctx.doc.p(note)
    extra = [EXTRA_PART, *extra_sections] if extra_sections else []
    for section in sections if sections is not None else REPORT:
        if not paper and section not in WITHOUT_PAPER_RUNS:  # (extra_slot too: the extras read the paper runs)
            continue
        for placed in extra if section is extra_slot else [section]:
            placed(ctx)
    ctx.place_later()
    return _write_pages(ctx)


def _write_pages(ctx: ReportContext) -> Path:
    """Write the document's Markdown and HTML pages into ``ctx.out``; the path of the main page's Markdown."""
    for name, text in ctx.doc.markdown_pages(ctx.out).items():
        write_text(ctx.out / name, text)
    for name, text in ctx.doc.html_pages().items():
        write_text(ctx.out / name, text)
    return ctx.out / f"{MAIN_PAGE}.md"

