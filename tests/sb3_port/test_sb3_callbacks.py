"""Port of Stable-Baselines3's tests/agents/test_callbacks.py (algorithm-generic cases) to the tabular agents."""

from __future__ import annotations

import os
import shutil

import numpy as np
import pytest
import torch as th
from sb3_port import (
    ALGOS,
    ENV_IDS,
    SKIP_MULTI_ENV,
    SKIP_REPLAY_BUFFER,
    SKIP_VECNORMALIZE,
    DummySuccessEnv,
    eval_env,
    make_model,
)
from stable_baselines3.common.callbacks import (
    BaseCallback,
    CallbackList,
    CheckpointCallback,
    EvalCallback,
    EveryNTimesteps,
    LogEveryNTimesteps,
    StopTrainingOnMaxEpisodes,
    StopTrainingOnNoModelImprovement,
    StopTrainingOnRewardThreshold,
)
from stable_baselines3.common.envs import IdentityEnv
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_affect import QLearning


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("model_class", ALGOS)
def test_callbacks(tmp_path, model_class, env_id) -> None:
    """SB3 ``test_callbacks``: SB3's callbacks together, their locals and counters, the other callback forms."""
    log_folder = tmp_path / "logs/callbacks/"
    model = make_model(model_class, env_id, seed=0)

    checkpoint_callback = CheckpointCallback(save_freq=512, save_path=log_folder)
    evaluation_env = eval_env(env_id)
    callback_on_best = StopTrainingOnRewardThreshold(reward_threshold=1e9, verbose=1)
    callback_no_model_improvement = StopTrainingOnNoModelImprovement(max_no_improvement_evals=2, min_evals=1, verbose=1)
    eval_callback = EvalCallback(
        evaluation_env,
        callback_on_new_best=callback_on_best,
        callback_after_eval=callback_no_model_improvement,
        best_model_save_path=log_folder,
        log_path=log_folder,
        eval_freq=32,
        n_eval_episodes=1,
        warn=False,
    )
    checkpoint_on_event = CheckpointCallback(save_freq=1, save_path=log_folder, name_prefix="event")
    event_callback = EveryNTimesteps(n_steps=128, callback=checkpoint_on_event)
    log_callback = LogEveryNTimesteps(n_steps=64)
    callback_max_episodes = StopTrainingOnMaxEpisodes(max_episodes=100, verbose=1)

    callback = CallbackList([checkpoint_callback, eval_callback, event_callback, log_callback, callback_max_episodes])
    model.learn(128, callback=callback)

    assert model.env is not None
    assert model.env.observation_space.contains(callback.locals["new_obs"][0])
    assert checkpoint_callback.locals["new_obs"] is callback.locals["new_obs"]
    assert event_callback.locals["new_obs"] is callback.locals["new_obs"]
    assert checkpoint_on_event.locals["new_obs"] is callback.locals["new_obs"]
    assert event_callback.num_timesteps == model.num_timesteps
    assert event_callback.n_calls == model.num_timesteps

    model.learn(128, callback=None)
    model.learn(128, callback=[checkpoint_callback, eval_callback], progress_bar=True)
    model.learn(128, callback=lambda _locals, _globals: True)
    if os.path.exists(log_folder):
        shutil.rmtree(log_folder)


@pytest.mark.parametrize("model_class", ALGOS)
def test_callbacks_multi_env(model_class) -> None:
    """SB3 ``test_callbacks``, last part: StopTrainingOnMaxEpisodes with several envs."""
    pytest.skip(SKIP_MULTI_ENV)


@pytest.mark.parametrize("model_class", ALGOS)
def test_eval_callback_vec_env(model_class) -> None:
    """SB3 ``test_eval_callback_vec_env``: an EvalCallback on a 3-env VecEnv (batched predict) does not crash."""
    n_eval_envs = 3
    model = make_model(model_class, IdentityEnv(), seed=0)
    eval_envs = DummyVecEnv([lambda: IdentityEnv()] * n_eval_envs)
    eval_callback = EvalCallback(eval_envs, eval_freq=100, warn=False)
    model.learn(300, callback=eval_callback)
    assert eval_callback.last_mean_reward == 100.0


