"""
The affective agent decision by decision: how often joy is left once felt (near-absorbing), and where late episodes
cross the norm. The episode log keeps counts only, so a few runs are traced with an ``EmotionCallback`` that records
each decision's emotion (the Python loop; the compiled engine does not call back). Cached as
``DIR/joy_trace/episodes.csv``; the tracing itself (an agent and SB3, so torch) is in ``report.joy_trace_runs``, imported
only when the cache is missing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from sb3_affect.study.report.output_files import cached_json, output_folder, replacing, write_text

#: Traced runs (seeds 0..SEEDS-1) of the paper's affective agent on the paper's task, and their episodes.
SEEDS, EPISODES = 10, 200
#: The traces' columns, by version: a cache of another version is traced again.
TRACE_VERSION = 2
LATE = (151, 200)


def traced(folder: Path, seeds: int = SEEDS, episodes: int = EPISODES) -> pd.DataFrame:
    """The traced runs, from ``folder/episodes.csv`` when it holds the same size, else computed and written there."""
    folder = Path(folder)
    meta, table = folder / "meta.json", folder / "episodes.csv"
    wanted = {"seeds": seeds, "episodes": episodes, "version": TRACE_VERSION}
    if table.exists() and cached_json(meta) == wanted:
        return pd.read_csv(table)
    from sb3_affect.study.report.joy_trace_runs import trace

    frame = pd.concat([trace(seed, episodes) for seed in range(seeds)], ignore_index=True)
    output_folder(folder)
    with replacing(table) as tmp:
        frame.to_csv(tmp, index=False)
    write_text(meta, json.dumps(wanted))
    return frame


def summary(frame: pd.DataFrame) -> dict[str, float]:
    """Near-absorbing joy and the late crossings, from ``traced``."""
    with_joy = frame[frame.joy > 0]
    late = frame[(frame.episode >= LATE[0]) & (frame.episode <= LATE[1])]
    crossing = late[late.joy > 0]
    return {
        "runs": float(frame.seed.nunique()),
        "joy decisions": float(frame.joy.sum()),
        "exits per joy decision": float(frame.joy_exits.sum() / max(frame.joy.sum(), 1)),
        "share of joy episodes that ever leave joy": float((with_joy.joy_exits > 0).mean()) if len(with_joy) else np.nan,
        "late episodes": float(len(late)),
        "share of late episodes that cross the norm": float((late.joy > 0).mean()) if len(late) else np.nan,
        "late norm, median": float(late.norm.median()),
        "late decisions without crossing, median": float(late[late.joy == 0].decisions.median()),
        "first joy decision in crossing late episodes, median": float(crossing.first_joy.median()),
        "act at the crossing in late episodes, median (cells)": float(crossing.act_at_first_joy.median()),
        "decisions of crossing late episodes, median": float(crossing.decisions.median()),
    }


def norm_figure(frame: pd.DataFrame, path: Path, shortest: int | None) -> Path:
    """
    The norm per episode (median over runs) and, for episodes that cross it, ``act`` at the first joy decision: both
    in cells, the appraisal's units (Table II compares them).
    """
    from sb3_affect.study.report.figures import plt, save

    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    norm = frame.groupby("episode").norm.median()
    ax.plot(norm.index, norm.to_numpy(), color="black", lw=1.8, label="norm (median over runs)")
    crossing = frame[frame.joy > 0]
    label = "act at the first joy decision (crossing episodes)"
    ax.scatter(crossing.episode, crossing.act_at_first_joy, s=8, color="tab:red", alpha=0.5, label=label)
    if shortest:
        ax.axhline(shortest, color="grey", ls=":", lw=1, label=f"shortest path ({shortest} cells)")
    ax.set_yscale("log")
    ax.set_xlabel("episode")
    ax.set_ylabel("cells (log scale)")
    ax.set_title("Where episodes cross the norm: act against the norm, in cells")
    ax.legend(fontsize=7)
    return save(fig, path)
