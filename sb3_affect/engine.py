"""
``simulate``: many runs of one tabular agent on one env, each exactly what ``learn`` gives for its seed.

This is the batch entry point of large studies (the launcher's batches, the report's large-N parts, forensics): one
call, many seeds, one table of episode rows. Whatever engine computes it, row ``(seed, episode)`` equals
``model.episode_log`` of ``Algo("Grid", gym.make(env_id, **env_kwargs), seed=seed, **algo_kwargs)`` trained with
``StopTrainingOnMaxEpisodes(episodes)``.

On the compiled engine (the default wherever it applies, see ``TabularQAlgorithm``) all seeds run in one kernel call:
no SB3 model is built per seed, so a batch costs about what its decisions cost. Memory: the table holds
``len(seeds) * episodes`` rows (about 130 bytes each); give large studies in batches.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.episode_log import EPISODE_COLUMNS

#: Columns of ``simulate``'s table: the run's seed, then ``EPISODE_COLUMNS``.
SIMULATE_COLUMNS: tuple[str, ...] = ("seed", *EPISODE_COLUMNS)


def _resolve(algo: str | type) -> type:
    from sb3_affect.experiments.schema import resolve_class
    from sb3_affect.tabular import TabularQAlgorithm

    cls: Any = resolve_class(algo) if isinstance(algo, str) else algo
    if not (isinstance(cls, type) and issubclass(cls, TabularQAlgorithm)):
        raise TypeError(f"algo={algo!r} is not a tabular agent of this package (QLearning, AffectQ or a baseline)")
    return cls


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
    import gymnasium as gym
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
    from stable_baselines3.common.logger import Logger

    import sb3_affect  # noqa: F401  (registers the envs)

    cls = _resolve(algo)
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes={episodes!r} must be an integer >= 1")
    from sb3_affect.appraisal import check_choice
    from sb3_affect.tabular import ENGINES

    check_choice("engine", engine, ENGINES)
    seeds = list(seeds)
    for seed in seeds:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seeds must be integers, got {seed!r}")
    kwargs = dict(algo_kwargs or {})
    own = kwargs.get("engine", "auto")
    if engine != "python" and own != "python":
        from sb3_affect.kernel.batch import batch_reason, simulate_batch

        env = gym.make(env_id, **(env_kwargs or {}))
        template = cls("Grid", env, seed=0, **kwargs)
        reason = batch_reason(template, episodes)
        if reason is None:
            frame = simulate_batch(template, seeds, episodes) if seeds else None
            env.close()
            return frame if frame is not None else pd.DataFrame(columns=list(SIMULATE_COLUMNS))
        env.close()
        if engine == "compiled" or own == "compiled":
            raise ValueError(f"engine='compiled' can not run this simulation: {reason}")
    if engine == "python":
        kwargs["engine"] = "python"
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
