"""
Speed benchmark (issue 5): decisions per second of the SB3-interface learn loops against a bare pure-Python loop and
SB3's DQN, plus the wall time of the paper protocol.

    python benchmarks/bench.py                 # full run (a few minutes), table on stdout, CSV in benchmarks/results.csv
    python benchmarks/bench.py --smoke         # seconds: tiny sizes, no protocol (what the test suite runs)

Every figure is the median of repeated runs in this one process; ratios are between figures of the same run.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import random
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym

import sb3_affect
from sb3_affect import AffectQ, QLearning

ENV_ID = "sb3_affect/GridPursuit-v0"


def bare_loop(env: gym.Env, steps: int, epsilon: float = 0.1, alpha: float = 1.0, gamma: float = 0.8, seed: int = 0) -> int:
    """The floor: epsilon-greedy tabular Q-learning in plain Python (lists, ``random``, ``env.step``)."""
    rng = random.Random(seed)
    n_actions = int(env.action_space.n)  # type: ignore[attr-defined]
    q = [[0.0] * n_actions for _ in range(int(env.observation_space.n))]  # type: ignore[attr-defined]
    s = int(env.reset(seed=seed)[0])
    for _ in range(steps):
        row = q[s]
        if rng.random() < epsilon:
            a = rng.randrange(n_actions)
        else:
            best = max(row)
            a = row.index(best) if row.count(best) == 1 else rng.choice([i for i, v in enumerate(row) if v == best])
        obs, r, terminated, truncated, _ = env.step(a)
        s2 = int(obs)
        target = r if terminated else r + gamma * max(q[s2])
        row[a] += alpha * (target - row[a])
        s = s2
        if terminated or truncated:
            s = int(env.reset()[0])
    return steps


def timed(fn: Callable[[], int], repeats: int) -> float:
    """Median units per second of ``fn`` (which returns the units it did) over ``repeats`` runs."""
    rates = []
    for _ in range(repeats):
        start = time.perf_counter()
        units = fn()
        rates.append(units / (time.perf_counter() - start))
    return statistics.median(rates)


def learn_rate(cls: type, steps: int, **kwargs: object) -> Callable[[], int]:
    def run() -> int:
        model = cls("Grid", gym.make(ENV_ID), seed=0, **kwargs)
        model.learn(steps)
        return int(model.num_timesteps)

    return run


def dqn_rate(steps: int) -> Callable[[], int]:
    import torch as th
    from stable_baselines3 import DQN

    th.set_num_threads(1)

    def run() -> int:
        model = DQN("MlpPolicy", gym.make(ENV_ID), learning_starts=100, seed=0)
        model.learn(steps)
        return int(model.num_timesteps)

    return run


def protocol_seconds(workers: int) -> float | None:
    """Wall time of experiments/paper.yaml (360 runs) with the launcher, or None if the launcher is not there."""
    try:
        from sb3_affect.experiments import run_sweep
    except ImportError:
        return None
    sweep = Path(__file__).resolve().parents[1] / "experiments" / "paper.yaml"
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        run_sweep(sweep, Path(out) / "paper", workers=workers, progress=False)
        return time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes, no protocol: checks the script runs")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--csv", type=Path, default=Path(__file__).with_name("results.csv"))
    args = parser.parse_args(argv)
    steps, dqn_steps, repeats = (3000, 300, 1) if args.smoke else (200_000, 5000, args.repeats)

    rows: list[tuple[str, float, str]] = []
    bare = timed(lambda: bare_loop(gym.make(ENV_ID), steps), repeats)
    rows.append(("bare pure-Python loop (decisions/s)", bare, "floor"))
    q_rate = timed(learn_rate(QLearning, steps, exploration_rate=0.1), repeats)
    rows.append(("QLearning.learn (decisions/s)", q_rate, f"{q_rate / bare:.2f} x bare (target >= 0.5)"))
    a_rate = timed(learn_rate(AffectQ, steps), repeats)
    rows.append(("AffectQ.learn (decisions/s)", a_rate, f"{a_rate / bare:.2f} x bare (target >= 0.3)"))
    d_rate = timed(dqn_rate(dqn_steps), max(1, repeats // 2))
    rows.append(("SB3 DQN.learn (steps/s, 1 torch thread)", d_rate, "reference"))
    rows.append(("QLearning / DQN", q_rate / d_rate, "target >= 100"))
    rows.append(("AffectQ / DQN", a_rate / d_rate, "target >= 100"))
    if not args.smoke:
        for workers in (1, 2):
            seconds = protocol_seconds(workers)
            if seconds is None:
                rows.append((f"paper protocol, {workers} worker(s) (s)", float("nan"), "launcher not installed"))
            else:
                rows.append((f"paper protocol, {workers} worker(s) (s)", seconds, "360 runs x 200 episodes (target < 60 s)"))

    cores = os.cpu_count()
    print(f"sb3-affect {sb3_affect.__version__} | Python {platform.python_version()} | {cores} cores | {platform.machine()}")
    print(f"median of {repeats} run(s); {steps} decisions per tabular run, {dqn_steps} DQN steps per run")
    width = max(len(name) for name, _, _ in rows)
    for name, value, note in rows:
        print(f"{name:<{width}}  {value:>12,.1f}  {note}")
    args.csv.parent.mkdir(parents=True, exist_ok=True)
    with args.csv.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["measure", "value", "note", "cores", "repeats"])
        for name, value, note in rows:
            writer.writerow([name, f"{value:.3f}", note, cores, repeats])
    return 0


if __name__ == "__main__":
    sys.exit(main())
