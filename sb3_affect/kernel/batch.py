"""
Many fresh runs of one agent in one kernel call (``sb3_affect.engine.simulate`` on the compiled engine).

Each run starts as a new model does: the Q-table at ``q_init``, ``random.Random(seed)``'s state (seeded inside the
kernel by the same ``init_by_array``), an empty known map and power fit, the env at its start. No SB3 model is built
per run, so a batch of thousands of runs costs one call.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit

from sb3_affect.kernel import loop
from sb3_affect.kernel.agents import episode_schedule
from sb3_affect.kernel.inputs import BatchInputs
from sb3_affect.kernel.mt19937 import STATE_SIZE, TW_SIZE, seed_key, seed_state

if TYPE_CHECKING:
    import pandas as pd


@njit(cache=True)
def run_seeds(
    keys, key_lengths, q_init, n_actions, trans, tdist, icfg, fcfg, beh_rand, beh_speeds, beh_n, max_pred,
    alpha_e, p_e, episodes, total_timesteps, out_i, out_f,
):  # fmt: skip
    """
    Run ``episodes`` episodes from scratch for each seed key; rows of run ``r`` go to ``out[r * episodes ...]``.
    The arrays of a run are allocated once and reset for each run (the known map's ``pred`` needs no reset: only its
    first ``pred_n[v]`` entries are read).
    """
    n_states = trans.shape[0]
    q = np.empty((n_states, n_actions))
    mt = np.empty(STATE_SIZE, dtype=np.int64)
    ist = np.empty(loop.N_IST, dtype=np.int64)
    fst = np.empty(loop.N_FST)
    dist = np.empty(n_states)
    edge = np.empty((n_states, n_actions), dtype=np.bool_)
    pred = np.zeros((n_states, max_pred), dtype=np.int64)
    pred_n = np.empty(n_states, dtype=np.int64)
    goal = np.empty(n_states, dtype=np.bool_)
    fit_vals = np.zeros(episodes)
    ucb_n = np.empty((n_states, n_actions), dtype=np.int64)
    ucb_tot = np.empty(n_states, dtype=np.int64)
    work = np.empty(n_actions)
    seen = np.zeros(n_states, dtype=np.int64)
    stack = np.empty(n_states * n_actions + 1, dtype=np.int64)
    queue = np.empty(n_states + 1, dtype=np.int64)
    tw = np.empty(TW_SIZE, dtype=np.int64)
    for r in range(keys.shape[0]):
        q[:] = q_init
        seed_state(mt, keys[r], key_lengths[r])
        ist[:] = 0
        ist[loop.I_STATE] = icfg[loop.C_START]
        ist[loop.I_CHANGED] = 1
        ist[loop.I_GREEDY] = -1
        fst[:] = 0.0
        fst[loop.S_NORM] = math.nan
        fst[loop.S_LAST_ACT] = math.inf
        dist[:] = math.inf
        edge[:] = False
        pred_n[:] = 0
        goal[:] = False
        ucb_n[:] = 0
        ucb_tot[:] = 0
        seen[:] = 0
        lo, hi = r * episodes, (r + 1) * episodes
        loop.decision_loop(
            icfg[loop.C_KIND], q, trans, tdist, icfg, fcfg, beh_rand, beh_speeds, beh_n, ucb_n, ucb_tot, mt, ist, fst,
            dist, edge, pred, pred_n, goal, fit_vals, alpha_e, p_e, total_timesteps, episodes, out_i[lo:hi],
            out_f[lo:hi], work, seen, stack, queue, tw,
        )  # fmt: skip


def batch_reason(model: Any, episodes: int) -> str | None:
    """Why ``simulate`` can not run ``model``'s agent as one batch on the kernel (None: it can)."""
    from sb3_affect.kernel.agents import agent_spec
    from sb3_affect.kernel.bridge import compiled_reason

    reason = compiled_reason(model, model._single_env(), None)
    if reason is not None:
        return reason
    spec = agent_spec(model)
    assert not isinstance(spec, str)
    if episode_schedule(model, spec.kind, 0, 1) is None:
        return "a schedule depends on the training progress, which only the Python side evaluates (one episode at a time)"
    return None


def simulate_batch(inputs: BatchInputs, seeds: Sequence[int], episodes: int) -> pd.DataFrame:
    """
    The episode rows of fresh runs of one agent on one env for each seed.

    :param inputs: the agent and the env as the kernel runs them (``kernel.inputs.batch_inputs`` of a freshly built
        model whose ``batch_reason`` is None, or ``kernel.inputs.settings_inputs``), for ``episodes`` episodes
    :param seeds: one run per seed
    :param episodes: episodes per run
    :return: the rows, columns ``sb3_affect.engine.SIMULATE_COLUMNS``
    """
    import pandas as pd

    return pd.DataFrame(batch_columns(inputs, seeds, episodes), copy=False)  # (the columns are fresh arrays)


