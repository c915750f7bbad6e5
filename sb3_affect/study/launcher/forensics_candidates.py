"""
The candidate space of the replication forensics: every implementation the paper's text allows, as data.

A *candidate* is one way the paper's agents (and its tables) could have been implemented. It has two parts:

- what must be **simulated**: a ``Simulation`` of the affective agent (Table II reading, tie-breaking, how a 2-cell
  decision moves, alpha, gamma) and the matching ``Simulation`` of the epsilon-greedy agent (tie-breaking, alpha,
  gamma: it has no affective reading, so one epsilon-greedy simulation serves every affective reading);
- how the printed statistics are **read** off the simulated logs (``Reading``: which "optimal path found", what a
  step counts, Table V as sums over the simulations or per-run means). Readings need no extra simulation.

The protocol (``Protocol``) is the paper's: 9 epsilons x 20 simulations x 200 episodes per agent; the affective agent
ignores epsilon but runs once per epsilon with its own seeds. Replication ``r`` of a simulation uses seeds derived
from sha256 of the simulation's key, ``r``, the epsilon and the seed's index (``Protocol.seeds``).
"""

from __future__ import annotations

import hashlib
import inspect
import itertools
from dataclasses import dataclass, field
from typing import Any

STANDARD, AFFECTIVE = "epsilon-greedy", "affective"
COMPARISONS = ("literal", "valence")
ACTS = ("episode", "remaining")
UNITS = ("cells", "decisions")
TIE_BREAKS = ("random", "first")
MULTI_CELLS = ("steps", "jump")
OPTIMAL = ("walked", "greedy")
STEP_UNITS = ("decisions", "cells")
TABLE_V = ("sum", "mean")


def _choice(name: str, value: Any, allowed: tuple[Any, ...]) -> None:
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not allowed; use one of {', '.join(map(repr, allowed))}")


def _number(value: float) -> str:
    return f"{float(value):g}"


@dataclass(frozen=True)
class Simulation:
    """
    One agent implementation to simulate under the paper's protocol.

    :param agent: ``"epsilon-greedy"`` (QLearning) or ``"affective"`` (AffectQ)
    :param alpha: learning rate of Eq. 1, in (0, 1]
    :param gamma: discount factor, in [0, 1]
    :param tie_break: greedy ties during learning: ``"random"`` or ``"first"`` (None: the agent's default, for agents
        built before the option existed)
    :param comparison: affective only: Table II ``"literal"`` or ``"valence"``
    :param act: affective only: ``"episode"`` or ``"remaining"``
    :param units: affective only: what the appraisal counts, ``"cells"`` or ``"decisions"``
    :param multi_cell: affective only: a k-cell decision as k one-cell ``"steps"`` (k updates) or one ``"jump"`` (one
        update); None: the agent's default
    """

    agent: str
    alpha: float = 1.0
    gamma: float = 0.8
    tie_break: str | None = None
    comparison: str | None = None
    act: str | None = None
    units: str | None = None
    multi_cell: str | None = None

    def __post_init__(self) -> None:
        _choice("agent", self.agent, (STANDARD, AFFECTIVE))
        if not 0 < float(self.alpha) <= 1:
            raise ValueError(f"alpha={self.alpha!r} must be in (0, 1]")
        if not 0 <= float(self.gamma) <= 1:
            raise ValueError(f"gamma={self.gamma!r} must be in [0, 1]")
        if self.tie_break is not None:
            _choice("tie_break", self.tie_break, TIE_BREAKS)
        affective_fields = (self.comparison, self.act, self.units, self.multi_cell)
        if self.agent == STANDARD and any(v is not None for v in affective_fields):
            raise ValueError("an epsilon-greedy Simulation takes no comparison, act, units or multi_cell")
        if self.agent == AFFECTIVE:
            _choice("comparison", self.comparison, COMPARISONS)
            _choice("act", self.act, ACTS)
            _choice("units", self.units, UNITS)
            if self.multi_cell is not None:
                _choice("multi_cell", self.multi_cell, MULTI_CELLS)

    @property
    def key(self) -> str:
        """A readable, unique name (file names and seeds derive from it)."""
        parts = [self.agent, f"a{_number(self.alpha)}", f"g{_number(self.gamma)}"]
        if self.tie_break is not None:
            parts.append(f"tie-{self.tie_break}")
        if self.agent == AFFECTIVE:
            parts.append(f"{self.comparison}-{self.act}-{self.units}")
            if self.multi_cell is not None:
                parts.append(f"mc-{self.multi_cell}")
        return "_".join(parts)

    @property
    def algo(self) -> str:
        return "QLearning" if self.agent == STANDARD else "AffectQ"

    def algo_kwargs(self, epsilon: float) -> dict[str, Any]:
        """Constructor arguments of the agent for one epsilon of the protocol (the affective agent ignores it)."""
        kwargs: dict[str, Any] = {"learning_rate": float(self.alpha), "gamma": float(self.gamma), "q_init": 0.0}
        if self.tie_break is not None:
            kwargs["tie_break"] = self.tie_break
        if self.agent == STANDARD:
            kwargs["exploration_rate"] = float(epsilon)
        else:
            kwargs.update(comparison=self.comparison, act=self.act, units=self.units)
            if self.multi_cell is not None:
                kwargs["multi_cell"] = self.multi_cell
        return kwargs

    @property
    def standard(self) -> Simulation:
        """The epsilon-greedy simulation that goes with this one (same alpha, gamma and tie-breaking)."""
        return Simulation(STANDARD, self.alpha, self.gamma, self.tie_break)


