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
from sb3_affect.agents.sb3_fields import ModelFields
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
        if observation is trainer.fields[index].last_obs:
            return trainer.greedy()[index].copy(), state
        batch = np.asarray(observation).reshape(1, -1, *trainer.obs_shape)
        weights = [w[index:index + 1] for w in trainer.stack.weights]
        biases = [b[index:index + 1] for b in trainer.stack.biases]
        with th.no_grad():
            q_values = trainer.stack.forward(trainer.stack.features(batch), weights, biases)
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


def random_sampler(space: spaces.Space, count: int) -> Callable[[], np.ndarray]:
    """
    ``lambda: random_actions(space, count)``, a ``Discrete`` space's generator and bounds looked up once (bound when
    training starts: the same draws from the same generator, without the per-call lookups).
    """
    if type(space) is spaces.Discrete:
        integers, start, n = space.np_random.integers, space.start, space.n
        return lambda: start + integers(n, size=count)
    return lambda: random_actions(space, count)


def idle(callback: BaseCallback) -> bool:
    """Whether SB3's callback is its stand-in for none (an empty list, or ``ConvertCallback(None)``)."""
    return (isinstance(callback, CallbackList) and not callback.callbacks) or (
        isinstance(callback, ConvertCallback) and callback.callback is None)


def loop_methods(model: DQN) -> tuple[bool, bool, bool]:
    """
    ``(own_actions, own_storage, ends_repeats)``: whether the model's class has its own ``_sample_action``; its own
    ``_store_transition``; or SB3's, then ends the repeats of the envs whose episode ended (``ActionRepeat``'s).
    """
    kind = type(model)
    own_actions = kind._sample_action is not OffPolicyAlgorithm._sample_action
    stores, sb3_stores = kind._store_transition, OffPolicyAlgorithm._store_transition
    ends_repeats = stores is ActionRepeat._store_transition and (
        super(ActionRepeat, model)._store_transition.__func__ is sb3_stores)  # type: ignore[misc]
    return own_actions, stores is not sb3_stores and not ends_repeats, ends_repeats


