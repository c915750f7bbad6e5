"""
The checks at a tabular agent's entry points: the size of its Q-table (before it is allocated), the decision count
``learn`` is given and the observations ``predict`` is given. Each bad value is one error naming the argument, the
value and what is allowed.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

#: The largest Q-table an agent builds (entries: states x actions; float64, so 2 GiB).
MAX_TABLE_ENTRIES = 2**28


def _memory_bytes() -> int | None:
    """The machine's physical memory, where the OS says (None elsewhere)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def check_table_size(n_states: Any, n_actions: Any, where: str = "the Q-table") -> None:
    """Refuse a Q-table of ``n_states x n_actions`` float64 entries that is too large, before anything is allocated."""
    entries = int(n_states) * int(n_actions)
    size = entries * 8
    if entries > MAX_TABLE_ENTRIES:
        raise ValueError(
            f"{where}: {int(n_states):,} states x {int(n_actions):,} actions is a table of {size / 2**30:,.1f} GiB, "
            f"more than the {MAX_TABLE_ENTRIES:,} entries ({MAX_TABLE_ENTRIES * 8 / 2**30:.0f} GiB) a tabular agent "
            "allows; use a smaller observation space"
        )
    memory = _memory_bytes()
    if memory is not None and size > memory // 2:
        raise ValueError(
            f"{where}: {int(n_states):,} states x {int(n_actions):,} actions is a table of {size / 2**30:,.1f} GiB, more "
            f"than half this machine's {memory / 2**30:,.1f} GiB of memory"
        )


def check_seed(seed: Any) -> int | None:
    """A seed: None, or an integer (NumPy's too) in ``[0, 2**32 - 1]`` (what NumPy's seeding takes), as a Python int."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed must be an integer in [0, 2**32 - 1] or None, got {seed!r}")
    if not 0 <= seed < 2**32:
        raise ValueError(f"seed={seed} must be in [0, 2**32 - 1] (NumPy's seeds)")
    return int(seed)


def check_total_timesteps(total_timesteps: Any) -> int:
    """``learn``'s decision count: a whole number >= 0 (an integral float such as ``1e5`` is accepted, as by SB3)."""
    value = total_timesteps
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"total_timesteps must be a whole number of decisions >= 0, got {value!r}")
    if isinstance(value, (float, np.floating)) and (not math.isfinite(value) or value != math.floor(value)):
        raise ValueError(f"total_timesteps={value!r} must be a whole number of decisions >= 0")
    if value < 0:
        raise ValueError(f"total_timesteps={value!r} must be >= 0 (0 takes no decision)")
    return int(value)


def check_observation(observation: Any, n_states: int, start: int = 0) -> None:
    """
    That ``observation`` (one state or a batch) holds states of ``Discrete(n_states, start)``: integers (or integral
    floats) in ``[start, start + n_states)``; booleans, fractions, NaN and values outside the space are refused.
    """
    allowed = f"states of Discrete({n_states}{f', start={start}' if start else ''}): integers {start}..{start + n_states - 1}"
    try:
        obs = np.asarray(observation)
    except (ValueError, TypeError):
        raise ValueError(f"observation {observation!r:.80} is not a state; give {allowed}") from None
    if obs.dtype.kind not in "iuf" or obs.size == 0:
        raise ValueError(f"observation {observation!r:.80} is not a state ({obs.dtype} values); give {allowed}")
    flat = obs.reshape(-1)
    if obs.dtype.kind == "f":
        bad = ~np.isfinite(flat) | (flat != np.floor(flat))
        if bad.any():
            raise ValueError(f"observation {flat[bad][0]!r} is not a whole number; give {allowed}")
    outside = (flat < start) | (flat >= start + n_states)
    if outside.any():
        raise ValueError(f"observation {flat[outside][0]!r} is outside the observation space; give {allowed}")


_EPISODE_COUNTS = ("decisions", "cells", "random_moves", "waits")


def check_episode_in_progress(episode_state: Any, last_obs: Any, n_states: int, start: int = 0) -> None:
    """
    The episode a ``learn`` continues (a loaded model's, or one a caller set), checked before any engine runs: the
    compiled kernel indexes the Q-table with its state unchecked. ``_last_obs`` holds one observation of
    ``Discrete(n_states, start)``; ``_episode_state`` (when set) holds the state ``0 .. n_states - 1``, whole counts
    ``>= 0`` and a finite reward.
    """
    if last_obs is not None:
        try:
            check_observation(last_obs, n_states, start)
        except ValueError as error:
            raise ValueError(f"_last_obs: {error}") from None
    if episode_state is None:
        return
    if not isinstance(episode_state, dict) or set(episode_state) != {"state", "reward", *_EPISODE_COUNTS}:
        raise ValueError(
            f"_episode_state={episode_state!r:.80} must be a dict of state, reward, {', '.join(_EPISODE_COUNTS)}"
        )
    state = episode_state["state"]
    if not isinstance(state, (int, np.integer)) or isinstance(state, (bool, np.bool_)) or not 0 <= state < n_states:
        raise ValueError(f"_episode_state['state']={state!r:.40} is not a state: integers 0..{n_states - 1}")
    for name in _EPISODE_COUNTS:
        value = episode_state[name]
        if not isinstance(value, (int, np.integer)) or isinstance(value, (bool, np.bool_)) or not 0 <= value < 2**62:
            raise ValueError(f"_episode_state[{name!r}]={value!r:.40} must be a whole number in [0, 2**62)")
    reward = episode_state["reward"]
    if not isinstance(reward, (int, float, np.integer, np.floating)) or not math.isfinite(reward):
        raise ValueError(f"_episode_state['reward']={reward!r:.40} must be a finite number")
