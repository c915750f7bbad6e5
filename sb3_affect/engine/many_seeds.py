"""
``train_many``: many seeds of one DQN-family agent, or of PPO, trained in one process, in lockstep, one SB3 model per
seed.

``train_many(algo, env_id, seeds, n_envs, total_timesteps=T, obs=..., **kwargs)[i]`` is, up to floating-point summation
order, the model ``algo("MlpPolicy", make_vec_env(env_id, n_envs, seed=seeds[i], wrapper_class=FlatObsWrapper),
seed=seeds[i], **kwargs).learn(T)`` gives: the same class, the same random streams, the same SB3 loop
(``sb3_affect.engine.lockstep`` for the DQN family, ``sb3_affect.engine.stacked_ppo`` for PPO), saved, loaded, evaluated
and used as a model trained by ``learn``. What is shared is the arithmetic: every seed's forward pass and gradient step
is one batched matrix product per layer (``sb3_affect.engine.stacked_q``), and every seed's compiled envs are stepped
by one kernel call (``sb3_affect.engine.seed_envs``). Every input is checked, and the run's memory estimated, before
any model is built (docs/many_seeds.md).
"""

from __future__ import annotations

import inspect
import itertools
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import DQN, PPO
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
from stable_baselines3.common.type_aliases import MaybeCallback, TrainFrequencyUnit
from stable_baselines3.common.vec_env import VecEnv

from sb3_affect.engine.lockstep import Lockstep
from sb3_affect.engine.seed_envs import check_observation, seed_vec_env
from sb3_affect.engine.stacked_ppo import LockstepPPO
from sb3_affect.engine.stacked_q import ELEMENTWISE_OPTIMIZERS
from sb3_affect.engine.stacked_replay import available_memory, replay_bytes
from sb3_affect.kernel.minigrid_world import MINIGRID_TASKS

#: arguments ``train_many`` sets itself
_OWN_ARGUMENTS = ("env", "seed")
#: the bound of NumPy's (and so SB3's) seeds
SEED_LIMIT = 2**32
#: the algorithm arguments the lockstep loop shares among the seeds (every other one may take a value per seed)
LOCKSTEP_ARGUMENTS = ("policy", "policy_kwargs", "device", "buffer_size", "learning_starts", "batch_size", "train_freq",
                      "gradient_steps", "target_update_interval", "replay_buffer_class", "replay_buffer_kwargs",
                      "optimize_memory_usage", "n_steps", "n_epochs", "normalize_advantage", "target_kl",
                      "use_sde", "sde_sample_freq", "rollout_buffer_class", "rollout_buffer_kwargs")


def _count(name: str, value: Any, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}={value!r} must be an integer >= {minimum}")
    return int(value)


def _algorithm(algo: str | type) -> type[DQN] | type[PPO]:
    from sb3_affect.core.registry import resolve_class

    cls: Any = resolve_class(algo) if isinstance(algo, str) else algo
    name = getattr(cls, "__name__", repr(cls))
    if isinstance(cls, type) and issubclass(cls, PPO):
        for method in ("train", "collect_rollouts"):
            if getattr(cls, method) is not getattr(PPO, method):
                raise ValueError(f"algo={name} has its own {method}: train_many runs PPO's, which would not be {name}'s")
        return cls
    if isinstance(cls, type) and issubclass(cls, OnPolicyAlgorithm):
        raise ValueError(f"algo={name} is on-policy but not PPO: train_many trains SB3's PPO and the DQN family")
    if not (isinstance(cls, type) and issubclass(cls, DQN)):
        raise ValueError(f"algo={name} is not a DQN or PPO: train_many trains SB3's PPO, DQN and DQN's subclasses "
                         "(AffectDQN, ...)")
    for method in ("train", "_on_step"):
        if getattr(cls, method) is not getattr(DQN, method):
            raise ValueError(f"algo={name} has its own {method}: train_many runs DQN's, which would not be {name}'s")
    return cls


