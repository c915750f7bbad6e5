"""
What the two compiled ``learn`` runs share (``RunArrays``): a model's Q-table, its generator's MT19937 state, the
episode in progress, UCB counts, the kernel's output rows, the Monitor and the env's time limit, read into a kernel's
arrays at the start of a compiled ``learn`` and written back at its end. ``compiled_state.KernelRun`` adds the grid
kernel's env and known map, ``compiled_moving.MovingKernelRun`` the moving-prey kernel's.

A kernel's state arrays are laid out by ``kernel.state_layout`` in every world, each adding its own tail
(``RunArrays.n_ist``).
"""

from __future__ import annotations

import time
from itertools import repeat
from typing import Any, ClassVar

import numpy as np
from stable_baselines3.common.monitor import Monitor

from sb3_affect.kernel import agent_settings, state_layout
from sb3_affect.kernel.agent_settings import KernelAgent
from sb3_affect.kernel.grid_inputs import unwrap
from sb3_affect.kernel.mt19937 import state_from_rng, state_to_rng

__all__ = ["FitArrays", "RunArrays", "monitor_episodes", "read_appraisal_scalars", "write_appraisal_scalars"]


class FitArrays:
    """
    A power fit as a kernel leaves it: its values and its four running sums, built into the appraiser's ``PowerFit``
    only when something reads ``appraiser.fit`` (``Appraiser.defer``).
    """

    def __init__(self, values: np.ndarray, sums: np.ndarray) -> None:
        self.values, self.sums = values, sums

    def value(self, name: str) -> Any:
        from sb3_affect.core.appraisal import PowerFit

        fit = PowerFit()
        fit.values = self.values.tolist()
        sx, sy, sxx, sxy = self.sums.tolist()
        fit.sums = (sx, sy, sxx, sxy)
        return fit


def read_appraisal_scalars(callback: Any, ist: np.ndarray, fst: np.ndarray) -> np.ndarray:
    """
    An emotion callback's counts and its appraiser's power fit, norm, elapsed counters and ``last_act`` into a kernel's
    ``ist``/``fst`` (at ``kernel.state_layout``'s indices, every world's); returns the fit's
    values in an array with room to grow.
    """
    appraiser = callback.appraiser
    kept = appraiser.deferred("fit")
    if isinstance(kept, FitArrays):  # as the last compiled learn left it: no Python objects in between
        values, sums = kept.values, kept.sums
    else:
        fit = appraiser.fit
        values, sums = np.asarray(fit.values, dtype=np.float64), np.array(fit.sums)
    fit_vals = np.zeros(max(64, 2 * len(values)))
    fit_vals[: len(values)] = values
    fst[state_layout.S_FIT0 : state_layout.S_FIT0 + 4] = sums
    ist[state_layout.I_NFIT] = len(values)
    ist[state_layout.I_EL_CELLS] = appraiser.elapsed_cells
    ist[state_layout.I_EL_DECISIONS] = appraiser.elapsed_decisions
    ist[state_layout.I_JOY : state_layout.I_ANGER + 1] = callback.counts
    fst[state_layout.S_NORM] = appraiser.norm
    fst[state_layout.S_LAST_ACT] = appraiser.last_act
    return fit_vals


