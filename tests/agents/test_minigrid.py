"""MiniGrid (Farama's ``minigrid``): ``TabularMiniGrid`` for the tabular agents, ``position="minigrid"`` for the rest."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th

minigrid = pytest.importorskip("minigrid")  # the [minigrid] extra
from minigrid.wrappers import FlatObsWrapper  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402

from sb3_affect import AffectDQN, AffectQ, EmotionCallback, QLearning, TabularMiniGrid  # noqa: E402

LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE, DONE = range(7)


def test_empty_5x5_has_a_state_per_cell_and_direction_and_known_transitions() -> None:
    env = TabularMiniGrid(gym.make("MiniGrid-Empty-5x5-v0"))
    assert env.observation_space == gym.spaces.Discrete(5 * 5 * 4)  # no keys, no doors

    def state(x: int, y: int, direction: int) -> int:
        return (y * 5 + x) * 4 + direction

    obs, _ = env.reset(seed=0)
    assert obs == state(1, 1, 0)  # the top-left cell, facing right
    expected = [
        (FORWARD, state(2, 1, 0), False),
        (RIGHT, state(2, 1, 1), False),  # facing down
        (FORWARD, state(2, 2, 1), False),
        (FORWARD, state(2, 3, 1), False),
        (FORWARD, state(2, 3, 1), False),  # the wall below: no move
        (LEFT, state(2, 3, 0), False),
        (PICKUP, state(2, 3, 0), False),  # nothing to pick up
        (FORWARD, state(3, 3, 0), True),  # the goal
    ]
    for action, next_state, terminated in expected:
        obs, reward, done, _, _ = env.step(action)
        assert (obs, done) == (next_state, terminated), action
    assert reward > 0


def test_doorkey_state_holds_the_key_carried_and_the_door() -> None:
    env = TabularMiniGrid(gym.make("MiniGrid-DoorKey-5x5-v0"))
    assert (env.n_keys, env.n_doors) == (1, 1)
    assert env.observation_space.n == 5 * 5 * 4 * 2 * 3
    obs, _ = env.reset(seed=0)
    base: Any = env.unwrapped
    assert obs % 3 == 2 and (obs // 3) % 2 == 0  # the door is locked, nothing carried
    key = next(base.grid.get(x, y) for x in range(5) for y in range(5) if getattr(base.grid.get(x, y), "type", "") == "key")
    base.carrying = key  # as a pickup leaves it
    base.grid.set(*key.cur_pos, None)
    assert (env.observation(None) // 3) % 2 == 1


def test_objects_the_state_can_not_hold_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"has a ball at .* which the state can not encode") as raised:
        TabularMiniGrid(gym.make("MiniGrid-Dynamic-Obstacles-5x5-v0"))
    assert "\n" not in str(raised.value)


@pytest.mark.parametrize("agent", [QLearning, AffectQ])
def test_the_tabular_agents_reach_the_goal_on_empty_8x8(agent: type) -> None:
    env = TabularMiniGrid(gym.make("MiniGrid-Empty-8x8-v0"))
    model = agent("Grid", env, seed=0).learn(15_000)
    assert (model.episode_log.reward > 0).sum() >= 10
    obs, _ = env.reset(seed=1)
    for _ in range(50):
        action, _ = model.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, _ = env.step(int(action))
        if terminated or truncated:
            break
    assert terminated and reward > 0  # the greedy policy walks to the goal


@pytest.mark.parametrize("position", ["minigrid", "minigrid-dir"])
def test_affect_dqn_on_minigrid_maps_agent_pos_and_the_goal(position: str) -> None:
    th.set_num_threads(1)
    env = make_vec_env("MiniGrid-Empty-5x5-v0", n_envs=2, seed=0, wrapper_class=FlatObsWrapper)
    callback = EmotionCallback()
    AffectDQN("MlpPolicy", env, learning_starts=600, train_freq=4, batch_size=16, seed=0, position=position,
              emotion_callback=callback, policy_kwargs={"net_arch": [16]}, wait_action=DONE).learn(800)
    per_direction = 4 if position == "minigrid-dir" else 1
    goal = (3 * 5 + 3) * per_direction
    known = callback.appraiser.known  # type: ignore[union-attr]
    assert known.n_states == 25 * per_direction
    assert any(goal <= g < goal + per_direction for g in known.goals)  # the cell stepped on at the episode's end
    assert np.isfinite(known.distance[(1 * 5 + 1) * per_direction])  # the start cell knows its way to the goal
    assert callback.episode_log.optimal.isna().all()  # no package geometry on MiniGrid
