"""
Shared by the ports of Stable-Baselines3's and sb3-contrib's algorithm-generic tests (``tests/test_sb3_*.py``).

The ports keep the structure and the assertions of the originals (named in each test's docstring) and run them on
every tabular agent of the package, on sb3_affect/GridPursuit-v0 and on Gymnasium's toy-text envs with Discrete
observations. Where a case does not apply to a tabular agent it is skipped with the reason in the skip message.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.logger import Logger

import sb3_affect  # noqa: F401  (registers the envs)
from sb3_affect import AffectQ, QLearning, TabularQAlgorithm
from sb3_affect.agents.baselines import Boltzmann, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy, UCBQLearning

#: Every tabular agent of the package.
ALGOS: list[type[TabularQAlgorithm]] = [
    QLearning,
    AffectQ,
    Boltzmann,
    DecayingEpsilonGreedy,
    OptimisticQLearning,
    SpeedEpsilonGreedy,
    UCBQLearning,
]

#: The package's own env and Gymnasium's toy-text envs with a Discrete observation space (Blackjack's is a Tuple).
ENV_IDS = ["sb3_affect/GridPursuit-v0", "FrozenLake-v1", "FrozenLake8x8-v1", "CliffWalking-v1", "Taxi-v4"]

#: Agents exploring epsilon-greedily, whose ``predict`` honours ``exploration_rate`` as DQN's does.
EPSILON_ALGOS = [QLearning, DecayingEpsilonGreedy, OptimisticQLearning, SpeedEpsilonGreedy]

SKIP_MULTI_ENV = "tabular agents learn on a single env (support_multi_env=False), like SB3's DQN with one env"
SKIP_REPLAY_BUFFER = "tabular agents have no replay buffer: every transition updates the Q-table at once"
SKIP_Q_NET = "tabular agents have no q_net: the Q-table is a buffer of the policy itself (tested via the policy)"
SKIP_CNN = "tabular agents take Discrete observations only: no images, no CnnPolicy"
SKIP_SDE = "tabular agents have no state-dependent exploration (gSDE is for continuous actions)"
SKIP_BOX = "tabular agents need Discrete spaces; a Box space is refused at construction"
SKIP_VECNORMALIZE = "normalising a Discrete observation (a cell index) has no meaning for a Q-table lookup"


def make_model(algo: type[TabularQAlgorithm], env: Any, **kwargs: Any) -> TabularQAlgorithm:
    """An agent with a short safety cap (CliffWalking has no time limit), so every test stays quick."""
    kwargs.setdefault("max_episode_decisions", 300)
    return algo("Grid", env, **kwargs)


class InMemoryLogger(Logger):
    """Logger that keeps key/value pairs in memory without any writers (SB3's tests/test_logger.py)."""

    def __init__(self) -> None:
        super().__init__("", [])

    def dump(self, step: int = 0) -> None:
        pass


class DummySuccessEnv(gym.Env):
    """
    SB3's tests/test_logger.py env: Discrete spaces; each episode lasts ``ep_steps`` steps and ends truncated with
    ``info["is_success"]`` taken from ``dummy_successes[log_id][ep_id]``.
    """

    def __init__(self, dummy_successes: list[list[bool]], ep_steps: int) -> None:
        self.n_steps = 0
        self.log_id = 0
        self.ep_id = 0
        self.ep_steps = ep_steps
        self.dummy_success = dummy_successes
        self.num_logs = len(dummy_successes)
        self.ep_per_log = len(dummy_successes[0])
        self.steps_per_log = self.ep_per_log * self.ep_steps
        self.action_space = spaces.Discrete(2)
        self.observation_space = spaces.Discrete(2)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[int, dict]:
        super().reset(seed=seed)
        self.n_steps = 0
        if self.ep_id == self.ep_per_log:
            self.ep_id = 0
            self.log_id = (self.log_id + 1) % self.num_logs
        return int(self.observation_space.sample()), {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict]:
        self.n_steps += 1
        truncated = self.n_steps >= self.ep_steps
        info: dict[str, Any] = {}
        if truncated:
            info["is_success"] = self.dummy_success[self.log_id][self.ep_id]
            self.ep_id += 1
        return int(self.observation_space.sample()), 0.0, False, truncated, info


def observations(env_id: str, n: int = 10, seed: int = 0) -> np.ndarray:
    """``n`` observations of ``env_id`` met along a random walk, as a batch (SB3's tests take 10 from a VecEnv)."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    seen = []
    for _ in range(n):
        seen.append(int(obs))
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return np.array(seen)


def eval_env(env_id: str) -> gym.Env:
    """An evaluation env with a time limit: a greedy policy may walk into a wall forever (GridPursuit and
    CliffWalking have no time limit of their own)."""
    return gym.make(env_id, max_episode_steps=100)
