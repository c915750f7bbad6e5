"""
The table probe: memory and time of ``learn(500)`` on a ``Discrete(10**7)`` observation space (a chain env of the
probe's own; the Python loop), for QLearning and AffectQ, each in a fresh process. The Q-table itself is
10**7 x 4 float64 = 320 MB; the target is the table plus a bounded overhead over a small model's process.

    python benchmarks/bench_table.py                 # QLearning and AffectQ at 10**7 states, and the 100-state base
    python benchmarks/bench_table.py --states 1000000

Seconds: building the model and ``learn(500)``, first-use imports included. Measured on the 2-core development
machine (loaded by other jobs, so seconds vary by 2x): before the Python loop kept only visited rows (and the known
map only seen states), QLearning 30.7 s and 3,201 MB peak RSS, AffectQ 61.3 s and 6,214 MB; after, QLearning 1.6 to
3.3 s and 668 to 674 MB, AffectQ 1.7 to 3.5 s and 745 to 750 MB, against 363 to 368 MB for a 100-state model: the
table (320 MB) plus, for AffectQ, its known map's distance per state (80 MB).
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from typing import Any

import gymnasium as gym
from gymnasium import spaces


class Chain(gym.Env):
    """``n`` states in a chain; an action moves 1-4 states on; an episode ends every 97 states."""

    def __init__(self, n: int) -> None:
        self.observation_space, self.action_space, self.s = spaces.Discrete(n), spaces.Discrete(4), 0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.s = 0
        return 0, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        self.s = (self.s + 1 + int(action)) % int(self.observation_space.n)
        done = self.s % 97 == 0
        return self.s, float(done), done, False, {}


def probe(algo: str, states: int) -> str:
    """One measurement in this process: ``algo states seconds peak_mb``."""
    import sb3_affect

    start = time.perf_counter()
    model = getattr(sb3_affect, algo)("Grid", Chain(states), seed=0)
    model.learn(500)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return f"{algo} {states} {seconds:.2f} {peak:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--states", type=int, default=10**7)
    parser.add_argument("--one", nargs=2, metavar=("ALGO", "STATES"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(probe(args.one[0], int(args.one[1])))
        return
    print(f"{'algo':10s} {'states':>10s} {'seconds':>8s} {'peak MB':>8s}  (table: {args.states * 4 * 8 / 1e6:.0f} MB)")
    for algo, states in (("QLearning", 100), ("QLearning", args.states), ("AffectQ", args.states)):
        out = subprocess.run([sys.executable, __file__, "--one", algo, str(states)], capture_output=True, text=True)
        name, n, seconds, peak = out.stdout.split() if out.returncode == 0 else (algo, str(states), "error", "-")
        print(f"{name:10s} {int(n):>10,d} {seconds:>8s} {peak:>8s}")


if __name__ == "__main__":
    main()
