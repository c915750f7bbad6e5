"""The report's figures (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

from sb3_affect.core.emotions import EMOTION_NAMES

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from sb3_affect.study.report.estimation.bootstrap import bootstrap_ci
from sb3_affect.study.report.rendering.output_files import replacing

COLOURS = {
    "epsilon-greedy": "tab:blue",
    "affective": "tab:red",
    "joy": "gold",
    "sadness": "tab:blue",
    "fear": "tab:purple",
    "anger": "tab:red",
}


STYLES = ("-", "--", "-.", ":")


def distinct(n: int) -> list[tuple[float, float, float, float]]:
    """
    ``n`` colours that are told apart and never red (the affective agent's): viridis, dark to light green (its pale
    yellow end is left out: it does not show on white).
    """
    cmap = plt.get_cmap("viridis")
    return [cmap(0.8 * i / max(n - 1, 1)) for i in range(n)]


def save(fig: plt.Figure, path: Path | str, rect: tuple[float, float, float, float] | None = None) -> Path:
    """Write the figure as a PNG (tight layout within ``rect`` of the figure, all of it by default; 110 dpi), close it."""
    fig.tight_layout(rect=rect)
    with replacing(Path(path)) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return Path(path)


def metric_vs_epsilon(
    metrics: pd.DataFrame,
    column: str,
    ylabel: str,
    title: str,
    path: Path,
    agents: tuple[str, ...] = ("epsilon-greedy", "affective"),
    log: bool = False,
    mark_censored: bool = False,
    reference: dict[str, float] | None = None,
) -> Path:
    """
    Per-run ``column`` against epsilon: mean over runs with its bootstrap 95% CI band, and every run as a dot
    (``mark_censored``: runs that never found the optimal path as crosses); a cell of more than ``DOTS_PER_CELL``
    runs shows a seeded sample of that many (the mean and its band use every run).
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for agent in agents:
        data = metrics[metrics.agent == agent]
        if data.empty:
            continue
        eps = sorted(data.epsilon.unique())
        cis = np.array([bootstrap_ci(data[data.epsilon == e][column].to_numpy()) for e in eps])
        data = dot_sample(data)
        colour = COLOURS.get(agent)
        ax.plot(eps, cis[:, 0], "o-", color=colour, label=f"{agent} (mean, 95% CI)")
        ax.fill_between(eps, cis[:, 1], cis[:, 2], color=colour, alpha=0.2)
        jitter = 0.012 if agent == "affective" else -0.012
        censored = data.censored.astype(bool) if mark_censored and "censored" in data else pd.Series(False, index=data.index)
        ax.scatter(data.epsilon[~censored] + jitter, data[column][~censored], s=5, color=colour, alpha=0.25)
        if censored.any():
            ax.scatter(
                data.epsilon[censored] + jitter,
                data[column][censored],
                s=22,
                marker="x",
                color=colour,
                alpha=0.8,
                label=f"{agent}: censored run (never found it; all its steps)",
            )
    for (label, value), style in zip((reference or {}).items(), STYLES[1:]):
        ax.axhline(value, color="black", ls=style, lw=1, label=label)
    ax.set_xlabel("epsilon (the affective agent ignores it)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if log:
        ax.set_yscale("log")
    ax.legend(fontsize=7)
    return save(fig, path)


#: Most runs drawn as dots per (agent, epsilon) cell of ``metric_vs_epsilon``.
DOTS_PER_CELL = 2000


def dot_sample(data: pd.DataFrame, per_cell: int = DOTS_PER_CELL, seed: int = 0) -> pd.DataFrame:
    """The runs of ``data`` to draw as dots: all of them, or a seeded sample of ``per_cell`` per epsilon (in order)."""
    counts = data.groupby("epsilon").epsilon.transform("size").to_numpy()
    if not len(counts) or counts.max() <= per_cell:
        return data
    rng = np.random.default_rng(seed)
    rank = data.assign(_key=rng.random(len(data))).groupby("epsilon")["_key"].rank(method="first").to_numpy()
    return data[rank <= per_cell]


def emotion_profile(prof: pd.DataFrame, path: Path, title: str = "Fig. 5: emotion profile per episode") -> Path:
    """Two panels: the mean over runs of per-episode fractions (95% band), and the decision-weighted fractions."""
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.0), sharey=True)
    for emotion in EMOTION_NAMES:
        colour = COLOURS[emotion]
        style = "-" if emotion in ("joy", "anger") else ":"
        axes[0].plot(prof.index, prof[f"{emotion}_mean"], color=colour, ls=style, label=emotion)
        axes[0].fill_between(prof.index, prof[f"{emotion}_lo"], prof[f"{emotion}_hi"], color=colour, alpha=0.2)
        axes[1].plot(prof.index, prof[f"{emotion}_weighted"], color=colour, ls=style, label=emotion)
        if f"{emotion}_weighted_lo" in prof.columns:
            axes[1].fill_between(
                prof.index, prof[f"{emotion}_weighted_lo"], prof[f"{emotion}_weighted_hi"], color=colour, alpha=0.2
            )
    if len(prof) and int(prof.index.min()) == 1:
        for ax, column in zip(axes, ("joy_mean", "joy_weighted")):
            ax.annotate(
                "episode 1: joy by construction\n(no appraisal yet: it explores)",
                xy=(1, float(prof[column].iloc[0])),
                xytext=(25, 0.62),
                fontsize=7,
                arrowprops={"arrowstyle": "->", "lw": 0.8},
            )
    axes[0].set_title("mean of per-episode fractions (each episode counts once)", fontsize=9)
    axes[1].set_title("decision-weighted, pooled per episode (95% band over runs)", fontsize=9)
    axes[0].set_ylabel("fraction of decisions")
    for ax in axes:
        ax.set_xlabel("episode")
        ax.set_ylim(-0.02, 1.02)
    handles, labels = axes[0].get_legend_handles_labels()
    # one legend below the panels: never over the curves or the episode-1 annotation
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.suptitle(title)
    return save(fig, path, rect=(0, 0.07, 1, 1))


