"""
``train_many``: many seeds of one DQN-family agent trained in one process, in lockstep, one SB3 model per seed.

``train_many(algo, env_id, seeds, n_envs, total_timesteps=T, obs=..., **kwargs)[i]`` is, up to floating-point summation
order, the model ``algo("MlpPolicy", make_vec_env(env_id, n_envs, seed=seeds[i], wrapper_class=FlatObsWrapper),
seed=seeds[i], **kwargs).learn(T)`` gives: the same class, the same random streams, the same SB3 loop
(``sb3_affect.engine.lockstep``), saved, loaded, evaluated and used as a model trained by ``learn``. What is shared is
the arithmetic: every seed's Q-network forward pass and gradient step is one batched matrix product per layer
(``sb3_affect.engine.stacked_q``), and every seed's compiled envs are stepped by one kernel call
(``sb3_affect.engine.seed_envs``).

Speed (``python benchmarks/bench_many_seeds.py``, Empty-8x8, ``obs="image"``, 4 envs per seed, ``train_freq`` 4,
batch 32, one torch thread, on a shared 2-core machine): at S = 32 DQN makes about 58,000 env steps per CPU second,
50 times SB3's ``DQN.learn`` with one env and 21 times with four; the batched gradient step's own arithmetic caps
any trainer of these networks near 83,000 (docs/many_seeds.md, "Speed").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from stable_baselines3 import DQN
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.type_aliases import MaybeCallback, TrainFrequencyUnit
from stable_baselines3.common.vec_env import VecEnv

from sb3_affect.agents.minigrid_vec_env import OBSERVATIONS
from sb3_affect.engine.lockstep import Lockstep
from sb3_affect.engine.seed_envs import seed_vec_env
from sb3_affect.engine.stacked_q import ELEMENTWISE_OPTIMIZERS
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS

#: arguments ``train_many`` sets itself
_OWN_ARGUMENTS = ("env", "seed")


def _count(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}={value!r} must be an integer >= {minimum}")
    return int(value)


def _algorithm(algo: str | type) -> type[DQN]:
    from sb3_affect.core.registry import resolve_class

    cls: Any = resolve_class(algo) if isinstance(algo, str) else algo
    name = getattr(cls, "__name__", repr(cls))
    if isinstance(cls, type) and issubclass(cls, OnPolicyAlgorithm):
        raise ValueError(f"algo={name} is on-policy: train_many trains SB3's off-policy DQN family (DQN and its subclasses)")
    if not (isinstance(cls, type) and issubclass(cls, DQN)):
        raise ValueError(f"algo={name} is not a DQN: train_many trains SB3's DQN and its subclasses (AffectDQN, ...)")
    for method in ("train", "_on_step"):
        if getattr(cls, method) is not getattr(DQN, method):
            raise ValueError(f"algo={name} has its own {method}: train_many runs DQN's, which would not be {name}'s")
    return cls


def _seeds(seeds: Any) -> list[int]:
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Sequence) or not seeds:
        raise ValueError(f"seeds={seeds!r} must be a non-empty list of integers >= 0")
    values = [_count("seeds[]", seed, 0) for seed in seeds]
    twice = sorted({seed for seed in values if values.count(seed) > 1})
    if twice:
        raise ValueError(f"seeds has {twice[0]} twice: each seed is one run")
    return values


def _check_farama_env(env_id: str) -> None:
    """That Farama's MiniGrid is installed and names ``env_id`` (one line if not)."""
    import gymnasium as gym

    try:
        import minigrid  # noqa: F401  (registers MiniGrid's envs)
    except ImportError:
        raise ValueError(f"env_id={env_id!r} is not compiled ({', '.join(MINIGRID_TASKS)}): Farama's env needs "
                         "MiniGrid: pip install 'sb3-affect[minigrid]'") from None
    try:
        gym.spec(env_id)
    except gym.error.Error as error:
        raise ValueError(f"env_id={env_id!r} is not a registered env ({error})") from None


def _check_model(model: DQN) -> None:
    """What the lockstep loop needs of a constructed model (one line each)."""
    name = type(model).__name__
    if type(model.replay_buffer) is not ReplayBuffer:
        raise ValueError(f"replay_buffer_class={type(model.replay_buffer).__name__} is not ReplayBuffer: "
                         "train_many samples SB3's ReplayBuffer")
    if model.optimize_memory_usage:
        raise ValueError("optimize_memory_usage=True is not supported by train_many: give False")
    if model.train_freq.unit != TrainFrequencyUnit.STEP:  # type: ignore[union-attr]
        raise ValueError(f"train_freq={model.train_freq!r} counts episodes: train_many needs steps (e.g. train_freq=4)")
    if not isinstance(model.policy.optimizer, ELEMENTWISE_OPTIMIZERS):
        allowed = ", ".join(c.__name__ for c in ELEMENTWISE_OPTIMIZERS)
        raise ValueError(f"optimizer_class={type(model.policy.optimizer).__name__} of {name}: train_many stacks "
                         f"element-wise optimizers only ({allowed})")
    if model._vec_normalize_env is not None:
        raise ValueError("train_many does not support VecNormalize")