def _seeds(seeds: Any) -> list[int]:
    if isinstance(seeds, (str, bytes)) or not isinstance(seeds, Sequence) or not seeds:
        raise ValueError(f"seeds={seeds!r} must be a non-empty list of integers >= 0")
    values = [_count("seeds[]", seed, 0) for seed in seeds]
    large = [seed for seed in values if seed >= SEED_LIMIT]
    if large:
        raise ValueError(f"seeds[]={large[0]} must be below 2**32 (NumPy's seeds are 32-bit)")
    twice = sorted({seed for seed in values if values.count(seed) > 1})
    if twice:
        raise ValueError(f"seeds has {twice[0]} twice: each seed is one run")
    return values


def _check_env_id(env_id: Any, compiled: bool) -> None:
    """That ``env_id`` names a MiniGrid task (compiled, or Farama's when it is installed): one line if not."""
    import gymnasium as gym

    allowed = f"a MiniGrid env id (compiled: {', '.join(MINIGRID_TASKS)})"
    if isinstance(env_id, (gym.Env, VecEnv)):
        raise ValueError(f"env_id={type(env_id).__name__} is an env: train_many builds each seed's envs itself from "
                         f"{allowed}")
    if not isinstance(env_id, str):
        raise ValueError(f"env_id={env_id!r} must be {allowed}")
    if compiled and env_id in MINIGRID_TASKS:
        return
    try:
        import minigrid  # noqa: F401  (registers MiniGrid's envs)
    except ImportError:
        raise ValueError(f"env_id={env_id!r} is not compiled ({', '.join(MINIGRID_TASKS)}): Farama's env needs "
                         "MiniGrid: pip install 'sb3-affect[minigrid]'") from None
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as error:
        raise ValueError(f"env_id={env_id!r} is not a registered env ({error})") from None
    entry_point = spec.entry_point if isinstance(spec.entry_point, str) else getattr(spec.entry_point, "__module__", "")
    if not str(entry_point).startswith("minigrid"):
        raise ValueError(f"env_id={env_id!r} is not a MiniGrid env: train_many takes {allowed}")


def _callbacks_of(callback: Any) -> list[Any]:
    """The callback objects one ``learn(callback=...)`` argument holds (a list's members, nested lists' too)."""
    if isinstance(callback, CallbackList):
        return [callback, *[c for member in callback.callbacks for c in _callbacks_of(member)]]
    if isinstance(callback, list):
        return [c for member in callback for c in _callbacks_of(member)]
    return [] if callback is None else [callback]


def _check_callbacks(callbacks: Any, n_seeds: int) -> None:
    """One ``learn`` callback per seed, each SB3's kind, no object given to two seeds (one line if not)."""
    if isinstance(callbacks, (str, bytes)) or not isinstance(callbacks, Sequence) or len(callbacks) != n_seeds:
        raise ValueError(f"callbacks must be a list of one callback per seed ({n_seeds}), not {callbacks!r}")
    owner: dict[int, int] = {}
    for index, given in enumerate(callbacks):
        for callback in _callbacks_of(given):
            if not (isinstance(callback, BaseCallback) or callable(callback)):
                raise ValueError(f"callbacks[{index}]={callback!r} is not a callback: give a BaseCallback, a list of "
                                 "them, a function of (locals, globals) or None")
            first = owner.setdefault(id(callback), index)
            if first != index:
                raise ValueError(f"callbacks[{index}] holds the {type(callback).__name__} of callbacks[{first}]: one "
                                 "callback object sees one seed's steps, give each seed its own")


