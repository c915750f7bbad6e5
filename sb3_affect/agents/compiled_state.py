"""
A model's run state as the kernel's arrays (``KernelRun``), and back.

Read at the start of a compiled ``learn``: the Q-table, the random generator's MT19937 state, the episode in
progress, the appraisal (known map, power fit, elapsed counters, ``last_act``), UCB counts, the env's transition
table and its time limit. ``write_back`` returns all of it to the Python objects, so the Python loop can continue from there.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sb3_affect.agents.compiled_run import RunArrays, monitor_episodes, read_appraisal_scalars, write_appraisal_scalars
from sb3_affect.core.settings import TabularSettings
from sb3_affect.kernel import agent_settings, grid_arrays, grid_loop, state_layout
from sb3_affect.kernel.agent_settings import KernelAgent
from sb3_affect.kernel.grid_inputs import TableArrays, kernel_config, time_limit_of, unwrap
from sb3_affect.kernel.jit import GRID_COMPILE_CPU_SECONDS, announce_compile

__all__ = ["GridKnownArrays", "KernelRun", "empty_appraisal"]


def empty_appraisal(n_states: int, n_actions: int, max_pred: int, episodes: int) -> grid_arrays.Appraisal:
    """An empty known map (``dist``, ``edge``, ``pred``, ``pred_n``, ``goal``) and room for ``episodes`` fit values."""
    return grid_arrays.Appraisal(
        np.full(n_states, math.inf),
        np.zeros((n_states, n_actions), dtype=np.bool_),
        np.zeros((n_states, max_pred), dtype=np.int64),
        np.zeros(n_states, dtype=np.int64),
        np.zeros(n_states, dtype=np.bool_),
        np.zeros(episodes),
    )


class GridKnownArrays:
    """
    The grid kernel's known map (``dist``, ``edge`` by action, ``pred``, ``pred_n``, ``goal``, over the env's
    transition table ``trans``) at the end of a compiled ``learn``, built into the appraiser's ``KnownMap`` only when
    something reads ``appraiser.known`` (``Appraiser.defer``).
    """

    def __init__(
        self, trans: np.ndarray, dist: np.ndarray, edge: np.ndarray, pred: np.ndarray, pred_n: np.ndarray, goal: np.ndarray
    ) -> None:
        self.trans, self.dist, self.edge, self.pred, self.pred_n, self.goal = trans, dist, edge, pred, pred_n, goal

    def fits(self, trans: np.ndarray, pred_shape: tuple[int, ...]) -> bool:
        """Whether these arrays describe a run on the transition table ``trans`` with predecessor rows of ``pred_shape``."""
        return self.pred.shape == pred_shape and (self.trans is trans or np.array_equal(self.trans, trans))

    def copy_into(self, run: KernelRun) -> None:
        """Copy the map into a new run's arrays (the appraiser keeps these until the new run hands its own back)."""
        for name in ("dist", "edge", "pred", "pred_n", "goal"):
            np.copyto(getattr(run, name), getattr(self, name))

    def value(self, name: str) -> Any:
        from sb3_affect.core.appraisal import KnownMap

        known = KnownMap(len(self.dist))
        known.distance = self.dist.tolist()
        known.goals = {int(g) for g in np.flatnonzero(self.goal)}
        rows, moves = np.nonzero(self.edge)  # by state, in order
        targets = self.trans[rows, moves].tolist()
        firsts = np.flatnonzero(np.diff(rows, prepend=-1))  # each state's first edge
        bounds = [*firsts.tolist(), len(targets)]
        for i, state in enumerate(rows[firsts].tolist()):
            known.successors[state] = set(targets[bounds[i] : bounds[i + 1]])
        for v in np.flatnonzero(self.pred_n).tolist():
            known.predecessors[v] = self.pred[v, : self.pred_n[v]].tolist()
        return known


