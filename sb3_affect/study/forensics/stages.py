"""
The forensics' stages, planned in waves by the launcher (``launcher.run_sweep(..., stages=plan_stages)``), each
wave the units whose stage's inputs are stored:

0. Pre-screen: replication 0 of every simulation (its ``prescreen`` cell); a simulation whose mean steps per episode
   is more than ``REJECT_FACTOR`` times off its agent's printed Table IV mean (in both step units) is dropped, with its
   candidates (one replication is enough: that mean is over 36,000 episodes and varies by a few percent). Such a
   replication stops early once the limit is passed (stored as not complete).
1. Screen: every other simulation, ``screen_reps`` replications each (replication 0: the pre-screen's); every
   candidate (simulation x reading) scored with the diagonal synthetic likelihood.
2. Leaders: the ``leaders`` affective simulations whose best reading scores highest get ``reps`` replications (with
   their epsilon-greedy partners).

``Stages`` computes each stage's units from the stored replications; the analysis (``analysis``) reads the same.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from functools import cached_property

import numpy as np
import pandas as pd

from sb3_affect.study.forensics.scoring import log_likelihood
from sb3_affect.study.forensics.statistics import STATISTICS, candidate_statistics, printed_numbers
from sb3_affect.study.forensics.units import ForensicsBatch, Unit
from sb3_affect.study.launcher.batches import Job, batch_size, split_cell
from sb3_affect.study.launcher.forensics_candidates import STANDARD, STEP_UNITS, Candidate, Simulation
from sb3_affect.study.launcher.schema import PRESCREEN, REPLICATIONS, Cell, ForensicsSpec, Sweep
from sb3_affect.study.launcher.store import ResultsStore, StoreError

#: Pre-screen: a simulation whose mean steps per episode (one replication) is more than this factor from its agent's
#: printed Table IV mean, in both step units, is not screened further (its candidates score -inf).
REJECT_FACTOR = 10.0


class Replications:
    """The replications a forensics folder holds (``ResultsStore.summaries``), each read once."""

    def __init__(self, store: ResultsStore) -> None:
        self.root = store.root
        self._rows = store.summaries()
        self._frames: dict[tuple[str, str, int], pd.DataFrame] = {}

    def _frame(self, key: tuple[str, str, int]) -> pd.DataFrame:
        if key not in self._frames:
            rows = self._rows[key][0]
            frame = pd.DataFrame({name: values for name, values in rows.items() if name != "epsilon"},
                                 index=pd.Index(rows["epsilon"].tolist()))  # fmt: skip
            self._frames[key] = frame.sort_index()
        return self._frames[key]

    def prescreened(self, simulation: Simulation) -> bool:
        return (simulation.key, PRESCREEN, 0) in self._rows

    def has(self, simulation: Simulation, replication: int) -> bool:
        """Whether a complete replication is stored (replication 0: the pre-screen's, when it ran to the end)."""
        pre = self._rows.get((simulation.key, PRESCREEN, 0)) if replication == 0 else None
        return (pre is not None and pre[1]) or (simulation.key, REPLICATIONS, replication) in self._rows

    def read(self, simulation: Simulation, replication: int, partial_ok: bool = False) -> pd.DataFrame:
        """One replication's ``cell_summary`` rows, index: epsilon (sorted); with ``partial_ok`` maybe fewer cells."""
        pre = (simulation.key, PRESCREEN, 0)
        if replication == 0 and pre in self._rows and (partial_ok or self._rows[pre][1]):
            return self._frame(pre)
        key = (simulation.key, REPLICATIONS, replication)
        if key not in self._rows:
            raise StoreError(f"{self.root} holds no replication {replication} of {simulation.key}; rerun the same "
                             "command to simulate it")  # fmt: skip
        return self._frame(key)


def printed_steps(observed: np.ndarray, standard: bool) -> float:
    """The printed Table IV mean steps per episode of one agent (inf when not printed: nothing is rejected)."""
    printed = float(observed[STATISTICS.index("IV mean ε-greedy" if standard else "IV mean affective")])
    return printed if np.isfinite(printed) and printed > 0 else math.inf


def steps_ratio(summary: pd.DataFrame, observed: np.ndarray, standard: bool, cells: int | None = None) -> float:
    """
    How far (a factor >= 1) one replication's mean steps per episode is from the printed Table IV mean of its agent,
    in the closer of the two step units. ``cells``: the protocol's number of epsilon cells, when ``summary`` may be a
    replication stopped early (its missing cells count as 0 steps: a lower bound of a too-high mean).
    """
    printed = printed_steps(observed, standard)
    if not math.isfinite(printed):
        return 1.0
    factors = []
    for unit in STEP_UNITS:
        mean = float((summary[unit] / summary.n).sum()) / (cells or len(summary))
        factors.append(max(mean / printed, printed / mean) if mean > 0 else math.inf)
    return min(factors)


def units(simulations: list[Simulation], replications: range) -> list[Unit]:
    return [(sim, r) for r in replications for sim in simulations]


class Stages:
    """
    The stages of a study over the replications stored: each stage's units, and what the next stage follows from
    (read only once the units before are stored).

    :param printed: the numbers to explain, one per ``STATISTICS`` entry (default: the paper's)
    """

    def __init__(self, study: ForensicsSpec, stored: Replications, printed: np.ndarray | None = None) -> None:
        self.study, self.stored = study, stored
        self.space, self.protocol = study.space(), study.paper_protocol()
        self.observed = printed_numbers() if printed is None else np.asarray(printed, dtype=float)
        if self.observed.shape != (len(STATISTICS),):
            raise ValueError(f"printed must hold {len(STATISTICS)} values ({', '.join(STATISTICS)}), got shape "
                             f"{self.observed.shape}")  # fmt: skip
        self.affective = self.space.affective_simulations()
        self.standard = self.space.standard_simulations()
        self._samples: dict[tuple[str, int], pd.DataFrame] = {}

    @property
    def prescreen_units(self) -> list[Unit]:
        return units(self.standard + self.affective, range(1))

    def stop_above(self, simulation: Simulation) -> float:
        """The pre-screen's early stop of a simulation (``units.simulate_unit``)."""
        cells = len(self.protocol.epsilons)
        return REJECT_FACTOR * cells * printed_steps(self.observed, simulation.agent == STANDARD)

    @cached_property
    def ratios(self) -> dict[Simulation, float]:
        cells = len(self.protocol.epsilons)
        return {
            sim: steps_ratio(self.stored.read(sim, 0, partial_ok=True), self.observed, sim.agent == STANDARD, cells)
            for sim in self.standard + self.affective
        }

    @cached_property
    def kept(self) -> list[Simulation]:
        return [sim for sim in self.affective if max(self.ratios[sim], self.ratios[sim.standard]) <= REJECT_FACTOR]

    @property
    def screen_units(self) -> list[Unit]:
        partners = list(dict.fromkeys(sim.standard for sim in self.kept))
        return units(partners + self.kept, range(self.study.screen_reps))

    def sample(self, candidate: Candidate, replications: range) -> np.ndarray:
        """A candidate's printed statistics, one row per replication."""
        rows = [
            candidate_statistics(self._summary(candidate.standard, r), self._summary(candidate.affective, r),
                                 candidate.reading)
            for r in replications
        ]  # fmt: skip
        return np.array(rows, dtype=float).reshape(len(rows), len(STATISTICS))  # (0, n) for no replications

    def _summary(self, simulation: Simulation, replication: int) -> pd.DataFrame:
        key = (simulation.key, replication)
        if key not in self._samples:
            self._samples[key] = self.stored.read(simulation, replication)
        return self._samples[key]

    @cached_property
    def screened(self) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
        """Every candidate with its screening log-likelihood, best first; and each candidate's screen sample."""
        rows, samples = [], {}
        for candidate in self.space.candidates():
            sim = candidate.affective
            ratio = max(self.ratios[sim], self.ratios[sim.standard])
            samples[candidate.name] = self.sample(candidate, range(self.study.screen_reps) if sim in self.kept else range(0))
            ll = log_likelihood(samples[candidate.name], self.observed, diagonal=True) if sim in self.kept else -math.inf
            rows.append({"candidate": candidate.name, **candidate.describe(), "screen_loglik": ll, "steps_ratio": ratio})
        screen = pd.DataFrame(rows).sort_values(["screen_loglik", "steps_ratio"], ascending=[False, True], kind="stable")
        return screen.reset_index(drop=True), samples

    @cached_property
    def leading(self) -> list[Simulation]:
        by_sim = {c.name: c for c in self.space.candidates()}
        leading: list[Simulation] = []
        for name in self.screened[0].candidate:
            sim = by_sim[name].affective
            if sim not in leading:
                leading.append(sim)
            if len(leading) == self.study.leaders:
                break
        return leading

    @property
    def leader_units(self) -> list[Unit]:
        return units(list(dict.fromkeys([s.standard for s in self.leading])) + self.leading, range(self.study.reps))


def plan_stages(
    study: Sweep,
    cells: list[Cell],
    cell_ids: list[list[str]],
    store: ResultsStore,
    workers: int,
    tried: Collection[str] = (),
    printed: np.ndarray | None = None,
) -> list[Job]:
    """
    The launcher's next wave of a forensics study (``launcher.plan_jobs``): the units of the first stage not stored
    yet (nor ``tried``: a failed unit waits for the next launch), as batches of one simulation each; [] when every
    stage is stored or the first one missing can not run now. ``printed``: the numbers the stages score (``Stages``).
    """
    assert study.forensics is not None  # (a forensics study: the launcher binds it)
    stored = Replications(store)
    stages = Stages(study.forensics, stored, printed)
    cell_of = {(c.base["agent"], c.base["labels"]["stage"]): (c, ids) for c, ids in zip(cells, cell_ids)}
    missing = [u for u in stages.prescreen_units if not stored.prescreened(u[0])]
    stage = PRESCREEN
    if not missing:
        stage = REPLICATIONS
        missing = [u for u in stages.screen_units if not stored.has(*u)]
    if not missing:
        missing = [u for u in stages.leader_units if not stored.has(*u)]
    by_cell: dict[Simulation, list[tuple[str, int, int]]] = {}
    for sim, replication in missing:
        rid = cell_of[sim.key, stage][1][replication]
        if rid not in tried:
            by_cell.setdefault(sim, []).append((rid, replication, replication))
    size = batch_size(sum(len(runs) for runs in by_cell.values()), workers)
    jobs: list[Job] = []
    for sim, runs in by_cell.items():
        stop = stages.stop_above(sim) if stage == PRESCREEN else None
        base = cell_of[sim.key, stage][0].base
        jobs.extend(ForensicsBatch(b.name, b.base, b.runs, stop) for b in split_cell(base, runs, size, ForensicsBatch))
    return jobs
