"""
Known answer: the rooms example of the classic "Q-learning step by step" tutorial.

Source: Kardi Teknomo, "Q-Learning by Examples" (revoledu.com, people.revoledu.com/kardi/tutorial/ReinforcementLearning/),
retold by John McCullock, "A Painless Q-Learning Tutorial" (mnemstudio.org/path-finding-q-learning-tutorial.htm).
Five rooms 0..4 of a building and the outside, room 5; an action is the room to go to through a door. Entering 5
pays 100, every other door 0; 5 loops onto itself with 100. The tutorial's rule is Q(s, a) = R(s, a) + gamma * max
Q(s', .) with gamma = 0.8, i.e. Eq. 1 with alpha = 1, and an episode ends on reaching 5 *without* cutting the
bootstrap (the outside keeps its value), which for Eq. 1 is a truncation, not a termination. Its worked steps:
episode 1 starts in room 1 and goes to 5: Q(1, 5) = 100 + 0.8 * 0 = 100; episode 2 starts in room 3, goes to 1:
Q(3, 1) = 0 + 0.8 * max(Q(1, 3), Q(1, 5)) = 80, then to 5 (Q(1, 5) stays 100). After many episodes Q converges to
the matrix below (the tutorial also shows it normalised, divided by 5: 80, 100, 64, 51).
"""

from __future__ import annotations

import random
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

from sb3_affect import TabularQAlgorithm

R = [  # the tutorial's reward matrix, -1 where there is no door
    [-1, -1, -1, -1, 0, -1],
    [-1, -1, -1, 0, -1, 100],
    [-1, -1, -1, 0, -1, -1],
    [-1, 0, 0, -1, 0, -1],
    [0, -1, -1, 0, -1, 100],
    [-1, 0, -1, -1, 0, 100],
]
CONVERGED_Q = [
    [0, 0, 0, 0, 400, 0],
    [0, 0, 0, 320, 0, 500],
    [0, 0, 0, 320, 0, 0],
    [0, 400, 256, 0, 400, 0],
    [320, 0, 0, 320, 0, 500],
    [0, 400, 0, 0, 400, 500],
]
GOAL = 5


class Rooms(gym.Env):
    """The tutorial's building: observation and action are rooms; reaching 5 ends the episode as a truncation."""

    def __init__(self, starts: list[int] | None = None, seed: int = 0) -> None:
        self.observation_space = spaces.Discrete(6)
        self.action_space = spaces.Discrete(6)
        self.starts = list(starts or [])
        self.pick = random.Random(seed)
        self.s = 0

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[int, dict]:
        super().reset(seed=seed)
        self.s = self.starts.pop(0) if self.starts else self.pick.randrange(6)
        return self.s, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict]:
        if R[self.s][action] < 0:
            raise ValueError(f"no door from room {self.s} to room {action}")
        reward = float(R[self.s][action])
        self.s = int(action)
        return self.s, reward, False, self.s == GOAL, {}


class TutorialAgent(TabularQAlgorithm):
    """The tutorial's agent: alpha = 1, gamma = 0.8, a door chosen at random (or from a script), one room per decision."""

    def __init__(self, env: gym.Env, script: list[int] | None = None, **kwargs: Any) -> None:
        self.script = list(script or [])
        super().__init__("Grid", env, learning_rate=1.0, gamma=0.8, **kwargs)

    def _decide(self, state: int, q: list[list[float]]) -> tuple[int, int, bool]:
        if self.script:
            return self.script.pop(0), 1, False
        doors = [a for a in range(6) if R[state][a] >= 0]
        return doors[self._rng.randrange(len(doors))], 1, True


def test_the_tutorials_two_worked_episodes() -> None:
    agent = TutorialAgent(Rooms(starts=[1, 3]), script=[5, 1, 5], seed=0)
    agent.learn(3)
    q = agent.q_table
    assert q[1, 5] == 100.0  # episode 1
    assert q[3, 1] == 80.0  # episode 2
    assert np.count_nonzero(q) == 2
    assert agent.episode_log["cells"].tolist() == [1, 2]


def test_the_tutorials_converged_matrix() -> None:
    agent = TutorialAgent(Rooms(seed=1), seed=0)
    agent.learn(1_000_000, callback=StopTrainingOnMaxEpisodes(3000))
    assert agent.q_table == pytest.approx(np.array(CONVERGED_Q, dtype=float), rel=1e-9, abs=1e-9)
    normalised = np.round(agent.q_table / 5.0)
    assert normalised[3].tolist() == [0, 80, 51, 0, 80, 0]
