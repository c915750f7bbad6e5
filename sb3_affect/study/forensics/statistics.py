"""
From simulated episode logs to the statistics the paper prints, for every reading of the logs at once.

One replication of one simulation is summarised per epsilon cell (``cell_summary``: a few sums over its runs, enough
for every ``Reading``); a candidate's printed statistics then come from two such summaries (epsilon-greedy and
affective) through the report's own paired t-test (``report.estimation.bootstrap.paired_ttest_table``). The per-run
quantities are the report's definitions (``report.reading.run_tables.run_metrics``: first optimal episode, steps
before it, censored runs contributing all their steps); a test checks the two agree.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from sb3_affect.study.launcher.forensics_candidates import OPTIMAL, STEP_UNITS, Reading
from sb3_affect.study.report.estimation.bootstrap import paired_ttest_table
from sb3_affect.study.report.verdicts import paper_numbers as paper

#: The printed statistics, in order: Table IV and Table V rows (epsilon-greedy = Variable 1), then the 27.35 episodes.
STATISTICS: tuple[str, ...] = (
    "IV mean ε-greedy",
    "IV mean affective",
    "IV variance ε-greedy",
    "IV variance affective",
    "IV Pearson r",
    "IV t Stat",
    "V mean ε-greedy",
    "V mean affective",
    "V variance ε-greedy",
    "V variance affective",
    "V Pearson r",
    "V t Stat",
    "episodes to optimal (affective)",
)

#: Statistics scored on a log scale (positive by construction); the others (r, t) on their own scale.
LOG_SCALE: tuple[bool, ...] = tuple(not name.endswith(("Pearson r", "t Stat")) for name in STATISTICS)


def printed_numbers() -> np.ndarray:
    """The paper's printed values of ``STATISTICS`` (Tables IV and V, Sec. V: report.verdicts.paper_numbers)."""
    iv, v = paper.TABLE_IV, paper.TABLE_V
    return np.array(
        [
            iv["Mean"][0],
            iv["Mean"][1],
            iv["Variance"][0],
            iv["Variance"][1],
            iv["Pearson Correlation"][0],
            iv["t Stat"][0],
            v["Mean"][0],
            v["Mean"][1],
            v["Variance"][0],
            v["Variance"][1],
            v["Pearson Correlation"][0],
            v["t Stat"][0],
            paper.EPISODES_TO_OPTIMAL,
        ],
        dtype=float,
    )


def _first_stable(flags: np.ndarray) -> np.ndarray:
    """Per row: first episode (1-based) from which the row's flags stay True to the end; NaN if the last is False."""
    episodes = flags.shape[1]
    false_after = np.where(~flags, np.arange(1, episodes + 1), 0).max(axis=1)  # last False episode (0: none)
    return np.where(flags[:, -1], false_after + 1.0, math.nan)


def _first_true(flags: np.ndarray) -> np.ndarray:
    """Per row: first episode (1-based) whose flag is True; NaN if none."""
    any_true = flags.any(axis=1)
    return np.where(any_true, flags.argmax(axis=1) + 1.0, math.nan)


def cell_summary(log: pd.DataFrame) -> dict[str, float]:
    """
    Sums over the runs of one epsilon cell (one ``simulate`` table, every run with the same number of episodes).

    ``n`` runs; ``decisions`` / ``cells``: the sum over runs of the mean steps per episode; per optimal definition
    ``o``: ``o_found`` runs that found it, ``o_first`` the sum of their first episodes, and per step unit ``u``:
    ``o_u_before`` the sum over runs of the steps before it (a run that never finds it: all its steps).
    """
    log = log.sort_values(["seed", "episode"], kind="stable")
    runs = log.seed.nunique()
    episodes = len(log) // runs
    if runs * episodes != len(log):
        raise ValueError("every run of an epsilon cell must have the same number of episodes")
    steps = {unit: log[unit].to_numpy(dtype=float).reshape(runs, episodes) for unit in STEP_UNITS}
    first = {
        "walked": _first_true(log.optimal.to_numpy(dtype=bool).reshape(runs, episodes)),
        "greedy": _first_stable(log.greedy_optimal.to_numpy(dtype=bool).reshape(runs, episodes)),
    }
    out: dict[str, float] = {"n": float(runs)}
    for unit in STEP_UNITS:
        out[unit] = float(steps[unit].mean(axis=1).sum())
    column = np.arange(1, episodes + 1)
    for name in OPTIMAL:
        f = first[name]
        found = ~np.isnan(f)
        out[f"{name}_found"] = float(found.sum())
        out[f"{name}_first"] = float(np.nansum(f))
        limit = np.where(found, f, episodes + 1.0)  # censored: every episode counts
        before = column[None, :] < limit[:, None]
        for unit in STEP_UNITS:
            out[f"{name}_{unit}_before"] = float((steps[unit] * before).sum())
    return out


def candidate_statistics(standard: pd.DataFrame, affective: pd.DataFrame, reading: Reading) -> np.ndarray:
    """
    The printed statistics (``STATISTICS``) of one replication under one reading.

    :param standard: the epsilon-greedy agent's ``cell_summary`` rows, one per epsilon (index: epsilon)
    :param affective: the affective agent's, same epsilons
    :param reading: how to read the logs
    """
    if list(standard.index) != list(affective.index):
        raise ValueError(f"the two agents' epsilons differ: {list(standard.index)} vs {list(affective.index)}")
    u, o = reading.step, reading.optimal
    iv = paired_ttest_table(standard[u] / standard.n, affective[u] / affective.n)
    before = f"{o}_{u}_before"
    if reading.table_v == "sum":
        v = paired_ttest_table(standard[before], affective[before])
    else:
        v = paired_ttest_table(standard[before] / standard.n, affective[before] / affective.n)
    found = affective[f"{o}_found"].sum()
    episodes = affective[f"{o}_first"].sum() / found if found else math.nan
    values = []
    for table in (iv, v):
        col1, col2 = table["Variable 1"], table["Variable 2"]
        values += [col1["Mean"], col2["Mean"], col1["Variance"], col2["Variance"], col1["Pearson Correlation"]]
        values.append(col1["t Stat"])
    values.append(episodes)
    return np.array(values, dtype=float)
