"""
The issue-7 comparison as plain run configs (the launcher's format, ``docs/interfaces.md``), and a small in-process
executor for them, so the comparison can run with or without the launcher (``sb3_affect.experiments``).

``experiments/baselines.yaml`` describes the same runs for the launcher; ``experiments/baselines_run.py`` runs these
configs directly with a process pool and writes one JSON per run in the launcher's run-file format.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
import platform
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: Seeds of the reported runs, and separate seeds for tuning (best fixed epsilon, temperature, UCB coefficient).
REPORT_SEEDS = range(20)
TUNING_SEEDS = range(10_000, 10_010)

STATIC: dict[str, Any] = {"env_id": "sb3_affect/GridPursuit-v0", "env_kwargs": {}}
MOVING: dict[str, Any] = {"env_id": "sb3_affect/MovingPursuit-v0", "env_kwargs": {"prey": "random", "prey_speed": 0.5}}
MOVING_SMALL: dict[str, Any] = {
    "env_id": "sb3_affect/MovingPursuit-v0",
    "env_kwargs": {"size": 7, "start": [0, 0], "prey_start": [3, 3], "prey": "random", "prey_speed": 0.5},
}
TASKS: dict[str, tuple[dict[str, Any], int]] = {
    "static": (STATIC, 200),
    "moving": (MOVING, 200),
    "moving-7x7": (MOVING_SMALL, 200),
}

#: Tuning grids (static task, TUNING_SEEDS, criterion: mean decisions per episode).
TUNING = {
    "epsilon-greedy-best": ("QLearning", "exploration_rate", [0.01, 0.05, 0.1, 0.2, 0.3, 0.5]),
    "boltzmann": ("sb3_affect.baselines:Boltzmann", "temperature", [0.1, 0.3, 1.0, 3.0, 10.0]),
    "ucb": ("sb3_affect.baselines:UCBQLearning", "exploration_coef", [0.1, 1.0, 10.0, 100.0]),
}

#: Values chosen by the tuning runs (``experiments/baselines_run.py --tune``); see docs/beyond_the_paper.md.
TUNED: dict[str, float] = {"epsilon-greedy-best": 0.01, "boltzmann": 1.0, "ucb": 1.0}


def agents(tuned: dict[str, float] | None = None) -> dict[str, tuple[str, dict[str, Any]]]:
    """Agent name -> (algo, algo_kwargs) of the comparison."""
    t = {**TUNED, **(tuned or {})}
    return {
        "affective": ("AffectQ", {}),
        "affective-optimistic": ("AffectQ", {"personality": "optimistic"}),
        "affective-pessimistic": ("AffectQ", {"personality": "pessimistic"}),
        "epsilon-greedy-best": ("QLearning", {"exploration_rate": t["epsilon-greedy-best"]}),
        "epsilon-decay": ("sb3_affect.baselines:DecayingEpsilonGreedy", {}),
        "boltzmann": ("sb3_affect.baselines:Boltzmann", {"temperature": t["boltzmann"]}),
        "boltzmann-decay": (
            "sb3_affect.baselines:Boltzmann",
            {"temperature": 10.0, "temperature_final": 0.1, "temperature_decay_episodes": 100},
        ),
        "ucb": ("sb3_affect.baselines:UCBQLearning", {"exploration_coef": t["ucb"]}),
        "optimistic-q100": ("sb3_affect.baselines:OptimisticQLearning", {"q_init": 100.0}),
        "optimistic-q1": ("sb3_affect.baselines:OptimisticQLearning", {"q_init": 1.0}),
        "speed-epsilon-greedy": ("sb3_affect.baselines:SpeedEpsilonGreedy", {"exploration_rate": t["epsilon-greedy-best"]}),
    }


def _config(sweep: str, agent: str, algo: str, kwargs: dict[str, Any], task: str, seed: int, **labels: Any) -> dict[str, Any]:
    env, episodes = TASKS[task]
    return {
        "sweep": sweep,
        "agent": agent,
        "algo": algo,
        "algo_kwargs": dict(kwargs),
        "env_id": env["env_id"],
        "env_kwargs": dict(env["env_kwargs"]),
        "seed": seed,
        "episodes": episodes,
        "max_timesteps": None,
        "labels": {"task": task, **labels},
    }


def tuning_configs() -> Iterator[dict[str, Any]]:
    """The tuning runs: each grid value on the static task with TUNING_SEEDS."""
    for agent, (algo, key, values) in TUNING.items():
        for value in values:
            for seed in TUNING_SEEDS:
                yield _config("baselines-tuning", agent, algo, {key: value}, "static", seed, **{key: value})


def report_configs(
    tasks: tuple[str, ...] = ("static", "moving", "moving-7x7"),
    seeds: range = REPORT_SEEDS,
    tuned: dict[str, float] | None = None,
    paper_epsilon_seeds: int = 5,
) -> Iterator[dict[str, Any]]:
    """The reported runs: every agent on every task, plus the paper's epsilon-greedy pooled over epsilon 0.1..0.9."""
    for task in tasks:
        for agent, (algo, kwargs) in agents(tuned).items():
            for seed in seeds:
                yield _config("baselines", agent, algo, kwargs, task, seed)
        for i in range(1, 10):
            epsilon = round(i / 10, 1)
            for seed in seeds[:paper_epsilon_seeds]:
                yield _config(
                    "baselines",
                    "epsilon-greedy-paper",
                    "QLearning",
                    {"exploration_rate": epsilon},
                    task,
                    seed + 1000 * i,
                    epsilon=epsilon,
                )


def load_algo(algo: str) -> Any:
    """``"QLearning"``, ``"AffectQ"`` or ``"package.module:Class"`` -> the class."""
    if ":" in algo:
        module, name = algo.split(":", 1)
        return getattr(importlib.import_module(module), name)
    import sb3_affect

    return getattr(sb3_affect, algo)


def run_id(config: dict[str, Any]) -> str:
    digest = hashlib.sha1(json.dumps(config, sort_keys=True).encode()).hexdigest()[:10]
    return f"{config['labels'].get('task', 'run')}-{config['agent']}-s{config['seed']}-{digest}"


def execute(config: dict[str, Any]) -> dict[str, Any]:
    """Run one config in this process; returns the run record (the launcher's run-file format)."""
    import gymnasium as gym
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

    import sb3_affect

    start = time.perf_counter()
    env = gym.make(config["env_id"], **config["env_kwargs"])
    model = load_algo(config["algo"])("Grid", env, seed=config["seed"], **config["algo_kwargs"])
    model.learn(config["max_timesteps"] or 10**12, callback=StopTrainingOnMaxEpisodes(config["episodes"]))
    log = model.episode_log
    episodes = {c: [None if isinstance(v, float) and math.isnan(v) else v for v in log[c].tolist()] for c in log.columns}
    return {
        "schema": 1,
        "run_id": run_id(config),
        "config": config,
        "status": "ok",
        "episodes": episodes,
        "timings": {"wall_seconds": time.perf_counter() - start},
        "versions": {"python": platform.python_version(), "sb3_affect": sb3_affect.__version__},
    }


def execute_to(config: dict[str, Any], out: str) -> str:
    """Run a config and write ``out/runs/<run_id>.json`` (skipped if it exists); returns the path."""
    path = Path(out) / "runs" / f"{run_id(config)}.json"
    if not path.exists():
        record = execute(config)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(record))
        tmp.replace(path)
    return str(path)
