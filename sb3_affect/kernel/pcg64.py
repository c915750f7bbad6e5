"""
NumPy's default generator, ``np.random.Generator(np.random.PCG64(seed))``, ported to numba draw for draw: the stream a
Gymnasium env's ``np_random`` draws from (MovingPursuit's and HunterPursuit's prey).

What the functions reproduce (NumPy's ``random/src/pcg64/pcg64.h`` and ``random/src/distributions``):

- ``next64``: PCG64 (XSL-RR, 128-bit LCG state and increment): advance ``state = state * MULT + inc`` (mod 2**128),
  output ``rotr64(hi ^ lo, hi >> 58)`` of the new state;
- ``next32``: ``next_uint32``, which uses a 64-bit output twice: the low half first, the high half kept
  (``has_uint32``/``uinteger``) for the next call;
- ``random01``: ``Generator.random()``, ``(next64 >> 11) / 2**53``;
- ``integers``: ``Generator.integers(n)`` for ``1 <= n < 2**32`` (default int64 dtype): no draw for ``n == 1``, else
  Lemire's bounded method on ``next32`` (``buffered_bounded_lemire_uint32``), drawing again while the low 32 bits
  of the product fall below ``(2**32 - n) % n``.

The state is a uint64 array of ``STATE_SIZE`` entries: the state's high and low words, the increment's high and low
words, ``has_uint32`` and ``uinteger`` (the ``bit_generator.state`` dict's fields). ``state_from_generator`` and
``state_to_generator`` move it from and to a NumPy generator, so a Python generator continues exactly where the
kernel stopped. numba's own ``np.random.Generator`` support calls the same C functions through the generator's
object, which can not be kept in arrays nor seeded inside a kernel, so a batch of runs could not carry one per run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sb3_affect.kernel.jit import kernel_inline

STATE_SIZE = 6
P_STATE_HI, P_STATE_LO, P_INC_HI, P_INC_LO, P_HAS32, P_UINT32 = range(STATE_SIZE)
_MULT = 0x2360ED051FC65DA44385DF649FCCF645
MULT_HI = np.uint64(_MULT >> 64)
MULT_LO = np.uint64(_MULT & 0xFFFFFFFFFFFFFFFF)
M32 = np.uint64(0xFFFFFFFF)
U0 = np.uint64(0)
U1 = np.uint64(1)
U11 = np.uint64(11)
U32 = np.uint64(32)
U58 = np.uint64(58)
U63 = np.uint64(63)
U64 = np.uint64(64)


@kernel_inline
def _mulhi(a: Any, b: Any) -> Any:
    """The high 64 bits of the 128-bit product of two uint64."""
    a_lo, a_hi = a & M32, a >> U32
    b_lo, b_hi = b & M32, b >> U32
    p0 = a_lo * b_lo
    p1 = a_lo * b_hi
    p2 = a_hi * b_lo
    p3 = a_hi * b_hi
    mid = (p0 >> U32) + (p1 & M32) + (p2 & M32)
    return p3 + (p1 >> U32) + (p2 >> U32) + (mid >> U32)


@kernel_inline
def next64(pcg: np.ndarray) -> Any:
    """One 64-bit output (uint64); advances the state."""
    sh, sl = pcg[P_STATE_HI], pcg[P_STATE_LO]
    low = sl * MULT_LO
    lo = low + pcg[P_INC_LO]
    carry = U1 if lo < low else U0
    hi = _mulhi(sl, MULT_LO) + sh * MULT_LO + sl * MULT_HI + pcg[P_INC_HI] + carry
    pcg[P_STATE_HI] = hi
    pcg[P_STATE_LO] = lo
    value = hi ^ lo
    rot = hi >> U58
    return (value >> rot) | (value << ((U64 - rot) & U63))


@kernel_inline
def next32(pcg: np.ndarray) -> Any:
    """``next_uint32`` (uint64 holding 32 bits): half of a 64-bit output, the other half kept for the next call."""
    if pcg[P_HAS32] != U0:
        pcg[P_HAS32] = U0
        return pcg[P_UINT32]
    value = next64(pcg)
    pcg[P_HAS32] = U1
    pcg[P_UINT32] = value >> U32
    return value & M32


@kernel_inline
def random01(pcg: np.ndarray) -> float:
    """``Generator.random()``: a float in [0, 1) with 53 random bits."""
    return float(next64(pcg) >> U11) * (1.0 / 9007199254740992.0)


@kernel_inline
def integers(pcg: np.ndarray, n: int) -> Any:
    """``Generator.integers(n)`` for ``1 <= n < 2**32``: uniform in ``[0, n)``."""
    if n <= 1:
        return 0
    bound = np.uint64(n)
    m = next32(pcg) * bound
    leftover = m & M32
    if leftover < bound:
        threshold = (M32 - (bound - U1)) % bound
        while leftover < threshold:
            m = next32(pcg) * bound
            leftover = m & M32
    return np.int64(m >> U32)


def state_from_generator(generator: np.random.Generator) -> np.ndarray:
    """A copy of a NumPy ``Generator``'s (PCG64) state for the kernel."""
    state = generator.bit_generator.state
    if state.get("bit_generator") != "PCG64":
        raise ValueError(f"the generator's bit generator is {state.get('bit_generator')}, not PCG64")
    inner = state["state"]
    mask = (1 << 64) - 1
    words = (inner["state"] >> 64, inner["state"] & mask, inner["inc"] >> 64, inner["inc"] & mask)
    return np.array([*words, state["has_uint32"], state["uinteger"]], dtype=np.uint64)


def state_to_generator(generator: np.random.Generator, pcg: np.ndarray) -> None:
    """Write a kernel state back into a NumPy ``Generator``, which then continues where the kernel stopped."""
    words = [int(v) for v in pcg]
    generator.bit_generator.state = {
        "bit_generator": "PCG64",
        "state": {"state": words[P_STATE_HI] << 64 | words[P_STATE_LO], "inc": words[P_INC_HI] << 64 | words[P_INC_LO]},
        "has_uint32": words[P_HAS32],
        "uinteger": words[P_UINT32],
    }


def seeded_state(seed: int) -> np.ndarray:
    """The state of ``np.random.Generator(np.random.PCG64(seed))``: what ``env.reset(seed=seed)`` gives its env."""
    return state_from_generator(np.random.Generator(np.random.PCG64(int(seed))))
