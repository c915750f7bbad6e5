"""
``train_many`` (many seeds of DQN or PPO in lockstep, stacked networks) beside SB3's own ``learn`` on MiniGrid-Empty-8x8,
the 7x7x3 view flattened (``obs="view"``), 4 envs per seed (needs the ``[minigrid]`` extra), one torch thread.

* speed (default): env steps per CPU second of the process (so that other work on a shared machine counts less) and
  per wall second of SB3's ``DQN.learn`` and ``PPO.learn`` on Farama's env with 1 env (as a user runs it) and with 4,
  the same on the compiled MiniGrid with 4 (the compiled env inside SB3's own loop), and ``train_many`` DQN and PPO at
  S = 8, 32 and 128 seeds (all seeds' env steps, on the compiled MiniGrid, set-up included), each with its ratios to
  SB3's same algorithm with 1 env and with 4, and for SB3's ``learn`` the compiled env's gain with the share of that
  run its VecEnv's own steps take (random actions, timed alone) and the gain a VecEnv that cost nothing would give;
  then the DQN gradient step of S = 32 (and 128) stacked networks, in the
  state a run of the same steps leaves them (Adam's moments with their zeros and denormals),
  beside its arithmetic bound: its matrix products' FLOPs over the GFLOP/s this core measures on one large product; then
  the JAX rows, a vmapped JAX DQN on NAVIX's Empty-8x8 (``benchmarks/jax_dqn.py``: the same network, batch and train
  ratio, one XLA thread) at S = 8 and 32, its compile timed apart, and its own update step
  (``jax.jit(jax.vmap(update))`` on the seeds' state its run leaves, the same batch) beside the stacked gradient step of
  the same S, where ``jax``, ``navix`` and ``optax`` are installed
  (``pip install "sb3-affect[jax]"``; a line says so otherwise). ``--rows`` runs some of them only: ``sb3`` (SB3's
  ``learn``), ``many`` (``train_many``), ``gradient`` (the gradient step), ``jax``; ``--agents`` the algorithms.
* ``--equivalence [--algo PPO]``: 20 seeds of SB3's ``learn`` and of ``train_many`` with the same seeds and settings
  (both on the compiled MiniGrid, equal to Farama's step for step), the greedy policy evaluated on its own env
  (seed + 1000) every ``--every`` env steps over ``--episodes`` episodes, each run's curve summarised by its mean
  return (the area under the curve over its length); the two are equivalent within ``--margin`` (in return, on
  [0, 1]) by a paired TOST (two one-sided t-tests, scipy.stats, alpha 0.05): the 90% confidence interval of the mean
  difference lies inside ``(-margin, margin)``.

    python benchmarks/bench_many_seeds.py [--smoke] [--steps N] [--csv PATH] [--rows sb3,many,gradient,jax] [--agents PPO]
    python benchmarks/bench_many_seeds.py --equivalence [--algo DQN|PPO] [--seeds 20] [--steps 20000] [--every 5000]
"""

from __future__ import annotations

import argparse
import csv
import itertools
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
#: PPO's settings here (SB3's defaults otherwise): a rollout of 128 steps per env, 4 epochs of minibatches of 64
PPO_SETTINGS: dict[str, Any] = dict(n_steps=128, batch_size=64, n_epochs=4, learning_rate=3e-4, ent_coef=0.01)


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


def _settings(agent: str) -> dict[str, Any]:
    if agent == "PPO":
        return PPO_SETTINGS
    return {**SETTINGS, **(AFFECT if agent == "AffectDQN" else EPSILON)}


def sb3_rate(agent: str, steps: int, n_envs: int = N_ENVS, compiled: bool = False) -> Rate:
    """Env steps per second of ``agent.learn(steps)`` (SB3's loop, Farama's env or the compiled one; built outside)."""
    from sb3_affect.core.registry import resolve_class
    from sb3_affect.engine.seed_envs import seed_vec_env

    _threads()
    cls = resolve_class(agent)
    model = cls("MlpPolicy", seed_vec_env(ENV_ID, n_envs, 0, "view", compiled), seed=0, device="cpu", **_settings(agent))
    return _timed(lambda: model.learn(steps).num_timesteps)


