"""
The affective agent decision by decision: how often joy is left once felt (near-absorbing), and where late episodes
cross the norm. The episode log keeps counts only, so a few runs are traced (experiments/joy_trace.yaml, an agent with
``trace: true``: the launcher stores each episode's first joy decision, ``act`` at it and joy's exits,
``sb3_affect.study.launcher.emotion_trace``); this module reads them from the results folder ``DIR/joy_trace``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sb3_affect.core.episode_log import TRACE_COLUMNS
from sb3_affect.study.launcher.store import ResultsStore
from sb3_affect.study.report.reading.run_tables import load_results
from sb3_affect.study.report.rendering.figures import plt, save

#: The late episodes whose crossings of the norm the section reads.
LATE = (151, 200)


def traced(folder: Path) -> pd.DataFrame | None:
    """
    The traced runs of the results folder ``folder``, one row per episode (``seed``, ``episode``, ``norm``,
    ``decisions``, ``joy`` and ``TRACE_COLUMNS``) in seed and episode order; None when it holds no finished run.
    """

    if ResultsStore(folder).saved_sweep() is None:
        return None
    results = load_results(Path(folder), ("episode", "norm", "decisions", "joy", *TRACE_COLUMNS))
    if not len(results.runs):
        return None
    seeds = results.runs.set_index("run_id").seed
    frame = results.episodes.drop(columns=["agent", "replicate"], errors="ignore")
    frame.insert(0, "seed", seeds.loc[frame.pop("run_id").astype(str)].to_numpy())
    return frame.sort_values(["seed", "episode"], kind="stable").reset_index(drop=True)


def summary(frame: pd.DataFrame) -> dict[str, float]:
    """Near-absorbing joy and the late crossings, from ``traced``."""
    with_joy = frame[frame.joy > 0]
    late = frame[(frame.episode >= LATE[0]) & (frame.episode <= LATE[1])]
    crossing = late[late.joy > 0]
    return {
        "runs": float(frame.seed.nunique()),
        "episodes": float(frame.episode.max()),
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
    Left: the norm per episode (median over runs), in cells. Right: for the episodes that cross it, ``act`` at the
    first joy decision minus that run's own norm in that episode (how far past its own norm an episode turns to joy).
    """

    fig, (left, right) = plt.subplots(1, 2, figsize=(10.0, 4.0))
    norm = frame.groupby("episode").norm.median()
    left.plot(norm.index, norm.to_numpy(), color="black", lw=1.8, label="norm (median over runs)")
    if shortest:
        left.axhline(shortest, color="grey", ls=":", lw=1, label=f"shortest path ({shortest} cells)")
    left.set_yscale("log")
    left.set_xlabel("episode")
    left.set_ylabel("cells (log scale)")
    left.set_title("The norm per episode", fontsize=9)
    left.legend(fontsize=7)
    crossing = frame[frame.joy > 0]
    right.scatter(crossing.episode, crossing.act_at_first_joy - crossing.norm, s=8, color="tab:red", alpha=0.5,
                  label="act at the first joy decision minus the run's own norm")
    right.axhline(0, color="black", lw=0.8)
    right.set_xlabel("episode")
    right.set_ylabel("act - own norm (cells)")
    right.set_title("Where episodes cross their own norm", fontsize=9)
    right.legend(fontsize=7)
    fig.suptitle("Where episodes cross the norm (cells, the appraisal's units)")
    return save(fig, path)
