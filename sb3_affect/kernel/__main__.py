"""
``python -m sb3_affect.kernel``: compile (or load) every kernel of the compiled engine, and say how long it took.

On a cold cache that is about a CPU minute, most of it the tabular loops (the MiniGrid worlds take seconds); numba's
cache on disk keeps the result for every later process.
"""

import sys
import time

from sb3_affect.kernel import warm_up

print("sb3_affect: compiling every kernel (the tabular grid, moving-prey and team loops, the MiniGrid worlds) where numba's "
      "cache does not hold them yet: about a CPU minute the first time on a machine, seconds afterwards", file=sys.stderr,
      flush=True)
wall, cpu = time.perf_counter(), time.process_time()
warm_up(tabular=True, minigrid=True)
print(f"the compiled engine's kernels are ready ({time.process_time() - cpu:.0f} CPU s, {time.perf_counter() - wall:.0f} s)")
