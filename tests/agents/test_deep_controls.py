"""
The exploration controls of the deep affective agents (``sb3_affect.agents.deep_controls``) and the reversed Table III:
real SB3 DQN on a real env, the executed actions read from a wrapper.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from scipy.stats import chisquare
from stable_baselines3 import DQN

from sb3_affect import AffectQ, Emotion
from sb3_affect.agents.deep_controls import EzGreedyDQN, SpeedEpsilonGreedyDQN, zeta_probabilities
from sb3_affect.core.behaviour import BEHAVIOUR_TABLES, TABLE_III, TABLE_III_REVERSED

NO_TRAINING = {"gradient_steps": 0}  # the rule alone: no gradient step in these short runs


class Endless(gym.Env):
    """One observation, three actions, no episode end: every executed action is recorded."""

    observation_space = spaces.Box(0.0, 1.0, (1,), np.float32)
    action_space = spaces.Discrete(3)

    def __init__(self) -> None:
        self.actions: list[int] = []

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        super().reset(seed=seed)
        return np.zeros(1, np.float32), {}

    def step(self, action: Any) -> Any:
        self.actions.append(int(action))
        return np.zeros(1, np.float32), 0.0, False, False, {}


def recorded(cls: type) -> type:
    """``cls`` recording each decision ``(random_direction, speed)`` its rule makes."""

    class Recorded(cls):  # type: ignore[misc, valid-type]
        def _decide(self, index: int) -> tuple[bool, int]:
            decision = super()._decide(index)
            self.decisions.append(decision)
            return decision

    Recorded.decisions = []  # type: ignore[attr-defined]
    return Recorded


def expanded(decisions: list[tuple[bool, int]], actions: list[int]) -> list[int]:
    """
    The actions the decisions should execute: each decision's first action, ``speed`` times (up to the last action
    executed: training may stop in a repeat).
    """
    out: list[int] = []
    for _, speed in decisions:
        out.extend([actions[len(out)]] * max(speed, 1))
    return out[: len(actions)]


def run(cls: type, steps: int, **kwargs: Any) -> tuple[Any, Endless]:
    th.set_num_threads(1)
    env = Endless()
    model = cls("MlpPolicy", env, learning_starts=10, seed=0, policy_kwargs={"net_arch": [8]}, **NO_TRAINING, **kwargs)
    model.learn(steps)
    return model, env


def test_ez_greedy_durations_follow_the_zeta_distribution_and_are_executed() -> None:
    model, env = run(recorded(EzGreedyDQN), 6000, exploration_initial_eps=1.0, exploration_final_eps=1.0, mu=2.0,
                     max_duration=10)
    decisions = model.decisions
    assert all(random for random, _ in decisions)  # epsilon 1: every decision is random
    durations = np.array([speed for _, speed in decisions])
    observed = np.bincount(durations, minlength=11)[1:]
    expected = zeta_probabilities(2.0, 10) * len(durations)
    assert chisquare(observed, expected).pvalue > 0.001  # a chi-square test at the 0.1% level
    assert observed[0] > observed[1] > observed[2] and observed[9] > 0  # heavy-tailed: long repeats do occur
    after_warm_up = env.actions[10:]
    assert after_warm_up == expanded(decisions, after_warm_up)


def test_ez_greedy_without_epsilon_is_dqn_without_epsilon() -> None:
    greedy = {"exploration_initial_eps": 0.0, "exploration_final_eps": 0.0}
    ez, ez_env = run(EzGreedyDQN, 300, **greedy)
    dqn, dqn_env = run(DQN, 300, **greedy)
    assert ez_env.actions == dqn_env.actions
    np.testing.assert_array_equal(ez.replay_buffer.actions, dqn.replay_buffer.actions)


def test_ez_greedy_reads_dqn_epsilon_schedule() -> None:
    """SB3's linear schedule from 1 to 0 over the first half: random decisions early, none at the end."""
    model, _ = run(recorded(EzGreedyDQN), 2000, exploration_initial_eps=1.0, exploration_final_eps=0.0,
                   exploration_fraction=0.5)
    randoms = [random for random, _ in model.decisions]
    assert np.mean(randoms[:50]) > 0.8 and not any(randoms[-300:])


