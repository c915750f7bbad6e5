"""``StackedReplay.release`` hands each model its slice of the stacked arrays, or, where only the rows training reaches
could be mapped, copies each seed's transitions into its own buffer, freeing the stacked arrays as it copies them."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

#: a process that fills 4 seeds' stacked buffers of 40 MB each, then releases them, printing its peak RSS (KB) around it
#: (``short``: the buffers' own size is refused, so the slices hold the 20,001 rows reached of 40,000)
SCRIPT = textwrap.dedent("""
    import resource, sys, types
    import numpy as np
    from gymnasium import spaces
    from stable_baselines3.common.buffers import ReplayBuffer
    from sb3_affect.engine.stacked_replay import StackedReplay

    rows, seeds, short = 20_000, 4, sys.argv[1] == "short"
    if short:
        mapped = StackedReplay._map
        def refuse_full_size(replay, count):
            if count == replay.size:
                raise OSError(12, "Cannot allocate memory")
            return mapped(replay, count)
        StackedReplay._map = refuse_full_size
    space = spaces.Box(0, 255, (1000,), np.uint8)
    size = 2 * rows if short else rows
    # buffers built of one row, as train_many builds them: the stacked arrays give them the models' buffer_size
    models = [types.SimpleNamespace(buffer_size=size, replay_buffer=ReplayBuffer(1, space, spaces.Discrete(7), n_envs=1))
              for _ in range(seeds)]
    replay = StackedReplay(models, rows + 1)  # the rows reached and one more, as a trainer gives them
    assert replay.rows == (rows + 1 if short else rows)
    for row in range(rows):
        obs = np.full((seeds, 1, 1000), row % 251, dtype=np.uint8)
        replay.add(obs, obs, np.full((seeds, 1), row % 7), np.ones((seeds, 1)), np.zeros((seeds, 1)), np.zeros((seeds, 1)))
    stacked = replay.arrays["observations"]
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    replay.release()
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    buffers = [m.replay_buffer for m in models]
    assert all(b.buffer_size == size and len(b.observations) == size for b in buffers)
    assert all((b.full, b.pos) == ((False, rows) if short else (True, 0)) for b in buffers)
    assert all((b.observations[:rows, 0, 0] == np.arange(rows) % 251).all() for b in buffers)
    assert all((b.actions[:rows, 0, 0] == np.arange(rows) % 7).all() for b in buffers)
    assert all(np.shares_memory(b.observations, stacked) != short for b in buffers)
    assert not short or not stacked[:, 8:-8].any(), "the copied slices' whole pages were not given back (they read as 0)"
    print(before, after)
""")

#: one seed's observations and next observations, KB
SEED_KB = 2 * 20_000 * 1000 / 1024


@pytest.mark.parametrize(("mode", "bound"), [("full", 0.05 * SEED_KB), ("short", 2 * SEED_KB)])
def test_release(mode: str, bound: float) -> None:
    """Releasing 160 MB of stacked buffers (observations and next observations of 4 seeds): handing the slices over
    raises the peak RSS by nearly nothing; copying them raises it by less than two seeds' share (copying before freeing
    would raise it by all four); every buffer holds its rows, at its own size."""
    result = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, check=True)
    before, after = (int(value) for value in result.stdout.split())
    assert after - before < bound, (before, after)
