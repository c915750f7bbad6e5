"""
``MiniGridBatch``: several compiled MiniGrid VecEnvs (one per seed) stepped by one kernel call give, env for env, what
each VecEnv's own ``step`` gives, and each VecEnv stays usable on its own (attributes, ``Monitor`` records, ``step``).
"""

from __future__ import annotations

import numpy as np
import pytest

from sb3_affect import minigrid_vec_env
from sb3_affect.agents.minigrid_vec_env import MiniGridBatch


def _assert_same_infos(got: list[dict], want: list[dict]) -> None:
    assert [list(info) for info in got] == [list(info) for info in want]
    for have, expected in zip(got, want):
        assert have["TimeLimit.truncated"] == expected["TimeLimit.truncated"]
        if "terminal_observation" in expected:
            np.testing.assert_array_equal(have["terminal_observation"], expected["terminal_observation"])
            assert (have["episode"]["r"], have["episode"]["l"]) == (expected["episode"]["r"], expected["episode"]["l"])


@pytest.mark.parametrize("env_id", ["MiniGrid-Empty-5x5-v0", "MiniGrid-DoorKey-5x5-v0"])
def test_batch_steps_as_each_vec_env_alone(env_id: str) -> None:
    """Three seeds of 1, 3 and 2 envs, 600 random steps (many episodes end): the batch's observations, rewards,
    dones and infos are each VecEnv's own, and so are its Monitor records and cells afterwards."""
    seeds, sizes = [4, 0, 11], [1, 3, 2]
    alone = [minigrid_vec_env(env_id, n, seed=seed, obs="image") for seed, n in zip(seeds, sizes)]
    joined = [minigrid_vec_env(env_id, n, seed=seed, obs="image") for seed, n in zip(seeds, sizes)]
    for env in (*alone, *joined):
        env.reset()
    batch = MiniGridBatch(joined)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(600):
        actions = rng.integers(7, size=sum(sizes))
        obs, rewards, dones = batch.step(actions)
        infos = batch.infos()
        for index, (env, start, stop) in enumerate(zip(alone, batch.offsets, batch.offsets[1:])):
            want = env.step(actions[start:stop])
            np.testing.assert_array_equal(obs[start:stop], want[0])
            np.testing.assert_array_equal(rewards[start:stop], want[1])
            np.testing.assert_array_equal(dones[start:stop], want[2])
            _assert_same_infos(infos[index], want[3])
        ended += int(dones.sum())
    assert ended > 10
    for env, own in zip(alone, joined):
        assert own.get_attr("agent_pos") == env.get_attr("agent_pos")
        assert own.env_method("get_episode_lengths") == env.env_method("get_episode_lengths")
        assert own.env_method("get_total_steps") == env.env_method("get_total_steps")
        step = own.step(np.zeros(own.num_envs, dtype=np.int64))  # on its own again: its rows of the batch
        np.testing.assert_array_equal(step[0], env.step(np.zeros(env.num_envs, dtype=np.int64))[0])


def test_batch_refuses_other_envs_and_bad_actions() -> None:
    envs = [minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=0), minigrid_vec_env("MiniGrid-Empty-8x8-v0", 2, seed=1)]
    with pytest.raises(ValueError, match="every env must be a minigrid_vec_env of MiniGrid-Empty-5x5-v0"):
        MiniGridBatch(envs)
    batch = MiniGridBatch([envs[0], minigrid_vec_env("MiniGrid-Empty-5x5-v0", 1, seed=3)])
    for env in batch.envs:
        env.reset()
    with pytest.raises(ValueError, match="action 7 of env 2 is not a MiniGrid action"):
        batch.step(np.array([0, 1, 7]))
