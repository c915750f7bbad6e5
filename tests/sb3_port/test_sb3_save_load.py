"""
Port of Stable-Baselines3's tests/test_save_load.py and sb3-contrib's tests/test_save_load.py (algorithm-generic
cases) to the tabular agents. Each test names the original it ports; adaptations are stated in its docstring.
"""

from __future__ import annotations

import base64
import json
import os
import tempfile
import warnings
import zipfile
from collections import OrderedDict
from copy import deepcopy

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from sb3_port import (
    ALGOS,
    ENV_IDS,
    SKIP_CNN,
    SKIP_MULTI_ENV,
    SKIP_Q_NET,
    SKIP_REPLAY_BUFFER,
    SKIP_SDE,
    make_model,
    observations,
)
from stable_baselines3.common.utils import ConstantSchedule, FloatSchedule, LinearSchedule, get_device
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_affect import QLearning


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("model_class", ALGOS)
def test_save_load(tmp_path, model_class, env_id) -> None:
    """
    SB3 ``test_save_load`` (and contrib's): ``get_parameters``/``set_parameters`` error cases, parameters set before
    ``save`` are those loaded on every device, predictions are unchanged, learning continues, and a ``th.compile``d
    policy saves and loads. Adaptation: the policy's state dict holds one tensor (the Q-table), so "randomise all but
    the last tensor" (which would randomise nothing) becomes "randomise the Q-table".
    """
    env = DummyVecEnv([lambda: gym.make(env_id)])
    model = make_model(model_class, env, seed=0)
    model.learn(total_timesteps=128)
    obs = observations(env_id)

    original_params = deepcopy(model.get_parameters())

    invalid_object_params = deepcopy(original_params)
    invalid_object_params["I_should_not_be_a_valid_object"] = "and_I_am_an_invalid_tensor"
    with pytest.raises(ValueError):
        model.set_parameters(invalid_object_params, exact_match=True)
    with pytest.raises(ValueError):
        model.set_parameters(invalid_object_params, exact_match=False)

    missing_object_params = {k: v for k, v in list(original_params.items())[:-1]}
    with pytest.raises(ValueError):
        model.set_parameters(missing_object_params, exact_match=True)

    missing_state_dict_tensor_params = {name: OrderedDict() for name in original_params}
    with pytest.raises(RuntimeError):
        model.set_parameters(missing_state_dict_tensor_params, exact_match=True)

    random_params = {
        name: OrderedDict((key, th.rand_like(value)) for key, value in params.items())
        for name, params in original_params.items()
    }
    model.set_parameters(random_params, exact_match=True)
    new_params = model.get_parameters()
    for name in original_params:
        for key in original_params[name]:
            assert not th.allclose(original_params[name][key], new_params[name][key]), "Parameters did not change"
    params = new_params

    selected_actions, _ = model.predict(obs, deterministic=True)
    model.save(tmp_path / "test_save.zip")
    # saving does not change the live model
    for name in params:
        for key in params[name]:
            assert th.equal(params[name][key], model.get_parameters()[name][key])
    del model

    for device in ["auto", "cpu", "cuda"]:
        model = model_class.load(str(tmp_path / "test_save.zip"), env=env, device=device)
        assert model.device.type == get_device(device).type
        assert model.policy.device.type == get_device(device).type
        new_params = model.get_parameters()
        for name in new_params:
            for key in params[name]:
                assert new_params[name][key].device.type == get_device(device).type
                assert th.allclose(params[name][key].to("cpu"), new_params[name][key].to("cpu")), (
                    "Model parameters not the same after save and load."
                )
        new_selected_actions, _ = model.predict(obs, deterministic=True)
        assert np.allclose(selected_actions, new_selected_actions, 1e-4)
        model.learn(total_timesteps=128)
        del model

    # loading after compiling works (SB3 GH#2137); legacy loader, as SB3's test uses SB3's own
    model = model_class.load(tmp_path / "test_save.zip")
    model.policy = th.compile(model.policy)
    model.save(tmp_path / "test_save.zip")
    model_class.load(tmp_path / "test_save.zip", safe=False)
    os.remove(tmp_path / "test_save.zip")


