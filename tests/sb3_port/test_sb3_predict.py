"""Port of Stable-Baselines3's tests/test_predict.py and tests/test_deterministic.py to the tabular agents."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from gymnasium import spaces
from sb3_port import ALGOS, ENV_IDS, EPSILON_ALGOS, SKIP_BOX, make_model
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.envs import IdentityEnv
from stable_baselines3.common.utils import get_device
from stable_baselines3.common.vec_env import DummyVecEnv


class SubClassedDiscrete(spaces.Discrete):
    pass


class CustomSubClassedSpaceEnv(gym.Env):
    """SB3's env with subclassed spaces, with Discrete spaces instead of Box ones."""

    def __init__(self) -> None:
        super().__init__()
        self.observation_space = SubClassedDiscrete(4)
        self.action_space = SubClassedDiscrete(2)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[int, dict]:
        super().reset(seed=seed)
        return int(self.observation_space.sample()), {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict]:
        return int(self.observation_space.sample()), 0.0, bool(np.random.rand() > 0.5), False, {}


def test_env() -> None:
    """SB3 ``test_env``: the env used below passes SB3's env checker."""
    check_env(CustomSubClassedSpaceEnv(), skip_render_check=True)


@pytest.mark.parametrize("model_class", ALGOS)
def test_auto_wrap(model_class) -> None:
    """SB3 ``test_auto_wrap``: a Gymnasium env is wrapped into a VecEnv."""
    model = make_model(model_class, gym.make("FrozenLake-v1"))
    model.learn(100)


@pytest.mark.parametrize("device", ["cpu", "cuda", "auto"])
@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("model_class", ALGOS)
def test_predict(model_class, env_id, device) -> None:
    """
    SB3 ``test_predict``: devices, and the shapes of ``predict``'s actions for one observation and for a batch; DQN's
    special case (``exploration_rate = 1.0`` with ``deterministic=False``) runs for the epsilon-greedy agents.
    """
    if device == "cuda" and not th.cuda.is_available():
        pytest.skip("CUDA not available")
    model = make_model(model_class, env_id, device=device)
    assert get_device(device).type == model.policy.device.type

    env = gym.make(env_id)
    vec_env = DummyVecEnv([lambda: gym.make(env_id), lambda: gym.make(env_id)])

    obs, _ = env.reset()
    for deterministic in (False, True):
        action, _ = model.predict(obs, deterministic=deterministic)
        assert isinstance(action, np.ndarray)
        assert action.shape == env.action_space.shape
        assert env.action_space.contains(action)

    vec_env_obs = vec_env.reset()
    action, _ = model.predict(vec_env_obs)
    assert isinstance(action, np.ndarray)
    assert action.shape[0] == vec_env_obs.shape[0]

    if model_class in EPSILON_ALGOS:
        model.exploration_rate = 1.0
        action, _ = model.predict(obs, deterministic=False)
        assert isinstance(action, np.ndarray)
        assert action.shape == env.action_space.shape
        assert env.action_space.contains(action)
        action, _ = model.predict(vec_env_obs, deterministic=False)
        assert action.shape[0] == vec_env_obs.shape[0]


@pytest.mark.parametrize("model_class", EPSILON_ALGOS)
def test_dqn_epsilon_greedy(model_class) -> None:
    """SB3 ``test_dqn_epsilon_greedy``: the exploration branch with a Discrete observation does not crash."""
    env = IdentityEnv(2)
    model = make_model(model_class, env)
    model.exploration_rate = 1.0
    obs, _ = env.reset()
    action, _ = model.predict(obs, deterministic=False)
    assert env.action_space.contains(action)


@pytest.mark.parametrize("model_class", ALGOS)
def test_subclassed_space_env(model_class) -> None:
    """SB3 ``test_subclassed_space_env``, with subclassed Discrete spaces (the original's Box spaces: see below)."""
    env = CustomSubClassedSpaceEnv()
    model = make_model(model_class, env)
    model.learn(300)
    obs, _ = env.reset()
    env.step(model.predict(obs)[0])


def test_subclassed_box_space_env() -> None:
    """SB3 ``test_subclassed_space_env`` with its Box spaces."""
    pytest.skip(SKIP_BOX)


@pytest.mark.parametrize("deterministic", [False, True])
@pytest.mark.parametrize("model_class", ALGOS)
def test_mixing_gym_vecenv_api(model_class, deterministic) -> None:
    """SB3 ``test_mixing_gym_vecenv_api``: ``predict(env.reset())`` raises SB3's error, in every branch of predict."""
    env = gym.make("FrozenLake-v1")
    model = make_model(model_class, env)
    if model_class in EPSILON_ALGOS:
        model.exploration_rate = 1.0  # the exploration branch
    wrong_obs = env.reset()
    with pytest.raises(ValueError, match=r"mixing Gym API"):
        model.predict(wrong_obs, deterministic=deterministic)


@pytest.mark.parametrize("model_class", ALGOS)
def test_deterministic_training_common(model_class) -> None:
    """
    SB3 ``test_deterministic.py::test_deterministic_training_common``: two runs with the same seed learn the same and
    then predict (``deterministic=False``) the same actions with the same rewards.
    """
    results: list[list[int]] = [[], []]
    rewards: list[list[float]] = [[], []]
    for i in range(2):
        model = make_model(model_class, "FrozenLake-v1", seed=0)
        model.learn(500)
        env = model.get_env()
        assert env is not None
        obs = env.reset()
        for _ in range(100):
            action, _ = model.predict(obs, deterministic=False)
            obs, reward, _, _ = env.step(action)
            results[i].append(int(action[0]))
            rewards[i].append(float(reward[0]))
    assert results[0] == results[1]
    assert rewards[0] == rewards[1]


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("model_class", ALGOS)
def test_deterministic_predict_is_deterministic(model_class, env_id) -> None:
    """
    ``predict(deterministic=True)`` gives the same action for the same observation on every call, also where the
    Q-table ties (the first maximal action), and is the greedy action.
    """
    model = make_model(model_class, env_id, seed=0)
    n_states = int(model.observation_space.n)
    all_obs = np.arange(n_states)
    first, _ = model.predict(all_obs, deterministic=True)
    assert (first == 0).all()  # a fresh table ties everywhere: the first action
    model.learn(300)
    first, _ = model.predict(all_obs, deterministic=True)
    for _ in range(5):
        again, _ = model.predict(all_obs, deterministic=True)
        assert np.array_equal(first, again)
    table = model.q_table
    assert np.array_equal(first, table.argmax(axis=1))
