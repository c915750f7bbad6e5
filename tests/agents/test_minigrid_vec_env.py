"""
The compiled MiniGrid (``minigrid_vec_env``) against Farama's env through
``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)``: the same layouts, observations, rewards,
dones, infos and agent cells, step for step, on 1,000 seeds per task; SB3's agents on it train as on Farama's.
"""

from __future__ import annotations

import multiprocessing
import pickle
from collections import deque
from typing import Any

import numpy as np
import pytest
import torch as th

pytest.importorskip("minigrid")  # the [minigrid] extra: the reference
from minigrid.wrappers import FlatObsWrapper, ImgObsWrapper
from stable_baselines3 import DQN, PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecVideoRecorder

from sb3_affect import AffectDQN, EmotionCallback, minigrid_vec_env
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS

TASKS = ["MiniGrid-Empty-8x8-v0", "MiniGrid-FourRooms-v0", "MiniGrid-DoorKey-5x5-v0"]
LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE, DONE = range(7)
#: Random actions, forward the likeliest (so the agent moves about and meets the key and the door).
ACTION_PROBS = [0.15, 0.15, 0.4, 0.1, 0.05, 0.1, 0.05]
DIRECTIONS = ((1, 0), (0, 1), (-1, 0), (0, -1))


def both(env_id: str, n_envs: int, seed: int, obs: str = "flat", env_kwargs: dict | None = None
         ) -> tuple[DummyVecEnv, VecEnv]:
    wrapper = ImgObsWrapper if obs == "image" else FlatObsWrapper
    farama = make_vec_env(env_id, n_envs, seed=seed, wrapper_class=wrapper, env_kwargs=env_kwargs)
    return farama, minigrid_vec_env(env_id, n_envs, seed=seed, obs=obs, env_kwargs=env_kwargs)  # type: ignore[return-value]


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


def test_view_observation_is_the_first_147_entries() -> None:
    flat = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 4, seed=3)
    view = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 4, seed=3, obs="view")
    assert view.observation_space.shape == (147,) and view.observation_space.dtype == np.uint8
    assert np.array_equal(view.reset(), flat.reset()[:, :147])
    actions, ended = random_actions(5), 0
    for _ in range(300):
        chosen = actions(flat)
        (obs_f, rew_f, done_f, info_f), (obs_i, rew_i, done_i, info_i) = flat.step(chosen), view.step(chosen)
        assert np.array_equal(obs_i, obs_f[:, :147]) and np.array_equal(rew_i, rew_f) and np.array_equal(done_i, done_f)
        for want, have in zip(info_f, info_i):
            if "terminal_observation" in want:
                ended += 1
                assert np.array_equal(have["terminal_observation"], want["terminal_observation"][:147])
    assert ended > 0


@pytest.mark.parametrize("env_id", ["MiniGrid-DoorKey-5x5-v0", "MiniGrid-FourRooms-v0"])
def test_image_observation_is_img_obs_wrappers(env_id: str) -> None:
    """obs="image" against make_vec_env(wrapper_class=ImgObsWrapper): the 7x7x3 Box, every observation and info."""
    farama, compiled = both(env_id, 4, 8, obs="image")
    assert compiled.observation_space == farama.observation_space
    assert compiled.observation_space.shape == (7, 7, 3)
    assert np.array_equal(compiled.reset(), farama.reset())
    counts = run_both(farama, compiled, mostly_scripted(8), 150)
    assert counts["episodes"] > 0 and counts["goals"] > 0


class SmallCNN(BaseFeaturesExtractor):
    """A CNN for a 7x7 image (SB3's NatureCNN needs 36x36 or more)."""

    def __init__(self, observation_space: Any, features_dim: int = 16) -> None:
        super().__init__(observation_space, features_dim)
        self.cnn = th.nn.Sequential(th.nn.Conv2d(3, 8, 2), th.nn.ReLU(), th.nn.Flatten(),
                                    th.nn.Linear(8 * 6 * 6, features_dim), th.nn.ReLU())

    def forward(self, observations: th.Tensor) -> th.Tensor:
        return self.cnn(observations)