@pytest.mark.parametrize("model_class", ALGOS)
def test_set_env(tmp_path, model_class) -> None:
    """SB3 ``test_set_env`` (one-env parts; contrib's is a subset): set_env, force_reset, timesteps kept on load."""
    env_id = "FrozenLake-v1"
    env = DummyVecEnv([lambda: gym.make(env_id)])
    env2 = DummyVecEnv([lambda: gym.make(env_id)])
    env3 = gym.make(env_id)
    env4 = DummyVecEnv([lambda: gym.make(env_id) for _ in range(2)])

    model = make_model(model_class, env)
    model.learn(total_timesteps=64)

    model.set_env(env2, force_reset=True)
    assert model._last_obs is None
    model.learn(total_timesteps=64, reset_num_timesteps=True)
    assert model.num_timesteps == 64

    model.set_env(env3)
    model.learn(total_timesteps=64)

    with pytest.raises(AssertionError):
        model.set_env(env4)

    model.set_env(model.get_env(), force_reset=False)
    assert model._last_obs is not None
    model.learn(total_timesteps=64, reset_num_timesteps=False)
    assert model.num_timesteps == 2 * 64

    current_env = model.get_env()
    model.save(tmp_path / "test_save.zip")
    del model
    model = model_class.load(tmp_path / "test_save.zip", env=current_env, force_reset=False)
    assert model._last_obs is not None
    model.learn(total_timesteps=64, reset_num_timesteps=False)
    assert model.num_timesteps == 3 * 64

    del model
    model = model_class.load(tmp_path / "test_save.zip", env=env3, force_reset=True)
    assert model._last_obs is None
    model.learn(total_timesteps=64, reset_num_timesteps=False)
    assert model.num_timesteps == 3 * 64


@pytest.mark.parametrize("model_class", ALGOS)
def test_set_env_load_with_more_envs(model_class) -> None:
    """SB3 ``test_set_env``, last part: load the model with a different number of envs."""
    pytest.skip(SKIP_MULTI_ENV)


@pytest.mark.parametrize("model_class", ALGOS)
def test_exclude_include_saved_params(tmp_path, model_class) -> None:
    """
    SB3 ``test_exclude_include_saved_params`` (and contrib's). ``custom_objects`` belongs to SB3's legacy loader
    (it replaces pickled objects), so that part loads with ``safe=False``; the rest uses the default safe loader.
    """
    env = DummyVecEnv([lambda: gym.make("FrozenLake-v1")])
    model = make_model(model_class, env, verbose=2)

    model.save(tmp_path / "test_save", exclude=["verbose"])
    del model
    model = model_class.load(str(tmp_path / "test_save.zip"))
    assert model.verbose != 2

    model.verbose = 2
    model.save(tmp_path / "test_save", exclude=["verbose"], include=["verbose"])
    del model
    assert model_class.load(str(tmp_path / "test_save.zip")).verbose == 2  # contrib's version stops here
    custom_objects = dict(learning_rate=0.5, dummy=1.0)
    model = model_class.load(
        str(tmp_path / "test_save.zip"), custom_objects=custom_objects, print_system_info=True, safe=False
    )
    assert model.verbose == 2
    assert model.learning_rate == custom_objects["learning_rate"]
    assert not hasattr(model, "dummy")
    os.remove(tmp_path / "test_save.zip")


@pytest.mark.parametrize("model_class", ALGOS)
def test_save_load_replay_buffer(model_class) -> None:
    """SB3 ``test_save_load_replay_buffer`` and ``test_warn_buffer``."""
    pytest.skip(SKIP_REPLAY_BUFFER)


