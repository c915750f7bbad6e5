"""
Rank the agents of the fair-baselines comparison: decisions per episode, cells per episode and steps before the optimal path,
each a mean over runs with a percentile-bootstrap 95% confidence interval.

Reads the launcher's results (``run_tables.load_run_records``: chunks and run files, ``docs/interfaces.md``); groups by
task (``labels["task"]``, else the sweep name) and ``config["agent"]``. "Optimal" is the episode log's ``optimal``
column (a shortest path from the start) except on envs that define ``capture_distance``
(``sb3_affect/MovingPursuit-v0``), where it is an optimal capture: captured within ``capture_distance`` cells (see
``MovingPursuitEnv``). Steps before the optimal path: decisions summed over the episodes before the first optimal
one; a run that never finds it contributes all its decisions and is counted as censored.

    python -m sb3_affect.study.report.reading.baseline_ranks runs/baselines [--markdown report.md]
    python -m sb3_affect.study.report.reading.baseline_ranks runs/baselines-tuning --tuning
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.study.launcher.one_run import package_env
from sb3_affect.study.launcher.regular_files import write_file
from sb3_affect.study.report.reading.run_tables import load_run_records
from sb3_affect.study.report.rendering.document import fmt

METRICS = ("decisions_per_episode", "cells_per_episode", "steps_before_optimal")
_CAPTURE: dict[str, int | None] = {}


def capture_distance(config: dict[str, Any]) -> int | None:
    """The env's ``capture_distance`` (moving prey), or None for envs without one."""
    key = json.dumps([config["env_id"], config.get("env_kwargs", {})], sort_keys=True)
    if not package_env(config["env_id"]):  # a folder's id is never imported (``module:Env``)
        return None
    if key not in _CAPTURE:
        env = gym.make(config["env_id"], **config.get("env_kwargs", {}))
        value = getattr(env.unwrapped, "capture_distance", None)
        _CAPTURE[key] = None if value is None else int(value)
        env.close()
    return _CAPTURE[key]


def optimal_flags(record: dict[str, Any]) -> list[bool]:
    """Per episode: was it optimal (see the module docstring)."""
    episodes = record["episodes"]
    bound = capture_distance(record["config"])
    if bound is not None:
        return [not bool(t) and int(c) <= bound for c, t in zip(episodes["cells"], episodes["truncated"])]
    return [bool(v) if v is not None and v == v else False for v in episodes["optimal"]]


def record_metrics(record: dict[str, Any]) -> dict[str, Any]:
    """One run record's numbers (a dict; ``report.reading.run_tables.run_metrics`` is the table of the paper's metrics)."""
    config = record["config"]
    episodes = record["episodes"]
    decisions = [int(d) for d in episodes["decisions"]]
    flags = optimal_flags(record)
    first = flags.index(True) if True in flags else None
    greedy = [bool(v) for v in episodes["greedy_optimal"] if v is not None and v == v]
    return {
        "task": config.get("labels", {}).get("task") or config.get("sweep") or config["env_id"],
        "agent": config["agent"],
        "seed": config["seed"],
        "episodes": len(decisions),
        "decisions_per_episode": float(np.mean(decisions)),
        "cells_per_episode": float(np.mean(episodes["cells"])),
        "steps_before_optimal": float(sum(decisions[: len(decisions) if first is None else first])),
        "censored": first is None,
        "episodes_to_optimal": math.nan if first is None else first + 1,
        "first_greedy_optimal_episode": (greedy.index(True) + 1) if True in greedy else math.nan,
        "truncated": int(sum(bool(t) for t in episodes["truncated"])),
        **{f"label:{k}": v for k, v in config.get("labels", {}).items() if k not in ("task", "replicate")},
    }


