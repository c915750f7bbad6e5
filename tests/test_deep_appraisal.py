"""
The deep agents' appraisal (``EmotionCallback`` in observer mode, ``sb3_affect.core.lane_appraisal``): one unit for
elapsed, norm and act (moves), ``last_act`` reset at each episode's start, the warm-up out of the emotion profile, the
episode log's ``random_moves`` and ``waits``, the position read with the reset's info after an auto-reset, and the
appraisal saved and loaded with the model. Real SB3 DQN, real envs.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from stable_baselines3.common.env_util import make_vec_env

from sb3_affect import AffectDQN, Behaviour, Emotion, EmotionCallback
from sb3_affect.core.appraisal import INF, Appraisal, Appraiser
from sb3_affect.core.emotions import table_ii, table_ii_act_first
from sb3_affect.core.lane_appraisal import LaneAppraisal
from sb3_affect.core.positions import MiniGridPosition

EMOTIONS = ["joy", "sadness", "fear", "anger"]


def table(random_direction: bool, speeds: tuple[int, ...]) -> dict[Emotion, Behaviour]:
    return {emotion: Behaviour(random_direction, speeds) for emotion in Emotion}


def small(env: Any, **kwargs: Any) -> AffectDQN:
    th.set_num_threads(1)
    kwargs.setdefault("learning_starts", 16)
    return AffectDQN("MlpPolicy", env, batch_size=16, train_freq=4, seed=0, policy_kwargs={"net_arch": [16]}, **kwargs)


class Actions(gym.Wrapper):
    """Records each episode's actions."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.episodes: list[list[int]] = [[]]

    def step(self, action: Any) -> Any:
        result = self.env.step(action)
        self.episodes[-1].append(int(action))
        if result[2] or result[3]:
            self.episodes.append([])
        return result


def test_a_lane_resets_last_act_at_each_episode_start() -> None:
    """A cell with no known path keeps act from a cell of the same episode, never from the episode before."""
    appraiser = Appraiser(4)
    lane = LaneAppraisal(appraiser)
    lane.begin(0)
    for cell in (1, 2):
        lane.step(cell, 0.0, False)
    lane.step(3, 1.0, True)
    lane.close(True)
    lane.begin(0)
    lane.feel(table_ii)
    assert appraiser.last_act == 3  # 0 elapsed + 3 cells known from cell 0
    lane.close(False)
    appraiser.known = type(appraiser.known)(4)  # a new layout: no cell knows its way
    lane.begin(0)
    emotion = lane.feel(table_ii)
    assert appraiser.last_act == INF and emotion == Emotion.JOY  # act unknown again, not the last episode's 3


def test_minigrid_moves_are_forward_and_turns_only_with_direction() -> None:
    assert [MiniGridPosition().is_move(a) for a in range(7)] == [False, False, True, False, False, False, False]
    assert [MiniGridPosition(direction=True).is_move(a) for a in range(7)] == [True, True, True, False, False, False, False]


def test_sadness_is_unreachable_as_printed_and_every_emotion_is_reached_act_first() -> None:
    """Over appraisals as the appraiser makes them (exp1 = max(norm, elapsed); act = elapsed + remaining, or remaining)."""
    reached: dict[tuple[str, str, str], set[Emotion]] = {}
    for norm, elapsed, remaining in itertools.product(range(1, 12), range(12), range(12)):
        exp1 = max(norm, elapsed)
        for act_mode, act in (("episode", elapsed + remaining), ("remaining", remaining)):
            appraisal = Appraisal(float(norm), float(exp1), float(act))
            for comparison in ("literal", "valence"):
                reached.setdefault(("table", comparison, act_mode), set()).add(table_ii(appraisal, comparison))
                reached.setdefault(("act-first", comparison, act_mode), set()).add(table_ii_act_first(appraisal, comparison))
    for (order, comparison, act_mode), emotions in reached.items():
        if order == "table":
            assert Emotion.SADNESS not in emotions
        if comparison == "literal":
            assert emotions == {Emotion.JOY, Emotion.ANGER}, (order, act_mode)
    assert reached[("table", "valence", "episode")] == {Emotion.JOY, Emotion.FEAR, Emotion.ANGER}
    assert reached[("act-first", "valence", "remaining")] == set(Emotion)


