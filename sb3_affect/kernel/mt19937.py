"""
The random stream both engines share: CPython's ``random.Random`` (MT19937), ported to numba draw for draw.

The Python loop draws from the model's ``random.Random`` with ``random()``, ``randrange(n)`` and ``choice(seq)``. The
kernel draws the same numbers in the same order from a copy of that generator's state: it loads the state with
``getstate()`` before a run, draws with the functions below, and writes the state back with ``setstate()`` after, so
the Python generator continues exactly where the kernel stopped. What the functions reproduce (CPython's
``Modules/_randommodule.c`` and ``Lib/random.py``):

- ``genrand``: one 32-bit MT19937 output (the 624-word state and its index, the twist, the tempering);
- ``random01``: ``random()``, 53 bits from two outputs, ``(a >> 5) * 2**26 + (b >> 6)`` over ``2**53``;
- ``randbelow``: ``randrange(n)`` and ``choice`` (``seq[randbelow(len(seq))]``): ``k = n.bit_length()`` bits of one
  output (``getrandbits(k) = genrand() >> (32 - k)``), drawn again while ``>= n``;
- ``seed_state``: ``random.Random(seed)`` for an integer seed (``init_by_array`` on the 32-bit words of ``|seed|``).

The state is an int64 array of 625 entries: the 624 words and, last, the index of the next word to use.

The decision loop draws through ``draw``/``draw01``/``draw_below``, which keep the index in the caller's local and
read a second array ``tw`` (``TW_SIZE`` entries, filled by ``temper_all`` from the state and again at each twist):
``tw[:N]`` the 624 words tempered (a draw is one load), ``tw[N + i]`` the first index ``j >= i`` whose tempered word
has its top bit clear (``tw[2N] = N``). For ``n`` a power of two, ``getrandbits(k)`` with ``k = n.bit_length()`` is
``< n`` exactly when the word's top bit is clear, so ``randbelow(n)`` is the word at ``tw[N + i]``: the words it
skips are those CPython draws and rejects. The state words themselves stay untempered (they go back to Python).
"""

from __future__ import annotations

import random
from collections.abc import Sequence

import numpy as np

from sb3_affect.kernel.jit import kernel_inline, kernel_jit

N = 624
M = 397
MATRIX_A = 0x9908B0DF
UPPER_MASK = 0x80000000
LOWER_MASK = 0x7FFFFFFF
MASK32 = 0xFFFFFFFF
STATE_SIZE = N + 1
TW_SIZE = 2 * N + 1
TOP_BIT = 0x80000000


@kernel_jit
def _twist(mt: np.ndarray) -> None:
    for kk in range(N - M):
        y = (mt[kk] & UPPER_MASK) | (mt[kk + 1] & LOWER_MASK)
        mt[kk] = mt[kk + M] ^ (y >> 1) ^ (MATRIX_A if y & 1 else 0)
    for kk in range(N - M, N - 1):
        y = (mt[kk] & UPPER_MASK) | (mt[kk + 1] & LOWER_MASK)
        mt[kk] = mt[kk + (M - N)] ^ (y >> 1) ^ (MATRIX_A if y & 1 else 0)
    y = (mt[N - 1] & UPPER_MASK) | (mt[0] & LOWER_MASK)
    mt[N - 1] = mt[M - 1] ^ (y >> 1) ^ (MATRIX_A if y & 1 else 0)
    mt[N] = 0


@kernel_inline
def temper(y: int) -> int:
    """MT19937's tempering of one state word."""
    y ^= y >> 11
    y ^= (y << 7) & 0x9D2C5680
    y ^= (y << 15) & 0xEFC60000
    y ^= y >> 18
    return y & MASK32


@kernel_jit
def temper_all(mt: np.ndarray, tw: np.ndarray) -> None:
    """Fill ``tw`` from the state's words (see the module's docstring)."""
    for k in range(N):
        tw[k] = temper(mt[k])
    nxt = N
    tw[2 * N] = N
    for k in range(N - 1, -1, -1):
        nxt = k if tw[k] < TOP_BIT else nxt
        tw[N + k] = nxt


@kernel_jit
def _twist_tempered(mt: np.ndarray, tw: np.ndarray) -> None:
    _twist(mt)
    temper_all(mt, tw)


@kernel_inline
def _draw_raw(mt: np.ndarray, i: int) -> tuple[int, int]:
    """``genrand`` on the state alone (tempering the word), for the functions below that take no ``tw``."""
    if i >= N:
        _twist(mt)
        i = 0
    return temper(mt[i]), i + 1


@kernel_inline
def draw(mt: np.ndarray, tw: np.ndarray, i: int) -> tuple[int, int]:
    """
    ``genrand`` with the index in the caller's hands: the output at index ``i`` (twisting first when ``i == N``) and
    the index of the next word. The decision loop keeps the index in a local and stores it in ``mt[N]`` when it
    returns, instead of reading and writing ``mt[N]`` on every draw. ``tw`` is the tempered copy of ``mt``.
    """
    if i >= N:
        _twist_tempered(mt, tw)
        i = 0
    return tw[i], i + 1


