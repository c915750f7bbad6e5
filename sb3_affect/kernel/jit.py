"""
How the kernel's functions are compiled.

``kernel_jit`` is ``numba.njit`` with the compiled code cached on disk and without numba's reference counting of
arrays (the NRT, numba's ``_nrt`` option). Every function it compiles only reads and writes arrays it is given (it
allocates none), so it needs no reference counting; with it, numba increments and decrements a counter (an atomic,
locked instruction) around calls that pass an array, which in the decision loop cost about as much as the decisions
themselves. The functions that allocate (``grid_loop.run``'s work space, ``grid_batch.run_seeds``'s fresh runs) use plain
``njit(cache=True)`` and call these.

``kernel_inline`` also inlines the function into its callers (numba's ``inline="always"``): the small functions of
the decision loop (random draws, row maximum, greedy choice), whose call would cost more than their work (a call
passes every array as seven machine words). The MiniGrid worlds' functions are plain ``kernel_jit`` calls: inlined
in numba's IR they took 105 CPU s to compile on a cold cache, as calls 5 CPU s, for the same steps per second.

``announce_compile`` says, in one line on stderr, that a compiled feature's kernels are about to be compiled (their
first use on a machine, numba's cache cold) and about how long it takes; silent once they are cached.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

from numba import njit
from numba.core.options import DefaultOptions

#: ``_nrt`` is numba's (private) switch of the NRT; a numba without it compiles the same code with reference counting.
_OPTIONS: dict[str, Any] = {"cache": True, "_nrt": False} if hasattr(DefaultOptions, "_nrt") else {"cache": True}

#: ``@kernel_jit``: ``njit(cache=True)`` without reference counting, for functions that allocate no array.
kernel_jit = njit(**_OPTIONS)

#: ``@kernel_inline``: the same, inlined into its callers.
kernel_inline = njit(inline="always", **_OPTIONS)


#: The CPU time of compiling a loop on a cold cache, measured on the 2-core machine under load: the grid loop (README's
#: first example took 29.6 CPU s cold, 3.7 s warm), the moving-prey loop (the grid loop's figure: it shares its decision
#: functions; not measured on its own) and the hunter team's loop (21 CPU s for AffectQ beside QLearning).
GRID_COMPILE_CPU_SECONDS = 30
MOVING_COMPILE_CPU_SECONDS = 30
TEAM_COMPILE_CPU_SECONDS = 20

#: The features ``announce_compile`` has already considered in this process.
_ANNOUNCED: set[str] = set()


def cached(dispatcher: Any) -> bool:
    """Whether numba's disk cache holds compiled code of ``dispatcher`` (a ``kernel_jit`` function) for its source as it
    is, or the process has compiled it already: its next call does not compile (numba's cache index, read as numba reads
    it; anything unexpected counts as not cached)."""
    if dispatcher.signatures:
        return True
    try:
        return bool(dispatcher._cache._cache_file._load_index())
    except Exception:  # a numba whose cache has another layout: say it may compile
        return False


def announce_compile(feature: str, dispatchers: Iterable[Any], cpu_seconds: float) -> bool:
    """
    Before the first use of ``feature`` in this process: when any of its ``dispatchers`` is not cached (``cached``),
    print one line to stderr naming what compiles and about how long it takes (``cpu_seconds``, measured), and how to
    compile every kernel ahead (``python -m sb3_affect.kernel``). Returns whether it printed.
    """
    if feature in _ANNOUNCED:
        return False
    _ANNOUNCED.add(feature)
    if all(cached(dispatcher) for dispatcher in dispatchers):
        return False
    minutes = f"{cpu_seconds / 60:.0f} CPU minutes" if cpu_seconds >= 90 else f"{cpu_seconds:.0f} CPU seconds"
    print(f"sb3_affect: compiling {feature} (first use on this machine, cached afterwards; about {minutes}, longer on a "
          "busy machine; 'python -m sb3_affect.kernel' compiles every kernel ahead)", file=sys.stderr, flush=True)
    return True