def write_appraisal_scalars(callback: Any, ist: np.ndarray, fst: np.ndarray, fit_vals: np.ndarray) -> None:
    """``read_appraisal_scalars`` the other way: the kernel's values back into the callback and its appraiser (the fit
    kept as arrays until read: ``FitArrays``)."""
    appraiser = callback.appraiser
    n_fit = int(ist[state_layout.I_NFIT])
    appraiser.defer("fit", FitArrays(fit_vals[:n_fit].copy(), fst[state_layout.S_FIT0 : state_layout.S_FIT0 + 4].copy()))
    appraiser.norm = float(fst[state_layout.S_NORM])
    appraiser.elapsed_cells = int(ist[state_layout.I_EL_CELLS])
    appraiser.elapsed_decisions = int(ist[state_layout.I_EL_DECISIONS])
    appraiser.last_act = float(fst[state_layout.S_LAST_ACT])
    callback.counts = [int(v) for v in ist[state_layout.I_JOY : state_layout.I_ANGER + 1]]


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
    any_truncated = bool(truncated.any())
    seen = ~truncated | ((cells >= time_limit) if time_limit > 0 else False)  # the safety cap: the env saw no episode end
    lengths = cells[seen].tolist() if any_truncated else cells.tolist()
    if not lengths:
        return None
    # the Monitor sums each episode's rewards with Python's sum: once per distinct (length, truncated) pair,
    # found by counting (no sort), then looked up for every episode
    if step == 0.0 and not any_truncated:  # every sum is 0.0 + ... + 0.0 + goal: exactly 0.0 + goal
        returns = repeat(0.0 + goal, len(lengths))  # (an iterator: the lists below are filled without a copy in between)
    elif step == 0.0:  # the same, or 0.0 for an episode the time limit ended
        returns = np.where(truncated[seen], 0.0, 0.0 + goal).tolist()
    else:
        keys = cells[seen] * 2 + truncated[seen]
        distinct = np.flatnonzero(np.bincount(keys))
        lookup = np.zeros(int(distinct[-1]) + 1)
        lookup[distinct] = [sum([step] * (key // 2 - 1) + [step if key % 2 else goal]) for key in distinct.tolist()]
        returns = lookup[keys].tolist()
    elapsed = time.time() - monitor.t_start
    first = len(monitor.episode_returns)
    monitor.episode_returns.extend(returns)
    monitor.episode_lengths.extend(lengths)
    monitor.episode_times.extend(repeat(elapsed, len(lengths)))
    writer = monitor.results_writer
    if writer is not None:
        for ep_rew, n in zip(monitor.episode_returns[first:], lengths):
            writer.write_row({"r": round(ep_rew, 6), "l": n, "t": round(elapsed, 6), **monitor.current_reset_info})
    last_return = monitor.episode_returns[-1]
    last = {"r": round(last_return, 6), "l": lengths[-1], "t": round(elapsed, 6), **monitor.current_reset_info}
    return last if bool(seen[-1]) else None


class RunArrays:
    """
    The state every compiled ``learn`` run carries (see the module docstring); subclasses set ``n_ist`` and
    ``fixed_goal`` and add their
    env's state, their known map, ``step``, ``state``, ``last_info`` and ``monitor_episodes``.

    :param model: the tabular model
    :param env: the model's single env (wrapped)
    :param q: the model's Q-table during the run (float64, C order: the kernel updates it in place)
    :param episode: the episode in progress (``TabularQAlgorithm.resume_episode``)
    :param agent: the agent as the kernel runs it
    """

    #: the length of the kernel's ``ist`` (its world's tail included) and whether its world has a fixed goal
    n_ist: ClassVar[int] = state_layout.N_IST
    fixed_goal: ClassVar[bool] = True

    def __init__(
        self, model: Any, env: Any, q: np.ndarray, episode: dict[str, Any], agent: KernelAgent
    ) -> None:
        self.model, self.agent = model, agent
        self.base, wrappers = unwrap(env)
        self.monitor = next((w for w in wrappers if isinstance(w, Monitor)), None)
        self.time_limit = next((w for w in wrappers if hasattr(w, "_max_episode_steps")), None)  # (as time_limit_of)
        self.obs_start = int(model.observation_space.start)
        self.act_start = int(model.action_space.start)
        self.q = q  # the live table: what predict, q_table and save see from an episode-level callback
        n_states, n_actions = self.q.shape
        self.mt, self.gauss = state_from_rng(model.rng)
        ist = self.ist = np.zeros(self.n_ist, dtype=np.int64)
        fst = self.fst = np.zeros(state_layout.N_FST)
        ist[state_layout.I_T] = model.num_timesteps
        ist[state_layout.I_DECISIONS] = episode["decisions"]
        ist[state_layout.I_CELLS] = episode["cells"]
        ist[state_layout.I_RANDOM] = episode["random_moves"]
        ist[state_layout.I_WAITS] = episode["waits"]
        fst[state_layout.S_REWARD] = episode["reward"]
        ist[state_layout.I_TL_ELAPSED] = 0 if self.time_limit is None else int(self.time_limit._elapsed_steps or 0)
        self.fit_vals = np.zeros(64)
        self.ucb_n = np.zeros((n_states, n_actions), dtype=np.int64)
        self.ucb_tot = np.zeros(n_states, dtype=np.int64)
        if agent.kind == agent_settings.UCB:
            self.ucb_n[:] = np.asarray(model.counts, dtype=np.int64)
            self.ucb_tot[:] = np.asarray(model.totals, dtype=np.int64)
        self.out_i = np.zeros((1, state_layout.N_OUT_I), dtype=np.int64)
        self.out_f = np.zeros((1, state_layout.N_OUT_F))
        self._handed_over = False  # whether the episode log holds the output rows (``block``)
        self.monitor_cells = 0
        self.last_monitor_info: dict[str, Any] | None = None

    # -- what a subclass defines -------------------------------------------------------------------------------
    def step(self, alpha: np.ndarray, p: np.ndarray, total_timesteps: int, max_episodes: int) -> tuple[int, int]:
        """Run the kernel until ``total_timesteps`` or ``max_episodes`` finished episodes (episode ``j`` of the call
        with ``alpha[j]`` and ``p[j]``); returns (episodes finished, why it stopped)."""
        raise NotImplementedError

    def monitor_episodes(self, cells: np.ndarray, truncated: np.ndarray) -> None:
        """The Monitor's bookkeeping of a block of finished episodes (``monitor_episodes``)."""
        raise NotImplementedError

    def last_info(self) -> dict[str, Any]:
        """The env's info of the last decision of the last finished episode (what its ``step`` returned)."""
        raise NotImplementedError

    def write_back(self) -> None:
        """Return every piece of state to the model, its generator, its appraisal, the env and its wrappers."""
        raise NotImplementedError

    # -- around a kernel call ------------------------------------------------------------------------------------
    def _room(self, max_episodes: int) -> int:
        """Room for ``max_episodes`` output rows and fit values; returns the cells of the episode in progress."""
        if self.out_i.shape[0] < max_episodes or self._handed_over:  # (not zeroed: the kernel writes every column of
            self._handed_over = False  # an episode's row, and only the rows it wrote are read)
            self.out_i = np.empty((max_episodes, state_layout.N_OUT_I), dtype=np.int64)
            self.out_f = np.empty((max_episodes, state_layout.N_OUT_F))
        need = int(self.ist[state_layout.I_NFIT]) + max_episodes
        if self.agent.kind == agent_settings.AFFECT and self.fit_vals.shape[0] < need:  # (only the affective agent fits)
            grown = np.zeros(max(need, 2 * self.fit_vals.shape[0]))
            grown[: self.fit_vals.shape[0]] = self.fit_vals
            self.fit_vals = grown
        return int(self.ist[state_layout.I_CELLS])

    def _stepped(self, finished: int, cells_before: int) -> None:
        """Count the env steps of a kernel call that finished ``finished`` episodes (the Monitor's ``total_steps``)."""
        cells = state_layout.I_CELLS
        stepped = int(self.out_i[:finished, state_layout.O_CELLS].sum()) - (cells_before if finished else 0)
        self.monitor_cells += stepped + int(self.ist[cells]) - (0 if finished else cells_before)

    def block(self, finished: int) -> dict[str, np.ndarray]:
        """The ``finished`` episodes of the last ``step`` as columns of the episode log (views of the output rows, which
        the run hands over, or of a copy when they fill less than a quarter of them; ``optimal`` and ``greedy_optimal``
        NaN unless the kernel's module has them)."""
        ints, floats = self.out_i[:finished], self.out_f[:finished]  # the columns are views of these
        if 4 * finished < self.out_i.shape[0]:  # a few rows of a large buffer: copied, the buffer kept for the next call
            ints, floats = ints.copy(), floats.copy()
        else:  # handed over: the next kernel call gets new rows
            self._handed_over = True
        return {
            "decisions": ints[:, state_layout.O_DECISIONS],
            "cells": ints[:, state_layout.O_CELLS],
            "reward": floats[:, 0],
            "optimal": self._flags(ints, "O_OPTIMAL"),
            "truncated": ints[:, state_layout.O_TRUNCATED].astype(bool),
            "random_moves": ints[:, state_layout.O_RANDOM],
            "waits": ints[:, state_layout.O_WAITS],
            "joy": ints[:, state_layout.O_JOY],
            "sadness": ints[:, state_layout.O_SADNESS],
            "fear": ints[:, state_layout.O_FEAR],
            "anger": ints[:, state_layout.O_ANGER],
            "greedy_optimal": self._flags(ints, "O_GREEDY"),
            "norm": floats[:, 1],
        }

    def _flags(self, ints: np.ndarray, name: str) -> np.ndarray:
        return ints[:, getattr(state_layout, name)].astype(bool) if self.fixed_goal else np.full(len(ints), np.nan)

    def _write_back(self, step_reward: float) -> None:
        """The state every run returns: Q-table, generator, UCB counts, the episode in progress, the wrappers."""
        model, ist = self.model, self.ist
        state_to_rng(model.rng, self.mt, self.gauss)
        if self.agent.kind == agent_settings.UCB:
            model.counts = self.ucb_n.tolist()
            model.totals = self.ucb_tot.tolist()
        model.keep_episode(
            {
                "state": self.state,
                "decisions": int(ist[state_layout.I_DECISIONS]),
                "cells": int(ist[state_layout.I_CELLS]),
                "random_moves": int(ist[state_layout.I_RANDOM]),
                "waits": int(ist[state_layout.I_WAITS]),
                "reward": float(self.fst[state_layout.S_REWARD]),
            }
        )
        if self.time_limit is not None:
            self.time_limit._elapsed_steps = int(ist[state_layout.I_TL_ELAPSED])
        if self.monitor is not None:
            self.monitor.rewards = [step_reward] * int(ist[state_layout.I_CELLS])
            self.monitor.needs_reset = False
            self.monitor.total_steps += self.monitor_cells

    # -- the last decision of the last finished episode (callback locals) --------------------------------------------
    @property
    def state(self) -> int:
        raise NotImplementedError

    @property
    def timesteps(self) -> int:
        return int(self.ist[state_layout.I_T])

    @property
    def last_s2(self) -> int:
        return int(self.ist[state_layout.I_LAST_S2])

    @property
    def last_prev(self) -> int:
        return int(self.ist[state_layout.I_LAST_PREV])

    @property
    def last_action(self) -> int:
        return int(self.ist[state_layout.I_LAST_ACTION])

    @property
    def last_terminated(self) -> bool:
        return bool(self.ist[state_layout.I_LAST_TERMINATED])

    @property
    def last_reward(self) -> float:
        return float(self.fst[state_layout.S_LAST_REWARD])
