"""
``run_forensics``: which candidate implementation could have produced the paper's numbers?

0. Pre-screen: one replication of every simulation; a simulation whose mean steps per episode is more than
   ``REJECT_FACTOR`` times off its agent's printed Table IV mean (in both step units) is dropped, with its
   candidates (one replication is enough: that mean is over 36,000 episodes and varies by a few percent).
1. Screen: every other simulation, ``screen_reps`` replications each; score every candidate (simulation x reading)
   with the diagonal synthetic likelihood.
2. Leaders: the ``leaders`` affective simulations whose best reading scores highest get ``reps`` replications
   (with their epsilon-greedy partners); their candidates are scored with the full synthetic likelihood and given
   posterior probabilities under a uniform prior over the leaders' candidates.
3. Intervals: each printed number against the simulated 95% interval of the best candidates. A number counts as
   reached only when a leader's 95% predictive interval from its ``reps`` replications holds it; the screen's
   intervals (a few replications, very wide) can only leave a number "not ruled out at screen size".
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

from sb3_affect.core.extras import require_extra

require_extra("report", "the forensics")

import numpy as np
import pandas as pd

from sb3_affect.study.forensics.candidates import STANDARD, STEP_UNITS, Candidate, CandidateSpace, Protocol, Simulation
from sb3_affect.study.forensics.parallel_units import run_units
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
from sb3_affect.study.forensics.statistics import STATISTICS, candidate_statistics, printed_numbers
from sb3_affect.study.forensics.unit_files import SummaryStore
from sb3_affect.study.launcher.store import store_error, write_atomic

#: Pre-screen: a simulation whose mean steps per episode (one replication) is more than this factor from its agent's
#: printed Table IV mean, in both step units, is not screened further (its candidates score -inf).
REJECT_FACTOR = 10.0


@dataclass
class ForensicsResult:
    """
    What ``run_forensics`` found (also written to its folder as CSV files).

    :param screen: every candidate with its screening log-likelihood, best first
    :param leaders: the leaders' candidates with their full log-likelihood and posterior probability, best first;
        ``loglik_reachable`` / ``posterior_reachable``: the same with the unreached statistics left out
    :param intervals: per printed statistic: the printed value, the best candidates' 95% intervals, how many
        leader candidates reach it, how many screened candidates' wide intervals cover it, and the finding
    :param unreached: the printed statistics that no leader candidate reaches (``intervals``' "finding" says whether a
        screen-size interval covers them: not ruled out, not shown)
    :param seconds: wall time
    :param simulated: the replications simulated by this call
    :param reused: the replications the folder held already (an earlier run's), read back instead
    """

    screen: pd.DataFrame
    leaders: pd.DataFrame
    intervals: pd.DataFrame
    unreached: list[str]
    seconds: float
    simulated: int = 0
    reused: int = 0


class _Samples:
    """Per-candidate samples of the printed statistics, reading each stored summary once."""

    def __init__(self, store: SummaryStore) -> None:
        self.store = store
        self._cache: dict[tuple[str, int], pd.DataFrame] = {}

    def summary(self, simulation: Simulation, replication: int) -> pd.DataFrame:
        key = (simulation.key, replication)
        if key not in self._cache:
            self._cache[key] = self.store.read(simulation, replication)
        return self._cache[key]

    def sample(self, candidate: Candidate, replications: range) -> np.ndarray:
        rows = [
            candidate_statistics(self.summary(candidate.standard, r), self.summary(candidate.affective, r), candidate.reading)
            for r in replications
        ]
        return np.array(rows, dtype=float).reshape(len(rows), len(STATISTICS))  # (0, n) for no replications


def _printed_steps(observed: np.ndarray, standard: bool) -> float:
    """The printed Table IV mean steps per episode of one agent (inf when not printed: nothing is rejected)."""
    printed = float(observed[STATISTICS.index("IV mean ε-greedy" if standard else "IV mean affective")])
    return printed if np.isfinite(printed) and printed > 0 else math.inf


def _steps_ratio(summary: pd.DataFrame, observed: np.ndarray, standard: bool, cells: int | None = None) -> float:
    """
    How far (a factor >= 1) one replication's mean steps per episode is from the printed Table IV mean of its agent,
    in the closer of the two step units. ``cells``: the protocol's number of epsilon cells, when ``summary`` may be a
    replication stopped early (its missing cells count as 0 steps: a lower bound of a too-high mean).
    """
    printed = _printed_steps(observed, standard)
    if not math.isfinite(printed):
        return 1.0
    factors = []
    for unit in STEP_UNITS:
        mean = float((summary[unit] / summary.n).sum()) / (cells or len(summary))
        factors.append(max(mean / printed, printed / mean) if mean > 0 else math.inf)
    return min(factors)


def _units(simulations: list[Simulation], replications: range) -> list[tuple[Simulation, int]]:
    pairs = [(sim, r) for r in replications for sim in simulations]
    return pairs


def run_forensics(
    out: str | Path,
    space: CandidateSpace | None = None,
    protocol: Protocol | None = None,
    screen_reps: int = 3,
    leaders: int = 4,
    reps: int = 100,
    workers: int = 2,
    progress: bool = True,
    printed: np.ndarray | None = None,
    backend: str = "local",
    ray_address: str | None = None,
    ray_timeout: float = 60.0,
) -> ForensicsResult:
    """
    Screen the candidate space, replicate the leaders, score the printed numbers, write the tables and the report.

    :param out: results folder (resumable: finished replications are kept and skipped)
    :param space: the candidate space (default: ``CandidateSpace.default()``)
    :param protocol: the protocol (default: the paper's)
    :param screen_reps: replications of every simulation in the screen (>= 2)
    :param leaders: affective simulations given the full number of replications
    :param reps: replications of each leader (>= screen_reps)
    :param workers: worker processes (Ray: tasks at a time on a private instance)
    :param progress: show progress bars
    :param printed: the numbers to explain, one per ``STATISTICS`` entry (default: the paper's)
    :param backend: where the replications run: ``"local"`` (forked processes) or ``"ray"`` (Ray tasks), as a sweep's
    :param ray_address: the Ray cluster, HOST:PORT or ray://HOST:PORT (default: a private instance)
    :param ray_timeout: seconds to wait for the Ray cluster to answer
    """
    start = time.perf_counter()
    space = space or CandidateSpace.default()
    protocol = protocol or Protocol()
    if screen_reps < 2:
        raise ValueError(f"screen_reps={screen_reps!r} must be >= 2 (a spread needs two replications)")
    if reps < screen_reps:
        raise ValueError(f"reps={reps!r} must be >= screen_reps={screen_reps!r}")
    if leaders < 1:
        raise ValueError(f"leaders={leaders!r} must be >= 1")
    observed = printed_numbers() if printed is None else np.asarray(printed, dtype=float)
    if observed.shape != (len(STATISTICS),):
        raise ValueError(f"printed must hold {len(STATISTICS)} values ({', '.join(STATISTICS)}), got shape {observed.shape}")
    out = Path(out)
    store = SummaryStore(out, protocol)
    with store.lock():  # one run at a time in a folder, as a sweep's launcher
        affective = space.affective_simulations()
        standard = space.standard_simulations()
        screen_range = range(screen_reps)
        samples = _Samples(store)
        cells = len(protocol.epsilons)
        requested: dict[tuple[Simulation, int], None] = {}
        simulated = 0

        def phase(units: list[tuple[Simulation, int]], desc: str, stop_above: dict[Simulation, float] | None) -> None:
            nonlocal simulated
            requested.update(dict.fromkeys(units))
            simulated += run_units(store, units, workers, progress, desc, stop_above, backend, ray_address, ray_timeout)

        stop = {sim: REJECT_FACTOR * cells * _printed_steps(observed, sim.agent == STANDARD) for sim in standard + affective}
        phase(_units(standard + affective, range(1)), "pre-screen", stop)
        ratios = {
            sim: _steps_ratio(store.read(sim, 0, partial_ok=True), observed, sim.agent == STANDARD, cells)
            for sim in standard + affective
        }
        kept = [sim for sim in affective if max(ratios[sim], ratios[sim.standard]) <= REJECT_FACTOR]
        partners = list(dict.fromkeys(sim.standard for sim in kept))
        phase(_units(partners + kept, screen_range), "screen", None)

        rows = []
        screened = {}
        for candidate in space.candidates():
            sim = candidate.affective
            ratio = max(ratios[sim], ratios[sim.standard])
            screened[candidate.name] = samples.sample(candidate, screen_range if sim in kept else range(0))
            ll = log_likelihood(screened[candidate.name], observed, diagonal=True) if sim in kept else -math.inf
            rows.append({"candidate": candidate.name, **candidate.describe(), "screen_loglik": ll, "steps_ratio": ratio})
        screen = pd.DataFrame(rows).sort_values(["screen_loglik", "steps_ratio"], ascending=[False, True], kind="stable")
        screen = screen.reset_index(drop=True)
        by_sim = {c.name: c for c in space.candidates()}
        leading: list[Simulation] = []
        for name in screen.candidate:
            sim = by_sim[name].affective
            if sim not in leading:
                leading.append(sim)
            if len(leading) == leaders:
                break
        full_range = range(reps)
        leader_units = _units(list(dict.fromkeys([s.standard for s in leading])) + leading, full_range)
        phase(leader_units, "leaders", None)

        finalists = [c for c in space.candidates() if c.affective in leading]
        full = {c.name: samples.sample(c, full_range) for c in finalists}
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
        result = ForensicsResult(screen, leaders_table, table, unreached, seconds, simulated, len(requested) - simulated)
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
                    "screen_reps": screen_reps,
                    "leaders": leaders,
                    "reps": reps,
                    "candidates": len(screen),
                    "affective_simulations": len(affective),
                    "standard_simulations": len(standard),
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
