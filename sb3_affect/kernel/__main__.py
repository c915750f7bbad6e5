"""``python -m sb3_affect.kernel``: compile (or load) every kernel of the compiled engine, and say how long it took."""

import sys
import time

from sb3_affect.kernel import warm_up

print("sb3_affect: compiling every kernel (the tabular grid, moving-prey and team loops, the MiniGrid worlds) where numba's "
      "cache does not hold them yet: minutes of CPU the first time on a machine, seconds afterwards", file=sys.stderr,
      flush=True)
start = time.process_time()
warm_up()
print(f"the compiled engine's kernels are ready ({time.process_time() - start:.0f} CPU s)")
