"""
What the deep study records while ``sb3_affect.train_many`` trains a batch of seeds, through the trainer's public hooks:

* ``TrainingRecorder``, one SB3 callback per seed (``train_many(callbacks=...)``): the training episodes ended and
  reached the goal, the env step of the first that reached it, each env step's emotion (``AffectDQN``), and ε summed
  over the steps after ``learning_starts`` (SB3's DQN); the share of random decisions of an ``ActionRepeat`` agent is
  read from its own counters (which only ``dump_logs`` resets: the study trains with a ``log_interval`` no run reaches);
* ``GreedyEvaluation`` (``train_many(every=..., on_models=...)``, every ``evaluation.every`` env steps): every seed's
  greedy policy for one episode on each of its evaluation envs, all seeds' Q-networks in one batched matrix product
  per layer, the weights read from the models (what each model's ``predict(obs, deterministic=True)`` computes,
  batched).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.preprocessing import preprocess_obs
from stable_baselines3.common.vec_env import VecEnv

from sb3_affect.agents.action_repeat import ActionRepeat
from sb3_affect.core.emotions import EMOTION_NAMES
from sb3_affect.engine.seed_envs import SeedEnvs


def reached_goal(info: dict[str, Any]) -> bool:
    """Whether an episode that ended reached the goal (MiniGrid ends an episode early only there)."""
    return not info.get("TimeLimit.truncated", False)


class TrainingRecorder(BaseCallback):
    """One seed's training, counted since the last ``take_interval`` (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self.first_success: int | None = None
        self._seen = (0, 0)  # an ActionRepeat agent's (random decisions, decisions) at the last interval's end
        self._clear()

    def _clear(self) -> None:
        self.episodes = np.zeros(2)  # (ended, reached the goal)
        self.emotions = np.zeros(len(EMOTION_NAMES))
        self.epsilon_sum, self.epsilon_steps = 0.0, 0  # SB3's DQN after learning_starts

    def _on_training_start(self) -> None:
        self._epsilon_greedy = not isinstance(self.model, ActionRepeat)

    def _on_step(self) -> bool:
        model: Any = self.model
        dones = self.locals["dones"]
        if dones.any():
            infos = self.locals["infos"]
            for index in np.flatnonzero(dones):
                goal = reached_goal(infos[index])
                self.episodes += (1, goal)
                if goal and self.first_success is None:
                    self.first_success = int(model.num_timesteps)
        if self._epsilon_greedy:
            if model.num_timesteps > model.learning_starts:
                self.epsilon_sum += model.exploration_rate
                self.epsilon_steps += 1
        else:
            for emotion in getattr(model, "decision_emotions", None) or ():  # each env's emotion at its decision
                self.emotions[int(emotion)] += 1
        return True

    def take_interval(self) -> dict[str, Any]:
        """The interval's random share, emotion shares (NaN: no emotion felt) and episodes; a new interval begins."""
        model = self.model
        with np.errstate(invalid="ignore", divide="ignore"):
            if isinstance(model, ActionRepeat):
                counts = model.decision_counts
                decided = counts[1] - self._seen[1]
                random_share = (counts[0] - self._seen[0]) / decided if decided else np.nan
                self._seen = counts
            else:
                random_share = self.epsilon_sum / self.epsilon_steps if self.epsilon_steps else np.nan
            steps = self.emotions.sum()
            shares = self.emotions / steps if steps else np.full(len(EMOTION_NAMES), np.nan)
        interval = {"random_share": float(random_share), "emotions": shares.tolist(),
                    "train_episodes": float(self.episodes[0]), "train_successes": float(self.episodes[1])}
        self._clear()
        return interval


class GreedyEvaluation:
    """
    Each seed's greedy policy on its own evaluation VecEnv, one episode per env, all seeds at once.

    :param envs: one VecEnv per seed, all of one size
    :param seeds: the seed each evaluation VecEnv is seeded with before each evaluation (the same episodes every time)
    """

    def __init__(self, envs: Sequence[VecEnv], seeds: Sequence[int]) -> None:
        self.envs, self.seeds = SeedEnvs(envs), list(seeds)

    @staticmethod
    def _stacked(models: Sequence[Any]) -> list[Any]:
        """The models' Q-network layers, their Linear layers' weights stacked over the seeds ``(S, in, out)``."""
        layers: list[Any] = []
        for modules in zip(*(model.q_net.q_net for model in models)):
            if isinstance(modules[0], th.nn.Linear):
                weight = th.stack([m.weight.detach().T for m in modules])
                layers.append((weight, th.stack([m.bias.detach() for m in modules]).unsqueeze(1)))
            else:
                layers.append(modules[0])  # an activation (the same, element-wise, in every seed)
        return layers

    def greedy(self, models: Sequence[Any], obs: np.ndarray, layers: list[Any] | None = None) -> np.ndarray:
        """
        The greedy actions ``(S, E)`` of each seed's model for its observations ``obs`` ``(S, E, ...)``.

        :param layers: the models' layers stacked (``_stacked(models)``: given, they are not stacked again)
        """
        first = models[0]
        n_seeds, n_envs = obs.shape[:2]
        with th.no_grad():
            batch = th.as_tensor(obs.reshape(n_seeds * n_envs, *obs.shape[2:]))
            x = first.q_net.features_extractor(preprocess_obs(batch, first.observation_space, first.q_net.normalize_images))
            x = x.reshape(n_seeds, n_envs, -1)
            for layer in layers or self._stacked(models):
                x = th.baddbmm(layer[1], x, layer[0]) if isinstance(layer, tuple) else layer(x)
        return x.argmax(dim=2).numpy()

    def __call__(self, models: Sequence[Any]) -> tuple[np.ndarray, np.ndarray]:
        """Each seed's (success rate, mean return) over one episode on each of its evaluation envs."""
        for env, seed in zip(self.envs.envs, self.seeds):
            env.seed(seed)
        obs = np.stack([np.asarray(env.reset()) for env in self.envs.envs])
        layers = self._stacked(models)
        finished = np.zeros(obs.shape[:2], dtype=bool)
        reached = np.zeros(obs.shape[:2], dtype=bool)
        returns = np.zeros(obs.shape[:2])
        while not finished.all():
            obs, rewards, dones, infos = self.envs.step(self.greedy(models, obs, layers))
            live = ~finished
            returns[live] += rewards[live]
            for s, e in zip(*np.nonzero(dones & live)):
                finished[s, e] = True
                reached[s, e] = reached_goal(infos[s][e])
        return reached.mean(axis=1), returns.mean(axis=1)
