"""
The compiled MiniGrid (``minigrid_vec_env``) against Farama's env through
``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)``: the same layouts, observations, rewards,
dones, infos and agent cells, step for step, on 1,000 seeds per task; SB3's agents on it train as on Farama's.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np
import pytest
import torch as th

pytest.importorskip("minigrid")  # the [minigrid] extra: the reference
from minigrid.wrappers import FlatObsWrapper
from stable_baselines3 import DQN, PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from sb3_affect import AffectDQN, EmotionCallback, minigrid_vec_env
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS

TASKS = ["MiniGrid-Empty-8x8-v0", "MiniGrid-FourRooms-v0", "MiniGrid-DoorKey-5x5-v0"]
LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE, DONE = range(7)
#: Random actions, forward the likeliest (so the agent moves about and meets the key and the door).
ACTION_PROBS = [0.15, 0.15, 0.4, 0.1, 0.05, 0.1, 0.05]
DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))


def both(env_id: str, n_envs: int, seed: int, obs: str = "flat") -> tuple[DummyVecEnv, VecEnv]:
    farama = make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)
    return farama, minigrid_vec_env(env_id, n_envs, seed=seed, obs=obs)  # type: ignore[return-value]


def assert_same_layouts(farama: DummyVecEnv, compiled: Any) -> None:
    for index, env in enumerate(farama.envs):
        world = env.unwrapped
        assert np.array_equal(world.grid.encode(), compiled.worlds.grid[index]), index  # type: ignore[attr-defined]
    assert_same_cells(farama, compiled)


def assert_same_cells(farama: DummyVecEnv, compiled: VecEnv) -> None:
    assert [tuple(int(v) for v in p) for p in farama.get_attr("agent_pos")] == compiled.get_attr("agent_pos")
    assert [int(d) for d in farama.get_attr("agent_dir")] == compiled.get_attr("agent_dir")


def assert_same_step(expected: tuple, got: tuple) -> int:
    """The two VecEnvs' step returns are equal (the Monitor's wall time aside); returns the episodes that ended."""
    for want, have in zip(expected[:3], got[:3]):
        assert have.dtype == want.dtype and have.shape == want.shape
        assert np.array_equal(have, want)
    ended = 0
    for want, have in zip(expected[3], got[3]):
        assert list(have) == list(want)  # the same keys, in the same order
        assert have["TimeLimit.truncated"] == want["TimeLimit.truncated"]
        if "terminal_observation" in want:
            ended += 1
            terminal = have["terminal_observation"]
            assert terminal.dtype == want["terminal_observation"].dtype
            assert np.array_equal(terminal, want["terminal_observation"])
            assert (have["episode"]["r"], have["episode"]["l"]) == (want["episode"]["r"], want["episode"]["l"])
    return ended


def run_both(farama: DummyVecEnv, compiled: VecEnv, actions: Any, steps: int) -> dict[str, int]:
    """Steps both with ``actions(farama)``, checking every step; counts the goals, truncations and episodes."""
    counts = {"goals": 0, "truncations": 0, "episodes": 0}
    for _ in range(steps):
        chosen = actions(farama)
        expected, got = farama.step(chosen), compiled.step(chosen)
        counts["episodes"] += assert_same_step(expected, got)
        counts["goals"] += int((expected[1] > 0).sum())
        counts["truncations"] += sum(info["TimeLimit.truncated"] for info in expected[3])
        assert_same_cells(farama, compiled)
    return counts


def random_actions(seed: int) -> Any:
    rng = np.random.default_rng(seed)
    return lambda venv: rng.choice(7, size=venv.num_envs, p=ACTION_PROBS)


def scripted_action(world: Any) -> int:
    """The next action towards the goal (DoorKey: the key, then the door, then the goal): a search over cells and facings."""
    grid = world.grid.encode()
    kinds = grid[:, :, 0]
    if world.carrying is None and (kinds == 5).any():
        target, use = tuple(np.argwhere(kinds == 5)[0]), PICKUP
    elif ((kinds == 4) & (grid[:, :, 2] != 0)).any():
        target, use = tuple(np.argwhere(kinds == 4)[0]), TOGGLE
    else:
        target, use = tuple(np.argwhere(kinds == 8)[0]), FORWARD
    start = (int(world.agent_pos[0]), int(world.agent_pos[1]), int(world.agent_dir))
    first: dict[tuple[int, int, int], int | None] = {start: None}
    queue = deque([start])
    while queue:
        x, y, d = state = queue.popleft()
        if (x + DIRECTIONS[d][0], y + DIRECTIONS[d][1]) == target:
            action = first[state]
            return use if action is None else action
        fx, fy = x + DIRECTIONS[d][0], y + DIRECTIONS[d][1]
        passable = kinds[fx, fy] == 1 or (kinds[fx, fy] == 4 and grid[fx, fy, 2] == 0)
        moves = [(LEFT, (x, y, (d + 3) % 4)), (RIGHT, (x, y, (d + 1) % 4))] + ([(FORWARD, (fx, fy, d))] if passable else [])
        for action, nxt in moves:
            if nxt not in first:
                first[nxt] = first[state] if first[state] is not None else action
                queue.append(nxt)
    return DONE


def mostly_scripted(seed: int) -> Any:
    rng = np.random.default_rng(seed)

    def actions(venv: DummyVecEnv) -> np.ndarray:
        scripted = [scripted_action(env.unwrapped) for env in venv.envs]
        return np.where(rng.random(venv.num_envs) < 0.8, scripted, rng.choice(7, size=venv.num_envs, p=ACTION_PROBS))

    return actions


@pytest.mark.parametrize("env_id", TASKS)
def test_equals_farama_on_1000_seeds(env_id: str) -> None:
    for first_seed in range(0, 1000, 100):  # envs seeded 0..999
        farama, compiled = both(env_id, 100, first_seed)
        assert compiled.observation_space == farama.observation_space
        assert compiled.action_space == farama.action_space
        expected, got = farama.reset(), compiled.reset()
        assert got.dtype == expected.dtype and np.array_equal(got, expected)
        assert_same_layouts(farama, compiled)
        run_both(farama, compiled, random_actions(first_seed), 12)


@pytest.mark.parametrize("env_id", sorted(set(MINIGRID_TASKS) - set(TASKS)))
def test_every_other_task_equals_farama(env_id: str) -> None:
    farama, compiled = both(env_id, 20, 5000)
    assert np.array_equal(compiled.reset(), farama.reset())
    assert_same_layouts(farama, compiled)
    run_both(farama, compiled, random_actions(3), 20)
    run_both(farama, compiled, mostly_scripted(4), 20)


@pytest.mark.parametrize("env_id", TASKS)
def test_equals_farama_to_the_goal_and_the_time_limit(env_id: str) -> None:
    farama, compiled = both(env_id, 6, 2024)
    assert np.array_equal(compiled.reset(), farama.reset())
    scripted = run_both(farama, compiled, mostly_scripted(0), 120)
    assert scripted["goals"] >= 6  # the scripted walks end at the goal: rewards and termination
    task = MINIGRID_TASKS[env_id]
    wandering = run_both(farama, compiled, random_actions(1), task.max_steps + 5)
    assert wandering["truncations"] >= 1  # random walks reach the time limit
    assert_same_layouts(farama, compiled)  # later layouts, from the unseeded resets
    assert compiled.env_method("get_episode_rewards") == farama.env_method("get_episode_rewards")
    assert compiled.env_method("get_episode_lengths") == farama.env_method("get_episode_lengths")
    assert compiled.env_method("get_total_steps") == farama.env_method("get_total_steps")


def test_reseeding_and_reset_follow_dummy_vec_env() -> None:
    farama, compiled = both("MiniGrid-DoorKey-5x5-v0", 3, 7)
    for seed in (7, None, 11):
        if seed is not None:
            assert compiled.seed(seed) == farama.seed(seed)
        assert np.array_equal(compiled.reset(), farama.reset())
        assert_same_layouts(farama, compiled)
        run_both(farama, compiled, random_actions(seed or 0), 5)


def test_image_observation_is_the_first_147_entries() -> None:
    flat = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 4, seed=3)
    image = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 4, seed=3, obs="image")
    assert image.observation_space.shape == (147,) and image.observation_space.dtype == np.uint8
    assert np.array_equal(image.reset(), flat.reset()[:, :147])
    actions, ended = random_actions(5), 0
    for _ in range(300):
        chosen = actions(flat)
        (obs_f, rew_f, done_f, info_f), (obs_i, rew_i, done_i, info_i) = flat.step(chosen), image.step(chosen)
        assert np.array_equal(obs_i, obs_f[:, :147]) and np.array_equal(rew_i, rew_f) and np.array_equal(done_i, done_f)
        for want, have in zip(info_f, info_i):
            if "terminal_observation" in want:
                ended += 1
                assert np.array_equal(have["terminal_observation"], want["terminal_observation"][:147])
    assert ended > 0


def test_step_arrays_is_the_step_without_infos() -> None:
    stepped = minigrid_vec_env("MiniGrid-FourRooms-v0", 5, seed=1)
    raw = minigrid_vec_env("MiniGrid-FourRooms-v0", 5, seed=1)
    assert np.array_equal(stepped.reset(), raw.reset())
    actions = random_actions(2)
    for _ in range(150):
        chosen = actions(stepped)
        obs, rewards, dones, infos = stepped.step(chosen)
        raw_obs, raw_rewards, terminated, truncated = raw.step_arrays(chosen)
        assert np.array_equal(raw_obs, obs) and np.array_equal(raw_rewards, rewards)
        assert np.array_equal(terminated | truncated, dones)
        assert [info["TimeLimit.truncated"] for info in infos] == (truncated & ~terminated).tolist()
        for index in np.flatnonzero(dones):
            assert np.array_equal(raw.terminal_observations[index], infos[index]["terminal_observation"])


def test_bad_input_is_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"env_id='MiniGrid-LavaGapS5-v0' is not implemented; supported: .*FourRooms"):
        minigrid_vec_env("MiniGrid-LavaGapS5-v0", 2)
    with pytest.raises(ValueError, match="obs='rgb' is not supported"):
        minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, obs="rgb")
    with pytest.raises(ValueError, match="n_envs=0 must be a positive integer"):
        minigrid_vec_env("MiniGrid-Empty-5x5-v0", 0)
    venv = minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=0)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros(2, dtype=np.int64))
    venv.reset()
    before = venv.get_attr("agent_pos")
    with pytest.raises(ValueError, match="action 7 of env 1 is not a MiniGrid action"):
        venv.step(np.array([2, 7]))
    assert venv.get_attr("agent_pos") == before  # nothing moved
    with pytest.raises(AttributeError, match="no attribute 'np_random'"):
        venv.get_attr("np_random")
    with pytest.raises(AttributeError, match="can not be set"):
        venv.set_attr("max_steps", 10)
    with pytest.raises(AttributeError, match="env_method\\('reset'\\) is not supported"):
        venv.env_method("reset")
    with pytest.raises(NotImplementedError, match="renders no images"):
        venv.render("rgb_array")


def test_attributes_and_wrappers_as_make_vec_env() -> None:
    farama, compiled = both("MiniGrid-DoorKey-6x6-v0", 3, 0)
    farama.reset(), compiled.reset()
    for name in ("width", "height", "max_steps", "step_count", "mission", "see_through_walls", "agent_view_size"):
        assert compiled.get_attr(name) == farama.get_attr(name), name
    assert compiled.get_attr("agent_dir", indices=[2]) == farama.get_attr("agent_dir", indices=[2])
    assert compiled.env_is_wrapped(Monitor) == farama.env_is_wrapped(Monitor) == [True] * 3
    assert compiled.env_is_wrapped(FlatObsWrapper) == farama.env_is_wrapped(FlatObsWrapper) == [True] * 3
    image = minigrid_vec_env("MiniGrid-DoorKey-6x6-v0", 3, obs="image")
    assert image.env_is_wrapped(FlatObsWrapper) == [False] * 3


def dqn_run(cls: type, venv: VecEnv, steps: int = 400, **kwargs: Any) -> Any:
    th.set_num_threads(1)
    return cls("MlpPolicy", venv, learning_starts=steps - 300, train_freq=4, batch_size=16, seed=0,
               policy_kwargs={"net_arch": [16]}, **kwargs).learn(steps)


def assert_same_weights(first: Any, second: Any) -> None:
    for (name, want), have in zip(first.policy.state_dict().items(), second.policy.state_dict().values()):
        assert th.equal(want, have), name


def test_sb3_dqn_trains_on_it_as_on_farama() -> None:
    farama, compiled = both("MiniGrid-Empty-5x5-v0", 2, 0)
    want, have = dqn_run(DQN, farama), dqn_run(DQN, compiled)
    assert have.num_timesteps == want.num_timesteps == 400
    assert len(have.ep_info_buffer) > 0
    assert [(e["r"], e["l"]) for e in have.ep_info_buffer] == [(e["r"], e["l"]) for e in want.ep_info_buffer]
    assert_same_weights(want, have)
    assert evaluate_policy(have, compiled, n_eval_episodes=4) == evaluate_policy(want, farama, n_eval_episodes=4)


def test_sb3_ppo_trains_on_it_as_on_farama() -> None:
    th.set_num_threads(1)
    runs = [PPO("MlpPolicy", venv, n_steps=64, batch_size=32, n_epochs=2, seed=0, policy_kwargs={"net_arch": [16]}).learn(256)
            for venv in both("MiniGrid-DoorKey-5x5-v0", 2, 0, obs="flat")]
    assert runs[1].num_timesteps == 256
    assert_same_weights(*runs)


def test_affect_dqn_reads_the_agent_cell_from_it() -> None:
    callbacks = [EmotionCallback(), EmotionCallback()]
    runs = [dqn_run(AffectDQN, venv, 900, position="minigrid", emotion_callback=callback, wait_action=DONE)
            for venv, callback in zip(both("MiniGrid-Empty-5x5-v0", 2, 0), callbacks)]
    known = [callback.appraiser.known for callback in callbacks]  # type: ignore[union-attr]
    assert known[1].n_states == 25 and len(known[1].goals) > 0
    assert known[1].goals == known[0].goals
    assert np.array_equal(known[1].distance, known[0].distance)
    logs = [callback.episode_log.drop(columns=[c for c in callback.episode_log if "time" in c]) for callback in callbacks]
    assert logs[1].equals(logs[0])
    assert_same_weights(*runs)
