"""
``analyse``: which candidate implementation could have produced the paper's numbers, read from a forensics folder
whose stages are stored (``stages``: pre-screen, screen, leaders; run by the launcher, ``study_run.run_study``).

1. Screen: every candidate (simulation x reading) with its screening log-likelihood (``stages.Stages.screened``).
2. Leaders: the leaders' candidates are scored with the full synthetic likelihood and given posterior probabilities
   under a uniform prior over the leaders' candidates.
3. Intervals: each printed number against the simulated 95% interval of the best candidates. A number counts as
   reached only when a leader's 95% predictive interval from its ``reps`` replications holds it; the screen's
   intervals (a few replications, very wide) can only leave a number "not ruled out at screen size".
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from sb3_affect.core.extras import require_extra

require_extra("report", "the forensics")

import numpy as np
import pandas as pd

from sb3_affect.study.forensics.scoring import (
    MIN_REACH_REPS,
    NOT_REACHED,
    NOT_RULED_OUT,
    intervals,
    log_likelihood,
    monte_carlo_error,
    posterior,
    predictive_reach,
    reach_findings,
    transform,
)
from sb3_affect.study.forensics.section import write_standalone
from sb3_affect.study.forensics.stages import Replications, Stages
from sb3_affect.study.forensics.statistics import STATISTICS
from sb3_affect.study.launcher.schema import ForensicsSpec
from sb3_affect.study.launcher.store import ResultsStore, store_error, write_atomic


@dataclass
class ForensicsResult:
    """
    What ``analysis.analyse`` found (also written to its folder as CSV files).

    :param screen: every candidate with its screening log-likelihood, best first
    :param leaders: the leaders' candidates with their full log-likelihood and posterior probability, best first;
        ``loglik_reachable`` / ``posterior_reachable``: the same with the unreached statistics left out
    :param intervals: per printed statistic: the printed value, the best candidates' 95% intervals, how many
        leader candidates reach it, how many screened candidates' wide intervals cover it, and the finding
    :param unreached: the printed statistics that no leader candidate reaches (``intervals``' "finding" says whether a
        screen-size interval covers them: not ruled out, not shown)
    :param seconds: wall time (the launcher's and the analysis')
    :param simulated: the replications simulated by this run
    :param reused: the replications the folder held already (an earlier run's), read back instead
    """

    screen: pd.DataFrame
    leaders: pd.DataFrame
    intervals: pd.DataFrame
    unreached: list[str]
    seconds: float
    simulated: int = 0
    reused: int = 0


def analyse(
    study: ForensicsSpec, out: str | Path, printed: np.ndarray | None = None, launched: float = 0.0
) -> ForensicsResult:
    """
    Score the printed numbers on the replications stored in ``out`` (every stage of ``study``), write the tables and
    the report section (``forensics.md``). StoreError when a stage's replication is missing (rerun the study).

    :param printed: the numbers to explain, one per ``STATISTICS`` entry (default: the paper's)
    :param launched: the seconds the launcher took to simulate them (counted in the result's and run.json's)
    """
    start = time.perf_counter() - launched
    out = Path(out)
    stages = Stages(study, Replications(ResultsStore(out)), printed)
    observed = stages.observed
    screen, screened = stages.screened
    leading = stages.leading
    full_range = range(study.reps)
    finalists = [c for c in stages.space.candidates() if c.affective in leading]
    full = {c.name: stages.sample(c, full_range) for c in finalists}
    leaders_table = pd.DataFrame(
        [{"candidate": c.name, **c.describe(), "loglik": log_likelihood(full[c.name], observed)} for c in finalists]
    )
    leaders_table["posterior"] = posterior(leaders_table.loglik)
    leaders_table = leaders_table.sort_values("loglik", ascending=False, kind="stable").reset_index(drop=True)
    table, unreached = _interval_table(leaders_table, full, screened, observed)
    # the same ranking with the unreachable statistics left out: which candidate explains the rest best
    reachable = np.where(np.isin(np.array(STATISTICS), unreached), np.nan, observed)
    leaders_table["loglik_reachable"] = [log_likelihood(full[name], reachable) for name in leaders_table.candidate]
    leaders_table["posterior_reachable"] = posterior(leaders_table.loglik_reachable)
    # the Monte Carlo error of each log-likelihood (bootstrap over its replications), for the section's differences
    leaders_table["loglik_mc_error"] = [monte_carlo_error(full[name], observed) for name in leaders_table.candidate]
    leaders_table["loglik_reachable_mc_error"] = [
        monte_carlo_error(full[name], reachable) for name in leaders_table.candidate
    ]
    seconds = time.perf_counter() - start
    result = ForensicsResult(screen, leaders_table, table, unreached, seconds)
    files = {
        "screen.csv": screen.to_csv(index=False),
        "leaders.csv": leaders_table.to_csv(index=False),
        "intervals.csv": table.to_csv(),
        **{
            f"sample_top{rank + 1}.csv": pd.DataFrame(full[name], columns=list(STATISTICS)).to_csv(index=False)
            for rank, name in enumerate(leaders_table.candidate[:3])
        },
    }
    files["run.json"] = (
        pd.Series(
            {
                "screen_reps": study.screen_reps,
                "leaders": study.leaders,
                "reps": study.reps,
                "candidates": len(screen),
                "affective_simulations": len(stages.affective),
                "standard_simulations": len(stages.standard),
                "seconds": round(result.seconds, 1),
                "unreached": unreached,
                "findings": dict(zip(STATISTICS, table["finding"])),
                "printed": observed.tolist(),
            }
        ).to_json(indent=1)
    )
    for name, text in files.items():  # each whole or not at all (a full disk, a kill): a rerun rewrites them
        write_atomic(out / name, text.encode())
    try:
        write_standalone(out)
    except OSError as error:
        raise store_error(out, error) from None
    return result


def _interval_table(
    leaders_table: pd.DataFrame,
    full: dict[str, np.ndarray],
    screened: dict[str, np.ndarray],
    observed: np.ndarray,
) -> tuple[pd.DataFrame, list[str]]:
    """
    Printed values beside the top candidates' 95% intervals; how many leader candidates (full replications) reach
    each and how many screened candidates' wide screen-size intervals cover it; the finding (``reach_findings``).
    The unreached statistics are those no leader reaches: a screen-size interval that covers a number does not count.
    """
    table = pd.DataFrame(index=pd.Index(STATISTICS, name="statistic"))
    table["printed"] = observed
    for rank, name in enumerate(leaders_table.candidate[:3]):
        lo, hi = intervals(full[name])
        table[f"#{rank + 1} 2.5%"] = lo
        table[f"#{rank + 1} 97.5%"] = hi
    leader_samples = [full[name] for name in leaders_table.candidate]
    leader_reach = np.zeros(len(STATISTICS), dtype=int)
    for sample in leader_samples:
        enough = np.isfinite(transform(sample)).sum(axis=0) >= MIN_REACH_REPS
        leader_reach += predictive_reach(sample, observed) & enough
    screen_reach = np.zeros(len(STATISTICS), dtype=int)
    for sample in screened.values():
        screen_reach += predictive_reach(sample, observed)
    table["leaders reaching"] = leader_reach
    table["screened covering"] = screen_reach
    findings = reach_findings(leader_samples, list(screened.values()), observed)
    table["finding"] = findings
    unreached = [s for s, finding in zip(STATISTICS, findings) if finding in (NOT_REACHED, NOT_RULED_OUT)]
    return table, unreached
