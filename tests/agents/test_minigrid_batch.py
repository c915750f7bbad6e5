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
        infos, ended_infos = batch.infos(), batch.infos(ended_only=True)
        for index, (env, start, stop) in enumerate(zip(alone, batch.offsets, batch.offsets[1:])):
            want = env.step(actions[start:stop])
            np.testing.assert_array_equal(obs[start:stop], want[0])
            np.testing.assert_array_equal(rewards[start:stop], want[1])
            np.testing.assert_array_equal(dones[start:stop], want[2])
            _assert_same_infos(infos[index], want[3])
            if want[2].any():
                _assert_same_infos(ended_infos[index], want[3])
            else:
                assert ended_infos[index] == []
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


def test_batch_checks_its_actions_as_step_arrays_and_casts_once() -> None:
    """The reproducers: too many or too few actions, a list, 2-D arrays, int32, float64, 2.5, complex and bool."""
    from sb3_affect.kernel.minigrid_world import step_worlds

    batch = MiniGridBatch([minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=s) for s in (0, 1)])
    alone = [minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=s) for s in (0, 1)]
    with pytest.raises(RuntimeError, match="reset"):
        batch.step(np.zeros(4, dtype=np.int64))
    for env in (*batch.envs, *alone):
        env.reset()
    before = [env.get_attr("agent_pos") for env in batch.envs]
    refused = [(np.zeros(4000, dtype=np.int64), r"actions of shape \(4000,\) for 4 envs"),
               (np.zeros(1, dtype=np.int64), r"actions of shape \(1,\) for 4 envs"),
               (np.zeros((2, 2), dtype=np.int64), r"actions of shape \(2, 2\) for 4 envs"),
               (np.array([0, 1, 2.5, 0]), "action 2.5 of env 2 is not a MiniGrid action"),
               (np.full(4, 2 + 0j), "actions of dtype complex128"), (np.ones(4, dtype=bool), "actions of dtype bool"),
               (np.array([0, 1, 2, 9], dtype=np.int32), "action 9 of env 3"), (["a", "b", "c", "d"], "dtype <U1")]
    for actions, message in refused:
        with pytest.raises(ValueError, match=message) as error:
            batch.step(actions)  # type: ignore[arg-type]
        assert "\n" not in str(error.value)
    assert [env.get_attr("agent_pos") for env in batch.envs] == before  # nothing moved
    signatures = len(step_worlds.signatures)
    for actions in ([2, 2, 0, 1], np.array([1, 2, 2, 0], dtype=np.int32), np.array([2.0, 1.0, 2.0, 2.0]),
                    np.array([[0], [2], [2], [1]], dtype=np.uint8)):
        obs, rewards, dones = batch.step(actions)  # type: ignore[arg-type]
        flat = np.asarray(actions).reshape(4).astype(np.int64)
        want = [env.step(flat[2 * i: 2 * i + 2]) for i, env in enumerate(alone)]
        np.testing.assert_array_equal(obs, np.concatenate([w[0] for w in want]))
        np.testing.assert_array_equal(rewards, np.concatenate([w[1] for w in want]))
        np.testing.assert_array_equal(dones, np.concatenate([w[2] for w in want]))
    assert len(step_worlds.signatures) == signatures  # cast once to the kernel's int64: no new signature compiled


def test_an_env_of_a_batch_pickles_into_one_of_its_own() -> None:
    """A batched env's copy holds its rows as arrays of its own and continues as the env would alone."""
    import pickle

    batch = MiniGridBatch([minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", n, seed=s, obs="view") for s, n in ((0, 2), (5, 3))])
    for env in batch.envs:
        env.reset()
    rng = np.random.default_rng(1)
    for _ in range(30):
        batch.step(rng.integers(7, size=5))
    copy = pickle.loads(pickle.dumps(batch.envs[1]))
    assert not np.shares_memory(copy._obs, batch.arrays[4])  # not the batch's memory
    for _ in range(80):
        actions = rng.integers(7, size=5)
        batch.step(actions)
        np.testing.assert_array_equal(copy.step(actions[2:])[0], batch.envs[1]._obs)
    assert copy.env_method("get_episode_lengths") == batch.envs[1].env_method("get_episode_lengths")
