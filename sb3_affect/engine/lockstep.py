"""
``Lockstep``: SB3's off-policy ``learn`` loop (``OffPolicyAlgorithm.learn``, ``collect_rollouts``, ``DQN._on_step`` and
``DQN.train``) run for S DQN models at once, each with its own VecEnv of E envs, replay buffer and random streams,
their Q-networks stacked (``sb3_affect.engine.stacked_q.StackedQ``).

Per seed, everything is SB3's, in SB3's order:

* **random streams**: SB3 draws from NumPy's global generator (seeded by ``set_random_seed(seed)``) for the
  epsilon test of ``DQN.predict`` (one draw per VecEnv step, for all E envs) and the replay sampling (batch indices,
  then env indices); here each seed has a ``RandomState(seed)`` taking exactly those draws. Random actions come from
  the seed's own ``action_space.sample()`` (seeded by SB3) and a control's decisions from its own generator;
* **steps**: ``learning_starts`` (SB3's uniformly random actions while ``num_timesteps < learning_starts``), each VecEnv
  step counting E env steps, ``train_freq`` VecEnv steps per rollout, then ``gradient_steps`` (-1: as many as env steps
  collected) once ``num_timesteps > learning_starts``; the target network copied (``tau``) every
  ``max(target_update_interval // E, 1)`` VecEnv steps; epsilon from the linear schedule of the progress;
* **storage**: the transition in the model's own ``ReplayBuffer``, the terminal observation as next observation where an
  episode ended, ``TimeLimit.truncated`` as timeout (``handle_timeout_termination``);
* **bookkeeping**: ``num_timesteps``, the episode count and ``ep_info_buffer``, the logged keys
  (``rollout/exploration_rate``, ``train/*``, and ``dump_logs`` every ``log_interval`` episodes), the callbacks the
  model adds itself (the emotion callback of ``AffectDQN``).

A model whose class decides its actions itself (the ``ActionRepeat`` agents: ``AffectDQN``, the controls) runs its own
``_sample_action`` per seed, its ``predict`` answered from the stacked networks; plain DQN draws them batched. The
transitions of all seeds are stored by one write per array, then an ``ActionRepeat`` agent ends the repeats of the
envs whose episode ended, as its ``_store_transition`` does; a class with another ``_store_transition`` runs its own
per seed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback, CallbackList, ConvertCallback
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.type_aliases import MaybeCallback

from sb3_affect.agents.action_repeat import ActionRepeat
from sb3_affect.engine.seed_envs import SeedEnvs
from sb3_affect.engine.stacked_q import StackedQ
from sb3_affect.engine.stacked_replay import StackedReplay


class _StackedPredict:
    """
    ``DQN.predict`` of seed ``index``, answered from the stacked networks while the trainer owns the weights: the same
    epsilon draw from the seed's stream; the greedy action of the current observation from the step's batched pass.
    """

    def __init__(self, trainer: Lockstep, index: int) -> None:
        self.trainer, self.index = trainer, index

    def __call__(self, observation: Any, state: Any = None, episode_start: Any = None,
                 deterministic: bool = False) -> tuple[np.ndarray, Any]:
        trainer, index = self.trainer, self.index
        model = trainer.models[index]
        if not deterministic and trainer.rngs[index].rand() < model.exploration_rate:
            batch = np.asarray(observation).reshape(-1, *trainer.obs_shape)
            return random_actions(model.action_space, len(batch)), state
        if observation is model._last_obs:
            return trainer.greedy()[index].copy(), state
        batch = np.asarray(observation).reshape(1, -1, *trainer.obs_shape)
        weights = [w[index:index + 1] for w in trainer.stack.weights]
        biases = [b[index:index + 1] for b in trainer.stack.biases]
        with th.no_grad():
            q_values = trainer.stack._forward(trainer.stack.features(batch), weights, biases)
        return q_values.argmax(dim=2).numpy()[0], state


def random_actions(space: spaces.Space, count: int) -> np.ndarray:
    """
    ``np.array([space.sample() for _ in range(count)])``, SB3's random actions, drawn at once from the same generator:
    a ``Discrete`` space's ``sample()`` is ``start + np_random.integers(n)``, and ``count`` such calls draw what one
    ``integers(n, size=count)`` draws.
    """
    if type(space) is spaces.Discrete:
        return space.start + space.np_random.integers(space.n, size=count)
    return np.array([space.sample() for _ in range(count)])


def _idle(callback: BaseCallback) -> bool:
    """Whether SB3's callback is its stand-in for none (an empty list, or ``ConvertCallback(None)``)."""
    return (isinstance(callback, CallbackList) and not callback.callbacks) or (
        isinstance(callback, ConvertCallback) and callback.callback is None)