def test_ppo_cnn_policy_trains_on_the_image_as_on_farama() -> None:
    th.set_num_threads(1)
    policy_kwargs = {"features_extractor_class": SmallCNN, "net_arch": [16]}
    runs = [PPO("CnnPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, policy_kwargs=policy_kwargs).learn(128)
            for venv in both("MiniGrid-DoorKey-5x5-v0", 2, 0, obs="image")]
    assert runs[1].num_timesteps == 128
    assert_same_weights(*runs)


#: Farama's env keyword arguments the compiled worlds take, each checked step for step.
ENV_KWARGS = [
    ("MiniGrid-DoorKey-5x5-v0", {"max_steps": 25, "agent_view_size": 5}),
    ("MiniGrid-DoorKey-6x6-v0", {"see_through_walls": True, "agent_view_size": 9}),
    ("MiniGrid-FourRooms-v0", {"agent_view_size": 3, "max_steps": 40, "see_through_walls": False}),
    ("MiniGrid-Empty-5x5-v0", {"size": 7, "agent_start_pos": None}),
    ("MiniGrid-Empty-Random-6x6-v0", {"agent_start_pos": (1, 1), "max_steps": 30, "render_mode": None}),
    ("MiniGrid-DoorKey-8x8-v0", {"size": 6, "agent_view_size": 11, "highlight": False, "tile_size": 8}),
]


@pytest.mark.parametrize(("env_id", "env_kwargs"), ENV_KWARGS)
@pytest.mark.parametrize("obs", ["flat", "image"])
def test_env_kwargs_equal_farama_step_for_step(env_id: str, env_kwargs: dict, obs: str) -> None:
    farama, compiled = both(env_id, 5, 40, obs=obs, env_kwargs=env_kwargs)
    assert compiled.observation_space == farama.observation_space
    assert np.array_equal(compiled.reset(), farama.reset())
    assert_same_layouts(farama, compiled)
    for name in ("width", "max_steps", "see_through_walls", "agent_view_size", "render_mode", "mission"):
        assert compiled.get_attr(name) == farama.get_attr(name), name
    counts = run_both(farama, compiled, random_actions(1), 200)
    counts_scripted = run_both(farama, compiled, mostly_scripted(2), 100)
    assert counts["episodes"] + counts_scripted["episodes"] > 0
    assert compiled.env_method("get_episode_lengths") == farama.env_method("get_episode_lengths")


@pytest.mark.parametrize(("env_id", "obs", "env_kwargs"), [
    ("MiniGrid-Empty-Random-5x5-v0", "flat", None), ("MiniGrid-FourRooms-v0", "image", {"max_steps": 9}),
    ("MiniGrid-DoorKey-8x8-v0", "flat", {"render_mode": None, "agent_view_size": 5}),
    ("MiniGrid-Empty-8x8-v0", "image", None)])
def test_spec_and_metadata_are_make_vec_envs(env_id: str, obs: str, env_kwargs: dict | None) -> None:
    farama, compiled = both(env_id, 2, 0, obs=obs, env_kwargs=env_kwargs)
    assert compiled.spec == farama.get_attr("spec")[0]  # type: ignore[attr-defined]
    assert compiled.get_attr("spec") == farama.get_attr("spec")
    assert compiled.get_attr("metadata") == farama.get_attr("metadata")
    assert (compiled.render_mode, compiled.metadata) == (farama.render_mode, farama.metadata)


def test_env_kwargs_it_does_not_compile_are_refused_in_one_line() -> None:
    refused = [
        ("MiniGrid-Empty-5x5-v0", {"see_through_walls": False}, "key 'see_through_walls' is not taken by"),
        ("MiniGrid-DoorKey-5x5-v0", {"lava": 1}, "key 'lava' is not taken by MiniGrid-DoorKey-5x5-v0; it takes size"),
        ("MiniGrid-DoorKey-5x5-v0", {"agent_view_size": 4}, "agent_view_size=4 is not allowed; an odd integer"),
        ("MiniGrid-DoorKey-5x5-v0", {"max_steps": 2.5}, "max_steps=2.5 is not allowed; a positive integer"),
        ("MiniGrid-FourRooms-v0", {"agent_pos": (3, 3)}, "agent_pos=\\(3, 3\\) is not allowed"),
        ("MiniGrid-Empty-8x8-v0", {"agent_start_pos": (2, 2)}, "agent_start_pos=\\(2, 2\\) is not allowed"),
        ("MiniGrid-Empty-8x8-v0", {"render_mode": "human"}, "render_mode='human' is not allowed"),
        ("MiniGrid-DoorKey-5x5-v0", {"size": 4}, "size=4 is not allowed; an integer from 5"),
    ]
    for env_id, env_kwargs, message in refused:
        with pytest.raises(ValueError, match=message) as error:
            minigrid_vec_env(env_id, 2, env_kwargs=env_kwargs)
        assert "\n" not in str(error.value)
    with pytest.raises(ValueError, match="env_id='MiniGrid-LavaGapS5-v0' is not implemented; supported: MiniGrid-DoorKey"):
        minigrid_vec_env("MiniGrid-LavaGapS5-v0", 2)


def test_closed_and_bad_indices_and_actions_are_refused() -> None:
    venv = minigrid_vec_env("MiniGrid-Empty-5x5-v0", 4, seed=0)
    venv.reset()
    with pytest.raises(IndexError, match=r"indices has 5; its 4 envs are 0\.\.3"):
        venv.get_attr("agent_pos", indices=[5])
    with pytest.raises(IndexError, match="indices has 4"):
        venv.env_method("get_total_steps", indices=4)
    assert venv.get_attr("agent_dir", indices=[-1]) == venv.get_attr("agent_dir", indices=[3])
    for bad, message in [(np.array([1, 2, 0, 2.5]), "action 2.5 of env 3"), (np.full(4, 1 + 0j), "dtype complex128"),
                         (np.ones(4, dtype=bool), "dtype bool"), (np.zeros(4000, dtype=np.int64), "shape \\(4000,\\) for 4"),
                         (np.zeros((4, 2), dtype=np.int64), "shape \\(4, 2\\) for 4"), ([0], "shape \\(1,\\) for 4"),
                         (np.array([0, 1, 2, np.nan]), "action nan of env 3")]:
        with pytest.raises(ValueError, match=message):
            venv.step(bad)
    venv.close()
    with pytest.raises(RuntimeError, match="closed"):
        venv.step(np.zeros(4, dtype=np.int64))
    with pytest.raises(RuntimeError, match="closed"):
        venv.reset()


def test_pickled_copy_continues_as_the_original() -> None:
    original = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 3, seed=2, obs="image")
    original.reset()
    actions = random_actions(0)
    for _ in range(40):
        original.step(actions(original))
    copy = pickle.loads(pickle.dumps(original))
    ended = 0
    for _ in range(120):
        chosen = actions(original)
        ended += assert_same_step(original.step(chosen), copy.step(chosen))
    assert ended > 0 and copy.env_method("get_episode_lengths") == original.env_method("get_episode_lengths")
    assert copy.spec == original.spec and copy.get_attr("agent_pos") == original.get_attr("agent_pos")


