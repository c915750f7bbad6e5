"""``python -m sb3_affect.kernel``: compile (or load) every kernel of the compiled engine, and say how long it took."""

import time

from sb3_affect.kernel import warm_up

start = time.perf_counter()
warm_up()
print(f"the compiled engine's kernels are ready ({time.perf_counter() - start:.0f} s)")
