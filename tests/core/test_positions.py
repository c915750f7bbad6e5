"""
``BatchPosition``: a ``position=`` function of the whole VecEnv, called once a step for all envs, gives the emotion
callbacks the same cells, so the same episode logs, as the per-env callable of the same cells; bad returns are one line.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pytest
import torch as th
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

from sb3_affect import BroekensCallback, EmotionCallback
from sb3_affect.core.positions import BatchPosition

N_ENVS, STEPS = 4, 512


def _learn(callback: Any) -> Any:
    th.set_num_threads(1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        PPO("MlpPolicy", make_vec_env("CartPole-v1", n_envs=N_ENVS, seed=0), n_steps=64, batch_size=64, n_epochs=1,
            seed=0).learn(STEPS, callback=callback)
    return callback


def test_a_batch_position_is_called_once_a_step_and_gives_the_per_env_callables_logs() -> None:
    calls = {"one": 0, "batch": 0}

    def one(observation: Any, info: dict[str, Any]) -> tuple[int, int]:
        calls["one"] += 1
        return int(observation[2] > 0), int(observation[0] > 0)

    def batch(observations: Any, infos: Any) -> Any:
        calls["batch"] += 1
        return np.stack([observations[:, 2] > 0, observations[:, 0] > 0], axis=1).astype(int)

    goal = {"goal": lambda reward, info: False, "warn_after": None}
    each = _learn(EmotionCallback(position=one, **goal))
    together = _learn(EmotionCallback(position=BatchPosition(batch), **goal))
    assert len(each.rows) > 10 and each.episode_log.equals(together.episode_log)
    episodes = len(each.rows)
    assert calls["one"] == N_ENVS * (1 + STEPS // N_ENVS) + episodes  # each env each step, and each ended episode's last
    assert calls["batch"] == 1 + STEPS // N_ENVS + episodes  # once a step (the last cells: a batch of one each)
    each_b = _learn(BroekensCallback(position=one))
    together_b = _learn(BroekensCallback(position=BatchPosition(batch)))
    assert len(each_b.cell_log) > 1 and each_b.cell_log.equals(together_b.cell_log)
    assert each_b.episode_log.equals(together_b.episode_log)


@pytest.mark.parametrize(
    ("function", "words"),
    [
        (lambda obs, infos: [0], r"position=<lambda>: the function returned \[0\] for 4 envs; a BatchPosition function "
                                 r"returns one cell per env"),
        (lambda obs, infos: obs[:, 2] * np.nan, r"position=<lambda>: the callable returned nan, which is not a cell"),
        (lambda obs, infos: 3, r"position=<lambda>: the function returned 3 for 4 envs"),
    ],
)
def test_a_batch_position_returning_no_cell_per_env_is_one_line(function: Any, words: str) -> None:
    with pytest.raises(ValueError, match=words) as raised:
        _learn(EmotionCallback(position=BatchPosition(function), goal=lambda reward, info: False))
    assert "\n" not in str(raised.value)


def test_a_batch_position_needs_a_callable() -> None:
    with pytest.raises(TypeError, match=r"BatchPosition needs a callable function\(observations, infos\) -> cells, got 5"):
        BatchPosition(5)  # type: ignore[arg-type]