class AlwaysFailCallback(BaseCallback):
    def __init__(self, *args, callback_false_value, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.callback_false_value = callback_false_value

    def _on_step(self) -> bool:
        return self.callback_false_value


@pytest.mark.parametrize("callback_false_value", [False, np.bool_(0), th.tensor(0, dtype=th.bool)])
@pytest.mark.parametrize("model_class", ALGOS)
def test_callbacks_can_cancel_runs(model_class, callback_false_value) -> None:
    """SB3 ``test_callbacks_can_cancel_runs``: a callback returning a false value stops learn after one call."""
    assert not callback_false_value
    model = make_model(model_class, "sb3_affect/GridPursuit-v0", stats_window_size=1)
    always_fail = AlwaysFailCallback(callback_false_value=callback_false_value)
    model.learn(10, callback=always_fail)
    assert always_fail.n_calls == 1
    assert model.num_timesteps == 1


@pytest.mark.parametrize("model_class", ALGOS)
def test_eval_success_logging(tmp_path, model_class) -> None:
    """
    SB3 ``test_eval_success_logging``: EvalCallback collects ``is_success``. The original's BitFlippingEnv with HER
    needs a Dict observation and a replay buffer; this port uses SB3's logger-test env with Discrete spaces, which
    reports ``is_success`` at each episode end, successes 3 in 10 (so each 10-episode evaluation sees 0.3).
    """
    successes = [[True] * 3 + [False] * 7]
    env = DummySuccessEnv(successes, ep_steps=5)
    eval_envs = DummyVecEnv([lambda: DummySuccessEnv(successes, ep_steps=5)])
    eval_callback = EvalCallback(eval_envs, eval_freq=50, n_eval_episodes=10, log_path=tmp_path, warn=False)
    model = make_model(model_class, env, seed=0)
    model.learn(200, callback=eval_callback)
    assert len(eval_callback._is_success_buffer) > 0
    assert np.mean(eval_callback._is_success_buffer) == pytest.approx(0.3)


@pytest.mark.parametrize("model_class", ALGOS)
def test_eval_callback_logs_are_written_with_the_correct_timestep(tmp_path, model_class) -> None:
    """SB3 ``test_eval_callback_logs_are_written_with_the_correct_timestep``; the run is ``<ClassName>_1``."""
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    env_id = "FrozenLake-v1"
    model = make_model(model_class, env_id, tensorboard_log=str(tmp_path), verbose=1, seed=1)
    eval_freq = 101
    eval_callback = EvalCallback(eval_env(env_id), eval_freq=eval_freq, n_eval_episodes=2, warn=False)
    model.learn(500, callback=eval_callback)

    acc = EventAccumulator(str(tmp_path / f"{model_class.__name__}_1"))
    acc.Reload()
    events = acc.scalars.Items("eval/mean_reward")
    assert len(events) > 0
    for event in events:
        assert event.step % eval_freq == 0


@pytest.mark.parametrize("model_class", ALGOS)
def test_eval_friendly_error(model_class) -> None:
    """SB3 ``test_eval_friendly_error`` (VecNormalize train and eval envs)."""
    pytest.skip(SKIP_VECNORMALIZE)


@pytest.mark.parametrize("model_class", ALGOS)
def test_checkpoint_additional_info(tmp_path, model_class) -> None:
    """
    SB3 ``test_checkpoint_additional_info``: a checkpoint is written at the right step and loads. Its replay buffer
    and VecNormalize parts do not apply (no replay buffer; no VecNormalize on Discrete observations), and a
    checkpoint asked to save them writes only the model.
    """
    checkpoint_dir = tmp_path / "checkpoints"
    checkpoint_callback = CheckpointCallback(
        save_freq=200, save_path=checkpoint_dir, save_replay_buffer=True, save_vecnormalize=True, verbose=2
    )
    model = make_model(model_class, "Taxi-v4", seed=0)
    model.learn(200, callback=checkpoint_callback)
    assert os.path.exists(checkpoint_dir / "rl_model_200_steps.zip")
    assert not os.path.exists(checkpoint_dir / "rl_model_replay_buffer_200_steps.pkl")
    loaded = model_class.load(checkpoint_dir / "rl_model_200_steps.zip")
    assert np.array_equal(loaded.q_table, model.q_table)  # the checkpoint is the table at step 200, the last one


def test_checkpoint_replay_buffer() -> None:
    """SB3 ``test_checkpoint_additional_info``, replay-buffer part."""
    pytest.skip(SKIP_REPLAY_BUFFER)


@pytest.mark.parametrize("model_class", ALGOS)
def test_eval_callback_chaining(tmp_path, model_class) -> None:
    """SB3 ``test_eval_callback_chaining``: child callbacks of an EvalCallback see it as their parent."""

    class DummyCallback(BaseCallback):
        def _on_step(self) -> bool:
            assert isinstance(self.parent, EvalCallback)
            assert hasattr(self.parent, "best_mean_reward")
            return True

    stop_on_threshold_callback = StopTrainingOnRewardThreshold(reward_threshold=-200, verbose=1)
    eval_callback = EvalCallback(
        eval_env("CliffWalking-v1"),
        best_model_save_path=tmp_path,
        log_path=tmp_path,
        eval_freq=32,
        n_eval_episodes=2,
        deterministic=True,
        render=False,
        callback_on_new_best=CallbackList([DummyCallback(), stop_on_threshold_callback]),
        callback_after_eval=CallbackList([DummyCallback()]),
        warn=False,
    )
    model = make_model(model_class, "CliffWalking-v1")
    model.learn(64, callback=eval_callback)
    assert eval_callback.n_calls == 64 or eval_callback.n_calls % 32 == 0


def test_eval_callback_sees_the_table_being_learnt() -> None:
    """
    Not in SB3 (its networks are always live): an EvalCallback evaluates the table learnt so far, not the table
    the model had when learn started.
    """
    seen = []

    class Snapshot(BaseCallback):
        def _on_step(self) -> bool:
            if self.n_calls % 50 == 0:
                seen.append(self.model.get_parameters()["policy"]["q_table"].clone())
            return True

    model = QLearning("Grid", "sb3_affect/GridPursuit-v0", seed=0)
    model.learn(2000, callback=Snapshot())
    assert len(seen) == 40
    assert not th.equal(seen[0], seen[-1])
    assert th.count_nonzero(seen[-1]) > 0


def test_replay_buffer_callbacks() -> None:
    """SB3's callback tests that save or load a replay buffer."""
    pytest.skip(SKIP_REPLAY_BUFFER)