def _check_settings(kwargs: dict[str, Any], where: str = "") -> None:
    """The loop counts an algorithm argument sets (what SB3 refuses, or would hang or divide by): one line each."""
    for name, minimum in (("batch_size", 1), ("buffer_size", 1), ("learning_starts", 0), ("target_update_interval", 1),
                          ("n_steps", 1), ("n_epochs", 1)):
        if name in kwargs:
            _count(f"{where}{name}", kwargs[name], minimum)
    if "gradient_steps" in kwargs:
        _count(f"{where}gradient_steps", kwargs["gradient_steps"], -1)
    if "train_freq" in kwargs:
        value = kwargs["train_freq"]
        frequency = value[0] if isinstance(value, tuple) and len(value) == 2 else value
        if isinstance(frequency, bool) or not isinstance(frequency, (int, np.integer)) or frequency < 1:
            raise ValueError(f"{where}train_freq={value!r} must be an integer >= 1 or (integer >= 1, 'step')")


def _per_seed(per_seed: Any, n_seeds: int, algo_kwargs: dict[str, Any]) -> list[dict[str, Any]]:
    """Each seed's own arguments from ``per_seed`` (a list of ``n_seeds`` values per argument): one line if not."""
    if per_seed is None:
        return [{} for _ in range(n_seeds)]
    if not isinstance(per_seed, Mapping):
        raise ValueError(f"per_seed={per_seed!r} must be a dict of argument name -> list of one value per seed")
    for name, values in per_seed.items():
        if name in LOCKSTEP_ARGUMENTS or name in _OWN_ARGUMENTS:
            raise ValueError(f"per_seed[{name!r}]: the seeds run in lockstep, so {name} is one value for all; per seed "
                             f"go the others (learning_rate, gamma, exploration_fraction, ...)")
        if name in algo_kwargs:
            raise ValueError(f"per_seed[{name!r}] and {name}= are both given: give one")
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or len(values) != n_seeds:
            raise ValueError(f"per_seed[{name!r}]={values!r} must be a list of one value per seed ({n_seeds})")
    return [{name: values[index] for name, values in per_seed.items()} for index in range(n_seeds)]


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
    if model.get_vec_normalize_env() is not None:
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
    per_seed: Mapping[str, Sequence[Any]] | None = None,
    **algo_kwargs: Any,
) -> list[Any]:
    """
    Train one ``algo`` model per seed on ``n_envs`` envs each, all seeds in lockstep, and return the models.

    :param algo: SB3's ``DQN`` or a subclass that keeps its ``train`` (``AffectDQN``, ``EzGreedyDQN``,
        ``SpeedEpsilonGreedyDQN``), or SB3's ``PPO`` (discrete actions), a class or its name
    :param env_id: a MiniGrid env id (``"MiniGrid-Empty-8x8-v0"``; ``sb3_affect.kernel.minigrid_world.MINIGRID_TASKS``
        are compiled)
    :param seeds: one run per seed
    :param n_envs: envs per seed (SB3's ``n_envs``: each VecEnv step is ``n_envs`` env steps)
    :param total_timesteps: env steps per seed, as ``learn(total_timesteps)``
    :param obs: ``"flat"`` (``FlatObsWrapper``'s vector) or ``"view"`` (its first 147 entries, the 7x7x3 view flattened)
    :param compiled: step the compiled MiniGrid (``minigrid_vec_env``, equal to Farama's step for step) where it
        implements ``env_id``; False: Farama's env through ``make_vec_env``
    :param log_interval: ``learn``'s: ``dump_logs`` every this many episodes
    :param every: with ``on_models``: call it each time the env steps per seed pass a multiple of ``every``
    :param on_models: ``on_models(models)``, the models holding the weights so far (e.g. to evaluate the greedy
        policy during training); called after the callbacks' ``on_step`` of the step that passes the multiple
    :param callbacks: one per seed, in the order of ``seeds``: what ``learn(callback=...)`` takes (a ``BaseCallback``, a
        list of them, a function, or None), called as ``learn`` calls it (``on_step`` after each VecEnv step, its
        ``self.locals`` holding the seed's ``actions``, ``new_obs``, ``rewards``, ``dones`` and ``infos``); a callback
        whose ``on_step`` returns False stops its seed as it stops ``learn``: that model is kept as it was then (its
        weights, replay buffer and counts) and the other seeds run on
    :param env_wrapper: applied to each seed's VecEnv before its model is built (e.g. a ``VecEnvWrapper`` that shapes
        the training reward); the wrapped VecEnv keeps the number of envs and the spaces
    :param per_seed: arguments of the class that take one value per seed, each a list in the order of ``seeds``
        (``per_seed={"learning_rate": [1e-3, 3e-4], "gamma": [0.9, 0.99]}``: a tuning grid in one call); those the
        lockstep loop shares (``LOCKSTEP_ARGUMENTS``: batch size, train frequency, buffer, network, ...) are refused
    :param algo_kwargs: the class's arguments (``policy`` included, ``"MlpPolicy"`` by default), the same for every seed
    :return: the trained models, in the order of ``seeds``
    """
    cls = _algorithm(algo)
    seed_list = _seeds(seeds)
    n_envs = _count("n_envs", n_envs, 1)
    total_timesteps = _count("total_timesteps", total_timesteps, 1)
    log_interval = _count("log_interval", log_interval, 1)
    if not isinstance(compiled, bool):
        raise ValueError(f"compiled={compiled!r} must be True or False")
    _check_env_id(env_id, compiled)
    if callbacks is not None:
        _check_callbacks(callbacks, len(seed_list))
    if env_wrapper is not None and not callable(env_wrapper):
        raise ValueError(f"env_wrapper={env_wrapper!r} must be a function of a VecEnv returning a VecEnv")
    if on_models is not None:
        every = _count("every", every, 1)
        if not callable(on_models):
            raise ValueError(f"on_models={on_models!r} must be a function of the list of models")
    check_observation(obs)
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
    _check_settings(algo_kwargs)
    own_kwargs = _per_seed(per_seed, len(seed_list), algo_kwargs)
    if issubclass(cls, PPO):
        _check_ppo(algo_kwargs, per_seed or {})
    for index, kwargs in enumerate(own_kwargs):
        _check_settings(kwargs, f"per_seed[{index}]: ")
    envs = [_wrapped(env_wrapper, seed_vec_env(env_id, n_envs, seed_list[0], obs, compiled))]
    _check_memory(cls, envs[0], len(seed_list), total_timesteps, algo_kwargs)
    envs += [_wrapped(env_wrapper, seed_vec_env(env_id, n_envs, seed, obs, compiled)) for seed in seed_list[1:]]
    if issubclass(cls, PPO):
        ppo_models, generators = [], []
        for env, seed, kwargs in zip(envs, seed_list, own_kwargs):
            ppo_models.append(cls(policy, env, seed=seed, device="cpu", **algo_kwargs, **kwargs))
            generators.append(th.random.get_rng_state())  # what the model's learn samples its actions from
        return LockstepPPO(ppo_models, seed_list, generators).learn(
            total_timesteps, log_interval=log_interval, every=every, on_models=on_models, user_callbacks=callbacks)
    # each model's replay buffer is built of one row (its arrays would be written only to be replaced): the trainer gives
    # it its ``buffer_size // n_envs`` rows (``StackedReplay``)
    buffer_size = algo_kwargs.pop("buffer_size", _default(cls, "buffer_size"))
    models: list[DQN] = [cls(policy, env, seed=seed, device="cpu", buffer_size=1, **algo_kwargs, **kwargs)
                         for env, seed, kwargs in zip(envs, seed_list, own_kwargs)]
    for model in models:
        model.buffer_size = buffer_size
    _check_model(models[0])
    return Lockstep(models, seed_list).learn(total_timesteps, log_interval=log_interval, every=every, on_models=on_models,
                                             user_callbacks=callbacks)


