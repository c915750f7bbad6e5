"""
The benchmark's main rates in CPU time (``time.process_time``) instead of wall time, which other jobs on a shared
machine distort less; ratios are between runs of this one process.

    python benchmarks/cpu_time.py            # about a minute
    python benchmarks/cpu_time.py --seeds 1000   # also the paper protocol with 1,000 seeds per cell through simulate
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import ENV_ID, bare_loop, simulate_protocol

from sb3_affect import AffectQ, QLearning


def cpu_rate(make: Callable[[], Any], steps: int, repeats: int) -> float:
    """Median decisions per CPU second of ``make().learn(steps)`` (building the model is not timed)."""
    rates = []
    for _ in range(repeats):
        model = make()
        start = time.process_time()
        model.learn(steps)
        rates.append(steps / (time.process_time() - start))
    return statistics.median(rates)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seeds", type=int, default=0, help="also simulate the paper protocol with this many seeds per cell")
    args = parser.parse_args(argv)

    def env() -> gym.Env:
        return gym.make(ENV_ID)

    QLearning("Grid", env(), seed=0).learn(10)  # load (or compile) the kernel before timing it
    rates = []
    for _ in range(args.repeats):
        start = time.process_time()
        bare_loop(env(), args.steps)
        rates.append(args.steps / (time.process_time() - start))
    bare = statistics.median(rates)
    print(f"bare pure-Python loop: {bare:,.0f} decisions per CPU second")
    for cls in (QLearning, AffectQ):
        for engine in ("python", "compiled"):
            rate = cpu_rate(lambda: cls("Grid", env(), seed=0, engine=engine), args.steps, args.repeats)  # noqa: B023
            print(f"{cls.__name__}.learn, {engine}: {rate:,.0f} decisions per CPU second, {rate / bare:.2f} x bare")
    start = time.process_time()
    _, decisions = simulate_protocol(20)
    print(f"simulate, paper protocol (360 runs): {time.process_time() - start:.3f} CPU s, {decisions:,} decisions")
    if args.seeds:
        start = time.process_time()
        _, decisions = simulate_protocol(args.seeds)
        seconds = time.process_time() - start
        print(f"simulate, paper protocol, {args.seeds} seeds per cell: {seconds:.2f} CPU s, {decisions:,} decisions")
    return 0


if __name__ == "__main__":
    sys.exit(main())
