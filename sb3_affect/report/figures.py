"""The report's figures (matplotlib, Agg backend, PNG files)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from sb3_affect.report.stats import bootstrap_ci

COLOURS = {
    "epsilon-greedy": "tab:blue",
    "affective": "tab:red",
    "joy": "gold",
    "sadness": "tab:blue",
    "fear": "tab:purple",
    "anger": "tab:red",
}


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def metric_vs_epsilon(
    metrics: pd.DataFrame,
    column: str,
    ylabel: str,
    title: str,
    path: Path,
    agents: tuple[str, ...] = ("epsilon-greedy", "affective"),
    log: bool = False,
) -> Path:
    """Per-run ``column`` against epsilon: mean over runs with its bootstrap 95% CI band, and every run as a dot."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for agent in agents:
        data = metrics[metrics.agent == agent]
        if data.empty:
            continue
        eps = sorted(data.epsilon.unique())
        cis = np.array([bootstrap_ci(data[data.epsilon == e][column].to_numpy()) for e in eps])
        colour = COLOURS.get(agent)
        ax.plot(eps, cis[:, 0], "o-", color=colour, label=f"{agent} (mean, 95% CI)")
        ax.fill_between(eps, cis[:, 1], cis[:, 2], color=colour, alpha=0.2)
        jitter = 0.012 if agent == "affective" else -0.012
        ax.scatter(data.epsilon + jitter, data[column], s=5, color=colour, alpha=0.25)
    ax.set_xlabel("epsilon (the affective agent ignores it)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    if log:
        ax.set_yscale("log")
    ax.legend()
    return _save(fig, path)


def emotion_profile(prof: pd.DataFrame, path: Path, title: str = "Fig. 5: emotion profile per episode") -> Path:
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for emotion in ("joy", "sadness", "fear", "anger"):
        colour = COLOURS[emotion]
        ax.plot(prof.index, prof[f"{emotion}_mean"], color=colour, label=emotion)
        ax.fill_between(prof.index, prof[f"{emotion}_lo"], prof[f"{emotion}_hi"], color=colour, alpha=0.2)
    ax.set_xlabel("episode")
    ax.set_ylabel("fraction of decisions (mean over runs, 95% band)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title)
    ax.legend()
    return _save(fig, path)


def equivalent_epsilon(prof: pd.DataFrame, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(prof.index, prof["equivalent_epsilon_mean"], color="tab:red", label="affective: random-direction fraction")
    ax.fill_between(
        prof.index,
        prof["equivalent_epsilon_lo"],
        prof["equivalent_epsilon_hi"],
        color="tab:red",
        alpha=0.2,
        label="95% band of the mean (runs)",
    )
    ax.axhline(0.3, color="grey", ls="--", lw=1, label="paper: starts ~0.3")
    ax.axhline(0.1, color="grey", ls=":", lw=1, label="paper: falls to ~0.1")
    ax.set_xlabel("episode")
    ax.set_ylabel("equivalent epsilon")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title("Fig. 6: equivalent epsilon per episode")
    ax.legend()
    return _save(fig, path)


def learning_curves(episodes: pd.DataFrame, path: Path, title: str, groups: list[tuple[str, pd.DataFrame]]) -> Path:
    """Decisions per episode over episodes: median over runs with the quartile band, one line per group."""
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    cmap = plt.get_cmap("viridis")
    for i, (label, data) in enumerate(groups):
        grouped = data.groupby("episode").decisions
        median, q25, q75 = grouped.median(), grouped.quantile(0.25), grouped.quantile(0.75)
        colour = COLOURS.get(label, cmap(i / max(1, len(groups) - 1)))
        ax.plot(median.index, median, color=colour, label=label, lw=1.3)
        ax.fill_between(median.index, q25, q75, color=colour, alpha=0.12)
    ax.axhline(12, color="black", lw=0.8, ls=":", label="12 (shortest path in cells)")
    ax.set_yscale("log")
    ax.set_xlabel("episode")
    ax.set_ylabel("decisions per episode (median; band: quartiles)")
    ax.set_title(title)
    ax.legend(fontsize=7, ncol=2)
    return _save(fig, path)


def ablation_bars(ranking: pd.DataFrame, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    labels = [r for r in ranking.reading]
    ax.barh(labels[::-1], ranking.distance.to_numpy()[::-1], color="tab:gray")
    ax.set_xlabel("distance to the paper (lower is closer)")
    ax.set_title("Reading ablation")
    return _save(fig, path)