class Lockstep:
    """
    SB3's ``learn`` of S DQN models in lockstep (see the module docstring).

    The counts every seed shares while it trains (``num_timesteps``, ``_n_calls``, ``_n_updates``, the progress, the
    exploration rates) are kept here and written into the models once per step only when something per seed reads them
    (a callback, a class's own ``_sample_action``), else before each ``dump_logs``, each ``on_models`` and at the end; the
    logged keys are recorded when they are dumped, with the values SB3 would have recorded last.

    :param models: the models, one per seed, of one class and one set of arguments, each with its VecEnv of E envs
    :param seeds: their seeds (each model's NumPy stream is ``RandomState(seed)``, as ``set_random_seed`` seeds SB3's)
    """

    def __init__(self, models: Sequence[DQN], seeds: Sequence[int]) -> None:
        self.models = list(models)
        self.rngs = [np.random.RandomState(seed) for seed in seeds]
        self.n_seeds, self.n_envs = len(self.models), self.models[0].n_envs
        self.obs_shape = self.models[0].observation_space.shape or ()
        self.fields = [ModelFields(m) for m in self.models]
        self.envs = SeedEnvs([m.get_env() for m in self.models])  # type: ignore[misc]
        self.own_actions, self.own_storage, self.ends_repeats = loop_methods(self.models[0])
        self._greedy: np.ndarray | None = None
        self.frozen = np.zeros(self.n_seeds, dtype=bool)
        # the seeds of each exploration schedule (one group unless the seeds were given their own)
        groups: dict[tuple[float, float, float], list[int]] = {}
        for index, model in enumerate(self.models):
            key = (model.exploration_initial_eps, model.exploration_final_eps, model.exploration_fraction)
            groups.setdefault(key, []).append(index)
        self.schedules = [(self.models[group[0]].exploration_schedule, np.array(group)) for group in groups.values()]
        self.exploration = np.array([m.exploration_rate for m in self.models], dtype=float)
        points = (1.0, 0.5, 0.0)
        self.one_rate = len({tuple(m.lr_schedule(p) for p in points) for m in self.models}) == 1
        first = self.fields[0]
        self.num_timesteps, self.n_calls, self.n_updates = self.models[0].num_timesteps, first.n_calls, first.n_updates
        self.total_timesteps = 0  # learn's, once it has set up
        self.losses: list[float] = [0.0] * self.n_seeds
        self.learning_rates: list[float] = [0.0] * self.n_seeds
        self.clock = 0  # steps taken; a seed's logged keys since its last dump are those of the steps after it
        self.dumped_at = [-1] * self.n_seeds
        self.trained_at = -1.0

    # -- the counts and logs of the models -----------------------------------------------------------------------------
    def _sync(self, indices: Sequence[int]) -> None:
        """Write the shared counts into the models ``indices`` (not frozen)."""
        progress = self.fields[0].progress
        for index in indices:
            model, fields = self.models[index], self.fields[index]
            model.num_timesteps, fields.n_calls, fields.n_updates = self.num_timesteps, self.n_calls, self.n_updates
            fields.progress = progress
            model.exploration_rate = float(self.exploration[index])

    def _record(self, index: int) -> None:
        """Record seed ``index``'s keys of the steps since its last dump, with their last values (as SB3 records them)."""
        logger = self.models[index].logger
        if self.clock > self.dumped_at[index]:
            logger.record("rollout/exploration_rate", float(self.exploration[index]))
        if self.trained_at > self.dumped_at[index]:
            logger.record("train/learning_rate", self.learning_rates[index])
            logger.record("train/n_updates", self.n_updates, exclude="tensorboard")
            logger.record("train/loss", self.losses[index])

    def _live(self) -> list[int]:
        return np.flatnonzero(~self.frozen).tolist()

    # -- the parts of SB3's loop ---------------------------------------------------------------------------------------
    def greedy(self) -> np.ndarray:
        """Every seed's greedy actions ``(S, E)`` for its current observation (one batched pass per step)."""
        if self._greedy is None:
            self._greedy = self.stack.greedy(self.obs)
        return self._greedy

    def _sample_actions(self, learning_starts: int) -> tuple[np.ndarray, np.ndarray]:
        """Each seed's ``_sample_action``: its own where its class has one, else DQN's ``predict`` batched."""
        self._greedy = None
        n_envs = self.n_envs
        if self.own_actions:
            pairs = [fields.sample_action(learning_starts, n_envs) for fields in self.fields]
            return np.stack([np.asarray(p[0]).reshape(n_envs) for p in pairs]), np.stack([p[1] for p in pairs])
        if self.num_timesteps < learning_starts:
            actions = np.stack([sample() for sample in self.samplers])
            return actions, actions
        explore = np.array([rng.rand() for rng in self.rngs]) < self.exploration
        actions = self.greedy().copy() if not explore.all() else np.zeros((self.n_seeds, n_envs), dtype=np.int64)
        for index in np.flatnonzero(explore).tolist():
            actions[index] = self.samplers[index]()
        return actions, actions

    def _store(self, buffer_actions: np.ndarray, new_obs: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
               infos: list[list[dict[str, Any]]]) -> None:
        """Each seed's ``_store_transition`` into its replay buffer (SB3's ``ReplayBuffer.add``, for all seeds at once)."""
        if self.own_storage:
            for index in self._live():
                self.fields[index].store_transition(buffer_actions[index], new_obs[index], rewards[index], dones[index],
                                                    infos[index])
            self.replay.follow(self._live()[0])
            return
        next_obs = new_obs.copy()
        timeouts = np.zeros(dones.shape, dtype=bool)  # a VecEnv's TimeLimit.truncated is False where no episode ended
        for s, e in zip(*np.nonzero(dones)):
            info = infos[s][e]
            terminal = info.get("terminal_observation")
            if terminal is not None:
                next_obs[s, e] = terminal
            timeouts[s, e] = info.get("TimeLimit.truncated", False)
        self.replay.add(self.obs, next_obs, buffer_actions, rewards, dones, timeouts)
        if self.ends_repeats:
            for index in self._live():
                self.models[index].end_repeats(dones[index])  # type: ignore[attr-defined]

    def _train(self, gradient_steps: int, batch_size: int) -> None:
        """``DQN.train`` of every seed: ``gradient_steps`` batched steps, then SB3's bookkeeping (logged when dumped)."""
        models = self.models
        progress = self.fields[0].progress
        if self.one_rate:
            rate = models[0].lr_schedule(progress)
            self.stack.set_learning_rate(rate)
            self.learning_rates = [rate] * self.n_seeds
        else:
            self.learning_rates = [m.lr_schedule(progress) for m in models]
            self.stack.set_learning_rate(self.learning_rates)
        losses = th.stack([self.stack.train_step(*self.replay.sample(self.rngs, batch_size)) for _ in range(gradient_steps)])
        self.losses = losses.double().mean(dim=0).tolist()
        self.n_updates += gradient_steps
        self.trained_at = self.clock + 0.5

    def _after_step(self, dones: np.ndarray, log_interval: int) -> None:
        """``_update_current_progress_remaining``, ``DQN._on_step`` and the episode count of every seed."""
        first = self.models[0]
        self.fields[0].update_progress(self.num_timesteps, self.total_timesteps)
        progress = self.fields[0].progress
        for schedule, group in self.schedules:
            self.exploration[group] = schedule(progress)
        self.n_calls += 1
        self.clock += 1
        if self.n_calls % max(first.target_update_interval // self.n_envs, 1) == 0:
            self.stack.update_target()
        for s in np.flatnonzero(dones.any(axis=1) & ~self.frozen).tolist():
            fields = self.fields[s]
            for _ in range(int(dones[s].sum())):
                fields.episode_num += 1
                if fields.episode_num % log_interval == 0:
                    self._sync([s])
                    self._record(s)
                    self.dumped_at[s] = self.clock
                    self.models[s].dump_logs()

    def _freeze(self, index: int, callback: BaseCallback) -> None:
        """Seed ``index``'s callback stopped its training: keep its model as ``learn`` leaves it, the others run on."""
        model = self.models[index]
        self.frozen[index] = True
        self.stack.write_back(self.models, [index])
        self.replay.release_one(index)
        model.__dict__.pop("predict", None)
        self.fields[index].last_obs = self.obs[index]
        self._record(index)
        callback.on_training_end()

    # -- the loop --------------------------------------------------------------------------------------------------
    def learn(self, total_timesteps: int, log_interval: int = 4, every: int = 0,
              on_models: Callable[[list[DQN]], object] | None = None,
              user_callbacks: Sequence[MaybeCallback] | None = None) -> list[DQN]:
        """
        ``model.learn(total_timesteps, callback=user_callbacks[i], log_interval=log_interval)`` of every model, in
        lockstep; ``on_models(models)`` each time ``num_timesteps`` passes a multiple of ``every``, after the callbacks'
        ``on_step``, with the weights so far written into the models. A seed whose callback's ``on_step`` returns False
        stops there, as its ``learn`` would (its model, buffer and counts kept); the others run on.
        """
        models, first = self.models, self.models[0]
        callbacks: list[BaseCallback] = []
        for model, fields, given in zip(models, self.fields, user_callbacks or [None] * len(models)):
            total, callback = fields.setup_learn(total_timesteps, given, "run")
            callback.on_training_start({"self": model, "total_timesteps": total, "callback": callback,
                                        "log_interval": log_interval}, globals())
            callbacks.append(callback)
        self.num_timesteps, self.total_timesteps = first.num_timesteps, total
        self.samplers = [random_sampler(model.action_space, self.n_envs) for model in models]
        active = {i: c for i, c in enumerate(callbacks) if not idle(c)}
        self.obs = np.stack([fields.last_obs for fields in self.fields])
        self.stack = StackedQ(models)
        frequency = first.train_freq.frequency  # type: ignore[union-attr]
        vec_steps = -(-total // (self.n_envs * frequency)) * frequency
        self.replay = StackedReplay(models, vec_steps + 1)
        if self.own_actions:
            for index, model in enumerate(models):
                model.predict = _StackedPredict(self, index)  # type: ignore[method-assign]
        n_envs = self.n_envs
        every_step = self.own_actions or self.own_storage or bool(active)
        try:
            while self.num_timesteps < total and not self.frozen.all():
                for callback in active.values():
                    callback.on_rollout_start()
                collected = 0
                while collected < frequency and not self.frozen.all():
                    actions, buffer_actions = self._sample_actions(first.learning_starts)
                    new_obs, rewards, dones, infos = self.envs.step(actions, all_infos=self.own_storage or bool(active))
                    self.num_timesteps += n_envs
                    collected += 1
                    if every_step:
                        self._sync(self._live())
                    for index, callback in list(active.items()):
                        model = models[index]
                        callback.update_locals({"self": model, "actions": actions[index], "new_obs": new_obs[index],
                                                "rewards": rewards[index], "dones": dones[index],
                                                "infos": infos[index], "env": model.env})
                        if not callback.on_step():
                            del active[index]
                            self._freeze(index, callback)
                    if on_models is not None and self.num_timesteps // every > (self.num_timesteps - n_envs) // every:
                        live = self._live()
                        self._sync(live)
                        self.stack.write_back(models, live)
                        on_models(models)
                    for ended in np.flatnonzero(dones.any(axis=1) & ~self.frozen).tolist():
                        self.fields[ended].update_info_buffer(infos[ended], dones[ended])
                    self._store(buffer_actions, new_obs, rewards, dones, infos)
                    self.obs = new_obs
                    if self.own_actions and not self.own_storage:  # SB3's _sample_action predicts from _last_obs
                        for fields, obs in zip(self.fields, new_obs):
                            fields.last_obs = obs
                    self._after_step(dones, log_interval)
                    if every_step:
                        self._sync(self._live())
                for callback in active.values():
                    callback.on_rollout_end()
                if self.num_timesteps > 0 and self.num_timesteps > first.learning_starts and not self.frozen.all():
                    gradient_steps = first.gradient_steps if first.gradient_steps >= 0 else collected * n_envs
                    if gradient_steps > 0:
                        self._train(gradient_steps, first.batch_size)
            for callback in active.values():
                callback.on_training_end()
        finally:
            live = self._live()
            for model in models:
                model.__dict__.pop("predict", None)
            self._sync(live)
            for index in live:
                self._record(index)
            self.stack.write_back(models, live)
            self.replay.release()
            if not self.own_storage:
                for index in live:
                    self.fields[index].last_obs = self.obs[index]
        return models
