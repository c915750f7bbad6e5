"""
``build_report``: the replication report from a results folder (the paper sweep) or a ``replicate`` folder
(paper/, dqn/, ablation/, baselines*/, beyond/, large/, minigrid*/, ...).

The report is the list ``SECTIONS`` of section functions, each ``section(ctx: ReportContext) -> None`` adding its
blocks to ``ctx.doc`` (see ``report.context``): the main text, then ``APPENDIX``. To add a section, write the function
in its own module and append it to ``SECTIONS`` (or pass ``sections=`` to ``build_report``); a layer above the report
(the forensics, wired by ``sb3_affect.study.replicate``) passes its own with ``extra_sections=``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from sb3_affect.study.report import engine_studies
from sb3_affect.study.report.ablation import ablation_section
from sb3_affect.study.report.abstract import abstract_section
from sb3_affect.study.report.baselines_section import beyond_section
from sb3_affect.study.report.checks import checks_section
from sb3_affect.study.report.context import ReportContext
from sb3_affect.study.report.deep_minigrid import deep_minigrid_section
from sb3_affect.study.report.document import APPENDIX_HEADING, Document, fmt
from sb3_affect.study.report.dqn import dqn_section, learning_curves_section
from sb3_affect.study.report.evidence import evidence_section
from sb3_affect.study.report.mechanism import mechanism_section
from sb3_affect.study.report.metrics import EARLY_WINDOWS, LATE_WINDOWS, load_results, run_metrics
from sb3_affect.study.report.minigrid import FOLDERS as MINIGRID_FOLDERS
from sb3_affect.study.report.minigrid import minigrid_sections
from sb3_affect.study.report.output_files import output_folder, write_text
from sb3_affect.study.report.reading_verdicts import readings_section
from sb3_affect.study.report.record import record_section
from sb3_affect.study.report.scan import scan
from sb3_affect.study.report.speed_ablation import speed_one_section
from sb3_affect.study.report.survival import survival_section
from sb3_affect.study.report.tables import figures_3_4_section, table_iv_section, table_v_section
from sb3_affect.study.report.verdict import tests_section, verdict_section
from sb3_affect.study.report.windows import windows_section

Section = Callable[[ReportContext], None]
#: Sub-folders of a replicate folder the sections may read (``ctx.folders[name]``).
FOLDERS = ("dqn", "ablation", "baselines", "baselines_moving7", "baselines_moving", "beyond", "hunters", "hunters_moving",
           *(name for name, _, _ in MINIGRID_FOLDERS))
#: Two-hunter results folders (experiments/hunters*.yaml): two hunters, and the two emotion models side by side.
HUNTER_FOLDERS = ("hunters", "hunters_moving")


def overview_section(ctx: ReportContext) -> None:
    m = ctx.metrics
    ctx.doc.h("Overview")
    runs = m.groupby("agent").run_id.count().to_dict()
    eps = sorted(m.epsilon.dropna().unique()) if "epsilon" in m.columns else []
    ctx.doc.p(
        f"Results folder `{ctx.paper.folder}`: {len(m)} runs ({', '.join(f'{a}: {n}' for a, n in runs.items())}), "
        f"up to {int(m.episodes.max())} episodes each, ε values {', '.join(fmt(e, 1) for e in eps) or 'none'}. "
        "A *step* is one decision (one unit of time), as in the paper; *cells* are one-cell moves (the affective "
        "agent moves 0, 1 or 2 cells per decision). The paper's numbers are quoted verbatim with their table, figure "
        "or section; every other number is computed from the run files by `sb3-affect report`."
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
    from sb3_affect.core.settings import TabularSettings
    from sb3_affect.study.launcher.one_run import package_env
    from sb3_affect.study.launcher.store import ResultsStore

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
        import gymnasium as gym

        import sb3_affect  # noqa: F401  (registers the envs)

        env = gym.make(sweep["env"]["id"], **sweep["env"].get("kwargs", {}))
        length = getattr(env.unwrapped, "shortest_path_length", None)
        shortest = None if length is None else int(length)
        env.close()
    except Exception:  # an env the report can not build: the fact is left out, not guessed
        shortest = None
    return (caps.pop() if len(caps) == 1 else None), shortest


def _if_paper_agents(section: Section) -> Section:
    def wrapped(ctx: ReportContext) -> None:
        if ctx.has_paper_agents:
            section(ctx)

    wrapped.__name__ = section.__name__
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


def _hunter_dirs(ctx: ReportContext) -> list[Path]:
    dirs = [ctx.root / name for name in HUNTER_FOLDERS if (ctx.root / name / "runs").is_dir()]
    if "team" in ctx.paper.runs.columns or (ctx.paper.runs.algo == "team").any():  # a single folder of team runs
        dirs.append(ctx.paper.folder)
    return dirs


def hunters_sections(ctx: ReportContext) -> None:
    """The two-hunter section, when a folder holds team runs."""
    from sb3_affect.study.report.hunters import hunters_section

    dirs = _hunter_dirs(ctx)
    if dirs:
        _add(ctx, *hunters_section(dirs, ctx.out))


def emotion_models_sections(ctx: ReportContext) -> None:
    """The two emotion models side by side on the two-hunter runs (appendix)."""
    from sb3_affect.study.report.emotion_models import emotion_models_section

    dirs = _hunter_dirs(ctx)
    if dirs:
        _add(ctx, *emotion_models_section(dirs, ctx.out))


def _add(ctx: ReportContext, text: str, images: list[tuple[Path, str]]) -> None:
    ctx.doc.md(text)
    for path, caption in images:
        ctx.doc.img(path, caption)


def appendix_heading(ctx: ReportContext) -> None:
    ctx.doc.h(APPENDIX_HEADING, 1)
    ctx.doc.p(
        "The long tables behind the verdict: every test with raw and Holm-adjusted p-values, the seed-count study, "
        "AdaStop, DQN, the second emotion model, the reproducibility record and the definitions."
    )


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
            "Emotion profile: fraction of decisions in each emotion; averaged over runs per episode (each episode "
            "counts once) or pooled over decisions (decision-weighted).",
        ]
    )


#: The main text, in order (``extra_sections`` of ``build_report`` follow it, then ``APPENDIX``).
SECTIONS: list[Section] = [
    abstract_section,
    overview_section,
    agents_section,
    verdict_section,
    readings_section,
    speed_one_section,
    windows_section,
    mechanism_section,
    _if_paper_agents(table_iv_section),
    _if_paper_agents(table_v_section),
    _if_paper_agents(figures_3_4_section),
    survival_section,
    checks_section,
    learning_curves_section,
    beyond_section,
    hunters_sections,
    minigrid_sections,
    deep_minigrid_section,
    ablation_section,
]
#: The appendix, in order.
APPENDIX: list[Section] = [
    appendix_heading,
    tests_section,
    evidence_section,
    dqn_section,
    emotion_models_sections,
    record_section,
    definitions_section,
]


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
    from sb3_affect.study.launcher.store import ResultsStore

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

    :param run_dir: a results folder of the paper sweep, or a ``replicate`` folder holding paper/, dqn/, ...
    :param out: where to write (default: ``run_dir``)
    :param dqn_dir: results of experiments/dqn.yaml (default: ``run_dir/dqn`` when present)
    :param ablation_dir: results of experiments/ablation.yaml (default: ``run_dir/ablation`` when present)
    :param sections: the sections in order (default: ``SECTIONS``, then ``extra_sections``, then ``APPENDIX``)
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
    if not len(results.runs) or not int(results.runs.episodes.sum()):
        raise ValueError(f"{paper_dir / 'runs'} holds no finished runs")
    found = scan(results, (*EARLY_WINDOWS, *LATE_WINDOWS))  # one pass over the episode rows, by parts
    large, meta = engine_studies.study(run_dir, "large") or (None, None)
    ctx = ReportContext(
        Document("Q-Learning with Basic Emotions: a replication study"),
        out,
        run_dir,
        results,
        found.metrics,
        folders=folders,
        large=large,
        large_meta=meta,
        timings=dict(timings or {}),
        command=command,
        cache={"scan": found},
    )
    del found
    for note in notes:
        ctx.doc.p(note)
    for section in sections if sections is not None else [*SECTIONS, *extra_sections, *APPENDIX]:
        section(ctx)
    ctx.place_later()
    md = out / "report.md"
    write_text(md, ctx.doc.markdown(out))
    write_text(out / "report.html", ctx.doc.html())
    return md


def summary_numbers(run_dir: Path) -> dict[str, float]:
    """A few headline numbers (for notes and tests)."""
    results = load_results(Path(run_dir))
    metrics = run_metrics(results.episodes)
    return {
        f"{agent} decisions_per_episode": float(group.decisions_per_episode.mean())
        for agent, group in metrics.groupby("agent")
    } | {"runs": float(len(metrics)), "censored": float(metrics.censored.sum())}
