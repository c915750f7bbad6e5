"""
``train_many`` (many seeds of DQN in lockstep, stacked Q-networks) beside SB3's own ``learn`` on MiniGrid-Empty-8x8,
the 7x7x3 view (``obs="image"``), 4 envs per seed (needs the ``[minigrid]`` extra).

* speed (default): env steps per CPU second of the process (so that other work on a shared machine counts less) and
  per wall second, with 1 and with 2 torch threads, of SB3's ``DQN.learn`` on Farama's env with 1 env (as a user runs
  it) and with 4, SB3's ``AffectDQN.learn`` with 4, and ``train_many`` at S = 1, 8 and 32 seeds (all seeds' env
  steps, on the compiled MiniGrid, set-up included), each with its ratios to SB3's DQN with 1 env and with 4 (each at
  the thread count of its faster wall time), all in one run;
* ``--equivalence``: 20 seeds of SB3's ``DQN.learn`` and of ``train_many`` with the same seeds and settings (both on
  the compiled MiniGrid, equal to Farama's step for step, and training at every VecEnv step), the greedy
  policy evaluated on its own env (seed + 1000) every ``--every`` env steps over ``--episodes`` episodes, each run's
  curve summarised by its mean return (the area under the curve over its length); the two are equivalent within
  ``--margin`` (in return, on [0, 1]) by a paired TOST (two one-sided t-tests, scipy.stats, alpha 0.05): the 90%
  confidence interval of the mean difference lies inside ``(-margin, margin)``.

    python benchmarks/bench_many_seeds.py [--smoke] [--steps N] [--csv PATH]
    python benchmarks/bench_many_seeds.py --equivalence [--seeds 20] [--steps 20000] [--every 5000] [--margin 0.1]
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

ENV_ID = "MiniGrid-Empty-8x8-v0"
N_ENVS = 4
#: the settings of every run here (SB3's DQN defaults otherwise): a DQN that learns Empty-8x8 within 20,000 steps
SETTINGS: dict[str, Any] = dict(learning_starts=1000, buffer_size=50_000, learning_rate=1e-3, target_update_interval=1000,
                                batch_size=32, train_freq=4)
EPSILON: dict[str, Any] = dict(exploration_fraction=0.3)
#: the equivalence runs take the deep study's shared settings and its Empty-8x8 picks (gamma 0.9: with 0.99 no greedy policy
#: reaches the goal within these budgets, and the equivalence would be an empty one)
LEARNING: dict[str, Any] = {**SETTINGS, "batch_size": 64, "gamma": 0.9, "exploration_fraction": 0.5}
AFFECT: dict[str, Any] = dict(position="minigrid", wait_action=6)


def _threads(n: int = 1) -> None:
    import torch as th

    th.set_num_threads(n)


class Rate(NamedTuple):
    """A run's env steps (all seeds') per CPU second of the process and per wall second."""

    cpu: float
    wall: float


def _timed(run: Callable[[], int]) -> Rate:
    cpu, wall = time.process_time(), time.perf_counter()
    steps = run()
    return Rate(steps / (time.process_time() - cpu), steps / (time.perf_counter() - wall))


def sb3_rate(agent: str, steps: int, n_envs: int = N_ENVS, threads: int = 1) -> Rate:
    """Env steps per second of ``agent.learn(steps)`` (SB3's loop, Farama's env; the model built outside)."""
    from sb3_affect.core.registry import resolve_class
    from sb3_affect.engine.seed_envs import seed_vec_env

    _threads(threads)
    cls = resolve_class(agent)
    extra = AFFECT if agent == "AffectDQN" else EPSILON
    model = cls("MlpPolicy", seed_vec_env(ENV_ID, n_envs, 0, "image"), seed=0, device="cpu", **SETTINGS, **extra)
    return _timed(lambda: model.learn(steps).num_timesteps)


def trainer_rate(agent: str, n_seeds: int, steps: int, threads: int = 1) -> Rate:
    """Env steps per second, all seeds together, of ``train_many(agent, ..., seeds=range(n_seeds))`` (set-up included)."""
    from sb3_affect import train_many

    _threads(threads)
    extra = AFFECT if agent == "AffectDQN" else EPSILON

    def run() -> int:
        models = train_many(agent, ENV_ID, list(range(n_seeds)), N_ENVS, total_timesteps=steps, obs="image",
                            **SETTINGS, **extra)
        return sum(m.num_timesteps for m in models)

    return _timed(run)


def gradient_floor(n_seeds: int, repeats: int = 200) -> tuple[float, float]:
    """
    CPU milliseconds of one batched gradient step of ``n_seeds`` stacked networks (batch 32, random uint8 views; the
    forward passes, the loss, backward, clipping and Adam) and of one greedy pass on a VecEnv step's observations
    (``n_seeds`` x 4): the arithmetic every trainer of these networks pays, whatever its loop.
    """
    import torch as th
    from stable_baselines3 import DQN

    from sb3_affect.engine.seed_envs import seed_vec_env
    from sb3_affect.engine.stacked_q import StackedQ

    _threads()
    models = [DQN("MlpPolicy", seed_vec_env(ENV_ID, 1, seed, "image", compiled=True), seed=seed, device="cpu",
                  learning_rate=SETTINGS["learning_rate"]) for seed in range(n_seeds)]
    stack = StackedQ(models)
    rng = np.random.default_rng(0)
    size, n_obs = SETTINGS["batch_size"], models[0].observation_space.shape[0]  # type: ignore[index]
    views = [rng.integers(0, 11, size=(n_seeds, size, n_obs), dtype=np.uint8) for _ in range(2)]
    batch = (th.as_tensor(views[0]), th.as_tensor(rng.integers(7, size=(n_seeds, size, 1))), th.as_tensor(views[1]),
             th.zeros(n_seeds, size, 1), th.as_tensor(rng.random((n_seeds, size, 1), dtype=np.float32)))
    observations = views[0][:, :N_ENVS]

    def cpu_ms(run: Callable[[], object]) -> float:
        for _ in range(10):
            run()
        start = time.process_time()
        for _ in range(repeats):
            run()
        return (time.process_time() - start) / repeats * 1e3

    return cpu_ms(lambda: stack.train_step(*batch)), cpu_ms(lambda: stack.greedy(observations))


def speed(steps: int, sizes: list[int], out: Path) -> None:
    """Every row's rates, and their ratios to SB3's DQN with 1 env (as a user runs it) and with 4 envs, in one run."""
    trainer_rate("DQN", 2, 400)  # loads the compiled kernels and torch's first calls: no row pays for them
    rows: list[tuple[str, int, Rate]] = []  # (run, torch threads, rates)

    def row(name: str, threads: int, rate: Rate) -> None:
        rows.append((name, threads, rate))
        print(f"  ({name}, {threads} torch threads: {rate.cpu:,.0f} per CPU s, {rate.wall:,.0f} per wall s)", flush=True)

    for threads in (1, 2):
        row("SB3 DQN.learn, n_envs=1", threads, sb3_rate("DQN", steps, 1, threads))
        row(f"SB3 DQN.learn, n_envs={N_ENVS}", threads, sb3_rate("DQN", steps, threads=threads))
    row(f"SB3 AffectDQN.learn, n_envs={N_ENVS}", 1, sb3_rate("AffectDQN", steps))
    for agent in ("DQN", "AffectDQN"):
        for n_seeds in sizes:
            row(f"train_many {agent}, S={n_seeds}", 1, trainer_rate(agent, n_seeds, steps))
        row(f"train_many {agent}, S={sizes[-1]}", 2, trainer_rate(agent, sizes[-1], steps, threads=2))
    one = max((rate for name, _, rate in rows if name == "SB3 DQN.learn, n_envs=1"), key=lambda r: r.wall)
    four = max((rate for name, _, rate in rows if name == f"SB3 DQN.learn, n_envs={N_ENVS}"), key=lambda r: r.wall)
    print(f"{ENV_ID}, obs=image, {N_ENVS} envs per seed, {steps:,} env steps per seed, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}; ratios to SB3's DQN at its best thread count (the faster wall time)")
    header = ["run", "torch_threads", "env_steps_per_cpu_s", "env_steps_per_wall_s", "cpu_x_sb3_dqn_1_env",
              "cpu_x_sb3_dqn_4_envs", "wall_x_sb3_dqn_1_env", "wall_x_sb3_dqn_4_envs"]
    table = [[name, threads, f"{rate.cpu:.0f}", f"{rate.wall:.0f}", f"{rate.cpu / one.cpu:.1f}", f"{rate.cpu / four.cpu:.1f}",
              f"{rate.wall / one.wall:.1f}", f"{rate.wall / four.wall:.1f}"] for name, threads, rate in rows]
    print("  " + " | ".join(header))
    for row in table:
        print("  " + " | ".join(map(str, row)))
    with out.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(table)
    step_ms, greedy_ms = gradient_floor(sizes[-1])
    per_step = N_ENVS * SETTINGS["train_freq"]  # env steps per seed between two gradient steps
    cap = sizes[-1] * per_step / ((step_ms + SETTINGS["train_freq"] * greedy_ms) / 1e3)
    print(f"the arithmetic alone, S={sizes[-1]}, 1 torch thread: a batched gradient step {step_ms:.2f} ms of CPU, a "
          f"greedy pass {greedy_ms:.2f} ms; one gradient step and {SETTINGS['train_freq']} greedy passes per "
          f"{per_step} env steps of each seed cap any trainer at {cap:,.0f} env steps per CPU second "
          f"({cap / one.cpu:.0f}x SB3's DQN with 1 env, {cap / four.cpu:.0f}x with {N_ENVS})")


def _evaluate(model: Any, seed: int, episodes: int) -> float:
    from stable_baselines3.common.evaluation import evaluate_policy

    from sb3_affect.engine.seed_envs import seed_vec_env

    mean, _ = evaluate_policy(model, seed_vec_env(ENV_ID, 1, seed + 1000, "image", compiled=True), n_eval_episodes=episodes)
    return float(mean)


def sb3_curve(seed: int, steps: int, every: int, episodes: int) -> list[float]:
    """The greedy curve of SB3's ``DQN.learn`` with this seed (evaluated where ``train_many`` evaluates)."""
    from stable_baselines3 import DQN
    from stable_baselines3.common.callbacks import BaseCallback

    from sb3_affect.engine.seed_envs import seed_vec_env

    _threads()
    curve: list[float] = []

    class Evaluate(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps // every > (self.num_timesteps - N_ENVS) // every:
                curve.append(_evaluate(self.model, seed, episodes))
            return True

    model = DQN("MlpPolicy", seed_vec_env(ENV_ID, N_ENVS, seed, "image", compiled=True), seed=seed, device="cpu", **LEARNING)
    model.learn(steps, callback=Evaluate())
    return curve


def equivalence(n_seeds: int, steps: int, every: int, episodes: int, margin: float) -> None:
    from concurrent.futures import ProcessPoolExecutor

    from scipy import stats

    from sb3_affect import train_many

    seeds = list(range(n_seeds))
    start = time.perf_counter()
    with ProcessPoolExecutor(2) as pool:
        theirs = np.array(list(pool.map(sb3_curve, seeds, [steps] * n_seeds, [every] * n_seeds, [episodes] * n_seeds)))
    sb3_time = time.perf_counter() - start
    _threads()
    curves: list[list[float]] = []
    start = time.perf_counter()
    train_many("DQN", ENV_ID, seeds, N_ENVS, total_timesteps=steps, obs="image", every=every,
               on_models=lambda models: curves.append([_evaluate(m, s, episodes) for m, s in zip(models, seeds)]),
               **LEARNING)
    trainer_time = time.perf_counter() - start
    ours = np.array(curves).T
    differences = ours.mean(axis=1) - theirs.mean(axis=1)
    mean, sd = differences.mean(), differences.std(ddof=1)
    if sd > 0:
        p_lower = stats.ttest_1samp(differences, -margin, alternative="greater").pvalue
        p_upper = stats.ttest_1samp(differences, margin, alternative="less").pvalue
        half = stats.t.ppf(0.95, n_seeds - 1) * sd / np.sqrt(n_seeds)
    else:
        p_lower = p_upper = 0.0 if abs(mean) < margin else 1.0
        half = 0.0
    p_value = max(p_lower, p_upper)
    print(f"{ENV_ID}, obs=image, {n_seeds} seeds x {N_ENVS} envs, {steps:,} env steps, greedy return every {every:,} "
          f"steps over {episodes} episodes; SB3 {sb3_time:.0f} s (2 processes), train_many {trainer_time:.0f} s (1)")
    print("  SB3's curve (mean over seeds):       ", np.round(theirs.mean(axis=0), 3).tolist())
    print("  train_many's curve (mean over seeds):", np.round(ours.mean(axis=0), 3).tolist())
    print(f"  seeds whose curves differ: {int((np.abs(ours - theirs).max(axis=1) > 0).sum())} of {n_seeds}")
    print(f"  mean return difference (train_many - SB3) {mean:+.4f}, 90% CI [{mean - half:+.4f}, {mean + half:+.4f}]; "
          f"TOST p = {p_value:.4f} for margin {margin}: {'equivalent' if p_value < 0.05 else 'NOT shown equivalent'}")


def main(argv: list[str] | None = None) -> int:
    global ENV_ID
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--smoke", action="store_true", help="tiny sizes: checks the script runs")
    parser.add_argument("--steps", type=int, default=None, help="env steps per seed (speed 8,000; equivalence 100,000)")
    parser.add_argument("--csv", type=Path, default=Path(__file__).with_name("results_many_seeds.csv"))
    parser.add_argument("--equivalence", action="store_true", help="greedy curves of train_many and SB3 over seeds")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--every", type=int, default=10_000)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--margin", type=float, default=0.1)
    parser.add_argument("--env", default=ENV_ID, help=f"the MiniGrid task (default {ENV_ID})")
    args = parser.parse_args(argv)
    ENV_ID = args.env
    if args.equivalence:
        steps = args.steps or (2000 if args.smoke else 100_000)
        equivalence(3 if args.smoke else args.seeds, steps, 1000 if args.smoke else args.every,
                    2 if args.smoke else args.episodes, args.margin)
    else:
        steps = args.steps or (1200 if args.smoke else 8000)
        speed(steps, [1, 2] if args.smoke else [1, 8, 32], args.csv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