@dataclass(frozen=True)
class Reading:
    """
    How the printed statistics are read off the simulated episode logs (no extra simulation).

    :param optimal: "optimal path found" is the first episode whose ``"walked"`` path is a shortest path, or the first
        episode from which the ``"greedy"`` policy stays optimal to the end of the run
    :param step: what a step counts in Tables IV and V: ``"decisions"`` or ``"cells"``
    :param table_v: Table V's figures per epsilon as the ``"sum"`` over the simulations or the per-run ``"mean"``
    """

    optimal: str = "walked"
    step: str = "decisions"
    table_v: str = "sum"

    def __post_init__(self) -> None:
        _choice("optimal", self.optimal, OPTIMAL)
        _choice("step", self.step, STEP_UNITS)
        _choice("table_v", self.table_v, TABLE_V)

    @property
    def key(self) -> str:
        return f"opt-{self.optimal}_step-{self.step}_v-{self.table_v}"


@dataclass(frozen=True)
class Candidate:
    """
    One full candidate implementation: the affective simulation, its epsilon-greedy partner, and the reading.

    :param affective: the affective agent's ``Simulation``
    :param reading: how the statistics are read off the logs
    """

    affective: Simulation
    reading: Reading

    @property
    def standard(self) -> Simulation:
        return self.affective.standard

    @property
    def name(self) -> str:
        return f"{self.affective.key}|{self.reading.key}"

    def describe(self) -> dict[str, Any]:
        """The candidate's factors as a flat dict (one table row)."""
        a, r = self.affective, self.reading
        return {
            "comparison": a.comparison,
            "act": a.act,
            "units": a.units,
            "tie_break": a.tie_break or "default",
            "multi_cell": a.multi_cell or "default",
            "alpha": a.alpha,
            "gamma": a.gamma,
            "optimal": r.optimal,
            "step": r.step,
            "table_v": r.table_v,
        }


def supported_options() -> dict[str, bool]:
    """Whether the installed agents accept ``tie_break`` (both agents) and ``multi_cell`` (AffectQ)."""
    from sb3_affect import AffectQ, QLearning  # (the agents load torch: only when this is asked)

    q_params = inspect.signature(QLearning.__init__).parameters
    a_params = inspect.signature(AffectQ.__init__).parameters
    return {"tie_break": "tie_break" in q_params and "tie_break" in a_params, "multi_cell": "multi_cell" in a_params}