def _check_ppo(kwargs: dict[str, Any], per_seed: Mapping[str, Any]) -> None:
    """What the lockstep PPO does not stack (one line each)."""
    if "learning_rate" in per_seed:
        raise ValueError("per_seed['learning_rate']: train_many's PPO takes one learning rate for all seeds")
    if kwargs.get("target_kl") is not None:
        raise ValueError(f"target_kl={kwargs['target_kl']!r}: train_many's PPO runs every epoch (give None)")
    if kwargs.get("use_sde"):
        raise ValueError("use_sde=True: train_many's PPO samples discrete actions (give False)")
    if kwargs.get("normalize_advantage", True) not in (True, False):
        raise ValueError(f"normalize_advantage={kwargs['normalize_advantage']!r} must be True or False")


def _wrapped(env_wrapper: Callable[[VecEnv], VecEnv] | None, env: VecEnv) -> VecEnv:
    """``env_wrapper(env)``, which must be a VecEnv of the same envs and spaces (one line if not)."""
    if env_wrapper is None:
        return env
    wrapped = env_wrapper(env)
    if not isinstance(wrapped, VecEnv):
        raise ValueError(f"env_wrapper returned {type(wrapped).__name__}, not a VecEnv: it must return the wrapped VecEnv")
    if (wrapped.num_envs, wrapped.observation_space, wrapped.action_space) != (
            env.num_envs, env.observation_space, env.action_space):
        raise ValueError("env_wrapper returned a VecEnv of other envs or spaces: it must keep the number of envs and "
                         "the spaces")
    return wrapped


