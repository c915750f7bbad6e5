"""The appraisal of Sec. III: ``norm`` (power regression), ``exp1`` and ``act`` (the agent's known map).

Everything here is plain Python on purpose: it runs once per decision inside the learning loop.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

INF = float("inf")
ACT_MODES = ("episode", "remaining")
UNITS = ("cells", "decisions")


def check_choice(name: str, value: Any, allowed: tuple[str, ...]) -> str:
    """Return ``value`` if it is one of ``allowed``; otherwise raise a ValueError naming the argument."""
    if value not in allowed:
        raise ValueError(f"{name}={value!r} is not supported; choose one of {', '.join(repr(a) for a in allowed)}")
    return value


class PowerFit:
    """
    Least-squares fit of ``y = a * t**b`` on ``(ln t, ln y)``, a spreadsheet "power trendline".

    Points are added one at a time (``t = 1, 2, ...``) and the running sums make each fit O(1).
    Values <= 0 are clamped to a tiny positive number so the logarithm stays finite.
    """

    def __init__(self) -> None:
        self.values: list[float] = []
        self._sx = self._sy = self._sxx = self._sxy = 0.0

    def add(self, y: float) -> None:
        self.values.append(float(y))
        x = math.log(len(self.values))
        ly = math.log(max(float(y), 1e-12))
        self._sx += x
        self._sy += ly
        self._sxx += x * x
        self._sxy += x * ly

    @property
    def sums(self) -> tuple[float, float, float, float]:
        """The fit's running sums ``(sum ln t, sum ln y, sum ln t^2, sum ln t ln y)`` (the compiled engine's copy)."""
        return self._sx, self._sy, self._sxx, self._sxy

    @sums.setter
    def sums(self, sums: tuple[float, float, float, float]) -> None:
        self._sx, self._sy, self._sxx, self._sxy = sums

    def coefficients(self) -> tuple[float, float]:
        """``(a, b)`` of the current fit; needs at least one point (with one point: ``a = y, b = 0``)."""
        n = len(self.values)
        if n == 0:
            raise ValueError("the power fit needs at least one finished episode")
        denominator = n * self._sxx - self._sx * self._sx
        b = 0.0 if n == 1 or denominator <= 1e-300 else (n * self._sxy - self._sx * self._sy) / denominator
        ln_a = (self._sy - b * self._sx) / n
        return math.exp(ln_a), b

    def predict(self, t: float) -> float:
        """The fitted value at ``t`` (finite for any positive inputs); with one point, that point exactly."""
        if len(self.values) == 1:
            return self.values[0]
        a, b = self.coefficients()
        value = a * math.exp(b * math.log(t)) if t > 0 else a
        return value if math.isfinite(value) else 1e300

    def state(self) -> list[float]:
        return list(self.values)

    @classmethod
    def from_state(cls, values: list[float]) -> PowerFit:
        fit = cls()
        for y in values:
            fit.add(y)
        return fit


class _Rows(dict):
    """
    One container per state, made the first time the state is used (a dict underneath: a map of millions of states
    holds only the rows of the states the agent has seen). Indexed and iterated as a list of ``n_states`` rows; an
    unseen state iterates as an empty row that is not stored.
    """

    def __init__(self, n_states: int, make: type) -> None:
        super().__init__()
        self.n_states, self.make = n_states, make

    def __missing__(self, state: int) -> Any:
        if not 0 <= state < self.n_states:
            raise IndexError(f"state {state} is outside the map's {self.n_states} states")
        row = self[state] = self.make()
        return row

    def __len__(self) -> int:
        return self.n_states

    def __iter__(self) -> Any:
        get, empty = self.get, self.make()
        return (get(state, empty) for state in range(self.n_states))

    def seen(self) -> list[int]:
        """The states that have a row, in order."""
        return sorted(dict.keys(self))


class KnownMap:
    """
    The transitions the agent has actually experienced, and the shortest known distance (in cells) from each cell
    to a goal it has reached. Edges are only ever added, so distances only decrease; each new edge propagates the
    decrease backwards (incremental BFS), which costs nothing once the map stops growing. Successors and
    predecessors are kept for the states seen only (``_Rows``).
    """

    def __init__(self, n_states: int) -> None:
        self.n_states = n_states
        self.successors: Any = _Rows(n_states, set)
        self.predecessors: Any = _Rows(n_states, list)
        self.distance: list[float] = [INF] * n_states
        self.goals: set[int] = set()

    def add(self, s: int, s2: int) -> None:
        """Record the experienced one-cell transition ``s -> s2`` (a bump into a wall, ``s == s2``, adds nothing)."""
        if s == s2 or s2 in self.successors[s]:
            return
        self.successors[s].add(s2)
        self.predecessors[s2].append(s)
        if self.distance[s2] + 1 < self.distance[s]:
            self.distance[s] = self.distance[s2] + 1
            self._propagate(s)

    def add_goal(self, g: int) -> None:
        """Record that entering ``g`` ended an episode at the goal."""
        if self.distance[g] > 0:
            self.goals.add(g)
            self.distance[g] = 0.0
            self._propagate(g)

    def _propagate(self, start: int) -> None:
        stack = [start]
        distance = self.distance
        while stack:
            v = stack.pop()
            dv = distance[v] + 1
            for u in self.predecessors[v]:
                if dv < distance[u]:
                    distance[u] = dv
                    stack.append(u)

    def state(self) -> dict[str, Any]:
        rows = self.successors
        states = rows.seen() if isinstance(rows, _Rows) else range(self.n_states)
        edges = [[s, t] for s in states for t in sorted(rows[s])]
        return {"n_states": self.n_states, "edges": edges, "goals": sorted(self.goals)}

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> KnownMap:
        known = cls(int(state["n_states"]))
        for g in state["goals"]:
            known.add_goal(int(g))
        for s, t in state["edges"]:
            known.add(int(s), int(t))
        return known


class Appraisal(NamedTuple):
    """The three values of Table II at one decision (all in the appraiser's units)."""

    norm: float
    exp1: float
    act: float


class Appraiser:
    """
    Appraises each decision (docs/definitions.md, "Appraisal").

    - ``norm``: power regression over the finished episodes 1..k-1 of this run, evaluated at ``t = k``
      (one finished episode: its value). Before any episode has finished there is no appraisal.
    - ``exp1 = max(norm, elapsed)``: what this episode is expected to use.
    - ``act``: ``elapsed + remaining`` (``act="episode"``) or ``remaining`` (``act="remaining"``), where ``remaining``
      is the shortest known path (in cells) from the current cell to the goal over the agent's known map. Where the
      cell has no known path, act keeps its previous value.

    :param n_states: number of cells (Discrete observation size)
    :param act: ``"episode"`` or ``"remaining"``
    :param units: ``"cells"`` (episode lengths and elapsed counted in cells moved) or ``"decisions"``
    """

    def __init__(self, n_states: int, act: str = "episode", units: str = "cells") -> None:
        self.act_mode = check_choice("act", act, ACT_MODES)
        self.units = check_choice("units", units, UNITS)
        self.known = KnownMap(n_states)
        self.fit = PowerFit()
        self.norm = math.nan
        self.elapsed_cells = 0
        self.elapsed_decisions = 0
        self.last_act = INF

    # -- episode bookkeeping ---------------------------------------------------------------------------------
    def start_episode(self) -> None:
        self.elapsed_cells = 0
        self.elapsed_decisions = 0
        n = len(self.fit.values)
        self.norm = self.fit.predict(n + 1) if n else math.nan

    def observe(self, s: int, s2: int, terminated: bool) -> None:
        """One experienced one-cell transition."""
        self.elapsed_cells += 1
        if terminated:
            self.known.add_goal(s2)
        if s != s2:
            self.known.add(s, s2)

    def end_episode(self, reached_goal: bool) -> None:
        """Add the finished episode to the norm's regression (truncated episodes count with their length too)."""
        self.fit.add(self.elapsed_cells if self.units == "cells" else self.elapsed_decisions)

    def reset_history(self) -> None:
        """Forget the episode history (a new run); the known map is knowledge and is kept."""
        self.fit = PowerFit()
        self.norm = math.nan

    # -- the appraisal ---------------------------------------------------------------------------------------
    def appraise(self, state: int) -> Appraisal | None:
        """The appraisal before a decision in ``state``; ``None`` while no episode has finished."""
        norm = self.norm
        if norm != norm:  # NaN: nothing known yet
            return None
        elapsed = self.elapsed_cells if self.units == "cells" else self.elapsed_decisions
        remaining = self.known.distance[state]
        if remaining != INF:
            self.last_act = elapsed + remaining if self.act_mode == "episode" else remaining
        return Appraisal(norm, norm if norm > elapsed else float(elapsed), self.last_act)

    # -- state held elsewhere until it is read ---------------------------------------------------------------
    def defer(self, name: str, source: Any) -> None:
        """
        Keep the attribute ``name`` (``known`` or ``fit``) in ``source``, an object whose ``value(name)`` builds it,
        until it is first read: reading it then builds it and stores it as a plain attribute. The compiled engine
        hands its known map and power fit back this way, so a ``learn`` whose appraiser nobody reads pays nothing to
        turn the kernel's arrays into Python objects, and the next compiled ``learn`` takes the arrays as they are.
        """
        self.__dict__.pop(name, None)
        self.__dict__["_deferred"] = {**self.__dict__.get("_deferred", {}), name: source}  # a new dict: copies share none

    def deferred(self, name: str) -> Any:
        """The source ``defer`` keeps ``name`` in, or None when the attribute is a plain object (read or set since)."""
        sources = self.__dict__.get("_deferred")
        return None if not sources or name in self.__dict__ else sources.get(name)

    def __getattr__(self, name: str) -> Any:  # called only for an attribute the instance does not hold
        sources = self.__dict__.get("_deferred") or {}
        source = sources.get(name)
        if source is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        value = source.value(name)
        setattr(self, name, value)
        self.__dict__["_deferred"] = {key: kept for key, kept in sources.items() if key != name}
        return value

    # -- plain-data state (save/load) ------------------------------------------------------------------------
    def get_state(self) -> dict[str, Any]:
        return {
            "act": self.act_mode,
            "units": self.units,
            "known": self.known.state(),
            "history": self.fit.state(),
            "norm": None if self.norm != self.norm else self.norm,
            "elapsed_cells": self.elapsed_cells,
            "elapsed_decisions": self.elapsed_decisions,
            "last_act": None if self.last_act == INF else self.last_act,
        }

    def set_state(self, state: dict[str, Any]) -> None:
        self.known = KnownMap.from_state(state["known"])
        self.fit = PowerFit.from_state([float(v) for v in state["history"]])
        self.norm = math.nan if state["norm"] is None else float(state["norm"])
        self.elapsed_cells = int(state["elapsed_cells"])
        self.elapsed_decisions = int(state["elapsed_decisions"])
        self.last_act = INF if state["last_act"] is None else float(state["last_act"])
