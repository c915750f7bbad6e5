"""
``python -m sb3_affect.kernel``: compile (or load) every kernel of the compiled engine, and say how long it took.

On a cold cache that is minutes of CPU, most of a fresh machine's set-up: with two or more usable cores the MiniGrid
worlds compile in a second process beside the tabular loops (about half the CPU each; the two parts share no kernel
file, and numba's cache on disk is what both fill). This process then loads every kernel from that cache, which also
compiles anything a part left out.
"""

import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

from sb3_affect.kernel import warm_up


def compile_part(tabular: bool) -> float:
    """Compile the tabular kernels (``tabular``) or the MiniGrid worlds into numba's cache; the CPU seconds it took."""
    start = time.process_time()
    warm_up(tabular=tabular, minigrid=not tabular)
    return time.process_time() - start


print("sb3_affect: compiling every kernel (the tabular grid, moving-prey and team loops, the MiniGrid worlds) where numba's "
      "cache does not hold them yet: minutes of CPU the first time on a machine, seconds afterwards", file=sys.stderr,
      flush=True)
wall = time.perf_counter()
cpu = 0.0
if len(os.sched_getaffinity(0)) >= 2:
    with ProcessPoolExecutor(2) as pool:
        cpu = sum(pool.map(compile_part, (True, False)))
cpu += compile_part(True) + compile_part(False)
print(f"the compiled engine's kernels are ready ({cpu:.0f} CPU s, {time.perf_counter() - wall:.0f} s)")
