"""
The core's validation, each bad value one error naming the argument, the value and what is allowed: numbers and rates
(``check_number``, ``check_rate``), then the checks of the tabular agents' hyperparameters and the per-episode schedules
they define, without torch. Each agent's constructor and its settings dataclass (``sb3_affect.core.settings``) call the
same functions in the same order, so a bad value is the same error either way.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from sb3_affect.core.appraisal import ACT_MODES, UNITS, check_choice
from sb3_affect.core.behaviour import MAX_SPEED, stored_behaviour_table
from sb3_affect.core.emotions import COMPARISONS, Emotion
from sb3_affect.core.personalities import check_personality

if TYPE_CHECKING:
    from stable_baselines3.common.type_aliases import Schedule

#: A number, or an SB3-style schedule of the remaining progress.
Rate = float | Callable[[float], float]

#: The largest safety cap on an episode's decisions (the kernel counts decisions in 64-bit integers).
MAX_EPISODE_DECISIONS = 10**15

ENGINES = ("auto", "python", "compiled")
TIE_BREAKS = ("random", "first")
MULTI_CELLS = ("steps", "jump")
DECAYS = ("linear", "exponential")


# -- numbers and rates: a clear error naming the argument, the value and the allowed range -------------------------
def check_number(name: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    """Validate a float hyperparameter in ``[low, high]`` (``(low, high]`` when ``low_open``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {value!r} ({type(value).__name__})")
    value = float(value)
    bad = not math.isfinite(value) or value > high or (value <= low if low_open else value < low)
    if bad:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise ValueError(f"{name}={value!r} is out of range: it must be in {interval}")
    return value


def check_rate(name: str, value: float | Schedule, low: float, high: float, low_open: bool = False) -> None:
    """A rate may be a number or an SB3-style schedule (a callable of the remaining progress)."""
    if callable(value):
        for progress in (1.0, 0.0):
            check_number(f"{name}({progress:g})", value(progress), low, high, low_open)
    else:
        check_number(name, value, low, high, low_open)


# -- the checks (each agent's constructor calls those of its own arguments) -------------------------------------------
def check_positive_int(name: str, value: Any, minimum: int = 1) -> int:
    """Validate an integer argument ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}={value} must be >= {minimum}")
    return int(value)


def check_tabular(
    learning_rate: Rate, gamma: float, q_init: float, max_episode_decisions: int, engine: str, tie_break: str
) -> tuple[str, str, float, float, int]:
    """``TabularQAlgorithm``'s arguments: ``(engine, tie_break, gamma, q_init, max_episode_decisions)`` as stored."""
    engine = check_choice("engine", engine, ENGINES)
    tie_break = check_choice("tie_break", tie_break, TIE_BREAKS)
    check_rate("learning_rate", learning_rate, 0.0, 1.0, low_open=True)
    gamma = check_number("gamma", gamma, 0.0, 1.0)
    q_init = check_number("q_init", q_init, -1e300, 1e300)
    if isinstance(max_episode_decisions, bool) or not isinstance(max_episode_decisions, (int, np.integer)):
        raise TypeError(f"max_episode_decisions must be an integer >= 1, got {max_episode_decisions!r}")
    if not 1 <= max_episode_decisions <= MAX_EPISODE_DECISIONS:
        raise ValueError(f"max_episode_decisions={max_episode_decisions} must be in [1, {MAX_EPISODE_DECISIONS:.0e}]")
    return engine, tie_break, gamma, q_init, int(max_episode_decisions)


def check_exploration_rate(exploration_rate: Rate) -> Rate:
    """Epsilon: a number in [0, 1] or a schedule."""
    check_rate("exploration_rate", exploration_rate, 0.0, 1.0)
    return exploration_rate


def check_decaying(initial: float, final: float, episodes: int, decay: str) -> tuple[float, float, int, str]:
    """``DecayingEpsilonGreedy``'s decay: ``(initial, final, episodes, decay)`` as stored."""
    initial = check_number("exploration_initial_eps", initial, 0.0, 1.0)
    final = check_number("exploration_final_eps", final, 0.0, 1.0)
    episodes = check_positive_int("exploration_decay_episodes", episodes)
    decay = check_choice("decay", decay, DECAYS)
    if decay == "exponential" and min(initial, final) <= 0:
        raise ValueError("decay='exponential' needs exploration_initial_eps > 0 and exploration_final_eps > 0")
    return initial, final, episodes, decay


def check_boltzmann(temperature: Rate, final: float | None, episodes: int, decay: str) -> tuple[Rate, float | None, int, str]:
    """``Boltzmann``'s temperature: ``(temperature, temperature_final, decay episodes, decay)`` as stored."""
    check_rate("temperature", temperature, 0.0, 1e300, low_open=True)
    if final is not None:
        if callable(temperature):
            raise ValueError("give either a temperature schedule or temperature_final, not both")
        final = check_number("temperature_final", final, 0.0, 1e300, low_open=True)
    episodes = check_positive_int("temperature_decay_episodes", episodes)
    return temperature, final, episodes, check_choice("decay", decay, DECAYS)


def check_speeds(multi_cell: str, speeds: Sequence[int]) -> tuple[str, list[int]]:
    """``SpeedEpsilonGreedy``'s ``multi_cell`` and ``speeds`` as stored."""
    multi_cell = check_choice("multi_cell", multi_cell, MULTI_CELLS)
    if isinstance(speeds, (str, bytes)) or not isinstance(speeds, Sequence):
        raise TypeError(f"speeds must be a sequence of integers >= 0, got {speeds!r}")
    if not speeds or not all(isinstance(k, int) and not isinstance(k, bool) and 0 <= k <= MAX_SPEED for k in speeds):
        raise ValueError(f"speeds={speeds!r} is invalid: use a non-empty sequence of integers in [0, {MAX_SPEED:,}]")
    return multi_cell, [int(k) for k in speeds]


def check_affect(
    multi_cell: str,
    personality: str,
    comparison: str,
    act: str,
    units: str,
    behaviour_table: Mapping[Emotion, Any] | str | None,
    emotion_callback: Any = None,
) -> tuple[str, str, str, str, str, dict[str, list[Any]]]:
    """
    ``AffectQ``'s options: ``(multi_cell, personality, comparison, act, units, behaviour_table)`` as stored (the
    table as ``{emotion name: [random_direction, speeds]}``). ``emotion_callback`` is only checked against
    ``personality`` here; its type is the constructor's to check.
    """
    multi_cell = check_choice("multi_cell", multi_cell, MULTI_CELLS)
    personality = check_personality(personality)
    if emotion_callback is not None and personality != "neutral":
        raise ValueError("give either a personality or an emotion_callback (with its own appraiser), not both")
    comparison = check_choice("comparison", comparison, COMPARISONS)
    act = check_choice("act", act, ACT_MODES)
    units = check_choice("units", units, UNITS)
    stored = stored_behaviour_table(behaviour_table)
    return multi_cell, personality, comparison, act, units, stored


def episode_decay(initial: float, final: float, episodes: int, kind: str, episode: int) -> float:
    """
    The value of a decay after ``episode`` finished episodes of the run.

    ``linear``: from ``initial`` to ``final`` in a straight line over ``episodes`` episodes, then ``final``.
    ``exponential``: ``initial * (final / initial) ** (episode / episodes)`` (a constant factor per episode; both
    values must be > 0), then ``final``.
    """
    if episode >= episodes:
        return final
    fraction = episode / episodes
    if kind == "linear":
        return initial + (final - initial) * fraction
    return initial * math.exp(fraction * math.log(final / initial))


def temperature_at(
    temperature: Rate, final: float | None, episodes: int, decay: str, finished_episodes: int, progress: float
) -> float:
    """Boltzmann's temperature of an episode that starts after ``finished_episodes`` episodes at this progress."""
    if final is None:
        return float(temperature(progress)) if callable(temperature) else float(temperature)
    assert not callable(temperature)
    return episode_decay(float(temperature), final, episodes, decay, finished_episodes)
