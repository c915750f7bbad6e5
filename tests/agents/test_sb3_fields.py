"""``ModelFields`` reads and writes the fields SB3's own loop keeps: a new SB3 that renames one fails here."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3 import DQN, PPO

from sb3_affect.agents.sb3_fields import ModelFields


@pytest.fixture(scope="module")
def dqn() -> DQN:
    return DQN("MlpPolicy", "CartPole-v1", learning_starts=50, train_freq=4, target_update_interval=50,
               stats_window_size=7, seed=0, device="cpu").learn(200)


def test_the_counts_are_sb3s_own(dqn: DQN) -> None:
    fields = ModelFields(dqn)
    episodes = len(dqn.get_env().env_method("get_episode_rewards")[0])
    assert (fields.n_calls, fields.n_updates, fields.episode_num) == (200, 38, episodes) and episodes > 7
    assert fields.progress == 0.0 and fields.stats_window_size == 7 == len(dqn.ep_info_buffer)
    fields.update_progress(50, 200)
    fields.n_updates += 1
    assert (dqn._current_progress_remaining, dqn._n_updates) == (fields.progress, fields.n_updates) == (0.75, 39)


def test_the_observation_is_the_one_the_next_step_acts_on(dqn: DQN) -> None:
    fields = ModelFields(dqn)
    observation = np.array([[0.1, -0.2, 0.05, 0.3]], dtype=np.float32)
    fields.last_obs = observation
    dqn.exploration_rate = 0.0
    actions, buffer_actions = fields.sample_action(learning_starts=0, n_envs=1)
    assert dqn._last_obs is fields.last_obs is observation
    assert actions.tolist() == buffer_actions.tolist() == dqn.predict(observation, deterministic=True)[0].tolist()


def test_an_on_policy_model_has_its_episode_starts_and_no_lstm_states() -> None:
    model = PPO("MlpPolicy", "CartPole-v1", n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    fields = ModelFields(model)
    assert fields.stats_window_size == 100 and fields.last_obs is None  # before learn's set-up
    total, callback = fields.setup_learn(64, None, "run")
    assert total == 64 and callback is not None and fields.last_obs.shape == (1, 4)
    assert fields.last_episode_starts.tolist() == [True] and fields.last_lstm_states is None
    assert fields.torch_save_params() == (["policy", "policy.optimizer"], [])
