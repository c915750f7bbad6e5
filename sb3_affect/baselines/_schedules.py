"""Plain-data schedules over episodes, so an experiment file (YAML) can express a decay without a callable."""

from __future__ import annotations

import math
from typing import Any

DECAYS = ("linear", "exponential")


def check_positive_int(name: str, value: Any, minimum: int = 1) -> int:
    """Validate an integer argument ``>= minimum``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"{name} must be an integer >= {minimum}, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}={value} must be >= {minimum}")
    return int(value)


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
