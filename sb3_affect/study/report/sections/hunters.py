"""
The report's two-hunter section: affective, epsilon-greedy and mixed teams of independent learners on
Kuremoto's pursuit problem (static prey) and on a random-walking prey, with bootstrap CIs and a verdict.

Entry point: ``hunters_section(run_dirs, out) -> (markdown, [(figure path, caption)])``; ``run_dirs`` are results
folders of team sweeps (``experiments/hunters.yaml``, ``experiments/hunters_moving.yaml``). Definitions (rounds, the
team's optimal capture) are in ``sb3_affect.agents.hunter_team`` and docs/hunters.md.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.study.launcher.folder_files import MAX_RUN_FILE_BYTES
from sb3_affect.study.launcher.regular_files import read_json
from sb3_affect.study.report.estimation.bootstrap import (
    BETTER,
    WORSE,
    bootstrap_ci,
    bootstrap_improvement,
    improvement_outcome,
)
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.figures import COLOURS, distinct, plt
from sb3_affect.study.report.rendering.output_files import output_folder, replacing

#: Two-hunter results folders (experiments/hunters*.yaml): two hunters, and the two emotion models side by side.
HUNTER_FOLDERS = ("hunters", "hunters_moving")
BASELINE = "epsilon-greedy"
LATE = 20  # the last episodes, for "after learning"


def _column(values: list[Any]) -> np.ndarray:
    """A record's column as an array (None, JSON's NaN, as NaN): a tenth of the memory of a list of Python numbers."""
    return np.asarray(values, dtype=float) if None in values else np.asarray(values)


#: The last ``team_runs`` answer, by the files it read (their names, sizes and modification times): the report's two
#: sections on the same runs read them once.
_LAST: dict[tuple[Any, ...], list[dict[str, Any]]] = {}


def team_runs(run_dirs: Sequence[str | Path]) -> list[dict[str, Any]]:
    """
    Every finished team run (a run file whose config has ``team``) of the folders (``DIR/runs/*.json``), its episode
    columns as NumPy arrays (8,000 runs of 200 episodes: under 1 GB, against about 3 GB as lists).
    """
    paths = [path for folder in run_dirs for path in sorted((Path(folder) / "runs").glob("[!.]*.json"))]
    key = tuple((str(path), path.stat().st_mtime_ns, path.stat().st_size) for path in paths)
    if key in _LAST:
        return _LAST[key]
    runs = []
    for path in paths:
        record = read_json(path, MAX_RUN_FILE_BYTES)
        if record.get("status", "ok") == "ok" and "team" in record.get("config", {}):
            record["episodes"] = {name: _column(values) for name, values in record["episodes"].items()}
            runs.append(record)
    _LAST.clear()
    _LAST[key] = runs
    return runs


def markdown_table(frame: pd.DataFrame) -> str:
    """A plain Markdown table (cells as given; floats with 2 decimals, whole numbers with thousands separators)."""

    def cell(value: Any) -> str:
        if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
            return f"{value:,}"
        return f"{value:,.2f}" if isinstance(value, float) else str(value)

    lines = ["| " + " | ".join(map(str, frame.columns)) + " |", "|" + "---|" * len(frame.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in frame.itertuples(index=False)]
    return "\n".join(lines)


def describe_team(config: dict[str, Any]) -> str:
    """``AffectQ + QLearning(eps 0.1)``: the members in hunter order."""
    names = []
    for member in config["team"]:
        eps = member["kwargs"].get("exploration_rate")
        names.append(member["algo"].rpartition(":")[2] + (f"(eps {eps})" if eps is not None else ""))
    return " + ".join(names)


def team_metrics(record: dict[str, Any]) -> dict[str, Any]:
    """One team run: decisions (rounds) per episode, late ones, steps before the first optimal capture, capture shares."""
    episodes = record["episodes"]
    decisions = np.asarray(episodes["decisions"], dtype=float)
    optimal = np.asarray([bool(v) for v in episodes["optimal"]])
    first = int(np.argmax(optimal)) + 1 if optimal.any() else math.nan
    before = decisions[: first - 1].sum() if optimal.any() else decisions.sum()
    capturer = np.asarray(episodes["capturer"])
    return {
        "task": record["config"]["sweep"],
        "team": record["config"]["agent"],
        "members": describe_team(record["config"]),
        "seed": record["config"]["seed"],
        "decisions_per_episode": decisions.mean(),
        "late_decisions": decisions[-LATE:].mean(),
        "steps_before_optimal": before,
        "first_optimal": first,
        "censored": not optimal.any(),
        "hunter_0_captures": float((capturer == 0).mean()),
    }


def _ci(values: Any, digits: int = 1) -> str:
    mean, low, high = bootstrap_ci(np.asarray(values, dtype=float))
    return f"{mean:,.{digits}f} [{low:,.{digits}f}, {high:,.{digits}f}]"


def summary_table(metrics: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (task, team), group in metrics.groupby(["task", "team"], sort=False):
        rows.append(
            {
                "task": task,
                "team": team,
                "hunter_0 + hunter_1": group.members.iloc[0],
                "runs": len(group),
                "decisions per episode": _ci(group.decisions_per_episode),
                f"last {LATE} episodes": _ci(group.late_decisions),
                "steps before the first optimal capture": _ci(group.steps_before_optimal, 0),
                "never optimal": int(group.censored.sum()),
                "captures by hunter_0": f"{group.hunter_0_captures.mean():.2f}",
            }
        )
    return pd.DataFrame(rows)


def _improvement(a: pd.Series, b: pd.Series) -> tuple[float, float, float]:
    return bootstrap_improvement(a.to_numpy(dtype=float), b.to_numpy(dtype=float))


def claims(metrics: pd.DataFrame) -> list[tuple[str, bool, str]]:
    """(claim, supported, evidence) for each team against the epsilon-greedy team, per task and metric."""
    out = []
    for task, group in metrics.groupby("task", sort=False):
        base = group[group.team == BASELINE]
        if base.empty:
            continue
        for team in [t for t in group.team.unique() if t != BASELINE]:
            ours = group[group.team == team]
            for column, what in (
                ("decisions_per_episode", "decisions per episode"),
                ("late_decisions", f"decisions per episode in the last {LATE} episodes"),
                ("steps_before_optimal", "steps before the team's first optimal capture"),
            ):
                p, low, high = _improvement(ours[column], base[column])
                a, b = ours[column].mean(), base[column].mean()
                outcome = improvement_outcome(low, high)
                supported = outcome == BETTER
                reading = {BETTER: "", WORSE: " (the epsilon-greedy team is better)"}.get(outcome, " (no clear difference)")
                evidence = f"{a:,.1f} vs {b:,.1f}; P({team} better) = {p:.2f} [{low:.2f}, {high:.2f}]{reading}"
                out.append((f"{task}: the {team} team needs fewer {what} than the epsilon-greedy team", supported, evidence))
    return out


def learning_figure(runs: list[dict[str, Any]], path: Path) -> Path:
    """Decisions (rounds) per episode, mean over runs with a 95% bootstrap band per 10-episode block, per task."""

    tasks = sorted({r["config"]["sweep"] for r in runs})
    # one colour per team in every panel: the paper agents' own colours, the other teams by name
    names = sorted({str(r["config"]["agent"]) for r in runs})
    others = [name for name in names if name not in COLOURS]
    colour = {name: COLOURS.get(name) or distinct(len(others))[others.index(name)] for name in names}
    fig, axes = plt.subplots(1, len(tasks), figsize=(6.0 * len(tasks), 4.0), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        teams = list(dict.fromkeys(r["config"]["agent"] for r in runs if r["config"]["sweep"] == task))
        for team in sorted(teams):
            curves = np.array(
                [r["episodes"]["decisions"] for r in runs if r["config"]["sweep"] == task and r["config"]["agent"] == team]
            )
            width = min(10, curves.shape[1]) or 1  # runs of fewer than 10 episodes: one block of them all
            blocks = curves[:, : curves.shape[1] // width * width].reshape(len(curves), -1, width).mean(axis=2)
            cis = np.array([bootstrap_ci(blocks[:, j]) for j in range(blocks.shape[1])])
            x = np.arange(blocks.shape[1]) * width + (width + 1) / 2
            ax.plot(x, cis[:, 0], label=team, color=colour[str(team)])
            ax.fill_between(x, cis[:, 1], cis[:, 2], alpha=0.2, color=colour[str(team)])
        ax.set_yscale("log")
        ax.set_xlabel("episode (10-episode blocks)")
        ax.set_ylabel("decisions per episode (each hunter's)")
        ax.set_title(task)
        ax.legend(fontsize=8)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def _seed_text(metrics: pd.DataFrame) -> str:
    counts = metrics.groupby(["task", "team"]).size()
    low, high = int(counts.min()), int(counts.max())
    return f"{low:,} runs" if low == high else f"{low:,} to {high:,} runs"


def hunters_section(run_dirs: Sequence[str | Path], out: str | Path) -> tuple[str, list[tuple[Path, str]]]:
    """
    The section as markdown, and its figures as ``(path, caption)`` (written under ``out/figures``; the table also as
    ``out/tables/hunters.csv``). Empty markdown when no folder holds team runs.
    """
    runs = team_runs(run_dirs)
    if not runs:
        return "", []
    out = Path(out)
    output_folder(out / "figures")
    output_folder(out / "tables")
    metrics = pd.DataFrame([team_metrics(r) for r in runs])
    table = summary_table(metrics)
    with replacing(out / "tables" / "hunters.csv") as tmp:
        table.to_csv(tmp, index=False)
    found = claims(metrics)
    held = sum(s for _, s, _ in found)
    text = [
        "## Beyond the paper: two hunters",
        "",
        "The paper's task adapts Kuremoto et al.'s pursuit problem: two hunters on a 17 x 17 grid find and capture a "
        "prey that does not move at (9, 9), starting from (2, 2) and (14, 14). Here each hunter is an independent "
        "learner (its own Q-table, emotions and episode log; `sb3_affect.agents.hunter_team`): two affective hunters, two "
        "epsilon-greedy hunters (epsilon 0.1), and the two mixed teams (the affective hunter from the far or the near "
        "start). Every hunter takes one decision per round, so *decisions per episode* is each hunter's number of "
        "decisions until the capture. A capture is a hunter entering the prey's cell; each hunter observes its own cell "
        "(and the prey's when it moves). The team's capture is *optimal* when the capturing hunter made no more one-cell "
        "moves than the nearest hunter's shortest path (10 on Kuremoto's layout): the team could not have been faster. "
        "*Steps before the first optimal capture* sums the "
        "decisions of the episodes before the first optimal one (all of them when there is none). The moving prey "
        "random-walks at half the hunters' speed on Kuremoto's layout at half scale (9 x 9, prey from (4, 4), hunters "
        "from (1, 1) and (7, 7)). Means over runs with percentile-bootstrap 95% CIs.",
        "",
        markdown_table(table),
        "",
        "### Exploratory checks (two hunters)",
        "",
        f"Of {len(found)} checks, the runs support {held} and do not support {len(found) - held}. These are exploratory: "
        f"{_seed_text(metrics)} per team, no correction for the {len(found)} comparisons. "
        "P(X better) is the probability that a run of X beats a run of the epsilon-greedy team (bootstrap 95% CI); "
        "a check is supported when the whole interval is above 0.5.",
        "",
        *[f"- **{'Supported' if ok else 'Not supported'}**: {claim}. {evidence}." for claim, ok, evidence in found],
        "",
    ]
    figure = learning_figure(runs, out / "figures" / "hunters_learning.png")
    caption = "Two hunters: decisions per episode (log scale), mean over runs and 95% CI per 10-episode block"
    return "\n".join(text), [(figure, caption)]


def hunter_folders(ctx: ReportContext) -> list[Path]:
    """The folders of team runs: the two-hunter sweeps of a replicate folder, or the paper folder if it holds teams."""
    dirs = [ctx.root / name for name in HUNTER_FOLDERS if (ctx.root / name / "runs").is_dir()]
    if "team" in ctx.paper.runs.columns or (ctx.paper.runs.algo == "team").any():  # a single folder of team runs
        dirs.append(ctx.paper.folder)
    return dirs


def add_markdown(ctx: ReportContext, text: str, images: list[tuple[Path, str]]) -> None:
    """A section's markdown and its figures into the report."""
    ctx.doc.md(text)
    for path, caption in images:
        ctx.doc.img(path, caption)


def hunters_sections(ctx: ReportContext) -> None:
    """The two-hunter section, when a folder holds team runs."""
    dirs = hunter_folders(ctx)
    if dirs:
        add_markdown(ctx, *hunters_section(dirs, ctx.out))
