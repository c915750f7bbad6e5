"""
AffectQRDQN's per-step cost against QR-DQN's (and AffectDQN's against DQN's), with the zoo's shipped MiniGrid settings
(``sb3_affect.integrations.zoo.hyperparams``: 4 envs, FlatObsWrapper, batch 64, train_freq 4), in CPU time
(``time.process_time``), the agents' rounds alternating so that the machine's load falls on each alike. Also how much of
each step is the gradient step (``train``), where QR-DQN's quantile loss is.

    python benchmarks/bench_zoo_qrdqn.py                 # about 3 CPU minutes
    python benchmarks/bench_zoo_qrdqn.py --steps 8000 --rounds 3
"""

from __future__ import annotations

import argparse
import statistics
import time
from typing import Any

import torch as th
from minigrid.wrappers import FlatObsWrapper
from sb3_contrib import QRDQN
from stable_baselines3 import DQN
from stable_baselines3.common.env_util import make_vec_env

from sb3_affect import AffectDQN, AffectQRDQN
from sb3_affect.integrations.zoo import hyperparams

ENV_ID = "MiniGrid-Empty-8x8-v0"


def settings(algo: str) -> dict[str, Any]:
    """The package's zoo keywords of ``algo`` on ``ENV_ID`` (``hyperparams``, without the zoo's own keys)."""
    params = dict(hyperparams(algo)[ENV_ID])
    for key in ("env_wrapper", "n_envs", "n_timesteps", "policy"):
        params.pop(key, None)
    return params


def build(name: str) -> Any:
    env = make_vec_env(ENV_ID, n_envs=4, seed=0, wrapper_class=FlatObsWrapper)
    affect = settings("affectqrdqn" if "QRDQN" in name else "affectdqn")
    plain = {key: value for key, value in affect.items() if key not in ("position", "wait_action")}
    cls = {"DQN": DQN, "AffectDQN": AffectDQN, "QRDQN": QRDQN, "AffectQRDQN": AffectQRDQN}[name]
    return cls("MlpPolicy", env, seed=0, **(affect if name.startswith("Affect") else plain))


def timed(name: str, steps: int) -> tuple[float, float]:
    """CPU seconds per env step of ``learn(steps)`` (after ``learning_starts``), and the share of it in ``train``."""
    model = build(name)
    model.learn(model.learning_starts)  # the warm-up's random actions: not timed
    spent = [0.0]
    train = model.train

    def timed_train(*args: Any, **kwargs: Any) -> None:
        start = time.process_time()
        train(*args, **kwargs)
        spent[0] += time.process_time() - start

    model.train = timed_train
    start = time.process_time()
    model.learn(steps, reset_num_timesteps=False)
    total = time.process_time() - start
    return total / steps, spent[0] / total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=4000, help="env steps timed per run (after learning_starts)")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)
    th.set_num_threads(1)
    names = ("DQN", "AffectDQN", "QRDQN", "AffectQRDQN")
    per_step: dict[str, list[float]] = {name: [] for name in names}
    in_train: dict[str, list[float]] = {name: [] for name in names}
    for round_ in range(args.rounds):
        for name in names if round_ % 2 == 0 else tuple(reversed(names)):
            cost, share = timed(name, args.steps)
            per_step[name].append(cost)
            in_train[name].append(share)
    median = {name: statistics.median(values) for name, values in per_step.items()}
    for name in names:
        print(f"{name:12s} {1000 * median[name]:7.3f} CPU ms per env step  ({100 * statistics.median(in_train[name]):.0f}% "
              f"in train)  rounds: {', '.join(f'{1000 * v:.3f}' for v in per_step[name])}")
    print(f"AffectDQN / DQN {median['AffectDQN'] / median['DQN']:.2f} x;  AffectQRDQN / QRDQN "
          f"{median['AffectQRDQN'] / median['QRDQN']:.2f} x;  QRDQN / DQN {median['QRDQN'] / median['DQN']:.2f} x;  "
          f"AffectQRDQN / AffectDQN {median['AffectQRDQN'] / median['AffectDQN']:.2f} x")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
