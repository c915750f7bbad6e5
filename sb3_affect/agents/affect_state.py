"""
What a deep affective agent's model file holds of its ``EmotionCallback``: the callback's settings, each env's
appraisal (known map, the norm's history) and the episode log, as plain data (``callback_state``), and the way back
(``restore_callback``), every value checked as the constructor checks it. A custom emotion rule, goal test or appraiser
class has no plain form: ``callback_state`` hands it back apart, for SB3 to pickle, and a safe load refuses the file.
"""

from __future__ import annotations

import copy
import math
from typing import Any

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.core.appraisal import Appraiser, KnownMap, PowerFit
from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.core.goals import every_termination, positive_terminal_reward
from sb3_affect.core.personalities import PersonalityAppraiser
from sb3_affect.core.positions import MAX_MAPPED_CELLS

#: Goal tests a file names (the package's own).
GOALS = {"positive_terminal_reward": positive_terminal_reward, "every_termination": every_termination}
#: Appraiser classes a file names.
APPRAISERS: dict[str, type[Appraiser]] = {"Appraiser": Appraiser, "PersonalityAppraiser": PersonalityAppraiser}
#: The most episode-log rows and the longest norm history a file may hold.
MAX_ROWS = 10_000_000


class AffectStateError(ValueError):
    """A saved emotion callback's value that is not allowed (one line)."""


def callback_state(callback: EmotionCallback) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(plain, objects)``: the callback's state as plain data, and the custom objects that have none (may be empty)."""
    objects: dict[str, Any] = {}
    if type(callback) is not EmotionCallback:  # a subclass: only itself restores itself
        objects["callback"] = detached(callback)
    position = callback.position
    if position is not None and not isinstance(position, str):
        objects["position"] = position
    rule = callback.emotion_rule
    if getattr(rule, "table_ii_reading", None) != (callback.comparison, callback.order):
        objects["emotion_rule"] = rule
    goal = next((name for name, test in GOALS.items() if test is callback.goal), None)
    if goal is None:
        objects["goal"] = callback.goal
    appraisers = callback.lane_appraisers() or ([callback.appraiser] if callback.appraiser else [])
    kind = type(appraisers[0]).__name__ if appraisers else "Appraiser"
    if appraisers and APPRAISERS.get(kind) is not type(appraisers[0]):
        objects["appraisers"] = appraisers
        appraisers = []
    path = callback.episode_log_path
    episodes, goals, warned = callback.episode_counts()
    plain = {
        "comparison": callback.comparison,
        "act": callback.act,
        "units": callback.units,
        "order": callback.order,
        "position": position if isinstance(position, str) else None,
        "warn_after": callback.warn_after,
        "verbose": int(callback.verbose),
        "episode_log_path": None if path is None else str(path),
        "goal": goal,
        "appraiser": kind,
        "appraisers": [appraiser.get_state() for appraiser in appraisers],
        "rows": [[None if isinstance(v, float) and math.isnan(v) else v for v in row] for row in callback.rows],
        "episodes": episodes,
        "goals": goals,
        "warned": warned,
    }
    return plain, objects


def detached(callback: EmotionCallback) -> EmotionCallback:
    """A shallow copy of the callback without what ties it to a run (the model, its env and the step's locals)."""
    copied = copy.copy(callback)
    copied.forget_run()
    return copied


def restore_callback(plain: Any, objects: Any) -> EmotionCallback:
    """The callback ``callback_state`` saved, every value checked; an ``AffectStateError`` (one line) otherwise."""
    if not isinstance(plain, dict):
        raise AffectStateError(f"the saved emotion callback is not a mapping, got {type(plain).__name__}")
    objects = objects if isinstance(objects, dict) else {}
    if isinstance(objects.get("callback"), EmotionCallback):
        return objects["callback"]
    goal_name = plain.get("goal")
    if goal_name is not None and goal_name not in GOALS:
        raise AffectStateError(f"goal={goal_name!r} is not one of {', '.join(GOALS)}")
    path = plain.get("episode_log_path")
    if path is not None and not isinstance(path, str):
        raise AffectStateError(f"episode_log_path={path!r} must be a string or None")
    verbose = plain.get("verbose", 0)
    if isinstance(verbose, bool) or not isinstance(verbose, int) or not 0 <= verbose <= 2:
        raise AffectStateError(f"verbose={verbose!r} must be 0, 1 or 2")
    try:
        callback = EmotionCallback(
            comparison=plain.get("comparison", "literal"),
            act=plain.get("act", "episode"),
            units=plain.get("units", "cells"),
            order=plain.get("order", "table"),
            emotion_rule=objects.get("emotion_rule"),
            goal=objects.get("goal", GOALS.get(goal_name or "", positive_terminal_reward)),
            episode_log_path=path,
            warn_after=plain.get("warn_after", 20),
            verbose=verbose,
            position=objects.get("position", plain.get("position")),
        )
    except (TypeError, ValueError) as error:
        raise AffectStateError(str(error)) from None
    appraisers = objects.get("appraisers")
    if appraisers is None:
        kind = plain.get("appraiser", "Appraiser")
        if kind not in APPRAISERS:
            raise AffectStateError(f"appraiser={kind!r} is not one of {', '.join(APPRAISERS)}")
        states = plain.get("appraisers", [])
        if not isinstance(states, list) or len(states) > 4096:
            raise AffectStateError("appraisers must be a list of at most 4,096 appraisals (one per env)")
        appraisers = [_appraiser(APPRAISERS[kind], state, callback) for state in states]
    if appraisers:
        callback.set_lane_appraisers(appraisers)
    callback.rows = _rows(plain.get("rows", []))
    for key in ("episodes", "goals"):
        value = plain.get(key, 0)
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_ROWS * 1000:
            raise AffectStateError(f"{key}={value!r} must be a count (an integer >= 0)")
    callback.set_episode_counts(plain.get("episodes", 0), plain.get("goals", 0), bool(plain.get("warned", False)))
    return callback


