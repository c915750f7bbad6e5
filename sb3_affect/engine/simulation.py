"""
``simulate``: many runs of one tabular agent on one env, each exactly what ``learn`` gives for its seed.

This is the batch entry point of large studies (the launcher's batches, the report's large-N parts, forensics): one
call, many seeds, one table of episode rows. Whatever engine computes it, row ``(seed, episode)`` equals
``model.episode_log`` of ``Algo("Grid", gym.make(env_id, **env_kwargs), seed=seed, **algo_kwargs)`` trained with
``StopTrainingOnMaxEpisodes(episodes)``.

On the compiled engine (the default wherever it applies, see ``TabularQAlgorithm``) all seeds run in one kernel call:
no SB3 model is built per seed, so a batch costs about what its decisions cost. For the package's own agents named
with their settings' arguments (``sb3_affect.core.settings``) on its grid envs no model is built at all, and neither torch
nor SB3 is imported: the kernel's inputs come from the agent's settings, checked as its constructor checks them
(``kernel.grid_inputs.settings_inputs``); anything else (a class of your own, an SB3 argument such as ``device``, a
schedule of the training progress) builds one model as a template. MovingPursuit runs on its own kernel
(``kernel.moving_loop``, the prey drawing from a port of the env's NumPy generator, ``kernel.pcg64``). Memory: the table holds
``len(seeds) * episodes`` rows (about 130 bytes each); give large studies in batches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from sb3_affect.core.appraisal import check_choice
from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.core.registry import known_settings, resolve_class
from sb3_affect.core.setting_checks import ENGINES
from sb3_affect.envs import register_envs

if TYPE_CHECKING:
    import pandas as pd

#: Columns of ``simulate``'s table: the run's seed, then ``EPISODE_COLUMNS``.
SIMULATE_COLUMNS: tuple[str, ...] = ("seed", *EPISODE_COLUMNS)


def _resolve(algo: str | type) -> type:
    from sb3_affect.agents.tabular import TabularQAlgorithm

    cls: Any = resolve_class(algo) if isinstance(algo, str) else algo
    if not (isinstance(cls, type) and issubclass(cls, TabularQAlgorithm)):
        raise TypeError(f"algo={algo!r} is not a tabular agent of this package (QLearning, AffectQ or a baseline)")
    return cls


def _check_args(episodes: int, engine: str, seeds: list[Any]) -> None:
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
    check_choice("engine", engine, ENGINES)
    for seed in seeds:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seeds must be integers, got {seed!r}")


def simulate(
    algo: str | type,
    algo_kwargs: dict[str, Any] | None,
    env_id: str,
    env_kwargs: dict[str, Any] | None,
    seeds: Sequence[int],
    episodes: int,
    engine: str = "auto",
) -> pd.DataFrame:
    """
    Train one fresh agent per seed for ``episodes`` episodes and return all their episode logs.

    :param algo: the agent class or its name (``"QLearning"``, ``"AffectQ"``, a baseline's class name)
    :param algo_kwargs: constructor arguments (besides policy, env and seed)
    :param env_id: a registered Gymnasium id (``"sb3_affect/GridPursuit-v0"``, ...)
    :param env_kwargs: arguments of ``gym.make``
    :param seeds: one run per seed, in this order
    :param episodes: episodes per run
    :param engine: ``"auto"`` (one kernel call for all seeds where the kernel applies, else one ``learn`` per seed),
        ``"python"`` (one ``learn`` per seed on the Python loop) or ``"compiled"`` (the kernel, or an error saying why
        it can not apply); an ``engine`` in ``algo_kwargs`` is the agent's own and wins for ``"python"``
    :return: one row per (seed, episode), columns ``SIMULATE_COLUMNS``
    """
    import pandas as pd

    table = simulate_columns(algo, algo_kwargs, env_id, env_kwargs, seeds, episodes, engine)
    return table if isinstance(table, pd.DataFrame) else pd.DataFrame(table)


def simulate_columns(
    algo: str | type,
    algo_kwargs: dict[str, Any] | None,
    env_id: str,
    env_kwargs: dict[str, Any] | None,
    seeds: Sequence[int],
    episodes: int,
    engine: str = "auto",
) -> Any:
    """
    ``simulate``'s table, as a DataFrame or, where one kernel call computes it from the agent's settings, as
    ``{column: NumPy array}`` without importing pandas (the launcher's batches); same arguments as ``simulate``.
    """
    register_envs()
    seeds = list(seeds)
    kwargs = dict(algo_kwargs or {})
    own = kwargs.get("engine", "auto")
    compiled = engine != "python" and own != "python"
    if compiled and known_settings(algo) is not None:  # the package's agent: no model (nor torch, when named)
        _check_args(episodes, engine, seeds)
        table = _settings_columns(algo, kwargs, env_id, env_kwargs, seeds, episodes)
        if table is not None:
            return table
    cls = _resolve(algo)
    _check_args(episodes, engine, seeds)
    if compiled:
        table, reason = _template_columns(cls, kwargs, env_id, env_kwargs, seeds, episodes)
        if table is not None:
            return table
        if engine == "compiled" or own == "compiled":
            raise ValueError(f"engine='compiled' can not run this simulation: {reason}")
    if engine == "python":
        kwargs["engine"] = "python"
    return _learned_frame(cls, kwargs, env_id, env_kwargs, seeds, episodes)


def _settings_columns(
    algo: str | type, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any] | None, seeds: list[Any], episodes: int
) -> Any:
    """The table of one kernel call from the agent's settings, with no model (None: a model is needed)."""
    from sb3_affect.kernel.grid_batch import batch_columns
    from sb3_affect.kernel.grid_inputs import settings_inputs
    from sb3_affect.kernel.moving_batch import moving_columns, moving_settings_inputs

    inputs = settings_inputs(algo, kwargs, env_id, env_kwargs, episodes)
    if inputs is not None:
        _announce_compile(moving=False)
        return batch_columns(inputs, seeds, episodes) if seeds else _batch_frame(inputs, seeds, episodes)
    prey_inputs = moving_settings_inputs(algo, kwargs, env_id, env_kwargs, episodes)
    if prey_inputs is not None:
        _announce_compile(moving=True)
        return moving_columns(prey_inputs, seeds, episodes) if seeds else _batch_frame(None, seeds, episodes)
    return None


def _template_columns(
    cls: type, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any] | None, seeds: list[Any], episodes: int
) -> tuple[Any, str | None]:
    """The table of one kernel call from one template model (seed 0), or ``(None, why the kernel can not)``."""
    import gymnasium as gym
    import pandas as pd

    from sb3_affect.agents.compiled import batch_reason
    from sb3_affect.kernel.grid_inputs import batch_inputs
    from sb3_affect.kernel.moving_batch import moving_batch_reason, moving_columns, moving_inputs, moving_reason

    env = gym.make(env_id, **(env_kwargs or {}))
    try:
        template = cls("Grid", env, seed=0, **kwargs)
        reason = batch_reason(template, episodes)
        if reason is None:
            inputs = batch_inputs(template.compiled_settings(), template.single_env(), episodes)
            _announce_compile(moving=False)
            return _batch_frame(inputs, seeds, episodes), None
        if moving_reason(template.single_env()) is None:  # MovingPursuit: the moving-prey kernel, or why not
            reason = moving_batch_reason(template)
            if reason is None:
                prey_inputs = moving_inputs(template.compiled_settings(), template.single_env(), episodes)
                if not seeds:
                    return _batch_frame(None, seeds, episodes), None
                _announce_compile(moving=True)
                return pd.DataFrame(moving_columns(prey_inputs, seeds, episodes)), None
        return None, reason
    finally:
        env.close()


def _announce_compile(moving: bool) -> None:
    """Before a kernel call: one line if that kernel is not compiled yet on this machine (``kernel.jit.announce_compile``)."""
    from sb3_affect.kernel import grid_batch, moving_loop
    from sb3_affect.kernel.jit import GRID_COMPILE_CPU_SECONDS, MOVING_COMPILE_CPU_SECONDS, announce_compile

    if moving:
        feature, kernel, seconds = "moving-prey batch kernel", moving_loop.run_seeds, MOVING_COMPILE_CPU_SECONDS
    else:
        feature, kernel, seconds = "batch kernel", grid_batch.run_seeds, GRID_COMPILE_CPU_SECONDS
    announce_compile(f"the tabular agents' {feature} (simulate)", (kernel,), seconds)


def _learned_frame(
    cls: type, kwargs: dict[str, Any], env_id: str, env_kwargs: dict[str, Any] | None, seeds: list[Any], episodes: int
) -> pd.DataFrame:
    """One ``learn`` per seed (with ``StopTrainingOnMaxEpisodes``), their episode logs in one table."""
    import gymnasium as gym
    import pandas as pd
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
    from stable_baselines3.common.logger import Logger

    frames = []
    for seed in seeds:
        env = gym.make(env_id, **(env_kwargs or {}))
        model = cls("Grid", env, seed=int(seed), **kwargs)
        model.set_logger(Logger(folder=None, output_formats=[]))
        model.learn(episodes * model.max_episode_decisions, callback=StopTrainingOnMaxEpisodes(episodes))
        frame = model.episode_log
        frame.insert(0, "seed", int(seed))
        frames.append(frame)
        env.close()
    if not frames:
        return pd.DataFrame(columns=list(SIMULATE_COLUMNS))
    return pd.concat(frames, ignore_index=True)


def _batch_frame(inputs: Any, seeds: list[Any], episodes: int) -> pd.DataFrame:
    """The rows of one kernel call for all seeds (``kernel.grid_batch.simulate_batch``)."""
    import pandas as pd

    if not seeds or inputs is None:
        return pd.DataFrame(columns=list(SIMULATE_COLUMNS))
    from sb3_affect.kernel.grid_batch import simulate_batch

    return simulate_batch(inputs, seeds, episodes)