minigrid = pytest.importorskip("minigrid")


@pytest.mark.parametrize(("kwargs", "felt"), [
    ({}, {"joy", "anger"}),
    ({"comparison": "valence"}, {"joy", "fear", "anger"}),
    ({"comparison": "valence", "act": "remaining", "order": "act-first"}, set(EMOTIONS)),
])
def test_the_emotions_felt_on_minigrid_under_each_reading(kwargs: dict[str, str], felt: set[str]) -> None:
    from minigrid.wrappers import FlatObsWrapper

    env = make_vec_env("MiniGrid-Empty-5x5-v0", n_envs=4, seed=0, wrapper_class=FlatObsWrapper)
    th.set_num_threads(1)
    model = AffectDQN("MlpPolicy", env, learning_starts=500, seed=0, position="minigrid", wait_action=6,
                      emotion_callback=EmotionCallback(**kwargs), policy_kwargs={"net_arch": [64, 64]})
    counts = model.learn(3000).episode_log[EMOTIONS].sum()
    assert {name for name in EMOTIONS if counts[name] > 0} == felt, counts.to_dict()


@pytest.mark.parametrize("position", ["minigrid", "minigrid-dir"])
def test_on_minigrid_elapsed_and_norm_count_moves_as_the_map_does(position: str) -> None:
    """The norm after one episode is that episode's moves: forwards (and turns with direction), not all env steps."""
    from minigrid.wrappers import FlatObsWrapper

    env = make_vec_env("MiniGrid-Empty-5x5-v0", n_envs=1, seed=0, wrapper_class=lambda e: Actions(FlatObsWrapper(e)))
    model = small(env, learning_starts=0, position=position, behaviour_table=table(True, (1,)))
    model.learn(600)
    episodes = env.envs[0].episodes[:-1]
    moves = {0, 1, 2} if position == "minigrid-dir" else {2}
    log = model.episode_log
    assert len(log) >= 2 and math.isnan(log.norm.iloc[0])
    first_moves = sum(action in moves for action in episodes[0])
    assert first_moves < len(episodes[0])  # turns or other actions happened: the units differ
    assert log.norm.iloc[1] == first_moves
    assert list(log.cells) == [len(e) for e in episodes][: len(log)]  # the log's cells column: env steps


