"""QLearning and AffectQ through SB3's interface."""

from __future__ import annotations

import math
import random

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
from stable_baselines3.common.evaluation import evaluate_policy
from stable_baselines3.common.logger import configure
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.utils import LinearSchedule

from sb3_affect import EPISODE_COLUMNS, TABLE_III, AffectQ, Behaviour, Emotion, EmotionCallback, QLearning
from sb3_affect.agents.policies import greedy_action
from sb3_affect.envs.grid_pursuit import RIGHT

ENV_ID = "sb3_affect/GridPursuit-v0"


def train(cls: type, episodes: int = 200, seed: int = 0, **kwargs) -> QLearning | AffectQ:
    model = cls("Grid", gym.make(ENV_ID, **kwargs.pop("env_kwargs", {})), seed=seed, **kwargs)
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(episodes))
    return model


def test_env_as_registered_id_and_policy_alias() -> None:
    model = AffectQ("Grid", ENV_ID, seed=1)
    assert model.policy.q_table.shape == (225, 4)
    model.learn(300)
    assert model.num_timesteps == 300


def test_eq1_on_a_hand_worked_example() -> None:
    env = gym.make(ENV_ID, size=3, start=(0, 0), goal=(2, 2))
    model = QLearning("Grid", env, learning_rate=0.5, gamma=0.8, exploration_rate=0.0, seed=0)
    q = model.policy.q_table
    q[0, RIGHT] = 1.0  # the greedy choice at (0, 0)
    q[1] = q.new_tensor([2.0, 0.0, 0.0, 0.0])  # max Q at (0, 1) is 2
    model.learn(1)
    # Q(s,a) <- Q + alpha * (r + gamma * max Q(s') - Q) = 1 + 0.5 * (0 + 0.8 * 2 - 1) = 1.3
    assert model.q_table[0, RIGHT] == pytest.approx(1.3, abs=1e-15)
    assert model.q_table[1].tolist() == [2.0, 0.0, 0.0, 0.0]


def test_terminal_update_ignores_the_goal_row() -> None:
    env = gym.make(ENV_ID, size=2, start=(0, 0), goal=(0, 1))
    model = QLearning("Grid", env, learning_rate=1.0, exploration_rate=0.0, q_init=5.0, seed=0)
    model.policy.q_table[0, RIGHT] = 6.0
    model.learn(1)
    assert model.q_table[0, RIGHT] == 100.0  # r only: the goal ends the episode, its own row is never bootstrapped
    assert len(model.episode_log) == 1 and bool(model.episode_log.optimal.iloc[0])


def test_greedy_ties_are_uniform_and_only_among_the_best() -> None:
    rng = random.Random(0)
    row = [1.0, 3.0, 3.0, 0.0, 3.0]
    picks = [greedy_action(row, rng) for _ in range(6000)]
    assert set(picks) == {1, 2, 4}
    assert all(abs(picks.count(a) / 6000 - 1 / 3) < 0.03 for a in (1, 2, 4))
    assert greedy_action([0.0, 2.0, 1.0], rng) == 1


def test_all_zero_q_does_not_freeze_the_agent() -> None:
    model = QLearning("Grid", ENV_ID, exploration_rate=0.0, seed=3)
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(1))
    assert model.episode_log.decisions.iloc[0] < 20_000  # random ties reach the goal; "first index" would stick


def test_episode_log_columns_and_counts() -> None:
    model = train(AffectQ, episodes=30, seed=2)
    log = model.episode_log
    assert isinstance(log, pd.DataFrame) and tuple(log.columns) == EPISODE_COLUMNS
    assert log.episode.tolist() == list(range(1, 31))
    emotions = log[["joy", "sadness", "fear", "anger"]].sum(axis=1)
    assert (emotions == log.decisions).all()
    assert (log.random_moves == log.joy).all()  # only joy picks a random direction
    assert (log.cells <= 2 * log.decisions).all() and (log.cells >= log.decisions - log.waits).all()
    assert log.norm.isna().iloc[0] and log.norm.notna().iloc[1:].all()
    assert log.joy.iloc[0] == log.decisions.iloc[0]  # first episode: nothing to appraise -> joy
    assert model.num_timesteps == log.decisions.sum()
    assert (log.optimal == (log.cells == 12)).all() and not log.truncated.any()


