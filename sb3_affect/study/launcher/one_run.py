"""
Execute one run config (plain data) in whatever process it lands in: build the env, train, return the records; and
check a sweep's configs before anything runs. What needs an SB3 model (torch) is in ``model_runs``, imported only
where a run or a check builds one.
"""

from __future__ import annotations

import difflib
import functools
import importlib
import inspect
import json
import multiprocessing
import os
import platform
import re
import signal
import socket
import sys
import time
from collections.abc import Callable
from importlib.metadata import PackageNotFoundError, version
from typing import Any

import gymnasium as gym

import sb3_affect
from sb3_affect.core.registry import import_env_package, known_settings, resolve_class, resolve_wrapper
from sb3_affect.envs import PARALLEL_ENVS, make_parallel


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


def _check_single_env(env: Any, position: str | None, check_position: Callable[[Any, str], None] | None) -> None:
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
        assert check_position is not None  # (``check_configs`` passes it where a config has a position)
        check_position(env, position)


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
    no model built); any other config, and a position preset, by building SB3's objects (``model_runs``: torch).

    :return: ``(agent name, problem)`` for each config that can not be built (an unknown or impossible kwarg); the
        agent name is empty when the env itself can not be built
    """
    if all(settings_checkable(config) for config in configs):
        return _checked(configs, None, None)
    from sb3_affect.study.launcher import model_runs  # (torch: only where a config builds a model)

    return _checked(configs, model_runs.check_position, model_runs.check_model)


def _checked(
    configs: list[dict[str, Any]],
    check_position: Callable[[Any, str], None] | None,
    check_model: Callable[[dict[str, Any], Any], None] | None,
) -> list[tuple[str, str]]:
    """``check_configs`` with the checks that build SB3's objects (None: every config is ``settings_checkable``)."""
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
                        _check_single_env(env, config.get("env_position"), check_position)
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
            if settings_checkable(config):
                settings = known_settings(config["algo"])
                assert settings is not None
                settings(**config["algo_kwargs"])
            else:
                assert check_model is not None  # (``check_configs`` passes it where a config is not settings_checkable)
                check_model(config, _make_env(config))
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
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        problems = check_configs(configs)
    except BaseException as error:  # pragma: no cover - check_configs catches per config
        problems = [("", f"{type(error).__name__}: {error}")]
    conn.send(problems)
    conn.close()


def execute_run(config: dict[str, Any], log_dir: str | None = None, log_formats: tuple[str, ...] = ("csv",)) -> dict[str, Any]:
    """
    Run one config as it says and return ``{"episodes": {column: [...]}, "timings": ..., "versions": ...}``.

    A team run without SB3 logs runs on the team kernel (``sb3_affect.engine.team_simulation``: no model, no torch)
    when the kernel can run it; any other run builds its model and trains it (``model_runs.train``): tabular agents
    of this package keep their own ``episode_log``, any other SB3 algorithm is watched by an ``EmotionCallback``.
    """
    start = time.perf_counter()
    compiled = None
    if "team" in config and log_dir is None:  # None: an agent or argument the kernel does not know, ``engine="python"``
        from sb3_affect.engine.team_simulation import simulate_team  # (numba: only where a kernel runs)

        members = [(m["algo"], m["kwargs"]) for m in config["team"]]
        compiled = simulate_team(members, config["env_id"], config["env_kwargs"], int(config["seed"]), int(config["episodes"]))
    if compiled is not None:
        columns, decisions = compiled.columns, compiled.decisions
    else:
        from sb3_affect.study.launcher import model_runs  # (torch: off the tabular sweep path)

        columns, decisions = model_runs.train(config, _make_env(config), log_dir, log_formats)
    return {
        "episodes": columns,
        "timings": {
            "wall_seconds": round(time.perf_counter() - start, 4),
            "decisions": int(decisions),
            "pid": os.getpid(),
            "host": socket.gethostname(),
        },
        "versions": package_versions(),
    }
