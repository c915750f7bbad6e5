"""
Many fresh runs of one agent on MovingPursuit in one kernel call (``sb3_affect.engine.simulation.simulate`` on the compiled
engine; the loop is ``kernel.moving_loop``).

Each run starts as a new model does: the Q-table at ``q_init``, ``random.Random(seed)``'s state (seeded inside the
kernel), the env's NumPy generator as ``env.reset(seed=seed)`` leaves it (``np.random.Generator(PCG64(seed))``,
computed here per seed), an empty known map and power fit, hunter and prey at their starts. Nothing here imports torch
or SB3.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np

from sb3_affect.envs.grid_pursuit import PREY_MODES
from sb3_affect.kernel import moving_loop, state_layout
from sb3_affect.kernel.agent_settings import KernelAgent, kernel_agent, kernel_settings, settings_class
from sb3_affect.kernel.decision import known_widths
from sb3_affect.kernel.grid_arrays import Episodes
from sb3_affect.kernel.grid_inputs import time_limit_of, unwrap, wrapper_reason
from sb3_affect.kernel.mt19937 import seed_keys
from sb3_affect.kernel.pcg64 import STATE_SIZE as PCG_SIZE
from sb3_affect.kernel.pcg64 import seeded_state


class MovingInputs(NamedTuple):
    """Everything ``moving_columns`` needs besides the seeds: the same for every run of the batch."""

    agent: KernelAgent
    env: moving_loop.PreyEnv
    config: moving_loop.Config
    alpha: np.ndarray  # learning rate per episode
    p: np.ndarray  # exploration parameter per episode


class MovingRun(NamedTuple):
    """The rows of a batch and the state the last run left behind (its Q-table, generators and known distances)."""

    out_i: np.ndarray
    out_f: np.ndarray
    q: np.ndarray
    mt: np.ndarray
    pcg: np.ndarray
    dist: np.ndarray


def _monitor_class() -> Any:
    module = sys.modules.get("stable_baselines3.common.monitor")
    return None if module is None else module.Monitor


def moving_reason(env: Any) -> str | None:
    """Why the moving-prey kernel can not step ``env`` (None: it can): a MovingPursuit with standard wrappers only."""
    from sb3_affect.envs import MovingPursuitEnv

    base, wrappers = unwrap(env)
    if type(base) is not MovingPursuitEnv:
        return f"the env {type(base).__name__} is not MovingPursuit"
    monitor = _monitor_class()
    reason = wrapper_reason(wrappers, () if monitor is None else (monitor,))
    if reason is not None:
        return reason
    for wrapper in wrappers:
        if monitor is not None and isinstance(wrapper, monitor) and wrapper.info_keywords:
            return "the Monitor records info_keywords, which the kernel does not produce"
    return None


def _far(base: Any) -> np.ndarray:
    cached = getattr(base, "_sb3_affect_kernel_far", None)
    if cached is None:
        from sb3_affect.envs import distances_to

        cached = np.array([distances_to(h, base.cell_transitions) for h in range(base.n_cells)], dtype=np.float64)
        base._sb3_affect_kernel_far = cached
    return cached


def moving_inputs(settings: Any, env: Any, episodes: int) -> MovingInputs:
    """
    The kernel inputs of fresh runs of an agent of these ``settings`` (``sb3_affect.core.settings``: given, or the ones a
    freshly built model hands over) on ``env`` (a MovingPursuit, ``moving_reason(env)`` None).
    """
    agent = kernel_agent(settings)
    assert isinstance(agent, KernelAgent), agent
    base, wrappers = unwrap(env)
    config = moving_loop.Config(
        agent=agent.settings,
        n_cells=int(base.n_cells),
        hunter_start=int(base.hunter_start_cell),
        prey_start=int(base.prey_start_cell),
        prey=PREY_MODES.index(base.prey),
        time_limit=time_limit_of(wrappers),
        goal_reward=float(base.goal_reward),
        step_reward=float(base.step_reward),
        prey_speed=float(base.prey_speed),
        n_actions=int(env.action_space.n),
    )
    parameters = settings.episode_parameters(0, episodes)  # None: a schedule on the training progress (learn's)
    alpha, p = parameters if parameters is not None else (np.empty(0), np.empty(0))
    cell_trans = np.asarray(base.cell_transitions, dtype=np.int64)
    far = _far(base) if base.prey == "evade" else np.zeros((1, 1))
    succ_width, pred_width = known_widths(cell_trans, base.prey != "static")
    return MovingInputs(agent, moving_loop.PreyEnv(cell_trans, far, succ_width, pred_width), config, alpha, p)


def moving_settings_inputs(
    algo: str | type, kwargs: Mapping[str, Any], env_id: str, env_kwargs: Mapping[str, Any] | None, episodes: int
) -> MovingInputs | None:
    """
    ``kernel.grid_inputs.settings_inputs`` for MovingPursuit: the kernel inputs of fresh runs of ``algo`` with ``kwargs``
    without a model, or None where the model-based path must decide. Bad kwargs raise the constructor's error.
    """
    settings_cls = settings_class(algo, kwargs)
    if settings_cls is None:
        return None
    env = gym.make(env_id, **dict(env_kwargs or {}))
    try:
        if moving_reason(env) is not None:
            return None
        settings = kernel_settings(settings_cls, kwargs)
        if settings is None:
            return None
        return moving_inputs(settings, env, episodes)
    finally:
        env.close()


def run_moving(inputs: MovingInputs, seeds: Sequence[int], episodes: int) -> MovingRun:
    """Fresh runs of ``episodes`` episodes for each seed in one kernel call (``moving_loop.run_seeds``)."""
    keys, lengths = seed_keys(seeds)
    pcg_init = np.zeros((len(seeds), PCG_SIZE), dtype=np.uint64)
    for r, seed in enumerate(seeds):
        pcg_init[r] = seeded_state(int(seed))
    n_rows = len(seeds) * episodes
    out_i = np.zeros((n_rows, state_layout.N_OUT_I), dtype=np.int64)
    out_f = np.zeros((n_rows, state_layout.N_OUT_F))
    rows = Episodes(inputs.alpha, inputs.p, out_i, out_f)
    q, mt, pcg, dist = moving_loop.run_seeds(
        moving_loop.Seeds(keys, lengths, pcg_init), inputs.env, inputs.config, inputs.agent.behaviour, rows, episodes
    )
    return MovingRun(out_i, out_f, q, mt, pcg, dist)


def moving_columns(inputs: MovingInputs, seeds: Sequence[int], episodes: int) -> dict[str, np.ndarray]:
    """
    ``simulate``'s table for MovingPursuit as ``{column: array}``: the dtypes of the Python loop's episode log, with
    ``optimal`` and ``greedy_optimal`` NaN (the env has no fixed goal).
    """
    run = run_moving(inputs, seeds, episodes)
    col_i = np.ascontiguousarray(run.out_i.T)
    col_f = np.ascontiguousarray(run.out_f.T)
    n_rows = len(seeds) * episodes
    return {
        "seed": np.repeat(np.asarray([int(s) for s in seeds], dtype=np.int64), episodes),
        "episode": np.tile(np.arange(1, episodes + 1, dtype=np.int64), len(seeds)),
        "decisions": col_i[state_layout.O_DECISIONS],
        "cells": col_i[state_layout.O_CELLS],
        "reward": col_f[0],
        "optimal": np.full(n_rows, np.nan),
        "truncated": col_i[state_layout.O_TRUNCATED].astype(bool),
        "random_moves": col_i[state_layout.O_RANDOM].astype(np.float64),
        "waits": col_i[state_layout.O_WAITS],
        "joy": col_i[state_layout.O_JOY],
        "sadness": col_i[state_layout.O_SADNESS],
        "fear": col_i[state_layout.O_FEAR],
        "anger": col_i[state_layout.O_ANGER],
        "greedy_optimal": np.full(n_rows, np.nan),
        "norm": col_f[1],
    }


def moving_batch_reason(model: Any) -> str | None:
    """Why ``simulate`` can not run a freshly built ``model`` on MovingPursuit as one kernel batch (None: it can)."""
    reason = moving_reason(model.single_env())
    if reason is not None:
        return reason
    settings = model.compiled_settings()
    if isinstance(settings, str):
        return settings
    agent = kernel_agent(settings)
    if isinstance(agent, str):
        return agent
    if settings.episode_parameters(0, 1) is None:
        return "a schedule depends on the training progress, which only the Python side evaluates (one episode at a time)"
    return None


def warm_up() -> None:
    """Load (the first time on a machine: compile) the moving-prey kernel, on a 3 x 3 grid with an evading prey."""
    from sb3_affect.core.settings import AffectQSettings
    from sb3_affect.envs.moving_pursuit import MovingPursuitEnv

    env = MovingPursuitEnv(size=3, start=(0, 0), prey_start=(2, 2), prey="evade")
    run_moving(moving_inputs(AffectQSettings(max_episode_decisions=20), env, 1), [0], 1)