def _step_in_a_worker(pipe: Any) -> None:
    venv = pipe.recv()  # unpickled in the worker, as SubprocVecEnv and Ray send envs
    pipe.send([venv.step(np.full(venv.num_envs, 2)) for _ in range(30)])


def test_it_runs_in_a_worker_process() -> None:
    venv = minigrid_vec_env("MiniGrid-Empty-5x5-v0", 2, seed=1)
    venv.reset()
    context = multiprocessing.get_context("fork")
    ours, theirs = context.Pipe()
    worker = context.Process(target=_step_in_a_worker, args=(theirs,))
    worker.start()
    ours.send(venv)
    remote = ours.recv()
    worker.join(timeout=60)
    assert worker.exitcode == 0
    for got in remote:
        assert_same_step(venv.step(np.full(2, 2)), got)


RENDERED = [("MiniGrid-DoorKey-5x5-v0", {}), ("MiniGrid-FourRooms-v0", {"tile_size": 8}),
            ("MiniGrid-Empty-8x8-v0", {"highlight": False}), ("MiniGrid-DoorKey-6x6-v0", {"agent_pov": True}),
            ("MiniGrid-DoorKey-8x8-v0", {"agent_view_size": 5, "tile_size": 12})]


@pytest.mark.parametrize(("env_id", "env_kwargs"), RENDERED)
def test_frames_are_faramas_pixel_for_pixel(env_id: str, env_kwargs: dict) -> None:
    farama, compiled = both(env_id, 3, 11, env_kwargs=env_kwargs)
    farama.reset(), compiled.reset()
    actions = mostly_scripted(3)
    for step in range(60):
        if step % 6 == 0:
            frames, want = compiled.get_images(), farama.get_images()
            for have, expected in zip(frames, want):
                assert have is not None and have.dtype == expected.dtype and have.shape == expected.shape
                assert np.array_equal(have, expected), step
            assert np.array_equal(compiled.render(), farama.render())  # type: ignore[arg-type]
        chosen = actions(farama)
        farama.step(chosen), compiled.step(chosen)


def test_vec_video_recorder_records_it(tmp_path: Any) -> None:
    venv = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 2, seed=0)
    recorder = VecVideoRecorder(venv, str(tmp_path), record_video_trigger=lambda step: step == 0, video_length=12,
                                name_prefix="compiled")
    recorder.reset()
    for _ in range(14):
        recorder.step(np.full(2, FORWARD))
    recorder.close()
    videos = list(tmp_path.glob("compiled*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000
    no_frames = minigrid_vec_env("MiniGrid-DoorKey-5x5-v0", 2, env_kwargs={"render_mode": None})
    with pytest.warns(UserWarning, match="no images"):
        assert no_frames.get_images() == [None, None]


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
    assert image.env_is_wrapped(ImgObsWrapper) == [True] * 3


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
