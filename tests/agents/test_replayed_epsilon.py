"""ReplayedEpsilonDQN: SB3's DQN whose epsilon is a given list of values, one per equal part of training."""

from __future__ import annotations

import pytest

from sb3_affect.agents.replayed_epsilon import ReplayedEpsilonDQN


def test_epsilon_follows_the_given_values_part_by_part_of_training() -> None:
    model = ReplayedEpsilonDQN("MlpPolicy", "CartPole-v1", epsilons=[0.9, 0.4, 0.1], learning_starts=0, seed=0)
    assert [model.exploration_schedule(p) for p in (1.0, 0.7, 0.6, 0.3, 0.0)] == [0.9, 0.9, 0.4, 0.1, 0.1]
    model.learn(60)  # SB3's loop sets exploration_rate from the schedule at each step
    assert model.exploration_rate == 0.1 and model.epsilons == [0.9, 0.4, 0.1]


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"epsilons": []}, "must be a non-empty list of values in"),
    ({"epsilons": [0.5, 1.5]}, "must be a non-empty list of values in"),
    ({"epsilons": [0.5], "exploration_fraction": 0.2}, "not exploration_fraction=0.2"),
])  # fmt: skip
def test_bad_epsilons_are_refused_in_one_line(kwargs: dict, message: str) -> None:
    with pytest.raises((ValueError, TypeError), match=message):
        ReplayedEpsilonDQN("MlpPolicy", "CartPole-v1", **kwargs)
