"""Execute one run config (plain data) in whatever process it lands in: build the env, train, return the records."""

from __future__ import annotations

import math
import os
import platform
import time
from pathlib import Path
from typing import Any

from sb3_affect.episode_log import EPISODE_COLUMNS


def package_versions() -> dict[str, str]:
    import gymnasium
    import numpy
    import stable_baselines3
    import torch

    import sb3_affect

    return {
        "python": platform.python_version(),
        "sb3_affect": sb3_affect.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "gymnasium": gymnasium.__version__,
        "torch": torch.__version__,
        "numpy": numpy.__version__,
    }


def _plain(value: Any) -> Any:
    """A JSON-safe, deterministic Python value (NaN -> None, numpy scalars -> Python)."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def execute_run(config: dict[str, Any], log_dir: str | None = None, log_formats: tuple[str, ...] = ("csv",)) -> dict[str, Any]:
    """
    Train one agent as ``config`` says and return ``{"episodes": {column: [...]}, "timings": ..., "versions": ...}``.

    Tabular agents of this package keep their own ``episode_log``; any other SB3 algorithm is watched by an
    ``EmotionCallback``. Training stops after ``config["episodes"]`` episodes (``StopTrainingOnMaxEpisodes``) or
    ``config["max_timesteps"]`` decisions, whichever comes first.
    """
    import torch as th

    th.set_num_threads(1)
    import gymnasium as gym
    from stable_baselines3.common.callbacks import CallbackList, StopTrainingOnMaxEpisodes
    from stable_baselines3.common.logger import Logger, configure

    from sb3_affect.callbacks import EmotionCallback
    from sb3_affect.experiments.schema import resolve_class
    from sb3_affect.tabular import TabularQAlgorithm

    start = time.perf_counter()
    cls = resolve_class(config["algo"])
    env = gym.make(config["env_id"], **config["env_kwargs"])
    kwargs = dict(config["algo_kwargs"])
    episodes = int(config["episodes"])
    tabular = issubclass(cls, TabularQAlgorithm)
    if tabular:
        model = cls("Grid", env, seed=config["seed"], **kwargs)
        budget = config["max_timesteps"] or episodes * model.max_episode_decisions
        callback: Any = StopTrainingOnMaxEpisodes(episodes)
    else:
        policy = kwargs.pop("policy", "MlpPolicy")
        model = cls(policy, env, seed=config["seed"], **kwargs)
        budget = config["max_timesteps"] or episodes * 20_000
        emotions = EmotionCallback()
        callback = CallbackList([emotions, StopTrainingOnMaxEpisodes(episodes)])
    if log_dir is not None:
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        model.set_logger(configure(log_dir, list(log_formats)))
    else:  # SB3's default logger would leave an empty /tmp/SB3-<date> folder per run
        model.set_logger(Logger(folder=None, output_formats=[]))
    model.learn(int(budget), callback=callback)
    log = model.episode_log if tabular else emotions.episode_log
    columns = {name: [_plain(v) for v in log[name].tolist()] for name in EPISODE_COLUMNS}
    return {
        "episodes": columns,
        "timings": {
            "wall_seconds": round(time.perf_counter() - start, 4),
            "decisions": int(model.num_timesteps),
            "pid": os.getpid(),
        },
        "versions": package_versions(),
    }