def vec_env_cpu(steps: int, n_envs: int = N_ENVS, compiled: bool = True) -> float:
    """CPU seconds of the VecEnv alone for ``steps`` env steps of random actions (what ``learn`` pays for the env)."""
    from sb3_affect.engine.seed_envs import seed_vec_env

    env = seed_vec_env(ENV_ID, n_envs, 0, "view", compiled)
    actions = np.random.default_rng(0).integers(env.action_space.n, size=(steps // n_envs, n_envs))  # type: ignore[attr-defined]
    env.reset()
    cpu = time.process_time()
    for action in actions:
        env.step(action)
    return time.process_time() - cpu


def trainer_rate(agent: str, n_seeds: int, steps: int) -> Rate:
    """Env steps per second, all seeds together, of ``train_many(agent, ..., seeds=range(n_seeds))`` (set-up included)."""
    from sb3_affect import train_many

    _threads()

    def run() -> int:
        models = train_many(agent, ENV_ID, list(range(n_seeds)), N_ENVS, total_timesteps=steps, obs="view",
                            **_settings(agent))
        return sum(m.num_timesteps for m in models)

    return _timed(run)


def _cpu_ms(run: Callable[[], object], repeats: int) -> float:
    for _ in range(10):
        run()
    start = time.process_time()
    for _ in range(repeats):
        run()
    return (time.process_time() - start) / repeats * 1e3


def core_gflops() -> float:
    """GFLOP/s of one large float32 matrix product on one thread (the best of five): the core's arithmetic rate."""
    import torch as th

    _threads()
    a, b = th.randn(1024, 1024), th.randn(1024, 1024)
    return 2 * 1024**3 / min(_cpu_ms(lambda: a @ b, 5) for _ in range(5)) / 1e6


def step_flops(n_seeds: int, batch: int, sizes: list[int]) -> int:
    """
    The matrix products' FLOPs of one DQN gradient step of ``n_seeds`` MLPs of ``sizes``: the target network's and the
    online network's forward passes, the weight gradients and the input gradients of every layer but the first.
    """
    macs = [a * b for a, b in itertools.pairwise(sizes)]
    return 2 * n_seeds * batch * (3 * sum(macs) + sum(macs[1:]))


def gradient_step(n_seeds: int, steps: int, repeats: int = 100) -> tuple[float, float, float]:
    """
    CPU milliseconds of one batched gradient step of ``n_seeds`` stacked networks in the state a run leaves them
    (``train_many`` for ``steps`` env steps per seed: the weights and Adam's moments, whose entries for inputs not seen
    lately are exact zeros and denormals), on a batch of 32 random uint8 views with a third of the inputs 0 (the
    forward passes, the loss, backward, clipping and Adam), and of one greedy pass on a VecEnv step's observations
    (``n_seeds`` x 4): the arithmetic every trainer of these networks pays; and the share of Adam's first moments that
    are denormal at the start.
    """
    import torch as th

    from sb3_affect import train_many
    from sb3_affect.engine.stacked_q import StackedQ

    _threads()
    models = train_many("DQN", ENV_ID, list(range(n_seeds)), N_ENVS, total_timesteps=steps, obs="view",
                        **_settings("DQN"))
    stack = StackedQ(models)
    states = [[model.policy.optimizer.state[p] for p in model.q_net.parameters()] for model in models]
    stack.exp_avg = stack.rows([[s["exp_avg"] for s in state] for state in states])
    stack.exp_avg_sq = stack.rows([[s["exp_avg_sq"] for s in state] for state in states])
    stack.steps = int(states[0][0]["step"])
    magnitude = stack.exp_avg.abs()
    denormal = float(((magnitude > 0) & (magnitude < th.finfo(th.float32).tiny)).float().mean())
    arrays = _batch(n_seeds, models[0].observation_space.shape[0])  # type: ignore[index]
    batch = tuple(th.as_tensor(array) for array in arrays)
    observations = arrays[0][:, :N_ENVS]
    return (_cpu_ms(lambda: stack.train_step(*batch), repeats), _cpu_ms(lambda: stack.greedy(observations), repeats),
            denormal)


def _jax_available() -> bool:
    import importlib.util

    return all(importlib.util.find_spec(name) is not None for name in ("jax", "navix", "optax"))


def jax_rate(n_seeds: int, steps: int) -> tuple[Rate, float, Any]:
    """
    Env steps per second (all seeds') of the vmapped JAX DQN, its compile apart, the compile's CPU seconds, and the
    seeds' networks and optax states the timed run leaves.
    """
    from jax_dqn import dqn_many

    run = dqn_many(n_seeds, N_ENVS, steps, {**SETTINGS, **EPSILON})
    import jax

    cpu = time.process_time()
    jax.block_until_ready(run(0))  # the first call compiles
    compile_cpu = time.process_time() - cpu
    trained: list[Any] = []
    rate = _timed(lambda: (trained.append(jax.block_until_ready(run(1))), n_seeds * (steps // N_ENVS) * N_ENVS)[1])
    return rate, compile_cpu, trained[0]


def _batch(n_seeds: int, n_obs: int) -> tuple[np.ndarray, ...]:
    """
    The gradient steps' batch of 32 per seed, for the stacked step and JAX's alike: random uint8 views with a third
    of the inputs 0, random actions, no episode ended, random rewards: (obs, actions, next_obs, dones, rewards).
    """
    rng = np.random.default_rng(0)
    size = SETTINGS["batch_size"]
    views = rng.integers(0, 11, size=(2, n_seeds, size, n_obs), dtype=np.uint8)
    views[:, :, :, ::3] = 0
    return (views[0], rng.integers(7, size=(n_seeds, size, 1)), views[1], np.zeros((n_seeds, size, 1), np.float32),
            rng.random((n_seeds, size, 1), dtype=np.float32))


def jax_update_step(n_seeds: int, trained: Any, repeats: int = 100) -> float:
    """
    CPU milliseconds of ``jax.jit(jax.vmap(update))``, ``jax_dqn.py``'s own gradient step (the target's and the
    online network's forward passes, the Huber loss, its gradient, clipping and Adam as one XLA program) of
    ``n_seeds`` seeds in the state the JAX run left them, on the stacked step's batch; the compile excluded, each
    step waited for (``block_until_ready``).
    """
    import jax
    import jax.numpy as jnp
    from jax_dqn import dqn_update

    from sb3_affect.kernel.minigrid_view import VIEW_SIZE

    _, _, _, update = dqn_update({**SETTINGS, **EPSILON})
    step = jax.jit(jax.vmap(update))
    obs, actions, next_obs, dones, rewards = _batch(n_seeds, VIEW_SIZE)
    batch = (jnp.asarray(obs), jnp.asarray(actions[..., 0], jnp.int32), jnp.asarray(rewards[..., 0]),
             jnp.asarray(next_obs), jnp.asarray(dones[..., 0]))
    state = {"params": trained["params"], "opt": trained["opt"]}

    def once() -> None:
        state["params"], state["opt"] = jax.block_until_ready(step(state["params"], trained["target"], state["opt"], *batch))

    once()  # compiles
    return _cpu_ms(once, repeats)


#: the row groups ``--rows`` picks
ROWS = ("sb3", "many", "gradient", "jax")


def speed(steps: int, sizes: list[int], out: Path, groups: tuple[str, ...] = ROWS, agents: tuple[str, ...] = ("DQN", "PPO")
          ) -> None:
    """Every row's rates and their ratios to SB3's same algorithm with 1 env and with 4 envs, in one run."""
    trainer_rate("DQN", 2, 400)  # loads the compiled kernels and torch's first calls: no row pays for them
    trainer_rate("PPO", 2, 1024)
    rows: list[tuple[str, str, Rate]] = []  # (algorithm, run, rates)

    def row(agent: str, name: str, rate: Rate) -> None:
        rows.append((agent, name, rate))
        print(f"  ({agent} {name}: {rate.cpu:,.0f} per CPU s, {rate.wall:,.0f} per wall s)", flush=True)

    for agent in agents:
        if "sb3" in groups:
            row(agent, "SB3 learn, Farama, n_envs=1", sb3_rate(agent, steps, 1))
            row(agent, f"SB3 learn, Farama, n_envs={N_ENVS}", sb3_rate(agent, steps))
            row(agent, f"SB3 learn, compiled, n_envs={N_ENVS}", sb3_rate(agent, steps, compiled=True))
        for n_seeds in sizes if "many" in groups else []:
            row(agent, f"train_many, S={n_seeds}", trainer_rate(agent, n_seeds, steps))
    jax_compiles = []
    jax_steps: dict[int, float] = {}  # JAX's update step's CPU ms by S
    if "jax" in groups and "DQN" in agents and _jax_available():
        for n_seeds in sorted({min(8, sizes[-1]), min(32, sizes[-1])}):
            rate, compile_cpu, trained = jax_rate(n_seeds, steps)
            row("DQN", f"JAX vmapped, NAVIX, S={n_seeds} (compile apart)", rate)
            jax_compiles.append(f"S={n_seeds} {compile_cpu:.0f} CPU s")
            jax_steps[n_seeds] = jax_update_step(n_seeds, trained)
    print(f"{ENV_ID}, obs=view, {N_ENVS} envs per seed, {steps:,} env steps per seed, 1 torch thread, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} (a shared machine: CPU seconds are the measure)")
    header = ["algo", "run", "env_steps_per_cpu_s", "env_steps_per_wall_s", "cpu_x_sb3_1_env", "cpu_x_sb3_4_envs"]
    table = []
    for agent, name, rate in rows:
        one = next((r for a, n, r in rows if a == agent and n == "SB3 learn, Farama, n_envs=1"), None)
        four = next((r for a, n, r in rows if a == agent and n == f"SB3 learn, Farama, n_envs={N_ENVS}"), None)
        table.append([agent, name, f"{rate.cpu:.0f}", f"{rate.wall:.0f}", f"{rate.cpu / one.cpu:.1f}" if one else "",
                      f"{rate.cpu / four.cpu:.1f}" if four else ""])
    print("  " + " | ".join(header))
    for line in table:
        print("  " + " | ".join(map(str, line)))
    with out.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(header)
        writer.writerows(table)
    for agent in agents if "sb3" in groups else ():
        farama = next(r for a, n, r in rows if a == agent and n == f"SB3 learn, Farama, n_envs={N_ENVS}")
        compiled = next(r for a, n, r in rows if a == agent and n == f"SB3 learn, compiled, n_envs={N_ENVS}")
        env_cpu = vec_env_cpu(steps)
        ceiling = (steps / farama.cpu) / (steps / compiled.cpu - env_cpu)
        print(f"SB3 {agent}.learn with {N_ENVS} envs, compiled MiniGrid / Farama's: {compiled.cpu / farama.cpu:.2f}x (CPU); "
              f"the compiled VecEnv's own steps are {env_cpu * compiled.cpu / steps:.0%} of that run's CPU: a VecEnv "
              f"that cost nothing would make it {ceiling:.2f}x")
    if jax_compiles:
        print(f"JAX DQN compiles (once per S and step count, not in its rows): {', '.join(jax_compiles)}")
    elif "jax" in groups and "DQN" in agents:
        print("JAX DQN: jax, navix and optax are not installed, no row (pip install 'sb3-affect[jax]' to add it)")
    gflops = core_gflops() if "gradient" in groups else 0.0
    for n_seeds in sorted({min(32, sizes[-1]), sizes[-1]}) if "gradient" in groups else []:
        step_ms, greedy_ms, denormal = gradient_step(n_seeds, steps)
        flops = step_flops(n_seeds, SETTINGS["batch_size"], [147, 64, 64, 7])
        bound_ms = flops / gflops / 1e6
        per_step = N_ENVS * SETTINGS["train_freq"]  # env steps per seed between two gradient steps
        cap = n_seeds * per_step / ((step_ms + SETTINGS["train_freq"] * greedy_ms) / 1e3)
        print(f"the DQN gradient step, S={n_seeds}, batch {SETTINGS['batch_size']}, after {steps:,} env steps per seed "
              f"({denormal:.0%} of Adam's first moments denormal): {step_ms:.2f} ms of CPU; its "
              f"matrix products {flops / 1e6:.0f} MFLOP, {bound_ms:.2f} ms at this core's {gflops:.0f} GFLOP/s "
              f"({step_ms / bound_ms:.1f}x the bound); a greedy pass {greedy_ms:.2f} ms; one step and "
              f"{SETTINGS['train_freq']} greedy passes per {per_step} env steps of each seed cap any trainer at "
              f"{cap:,.0f} env steps per CPU second; load average {os.getloadavg()[0]:.1f}")
        if n_seeds in jax_steps:
            print(f"  JAX's update step, S={n_seeds}, same network and batch (jax.jit(jax.vmap(update)) of jax_dqn.py's "
                  f"own, after its run, compile excluded, block_until_ready): {jax_steps[n_seeds]:.2f} ms of CPU "
                  f"({jax_steps[n_seeds] / bound_ms:.1f}x the bound); the stacked step / JAX's: "
                  f"{step_ms / jax_steps[n_seeds]:.2f}")


def _evaluate(model: Any, seed: int, episodes: int) -> float:
    from stable_baselines3.common.evaluation import evaluate_policy

    from sb3_affect.engine.seed_envs import seed_vec_env

    mean, _ = evaluate_policy(model, seed_vec_env(ENV_ID, 1, seed + 1000, "view", compiled=True), n_eval_episodes=episodes)
    return float(mean)


def _learning(algo: str) -> dict[str, Any]:
    return {**PPO_SETTINGS, "gamma": 0.9} if algo == "PPO" else LEARNING


def sb3_curve(seed: int, steps: int, every: int, episodes: int, algo: str = "DQN") -> list[float]:
    """The greedy curve of SB3's ``learn`` with this seed (evaluated where ``train_many`` evaluates)."""
    from stable_baselines3.common.callbacks import BaseCallback

    from sb3_affect.core.registry import resolve_class
    from sb3_affect.engine.seed_envs import seed_vec_env

    _threads()
    curve: list[float] = []

    class Evaluate(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps // every > (self.num_timesteps - N_ENVS) // every:
                curve.append(_evaluate(self.model, seed, episodes))
            return True

    model = resolve_class(algo)("MlpPolicy", seed_vec_env(ENV_ID, N_ENVS, seed, "view", compiled=True), seed=seed,
                                device="cpu", **_learning(algo))
    model.learn(steps, callback=Evaluate())
    return curve


def equivalence(n_seeds: int, steps: int, every: int, episodes: int, margin: float, algo: str = "DQN") -> None:
    from concurrent.futures import ProcessPoolExecutor

    from scipy import stats

    from sb3_affect import train_many

    seeds = list(range(n_seeds))
    start = time.perf_counter()
    with ProcessPoolExecutor(2) as pool:
        theirs = np.array(list(pool.map(sb3_curve, seeds, [steps] * n_seeds, [every] * n_seeds, [episodes] * n_seeds,
                                        [algo] * n_seeds)))
    sb3_time = time.perf_counter() - start
    _threads()
    curves: list[list[float]] = []
    start = time.perf_counter()
    train_many(algo, ENV_ID, seeds, N_ENVS, total_timesteps=steps, obs="view", every=every,
               on_models=lambda models: curves.append([_evaluate(m, s, episodes) for m, s in zip(models, seeds)]),
               **_learning(algo))
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
    print(f"{algo}, {ENV_ID}, obs=view, {n_seeds} seeds x {N_ENVS} envs, {steps:,} env steps, greedy return every {every:,} "
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
    parser.add_argument("--algo", default="DQN", choices=["DQN", "PPO"], help="the equivalence's algorithm")
    parser.add_argument("--env", default=ENV_ID, help=f"the MiniGrid task (default {ENV_ID})")
    parser.add_argument("--rows", default=",".join(ROWS), help=f"the speed rows to run, of {','.join(ROWS)} (default all)")
    parser.add_argument("--agents", default="DQN,PPO", help="the speed rows' algorithms, of DQN,PPO (default both)")
    args = parser.parse_args(argv)
    ENV_ID = args.env
    groups, agents = tuple(args.rows.split(",")), tuple(args.agents.split(","))
    for option, chosen, allowed in (("--rows", groups, ROWS), ("--agents", agents, ("DQN", "PPO"))):
        for value in chosen:
            if value not in allowed:
                parser.error(f"{option} has {value!r}; allowed: {', '.join(allowed)}")
    if args.equivalence:
        steps = args.steps or (2000 if args.smoke else 100_000)
        equivalence(3 if args.smoke else args.seeds, steps, 1000 if args.smoke else args.every,
                    2 if args.smoke else args.episodes, args.margin, args.algo)
    else:
        steps = args.steps or (1200 if args.smoke else 8000)
        speed(steps, [1, 2] if args.smoke else [8, 32, 128], args.csv, groups, agents)
    return 0


if __name__ == "__main__":
    sys.exit(main())
