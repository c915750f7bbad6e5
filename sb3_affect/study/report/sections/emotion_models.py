"""
The report's side-by-side of the two emotion models on the same runs (the two-hunter sweeps): the paper's (Badoy & Teknomo:
appraisal of step counts, one emotion per decision) and Broekens, Jacobs & Jonker's (2015: joy/distress from the TD
error, hope/fear from the learned value; ``sb3_affect.agents.broekens``), for every hunter of the two-hunter runs.

Entry point: ``emotion_models_section(run_dirs, out) -> (markdown, [(figure path, caption)])``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.core.registry import EMOTION_MODELS
from sb3_affect.envs.hunter_pursuit import HunterPursuitEnv
from sb3_affect.study.report.reading.context import ReportContext
from sb3_affect.study.report.rendering.figures import COLOURS, plt
from sb3_affect.study.report.rendering.output_files import output_folder, replacing
from sb3_affect.study.report.sections.hunters import add_markdown, hunter_folders, markdown_table, team_runs

PAPER = EMOTION_NAMES
BROEKENS = EMOTION_MODELS["broekens"].emotions
EARLY, LATE = 10, 20


def hunter_frames(runs: list[dict[str, Any]]) -> pd.DataFrame:
    """
    One row per (run, hunter, episode): the paper model's fractions of decisions and Broekens' mean intensities.
    Built column by column (one array per hunter and run, joined once), not as one small frame per hunter.
    """
    numbers = ["episode", *(f"paper_{name}" for name in PAPER), *(f"broekens_{name}" for name in BROEKENS)]
    labels = ["task", "team", "hunter", "algo", "run"]
    parts: dict[str, list[Any]] = {name: [] for name in numbers + labels}
    lengths: list[int] = []
    for record in runs:
        episodes, config = record["episodes"], record["config"]
        for i, member in enumerate(config["team"]):
            hunter = f"hunter_{i}"
            decisions = np.asarray(episodes[f"{hunter}/decisions"], dtype=float)
            parts["episode"].append(np.asarray(episodes[f"{hunter}/episode"], dtype=np.int64))
            for name in PAPER:
                parts[f"paper_{name}"].append(np.asarray(episodes[f"{hunter}/{name}"], dtype=float) / decisions)
            for name in BROEKENS:
                parts[f"broekens_{name}"].append(np.asarray(episodes[f"{hunter}/broekens_{name}"], dtype=float))
            run = record["run_id"] if "run_id" in record else f"{config['agent']}-{config['seed']}"
            values = (config["sweep"], config["agent"], hunter, member["algo"].rpartition(":")[2], run)
            for name, value in zip(labels, values):
                parts[name].append(value)
            lengths.append(len(decisions))
    if not parts["episode"]:
        return pd.DataFrame()
    columns: dict[str, Any] = {name: np.concatenate(parts[name]) for name in numbers}
    for name in labels:
        one = np.empty(len(lengths), dtype=object)
        one[:] = parts[name]
        columns[name] = np.repeat(one, lengths)
    return pd.DataFrame(columns)


def profile_table(frames: pd.DataFrame) -> pd.DataFrame:
    """Per task, team and hunter: both models' profiles, early (first episodes) -> late (last episodes)."""
    last = int(frames.episode.max())
    rows = []
    for (task, team, hunter), group in frames.groupby(["task", "team", "hunter"], sort=False):
        early = group[group.episode <= EARLY]
        late = group[group.episode > last - LATE]
        row: dict[str, Any] = {"task": task, "team": team, "hunter": f"{hunter} ({group.algo.iloc[0]})"}
        feels = group.algo.iloc[0] == "AffectQ"
        for name in PAPER:
            row[f"paper {name}"] = (
                f"{early[f'paper_{name}'].mean():.2f} -> {late[f'paper_{name}'].mean():.2f}" if feels else "-"
            )
        for name in BROEKENS:
            row[f"Broekens {name}"] = f"{early[f'broekens_{name}'].mean():.1f} -> {late[f'broekens_{name}'].mean():.1f}"
        rows.append(row)
    return pd.DataFrame(rows)


