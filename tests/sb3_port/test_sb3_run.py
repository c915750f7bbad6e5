"""
Port of Stable-Baselines3's tests/test_run.py and tests/test_tensorboard.py, and of sb3-contrib's tests/test_run.py
(their algorithm-generic cases), to the tabular agents.
"""

from __future__ import annotations

import inspect
import os

import gymnasium as gym
import pytest
from sb3_port import ALGOS, ENV_IDS, SKIP_MULTI_ENV, make_model
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import HParam


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("model_class", ALGOS)
def test_run(model_class, env_id) -> None:
    """SB3 ``test_dqn``/``test_a2c`` and contrib's per-algorithm runs: build with a seed, verbose, and learn."""
    model = make_model(model_class, env_id, seed=0, verbose=1)
    model.learn(total_timesteps=200)
    assert model.num_timesteps == 200


@pytest.mark.parametrize("model_class", ALGOS)
def test_run_progress_bar(model_class) -> None:
    """contrib ``test_tqc`` (``learn(..., progress_bar=True)``)."""
    model = make_model(model_class, "FrozenLake-v1", verbose=1)
    model.learn(total_timesteps=110, progress_bar=True)
    assert model.num_timesteps == 110


@pytest.mark.parametrize("model_class", ALGOS)
def test_load_with_overridden_hyperparameter(tmp_path, model_class) -> None:
    """SB3 ``test_train_freq``: save, load with the env, learn; load with a hyperparameter overridden, learn."""
    model = make_model(model_class, "Taxi-v4", verbose=1, seed=0)
    model.learn(total_timesteps=150)
    model.save(tmp_path / "test_save.zip")
    env = model.get_env()
    model = model_class.load(tmp_path / "test_save.zip", env=env)
    model.learn(total_timesteps=150)
    model = model_class.load(tmp_path / "test_save.zip", gamma=0.5, env=env)
    assert model.gamma == 0.5
    model.learn(total_timesteps=150)


@pytest.mark.parametrize(
    "kwargs",
    [{"learning_rate": "4"}, {"learning_rate": 0.0}, {"gamma": 1.5}, {"max_episode_decisions": 0}, {"q_init": "x"}],
)
@pytest.mark.parametrize("model_class", ALGOS)
def test_bad_hyperparameter_fails(model_class, kwargs) -> None:
    """SB3 ``test_train_freq_fail``: a bad hyperparameter raises a ValueError (or a TypeError for a wrong type)."""
    with pytest.raises((ValueError, TypeError)):
        make_model(model_class, "FrozenLake-v1", **kwargs).learn(total_timesteps=250)


@pytest.mark.parametrize("model_class", ALGOS)
def test_offpolicy_multi_env(model_class) -> None:
    """SB3 ``test_offpolicy_multi_env`` and ``test_warn_dqn_multi_env``."""
    pytest.skip(SKIP_MULTI_ENV)


@pytest.mark.parametrize("model_class", ALGOS)
def test_n_updates_and_time_limit(model_class) -> None:
    """
    SB3 ``test_offpolicy_multi_env``, one-env part: a TimeLimit wrapper's truncations are handled and the logger's
    ``train/n_updates`` counts the updates made (one per decision for the tabular agents).
    """
    from sb3_port import InMemoryLogger

    env = gym.wrappers.TimeLimit(gym.make("CliffWalking-v1"), 50)
    model = make_model(model_class, env)
    logger = InMemoryLogger()
    model.set_logger(logger)
    model.learn(total_timesteps=150, log_interval=1)
    assert model.truncated_episodes >= 1
    assert logger.name_to_value["train/n_updates"] <= 150
    assert logger.name_to_value["train/n_updates"] == logger.name_to_value["time/total_timesteps"]


@pytest.mark.parametrize("model_class", ALGOS)
def test_learn_zero_timesteps(model_class) -> None:
    """SB3's algorithms accept ``learn(0)`` (their loops run zero times); so do the tabular agents."""
    model = make_model(model_class, "FrozenLake-v1", seed=0)
    model.learn(0)
    assert model.num_timesteps == 0
    assert len(model.episode_log) == 0
    model.learn(10, reset_num_timesteps=False)
    assert model.num_timesteps == 10


@pytest.mark.parametrize("model_class", ALGOS)
def test_learn_signature_is_sb3s(model_class) -> None:
    """``learn`` shows SB3's parameters to ``inspect`` (tools such as RL Zoo pass them by name)."""
    params = list(inspect.signature(model_class.learn).parameters)
    expected = [p for p in inspect.signature(DQN.learn).parameters]
    assert params == expected


class HParamCallback(BaseCallback):
    """SB3's tests/test_tensorboard.py callback: hyperparameters and metrics logged to TensorBoard."""

    def _on_training_start(self) -> None:
        hparam_dict: dict[str, str | float] = {"algorithm": self.model.__class__.__name__, "gamma": self.model.gamma}
        if isinstance(self.model.learning_rate, float):
            hparam_dict["learning rate"] = self.model.learning_rate
        metric_dict: dict[str, float] = {"rollout/ep_len_mean": 0}
        self.logger.record("hparams", HParam(hparam_dict, metric_dict), exclude=("stdout", "log", "json", "csv"))

    def _on_step(self) -> bool:
        return True


@pytest.mark.parametrize("model_class", ALGOS)
def test_tensorboard(tmp_path, model_class) -> None:
    """SB3 ``test_tensorboard``: runs are named ``<ClassName>_<n>``; continuing a run writes to the same folder."""
    pytest.importorskip("tensorboard")
    n_steps = 100
    logname = model_class.__name__
    model = make_model(model_class, "FrozenLake-v1", verbose=1, tensorboard_log=str(tmp_path))
    model.learn(n_steps, callback=HParamCallback())
    model.learn(n_steps, reset_num_timesteps=False)
    assert os.path.isdir(tmp_path / f"{logname}_1")
    assert not os.path.isdir(tmp_path / f"{logname}_2")

    logname = "tb_multiple_runs_" + model_class.__name__
    model.learn(n_steps, tb_log_name=logname)
    model.learn(n_steps, tb_log_name=logname)
    assert os.path.isdir(tmp_path / f"{logname}_1")
    assert os.path.isdir(tmp_path / f"{logname}_2")
