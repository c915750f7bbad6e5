"""
The compiled engine: numba kernels of the tabular agents' learning loop.

``sb3_affect/agents/reference_loop.py`` (``run_loop``) is the readable reference; the kernel runs the same
decisions with the same random draws and the same floating-point operations, so for a given seed both engines give
the identical episode log, Q-table, random-generator state and appraisal. Modules:

- ``mt19937``: CPython's ``random.Random`` (MT19937) in numba, the stream both engines draw from;
- ``affect``: the appraisal (known map, power fit, ``exp1`` and ``act``) and Table II (``feel``);
- ``agent_settings``: an agent as the kernel runs it (``AgentSettings``, which every world's configuration nests, and
  its behaviour rows), read from its settings object (``sb3_affect.core.settings``) by one builder (``kernel_agent``);
- ``state_layout``: the index tables of the run's state arrays and of an episode's row, and the prey's modes, which
  every world shares (each world adds only its own tail);
- ``choice`` and ``decision``: the decision step of every agent kind (``decide``), Eq. 1 (``q_update``) and the end
  of a single agent's episode (``end_episode``), which all three loops call;
- the grid (GridPursuit, MazePursuit): ``grid_loop`` (its decision loop), ``grid_arrays`` (its arguments, named tuples
  of arrays), ``grid_inputs`` (an env's transition table as arrays, a batch's inputs), ``grid_batch`` (many fresh runs
  in one call, ``simulate``'s);
- moving prey (MovingPursuit): ``moving_loop`` (its loop and arguments) and ``moving_batch`` (its inputs and batches);
- hunter teams (HunterPursuit): ``team_loop`` (its loop and arguments), ``team_env`` (the env's own pieces) and
  ``team_batch`` (its inputs and record columns); ``team_emotions``: the registry's emotion models observing each
  hunter, each from its kernel module (Broekens': ``td_emotions``).
- ``minigrid_world`` (the view: ``minigrid_view``): MiniGrid's Empty, FourRooms and DoorKey worlds, many stepped in one
  call (``sb3_affect.minigrid_vec_env``).

The kernel imports the core modules only (settings, registry, envs), never an agent class. ``learn`` on the kernel,
which needs SB3's objects (a model's state in and out, callbacks, the Monitor, the logger), is on the agents' side:
``sb3_affect.agents.compiled`` and ``sb3_affect.agents.compiled_state``.

Compiled code is cached on disk (numba ``cache=True``, in ``__pycache__`` beside these files or numba's cache
folder), so only the first import on a machine pays the compilation. numba checks a cached function against its own
file only, not against the functions it calls from the other files (a cached ``grid_batch.run_seeds`` would keep an old
``grid_loop.run``); so on import the kernel compares a digest of all its source files with the one its cache was built
from, and drops the cached code of every kernel file when they differ (``refresh_cache``).
"""

from __future__ import annotations

import contextlib
import hashlib
from pathlib import Path

_STAMP = "sb3_affect_kernel.sha256"


def refresh_cache(sources: Path, cache: Path) -> bool:
    """
    Remove numba's cached code (``*.nbi``, ``*.nbc``) from ``cache`` when the ``*.py`` files of ``sources`` are not
    those the cache was built from, and record their digest. Returns whether anything was removed.
    """
    digest = hashlib.sha256()
    for path in sorted(sources.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    stamp = cache / _STAMP
    with contextlib.suppress(OSError):
        if stamp.read_text() == digest.hexdigest():
            return False
    removed = False
    with contextlib.suppress(OSError):  # a cache folder we can not write: numba uses its own elsewhere
        cache.mkdir(exist_ok=True)  # (else a first run leaves no digest, and the second drops what the first compiled)
        for path in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            path.unlink(missing_ok=True)
            removed = True
        stamp.write_text(digest.hexdigest())
    return removed


refresh_cache(Path(__file__).parent, Path(__file__).parent / "__pycache__")


def warm_up(tabular: bool = True, minigrid: bool = True) -> None:
    """
    Load every kernel now (the grid, moving-prey and team kernels: ``tabular``; the MiniGrid worlds: ``minigrid``;
    compiling them, the first time on a machine), without building a model (no torch): for example in a launcher
    before it forks workers, so that each worker does not compile (on a cold cache) or load them again. Cheap once the
    cache is warm. ``make venv`` runs it once, so a first ``make replicate`` finds the kernels compiled
    (``python -m sb3_affect.kernel``, which compiles the two parts side by side on a machine of two cores or more).
    """
    if tabular:
        from sb3_affect.kernel.grid_batch import warm_up as grid
        from sb3_affect.kernel.moving_batch import warm_up as moving
        from sb3_affect.kernel.team_batch import warm_up as team

        for load in (grid, moving, team):
            load()
    if minigrid:
        from sb3_affect.kernel.minigrid_world import warm_up as worlds

        worlds()