def test_speed_two_moves_two_cells_each_with_its_own_update() -> None:
    fast = {e: Behaviour(False, (2,)) for e in Emotion}
    env = gym.make(ENV_ID, size=5, start=(0, 0), goal=(0, 3))
    model = AffectQ("Grid", env, behaviour_table=fast, seed=0)
    model.policy.q_table[:, RIGHT] = 1.0  # greedy: always right
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(1))
    row = model.episode_log.iloc[0]
    # (0,0) -> (0,2) in one decision, then (0,2) -> (0,3) goal: the second decision stops early after one cell
    assert (row.decisions, row.cells, row.waits) == (2, 3, 0)
    q = model.q_table
    assert q[0, RIGHT] == pytest.approx(0.8) and q[1, RIGHT] == pytest.approx(0.8) and q[2, RIGHT] == 100.0


def test_speed_zero_is_a_wait_and_the_cap_truncates() -> None:
    still = {e: Behaviour(False, (0,)) for e in Emotion}
    model = AffectQ("Grid", ENV_ID, behaviour_table=still, max_episode_decisions=50, seed=0)
    model.learn(120)
    log = model.episode_log
    assert log.decisions.tolist() == [50, 50] and log.cells.tolist() == [0, 0] and log.waits.tolist() == [50, 50]
    assert log.truncated.all() and model.truncated_episodes == 2
    assert not model.q_table.any()  # no transition, no update


def test_custom_emotion_rule_drives_behaviour() -> None:
    sad = EmotionCallback(emotion_rule=lambda appraisal: Emotion.SADNESS)
    model = AffectQ("Grid", ENV_ID, emotion_callback=sad, seed=4)
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(3))
    log = model.episode_log
    assert (log.sadness == log.decisions).all() and log.waits.sum() > 0 and (log.random_moves == 0).all()


def test_same_seed_same_log_and_different_seed_differs() -> None:
    for cls in (QLearning, AffectQ):
        a, b, c = (train(cls, episodes=40, seed=s).episode_log for s in (7, 7, 8))
        pd.testing.assert_frame_equal(a, b)
        assert not a.equals(c)


def test_qlearning_epsilon_01_finds_a_12_cell_greedy_path_for_most_seeds() -> None:
    found = [bool(train(QLearning, seed=s, exploration_rate=0.1).episode_log.greedy_optimal.any()) for s in range(10)]
    assert sum(found) >= 8, found


def test_stop_after_exactly_200_episodes_and_continue() -> None:
    model = train(QLearning, episodes=200, seed=5)
    assert len(model.episode_log) == 200
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(10), reset_num_timesteps=False)
    assert model.episode_log.episode.tolist() == list(range(1, 211))


def test_predict_and_evaluate_policy_after_learning() -> None:
    model = train(QLearning, episodes=200, seed=0, exploration_rate=0.1)
    env = gym.make(ENV_ID)
    action, _ = model.predict(np.int64(0), deterministic=True)
    assert action in range(4)
    actions, _ = model.predict(np.arange(5), deterministic=True)
    assert actions.shape == (5,)
    assert model.episode_log.greedy_optimal.iloc[-1]
    mean_reward, _ = evaluate_policy(model, Monitor(env), n_eval_episodes=3)
    assert mean_reward == 100.0


@pytest.mark.parametrize(
    ("kwargs", "error", "words"),
    [
        ({"gamma": 1.5}, ValueError, ["gamma=1.5", "[0, 1]"]),
        ({"learning_rate": 0.0}, ValueError, ["learning_rate=0.0", "(0, 1]"]),
        ({"exploration_rate": 1.2}, ValueError, ["exploration_rate=1.2", "[0, 1]"]),
        ({"exploration_rate": LinearSchedule(1.0, -0.5, 1.0)}, ValueError, ["exploration_rate(0)", "[0, 1]"]),
        ({"exploration_rate": "high"}, TypeError, ["exploration_rate", "'high'"]),
        ({"max_episode_decisions": 0}, ValueError, ["max_episode_decisions=0"]),
    ],
)
def test_invalid_hyperparameters_are_named(kwargs: dict, error: type[Exception], words: list[str]) -> None:
    with pytest.raises(error) as info:
        QLearning("Grid", ENV_ID, **kwargs)
    for word in words:
        assert word in str(info.value)


