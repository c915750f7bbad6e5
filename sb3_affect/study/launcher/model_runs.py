"""
The runs and checks that build an SB3 model (torch): a run config's algorithm or team of hunters on the env
``one_run`` built for it, trained with its callbacks, and the checks of a config that only a built model can do.
``one_run`` imports this module only where a run or a check needs a model: the tabular sweep path never imports torch.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import torch as th
from stable_baselines3.common.callbacks import CallbackList, StopTrainingOnMaxEpisodes
from stable_baselines3.common.logger import Logger, configure
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.agents.tabular import TabularQAlgorithm
from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.core.positions import make_position
from sb3_affect.core.registry import EMOTION_MODELS, observer_class, resolve_class
from sb3_affect.core.settings import AffectQSettings
from sb3_affect.study.launcher.chunks import checked_column
from sb3_affect.study.launcher.emotion_trace import TraceCallback

#: ``(columns, decisions)`` of a trained run: each episode column as a list of JSON-safe values, and the decisions taken.
Trained = tuple[dict[str, list[Any]], int]


def plain(value: Any) -> Any:
    """A JSON-safe, deterministic Python value (NaN -> None, numpy scalars -> Python)."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def build_team(config: dict[str, Any], env: Any) -> Any:
    """The ``HunterTeam`` of a team run config on its multi-agent ``env`` (one tabular agent per hunter)."""
    from sb3_affect.agents.hunter_team import HunterTeam  # (the hunters extra: pettingzoo)

    return HunterTeam(env, [(m["algo"], m["kwargs"]) for m in config["team"]], seed=config["seed"])


def build_model(config: dict[str, Any], env: Any) -> tuple[Any, bool]:
    """The algorithm of a run config on its ``env``: ``(model, tabular)`` (``tabular``: keeps its own ``episode_log``)."""
    cls: Any = resolve_class(config["algo"])
    kwargs = dict(config["algo_kwargs"])
    if issubclass(cls, TabularQAlgorithm):
        if config.get("trace"):
            kwargs["emotion_callback"] = _trace_callback(kwargs)
        return cls("Grid", env, seed=config["seed"], **kwargs), True
    policy = kwargs.pop("policy", "MlpPolicy")
    return cls(policy, env, seed=config["seed"], **kwargs), False


def _trace_callback(kwargs: dict[str, Any]) -> TraceCallback:
    """The ``TraceCallback`` a traced AffectQ run drives, reading as its kwargs say (``launcher.emotion_trace``)."""
    settings = AffectQSettings(**kwargs)
    return TraceCallback(comparison=settings.comparison, act=settings.act, units=settings.units)


def check_position(env: Any, position: str) -> None:
    """Read the ``position`` preset once on a single-agent ``env``, through SB3's ``DummyVecEnv`` as a run reads it."""
    venv = DummyVecEnv([lambda: env])
    hook = make_position(position, venv.observation_space)
    if hook is not None:
        hook.bind(venv, venv.observation_space)
        hook.cells(venv, venv.reset(), [{}])


def check_model(config: dict[str, Any], env: Any) -> None:
    """Build the model (or the team) of a run config on ``env``, without training, then close it (one torch thread)."""
    th.set_num_threads(1)
    if "team" in config:
        build_team(config, env).env.close()
    else:
        model, _ = build_model(config, env)
        model.get_env().close()


def train(config: dict[str, Any], env: Any, log_dir: str | None, log_formats: tuple[str, ...]) -> Trained:
    """
    Train the agent (or the team) of a run config on ``env`` with one torch thread: ``(columns, decisions)``.

    Tabular agents of this package keep their own ``episode_log``; any other SB3 algorithm is watched by an
    ``EmotionCallback``. Training stops after ``config["episodes"]`` episodes (``StopTrainingOnMaxEpisodes``) or
    ``config["max_timesteps"]`` decisions, whichever comes first.
    """
    th.set_num_threads(1)
    if "team" in config:
        return _train_team(config, env, log_dir, log_formats)
    model, tabular = build_model(config, env)
    episodes = int(config["episodes"])
    if tabular:
        budget = config["max_timesteps"] or episodes * model.max_episode_decisions
        callback: Any = StopTrainingOnMaxEpisodes(episodes)
    else:
        budget = config["max_timesteps"] or episodes * 20_000
        # an agent driven by emotions logs its own (the callback that steers it); any other is watched by one
        emotions = getattr(model, "emotion_callback", None) or EmotionCallback(position=config.get("env_position"))
        callback = [emotions, StopTrainingOnMaxEpisodes(episodes)]
    if log_dir is not None:
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        model.set_logger(configure(log_dir, list(log_formats)))
    else:  # SB3's default logger would leave an empty /tmp/SB3-<date> folder per run
        model.set_logger(Logger(folder=None, output_formats=[]))
    model.learn(int(budget), callback=callback)
    log = model.episode_log if tabular else emotions.episode_log
    columns = {name: [plain(v) for v in log[name].tolist()] for name in EPISODE_COLUMNS}
    for name in EPISODE_COLUMNS:  # a value that would not read back as it is: the run fails naming it
        checked_column(name, [math.nan if v is None else v for v in columns[name]])
    if config.get("trace"):  # the TraceCallback AffectQ drove (``build_model``)
        columns.update({name: [plain(v) for v in values] for name, values in model.emotion_callback.trace_columns().items()})
    return columns, int(model.num_timesteps)


def _train_team(config: dict[str, Any], env: Any, log_dir: str | None, log_formats: tuple[str, ...]) -> Trained:
    """
    A team run. Its columns: the team's (its ``episode_log``'s, ``TEAM_COLUMNS``: ``EPISODE_COLUMNS`` for the team,
    then ``capturer``), then per hunter ``<hunter>/<column>`` for its own episode log and, for each emotion model of the
    registry (``EMOTION_MODELS``: Broekens'), ``<hunter>/<model>_<column>`` (mean intensity per decision, and
    ``broekens_goal_joy``) from its observer watching the hunter.
    """
    team = build_team(config, env)
    if log_dir is not None:
        for agent, model in team.models.items():
            Path(log_dir, agent).mkdir(parents=True, exist_ok=True)
            model.set_logger(configure(str(Path(log_dir, agent)), list(log_formats)))
    observers = {agent: {name: observer_class(name)() for name in EMOTION_MODELS} for agent in team.models}
    callbacks = {agent: [*watching.values()] for agent, watching in observers.items()}
    team.learn(int(config["episodes"]), callbacks={a: c[0] if len(c) == 1 else CallbackList(c) for a, c in callbacks.items()})
    log = team.episode_log
    columns = {name: [plain(v) for v in log[name].tolist()] for name in log.columns}
    for agent, model in team.models.items():
        own = model.episode_log
        for name in EPISODE_COLUMNS:
            columns[f"{agent}/{name}"] = [plain(v) for v in own[name].tolist()]
        for model, observer in observers[agent].items():
            felt = observer.episode_log
            for name in EMOTION_MODELS[model].columns:
                columns[f"{agent}/{model}_{name}"] = [plain(v) for v in felt[name].tolist()]
    return columns, int(sum(m.num_timesteps for m in team.models.values()))