def batch_columns(inputs: BatchInputs, seeds: Sequence[int], episodes: int) -> dict[str, np.ndarray]:
    """
    ``simulate_batch``'s table as ``{column: array}`` (the dtypes of ``episode_log``), without pandas. The columns
    are rows of one transposed copy of the kernel's output (contiguous; ``simulate_batch`` hands them to pandas
    without copying or merging them into blocks by dtype, which would copy every column once more).
    """
    spec, geo = inputs.spec, inputs.geometry
    words = [seed_key(int(seed)) for seed in seeds]
    width = max((len(w) for w in words), default=1)
    keys = np.zeros((len(words), width), dtype=np.int64)
    lengths = np.zeros(len(words), dtype=np.int64)
    for r, w in enumerate(words):
        keys[r, : len(w)] = w
        lengths[r] = len(w)
    n_rows = len(words) * episodes
    out_i = np.zeros((n_rows, loop.N_OUT_I), dtype=np.int64)
    out_f = np.zeros((n_rows, 2))
    run_seeds(
        keys, lengths, inputs.q_init, inputs.n_actions, geo.trans, geo.tdist, inputs.icfg, inputs.fcfg,
        spec.beh_rand, spec.beh_speeds, spec.beh_n, geo.max_pred, inputs.alpha, inputs.p,
        episodes, episodes * inputs.cap, out_i, out_f,
    )  # fmt: skip
    seed_column = np.repeat(np.asarray([int(s) for s in seeds], dtype=np.int64), episodes)
    col_i = np.ascontiguousarray(out_i.T)
    col_f = np.ascontiguousarray(out_f.T)
    return {
        "seed": seed_column,
        "episode": np.tile(np.arange(1, episodes + 1, dtype=np.int64), len(words)),
        "decisions": col_i[loop.O_DECISIONS],
        "cells": col_i[loop.O_CELLS],
        "reward": col_f[0],
        "optimal": col_i[loop.O_OPTIMAL].astype(bool),
        "truncated": col_i[loop.O_TRUNCATED].astype(bool),
        "random_moves": col_i[loop.O_RANDOM].astype(np.float64),
        "waits": col_i[loop.O_WAITS],
        "joy": col_i[loop.O_JOY],
        "sadness": col_i[loop.O_SADNESS],
        "fear": col_i[loop.O_FEAR],
        "anger": col_i[loop.O_ANGER],
        "greedy_optimal": col_i[loop.O_GREEDY].astype(bool),
        "norm": col_f[1],
    }


def warm_up() -> None:
    """Call ``run_seeds`` and ``loop.run`` once on a 3 x 3 grid, with the argument types the engines use."""
    from sb3_affect.envs.grid_pursuit import build_transitions, distances_to

    table = build_transitions(3)
    trans = np.asarray(table, dtype=np.int64)
    tdist = np.asarray(distances_to(8, table), dtype=np.float64)
    icfg = np.zeros(loop.N_ICFG, dtype=np.int64)
    fields = [loop.C_KIND, loop.C_GOAL, loop.C_SHORTEST, loop.C_CAP, loop.C_ACT_EPISODE, loop.C_UNITS_CELLS]
    icfg[fields] = (loop.AFFECT, 8, 4, 50, 1, 1)
    fcfg = np.zeros(loop.N_FCFG)
    fcfg[[loop.F_GAMMA, loop.F_GOAL_REWARD, loop.F_NORM_SCALE]] = (0.8, 100.0, 1.0)
    beh_rand = np.array([1, 0, 0, 0], dtype=np.int64)
    beh_speeds = np.ones((4, 2), dtype=np.int64)
    beh_n = np.ones(4, dtype=np.int64)
    alpha, p = np.ones(1), np.zeros(1)
    out_i, out_f = np.zeros((1, loop.N_OUT_I), dtype=np.int64), np.zeros((1, 2))
    keys, lengths = np.zeros((1, 1), dtype=np.int64), np.ones(1, dtype=np.int64)
    run_seeds(keys, lengths, 0.0, 4, trans, tdist, icfg, fcfg, beh_rand, beh_speeds, beh_n, 2, alpha, p, 1, 50, out_i, out_f)
    mt = np.zeros(STATE_SIZE, dtype=np.int64)
    seed_state(mt, keys[0], 1)
    ist = np.zeros(loop.N_IST, dtype=np.int64)
    ist[loop.I_GREEDY] = -1
    fst = np.zeros(loop.N_FST)
    fst[loop.S_NORM] = np.nan
    dist, edge = np.full(9, np.inf), np.zeros((9, 4), dtype=np.bool_)
    pred, pred_n, goal = np.zeros((9, 2), dtype=np.int64), np.zeros(9, dtype=np.int64), np.zeros(9, dtype=np.bool_)
    ucb_n, ucb_tot = np.zeros((9, 4), dtype=np.int64), np.zeros(9, dtype=np.int64)
    loop.run(
        np.zeros((9, 4)), trans, tdist, icfg, fcfg, beh_rand, beh_speeds, beh_n, ucb_n, ucb_tot, mt, ist, fst,
        dist, edge, pred, pred_n, goal, np.zeros(4), alpha, p, 50, 1, out_i, out_f,
    )  # fmt: skip