def _default(cls: type, name: str) -> Any:
    """The default of argument ``name`` of ``cls`` (of the first class up its MRO that names it)."""
    for klass in cls.__mro__:
        if "__init__" not in vars(klass):
            continue
        parameter = inspect.signature(vars(klass)["__init__"]).parameters.get(name)
        if parameter is not None and parameter.default is not inspect.Parameter.empty:
            return parameter.default
    raise ValueError(f"{cls.__name__} has no default {name}: give {name}=")


def _check_memory(cls: type, env: VecEnv, n_seeds: int, total_timesteps: int, kwargs: dict[str, Any]) -> None:
    """
    Refuse, before any model is built, a run whose replay buffers and networks need more than the machine's available
    memory: the stacked buffers touch the rows training reaches (``StackedReplay``), one seed's more where they are
    copied back, and each seed's networks a few copies of their weights.
    """
    if issubclass(cls, PPO):  # the stacked rollout and each model's: float32 observations and seven numbers a row
        rows = kwargs.get("n_steps", _default(cls, "n_steps"))
        per_seed = 2 * rows * env.num_envs * (4 * int(np.prod(env.observation_space.shape or (1,))) + 4 * 8)
    else:
        buffer_size = kwargs.get("buffer_size", _default(cls, "buffer_size"))
        train_freq = kwargs.get("train_freq", _default(cls, "train_freq"))
        frequency = train_freq[0] if isinstance(train_freq, tuple) else train_freq
        vec_steps = -(-total_timesteps // (env.num_envs * frequency)) * frequency
        rows = min(vec_steps + 1, max(buffer_size // env.num_envs, 1))
        per_seed = replay_bytes(env.observation_space, env.action_space, env.num_envs, rows)
    net_arch = (kwargs.get("policy_kwargs") or {}).get("net_arch", [64, 64])
    sizes = [int(np.prod(env.observation_space.shape or (1,))), *net_arch, int(getattr(env.action_space, "n", 1))]
    parameters = sum((a + 1) * b for a, b in itertools.pairwise(sizes))
    # online, target, gradient and two optimizer moments, stacked and in the model: 10 float32 copies
    need = n_seeds * (per_seed + 10 * 4 * parameters) + per_seed
    available = available_memory()
    if available is not None and need > available:
        raise ValueError(f"train_many needs about {need / 2**20:,.0f} MB for {n_seeds} seeds ({rows:,} replay rows x "
                         f"{env.num_envs} envs, {per_seed / 2**20:,.1f} MB each, and their networks), more than the "
                         f"{available / 2**20:,.0f} MB of memory available: give fewer seeds, a smaller buffer_size or "
                         "fewer total_timesteps")