def side_by_side_figure(frames: pd.DataFrame, path: Path) -> Path:
    """Rows: tasks; columns: the paper's profile (affective hunters), Broekens' for the same hunters, Broekens' for
    the epsilon-greedy team's hunters. Means over runs and both hunters, per episode (10-episode moving average)."""

    colours = {**COLOURS, "distress": "tab:gray", "hope": "tab:green"}
    tasks = list(dict.fromkeys(frames.task))
    fig, axes = plt.subplots(len(tasks), 3, figsize=(15, 3.6 * len(tasks)), squeeze=False)
    for row, task in zip(axes, tasks):
        mine = frames[frames.task == task]
        panels = [
            (mine[mine.algo == "AffectQ"], "paper", PAPER, "Badoy & Teknomo (AffectQ hunters): share of decisions"),
            (mine[mine.algo == "AffectQ"], "broekens", BROEKENS, "Broekens et al. (the same AffectQ hunters): intensity"),
            (mine[mine.team == "epsilon-greedy"], "broekens", BROEKENS, "Broekens et al. (epsilon-greedy team)"),
        ]
        for ax, (data, model, names, title) in zip(row, panels):
            if data.empty:
                ax.set_visible(False)
                continue
            means = data.groupby("episode")[[f"{model}_{n}" for n in names]].mean()
            for name in names:
                curve = means[f"{model}_{name}"].rolling(10, min_periods=1).mean()
                ax.plot(curve.index, curve.to_numpy(), color=colours[name], label=name)
            if model == "broekens":
                ax.set_yscale("symlog", linthresh=1.0)
            ax.set_title(f"{task}: {title}", fontsize=9)
            ax.set_xlabel("episode")
            ax.set_ylabel(
                "intensity (10-episode mean, symlog)" if model == "broekens" else "share of decisions (10-episode mean)"
            )
            ax.legend(fontsize=7)
    fig.tight_layout()
    with replacing(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return path


def _change(before: float, after: float, digits: int) -> str:
    verb = "rises" if after > before else "falls" if after < before else "stays"
    return f"{verb} from {before:.{digits}f} to {after:.{digits}f}" if verb != "stays" else f"stays at {before:.{digits}f}"


def emotion_models_section(run_dirs: Sequence[str | Path], out: str | Path) -> tuple[str, list[tuple[Path, str]]]:
    """
    The section as markdown, and its figure as ``(path, caption)`` (``out/figures/emotion_models.png``; the table as
    ``out/tables/emotion_models.csv``). Empty markdown when no folder holds team runs.
    """
    runs = team_runs(run_dirs)
    if not runs:
        return "", []
    out = Path(out)
    output_folder(out / "figures")
    output_folder(out / "tables")
    frames = hunter_frames(runs)
    table = profile_table(frames)
    with replacing(out / "tables" / "emotion_models.csv") as tmp:
        table.to_csv(tmp, index=False)
    affective = frames[frames.algo == "AffectQ"]
    last = int(frames.episode.max())
    early, late = affective[affective.episode <= EARLY], affective[affective.episode > last - LATE]
    surprise_early = (early.broekens_joy + early.broekens_distress).mean()
    surprise_late = (late.broekens_joy + late.broekens_distress).mean()
    text = [
        "## Two emotion models on the same runs",
        "",
        "Every hunter of the two-hunter runs was also observed by `BroekensCallback` (Broekens, Jacobs & Jonker 2015): "
        "joy and distress are the positive and negative parts of the TD error of each decision, hope and fear those of "
        "the learned value V(s) = max Q of the state reached (plain definitions, without the paper's further scaling; "
        "docs/hunters.md). The paper's model feels one emotion per decision from the appraisal of step counts (shares of "
        "decisions; AffectQ hunters only, QLearning has no emotions of its own). The table gives each model's profile in "
        f"the first {EARLY} episodes -> the last {LATE} (means over runs; Broekens' intensities are in reward units).",
        "",
        markdown_table(table),
        "",
        f"The two models read different things. For the affective hunters (both starts pooled), the paper's joy share "
        f"{_change(early.paper_joy.mean(), late.paper_joy.mean(), 2)} and its anger share "
        f"{_change(early.paper_anger.mean(), late.paper_anger.mean(), 2)}: it follows each episode's length against the "
        f"expected one. Broekens' joy + distress per decision {_change(surprise_early, surprise_late, 1)} and hope "
        f"{_change(early.broekens_hope.mean(), late.broekens_hope.mean(), 1)}: it follows the values themselves, TD errors "
        "appearing only once values have propagated from the prey (the first episodes are long walks over cells worth 0) "
        "and hope growing with them."
        + (
            " Broekens' fear is 0 throughout: no reward is negative, so no learned value is."
            if (frames.broekens_fear == 0).all()
            else f" Broekens' fear averages {frames.broekens_fear.mean():.2f}."
        ),
        "",
    ]
    text += _far_hunter_lines(runs)
    figure = side_by_side_figure(frames, out / "figures" / "emotion_models.png")
    caption = (
        "The same hunters under both emotion models: the paper's profile (left) and Broekens et al.'s (middle; right: the "
        "epsilon-greedy team), means over runs and hunters, 10-episode moving average"
    )
    return "\n".join(text), [(figure, caption)]


def _far_hunter_lines(runs: list[dict[str, Any]]) -> list[str]:
    """
    Why an affective hunter that rarely captures ends in joy: over the last ``LATE`` episodes, its norm (fitted on
    its own episode lengths, which the other hunter's captures cut short) against its shortest distance to the prey.
    """

    rows = []
    for record in runs:
        config, episodes = record["config"], record["episodes"]
        if "capturer" not in episodes:
            continue
        env = HunterPursuitEnv(**config.get("env_kwargs", {}))
        distance = env.distances_to(env.prey_start_cell)
        capturer = np.asarray(episodes["capturer"], dtype=float)[-LATE:]
        for i, member in enumerate(config["team"]):
            if member["algo"].rpartition(":")[2] != "AffectQ" or f"hunter_{i}/norm" not in episodes:
                continue
            decisions = np.asarray(episodes[f"hunter_{i}/decisions"], float)[-LATE:]
            joy = np.asarray(episodes[f"hunter_{i}/joy"], float)[-LATE:] / decisions
            rows.append(
                {
                    "task": config["sweep"], "hunter": i, "start distance": float(distance[env.hunter_start_cells[i]]),
                    "norm": float(np.nanmedian(np.asarray(episodes[f"hunter_{i}/norm"], float)[-LATE:])),
                    "captures": float(np.mean(capturer == i)), "joy": float(np.nanmean(joy)),
                }
            )
    if not rows:
        return []
    table = pd.DataFrame(rows).groupby(["task", "hunter"], as_index=False).mean()
    lines = []
    for _, row in table.iterrows():
        task, hunter = row.task, int(row.hunter)
        if row.captures < 0.5 and row.norm < row["start distance"]:
            lines.append(
                f"Why the {task} hunter_{hunter} (AffectQ) ends in joy ({row.joy:.2f} of its decisions in the last {LATE} "
                f"episodes): it captures in {row.captures:.0%} of them, so the other hunter's captures end its episodes "
                f"early; its norm, fitted on those short episodes, is {row.norm:.1f} cells (median), below its own "
                f"{row['start distance']:.0f}-cell shortest distance to the prey. Its act starts at or above that distance, "
                "so it exceeds the norm from the first decision: joy (a random walk) all the way."
            )
    return [*lines, ""] if lines else []


def emotion_models_sections(ctx: ReportContext) -> None:
    """The two emotion models side by side on the two-hunter runs (appendix), when a folder holds team runs."""
    dirs = hunter_folders(ctx)
    if dirs:
        add_markdown(ctx, *emotion_models_section(dirs, ctx.out))