def _own(model: DQN, name: str) -> bool:
    """Whether the model's class overrides SB3's off-policy method ``name``."""
    return getattr(type(model), name) is not getattr(OffPolicyAlgorithm, name)


def _ends_repeats(model: DQN) -> bool:
    """Whether the model stores as SB3 does, then ends the repeats of the envs whose episode ended (``ActionRepeat``)."""
    stores = type(model)._store_transition
    return stores is ActionRepeat._store_transition and (
        super(ActionRepeat, model)._store_transition.__func__ is OffPolicyAlgorithm._store_transition)  # type: ignore[misc]


class Lockstep:
    """
    SB3's ``learn`` of S DQN models in lockstep (see the module docstring).

    :param models: the models, one per seed, of one class and one set of arguments, each with its VecEnv of E envs
    :param seeds: their seeds (each model's NumPy stream is ``RandomState(seed)``, as ``set_random_seed`` seeds SB3's)
    """

    def __init__(self, models: Sequence[DQN], seeds: Sequence[int]) -> None:
        self.models = list(models)
        self.rngs = [np.random.RandomState(seed) for seed in seeds]
        self.n_seeds, self.n_envs = len(self.models), self.models[0].n_envs
        self.obs_shape = self.models[0].observation_space.shape or ()
        self.envs = SeedEnvs([m.get_env() for m in self.models])  # type: ignore[misc]
        self.own_actions = _own(self.models[0], "_sample_action")
        self.ends_repeats = _ends_repeats(self.models[0])
        self.own_storage = _own(self.models[0], "_store_transition") and not self.ends_repeats
        self._greedy: np.ndarray | None = None

    # -- the parts of SB3's loop ---------------------------------------------------------------------------------------
    def greedy(self) -> np.ndarray:
        """Every seed's greedy actions ``(S, E)`` for its current observation (one batched pass per step)."""
        if self._greedy is None:
            self._greedy = self.stack.greedy(self.obs)
        return self._greedy

    def _sample_actions(self, learning_starts: int) -> tuple[np.ndarray, np.ndarray]:
        """Each seed's ``_sample_action``: its own where its class has one, else DQN's ``predict`` batched."""
        self._greedy = None
        models, n_envs = self.models, self.n_envs
        if self.own_actions:
            pairs = [m._sample_action(learning_starts, None, n_envs) for m in models]
            return np.stack([np.asarray(p[0]).reshape(n_envs) for p in pairs]), np.stack([p[1] for p in pairs])
        if models[0].num_timesteps < learning_starts:
            actions = np.stack([random_actions(m.action_space, n_envs) for m in models])
            return actions, actions
        explore = [rng.rand() < m.exploration_rate for rng, m in zip(self.rngs, models)]
        actions = self.greedy().copy() if not all(explore) else np.zeros((self.n_seeds, n_envs), dtype=np.int64)
        for index in np.flatnonzero(explore):
            actions[index] = random_actions(models[index].action_space, n_envs)
        return actions, actions

    def _store(self, buffer_actions: np.ndarray, new_obs: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
               infos: list[list[dict[str, Any]]]) -> None:
        """Each seed's ``_store_transition`` into its replay buffer (SB3's ``ReplayBuffer.add``, for all seeds at once)."""
        if self.own_storage:
            for index, model in enumerate(self.models):
                model._store_transition(model.replay_buffer, buffer_actions[index], new_obs[index],  # type: ignore[arg-type]
                                        rewards[index], dones[index], infos[index])
            self.replay.follow()
            return
        next_obs = new_obs.copy()
        for s, e in zip(*np.nonzero(dones)):
            terminal = infos[s][e].get("terminal_observation")
            if terminal is not None:
                next_obs[s, e] = terminal
        timeouts = [[info.get("TimeLimit.truncated", False) for info in seed_infos] for seed_infos in infos]
        self.replay.add(self.obs, next_obs, buffer_actions, rewards, dones, np.array(timeouts))
        if self.ends_repeats:
            for model, seed_dones in zip(self.models, dones):
                model._end_repeats(seed_dones)  # type: ignore[attr-defined]

    def _train(self, gradient_steps: int, batch_size: int) -> None:
        """``DQN.train`` of every seed: ``gradient_steps`` batched steps, then SB3's bookkeeping and logs."""
        models = self.models
        learning_rate = models[0].lr_schedule(models[0]._current_progress_remaining)
        self.stack.set_learning_rate(learning_rate)
        losses = th.stack([self.stack.train_step(*self.replay.sample(self.rngs, batch_size)) for _ in range(gradient_steps)])
        mean_losses = losses.double().mean(dim=0).tolist()
        for model, loss in zip(models, mean_losses):
            model.logger.record("train/learning_rate", learning_rate)
            model._n_updates += gradient_steps
            model.logger.record("train/n_updates", model._n_updates, exclude="tensorboard")
            model.logger.record("train/loss", loss)

    def _after_step(self, dones: np.ndarray, log_interval: int) -> None:
        """``_update_current_progress_remaining``, ``DQN._on_step`` and the episode count of every seed."""
        first = self.models[0]
        first._update_current_progress_remaining(first.num_timesteps, first._total_timesteps)
        progress = first._current_progress_remaining
        exploration_rate = first.exploration_schedule(progress)
        first._n_calls += 1
        if first._n_calls % max(first.target_update_interval // self.n_envs, 1) == 0:
            self.stack.update_target()
        for model in self.models:
            model._current_progress_remaining = progress
            model._n_calls = first._n_calls
            model.exploration_rate = exploration_rate
            model.logger.record("rollout/exploration_rate", exploration_rate)
        for s, _ in zip(*np.nonzero(dones)):
            model = self.models[s]
            model._episode_num += 1
            if model._episode_num % log_interval == 0:
                model.dump_logs()

    # -- the loop --------------------------------------------------------------------------------------------------
    def learn(self, total_timesteps: int, log_interval: int = 4, every: int = 0,
              on_models: Callable[[list[DQN]], object] | None = None,
              user_callbacks: Sequence[MaybeCallback] | None = None) -> list[DQN]:
        """
        ``model.learn(total_timesteps, callback=user_callbacks[i], log_interval=log_interval)`` of every model, in
        lockstep; ``on_models(models)`` each time ``num_timesteps`` passes a multiple of ``every``, after the callbacks'
        ``on_step``, with the weights so far written into the models.
        """
        models, first = self.models, self.models[0]
        callbacks: list[BaseCallback] = []
        for model, given in zip(models, user_callbacks or [None] * len(models)):
            total, callback = model._setup_learn(total_timesteps, given, True, "run", False)
            callback.on_training_start({"self": model, "total_timesteps": total, "callback": callback,
                                        "log_interval": log_interval}, globals())
            callbacks.append(callback)
        active = [(i, c) for i, c in enumerate(callbacks) if not _idle(c)]
        self.obs = np.stack([m._last_obs for m in models])  # type: ignore[misc]
        self.stack = StackedQ(models)
        frequency = first.train_freq.frequency  # type: ignore[union-attr]
        vec_steps = -(-total // (self.n_envs * frequency)) * frequency
        self.replay = StackedReplay(models, vec_steps + 1)
        if self.own_actions:
            for index, model in enumerate(models):
                model.predict = _StackedPredict(self, index)  # type: ignore[method-assign]
        train_freq, n_envs = first.train_freq, self.n_envs
        try:
            while first.num_timesteps < total:
                for _, callback in active:
                    callback.on_rollout_start()
                collected = 0
                while collected < train_freq.frequency:  # type: ignore[union-attr]
                    actions, buffer_actions = self._sample_actions(first.learning_starts)
                    new_obs, rewards, dones, infos = self.envs.step(actions)
                    for model in models:
                        model.num_timesteps += n_envs
                    collected += 1
                    for index, callback in active:
                        model = models[int(index)]
                        callback.update_locals({"self": model, "actions": actions[index], "new_obs": new_obs[index],
                                                "rewards": rewards[index], "dones": dones[index],
                                                "infos": infos[index], "env": model.env})
                        if not callback.on_step():
                            raise RuntimeError(f"a callback of seed {index} stopped training: train_many runs every "
                                               "seed for total_timesteps")
                    if on_models is not None and first.num_timesteps // every > (first.num_timesteps - n_envs) // every:
                        self.stack.write_back(models)
                        on_models(models)
                    for ended in np.flatnonzero(dones.any(axis=1)).tolist():
                        models[ended]._update_info_buffer(infos[ended], dones[ended])
                    self._store(buffer_actions, new_obs, rewards, dones, infos)
                    self.obs = new_obs
                    if self.own_actions and not self.own_storage:  # SB3's _sample_action predicts from _last_obs
                        for model, obs in zip(models, new_obs):
                            model._last_obs = obs
                    self._after_step(dones, log_interval)
                for _, callback in active:
                    callback.on_rollout_end()
                if first.num_timesteps > 0 and first.num_timesteps > first.learning_starts:
                    gradient_steps = first.gradient_steps if first.gradient_steps >= 0 else collected * n_envs
                    if gradient_steps > 0:
                        self._train(gradient_steps, first.batch_size)
            for _, callback in active:
                callback.on_training_end()
        finally:
            for model in models:
                model.__dict__.pop("predict", None)
            self.stack.write_back(models)
            self.replay.release()
            if not self.own_storage:
                for model, obs in zip(models, self.obs):
                    model._last_obs = obs
        return models
