"""
Both emotion callbacks on other people's runs: SB3's and sb3-contrib's algorithms on Discrete, Box and Dict
observations, single envs with a time limit and a 4-env VecEnv. Each cell is one short learn (real algorithms, real
envs) that must log finite ``affect/*`` values and write the episode logs beside the logger, or raise the documented
error.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest
import torch as th
from sb3_contrib import ARS, QRDQN, TQC, TRPO, CrossQ, MaskablePPO, RecurrentPPO
from sb3_contrib.common.wrappers import ActionMasker
from stable_baselines3 import A2C, DQN, PPO, SAC, TD3
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure

from sb3_affect import AffectDQN, AffectQRDQN, BroekensCallback, Emotion, EmotionCallback
from sb3_affect.core.appraisal import Appraisal


def past_norm(appraisal: Appraisal | None) -> Emotion:
    """An emotion rule that needs no map: fear once the episode runs past the norm."""
    return Emotion.JOY if appraisal is None or appraisal.exp1 <= appraisal.norm else Emotion.FEAR


class DictObservation(gym.ObservationWrapper):
    """The wrapped env's observation inside a Dict, with the step count beside it."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.observation_space = gym.spaces.Dict(
            {"obs": env.observation_space, "step": gym.spaces.Box(0.0, 1000.0, (1,), np.float32)}
        )
        self._t = 0

    def reset(self, **kwargs: Any) -> Any:
        self._t = 0
        return super().reset(**kwargs)

    def step(self, action: Any) -> Any:
        self._t += 1
        return super().step(action)

    def observation(self, observation: Any) -> dict[str, Any]:
        return {"obs": observation, "step": np.array([self._t], dtype=np.float32)}


def all_actions(env: gym.Env) -> np.ndarray:
    return np.ones(env.action_space.n, dtype=bool)  # type: ignore[attr-defined]


AFFECT = (AffectDQN, AffectQRDQN)  # the package's deep agents: the emotion callback drives them
DISCRETE_ONLY = (DQN, QRDQN, MaskablePPO, *AFFECT)
CONTINUOUS_ONLY = (SAC, TD3, TQC, CrossQ)
ALGOS = (A2C, PPO, DQN, SAC, TD3, QRDQN, TQC, TRPO, RecurrentPPO, MaskablePPO, CrossQ, *AFFECT)
ENVS = ("FrozenLake", "CartPole", "Pendulum", "Dict", "VecEnv4")


def applies(algo: type, name: str) -> bool:
    """Whether the algorithm takes the env: its action space, and Dict observations (CrossQ has no MultiInputPolicy)."""
    if algo in CONTINUOUS_ONLY and name in ("FrozenLake", "CartPole"):
        return False
    return not ((algo in DISCRETE_ONLY and name == "Pendulum") or (algo is CrossQ and name == "Dict"))


def make_env(name: str, algo: type) -> Any:
    """The cell's env (Dict and VecEnv4: CartPole for algorithms of discrete actions, Pendulum for the others)."""
    continuous = algo in CONTINUOUS_ONLY
    base = "Pendulum-v1" if continuous else "CartPole-v1"
    wrap = (lambda env: ActionMasker(env, all_actions)) if algo is MaskablePPO else None
    if name == "VecEnv4":
        return make_vec_env(base, n_envs=4, seed=0, env_kwargs={"max_episode_steps": 16}, wrapper_class=wrap)
    env_id = {"FrozenLake": "FrozenLake-v1", "Dict": base}.get(name, f"{name}-v1")
    env = gym.make(env_id, max_episode_steps=16) if env_id != "FrozenLake-v1" else gym.make(env_id, max_episode_steps=30)
    if name == "Dict":
        env = DictObservation(env)
    return wrap(env) if wrap else env


def make_model(algo: type, env: Any, emotions: EmotionCallback) -> Any:
    dict_obs = isinstance(env.observation_space, gym.spaces.Dict)
    policy = "MultiInputPolicy" if dict_obs else "MlpPolicy"
    kwargs: dict[str, Any] = {"seed": 0, "policy_kwargs": {"net_arch": [8]}}
    if algo is RecurrentPPO:
        policy = "MultiInputLstmPolicy" if dict_obs else "MlpLstmPolicy"
        kwargs["policy_kwargs"] = {"net_arch": [8], "lstm_hidden_size": 8}
    if algo in (A2C, PPO, TRPO, RecurrentPPO, MaskablePPO):
        kwargs["n_steps"] = 32
        if algo is not A2C:
            kwargs["batch_size"] = 32
        if algo in (PPO, RecurrentPPO, MaskablePPO):
            kwargs["n_epochs"] = 1
    else:
        kwargs.update(learning_starts=16, batch_size=16, train_freq=4)
        if algo is CrossQ:
            kwargs["policy_kwargs"] = {"net_arch": {"pi": [8], "qf": [16]}}
        if algo in AFFECT:
            kwargs["emotion_callback"] = emotions
    return algo(policy, env, **kwargs)


CELLS = [(algo, env) for algo in ALGOS for env in ENVS if applies(algo, env)]


@pytest.mark.parametrize(("algo", "env_name"), CELLS, ids=[f"{a.__name__}-{e}" for a, e in CELLS])
def test_both_callbacks_log_finite_affect_values(algo: type, env_name: str, tmp_path: Path) -> None:
    env = make_env(env_name, algo)
    th.set_num_threads(1)
    mapped = isinstance(env.observation_space, gym.spaces.Discrete)
    emotions = EmotionCallback() if mapped else EmotionCallback(emotion_rule=past_norm)
    model = make_model(algo, env, emotions)
    model.set_logger(configure(str(tmp_path), ["csv"]))
    broekens = BroekensCallback()
    model.learn(192, callback=[emotions, broekens], log_interval=1)
    n_envs = model.get_env().num_envs
    progress = pd.read_csv(tmp_path / "progress.csv")
    for key in ("affect/joy", "affect/fear", "affect/norm", "affect/broekens/joy", "affect/broekens/distress",
                "affect/broekens/hope", "affect/broekens/fear"):
        values = progress[key].dropna()
        assert len(values) and np.isfinite(values).all(), key
    for callback, file in ((emotions, "emotion_episodes.csv"), (broekens, "broekens_episodes.csv")):
        log = callback.episode_log
        assert len(log) >= n_envs and set(log.env) == set(range(n_envs))
        written = pd.read_csv(tmp_path / file)
        assert len(written) == len(log) and (written.env.to_numpy() == log.env.to_numpy()).all()
    steps = broekens.episode_log.steps
    assert (steps <= 16).all() or env_name == "FrozenLake"
    joy = broekens.episode_log[["joy", "distress", "hope", "fear"]].to_numpy()
    assert np.isfinite(joy).all() and (joy >= 0).all()


def test_ars_calls_callbacks_without_the_step_and_has_no_value() -> None:
    """ARS (sb3-contrib) calls on_step without the step's observations, and has no value estimate."""
    with pytest.raises(RuntimeError, match=r"EmotionCallback: ARS calls its callbacks without the step's observations"):
        ARS("LinearPolicy", gym.make("Pendulum-v1", max_episode_steps=16), n_delta=2, seed=0).learn(
            64, callback=EmotionCallback(emotion_rule=past_norm)
        )
    with pytest.raises(TypeError, match=r"needs a value-based algorithm.*ARS has no Q-table"):
        ARS("LinearPolicy", gym.make("Pendulum-v1", max_episode_steps=16), n_delta=2, seed=0).learn(
            64, callback=BroekensCallback()
        )