@kernel_inline
def draw01(mt: np.ndarray, tw: np.ndarray, i: int) -> tuple[float, int]:
    """``random01`` with the index in the caller's hands (see ``draw``)."""
    a, i = draw(mt, tw, i)
    b, i = draw(mt, tw, i)
    return ((a >> 5) * 67108864.0 + (b >> 6)) * (1.0 / 9007199254740992.0), i


@kernel_inline
def bit_length(n: int) -> int:
    """``n.bit_length()`` for ``n >= 0``."""
    k = 0
    while n:
        k += 1
        n >>= 1
    return k


@kernel_inline
def draw_below(mt: np.ndarray, tw: np.ndarray, i: int, n: int, shift: int) -> tuple[int, int]:
    """
    ``randbelow`` with the index in the caller's hands (see ``draw``); ``shift`` is ``32 - n.bit_length()``. For ``n``
    a power of two (the grids' four actions, ties of two and four) the accepted word is ``tw[N + i]``, without a loop.
    """
    if n & (n - 1) == 0:
        j = tw[N + i]
        while j >= N:  # no accepted word before the end: twist and look from the start
            _twist_tempered(mt, tw)
            j = tw[N]
        return tw[j] >> shift, j + 1
    r, i = draw(mt, tw, i)
    r >>= shift
    while r >= n:
        r, i = draw(mt, tw, i)
        r >>= shift
    return r, i


@kernel_inline
def _draw_below_raw(mt: np.ndarray, i: int, n: int, shift: int) -> tuple[int, int]:
    r, i = _draw_raw(mt, i)
    r >>= shift
    while r >= n:
        r, i = _draw_raw(mt, i)
        r >>= shift
    return r, i


@kernel_jit
def genrand(mt: np.ndarray) -> int:
    """One 32-bit output (``genrand_uint32``); ``mt`` is the 625-entry state (words, then the index)."""
    y, i = _draw_raw(mt, mt[N])
    mt[N] = i
    return y


@kernel_jit
def random01(mt: np.ndarray) -> float:
    """``random.Random.random()``: a float in [0, 1) with 53 random bits."""
    a, i = _draw_raw(mt, mt[N])
    b, i = _draw_raw(mt, i)
    mt[N] = i
    return ((a >> 5) * 67108864.0 + (b >> 6)) * (1.0 / 9007199254740992.0)


@kernel_jit
def randbelow(mt: np.ndarray, n: int) -> int:
    """``random.Random.randrange(n)`` (and ``choice`` of a sequence of length ``n``), for ``1 <= n < 2**32``."""
    r, i = _draw_below_raw(mt, mt[N], n, 32 - bit_length(n))
    mt[N] = i
    return r


@kernel_jit
def seed_state(mt: np.ndarray, key: np.ndarray, key_length: int) -> None:
    """Fill ``mt`` as ``random.Random(seed)`` does; ``key`` holds the 32-bit words of ``|seed|``, least significant first."""
    mt[0] = 19650218
    for i in range(1, N):
        mt[i] = (1812433253 * (mt[i - 1] ^ (mt[i - 1] >> 30)) + i) & MASK32
    i = 1
    j = 0
    for _ in range(max(N, key_length)):
        mt[i] = ((mt[i] ^ (((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1664525) & MASK32)) + key[j] + j) & MASK32
        i += 1
        j += 1
        if i >= N:
            mt[0] = mt[N - 1]
            i = 1
        if j >= key_length:
            j = 0
    for _ in range(N - 1):
        mt[i] = ((mt[i] ^ (((mt[i - 1] ^ (mt[i - 1] >> 30)) * 1566083941) & MASK32)) - i) & MASK32
        i += 1
        if i >= N:
            mt[0] = mt[N - 1]
            i = 1
    mt[0] = 0x80000000
    mt[N] = N


def seed_key(seed: int) -> list[int]:
    """The 32-bit words of ``|seed|`` (least significant first) that ``random.Random(seed)`` seeds with."""
    n = abs(int(seed))
    words = []
    while n:
        words.append(n & MASK32)
        n >>= 32
    return words or [0]


def seed_keys(seeds: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Each seed's ``seed_key`` as the rows of one array (zero-padded), and each key's length."""
    words = [seed_key(int(seed)) for seed in seeds]
    width = max((len(w) for w in words), default=1)
    keys = np.zeros((len(words), width), dtype=np.int64)
    lengths = np.zeros(len(words), dtype=np.int64)
    for r, w in enumerate(words):
        keys[r, : len(w)] = w
        lengths[r] = len(w)
    return keys, lengths


def state_from_rng(rng: random.Random) -> tuple[np.ndarray, object]:
    """A copy of ``rng``'s state for the kernel, and the ``gauss`` part (which the kernel does not use)."""
    version, internal, gauss = rng.getstate()
    if version != 3 or len(internal) != STATE_SIZE:
        raise RuntimeError(f"unexpected random.Random state (version {version}, {len(internal)} entries)")
    return np.array(internal, dtype=np.int64), gauss


def state_to_rng(rng: random.Random, mt: np.ndarray, gauss: object) -> None:
    """Write a kernel state back into ``rng``, which then continues the stream exactly where the kernel stopped."""
    rng.setstate((3, tuple(mt.tolist()), gauss))