def equivalent_epsilon(prof: pd.DataFrame, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(prof.index, prof["equivalent_epsilon_mean"], color="tab:red", label="mean of per-episode fractions")
    ax.plot(prof.index, prof["equivalent_epsilon_weighted"], color="tab:orange", ls="--", label="decision-weighted")
    if "equivalent_epsilon_weighted_lo" in prof.columns:
        ax.fill_between(
            prof.index,
            prof["equivalent_epsilon_weighted_lo"],
            prof["equivalent_epsilon_weighted_hi"],
            color="tab:orange",
            alpha=0.2,
            label="95% band of the decision-weighted (runs)",
        )
    ax.fill_between(
        prof.index,
        prof["equivalent_epsilon_lo"],
        prof["equivalent_epsilon_hi"],
        color="tab:red",
        alpha=0.2,
        label="95% band of the mean (runs)",
    )
    last = int(prof.index.max()) if len(prof) else 200
    ax.hlines(0.3, 1, min(10, last), color="black", lw=2.5, label="paper: about 0.3 early (episodes 1-10)")
    if last >= 181:
        ax.hlines(0.1, 181, last, color="black", lw=2.5, ls="--", label="paper: 0.1 near the end (episodes 181-200)")
    ax.set_xlabel("episode")
    ax.set_ylabel("equivalent epsilon")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title("Fig. 6: equivalent epsilon per episode")
    ax.legend()
    return save(fig, path)


def episode_quantiles(
    episode: np.ndarray, values: np.ndarray, quantiles: tuple[float, ...] = (0.25, 0.5, 0.75)
) -> tuple[np.ndarray, list[np.ndarray]]:
    """
    Per episode number: the quantiles (linear interpolation, as pandas and numpy) of integer ``values`` over runs.

    One sort of one int64 key (episode, value) for all episodes at once: memory 8 bytes a row, whatever the runs.
    """
    low = int(values.min()) if len(values) else 0
    span = int(values.max()) - low + 1 if len(values) else 1
    key = np.sort(episode.astype(np.int64) * span + (values.astype(np.int64) - low))
    episodes, counts = np.unique(key // span, return_counts=True)
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    ordered = key % span + low
    out = []
    for q in quantiles:
        h = (counts - 1) * q
        below = np.floor(h).astype(np.int64)
        above = np.minimum(below + 1, counts - 1)
        lo, hi = ordered[starts + below].astype(float), ordered[starts + above].astype(float)
        out.append(lo + (h - below) * (hi - lo))
    return episodes, out


def curve_of(data: pd.DataFrame) -> tuple[np.ndarray, list[np.ndarray]]:
    """A group's learning curve (``episode_quantiles`` of its decisions per episode): a group of ``learning_curves``."""
    return episode_quantiles(data.episode.to_numpy(), data.decisions.to_numpy())


def learning_curves(
    episodes: pd.DataFrame,
    path: Path,
    title: str,
    groups: Sequence[tuple[str, pd.DataFrame | tuple[np.ndarray, list[np.ndarray]]]],
) -> Path:
    """
    Decisions per episode over episodes: median over runs with the quartile band, one line per group (its episode
    rows, or its curve: ``curve_of`` them).
    """
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    others = [label for label, _ in groups if label not in COLOURS]
    palette = distinct(len(others))
    for label, data in groups:
        numbers, (q25, median, q75) = data if isinstance(data, tuple) else curve_of(data)
        own = label in COLOURS
        colour = COLOURS[label] if own else palette[others.index(label)]
        style = "-" if own else STYLES[others.index(label) % len(STYLES)]
        ax.plot(numbers, median, color=colour, label=label, lw=2.2 if own else 1.2, ls=style)
        ax.fill_between(numbers, q25, q75, color=colour, alpha=0.12 if own else 0.05)
    ax.axhline(12, color="black", lw=0.8, ls=":", label="12 decisions: the 12-cell shortest path at 1 cell a decision")
    ax.axhline(6, color="grey", lw=0.8, ls=":", label="6 decisions: the same path at 2 cells a decision")
    ax.set_yscale("log")
    ax.set_xlabel("episode")
    ax.set_ylabel("decisions per episode (median; band: quartiles)")
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=2)
    return save(fig, path)


def ablation_bars(ranking: pd.DataFrame, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    labels = [r for r in ranking.reading]
    ax.barh(labels[::-1], ranking.distance.to_numpy()[::-1], color="tab:gray")
    ax.set_xlabel("distance to the paper (lower is closer)")
    ax.set_title("Reading ablation")
    return save(fig, path)


def decisions_histogram(decisions: np.ndarray, path: Path, threshold: int, title: str) -> Path:
    """Per-episode decisions (log bins): count of episodes, and share of all decisions, per bin."""
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 3.8))
    bins = np.unique(np.logspace(0, np.log10(max(decisions.max(), 2)) + 0.01, 40).astype(int))
    axes[0].hist(decisions, bins=bins, color="tab:red", alpha=0.8)
    axes[0].set_ylabel("episodes")
    axes[1].hist(decisions, bins=bins, weights=decisions / decisions.sum(), color="tab:orange", alpha=0.8)
    axes[1].set_ylabel("share of all decisions")
    for ax in axes:
        ax.set_xscale("log")
        ax.axvline(threshold + 0.5, color="black", ls="--", lw=1, label=f"{threshold} decisions")
        ax.set_xlabel("decisions in the episode (log scale)")
        ax.legend(fontsize=8)
    fig.suptitle(title)
    return save(fig, path)