def _count(value: Any, name: str, limit: float) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= limit:
        raise AffectStateError(f"{name}={value!r} must be an integer in [0, {limit:,}]")
    return value


def _number(value: Any, name: str, allow_none: bool = True) -> float | None:
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise AffectStateError(f"{name}={value!r} must be a finite number >= 0")
    return float(value)


def _appraiser(cls: type[Appraiser], state: Any, callback: EmotionCallback) -> Appraiser:
    """An appraiser from its saved state (``Appraiser.get_state``), checked before anything is allocated."""
    if not isinstance(state, dict):
        raise AffectStateError(f"a saved appraisal is not a mapping, got {type(state).__name__}")
    known = state.get("known")
    if not isinstance(known, dict):
        raise AffectStateError("a saved appraisal has no known map")
    n = _count(known.get("n_states"), "known.n_states", MAX_MAPPED_CELLS)
    edges, goals = known.get("edges"), known.get("goals")
    if not isinstance(edges, list) or not isinstance(goals, list):
        raise AffectStateError("known.edges and known.goals must be lists")
    for edge in edges:
        if not isinstance(edge, list) or len(edge) != 2:
            raise AffectStateError(f"known.edges holds {edge!r}, not a pair of cells")
        for cell in edge:
            _count(cell, "known.edges cell", n - 1)
    for cell in goals:
        _count(cell, "known.goals cell", n - 1)
    history = state.get("history")
    if not isinstance(history, list) or len(history) > MAX_ROWS:
        raise AffectStateError(f"history must be a list of at most {MAX_ROWS:,} episode lengths")
    lengths = [_number(v, "history value", allow_none=False) for v in history]
    scale = state.get("norm_scale", 1.0)
    if cls is PersonalityAppraiser:
        appraiser: Appraiser = PersonalityAppraiser(n, act=callback.act, units=callback.units,
                                                    norm_scale=_number(scale, "norm_scale", allow_none=False) or 1.0)
    else:
        appraiser = cls(n, act=callback.act, units=callback.units)
    appraiser.known = KnownMap.from_state({"n_states": n, "edges": edges, "goals": goals})
    appraiser.fit = PowerFit.from_state([float(v) for v in lengths if v is not None])
    norm = _number(state.get("norm"), "norm")
    appraiser.norm = math.nan if norm is None else norm
    appraiser.elapsed_cells = _count(state.get("elapsed_cells", 0), "elapsed_cells", 2**62)
    appraiser.elapsed_decisions = _count(state.get("elapsed_decisions", 0), "elapsed_decisions", 2**62)
    last = _number(state.get("last_act"), "last_act")
    appraiser.last_act = math.inf if last is None else last
    return appraiser


def _rows(rows: Any) -> list[list[Any]]:
    """The episode log's rows (``EPISODE_COLUMNS`` and the env index), NaN restored from JSON's null."""
    width = len(EPISODE_COLUMNS) + 1
    if not isinstance(rows, list) or len(rows) > MAX_ROWS:
        raise AffectStateError(f"rows must be a list of at most {MAX_ROWS:,} episodes")
    restored = []
    for row in rows:
        if not isinstance(row, list) or len(row) != width:
            raise AffectStateError(f"an episode-log row must be a list of {width} values, got {str(row)[:80]}")
        if not all(v is None or (isinstance(v, (bool, int, float))) for v in row):
            raise AffectStateError(f"an episode-log row holds a value that is not a number: {str(row)[:80]}")
        restored.append([math.nan if v is None else v for v in row])
    return restored
