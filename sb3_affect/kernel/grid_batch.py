"""
Many fresh runs of one agent in one kernel call (``sb3_affect.engine.simulation.simulate`` on the compiled engine).

Each run starts as a new model does: the Q-table at ``q_init``, ``random.Random(seed)``'s state (seeded inside the
kernel by the same ``init_by_array``), an empty known map and power fit, the env at its start. No SB3 model is built
per run, so a batch of thousands of runs costs one call.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from sb3_affect.kernel import grid_arrays, grid_loop, state_layout
from sb3_affect.kernel.grid_inputs import BatchInputs
from sb3_affect.kernel.mt19937 import STATE_SIZE, seed_keys, seed_state

if TYPE_CHECKING:
    import pandas as pd


@njit(cache=True)
def run_seeds(seeds, env, config, behaviour, episodes, n_episodes):
    """
    Run ``n_episodes`` episodes from scratch for each of ``seeds`` (``grid_arrays.Seeds``); rows of run ``r`` go to
    ``episodes.rows_*[r * n_episodes ...]``, each run's episode ``j`` with ``episodes.alpha[j]``, ``episodes.p[j]``.
    The arrays of a run are allocated once and reset for each run (the known map's ``pred`` needs no reset: only its
    first ``pred_n[v]`` entries are read).
    """
    n_states = env.trans.shape[0]
    n_actions = config.n_actions
    state = grid_arrays.RunState(
        np.empty((n_states, n_actions)),
        np.empty(STATE_SIZE, dtype=np.int64),
        np.empty(state_layout.N_IST, dtype=np.int64),
        np.empty(state_layout.N_FST),
        np.empty((n_states, n_actions), dtype=np.int64),
        np.empty(n_states, dtype=np.int64),
    )
    appraisal = grid_arrays.Appraisal(
        np.empty(n_states),
        np.empty((n_states, n_actions), dtype=np.bool_),
        np.zeros((n_states, env.max_pred), dtype=np.int64),
        np.empty(n_states, dtype=np.int64),
        np.empty(n_states, dtype=np.bool_),
        np.zeros(n_episodes),
    )
    work = grid_arrays.work_space(n_states, n_actions)
    ist, fst = state.ist, state.fst
    total_timesteps = n_episodes * config.agent.cap
    for r in range(seeds.keys.shape[0]):
        state.q[:] = config.agent.q_init
        seed_state(state.mt, seeds.keys[r], seeds.lengths[r])
        ist[:] = 0
        ist[state_layout.I_STATE] = config.start
        ist[state_layout.I_CHANGED] = 1
        ist[state_layout.I_GREEDY] = -1
        fst[:] = 0.0
        fst[state_layout.S_NORM] = math.nan
        fst[state_layout.S_LAST_ACT] = math.inf
        appraisal.dist[:] = math.inf
        appraisal.edge[:] = False
        appraisal.pred_n[:] = 0
        appraisal.goal[:] = False
        state.ucb_n[:] = 0
        state.ucb_tot[:] = 0
        work.seen[:] = 0
        lo, hi = r * n_episodes, (r + 1) * n_episodes
        rows = grid_arrays.Episodes(episodes.alpha, episodes.p, episodes.rows_i[lo:hi], episodes.rows_f[lo:hi])
        grid_loop.decision_loop(env, config, behaviour, state, appraisal, rows, work, total_timesteps, n_episodes)


def simulate_batch(inputs: BatchInputs, seeds: Sequence[int], episodes: int) -> pd.DataFrame:
    """
    The episode rows of fresh runs of one agent on one env for each seed.

    :param inputs: the agent and the env as the kernel runs them (``kernel.grid_inputs.batch_inputs`` of a freshly built
        model whose ``batch_reason`` is None, or ``kernel.grid_inputs.settings_inputs``), for ``episodes`` episodes
    :param seeds: one run per seed
    :param episodes: episodes per run
    :return: the rows, columns ``sb3_affect.engine.simulation.SIMULATE_COLUMNS``
    """
    import pandas as pd

    return pd.DataFrame(batch_columns(inputs, seeds, episodes), copy=False)  # (the columns are fresh arrays)


def run_batch(
    inputs: BatchInputs, keys: np.ndarray, lengths: np.ndarray, episodes: int, out_i: np.ndarray, out_f: np.ndarray
) -> None:
    """The kernel call of ``batch_columns``: ``episodes`` episodes of a fresh run per key into the rows ``out_i``,
    ``out_f`` (run ``r``'s from row ``r * episodes``)."""
    rows = grid_arrays.Episodes(inputs.alpha, inputs.p, out_i, out_f)
    run_seeds(grid_arrays.Seeds(keys, lengths), inputs.table.env, inputs.config, inputs.agent.behaviour, rows, episodes)


def batch_columns(inputs: BatchInputs, seeds: Sequence[int], episodes: int) -> dict[str, np.ndarray]:
    """
    ``simulate_batch``'s table as ``{column: array}`` (the dtypes of ``episode_log``), without pandas. The columns
    are rows of one transposed copy of the kernel's output (contiguous; ``simulate_batch`` hands them to pandas
    without copying or merging them into blocks by dtype, which would copy every column once more).
    """
    keys, lengths = seed_keys(seeds)
    n_rows = len(seeds) * episodes
    out_i = np.zeros((n_rows, state_layout.N_OUT_I), dtype=np.int64)
    out_f = np.zeros((n_rows, 2))
    run_batch(inputs, keys, lengths, episodes, out_i, out_f)
    seed_column = np.repeat(np.asarray([int(s) for s in seeds], dtype=np.int64), episodes)
    col_i = np.ascontiguousarray(out_i.T)
    col_f = np.ascontiguousarray(out_f.T)
    return {
        "seed": seed_column,
        "episode": np.tile(np.arange(1, episodes + 1, dtype=np.int64), len(seeds)),
        "decisions": col_i[state_layout.O_DECISIONS],
        "cells": col_i[state_layout.O_CELLS],
        "reward": col_f[0],
        "optimal": col_i[state_layout.O_OPTIMAL].astype(bool),
        "truncated": col_i[state_layout.O_TRUNCATED].astype(bool),
        "random_moves": col_i[state_layout.O_RANDOM].astype(np.float64),
        "waits": col_i[state_layout.O_WAITS],
        "joy": col_i[state_layout.O_JOY],
        "sadness": col_i[state_layout.O_SADNESS],
        "fear": col_i[state_layout.O_FEAR],
        "anger": col_i[state_layout.O_ANGER],
        "greedy_optimal": col_i[state_layout.O_GREEDY].astype(bool),
        "norm": col_f[1],
    }


def warm_up() -> None:
    """Call ``run_seeds`` and ``grid_loop.run`` once on a 3 x 3 grid, with the argument types the engines use."""
    from sb3_affect.core.settings import AffectQSettings
    from sb3_affect.envs.grid_pursuit import GridPursuitEnv
    from sb3_affect.kernel.agent_settings import KernelAgent, kernel_agent
    from sb3_affect.kernel.grid_inputs import TableArrays, kernel_config

    env = GridPursuitEnv(size=3, goal=(2, 2))
    table = TableArrays.of(env)
    agent = kernel_agent(AffectQSettings(max_episode_decisions=50))
    assert isinstance(agent, KernelAgent), agent
    config = kernel_config(agent, table, 0)
    alpha, p = np.ones(1), np.zeros(1)
    out_i, out_f = np.zeros((1, state_layout.N_OUT_I), dtype=np.int64), np.zeros((1, state_layout.N_OUT_F))
    keys, lengths = np.zeros((1, 1), dtype=np.int64), np.ones(1, dtype=np.int64)
    rows = grid_arrays.Episodes(alpha, p, out_i, out_f)
    run_seeds(grid_arrays.Seeds(keys, lengths), table.env, config, agent.behaviour, rows, 1)
    mt = np.zeros(STATE_SIZE, dtype=np.int64)
    seed_state(mt, keys[0], 1)
    ist = np.zeros(state_layout.N_IST, dtype=np.int64)
    ist[state_layout.I_GREEDY] = -1
    fst = np.zeros(state_layout.N_FST)
    fst[state_layout.S_NORM] = np.nan
    state = grid_arrays.RunState(np.zeros((9, 4)), mt, ist, fst, np.zeros((9, 4), dtype=np.int64), np.zeros(9, dtype=np.int64))
    appraisal = grid_arrays.Appraisal(
        np.full(9, np.inf),
        np.zeros((9, 4), dtype=np.bool_),
        np.zeros((9, 2), dtype=np.int64),
        np.zeros(9, dtype=np.int64),
        np.zeros(9, dtype=np.bool_),
        np.zeros(4),
    )
    grid_loop.run(table.env, config, agent.behaviour, state, appraisal, grid_arrays.Episodes(alpha, p, out_i, out_f), 50, 1)
