"""train_many's per-seed callbacks and env wrapper: called and applied as learn(callback=...) and a wrapped env would be."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

import sb3_affect

SMALL: dict[str, Any] = {"learning_starts": 50, "buffer_size": 1000, "batch_size": 8, "policy_kwargs": {"net_arch": [8]}}


class Counting(BaseCallback):
    def __init__(self) -> None:
        super().__init__()
        self.steps = self.episodes = self.starts = self.ends = 0

    def _on_training_start(self) -> None:
        self.starts += 1

    def _on_step(self) -> bool:
        self.steps += 1
        self.episodes += int(np.sum(self.locals["dones"]))
        assert self.locals["new_obs"].shape[0] == len(self.locals["infos"]) == self.model.n_envs
        return True

    def _on_training_end(self) -> None:
        self.ends += 1


class Doubled(VecEnvWrapper):
    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        return obs, 2 * rewards, dones, infos


def test_each_seed_gets_its_callback_and_its_wrapped_env() -> None:
    callbacks = [Counting(), Counting()]
    wrapped: list[VecEnv] = []

    def wrap(env: VecEnv) -> VecEnv:
        wrapped.append(Doubled(env))
        return wrapped[-1]

    models = sb3_affect.train_many("AffectDQN", "MiniGrid-Empty-5x5-v0", [3, 4], 2, total_timesteps=200, obs="view",
                                   callbacks=callbacks, env_wrapper=wrap, position="minigrid", **SMALL)
    for model, callback, env in zip(models, callbacks, wrapped):
        assert callback.model is model and model.get_env() is env
        assert (callback.starts, callback.steps, callback.ends) == (1, 100, 1)  # one on_step per VecEnv step
        assert callback.episodes == model._episode_num


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"callbacks": [None]}, "callbacks must be a list of one callback per seed (2)"),
    ({"env_wrapper": 3}, "env_wrapper=3 must be a function of a VecEnv"),
])  # fmt: skip
def test_bad_hooks_are_refused_in_one_line(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        sb3_affect.train_many("DQN", "MiniGrid-Empty-5x5-v0", [0, 1], 2, total_timesteps=100, obs="view", **kwargs, **SMALL)
