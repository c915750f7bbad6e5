"""Port of Stable-Baselines3's tests/test_logger.py (the cases about algorithms) to the tabular agents."""

from __future__ import annotations

import time
from unittest import mock

import gymnasium as gym
import pytest
from gymnasium import spaces
from sb3_port import ALGOS, DummySuccessEnv, InMemoryLogger, make_model
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
from stable_baselines3.common.env_checker import check_env
from stable_baselines3.common.logger import CSVOutputFormat, HumanOutputFormat, TensorBoardOutputFormat, configure
from stable_baselines3.common.monitor import Monitor


class TimeDelayEnv(gym.Env):
    """SB3's env that sleeps ``delay`` seconds per step (Discrete spaces here, Box in SB3); every step ends the episode."""

    def __init__(self, delay: float = 0.01) -> None:
        super().__init__()
        self.delay = delay
        self.observation_space = spaces.Discrete(2)
        self.action_space = spaces.Discrete(2)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[int, dict]:
        super().reset(seed=seed)
        return int(self.observation_space.sample()), {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict]:
        time.sleep(self.delay)
        return int(self.observation_space.sample()), 0.0, True, False, {}


@pytest.mark.parametrize("model_class", ALGOS)
def test_set_logger(tmp_path, monkeypatch, model_class) -> None:
    """SB3 ``test_set_logger``: default outputs by verbosity, TensorBoard, SB3_LOGDIR, and a logger set by the user."""
    env_id = "FrozenLake-v1"
    new_logger = configure(str(tmp_path), ["stdout", "csv", "tensorboard"])
    model = make_model(model_class, env_id, verbose=0).learn(4)
    assert model.logger.output_formats == []

    model = make_model(model_class, env_id, verbose=0, tensorboard_log=str(tmp_path)).learn(4)
    assert str(tmp_path) in model.logger.dir
    assert isinstance(model.logger.output_formats[0], TensorBoardOutputFormat)

    new_tmp_path = str(tmp_path / "new_tmp")
    monkeypatch.setenv("SB3_LOGDIR", new_tmp_path)
    model = make_model(model_class, env_id, verbose=0).learn(4)
    assert model.logger.dir == new_tmp_path

    model = make_model(model_class, env_id, verbose=1).learn(4)
    assert isinstance(model.logger.output_formats[0], HumanOutputFormat)
    model = make_model(model_class, env_id, verbose=1, tensorboard_log=str(tmp_path)).learn(4)
    assert isinstance(model.logger.output_formats[0], HumanOutputFormat)
    assert isinstance(model.logger.output_formats[1], TensorBoardOutputFormat)
    assert len(model.logger.output_formats) == 2
    model.learn(32)
    model.set_logger(new_logger)
    assert isinstance(model.logger.output_formats[0], HumanOutputFormat)
    assert isinstance(model.logger.output_formats[1], CSVOutputFormat)
    assert isinstance(model.logger.output_formats[2], TensorBoardOutputFormat)
    assert len(model.logger.output_formats) == 3
    model.learn(32)

    model = make_model(model_class, env_id, verbose=1)
    model.set_logger(new_logger)
    model.learn(32)
    assert isinstance(model.logger.output_formats[0], HumanOutputFormat)
    assert isinstance(model.logger.output_formats[1], CSVOutputFormat)
    assert isinstance(model.logger.output_formats[2], TensorBoardOutputFormat)
    assert len(model.logger.output_formats) == 3


def test_time_delay_env() -> None:
    """SB3 ``test_env``: the env used below passes SB3's env checker."""
    check_env(TimeDelayEnv(), skip_render_check=True)


@pytest.mark.parametrize("model_class", ALGOS)
def test_fps_logger(model_class) -> None:
    """
    SB3 ``test_fps_logger``: ``time/fps`` reaches a logger without output formats, never exceeds what the env's
    sleep allows, and is computed afresh by each ``learn`` (even with ``num_timesteps`` moved far ahead). The
    original's lower bound (max_fps / 10) is a timing assertion on a shared machine, so only "> 0" is kept.
    """
    logger = InMemoryLogger()
    max_fps = 1000
    model = make_model(model_class, TimeDelayEnv(1 / max_fps), verbose=1)
    model.set_logger(logger)

    model.learn(100, log_interval=1)
    assert 0 < logger.name_to_value["time/fps"] <= max_fps
    model.learn(100, log_interval=1)
    assert 0 < logger.name_to_value["time/fps"] <= max_fps
    model.num_timesteps = 20_000
    model.learn(100, log_interval=1, reset_num_timesteps=False)
    assert 0 < logger.name_to_value["time/fps"] <= max_fps


