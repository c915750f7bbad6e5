"""
The agents on MiniGrid
======================

The package's agents on MiniGrid (needs ``pip install "sb3-affect[minigrid]"``): the tabular ``QLearning`` and
``AffectQ`` on ``TabularMiniGrid``, and with ``--deep`` SB3's ``DQN`` (epsilon-greedy, its default schedule) against
``AffectDQN`` on the ``FlatObsWrapper`` observation with 4 envs. Prints one Markdown table row per agent: the runs
whose greedy policy reaches the goal after learning, the mean return of the last 20 training episodes (deep agents:
the last 5 of each env) and the mean number of env steps before the first episode that reached the goal::

    python examples/minigrid_agents.py --env MiniGrid-Empty-8x8-v0 --seeds 5 --decisions 15000
    python examples/minigrid_agents.py --deep --seeds 3 --steps 50000
"""

from __future__ import annotations

import argparse
import statistics
from typing import Any

import gymnasium as gym
import minigrid  # noqa: F401  (registers the envs)
import numpy as np

from sb3_affect import AffectDQN, AffectQ, QLearning, TabularMiniGrid


def greedy_return(model: Any, env: gym.Env, seed: int) -> float:
    """The return of one greedy episode (MiniGrid's reward: 1 - 0.9 * steps / max_steps at the goal, else 0)."""
    obs, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        action, _ = model.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, _ = env.step(int(np.asarray(action).reshape(-1)[0]))
        total += float(reward)
        done = terminated or truncated
    return total


def tabular_row(agent: type, env_id: str, seeds: int, decisions: int) -> list[Any]:
    solved, last, first = 0, [], []
    for seed in range(seeds):
        env = TabularMiniGrid(gym.make(env_id))
        model = agent("Grid", env, seed=seed).learn(decisions)
        log = model.episode_log
        solved += greedy_return(model, env, 10_000 + seed) > 0
        last.append(float(log.reward.tail(20).mean()))
        goals = np.flatnonzero(log.reward.to_numpy() > 0)
        first.append(float(log.cells.to_numpy()[: goals[0] + 1].sum()) if len(goals) else float("nan"))
    return [agent.__name__, f"{solved}/{seeds}", statistics.mean(last), statistics.mean(first)]


def deep_row(agent: type, env_id: str, seeds: int, steps: int) -> list[Any]:
    import torch as th
    from minigrid.wrappers import FlatObsWrapper
    from stable_baselines3 import DQN
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.monitor import Monitor

    th.set_num_threads(1)
    solved, last, first = 0, [], []
    for seed in range(seeds):
        env = make_vec_env(env_id, n_envs=4, seed=seed, wrapper_class=FlatObsWrapper)
        extra = {} if agent is DQN else {"position": "minigrid", "wait_action": 6}
        model = agent("MlpPolicy", env, seed=seed, learning_starts=1000, **extra).learn(steps)
        solved += greedy_return(model, Monitor(FlatObsWrapper(gym.make(env_id))), 10_000 + seed) > 0
        rewards = [np.asarray(r, dtype=float) for r in env.env_method("get_episode_rewards")]
        lengths = [np.cumsum(n) for n in env.env_method("get_episode_lengths")]
        last.append(float(np.mean(np.concatenate([r[-5:] for r in rewards]))))  # the last 5 episodes of each env
        reached = [ends[np.flatnonzero(r > 0)[0]] for r, ends in zip(rewards, lengths) if (r > 0).any()]
        first.append(4.0 * min(reached) if reached else float("nan"))  # the 4 envs step together
    return [agent.__name__, f"{solved}/{seeds}", statistics.mean(last), statistics.mean(first)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="MiniGrid-Empty-8x8-v0")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--decisions", type=int, default=15_000, help="decisions per tabular run")
    parser.add_argument("--deep", action="store_true", help="DQN and AffectDQN instead of the tabular agents")
    parser.add_argument("--steps", type=int, default=50_000, help="env steps per deep run (all 4 envs together)")
    args = parser.parse_args()
    print("| agent | greedy policy reaches the goal | mean return, last 20 episodes | env steps to the first goal |")
    print("|---|---|---|---|")
    if args.deep:
        from stable_baselines3 import DQN

        rows = [deep_row(agent, args.env, args.seeds, args.steps) for agent in (DQN, AffectDQN)]
    else:
        rows = [tabular_row(agent, args.env, args.seeds, args.decisions) for agent in (QLearning, AffectQ)]
    for name, solved, last, first in rows:
        print(f"| {name} | {solved} | {last:.3f} | {first:,.0f} |")


if __name__ == "__main__":
    main()
