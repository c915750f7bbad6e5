"""
A model's run state as the kernel's arrays (``KernelRun``), and back.

Read at the start of a compiled ``learn``: the Q-table, the random generator's MT19937 state, the episode in
progress, the appraisal (known map, power fit, elapsed counters, ``last_act``), UCB counts, the env's transition
table and its time limit. ``write_back`` returns all of it to the Python objects, so the Python loop can continue from there.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from gymnasium.wrappers import TimeLimit
from stable_baselines3.common.monitor import Monitor

from sb3_affect.kernel import arrays, loop
from sb3_affect.kernel.agents import KernelAgent
from sb3_affect.kernel.inputs import TableArrays, kernel_config, unwrap
from sb3_affect.kernel.mt19937 import state_from_rng, state_to_rng
from sb3_affect.settings import TabularSettings

__all__ = ["KernelRun", "empty_appraisal", "monitor_episodes", "read_appraisal_scalars", "write_appraisal_scalars"]


def empty_appraisal(n_states: int, n_actions: int, max_pred: int, episodes: int) -> arrays.Appraisal:
    """An empty known map (``dist``, ``edge``, ``pred``, ``pred_n``, ``goal``) and room for ``episodes`` fit values."""
    return arrays.Appraisal(
        np.full(n_states, math.inf),
        np.zeros((n_states, n_actions), dtype=np.bool_),
        np.zeros((n_states, max_pred), dtype=np.int64),
        np.zeros(n_states, dtype=np.int64),
        np.zeros(n_states, dtype=np.bool_),
        np.zeros(episodes),
    )


def read_appraisal_scalars(callback: Any, ist: np.ndarray, fst: np.ndarray, at: Any) -> np.ndarray:
    """
    An emotion callback's counts and its appraiser's power fit, norm, elapsed counters and ``last_act`` into a kernel's
    ``ist``/``fst`` (at the indices of the module ``at``: ``kernel.arrays`` or ``kernel.moving``); returns the fit's
    values in an array with room to grow.
    """
    appraiser = callback.appraiser
    fit = appraiser.fit
    values = fit.values
    fit_vals = np.zeros(max(64, 2 * len(values)))
    fit_vals[: len(values)] = values
    fst[at.S_FIT0 : at.S_FIT0 + 4] = (fit._sx, fit._sy, fit._sxx, fit._sxy)
    ist[at.I_NFIT] = len(values)
    ist[at.I_EL_CELLS] = appraiser.elapsed_cells
    ist[at.I_EL_DECISIONS] = appraiser.elapsed_decisions
    ist[at.I_JOY : at.I_ANGER + 1] = callback.counts
    fst[at.S_NORM] = appraiser.norm
    fst[at.S_LAST_ACT] = appraiser.last_act
    return fit_vals


def write_appraisal_scalars(callback: Any, ist: np.ndarray, fst: np.ndarray, fit_vals: np.ndarray, at: Any) -> None:
    """``read_appraisal_scalars`` the other way: the kernel's values back into the callback and its appraiser."""
    from sb3_affect.appraisal import PowerFit

    appraiser = callback.appraiser
    fit = PowerFit()
    fit.values = fit_vals[: int(ist[at.I_NFIT])].tolist()
    fit._sx, fit._sy, fit._sxx, fit._sxy = (float(v) for v in fst[at.S_FIT0 : at.S_FIT0 + 4])
    appraiser.fit = fit
    appraiser.norm = float(fst[at.S_NORM])
    appraiser.elapsed_cells = int(ist[at.I_EL_CELLS])
    appraiser.elapsed_decisions = int(ist[at.I_EL_DECISIONS])
    appraiser.last_act = float(fst[at.S_LAST_ACT])
    callback.counts = [int(v) for v in ist[at.I_JOY : at.I_ANGER + 1]]


