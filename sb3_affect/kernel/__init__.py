"""
The compiled engine: numba kernels of the tabular agents' learning loop (issue 11).

``sb3_affect/loop.py`` (``run_loop``) is the readable reference; the kernel runs the same
decisions with the same random draws and the same floating-point operations, so for a given seed both engines give
the identical episode log, Q-table, random-generator state and appraisal. Modules:

- ``mt19937``: CPython's ``random.Random`` (MT19937) in numba, the stream both engines draw from;
- ``affect``: the appraisal (known map, power fit) and Table II;
- ``loop``: the decision loop (every agent kind, the env's moves, Eq. 1, the episode rows);
- ``agents``: what the kernel needs to know about each agent class;
- ``state``: a model's state as arrays and back; ``bridge``: ``learn`` on the kernel; ``batch``: ``simulate``.

Compiled code is cached on disk (numba ``cache=True``, in ``__pycache__`` beside these files or numba's cache
folder), so only the first import on a machine pays the compilation.
"""



def warm_up() -> None:
    """
    Load every kernel now (compiling it, the first time on a machine), without building a model (no torch): for
    example in a launcher before it forks workers, so that each worker does not import numba and load the kernels
    again (seconds per process). Cheap once the cache is warm.
    """
    from sb3_affect.kernel.batch import warm_up as load

    load()