def test_the_warm_up_is_out_of_the_emotion_profile_and_the_log_has_random_moves_and_waits() -> None:
    env = make_vec_env("FrozenLake-v1", n_envs=2, seed=0)
    model = small(env, learning_starts=400).learn(300)  # the warm-up only: SB3's random actions
    log = model.episode_log
    assert len(log) > 5 and (log[EMOTIONS].sum(axis=1) == 0).all()
    assert (log.random_moves == log.decisions).all() and (log.waits == 0).all()
    assert not any(key.startswith("affect/joy") for key in model.logger.name_to_value)

    model = small(make_vec_env("FrozenLake-v1", n_envs=2, seed=0), learning_starts=100).learn(1000)
    log = model.episode_log
    after = log.iloc[len(log) // 2:]  # episodes wholly after the warm-up: every decision an emotion's
    assert (after[EMOTIONS].sum(axis=1) == after.decisions).all()
    assert (log[EMOTIONS].sum(axis=1) < log.decisions).any()  # episodes that began in the warm-up

    waits = small(make_vec_env("FrozenLake-v1", n_envs=2, seed=0), learning_starts=0, wait_action=0,
                  behaviour_table=table(False, (0,))).learn(400).episode_log
    assert (waits.waits == waits.decisions).all() and (waits.random_moves == 0).all()
    joy = small(make_vec_env("FrozenLake-v1", n_envs=2, seed=0), learning_starts=0,
                behaviour_table=table(True, (2,))).learn(400).episode_log
    assert (joy.random_moves == joy.decisions).all() and (joy.waits == 0).all() and (joy.decisions < joy.cells).any()


class InfoCell(gym.Wrapper):
    """Puts the agent's cell in ``info["cell"]`` at reset and at every step."""

    def reset(self, **kwargs: Any) -> Any:
        obs, info = self.env.reset(**kwargs)
        return obs, {**info, "cell": int(obs)}

    def step(self, action: Any) -> Any:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, {**info, "cell": int(obs)}


def test_a_callable_position_reads_the_new_episodes_info_after_an_auto_reset() -> None:
    """SB3's VecEnv puts the reset's observation in obs and the ended episode's info in infos: the reset's info is used."""
    seen: list[tuple[int, int]] = []

    def position(observation: Any, info: dict[str, Any]) -> int:
        seen.append((int(np.asarray(observation).reshape(-1)[0]), int(info["cell"])))
        return int(info["cell"])

    env = make_vec_env("FrozenLake-v1", n_envs=2, seed=0, wrapper_class=InfoCell)
    model = small(env, position=position).learn(600)
    assert len(model.episode_log) > 10
    assert all(obs == cell for obs, cell in seen), [pair for pair in seen if pair[0] != pair[1]][:3]


def test_the_appraisal_and_the_callbacks_settings_are_saved_and_loaded(tmp_path: Path) -> None:
    env = make_vec_env("FrozenLake-v1", n_envs=2, seed=0)
    callback = EmotionCallback(comparison="valence", act="remaining", warn_after=5)
    model = small(env, emotion_callback=callback).learn(1500)
    model.save(tmp_path / "model.zip")
    for safe in (True, False):
        loaded = AffectDQN.load(tmp_path / "model.zip", env=env, safe=safe)
        restored = loaded.emotion_callback
        assert (restored.comparison, restored.act, restored.warn_after) == ("valence", "remaining", 5)
        assert restored.emotion_rule(None) == Emotion.JOY and restored.emotion_rule.table_ii_comparison == "valence"
        assert len(restored._lanes) == 2
        for before, after in zip(callback._lanes, restored._lanes):
            assert after.appraiser.get_state() == before.appraiser.get_state()
        assert restored.appraiser is restored._lanes[0].appraiser
        assert loaded.episode_log.equals(model.episode_log)
        loaded.learn(200, reset_num_timesteps=False)  # continues: the history grows from the saved one
        assert len(loaded.episode_log) > len(model.episode_log)
        history = loaded.emotion_callback._lanes[0].appraiser.fit.values
        assert history[: len(callback._lanes[0].appraiser.fit.values)] == callback._lanes[0].appraiser.fit.values


class MyCallback(EmotionCallback):
    """A user's subclass."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.mine = 7


def test_a_subclassed_callback_and_the_callbacks_own_position_survive_save_and_load(tmp_path: Path) -> None:
    env = make_vec_env("FrozenLake-v1", n_envs=2, seed=0)
    small(env, emotion_callback=EmotionCallback(position="discrete")).learn(100).save(tmp_path / "own.zip")
    assert AffectDQN.load(tmp_path / "own.zip").emotion_callback.position == "discrete"
    small(env, emotion_callback=MyCallback()).learn(100).save(tmp_path / "sub.zip")
    loaded = AffectDQN.load(tmp_path / "sub.zip", safe=False)  # a class of the user's: unpickled, when trusted
    assert type(loaded.emotion_callback) is MyCallback and loaded.emotion_callback.mine == 7
    assert (tmp_path / "sub.zip").stat().st_size < 2 * (tmp_path / "own.zip").stat().st_size  # not the model within
    loaded.set_env(env)
    loaded.learn(100, reset_num_timesteps=False)
    assert loaded.emotion_callback.model is loaded