def monitor_episodes(
    monitor: Any, cells: np.ndarray, truncated: np.ndarray, time_limit: int, step: float, goal: float
) -> dict[str, Any] | None:
    """
    The Monitor's bookkeeping of a block of finished episodes (``cells`` and ``truncated`` per episode) whose ends the
    env reported (goal reached or the env's time limit, not the safety cap); returns the last episode's
    ``info["episode"]``, or None when the env saw no end of it.
    """
    if monitor is None:
        return None
    seen = ~truncated | ((cells >= time_limit) if time_limit > 0 else False)  # the safety cap: the env saw no episode end
    lengths = cells[seen].tolist()
    if not lengths:
        return None
    # the Monitor sums each episode's rewards with Python's sum: once per distinct (length, truncated) pair,
    # found by counting (no sort), then looked up for every episode
    if step == 0.0:  # every sum is 0.0 + ... + the last reward: exactly the last reward (any order of summing)
        returns = np.where(truncated[seen], 0.0, 0.0 + goal).tolist()
    else:
        keys = cells[seen] * 2 + truncated[seen]
        distinct = np.flatnonzero(np.bincount(keys))
        lookup = np.zeros(int(distinct[-1]) + 1)
        lookup[distinct] = [sum([step] * (key // 2 - 1) + [step if key % 2 else goal]) for key in distinct.tolist()]
        returns = lookup[keys].tolist()
    elapsed = time.time() - monitor.t_start
    monitor.episode_returns.extend(returns)
    monitor.episode_lengths.extend(lengths)
    monitor.episode_times.extend([elapsed] * len(lengths))
    writer = monitor.results_writer
    if writer is not None:
        for ep_rew, n in zip(returns, lengths):
            writer.write_row({"r": round(ep_rew, 6), "l": n, "t": round(elapsed, 6), **monitor.current_reset_info})
    last = {"r": round(returns[-1], 6), "l": lengths[-1], "t": round(elapsed, 6), **monitor.current_reset_info}
    return last if bool(seen[-1]) else None


class KernelRun:
    """
    One model's state in kernel arrays for the length of a ``learn`` call.

    :param model: the tabular model (its episode in progress already begun)
    :param env: the model's single env (wrapped)
    :param settings: the model's settings (``compiled_settings``)
    :param agent: the agent as the kernel runs it
    """

    def __init__(self, model: Any, env: Any, settings: TabularSettings, agent: KernelAgent) -> None:
        self.model, self.agent = model, agent
        self.base, wrappers = unwrap(env)
        self.monitor = next((w for w in wrappers if isinstance(w, Monitor)), None)
        self.time_limit = next((w for w in wrappers if isinstance(w, TimeLimit)), None)
        self.table = table = TableArrays.of(self.base)
        self.width = table.width
        self.obs_start = int(model.observation_space.start)
        self.act_start = int(model.action_space.start)
        limit = 0 if self.time_limit is None else int(self.time_limit._max_episode_steps)
        self.config = kernel_config(settings, agent, table, limit)
        self.q = np.array(model._q, dtype=np.float64)
        n_states, n_actions = self.q.shape
        self.mt, self.gauss = state_from_rng(model._rng)
        self.ist = np.zeros(arrays.N_IST, dtype=np.int64)
        self.fst = np.zeros(arrays.N_FST)
        st = model._episode_state
        ist, fst = self.ist, self.fst
        ist[arrays.I_T] = model.num_timesteps
        if st is None:
            ist[arrays.I_STATE] = int(np.asarray(model._last_obs).reshape(-1)[0]) - self.obs_start
        else:
            ist[arrays.I_STATE] = st["state"]
            ist[arrays.I_DECISIONS], ist[arrays.I_CELLS] = st["decisions"], st["cells"]
            ist[arrays.I_RANDOM], ist[arrays.I_WAITS] = st["random_moves"], st["waits"]
            fst[arrays.S_REWARD] = st["reward"]
        ist[arrays.I_CHANGED] = 1
        ist[arrays.I_GREEDY] = -1
        ist[arrays.I_TL_ELAPSED] = 0 if self.time_limit is None else int(self.time_limit._elapsed_steps or 0)
        self.cells_at_start = int(ist[arrays.I_CELLS])
        self.dist, self.edge, self.pred, self.pred_n, self.goal, self.fit_vals = empty_appraisal(
            n_states, n_actions, table.max_pred, 64
        )
        if agent.kind == arrays.AFFECT:
            self._read_appraisal()
        self.ucb_n = np.zeros((n_states, n_actions), dtype=np.int64)
        self.ucb_tot = np.zeros(n_states, dtype=np.int64)
        if agent.kind == arrays.UCB:
            self.ucb_n[:] = np.asarray(model.counts, dtype=np.int64)
            self.ucb_tot[:] = np.asarray(model._totals, dtype=np.int64)
        self.out_i = np.zeros((1, arrays.N_OUT_I), dtype=np.int64)
        self.out_f = np.zeros((1, 2))
        self.monitor_cells = 0
        self.last_monitor_info: dict[str, Any] | None = None

    # -- appraisal in and out ------------------------------------------------------------------------------------
    def _read_appraisal(self) -> None:
        callback = self.model.emotion_callback
        appraiser = callback.appraiser
        known = appraiser.known
        trans = self.table.trans
        self.dist[:] = np.asarray(known.distance, dtype=np.float64)
        for g in known.goals:
            self.goal[g] = True
        seen = dict.items(known.successors) if isinstance(known.successors, dict) else enumerate(known.successors)
        pairs = np.array([(s, t) for s, successors in seen for t in successors], dtype=np.int64).reshape(-1, 2)
        hits = trans[pairs[:, 0]] == pairs[:, 1:]  # every action of s that leads to t
        unknown = np.flatnonzero(~hits.any(axis=1))
        if unknown.size:
            s, t = pairs[unknown[0]].tolist()
            raise ValueError(f"the appraiser's known map has a move {s} -> {t} that this env does not have")
        rows, moves = np.nonzero(hits)
        self.edge[pairs[rows, 0], moves] = True
        for v, preds in enumerate(known.predecessors):
            self.pred[v, : len(preds)] = preds
            self.pred_n[v] = len(preds)
        self.fit_vals = read_appraisal_scalars(callback, self.ist, self.fst, arrays)

    def _write_appraisal(self) -> None:
        from sb3_affect.appraisal import KnownMap

        callback = self.model.emotion_callback
        appraiser = callback.appraiser
        trans = self.table.trans
        known = KnownMap(len(self.dist))
        known.distance = self.dist.tolist()
        known.goals = {int(g) for g in np.flatnonzero(self.goal)}
        rows, moves = np.nonzero(self.edge)
        for s, t in zip(rows.tolist(), trans[rows, moves].tolist()):
            known.successors[s].add(t)
        known.predecessors = [row[:n] for row, n in zip(self.pred.tolist(), self.pred_n.tolist())]
        appraiser.known = known
        write_appraisal_scalars(callback, self.ist, self.fst, self.fit_vals, arrays)

    # -- running -------------------------------------------------------------------------------------------------
    def step(self, alpha: np.ndarray, p: np.ndarray, total_timesteps: int, max_episodes: int) -> tuple[int, int]:
        """Run the kernel (see ``loop.run``); returns (episodes finished, why it stopped)."""
        if self.out_i.shape[0] < max_episodes:
            self.out_i = np.zeros((max_episodes, arrays.N_OUT_I), dtype=np.int64)
            self.out_f = np.zeros((max_episodes, 2))
        need = int(self.ist[arrays.I_NFIT]) + max_episodes
        if self.fit_vals.shape[0] < need:
            grown = np.zeros(max(need, 2 * self.fit_vals.shape[0]))
            grown[: self.fit_vals.shape[0]] = self.fit_vals
            self.fit_vals = grown
        cells_before = int(self.ist[arrays.I_CELLS])
        state = arrays.RunState(self.q, self.mt, self.ist, self.fst, self.ucb_n, self.ucb_tot)
        appraisal = arrays.Appraisal(self.dist, self.edge, self.pred, self.pred_n, self.goal, self.fit_vals)
        episodes = arrays.Episodes(alpha, p, self.out_i, self.out_f)
        finished, stop = loop.run(
            self.table.env,
            self.config,
            self.agent.behaviour,
            state,
            appraisal,
            episodes,
            int(total_timesteps),
            int(max_episodes),
        )
        stepped = int(self.out_i[:finished, arrays.O_CELLS].sum()) - (cells_before if finished else 0)
        self.monitor_cells += stepped + int(self.ist[arrays.I_CELLS]) - (0 if finished else cells_before)
        return int(finished), int(stop)

    def monitor_episodes(self, cells: np.ndarray, truncated: np.ndarray) -> None:
        """The Monitor's bookkeeping of the episode ends the env reported (``monitor_episodes``)."""
        table = self.table
        self.last_monitor_info = monitor_episodes(
            self.monitor, cells, truncated, self.config.time_limit, table.step_reward, table.goal_reward
        )

    def write_back(self) -> None:
        """Return every piece of state to the model, its generator, its appraisal, the env and its wrappers."""
        model, ist = self.model, self.ist
        model._q = self.q.tolist()
        state_to_rng(model._rng, self.mt, self.gauss)
        if self.agent.kind == arrays.AFFECT:
            self._write_appraisal()
        if self.agent.kind == arrays.UCB:
            model.counts = self.ucb_n.tolist()
            model._totals = self.ucb_tot.tolist()
        s = int(ist[arrays.I_STATE])
        greedy = int(ist[arrays.I_GREEDY])
        model._greedy_optimal = None if greedy < 0 else bool(greedy)
        model._episode_state = {
            "state": s,
            "decisions": int(ist[arrays.I_DECISIONS]),
            "cells": int(ist[arrays.I_CELLS]),
            "random_moves": int(ist[arrays.I_RANDOM]),
            "waits": int(ist[arrays.I_WAITS]),
            "reward": float(self.fst[arrays.S_REWARD]),
        }
        model._last_obs = np.array([s + self.obs_start])
        self.base.state = s
        if self.time_limit is not None:
            self.time_limit._elapsed_steps = int(ist[arrays.I_TL_ELAPSED])  # type: ignore[assignment]
        if self.monitor is not None:
            self.monitor.rewards = [self.table.step_reward] * int(ist[arrays.I_CELLS])
            self.monitor.needs_reset = False
            self.monitor.total_steps += self.monitor_cells

    # -- finished episodes and the last decision (callback locals) -----------------------------------------------------
    def block(self, finished: int) -> dict[str, np.ndarray]:
        """The ``finished`` episodes of the last ``step`` as columns of the episode log (copies)."""
        ints, floats = self.out_i[:finished].copy(), self.out_f[:finished].copy()  # the columns are views of these
        return {
            "decisions": ints[:, arrays.O_DECISIONS],
            "cells": ints[:, arrays.O_CELLS],
            "reward": floats[:, 0],
            "optimal": ints[:, arrays.O_OPTIMAL].astype(bool),
            "truncated": ints[:, arrays.O_TRUNCATED].astype(bool),
            "random_moves": ints[:, arrays.O_RANDOM],
            "waits": ints[:, arrays.O_WAITS],
            "joy": ints[:, arrays.O_JOY],
            "sadness": ints[:, arrays.O_SADNESS],
            "fear": ints[:, arrays.O_FEAR],
            "anger": ints[:, arrays.O_ANGER],
            "greedy_optimal": ints[:, arrays.O_GREEDY].astype(bool),
            "norm": floats[:, 1],
        }

    def last_info(self) -> dict[str, Any]:
        """The env's info of the last decision of the last finished episode (what its ``step`` returned)."""
        s2 = self.last_s2
        return {"cell": divmod(s2, self.width), "moved": s2 != self.last_prev}

    @property
    def timesteps(self) -> int:
        return int(self.ist[arrays.I_T])

    @property
    def state(self) -> int:
        return int(self.ist[arrays.I_STATE])

    @property
    def last_s2(self) -> int:
        return int(self.ist[arrays.I_LAST_S2])

    @property
    def last_prev(self) -> int:
        return int(self.ist[arrays.I_LAST_PREV])

    @property
    def last_action(self) -> int:
        return int(self.ist[arrays.I_LAST_ACTION])

    @property
    def last_terminated(self) -> bool:
        return bool(self.ist[arrays.I_LAST_TERMINATED])

    @property
    def last_reward(self) -> float:
        return float(self.fst[arrays.S_LAST_REWARD])
