"""
``train_many`` (many seeds of DQN in lockstep, stacked Q-networks) beside SB3's own ``learn`` on MiniGrid-Empty-8x8,
the 7x7x3 view (``obs="image"``), 4 envs per seed, 1 torch thread per process (needs the ``[minigrid]`` extra).

* speed (default): env steps per CPU second (the process's CPU time, so that other work on a shared machine does not
  count; one thread, so it is the wall time on an idle core) of SB3's ``DQN`` and ``AffectDQN`` ``learn`` on Farama's
  env, and of ``train_many`` at S = 1, 8 and 32 seeds (all seeds' env steps, on the compiled MiniGrid), and each
  figure's ratio to SB3's DQN;
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
from pathlib import Path
from typing import Any

import numpy as np

ENV_ID = "MiniGrid-Empty-8x8-v0"
N_ENVS = 4
#: the settings of every run here (SB3's DQN defaults otherwise): a DQN that learns Empty-8x8 within 20,000 steps
SETTINGS: dict[str, Any] = dict(learning_starts=1000, buffer_size=50_000, learning_rate=1e-3, target_update_interval=1000,
                                batch_size=32, train_freq=4)
EPSILON: dict[str, Any] = dict(exploration_fraction=0.3)
#: the equivalence runs train once per VecEnv step (4 env steps), so 20,000 steps are 4,750 gradient steps
LEARNING: dict[str, Any] = {**SETTINGS, "train_freq": 1, "exploration_fraction": 0.5}
AFFECT: dict[str, Any] = dict(position="minigrid", wait_action=6)


def _threads() -> None:
    import torch as th

    th.set_num_threads(1)


def sb3_rate(agent: str, steps: int) -> float:
    """Env steps per CPU second of ``agent.learn(steps)`` (SB3's loop, Farama's env; the model built outside)."""
    from sb3_affect.core.registry import resolve_class
    from sb3_affect.engine.seed_envs import seed_vec_env

    _threads()
    cls = resolve_class(agent)
    extra = AFFECT if agent == "AffectDQN" else EPSILON
    model = cls("MlpPolicy", seed_vec_env(ENV_ID, N_ENVS, 0, "image"), seed=0, device="cpu", **SETTINGS, **extra)
    start = time.process_time()
    model.learn(steps)
    return model.num_timesteps / (time.process_time() - start)


def trainer_rate(agent: str, n_seeds: int, steps: int) -> float:
    """Env steps per CPU second, all seeds together, of ``train_many(agent, ..., seeds=range(n_seeds))`` (set-up included)."""
    from sb3_affect import train_many

    _threads()
    extra = AFFECT if agent == "AffectDQN" else EPSILON
    start = time.process_time()
    models = train_many(agent, ENV_ID, list(range(n_seeds)), N_ENVS, total_timesteps=steps, obs="image",
                        **SETTINGS, **extra)
    return sum(m.num_timesteps for m in models) / (time.process_time() - start)


def speed(steps: int, sizes: list[int], out: Path) -> None:
    rows: list[tuple[str, float, float]] = []
    base = sb3_rate("DQN", steps)
    rows.append(("SB3 DQN.learn", base, 1.0))
    affect = sb3_rate("AffectDQN", steps)
    rows.append(("SB3 AffectDQN.learn", affect, affect / base))
    for agent in ("DQN", "AffectDQN"):
        for n_seeds in sizes:
            rate = trainer_rate(agent, n_seeds, steps)
            rows.append((f"train_many {agent} S={n_seeds}", rate, rate / base))
    print(f"{ENV_ID}, obs=image, {N_ENVS} envs per seed, {steps:,} env steps per seed, 1 torch thread, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}")
    for name, rate, ratio in rows:
        print(f"  {name:<32} {rate:>10,.0f} env steps per CPU second  {ratio:>7.1f}x SB3's DQN")
    with out.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["measure", "env_steps_per_cpu_s", "ratio_to_sb3_dqn"])
        writer.writerows((name, f"{rate:.1f}", f"{ratio:.2f}") for name, rate, ratio in rows)


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
    parser.add_argument("--steps", type=int, default=None, help="env steps per seed (speed 8,000; equivalence 20,000)")
    parser.add_argument("--csv", type=Path, default=Path(__file__).with_name("results_many_seeds.csv"))
    parser.add_argument("--equivalence", action="store_true", help="greedy curves of train_many and SB3 over seeds")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--every", type=int, default=5000)
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--margin", type=float, default=0.1)
    parser.add_argument("--env", default=ENV_ID, help=f"the MiniGrid task (default {ENV_ID})")
    args = parser.parse_args(argv)
    ENV_ID = args.env
    if args.equivalence:
        steps = args.steps or (2000 if args.smoke else 20_000)
        equivalence(3 if args.smoke else args.seeds, steps, 1000 if args.smoke else args.every,
                    2 if args.smoke else args.episodes, args.margin)
    else:
        steps = args.steps or (1200 if args.smoke else 8000)
        speed(steps, [1, 2] if args.smoke else [1, 8, 32], args.csv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
