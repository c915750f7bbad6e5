"""Validation of numeric hyperparameters: a clear error naming the argument, the value and the allowed range."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from stable_baselines3.common.type_aliases import Schedule


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