def test_speed_matched_control_repeats_one_or_two_steps_in_an_epsilon_greedy_direction() -> None:
    model, env = run(recorded(SpeedEpsilonGreedyDQN), 3000, exploration_initial_eps=0.3, exploration_final_eps=0.3)
    decisions = model.decisions
    speeds = np.array([speed for _, speed in decisions])
    assert set(speeds.tolist()) == {1, 2}
    assert chisquare(np.bincount(speeds)[1:]).pvalue > 0.001  # uniform over 1 and 2
    share = np.mean([random for random, _ in decisions])
    assert abs(share - 0.3) < 4 * np.sqrt(0.3 * 0.7 / len(decisions))
    after_warm_up = env.actions[10:]
    assert after_warm_up == expanded(decisions, after_warm_up)


def test_controls_keep_their_options_through_save_and_load(tmp_path: Any) -> None:
    model, _ = run(EzGreedyDQN, 40, mu=1.5, max_duration=4)
    model.save(tmp_path / "ez.zip")
    loaded = EzGreedyDQN.load(tmp_path / "ez.zip")
    assert (loaded.mu, loaded.max_duration) == (1.5, 4)
    np.testing.assert_allclose(loaded._durations, zeta_probabilities(1.5, 4))
    speed, _ = run(SpeedEpsilonGreedyDQN, 40, speeds=[0, 1, 2], wait_action=0)
    speed.save(tmp_path / "speed.zip")
    loaded_speed = SpeedEpsilonGreedyDQN.load(tmp_path / "speed.zip")
    assert (loaded_speed.speeds, loaded_speed.wait_action) == ([0, 1, 2], 0)


@pytest.mark.parametrize(
    ("cls", "kwargs", "message"),
    [
        (EzGreedyDQN, {"mu": 0}, r"^mu=0 must be a finite number > 0"),
        (EzGreedyDQN, {"mu": float("inf")}, r"^mu=inf must be a finite number > 0"),
        (EzGreedyDQN, {"max_duration": 0}, r"^max_duration=0 must be an integer in \[1, "),
        (SpeedEpsilonGreedyDQN, {"speeds": []}, r"^speeds=\[\] must be a non-empty list of integers"),
        (SpeedEpsilonGreedyDQN, {"speeds": "12"}, r"^speeds='12' must be a non-empty list of integers"),
    ],
)
def test_controls_refuse_bad_options_in_one_line(cls: type, kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        cls("MlpPolicy", Endless(), **kwargs)


def test_reversed_table_iii_swaps_the_directions_and_keeps_the_speeds() -> None:
    for emotion in Emotion:
        assert TABLE_III_REVERSED[emotion].random_direction is not TABLE_III[emotion].random_direction
        assert TABLE_III_REVERSED[emotion].speeds == TABLE_III[emotion].speeds
    assert not TABLE_III_REVERSED[Emotion.JOY].random_direction and TABLE_III_REVERSED[Emotion.FEAR].random_direction
    model = AffectQ("Grid", "sb3_affect/GridPursuit-v0", behaviour_table="table-iii-reversed")
    assert model.behaviour_table == {e.name.lower(): [b.random_direction, b.speeds] for e, b in TABLE_III_REVERSED.items()}
    with pytest.raises(ValueError, match=r"^behaviour_table='table-3' is not a named table; the names are table-iii, "):
        AffectQ("Grid", "sb3_affect/GridPursuit-v0", behaviour_table="table-3")
    assert set(BEHAVIOUR_TABLES) == {"table-iii", "table-iii-reversed"}