def bootstrap_ci(
    values: Sequence[float], resamples: int = 10_000, level: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """``(mean, low, high)``: the mean and its percentile-bootstrap confidence interval (resampling runs)."""
    data = np.asarray([v for v in values if v == v], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = data[rng.integers(0, data.size, size=(resamples, data.size))].mean(axis=1)
    tail = (1 - level) / 2 * 100
    low, high = np.percentile(means, [tail, 100 - tail])
    return float(data.mean()), float(low), float(high)


def summarise(records: Iterable[dict[str, Any]], by: Sequence[str] = ("task", "agent")) -> pd.DataFrame:
    """One row per group: runs, each metric's mean and 95% CI, censored runs, episodes to optimal (found runs)."""
    frame = pd.DataFrame([record_metrics(r) for r in records])
    rows = []
    for key, group in frame.groupby(list(by), sort=False):
        row: dict[str, Any] = dict(zip(by, key if isinstance(key, tuple) else (key,)))
        row["runs"] = len(group)
        for metric in METRICS:
            mean, low, high = bootstrap_ci(group[metric].tolist())
            row[metric], row[f"{metric}_low"], row[f"{metric}_high"] = mean, low, high
        row["censored"] = int(group["censored"].sum())
        row["episodes_to_optimal"] = float(group["episodes_to_optimal"].mean())
        row["first_greedy_optimal_episode"] = float(group["first_greedy_optimal_episode"].mean())
        row["truncated"] = int(group["truncated"].sum())
        rows.append(row)
    out = pd.DataFrame(rows)
    order = {key: i for i, key in enumerate(dict.fromkeys(map(tuple, out[list(by[:-1])].to_numpy().tolist())))}
    out["_order"] = [order[tuple(k)] for k in out[list(by[:-1])].to_numpy().tolist()]
    out = out.sort_values(["_order", "decisions_per_episode"], kind="stable").drop(columns="_order")
    return out.reset_index(drop=True)


def _ci(row: pd.Series, metric: str, digits: int = 1) -> str:
    return f"{fmt(row[metric], digits)} [{fmt(row[f'{metric}_low'], digits)}, {fmt(row[f'{metric}_high'], digits)}]"


def focus_ranks(
    summary: pd.DataFrame, focus: str = "affective", metric: str = "decisions_per_episode"
) -> dict[str, tuple[int, int]]:
    """Per task: where ``focus`` ranks on ``metric`` (1 = fewest) and among how many agents."""
    out = {}
    for task, table in summary.groupby("task", sort=False):
        order = list(table.sort_values(metric, kind="stable")["agent"])
        if focus in order:
            out[str(task)] = (order.index(focus) + 1, len(order))
    return out


def clearly_better(summary: pd.DataFrame, focus: str = "affective", metric: str = "decisions_per_episode") -> dict[str, int]:
    """Per task: how many agents have a lower ``metric`` than ``focus`` with non-overlapping 95% CIs."""
    out = {}
    for task, table in summary.groupby("task", sort=False):
        me = table[table["agent"] == focus]
        if len(me):
            out[str(task)] = int((table[f"{metric}_high"] < float(me[f"{metric}_low"].iloc[0])).sum())
    return out


def markdown(summary: pd.DataFrame, focus: str = "affective") -> str:
    """Per task, a table ranking the agents by decisions per episode, and where ``focus`` stands."""
    lines = []
    for task, table in summary.groupby("task", sort=False):
        lines += [
            f"### {task}",
            "",
            "| rank | agent | runs | decisions/episode [95% CI] | cells/episode [95% CI] | steps before optimal [95% CI] "
            "| censored | episodes to optimal | first greedy-optimal episode |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        table = table.sort_values("decisions_per_episode").reset_index(drop=True)
        for rank, row in table.iterrows():
            lines.append(
                f"| {int(str(rank)) + 1} | {row['agent']} | {row['runs']} | {_ci(row, 'decisions_per_episode')} | "
                f"{_ci(row, 'cells_per_episode')} | {_ci(row, 'steps_before_optimal', 0)} | {row['censored']} | "
                f"{row['episodes_to_optimal']:.1f} | {row['first_greedy_optimal_episode']:.1f} |"
            )
        if focus in set(table["agent"]):
            me = table[table["agent"] == focus].iloc[0]
            position, _total = focus_ranks(summary, focus)[str(task)]
            better = table[table["decisions_per_episode_high"] < me["decisions_per_episode_low"]]["agent"].tolist()
            worse = table[table["decisions_per_episode_low"] > me["decisions_per_episode_high"]]["agent"].tolist()
            lines += [
                "",
                f"The {focus} agent ranks {position} of {len(table)} on decisions per episode. Fewer decisions with "
                f"non-overlapping 95% CIs: {', '.join(better) or 'none'}. More: {', '.join(worse) or 'none'}.",
            ]
        lines.append("")
    return "\n".join(lines)


def emotion_profile(records: Iterable[dict[str, Any]], prefix: str = "affective") -> pd.DataFrame:
    """Per task and agent (those whose name starts with ``prefix``): fraction of decisions in each emotion."""
    rows = []
    for record in records:
        config = record["config"]
        if not config["agent"].startswith(prefix):
            continue
        episodes = record["episodes"]
        row = {"task": record_metrics(record)["task"], "agent": config["agent"], "decisions": sum(episodes["decisions"])}
        for emotion in EMOTION_NAMES:
            row[emotion] = sum(episodes[emotion])
        rows.append(row)
    if not rows:
        return pd.DataFrame(columns=["task", "agent", *EMOTION_NAMES])
    totals = pd.DataFrame(rows).groupby(["task", "agent"], sort=False).sum()
    fractions = totals[list(EMOTION_NAMES)].div(totals["decisions"], axis=0)
    return fractions.reset_index()


def profile_markdown(profile: pd.DataFrame) -> str:
    """The emotion profile as a markdown table."""
    lines = [
        "Fraction of decisions per emotion:",
        "",
        "| task | agent | joy | sadness | fear | anger |",
        "|---|---|---|---|---|---|",
    ]
    for _, row in profile.iterrows():
        values = " | ".join(f"{row[e]:.3f}" for e in EMOTION_NAMES)
        lines.append(f"| {row['task']} | {row['agent']} | {values} |")
    return "\n".join(lines) + "\n"


def tuning_choice(records: Iterable[dict[str, Any]]) -> pd.DataFrame:
    """
    Tuning runs: per agent and grid value, mean decisions per episode; the best value per agent is flagged, and
    ``interior`` says whether it lies strictly inside the grid (at an edge: extend the grid; ``launcher.epsilon_tuning`` does).
    """
    frame = pd.DataFrame([record_metrics(r) for r in records])
    label = [c for c in frame.columns if c.startswith("label:")]
    value = frame[label].bfill(axis=1).iloc[:, 0] if label else pd.Series(math.nan, index=frame.index)
    frame = frame.assign(value=value)
    table = frame.groupby(["agent", "value"], as_index=False)[["decisions_per_episode", "steps_before_optimal"]].mean()
    table["best"] = table.groupby("agent")["decisions_per_episode"].transform("min") == table["decisions_per_episode"]
    # a best value at the smallest or largest value of its agent's grid is not a tuned optimum: the grid needs extending
    low = table.groupby("agent")["value"].transform("min")
    high = table.groupby("agent")["value"].transform("max")
    table["interior"] = table["best"] & (table["value"] > low) & (table["value"] < high)
    return table


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder")
    parser.add_argument("--markdown", help="also write the ranking as markdown to this file")
    parser.add_argument("--tuning", action="store_true", help="the folder holds tuning runs: show the grid")
    args = parser.parse_args(argv)
    records = load_run_records(args.folder)
    if args.tuning:
        print(tuning_choice(records).to_string(index=False))
        return
    text = markdown(summarise(records))
    profile = emotion_profile(records)
    if len(profile):
        text += "\n" + profile_markdown(profile)
    print(text)
    if args.markdown:
        write_file(args.markdown, text)


if __name__ == "__main__":
    main()
