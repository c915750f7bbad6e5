"""
What a ``position=`` function costs the emotion callbacks on PPO/CartPole: PPO alone, then with ``EmotionCallback`` and
``BroekensCallback`` given the pole's side as a per-env callable (called for each env at each step) and as a
``BatchPosition`` (called once a step for all envs), in CPU time (``time.process_time``), the configurations' order
alternating from round to round so that the machine's load falls on each alike. Prints each configuration's median
CPU seconds and its overhead over PPO alone.

    python benchmarks/bench_position.py                    # 8 envs, 3 rounds of 8,192 steps: about 3 CPU minutes
    python benchmarks/bench_position.py --n-envs 1 --rounds 5
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings
from collections.abc import Callable
from typing import Any

import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

from sb3_affect import BroekensCallback, EmotionCallback
from sb3_affect.core.positions import BatchPosition


def side(observation: Any, info: dict[str, Any]) -> int:
    """The pole's side (its angle's sign) of one env."""
    return int(observation[2] > 0)


def sides(observations: Any, infos: Any) -> Any:
    """The pole's side of every env, one NumPy expression."""
    return observations[:, 2] > 0


CONFIGURATIONS: dict[str, Callable[[], Any]] = {
    "PPO alone": lambda: None,
    "EmotionCallback, callable": lambda: EmotionCallback(position=side, goal=lambda r, i: False, warn_after=None),
    "EmotionCallback, BatchPosition": lambda: EmotionCallback(position=BatchPosition(sides), goal=lambda r, i: False,
                                                              warn_after=None),
    "BroekensCallback, callable": lambda: BroekensCallback(position=side),
    "BroekensCallback, BatchPosition": lambda: BroekensCallback(position=BatchPosition(sides)),
}


def cpu_seconds(make_callback: Callable[[], Any], n_envs: int, steps: int) -> float:
    model = PPO("MlpPolicy", make_vec_env("CartPole-v1", n_envs=n_envs, seed=0), n_steps=256, seed=0)
    callback = make_callback()
    start = time.process_time()
    model.learn(steps, callback=callback)
    return time.process_time() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-envs", type=int, default=8)
    parser.add_argument("--steps", type=int, default=8192)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    warnings.simplefilter("ignore")
    names = list(CONFIGURATIONS)
    seconds: dict[str, list[float]] = {name: [] for name in names}
    for round_ in range(args.rounds):
        for name in names if round_ % 2 == 0 else names[::-1]:
            seconds[name].append(cpu_seconds(CONFIGURATIONS[name], args.n_envs, args.steps))
    base = statistics.median(seconds["PPO alone"])
    print(f"PPO/CartPole, {args.n_envs} envs, {args.steps:,} steps, {args.rounds} rounds (median CPU seconds)")
    for name in names:
        median = statistics.median(seconds[name])
        rounds = ", ".join(f"{value:.2f}" for value in seconds[name])
        print(f"{name:34s} {median:7.2f} s  {100 * (median / base - 1):+6.1f}% over PPO alone  (rounds: {rounds})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