@pytest.mark.parametrize("use_sde", [False, True])
@pytest.mark.parametrize("policy_str", ["Grid", "CnnPolicy"])
@pytest.mark.parametrize("model_class", ALGOS)
def test_save_load_policy(tmp_path, model_class, policy_str, use_sde) -> None:
    """SB3 ``test_save_load_policy`` (and contrib's): save and load the policy alone, with random parameters."""
    if policy_str == "CnnPolicy":
        pytest.skip(SKIP_CNN)
    if use_sde:
        pytest.skip(SKIP_SDE)
    env_id = "Taxi-v4"
    model = make_model(model_class, DummyVecEnv([lambda: gym.make(env_id)]))
    model.learn(total_timesteps=128)
    obs = observations(env_id)

    policy = model.policy
    policy_class = policy.__class__
    params = deepcopy(policy.state_dict())
    policy.load_state_dict({name: th.rand_like(value) for name, value in params.items()})
    new_params = policy.state_dict()
    for k in params:
        assert not th.allclose(params[k], new_params[k]), "Parameters did not change as expected."
    params = new_params

    selected_actions, _ = policy.predict(obs, deterministic=True)
    policy.save(tmp_path / "policy.pkl")
    del policy
    policy = policy_class.load(tmp_path / "policy.pkl")
    new_params = policy.state_dict()
    for key in params:
        assert th.allclose(params[key], new_params[key]), "Policy parameters not the same after save and load."
    new_selected_actions, _ = policy.predict(obs, deterministic=True)
    assert np.allclose(selected_actions, new_selected_actions, 1e-4)
    os.remove(tmp_path / "policy.pkl")


@pytest.mark.parametrize("model_class", ALGOS)
def test_save_load_q_net(model_class) -> None:
    """SB3 ``test_save_load_q_net`` (and contrib's, for QR-DQN's quantile net)."""
    pytest.skip(SKIP_Q_NET)


@pytest.mark.parametrize("model_class", ALGOS)
def test_save_load_env_cnn(model_class) -> None:
    """SB3 ``test_save_load_env_cnn``."""
    pytest.skip(SKIP_CNN)


def test_load_invalid_object(tmp_path) -> None:
    """
    SB3 ``test_load_invalid_object``: a corrupt pickled schedule warns and names ``custom_objects`` (legacy loader);
    with ``custom_objects`` there is no warning. The safe loader refuses the corrupt file outright.
    """
    path = str(tmp_path / "qlearning.zip")
    QLearning("Grid", "FrozenLake-v1", learning_rate=lambda _: 1.0).save(path)
    with zipfile.ZipFile(path, mode="r") as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    json_data = json.loads(members["data"].decode())
    serialization = json_data["learning_rate"][":serialized:"]
    new_bytes = base64.b64decode(serialization.encode()).replace(b"CodeType", b"CodeTyps")
    json_data["learning_rate"][":serialized:"] = base64.b64encode(new_bytes).decode()
    members["data"] = json.dumps(json_data, indent=4).encode()
    with zipfile.ZipFile(path, mode="w") as archive:
        for name, payload in members.items():
            archive.writestr(name, payload)

    with pytest.warns(UserWarning, match=r"custom_objects"):
        QLearning.load(path, safe=False)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        QLearning.load(path, custom_objects=dict(learning_rate=lambda _: 1.0), safe=False)
    assert len(record) == 0
    from sb3_affect.agents.serialization import ModelFileError

    with pytest.raises(ModelFileError, match="learning_rate"):
        QLearning.load(path)


@pytest.mark.parametrize("model_class", ALGOS)
def test_hyperparameters_survive_reload(tmp_path, model_class) -> None:
    """
    SB3 ``test_dqn_target_update_interval`` (and contrib's): a hyperparameter must not change when the model is
    reloaded. Generalised to every constructor argument of every tabular agent that differs from its default.
    """
    model = make_model(model_class, "FrozenLake-v1", gamma=0.5, q_init=0.25, learning_rate=0.3, stats_window_size=7)
    model.save(tmp_path / "model")
    loaded = model_class.load(tmp_path / "model")
    for name in ("gamma", "q_init", "learning_rate", "max_episode_decisions"):
        assert getattr(loaded, name) == getattr(model, name), name
    assert loaded._stats_window_size == 7
    loaded.set_env(gym.make("FrozenLake-v1"))
    loaded.learn(1)
    assert loaded.ep_info_buffer is not None and loaded.ep_info_buffer.maxlen == 7


