"""Execute one run config (plain data) in whatever process it lands in: build the env, train, return the records."""

from __future__ import annotations

import difflib
import functools
import importlib
import inspect
import json
import math
import multiprocessing
import os
import platform
import re
import signal
import socket
import sys
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import gymnasium as gym

import sb3_affect
from sb3_affect.core.episode_log import EPISODE_COLUMNS
from sb3_affect.core.positions import make_position
from sb3_affect.core.registry import (
    EMOTION_MODELS,
    import_env_package,
    known_settings,
    observer_class,
    resolve_class,
    resolve_wrapper,
)
from sb3_affect.core.settings import AffectQSettings
from sb3_affect.envs import PARALLEL_ENVS, make_parallel
from sb3_affect.study.launcher.chunks import checked_column


def _version(name: str) -> str:
    """A package's version: its ``__version__`` if it is imported, else its installed metadata (no import: torch)."""
    module = sys.modules.get(name)
    if module is not None and hasattr(module, "__version__"):
        return str(module.__version__)

    try:
        return version(name)
    except PackageNotFoundError:
        return str(importlib.import_module(name).__version__)


@functools.cache
def _package_versions() -> tuple[tuple[str, str], ...]:
    return (
        ("python", platform.python_version()),
        ("sb3_affect", sb3_affect.__version__),
        ("stable_baselines3", _version("stable_baselines3")),
        ("gymnasium", _version("gymnasium")),
        ("torch", _version("torch")),
        ("numpy", _version("numpy")),
    )


def package_versions() -> dict[str, str]:
    """The versions a run records (Python, sb3-affect, SB3, Gymnasium, PyTorch, NumPy); read once per process."""
    return dict(_package_versions())


