"""
The MiniGrid figures of ``benchmarks/bench.py --minigrid`` (needs the ``[minigrid]`` extra):

* ``AffectDQN`` against SB3's ``DQN`` on MiniGrid-Empty-8x8 (``FlatObsWrapper``) with 4 envs, same seed and settings,
  1 torch thread: env steps per second of ``learn``, in paired rounds (DQN then AffectDQN, back to back); the cost of
  the emotions is ``1 - AffectDQN / DQN`` (target: at most 10%);
* ``QLearning`` and ``AffectQ`` (Python engine: the compiled engine runs the package's grids only) on
  ``TabularMiniGrid(MiniGrid-Empty-8x8)``: decisions per second of ``learn`` against a bare loop over the same env
  (epsilon-greedy Q-learning in plain Python), in paired rounds;
* the compiled MiniGrid's step (``sb3_affect.minigrid_vec_env``) beside minigrid's (``benchmarks/bench_minigrid_step.py``);
* ``--learn``: SB3's own ``DQN.learn`` and ``PPO.learn`` (SB3's default settings but the buffer, ``learning_starts``
  and ``train_freq`` of the row above; 4 envs, torch on one thread) on Farama's env (``make_vec_env`` with
  ``FlatObsWrapper``, or ``ImageVector``, its first 147 entries) and on ``minigrid_vec_env`` (``obs="flat"``,
  ``obs="view"``), env steps per CPU second (``time.process_time``), in alternating rounds (Farama's, then the
  compiled env's); a ratio is the median of the rounds' ratios. Target: at least 2x.

    python benchmarks/bench_minigrid.py [--smoke] [--repeats N] [--learn]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable

import gymnasium as gym

ENV_ID = "MiniGrid-Empty-8x8-v0"


def deep_rate(agent: str, steps: int) -> Callable[[], float]:
    """Env steps per second of ``agent.learn(steps)`` on 4 envs (the model is built outside the timed part)."""
    import torch as th
    from minigrid.wrappers import FlatObsWrapper
    from stable_baselines3 import DQN
    from stable_baselines3.common.env_util import make_vec_env

    from sb3_affect import AffectDQN

    th.set_num_threads(1)

    def run() -> float:
        env = make_vec_env(ENV_ID, n_envs=4, seed=0, wrapper_class=FlatObsWrapper)
        common = {"learning_starts": 1000, "train_freq": 4, "seed": 0, "buffer_size": 50_000}
        if agent == "DQN":
            model = DQN("MlpPolicy", env, **common)
        else:
            model = AffectDQN("MlpPolicy", env, position="minigrid", wait_action=6, **common)
        start = time.perf_counter()
        model.learn(steps)
        return model.num_timesteps / (time.perf_counter() - start)

    return run


def tabular_env() -> gym.Env:
    import minigrid  # noqa: F401  (registers the envs)

    from sb3_affect import TabularMiniGrid

    return TabularMiniGrid(gym.make(ENV_ID))


def bare_rate(steps: int) -> float:
    """Decisions per second of the bare loop (``bench.bare_loop``) over ``TabularMiniGrid``."""
    from bench import bare_loop  # type: ignore[import-not-found]

    env = tabular_env()
    start = time.perf_counter()
    bare_loop(env, steps, alpha=0.1, gamma=0.99)
    return steps / (time.perf_counter() - start)


def tabular_rate(agent: str, steps: int) -> Callable[[], float]:
    from sb3_affect import AffectQ, QLearning

    cls = {"QLearning": QLearning, "AffectQ": AffectQ}[agent]

    def run() -> float:
        model = cls("Grid", tabular_env(), seed=0, engine="python")
        start = time.perf_counter()
        model.learn(steps)
        return model.num_timesteps / (time.perf_counter() - start)

    return run


def minigrid_rows(repeats: int, smoke: bool = False) -> list[tuple[str, float, str]]:
    """The rows of ``bench.py --minigrid``: (measure, value, note)."""
    deep_steps, tabular_steps = (400, 500) if smoke else (20_000, 20_000)
    measures: dict[str, Callable[[], float]] = {
        "dqn": deep_rate("DQN", deep_steps),
        "affect": deep_rate("AffectDQN", deep_steps),
        "bare": lambda: bare_rate(tabular_steps),
        "q": tabular_rate("QLearning", tabular_steps),
        "a": tabular_rate("AffectQ", tabular_steps),
    }
    rounds = []
    for i in range(repeats):
        r = {key: fn() for key, fn in measures.items()}
        rounds.append(r)
        print(
            f"minigrid round {i}: DQN {r['dqn']:,.0f} steps/s, AffectDQN {r['affect'] / r['dqn']:.3f} x DQN | "
            f"bare {r['bare']:,.0f}/s, QLearning {r['q'] / r['bare']:.2f} x bare, AffectQ {r['a'] / r['bare']:.2f} x bare",
            flush=True,
        )
    rate = {key: statistics.median(r[key] for r in rounds) for key in measures}
    cost = statistics.median(1 - r["affect"] / r["dqn"] for r in rounds)
    q_ratio = statistics.median(r["q"] / r["bare"] for r in rounds)
    a_ratio = statistics.median(r["a"] / r["bare"] for r in rounds)
    what = f"{ENV_ID}, FlatObsWrapper, 4 envs, {deep_steps:,} steps"
    from bench_minigrid_step import step_rows  # type: ignore[import-not-found]

    return [
        (f"DQN.learn, {what} (env steps/s)", rate["dqn"], "reference"),
        (f"AffectDQN.learn, {what} (env steps/s)", rate["affect"], f"cost of the emotions {cost:.1%} (target <= 10%)"),
        (f"bare loop on TabularMiniGrid({ENV_ID}) (decisions/s)", rate["bare"], "floor"),
        ("QLearning.learn on TabularMiniGrid, Python engine (decisions/s)", rate["q"], f"{q_ratio:.2f} x bare"),
        ("AffectQ.learn on TabularMiniGrid, Python engine (decisions/s)", rate["a"], f"{a_ratio:.2f} x bare"),
        *step_rows(repeats, smoke),
    ]


def learn_rate(algo: str, compiled: bool, obs: str, steps: int) -> Callable[[], float]:
    """Env steps per CPU second of SB3's ``algo.learn(steps)`` on 4 envs of Farama's or the compiled env."""
    import torch as th
    from stable_baselines3 import DQN, PPO

    from sb3_affect import minigrid_vec_env
    from sb3_affect.engine.seed_envs import seed_vec_env

    th.set_num_threads(1)

    def run() -> float:
        if compiled:
            env = minigrid_vec_env(ENV_ID, 4, seed=0, obs=obs)
        else:
            env = seed_vec_env(ENV_ID, 4, 0, "flat" if obs == "flat" else "view")
        if algo == "DQN":
            model = DQN("MlpPolicy", env, learning_starts=1000, train_freq=4, seed=0, buffer_size=50_000, device="cpu")
        else:
            model = PPO("MlpPolicy", env, seed=0, device="cpu", **({"n_steps": 64, "batch_size": 64} if steps < 2000 else {}))
        start = time.process_time()
        model.learn(steps)
        return model.num_timesteps / (time.process_time() - start)

    return run


def learn_rows(repeats: int, smoke: bool = False) -> list[tuple[str, float, str]]:
    """SB3's DQN and PPO ``learn`` on Farama's env and on the compiled one: (measure, value, note)."""
    import os

    steps = {"DQN": 400, "PPO": 512} if smoke else {"DQN": 10_000, "PPO": 8_192}
    rows = []
    for algo in ("DQN", "PPO"):
        for obs in ("flat", "view"):
            farama, compiled = learn_rate(algo, False, obs, steps[algo]), learn_rate(algo, True, obs, steps[algo])
            rounds = []
            for i in range(repeats):
                pair = (farama(), compiled())
                rounds.append(pair)
                print(f"learn round {i}: {algo} {obs}: Farama {pair[0]:,.0f}, compiled {pair[1]:,.0f} env steps per CPU s "
                      f"({pair[1] / pair[0]:.2f} x), load {os.getloadavg()[0]:.1f}", flush=True)
            ratio = statistics.median(c / f for f, c in rounds)
            what = f"{algo}.learn({steps[algo]:,}), {ENV_ID}, 4 envs, obs={obs}"
            rows.append((f"{what}, Farama's env (env steps per CPU s)", statistics.median(f for f, _ in rounds), "reference"))
            rows.append((f"{what}, minigrid_vec_env (env steps per CPU s)", statistics.median(c for _, c in rounds),
                         f"{ratio:.2f} x Farama's (target >= 2)"))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--smoke", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--learn", action="store_true", help="only SB3's learn on Farama's env and the compiled one")
    args = parser.parse_args(argv)
    if args.learn:
        for name, value, note in learn_rows(1 if args.smoke else args.repeats, args.smoke):
            print(f"{name:<100}  {value:>12,.1f}  {note}")
        return 0
    for name, value, note in minigrid_rows(1 if args.smoke else args.repeats, args.smoke):
        print(f"{name:<90}  {value:>12,.1f}  {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