def test_affectq_options_are_validated() -> None:
    for key, value in (("comparison", "backwards"), ("act", "total"), ("units", "steps")):
        with pytest.raises(ValueError, match=f"{key}='{value}'"):
            AffectQ("Grid", ENV_ID, **{key: value})


def test_non_discrete_spaces_are_refused() -> None:
    with pytest.raises(TypeError, match="Discrete observation space"):
        AffectQ("Grid", "CartPole-v1")
    with pytest.raises(TypeError, match="Discrete action space"):
        QLearning("Grid", _box_action_env())


def _box_action_env() -> gym.Env:
    class BoxActions(gym.Env):
        observation_space = gym.spaces.Discrete(3)
        action_space = gym.spaces.Box(-1, 1, (1,))

    return BoxActions()


def test_logger_writes_dqn_keys_and_affect_keys(tmp_path) -> None:
    model = AffectQ("Grid", ENV_ID, seed=0)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    model.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(8), log_interval=2)
    frame = pd.read_csv(tmp_path / "progress.csv")
    for key in (
        "rollout/ep_len_mean",
        "rollout/ep_rew_mean",
        "rollout/exploration_rate",
        "time/fps",
        "time/total_timesteps",
        "time/episodes",
        "affect/joy",
        "affect/anger",
        "affect/equivalent_epsilon",
        "affect/norm",
    ):
        assert key in frame.columns, key
    assert len(frame) == 4 and frame["time/episodes"].tolist() == [2, 4, 6, 8]


def test_progress_bar_runs() -> None:
    model = QLearning("Grid", ENV_ID, seed=0)
    model.learn(2000, progress_bar=True)
    assert model.num_timesteps == 2000


def test_schedules_are_evaluated_per_episode() -> None:
    model = QLearning("Grid", ENV_ID, exploration_rate=LinearSchedule(1.0, 0.0, 1.0), seed=0)
    model.learn(20_000)
    log = model.episode_log
    first, last = log.head(5), log.tail(5)
    assert (first.random_moves / first.decisions).mean() > (last.random_moves / last.decisions).mean()
    assert math.isclose(model._epsilon, 1.0 - model.num_timesteps / 20_000, abs_tol=0.05)


def test_default_behaviour_is_table_iii() -> None:
    model = AffectQ("Grid", ENV_ID)
    for emotion in Emotion:
        assert model._behaviour[emotion] == TABLE_III[emotion]


def test_save_load_round_trip_and_continue(tmp_path) -> None:
    model = train(AffectQ, episodes=25, seed=11)
    path = tmp_path / "affect.zip"
    model.save(path)
    loaded = AffectQ.load(path, env=gym.make(ENV_ID))
    np.testing.assert_array_equal(loaded.q_table, model.q_table)
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    assert (loaded.comparison, loaded.act, loaded.units, loaded.gamma) == (model.comparison, model.act, model.units, 0.8)
    states = np.arange(225)
    best = model.q_table.max(axis=1, keepdims=True)
    unique = (model.q_table == best).sum(axis=1) == 1  # where there is no tie, the greedy action is determined
    np.testing.assert_array_equal(
        loaded.predict(states, deterministic=True)[0][unique], model.predict(states, deterministic=True)[0][unique]
    )
    # the appraisal carries on: same norm history, same known map
    assert loaded.emotion_callback.appraiser.fit.values == model.emotion_callback.appraiser.fit.values
    assert loaded.emotion_callback.appraiser.known.distance == model.emotion_callback.appraiser.known.distance
    # continued training from the file equals continued training in memory
    for m in (model, loaded):
        m.learn(10_000_000, callback=StopTrainingOnMaxEpisodes(5), reset_num_timesteps=False)
    pd.testing.assert_frame_equal(loaded.episode_log, model.episode_log)
    np.testing.assert_array_equal(loaded.q_table, model.q_table)


def test_load_without_env_predicts(tmp_path) -> None:
    model = train(QLearning, episodes=50, seed=1)
    model.save(tmp_path / "q.zip")
    loaded = QLearning.load(tmp_path / "q.zip")  # no env: enough to predict
    assert loaded.get_env() is None
    np.testing.assert_array_equal(loaded.q_table, model.q_table)
    action, _ = loaded.predict(0, deterministic=True)
    assert int(action) in range(4)