@pytest.mark.filterwarnings("error")
def test_no_resource_warning(tmp_path) -> None:
    """SB3 ``test_no_resource_warning`` (model part; the replay-buffer part does not apply): files are closed."""
    QLearning("Grid", "FrozenLake-v1", device="cpu").save(tmp_path / "q")
    QLearning.load(tmp_path / "q", device="cpu")
    QLearning("Grid", "FrozenLake-v1", device="cpu").save(str(tmp_path / "q"))
    QLearning.load(str(tmp_path / "q"), device="cpu")
    with tempfile.TemporaryFile() as fp:
        QLearning("Grid", "FrozenLake-v1", device="cpu").save(fp)
        fp.seek(0)
        QLearning.load(fp, device="cpu")
        assert not fp.closed


def test_cast_lr_schedule(tmp_path) -> None:
    """SB3 ``test_cast_lr_schedule`` (GH#1900): the learning-rate schedule returns a Python float, also after load."""
    model = QLearning("Grid", "FrozenLake-v1", learning_rate=lambda t: 0.5 + 0.5 * t * np.sin(1.0))
    assert type(model.lr_schedule(1.0)) is float
    assert np.allclose(model.lr_schedule(0.5), 0.5 + 0.25 * np.sin(1.0))
    model.save(tmp_path / "q.zip")
    model = QLearning.load(tmp_path / "q.zip", safe=False)  # a lambda can only be unpickled
    assert type(model.lr_schedule(1.0)) is float
    assert np.allclose(model.lr_schedule(0.5), 0.5 + 0.25 * np.sin(1.0))


def test_save_load_backward_compatible(tmp_path) -> None:
    """SB3 ``test_save_load_backward_compatible`` (GH#2115): lambdas as schedules still load (legacy loader)."""
    env = DummyVecEnv([lambda: gym.make("FrozenLake-v1")])
    model = QLearning("Grid", env, learning_rate=lambda _: 0.001, exploration_rate=lambda _: 0.3)
    model.learn(total_timesteps=100)
    model.save(tmp_path / "test_schedule_safe.zip")
    model = QLearning.load(tmp_path / "test_schedule_safe.zip", env=env, safe=False)
    assert model.learning_rate(0) == 0.001
    assert model.learning_rate.__name__ == "<lambda>"
    assert isinstance(model.exploration_schedule, FloatSchedule)
    assert model.exploration_schedule.value_schedule(0) == 0.3


def test_save_load_schedule_portable(tmp_path) -> None:
    """
    SB3 ``test_save_load_clip_range_portable`` (GH#2115): schedule classes (not lambdas) survive save and load, here
    with the safe loader, which rebuilds them from plain data.
    """
    env = DummyVecEnv([lambda: gym.make("FrozenLake-v1")])
    model = QLearning("Grid", env, exploration_rate=LinearSchedule(1.0, 0.05, 0.5))
    model.learn(total_timesteps=128)
    assert isinstance(model.exploration_schedule, FloatSchedule)
    assert isinstance(model.lr_schedule, FloatSchedule)
    assert isinstance(model.lr_schedule.value_schedule, ConstantSchedule)
    model.save(tmp_path / "test_schedule_safe.zip")
    model = QLearning.load(tmp_path / "test_schedule_safe.zip", env=env)
    assert isinstance(model.exploration_schedule, FloatSchedule)
    assert isinstance(model.exploration_schedule.value_schedule, LinearSchedule)
    assert model.exploration_schedule(0.0) == pytest.approx(0.05)
    assert isinstance(model.lr_schedule.value_schedule, ConstantSchedule)
    assert model.lr_schedule.value_schedule.val == 1.0
