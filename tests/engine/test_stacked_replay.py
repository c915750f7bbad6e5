"""``StackedReplay.release`` gives each buffer its transitions and frees the stacked arrays as it copies them."""

from __future__ import annotations

import subprocess
import sys
import textwrap

#: a process that fills 4 seeds' stacked buffers of 40 MB each, then releases them, printing its peak RSS (KB) around it
SCRIPT = textwrap.dedent("""
    import resource, types
    import numpy as np
    from gymnasium import spaces
    from stable_baselines3.common.buffers import ReplayBuffer
    from sb3_affect.engine.stacked_replay import StackedReplay

    rows, seeds = 20_000, 4
    space = spaces.Box(0, 255, (1000,), np.uint8)
    models = [types.SimpleNamespace(replay_buffer=ReplayBuffer(rows, space, spaces.Discrete(7), n_envs=1))
              for _ in range(seeds)]
    replay = StackedReplay(models, rows)
    for row in range(rows):
        obs = np.full((seeds, 1, 1000), row % 251, dtype=np.uint8)
        replay.add(obs, obs, np.full((seeds, 1), row % 7), np.ones((seeds, 1)), np.zeros((seeds, 1)), np.zeros((seeds, 1)))
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    replay.release()
    after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    buffers = [m.replay_buffer for m in models]
    assert all(b.full and b.pos == 0 for b in buffers)
    assert all((b.observations[:, 0, 0] == np.arange(rows) % 251).all() for b in buffers)
    assert all((b.actions[:, 0, 0] == np.arange(rows) % 7).all() for b in buffers)
    print(before, after)
""")


def test_release_frees_as_it_copies() -> None:
    """Releasing 160 MB of stacked buffers (observations and next observations of 4 seeds) raises the peak RSS by less
    than two seeds' share (copying before freeing would raise it by all four), and every buffer holds its rows."""
    result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True)
    before, after = (int(value) for value in result.stdout.split())
    seed_kb = 2 * 20_000 * 1000 / 1024
    assert after - before < 2 * seed_kb, (before, after)
