"""
A model's run state on MovingPursuit as the moving-prey kernel's arrays (``MovingKernelRun``), and back: what
``sb3_affect.compiled_state.KernelRun`` is for the grid kernel, for ``sb3_affect.kernel.moving``.

Read at the start of a compiled ``learn``: the Q-table, the agent's MT19937 state, the env's PCG64 state (the prey's
draws), hunter and prey cells, the episode in progress, the appraisal (known map over observations, power fit,
elapsed counters, ``last_act``) and UCB counts. ``write_back`` returns all of it to the Python objects and the env, so
the Python loop can continue from there.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium.wrappers import TimeLimit
from stable_baselines3.common.monitor import Monitor

from sb3_affect.compiled_state import monitor_episodes, read_appraisal_scalars, write_appraisal_scalars
from sb3_affect.kernel import arrays, moving
from sb3_affect.kernel.agents import KernelAgent
from sb3_affect.kernel.inputs import unwrap
from sb3_affect.kernel.mt19937 import TW_SIZE, state_from_rng, state_to_rng
from sb3_affect.kernel.pcg64 import state_from_generator, state_to_generator
from sb3_affect.kernel.prey_batch import moving_inputs
from sb3_affect.settings import TabularSettings

__all__ = ["MovingKernelRun"]


class MovingKernelRun:
    """
    One model's state in the moving-prey kernel's arrays for the length of a ``learn`` call (the interface of
    ``KernelRun``: ``step``, ``block``, ``monitor_episodes``, ``last_info``, ``write_back``).

    :param model: the tabular model (its episode in progress already begun)
    :param env: the model's single env (a MovingPursuit, wrapped)
    :param settings: the model's settings (``compiled_settings``)
    :param agent: the agent as the kernel runs it
    """

    def __init__(self, model: Any, env: Any, settings: TabularSettings, agent: KernelAgent) -> None:
        self.model, self.agent = model, agent
        self.base, wrappers = unwrap(env)
        base = self.base
        self.monitor = next((w for w in wrappers if isinstance(w, Monitor)), None)
        self.time_limit = next((w for w in wrappers if isinstance(w, TimeLimit)), None)
        self.inputs = moving_inputs(settings, env, 1)
        self.obs_start = int(model.observation_space.start)
        self.act_start = int(model.action_space.start)
        self.q = np.array(model._q, dtype=np.float64)
        n_states, n_actions = self.q.shape
        self.mt, self.gauss = state_from_rng(model._rng)
        self.pcg = state_from_generator(base.np_random)
        ist = self.ist = np.zeros(moving.N_IST, dtype=np.int64)
        fst = self.fst = np.zeros(moving.N_FST)
        ist[moving.I_T] = model.num_timesteps
        st = model._episode_state
        if st is not None:
            ist[moving.I_DECISIONS], ist[moving.I_CELLS] = st["decisions"], st["cells"]
            ist[moving.I_RANDOM], ist[moving.I_WAITS] = st["random_moves"], st["waits"]
            fst[moving.S_REWARD] = st["reward"]
        ist[moving.I_HUNTER], ist[moving.I_PREY] = base.hunter, base.prey_cell  # the env's state is the observation
        ist[moving.I_TL_ELAPSED] = 0 if self.time_limit is None else int(self.time_limit._elapsed_steps or 0)
        fst[moving.S_NORM] = math.nan
        fst[moving.S_LAST_ACT] = math.inf
        inputs = self.inputs
        self.dist = np.full(n_states, math.inf)
        self.succ = np.zeros((n_states, inputs.succ_width), dtype=np.int32)
        self.succ_n = np.zeros(n_states, dtype=np.int64)
        self.pred = np.zeros((n_states, inputs.pred_width), dtype=np.int32)
        self.pred_n = np.zeros(n_states, dtype=np.int64)
        self.goal = np.zeros(n_states, dtype=np.bool_)
        self.fit_vals = np.zeros(64)
        if agent.kind == arrays.AFFECT:
            self._read_appraisal()
        self.ucb_n = np.zeros((n_states, n_actions), dtype=np.int64)
        self.ucb_tot = np.zeros(n_states, dtype=np.int64)
        if agent.kind == arrays.UCB:
            self.ucb_n[:] = np.asarray(model.counts, dtype=np.int64)
            self.ucb_tot[:] = np.asarray(model._totals, dtype=np.int64)
        self.work = np.empty(n_actions)
        self.queue = np.empty(n_states + 1, dtype=np.int64)
        self.tw = np.empty(TW_SIZE, dtype=np.int64)
        self.ties = np.empty(inputs.cell_trans.shape[1] + 1, dtype=np.int64)
        self.out_i = np.zeros((1, moving.N_OUT_I), dtype=np.int64)
        self.out_f = np.zeros((1, 2))
        self.monitor_cells = 0
        self.last_monitor_info: dict[str, Any] | None = None

    # -- appraisal in and out ------------------------------------------------------------------------------------
    def _read_appraisal(self) -> None:
        callback = self.model.emotion_callback
        known = callback.appraiser.known
        self.dist[:] = np.asarray(known.distance, dtype=np.float64)
        self.goal[list(known.goals)] = True
        rows = dict.items(known.successors) if isinstance(known.successors, dict) else enumerate(known.successors)
        for s, successors in rows:
            self.succ[s, : len(successors)] = sorted(successors)  # a set: the kernel only asks whether a move is there
            self.succ_n[s] = len(successors)
        rows = dict.items(known.predecessors) if isinstance(known.predecessors, dict) else enumerate(known.predecessors)
        for v, preds in rows:
            self.pred[v, : len(preds)] = preds  # in the order they were added
            self.pred_n[v] = len(preds)
        self.fit_vals = read_appraisal_scalars(callback, self.ist, self.fst, moving)

    def _write_appraisal(self) -> None:
        from sb3_affect.appraisal import KnownMap

        callback = self.model.emotion_callback
        known = KnownMap(len(self.dist))
        known.distance = self.dist.tolist()
        known.goals = {int(g) for g in np.flatnonzero(self.goal)}
        for s in np.flatnonzero(self.succ_n).tolist():
            known.successors[s] = set(self.succ[s, : self.succ_n[s]].tolist())
        for v in np.flatnonzero(self.pred_n).tolist():
            known.predecessors[v] = self.pred[v, : self.pred_n[v]].tolist()
        callback.appraiser.known = known
        write_appraisal_scalars(callback, self.ist, self.fst, self.fit_vals, moving)

    # -- running -------------------------------------------------------------------------------------------------
    def step(self, alpha: np.ndarray, p: np.ndarray, total_timesteps: int, max_episodes: int) -> tuple[int, int]:
        """Run the kernel (``moving.moving_loop``); returns (episodes finished, 0)."""
        if self.out_i.shape[0] < max_episodes:
            self.out_i = np.zeros((max_episodes, moving.N_OUT_I), dtype=np.int64)
            self.out_f = np.zeros((max_episodes, 2))
        need = int(self.ist[moving.I_NFIT]) + max_episodes
        if self.fit_vals.shape[0] < need:
            grown = np.zeros(max(need, 2 * self.fit_vals.shape[0]))
            grown[: self.fit_vals.shape[0]] = self.fit_vals
            self.fit_vals = grown
        cells_before = int(self.ist[moving.I_CELLS])
        inputs, behaviour = self.inputs, self.agent.behaviour
        finished = moving.moving_loop(
            self.q, inputs.cell_trans, inputs.far, inputs.icfg, inputs.fcfg, behaviour.random, behaviour.speeds,
            behaviour.n, self.ucb_n, self.ucb_tot, self.mt, self.pcg, self.ist, self.fst, self.dist, self.succ,
            self.succ_n, self.pred, self.pred_n, self.goal, self.fit_vals, alpha, p, int(total_timesteps),
            int(max_episodes), self.out_i, self.out_f, self.work, self.queue, self.tw, self.ties,
        )  # fmt: skip
        stepped = int(self.out_i[:finished, moving.O_CELLS].sum()) - (cells_before if finished else 0)
        self.monitor_cells += stepped + int(self.ist[moving.I_CELLS]) - (0 if finished else cells_before)
        return int(finished), 0

    def block(self, finished: int) -> dict[str, np.ndarray]:
        """The ``finished`` episodes of the last ``step`` as columns of the episode log (``optimal`` and
        ``greedy_optimal`` NaN: the env has no fixed goal)."""
        ints, floats = self.out_i[:finished].copy(), self.out_f[:finished].copy()
        return {
            "decisions": ints[:, moving.O_DECISIONS],
            "cells": ints[:, moving.O_CELLS],
            "reward": floats[:, 0],
            "optimal": np.full(finished, np.nan),
            "truncated": ints[:, moving.O_TRUNCATED].astype(bool),
            "random_moves": ints[:, moving.O_RANDOM],
            "waits": ints[:, moving.O_WAITS],
            "joy": ints[:, moving.O_JOY],
            "sadness": ints[:, moving.O_SADNESS],
            "fear": ints[:, moving.O_FEAR],
            "anger": ints[:, moving.O_ANGER],
            "greedy_optimal": np.full(finished, np.nan),
            "norm": floats[:, 1],
        }

    def monitor_episodes(self, cells: np.ndarray, truncated: np.ndarray) -> None:
        """The Monitor's bookkeeping of the episode ends the env reported (``compiled_state.monitor_episodes``)."""
        base = self.base
        limit = int(self.inputs.icfg[moving.C_TIME_LIMIT])
        self.last_monitor_info = monitor_episodes(self.monitor, cells, truncated, limit, base.step_reward, base.goal_reward)

    def last_info(self) -> dict[str, Any]:
        """The env's info of the last decision of the last finished episode (what its ``step`` returned)."""
        size, n_cells = self.base.size, self.base.n_cells
        hunter, prey = divmod(self.last_s2, n_cells)
        return {"cell": divmod(hunter, size), "prey": divmod(prey, size), "moved": hunter != self.last_prev}

    def write_back(self) -> None:
        """Return every piece of state to the model, its generator, its appraisal, the env and its wrappers."""
        model, ist, base = self.model, self.ist, self.base
        model._q = self.q.tolist()
        state_to_rng(model._rng, self.mt, self.gauss)
        state_to_generator(base.np_random, self.pcg)
        if self.agent.kind == arrays.AFFECT:
            self._write_appraisal()
        if self.agent.kind == arrays.UCB:
            model.counts = self.ucb_n.tolist()
            model._totals = self.ucb_tot.tolist()
        base.hunter, base.prey_cell = int(ist[moving.I_HUNTER]), int(ist[moving.I_PREY])
        s = self.state
        model._greedy_optimal = None
        model._episode_state = {
            "state": s,
            "decisions": int(ist[moving.I_DECISIONS]),
            "cells": int(ist[moving.I_CELLS]),
            "random_moves": int(ist[moving.I_RANDOM]),
            "waits": int(ist[moving.I_WAITS]),
            "reward": float(self.fst[moving.S_REWARD]),
        }
        model._last_obs = np.array([s + self.obs_start])
        if self.time_limit is not None:
            self.time_limit._elapsed_steps = int(ist[moving.I_TL_ELAPSED])  # type: ignore[assignment]
        if self.monitor is not None:
            self.monitor.rewards = [base.step_reward] * int(ist[moving.I_CELLS])
            self.monitor.needs_reset = False
            self.monitor.total_steps += self.monitor_cells

    # -- the last decision (callback locals) -----------------------------------------------------------------------
    @property
    def timesteps(self) -> int:
        return int(self.ist[moving.I_T])

    @property
    def state(self) -> int:
        return int(self.ist[moving.I_HUNTER]) * self.base.n_cells + int(self.ist[moving.I_PREY])

    @property
    def last_s2(self) -> int:
        return int(self.ist[moving.I_LAST_OBS])

    @property
    def last_prev(self) -> int:
        return int(self.ist[moving.I_LAST_PREV])

    @property
    def last_action(self) -> int:
        return int(self.ist[moving.I_LAST_ACTION])

    @property
    def last_terminated(self) -> bool:
        return bool(self.ist[moving.I_LAST_TERMINATED])

    @property
    def last_reward(self) -> float:
        return float(self.fst[moving.S_LAST_REWARD])