def _plain(value: Any) -> Any:
    """A JSON-safe, deterministic Python value (NaN -> None, numpy scalars -> Python)."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and math.isnan(value):
        return None
    return value


def build_team(config: dict[str, Any]) -> Any:
    """The ``HunterTeam`` of a team run config (a multi-agent env and one tabular agent per hunter)."""
    from sb3_affect.agents.hunter_team import HunterTeam  # (torch: off the tabular sweep path)

    env = make_parallel(config["env_id"], **config["env_kwargs"])
    return HunterTeam(env, [(m["algo"], m["kwargs"]) for m in config["team"]], seed=config["seed"])


def _make_env(config: dict[str, Any]) -> Any:
    if config["env_id"] in PARALLEL_ENVS:
        return make_parallel(config["env_id"], **config["env_kwargs"])
    return make_single_env(config)


def make_single_env(config: dict[str, Any]) -> Any:
    """
    The single-agent env of a run config: ``gym.make`` of its id (after importing the package the registry says
    registers it: ``MiniGrid-*``), inside the wrappers it names (``env_wrappers``, the registry's ``ENV_WRAPPERS``).
    """
    import_env_package(config["env_id"])
    env = gym.make(config["env_id"], **config["env_kwargs"])
    for name in config.get("env_wrappers", ()):
        env = resolve_wrapper(name)(env)
    return env


#: The seeds the env of a sweep is reset with when the sweep is checked: an env that draws its layout at random
#: (MiniGrid's Fetch: keys or balls) shows what its runs will meet, whatever a first reset happens to draw.
CHECK_RESETS = 16


def _check_single_env(env: Any, position: str | None) -> None:
    """
    Reset a run's env (its wrappers and all) with each of ``CHECK_RESETS`` seeds and take one step after each, and
    read its ``position`` preset once: a wrapper, an env or a preset that can not work on it fails here, before
    anything runs, rather than in every run.
    """
    for seed in range(CHECK_RESETS):
        env.reset(seed=seed)
        env.action_space.seed(seed)
        env.step(env.action_space.sample())
    if position is not None:
        from stable_baselines3.common.vec_env import DummyVecEnv  # (torch: off the tabular sweep path)

        venv = DummyVecEnv([lambda: env])
        hook = make_position(position, venv.observation_space)
        if hook is not None:
            hook.bind(venv, venv.observation_space)
            hook.cells(venv, venv.reset(), [{}])


def build_model(config: dict[str, Any]) -> tuple[Any, bool]:
    """The env and the algorithm of a run config: ``(model, tabular)`` (``tabular``: keeps its own ``episode_log``)."""
    from sb3_affect.agents.tabular import TabularQAlgorithm  # (torch: off the tabular sweep path)

    cls: Any = resolve_class(config["algo"])
    env = make_single_env(config)
    kwargs = dict(config["algo_kwargs"])
    if issubclass(cls, TabularQAlgorithm):
        if config.get("trace"):
            kwargs["emotion_callback"] = _trace_callback(kwargs)
        return cls("Grid", env, seed=config["seed"], **kwargs), True
    policy = kwargs.pop("policy", "MlpPolicy")
    return cls(policy, env, seed=config["seed"], **kwargs), False


def _trace_callback(kwargs: dict[str, Any]) -> Any:
    """The ``TraceCallback`` a traced AffectQ run drives, reading as its kwargs say (``launcher.emotion_trace``)."""
    from sb3_affect.study.launcher.emotion_trace import TraceCallback  # (torch: off the tabular sweep path)

    settings = AffectQSettings(**kwargs)
    return TraceCallback(comparison=settings.comparison, act=settings.act, units=settings.units)


def package_env(env_id: str) -> bool:
    """
    Whether ``env_id`` is one of the package's single-agent envs (``sb3_affect/...``, not a multi-agent one; never a
    ``module:Env`` id, which Gymnasium would import).
    """
    return isinstance(env_id, str) and env_id.startswith("sb3_affect/") and ":" not in env_id and env_id not in PARALLEL_ENVS


def settings_checkable(config: dict[str, Any]) -> bool:
    """
    Whether ``check_configs`` can check a config without building its model (so without torch): one of the package's
    agents, given settings only (``sb3_affect.core.settings``), on one of its single-agent grid envs.
    """
    if "team" in config or config.get("env_position") is not None or not package_env(config["env_id"]):
        return False  # (a position preset is read through SB3's VecEnv: checked in the child)
    settings = known_settings(config["algo"])
    return settings is not None and set(config["algo_kwargs"]) <= set(settings.names())


def check_configs(configs: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """
    Build the env and the algorithm of each distinct (agent, env, kwargs) once, without training. The package's
    agents given settings only are checked by their settings (``settings_checkable``: the constructor's own checks,
    no model built).

    :return: ``(agent name, problem)`` for each config that can not be built (an unknown or impossible kwarg); the
        agent name is empty when the env itself can not be built
    """
    problems: list[tuple[str, str]] = []
    env_checked: set[str] = set()
    seen: set[str] = set()
    failed_agents: set[str] = set()  # one problem per agent, not one per grid point
    for config in configs:
        if config["agent"] in failed_agents:
            continue
        env_key = json.dumps(
            [config["env_id"], config["env_kwargs"], config.get("env_wrappers"), config.get("env_position")], sort_keys=True
        )
        if env_key not in env_checked:
            env_checked.add(env_key)
            try:
                env = _make_env(config)
                try:
                    if config["env_id"] not in PARALLEL_ENVS:
                        _check_single_env(env, config.get("env_position"))
                finally:
                    env.close()
            except Exception as error:
                problems.append(("", f"the env can not be built and stepped: {type(error).__name__}: {error}"))
                return problems
        key = json.dumps([config["agent"], config["algo"], config["algo_kwargs"], config.get("team")], sort_keys=True)
        if key in seen:
            continue
        seen.add(key)
        try:
            if "team" in config:
                build_team(config).env.close()
            elif settings_checkable(config):
                settings = known_settings(config["algo"])
                assert settings is not None
                settings(**config["algo_kwargs"])
            else:
                model, _ = build_model(config)
                model.get_env().close()
        except Exception as error:
            labels = {k: v for k, v in config["labels"].items() if k != "replicate"}
            where = f" at {labels}" if labels else ""
            hint = _kwarg_hint(config, error)
            failed_agents.add(config["agent"])
            problems.append(
                (config["agent"], f"{config['algo']} can not be built{where}: {type(error).__name__}: {error}{hint}")
            )
    return problems


def _kwarg_hint(config: dict[str, Any], error: Exception) -> str:
    """For an unknown keyword argument: ``; did you mean 'gamma'?`` (the closest argument of the class), else ''."""
    match = re.search(r"unexpected keyword argument '([^']+)'", str(error))
    if not isinstance(error, TypeError) or match is None or "team" in config:
        return ""

    try:
        parameters = list(inspect.signature(resolve_class(config["algo"])).parameters)
    except (ValueError, TypeError):
        return ""
    close = difflib.get_close_matches(match.group(1), [p for p in parameters if not p.startswith("_")], n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


def check_configs_in_child(configs: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """
    ``check_configs`` in a short-lived forked process (where fork exists), so that the launcher itself never runs
    torch operations before it forks its workers (an OpenMP pool used before ``fork`` can hang the children). When
    no config needs a model (``settings_checkable``), here: nothing imports torch.
    """
    if all(settings_checkable(config) for config in configs):
        return check_configs(configs)
    if "fork" not in multiprocessing.get_all_start_methods():  # pragma: no cover - not Linux/macOS
        return check_configs(configs)
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)
    process = context.Process(target=_check_child, args=(configs, sender), name="sb3-affect:check")
    process.start()
    sender.close()
    try:
        problems: list[tuple[str, str]] = receiver.recv()
    except EOFError:
        problems = [("", f"the check of the agents died before answering (exit code {process.exitcode})")]
    finally:
        receiver.close()
        process.join(timeout=30)
        if process.is_alive():  # pragma: no cover
            process.kill()
            process.join()
    return problems


def _check_child(configs: list[dict[str, Any]], conn: Any) -> None:
    import torch as th  # (torch: off the tabular sweep path)

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    th.set_num_threads(1)
    try:
        problems = check_configs(configs)
    except BaseException as error:  # pragma: no cover - check_configs catches per config
        problems = [("", f"{type(error).__name__}: {error}")]
    conn.send(problems)
    conn.close()


def execute_run(config: dict[str, Any], log_dir: str | None = None, log_formats: tuple[str, ...] = ("csv",)) -> dict[str, Any]:
    """
    Train one agent as ``config`` says and return ``{"episodes": {column: [...]}, "timings": ..., "versions": ...}``.

    Tabular agents of this package keep their own ``episode_log``; any other SB3 algorithm is watched by an
    ``EmotionCallback``. Training stops after ``config["episodes"]`` episodes (``StopTrainingOnMaxEpisodes``) or
    ``config["max_timesteps"]`` decisions, whichever comes first.
    """
    start = time.perf_counter()
    if "team" in config and log_dir is None:
        record = _execute_team_compiled(config, start)
        if record is not None:
            return record
    import torch as th  # (torch: off the tabular sweep path)

    th.set_num_threads(1)
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes  # (torch: off the tabular sweep path)
    from stable_baselines3.common.logger import Logger, configure  # (torch: off the tabular sweep path)

    from sb3_affect.agents.callbacks import EmotionCallback  # (torch: off the tabular sweep path)

    if "team" in config:
        return _execute_team(config, log_dir, log_formats, start)
    model, tabular = build_model(config)
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
    columns = {name: [_plain(v) for v in log[name].tolist()] for name in EPISODE_COLUMNS}
    for name in EPISODE_COLUMNS:  # a value that would not read back as it is: the run fails naming it
        checked_column(name, [math.nan if v is None else v for v in columns[name]])
    if config.get("trace"):  # the TraceCallback AffectQ drove (``build_model``)
        columns.update({name: [_plain(v) for v in values] for name, values in model.emotion_callback.trace_columns().items()})
    return {
        "episodes": columns,
        "timings": {
            "wall_seconds": round(time.perf_counter() - start, 4),
            "decisions": int(model.num_timesteps),
            "pid": os.getpid(),
            "host": socket.gethostname(),
        },
        "versions": package_versions(),
    }


def _execute_team_compiled(config: dict[str, Any], start: float) -> dict[str, Any] | None:
    """
    A team run on the team kernel (``sb3_affect.engine.team_simulation``), without building a model (no torch): the
    same record as ``_execute_team`` gives. None when the kernel can not run it (an agent or argument the kernel does
    not know, a member's ``engine="python"``, a schedule of the training progress).
    """
    from sb3_affect.engine.team_simulation import simulate_team  # (numba: only where a kernel runs)

    members = [(m["algo"], m["kwargs"]) for m in config["team"]]
    run = simulate_team(members, config["env_id"], config["env_kwargs"], int(config["seed"]), int(config["episodes"]))
    if run is None:
        return None
    return {
        "episodes": run.columns,
        "timings": {
            "wall_seconds": round(time.perf_counter() - start, 4),
            "decisions": run.decisions,
            "pid": os.getpid(),
            "host": socket.gethostname(),
        },
        "versions": package_versions(),
    }


def _execute_team(config: dict[str, Any], log_dir: str | None, log_formats: tuple[str, ...], start: float) -> dict[str, Any]:
    """
    A team run. Its ``episodes`` columns: the team's (``TEAM_COLUMNS``: ``EPISODE_COLUMNS`` for the team, then
    ``capturer``), then per hunter ``<hunter>/<column>`` for its own episode log and, for each emotion model of the
    registry (``EMOTION_MODELS``: Broekens'), ``<hunter>/<model>_<column>`` (mean intensity per decision, and
    ``broekens_goal_joy``) from its observer watching the hunter.
    """
    from stable_baselines3.common.callbacks import CallbackList  # (torch: off the tabular sweep path)
    from stable_baselines3.common.logger import configure  # (torch: off the tabular sweep path)

    from sb3_affect.agents.hunter_team import TEAM_COLUMNS  # (torch: off the tabular sweep path)

    team = build_team(config)
    if log_dir is not None:
        for agent, model in team.models.items():
            Path(log_dir, agent).mkdir(parents=True, exist_ok=True)
            model.set_logger(configure(str(Path(log_dir, agent)), list(log_formats)))
    observers = {agent: {name: observer_class(name)() for name in EMOTION_MODELS} for agent in team.models}
    callbacks = {agent: [*watching.values()] for agent, watching in observers.items()}
    team.learn(int(config["episodes"]), callbacks={a: c[0] if len(c) == 1 else CallbackList(c) for a, c in callbacks.items()})
    log = team.episode_log
    columns = {name: [_plain(v) for v in log[name].tolist()] for name in TEAM_COLUMNS}
    for agent, model in team.models.items():
        own = model.episode_log
        for name in EPISODE_COLUMNS:
            columns[f"{agent}/{name}"] = [_plain(v) for v in own[name].tolist()]
        for model, observer in observers[agent].items():
            felt = observer.episode_log
            for name in EMOTION_MODELS[model].columns:
                columns[f"{agent}/{model}_{name}"] = [_plain(v) for v in felt[name].tolist()]
    return {
        "episodes": columns,
        "timings": {
            "wall_seconds": round(time.perf_counter() - start, 4),
            "decisions": int(sum(m.num_timesteps for m in team.models.values())),
            "pid": os.getpid(),
            "host": socket.gethostname(),
        },
        "versions": package_versions(),
    }