def train_many(
    algo: str | type,
    env_id: str,
    seeds: Sequence[int],
    n_envs: int = 4,
    *,
    total_timesteps: int,
    obs: str = "flat",
    compiled: bool = True,
    log_interval: int = 4,
    every: int = 0,
    on_models: Callable[[list[Any]], object] | None = None,
    callbacks: Sequence[MaybeCallback] | None = None,
    env_wrapper: Callable[[VecEnv], VecEnv] | None = None,
    **algo_kwargs: Any,
) -> list[Any]:
    """
    Train one ``algo`` model per seed on ``n_envs`` envs each, all seeds in lockstep, and return the models.

    :param algo: SB3's ``DQN`` or a subclass that keeps its ``train`` (``AffectDQN``, ``EzGreedyDQN``,
        ``SpeedEpsilonGreedyDQN``), a class or its name
    :param env_id: a MiniGrid env id (``"MiniGrid-Empty-8x8-v0"``; ``sb3_affect.kernel.minigrid_world.MINIGRID_TASKS``
        are compiled)
    :param seeds: one run per seed
    :param n_envs: envs per seed (SB3's ``n_envs``: each VecEnv step is ``n_envs`` env steps)
    :param total_timesteps: env steps per seed, as ``learn(total_timesteps)``
    :param obs: ``"flat"`` (``FlatObsWrapper``'s vector) or ``"image"`` (its first 147 entries, the 7x7x3 view)
    :param compiled: step the compiled MiniGrid (``minigrid_vec_env``, equal to Farama's step for step) where it
        implements ``env_id``; False: Farama's env through ``make_vec_env``
    :param log_interval: ``learn``'s: ``dump_logs`` every this many episodes
    :param every: with ``on_models``: call it each time the env steps per seed pass a multiple of ``every``
    :param on_models: ``on_models(models)``, the models holding the weights so far (e.g. to evaluate the greedy
        policy during training); called after the callbacks' ``on_step`` of the step that passes the multiple
    :param callbacks: one per seed, in the order of ``seeds``: what ``learn(callback=...)`` takes (a ``BaseCallback``, a
        list of them, a function, or None), called as ``learn`` calls it (``on_step`` after each VecEnv step, its
        ``self.locals`` holding the seed's ``actions``, ``new_obs``, ``rewards``, ``dones`` and ``infos``); a callback
        whose ``on_step`` returns False stops training with an error: every seed runs ``total_timesteps``
    :param env_wrapper: applied to each seed's VecEnv before its model is built (e.g. a ``VecEnvWrapper`` that shapes
        the training reward); the wrapped VecEnv keeps the number of envs and the spaces
    :param algo_kwargs: the class's arguments (``policy`` included, ``"MlpPolicy"`` by default), the same for every seed
    :return: the trained models, in the order of ``seeds``
    """
    cls = _algorithm(algo)
    seed_list = _seeds(seeds)
    n_envs = _count("n_envs", n_envs, 1)
    total_timesteps = _count("total_timesteps", total_timesteps, 1)
    log_interval = _count("log_interval", log_interval, 1)
    if callbacks is not None and (isinstance(callbacks, (str, bytes)) or not isinstance(callbacks, Sequence)
                                  or len(callbacks) != len(seed_list)):
        raise ValueError(f"callbacks must be a list of one callback per seed ({len(seed_list)}), not {callbacks!r}")
    if env_wrapper is not None and not callable(env_wrapper):
        raise ValueError(f"env_wrapper={env_wrapper!r} must be a function of a VecEnv returning a VecEnv")
    if on_models is not None:
        every = _count("every", every, 1)
        if not callable(on_models):
            raise ValueError(f"on_models={on_models!r} must be a function of the list of models")
    if obs not in OBSERVATIONS:
        raise ValueError(f"obs={obs!r} is not one of {', '.join(OBSERVATIONS)}")
    shared = [key for key, value in algo_kwargs.items() if isinstance(value, BaseCallback)]
    if shared:
        raise ValueError(f"{shared[0]}= is one {type(algo_kwargs[shared[0]]).__name__} for every seed: give a dict of its "
                         "settings, from which each seed's model builds its own")
    own = [key for key in _OWN_ARGUMENTS if key in algo_kwargs]
    if own:
        raise ValueError(f"{own[0]}= is train_many's own argument: give env_id, n_envs and seeds instead")
    policy = algo_kwargs.pop("policy", "MlpPolicy")
    if policy != "MlpPolicy":
        raise ValueError(f"policy={policy!r}: train_many stacks SB3's MlpPolicy only")
    device = algo_kwargs.pop("device", "cpu")
    if str(device) != "cpu":
        raise ValueError(f"device={device!r}: train_many runs on the CPU")
    if not isinstance(compiled, bool):
        raise ValueError(f"compiled={compiled!r} must be True or False")
    if not (compiled and env_id in MINIGRID_TASKS):
        _check_farama_env(env_id)
    wrap = env_wrapper or (lambda env: env)
    models = [cls(policy, wrap(seed_vec_env(env_id, n_envs, seed, obs, compiled)), seed=seed, device="cpu", **algo_kwargs)
              for seed in seed_list]
    _check_model(models[0])
    return Lockstep(models, seed_list).learn(total_timesteps, log_interval=log_interval, every=every, on_models=on_models,
                                             user_callbacks=callbacks)