@dataclass(frozen=True)
class CandidateSpace:
    """
    A grid of candidates: every combination of the listed factor levels.

    :param readings: Table II readings as (comparison, act, units) triples (default: all 8)
    :param alphas: learning rates
    :param gammas: discount factors
    :param tie_breaks: greedy tie-breaking rules; ``(None,)`` keeps the agents' default
    :param multi_cells: how a 2-cell decision moves; ``(None,)`` keeps the agent's default
    :param optimal: definitions of "optimal path found"
    :param steps: what a step counts
    :param table_v: Table V as sums or per-run means
    :param probes: extra affective simulations outside the grid (e.g. one expensive level of a factor tried at the
        tutorial's values only)
    """

    readings: tuple[tuple[str, str, str], ...] = tuple(itertools.product(COMPARISONS, ACTS, UNITS))
    alphas: tuple[float, ...] = (0.5, 1.0)
    gammas: tuple[float, ...] = (0.7, 0.8, 0.9)
    tie_breaks: tuple[str | None, ...] = (None,)
    multi_cells: tuple[str | None, ...] = (None,)
    optimal: tuple[str, ...] = OPTIMAL
    steps: tuple[str, ...] = STEP_UNITS
    table_v: tuple[str, ...] = TABLE_V
    probes: tuple[Simulation, ...] = ()

    @classmethod
    def default(cls) -> CandidateSpace:
        """
        The default space: the 8 readings x alpha x gamma x (when the installed agents support them) both ways of
        moving 2 cells, with random tie-breaking; plus first-index tie-breaking probed at the tutorial's values
        (alpha 1, gamma 0.8) with the default reading and 2-cell steps. First-index ties freeze both agents at the
        start (every Q is 0, the first action walks into the wall), so their episodes run to the safety cap: one such
        simulation costs ~40 times a random-tie one, and the probe is enough to judge the level.
        """
        options = supported_options()
        multi = MULTI_CELLS if options["multi_cell"] else (None,)
        tie = "random" if options["tie_break"] else None
        probes = (Simulation(AFFECTIVE, 1.0, 0.8, "first", "literal", "episode", "cells", multi[0]),)
        return cls(tie_breaks=(tie,), multi_cells=multi, probes=probes if options["tie_break"] else ())

    def affective_simulations(self) -> list[Simulation]:
        grid = [
            Simulation(AFFECTIVE, alpha, gamma, tie, comparison, act, units, multi)
            for (comparison, act, units), alpha, gamma, tie, multi in itertools.product(
                self.readings, self.alphas, self.gammas, self.tie_breaks, self.multi_cells
            )
        ]
        for probe in self.probes:
            if probe.agent != AFFECTIVE:
                raise ValueError(f"probes must be affective simulations, got {probe.key}")
        return list(dict.fromkeys([*grid, *self.probes]))

    def standard_simulations(self) -> list[Simulation]:
        return list(dict.fromkeys(sim.standard for sim in self.affective_simulations()))

    def reading_variants(self) -> list[Reading]:
        return [Reading(o, s, v) for o, s, v in itertools.product(self.optimal, self.steps, self.table_v)]

    def candidates(self) -> list[Candidate]:
        return [Candidate(sim, reading) for sim in self.affective_simulations() for reading in self.reading_variants()]

    def as_dict(self) -> dict[str, Any]:
        return {
            "readings": [list(r) for r in self.readings],
            "alphas": list(self.alphas),
            "gammas": list(self.gammas),
            "tie_breaks": list(self.tie_breaks),
            "multi_cells": list(self.multi_cells),
            "optimal": list(self.optimal),
            "steps": list(self.steps),
            "table_v": list(self.table_v),
            "probes": [p.key for p in self.probes],
        }


@dataclass(frozen=True)
class Protocol:
    """
    The paper's protocol (Sec. IV): for each epsilon, ``seeds`` simulations of ``episodes`` episodes per agent.

    :param epsilons: the epsilon values (the affective agent ignores them but runs once per value)
    :param seeds: simulations per epsilon and agent
    :param episodes: episodes per simulation
    :param env_id: the Gymnasium id of the task
    :param env_kwargs: its ``gym.make`` arguments (the paper's 15 x 15 grid, start (0, 0), prey at (6, 6))
    """

    epsilons: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
    seeds: int = 20
    episodes: int = 200
    env_id: str = "sb3_affect/GridPursuit-v0"
    env_kwargs: dict[str, Any] = field(
        default_factory=lambda: {"size": 15, "start": [0, 0], "goal": [6, 6], "goal_reward": 100.0}
    )

    def __post_init__(self) -> None:
        if len(self.epsilons) < 2:
            raise ValueError(f"epsilons={self.epsilons!r}: a paired t-test needs at least 2 epsilon values")
        if self.seeds < 1 or self.episodes < 1:
            raise ValueError(f"seeds={self.seeds!r} and episodes={self.episodes!r} must be >= 1")

    def seed_list(self, simulation: Simulation, replication: int, epsilon: float) -> list[int]:
        """Fresh seeds of one replication's epsilon cell: sha256 of the simulation key, replication, epsilon, index."""
        out = []
        for index in range(self.seeds):
            text = f"{simulation.key}|r{replication}|eps{_number(epsilon)}|{index}"
            out.append(int(hashlib.sha256(text.encode()).hexdigest()[:8], 16) % 2**31)
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "epsilons": list(self.epsilons),
            "seeds": self.seeds,
            "episodes": self.episodes,
            "env_id": self.env_id,
            "env_kwargs": self.env_kwargs,
        }
