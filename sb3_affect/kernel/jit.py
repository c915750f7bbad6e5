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
passes every array as seven machine words).
"""

from __future__ import annotations

from typing import Any

from numba import njit
from numba.core.options import DefaultOptions

#: ``_nrt`` is numba's (private) switch of the NRT; a numba without it compiles the same code with reference counting.
_OPTIONS: dict[str, Any] = {"cache": True, "_nrt": False} if hasattr(DefaultOptions, "_nrt") else {"cache": True}

#: ``@kernel_jit``: ``njit(cache=True)`` without reference counting, for functions that allocate no array.
kernel_jit = njit(**_OPTIONS)

#: ``@kernel_inline``: the same, inlined into its callers.
kernel_inline = njit(inline="always", **_OPTIONS)
