"""
What a ``position=`` function costs the emotion callbacks on PPO/CartPole: PPO alone, then with ``EmotionCallback`` and
``BroekensCallback`` given the pole's side as a per-env callable (called for each env at each step) and as a
``BatchPosition`` (called once a step for all envs), in CPU time (``time.process_time``), the configurations' order
alternating from round to round so that the machine's load falls on each alike. Prints each configuration's median
CPU seconds and its overhead over PPO alone, and, steadier on a loaded machine, the CPU time spent inside the
callback's ``on_step`` within the same run (its share of ``learn``; the overhead it adds is share / (1 - share)).

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


def cpu_seconds(make_callback: Callable[[], Any], n_envs: int, steps: int) -> tuple[float, float]:
    """CPU seconds of ``learn(steps)``, and of it those inside the callback's ``on_step``."""
    model = PPO("MlpPolicy", make_vec_env("CartPole-v1", n_envs=n_envs, seed=0), n_steps=256, seed=0)
    callback = make_callback()
    inside = [0.0]
    if callback is not None:
        on_step = callback.on_step

        def timed_on_step() -> bool:
            begin = time.process_time()
            result = on_step()
            inside[0] += time.process_time() - begin
            return bool(result)

        callback.on_step = timed_on_step
    start = time.process_time()
    model.learn(steps, callback=callback)
    return time.process_time() - start, inside[0]


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
    shares: dict[str, list[float]] = {name: [] for name in names}
    for round_ in range(args.rounds):
        for name in names if round_ % 2 == 0 else names[::-1]:
            total, inside = cpu_seconds(CONFIGURATIONS[name], args.n_envs, args.steps)
            seconds[name].append(total)
            shares[name].append(inside / total)
    base = statistics.median(seconds["PPO alone"])
    print(f"PPO/CartPole, {args.n_envs} envs, {args.steps:,} steps, {args.rounds} rounds (median CPU seconds)")
    for name in names:
        median = statistics.median(seconds[name])
        share = statistics.median(shares[name])
        rounds = ", ".join(f"{value:.2f}" for value in seconds[name])
        print(f"{name:32s} {median:6.2f} s {100 * (median / base - 1):+6.1f}% over PPO alone; on_step "
              f"{100 * share:4.1f}% of learn, adding {100 * share / (1 - share):4.1f}%  (rounds: {rounds})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