class KernelRun(RunArrays):
    """
    One model's state in the grid kernel's arrays (``kernel.grid_loop``) for the length of a ``learn`` call.

    :param model: the tabular model
    :param env: the model's single env (wrapped)
    :param q: the model's Q-table during the run (``compiled_run.RunArrays``)
    :param episode: the episode in progress (``TabularQAlgorithm.resume_episode``)
    :param settings: the model's settings (``compiled_settings``)
    :param agent: the agent as the kernel runs it
    """


    def __init__(
        self,
        model: Any,
        env: Any,
        q: np.ndarray,
        episode: dict[str, Any],
        settings: TabularSettings,
        agent: KernelAgent,
    ) -> None:
        super().__init__(model, env, q, episode, agent)
        self.table = table = TableArrays.of(self.base)
        self.width = table.width
        limit = time_limit_of(unwrap(env)[1])
        self.config = kernel_config(agent, table, limit)
        ist = self.ist
        ist[state_layout.I_STATE] = episode["state"]
        ist[state_layout.I_CHANGED] = 1
        ist[state_layout.I_GREEDY] = -1
        n_states, n_actions = self.q.shape
        self.dist, self.edge, self.pred, self.pred_n, self.goal, self.fit_vals = empty_appraisal(
            n_states, n_actions, table.max_pred, 64
        )
        if agent.kind == agent_settings.AFFECT:
            self._read_appraisal()

    # -- appraisal in and out ------------------------------------------------------------------------------------
    def _read_appraisal(self) -> None:
        callback = self.model.emotion_callback
        appraiser = callback.appraiser
        kept = appraiser.deferred("known")
        if isinstance(kept, GridKnownArrays) and kept.fits(self.table.trans, self.pred.shape):
            kept.copy_into(self)  # as the last compiled learn left it: no Python objects in between
        else:
            self._read_known(appraiser.known)
        self.fit_vals = read_appraisal_scalars(callback, self.ist, self.fst)

    def _read_known(self, known: Any) -> None:
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
        seen = dict.items(known.predecessors) if isinstance(known.predecessors, dict) else enumerate(known.predecessors)
        for v, preds in seen:
            self.pred[v, : len(preds)] = preds
            self.pred_n[v] = len(preds)

    def _write_appraisal(self) -> None:
        callback = self.model.emotion_callback
        known = GridKnownArrays(self.table.trans, self.dist, self.edge, self.pred, self.pred_n, self.goal)
        callback.appraiser.defer("known", known)  # the run's arrays: this run is over, nothing writes them again
        write_appraisal_scalars(callback, self.ist, self.fst, self.fit_vals)

    # -- running -------------------------------------------------------------------------------------------------
    def step(self, alpha: np.ndarray, p: np.ndarray, total_timesteps: int, max_episodes: int) -> tuple[int, int]:
        """Run the kernel (see ``grid_loop.run``); returns (episodes finished, why it stopped)."""
        announce_compile("the tabular agents' grid loop (engine='compiled')", (grid_loop.run,), GRID_COMPILE_CPU_SECONDS)
        cells_before = self._room(max_episodes)
        state = grid_arrays.RunState(self.q, self.mt, self.ist, self.fst, self.ucb_n, self.ucb_tot)
        appraisal = grid_arrays.Appraisal(self.dist, self.edge, self.pred, self.pred_n, self.goal, self.fit_vals)
        episodes = grid_arrays.Episodes(alpha, p, self.out_i, self.out_f)
        finished, stop = grid_loop.run(
            self.table.env,
            self.config,
            self.agent.behaviour,
            state,
            appraisal,
            episodes,
            int(total_timesteps),
            int(max_episodes),
        )
        self._stepped(finished, cells_before)
        return int(finished), int(stop)

    def monitor_episodes(self, cells: np.ndarray, truncated: np.ndarray) -> None:
        """The Monitor's bookkeeping of the episode ends the env reported (``compiled_run.monitor_episodes``)."""
        table = self.table
        self.last_monitor_info = monitor_episodes(
            self.monitor, cells, truncated, self.config.time_limit, table.step_reward, table.goal_reward
        )

    def write_back(self) -> None:
        """Return every piece of state to the model, its generator, its appraisal, the env and its wrappers."""
        if self.agent.kind == agent_settings.AFFECT:
            self._write_appraisal()
        greedy = int(self.ist[state_layout.I_GREEDY])
        self.model.greedy_optimal = None if greedy < 0 else bool(greedy)
        self._write_back(self.table.step_reward)
        self.base.state = self.state

    def last_info(self) -> dict[str, Any]:
        """The env's info of the last decision of the last finished episode (what its ``step`` returned)."""
        s2 = self.last_s2
        return {"cell": divmod(s2, self.width), "moved": s2 != self.last_prev}

    @property
    def state(self) -> int:
        return int(self.ist[state_layout.I_STATE])
