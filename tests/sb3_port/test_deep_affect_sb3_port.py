"""
Ports of Stable-Baselines3's algorithm-generic tests (tests/test_save_load.py, test_predict.py, test_run.py,
test_callbacks.py, test_vec_envs.py) for ``AffectDQN`` and ``AffectQRDQN``, on one env and on a 4-env VecEnv. Each
keeps the original's structure and assertions (named in its docstring), on FrozenLake (Discrete observations: the
appraisal has cells).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3.common.callbacks import (
    CallbackList,
    CheckpointCallback,
    EvalCallback,
    EveryNTimesteps,
    StopTrainingOnMaxEpisodes,
)
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv

from sb3_affect import AffectDQN, AffectQRDQN

AGENTS = (AffectDQN, AffectQRDQN)
N_ENVS = (1, 4)


def make(agent: type, n_envs: int, **kwargs: Any) -> Any:
    th.set_num_threads(1)
    env = make_vec_env("FrozenLake-v1", n_envs=n_envs, seed=0)
    kwargs = {"learning_starts": 16, "batch_size": 16, "train_freq": 4, "seed": 0, **kwargs}
    return agent("MlpPolicy", env, policy_kwargs={"net_arch": [16]}, **kwargs)


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("n_envs", N_ENVS)
def test_save_load(agent: type, n_envs: int, tmp_path: Path) -> None:
    """test_save_load.py::test_save_load: the parameters and the deterministic predictions survive save and load."""
    model = make(agent, n_envs).learn(200)
    observations = np.arange(16)
    params = {key: value.clone() for key, value in model.policy.state_dict().items()}
    actions, _ = model.predict(observations, deterministic=True)
    model.save(tmp_path / "model.zip")
    del model
    model = agent.load(tmp_path / "model.zip", env=make_vec_env("FrozenLake-v1", n_envs=n_envs, seed=1))
    for key, value in model.policy.state_dict().items():
        assert th.equal(value, params[key]), key
    np.testing.assert_array_equal(model.predict(observations, deterministic=True)[0], actions)
    model.learn(100)  # learning goes on after loading


@pytest.mark.parametrize("agent", AGENTS)
def test_save_load_replay_buffer(agent: type, tmp_path: Path) -> None:
    """test_save_load.py::test_save_load_replay_buffer: the buffer's arrays come back as saved."""
    model = make(agent, 4, buffer_size=1000).learn(300)
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    old = {name: getattr(model.replay_buffer, name).copy() for name in ("observations", "actions", "rewards", "dones")}
    model.load_replay_buffer(tmp_path / "buffer.pkl")
    for name, value in old.items():
        np.testing.assert_array_equal(getattr(model.replay_buffer, name), value, err_msg=name)


@pytest.mark.parametrize("agent", AGENTS)
def test_exclude_include_saved_params(agent: type, tmp_path: Path) -> None:
    """test_save_load.py::test_exclude_include_saved_params: ``exclude`` leaves a parameter at its default on load."""
    model = make(agent, 1, wait_action=2)
    model.save(tmp_path / "model.zip", exclude=["wait_action"])
    assert agent.load(tmp_path / "model.zip").wait_action is None
    model.save(tmp_path / "model.zip")
    assert agent.load(tmp_path / "model.zip").wait_action == 2


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("n_envs", N_ENVS)
def test_predict(agent: type, n_envs: int) -> None:
    """test_predict.py::test_predict: one observation gives one action, a VecEnv's batch one per env."""
    model = make(agent, n_envs).learn(64)
    env = gym.make("FrozenLake-v1")
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs)
    assert env.action_space.contains(action)
    vec_env = model.get_env()
    actions, _ = model.predict(vec_env.reset())
    assert actions.shape == (n_envs,)
    for _ in range(4):
        actions, _ = model.predict(vec_env.reset(), deterministic=False)
        assert actions.shape == (n_envs,)


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("train_freq", [4, (1, "step"), (1, "episode")])
def test_train_freq(agent: type, train_freq: Any) -> None:
    """test_run.py::test_train_freq: steps and episodes as the training unit (episodes on one env only)."""
    model = make(agent, 1, train_freq=train_freq, gradient_steps=-1).learn(150)
    assert model.num_timesteps >= 150 and model._n_updates > 0


@pytest.mark.parametrize("agent", AGENTS)
@pytest.mark.parametrize("n_envs", N_ENVS)
def test_callbacks(agent: type, n_envs: int, tmp_path: Path) -> None:
    """test_callbacks.py::test_callbacks: evaluation, checkpoints, every-n-steps and stopping on episodes."""
    model = make(agent, n_envs)
    eval_env = make_vec_env("FrozenLake-v1", n_envs=1, seed=2)
    checkpoint = CheckpointCallback(save_freq=50, save_path=str(tmp_path / "checkpoints"), name_prefix="affect")
    evaluation = EvalCallback(eval_env, eval_freq=50, n_eval_episodes=2, log_path=str(tmp_path / "eval"), warn=False)
    every = EveryNTimesteps(n_steps=40, callback=CheckpointCallback(save_freq=1, save_path=str(tmp_path / "every")))
    model.learn(400, callback=CallbackList([checkpoint, evaluation, every]))
    assert list((tmp_path / "checkpoints").glob("affect_*_steps.zip"))
    assert (tmp_path / "eval" / "evaluations.npz").exists()
    assert list((tmp_path / "every").glob("*.zip"))
    model.learn(10_000, callback=StopTrainingOnMaxEpisodes(max_episodes=5, verbose=0))
    assert model.num_timesteps < 10_000  # stopped after 5 episodes of each env
    loaded = agent.load(next((tmp_path / "checkpoints").glob("affect_*_steps.zip")))
    assert loaded._behaviour == model._behaviour


@pytest.mark.parametrize("agent", AGENTS)
def test_subproc_vec_env(agent: type) -> None:
    """test_vec_envs.py (SubprocVecEnv): the emotions need only the observations the subprocesses send back."""
    th.set_num_threads(1)
    env = make_vec_env("FrozenLake-v1", n_envs=2, seed=0, vec_env_cls=SubprocVecEnv)
    try:
        model = agent("MlpPolicy", env, learning_starts=16, batch_size=16, seed=0, policy_kwargs={"net_arch": [8]})
        model.learn(300)
        assert set(model.emotion_callback.episode_log.env) == {0, 1}
    finally:
        env.close()