@pytest.mark.parametrize("model_class", ALGOS)
def test_fps_no_div_zero(model_class) -> None:
    """SB3 ``test_fps_no_div_zero``: a clock that does not move does not divide by zero."""
    with mock.patch("time.time", lambda: 42.0), mock.patch("time.time_ns", lambda: 42.0):
        model = make_model(model_class, "FrozenLake-v1")
        model.learn(total_timesteps=100)


@pytest.mark.parametrize("stats_window_size", [1, 42])
@pytest.mark.parametrize("model_class", ALGOS)
def test_ep_buffers_stats_window_size(model_class, stats_window_size) -> None:
    """SB3 ``test_ep_buffers_stats_window_size``."""
    model = make_model(model_class, "FrozenLake-v1", stats_window_size=stats_window_size)
    model.learn(total_timesteps=10)
    assert model.ep_info_buffer is not None and model.ep_info_buffer.maxlen == stats_window_size
    assert model.ep_success_buffer is not None and model.ep_success_buffer.maxlen == stats_window_size


@pytest.mark.parametrize("model_class", ALGOS)
def test_rollout_success_rate(tmp_path, model_class) -> None:
    """
    SB3 ``test_rollout_success_rate_onpolicy_algo``: ``rollout/success_rate`` is the mean ``is_success`` of the last
    ``stats_window_size`` episodes. The original sizes ``total_timesteps`` to 100 PPO episodes; the tabular agents
    count decisions, and some move 2 cells or none per decision, so the port stops each ``learn`` after 100 episodes.
    """
    stats_window_size = 10
    dummy_successes = [[True] * 3 + [False] * 7, [True] * 5 + [False] * 5, [True] * 8 + [False] * 2]
    ep_steps = 10
    monitor_file = str(tmp_path / "monitor.csv")
    env = Monitor(DummySuccessEnv(dummy_successes, ep_steps), filename=monitor_file, info_keywords=("is_success",))
    model = make_model(model_class, env, stats_window_size=stats_window_size, verbose=1)
    logger = InMemoryLogger()
    model.set_logger(logger)
    for expected in (0.3, 0.5, 0.8):
        model.learn(total_timesteps=10_000, log_interval=1, callback=StopTrainingOnMaxEpisodes(100))
        assert logger.name_to_value["rollout/success_rate"] == pytest.approx(expected)


@pytest.mark.parametrize("model_class", ALGOS)
def test_logger_without_outputs_receives_sb3s_keys(model_class) -> None:
    """A logger without output formats receives what SB3's DQN records (a custom logger reading name_to_value)."""
    logger = InMemoryLogger()
    model = make_model(model_class, "sb3_affect/GridPursuit-v0", seed=0)
    model.set_logger(logger)
    model.learn(2000, log_interval=1)
    values = logger.name_to_value
    for key in ("time/episodes", "time/fps", "time/total_timesteps", "rollout/ep_rew_mean", "rollout/ep_len_mean"):
        assert key in values, key
    assert values["time/fps"] > 0
    assert 0 < values["time/total_timesteps"] <= model.num_timesteps
    assert 0 < values["rollout/ep_rew_mean"] <= 100.0  # the goal's 100, or 0 for an episode the cap truncated
    assert "rollout/exploration_rate" in values and "train/learning_rate" in values


def test_the_engine_a_learn_ran_on_is_an_attribute_a_logger_key_and_said_once(tmp_path, capsys) -> None:
    import pandas as pd
    from stable_baselines3.common.callbacks import BaseCallback

    from sb3_affect import QLearning

    class EveryDecision(BaseCallback):  # called after each decision: the kernel can not run it
        def _on_step(self) -> bool:
            return True

    model = QLearning("Grid", gym.make("sb3_affect/GridPursuit-v0", size=5, goal=(2, 3)), seed=0, verbose=1)
    assert model.engine_used is None
    model.set_logger(configure(str(tmp_path), ["csv", "stdout"]))
    model.learn(300, log_interval=1)
    model.learn(300, log_interval=1, reset_num_timesteps=False)
    out = capsys.readouterr().out
    assert model.engine_used == "compiled" and out.count("QLearning.learn runs on the compiled engine") == 1
    model.learn(300, callback=EveryDecision(), log_interval=1, reset_num_timesteps=False)
    out = capsys.readouterr().out
    assert model.engine_used == "python"
    assert out.count("QLearning.learn runs the Python loop (the callback EveryDecision is called after every") == 1, out
    engines = pd.read_csv(tmp_path / "progress.csv")["train/engine"]
    assert engines.notna().all() and set(engines) == {"compiled", "python"} and engines.iloc[-1] == "python"
