"""
A model's run state on MovingPursuit as the moving-prey kernel's arrays (``MovingKernelRun``), and back: what
``sb3_affect.agents.compiled_state.KernelRun`` is for the grid kernel (both on ``compiled_run.RunArrays``), for
``sb3_affect.kernel.moving_loop``.

Read at the start of a compiled ``learn``: the Q-table, the agent's MT19937 state, the env's PCG64 state (the prey's
draws), hunter and prey cells, the episode in progress, the appraisal (known map over observations, power fit,
elapsed counters, ``last_act``) and UCB counts. ``write_back`` returns all of it to the Python objects and the env, so
the Python loop can continue from there.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from sb3_affect.agents.compiled_run import RunArrays, monitor_episodes, read_appraisal_scalars, write_appraisal_scalars
from sb3_affect.core.settings import TabularSettings
from sb3_affect.kernel import agent_settings, grid_arrays, moving_loop, state_layout
from sb3_affect.kernel.agent_settings import KernelAgent
from sb3_affect.kernel.decision import ObsAppraisal
from sb3_affect.kernel.jit import MOVING_COMPILE_CPU_SECONDS, announce_compile
from sb3_affect.kernel.moving_batch import moving_inputs
from sb3_affect.kernel.mt19937 import TW_SIZE
from sb3_affect.kernel.pcg64 import state_from_generator, state_to_generator

__all__ = ["MovingKernelRun", "MovingKnownArrays"]


class MovingKnownArrays:
    """
    The moving-prey kernel's known map over observations (``dist``, successor and predecessor rows, ``goal``) at the
    end of a compiled ``learn``, built into the appraiser's ``KnownMap`` only when something reads
    ``appraiser.known`` (``Appraiser.defer``).
    """

    NAMES = ("dist", "succ", "succ_n", "pred", "pred_n", "goal")

    def __init__(
        self, dist: np.ndarray, succ: np.ndarray, succ_n: np.ndarray, pred: np.ndarray, pred_n: np.ndarray, goal: np.ndarray
    ) -> None:
        self.dist, self.succ, self.succ_n, self.pred, self.pred_n, self.goal = dist, succ, succ_n, pred, pred_n, goal

    def fits(self, run: MovingKernelRun) -> bool:
        """Whether a new run's arrays have these shapes."""
        return all(getattr(self, name).shape == getattr(run, name).shape for name in self.NAMES)

    def copy_into(self, run: MovingKernelRun) -> None:
        """Copy the map into a new run's arrays (the appraiser keeps these until the new run hands its own back)."""
        for name in self.NAMES:
            np.copyto(getattr(run, name), getattr(self, name))

    def value(self, name: str) -> Any:
        from sb3_affect.core.appraisal import KnownMap

        known = KnownMap(len(self.dist))
        known.distance = self.dist.tolist()
        known.goals = {int(g) for g in np.flatnonzero(self.goal)}
        for s in np.flatnonzero(self.succ_n).tolist():
            known.successors[s] = set(self.succ[s, : self.succ_n[s]].tolist())
        for v in np.flatnonzero(self.pred_n).tolist():
            known.predecessors[v] = self.pred[v, : self.pred_n[v]].tolist()
        return known


class MovingKernelRun(RunArrays):
    """
    One model's state in the moving-prey kernel's arrays for the length of a ``learn`` call.

    :param model: the tabular model
    :param env: the model's single env (a MovingPursuit, wrapped)
    :param q: the model's Q-table during the run (``compiled_run.RunArrays``)
    :param episode: the episode in progress (``TabularQAlgorithm.resume_episode``)
    :param settings: the model's settings (``compiled_settings``)
    :param agent: the agent as the kernel runs it
    """

    n_ist: ClassVar[int] = moving_loop.N_MOVING_IST
    fixed_goal: ClassVar[bool] = False

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
        base, ist, fst = self.base, self.ist, self.fst
        self.inputs = inputs = moving_inputs(settings, env, 1)
        self.pcg = state_from_generator(base.np_random)
        ist[moving_loop.I_HUNTER], ist[moving_loop.I_PREY] = base.hunter, base.prey_cell  # the env's state is the observation
        fst[state_layout.S_NORM] = math.nan
        fst[state_layout.S_LAST_ACT] = math.inf
        n_states, n_actions = self.q.shape
        self.dist = np.full(n_states, math.inf)
        self.succ = np.zeros((n_states, inputs.env.succ_width), dtype=np.int32)
        self.succ_n = np.zeros(n_states, dtype=np.int64)
        self.pred = np.zeros((n_states, inputs.env.pred_width), dtype=np.int32)
        self.pred_n = np.zeros(n_states, dtype=np.int64)
        self.goal = np.zeros(n_states, dtype=np.bool_)
        if agent.kind == agent_settings.AFFECT:
            self._read_appraisal()
        self.work = moving_loop.Work(
            np.empty(n_actions),
            np.empty(n_states + 1, dtype=np.int64),
            np.empty(TW_SIZE, dtype=np.int64),
            np.empty(inputs.env.cell_trans.shape[1] + 1, dtype=np.int64),
        )

    # -- appraisal in and out ------------------------------------------------------------------------------------
    def _read_appraisal(self) -> None:
        callback = self.model.emotion_callback
        kept = callback.appraiser.deferred("known")
        if isinstance(kept, MovingKnownArrays) and kept.fits(self):
            kept.copy_into(self)  # as the last compiled learn left it: no Python objects in between
        else:
            self._read_known(callback.appraiser.known)
        self.fit_vals = read_appraisal_scalars(callback, self.ist, self.fst)

    def _read_known(self, known: Any) -> None:
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

    def _write_appraisal(self) -> None:
        callback = self.model.emotion_callback
        known = MovingKnownArrays(self.dist, self.succ, self.succ_n, self.pred, self.pred_n, self.goal)
        callback.appraiser.defer("known", known)  # the run's arrays: this run is over, nothing writes them again
        write_appraisal_scalars(callback, self.ist, self.fst, self.fit_vals)

    # -- running -------------------------------------------------------------------------------------------------
    def step(self, alpha: np.ndarray, p: np.ndarray, total_timesteps: int, max_episodes: int) -> tuple[int, int]:
        """Run the kernel (``moving_loop.moving_loop``); returns (episodes finished, 0)."""
        announce_compile("the tabular agents' moving-prey loop (engine='compiled')", (moving_loop.moving_loop,),
                         MOVING_COMPILE_CPU_SECONDS)
        cells_before = self._room(max_episodes)
        inputs = self.inputs
        finished = moving_loop.moving_loop(
            inputs.env,
            inputs.config,
            self.agent.behaviour,
            moving_loop.RunState(self.q, self.mt, self.pcg, self.ist, self.fst, self.ucb_n, self.ucb_tot),
            ObsAppraisal(self.dist, self.succ, self.succ_n, self.pred, self.pred_n, self.goal, self.fit_vals),
            grid_arrays.Episodes(alpha, p, self.out_i, self.out_f),
            self.work,
            int(total_timesteps),
            int(max_episodes),
        )
        self._stepped(finished, cells_before)
        return int(finished), 0

    def monitor_episodes(self, cells: np.ndarray, truncated: np.ndarray) -> None:
        """The Monitor's bookkeeping of the episode ends the env reported (``compiled_run.monitor_episodes``)."""
        base = self.base
        limit = self.inputs.config.time_limit
        self.last_monitor_info = monitor_episodes(self.monitor, cells, truncated, limit, base.step_reward, base.goal_reward)

    def write_back(self) -> None:
        """Return every piece of state to the model, its generator, its appraisal, the env and its wrappers."""
        base = self.base
        state_to_generator(base.np_random, self.pcg)
        if self.agent.kind == agent_settings.AFFECT:
            self._write_appraisal()
        base.hunter, base.prey_cell = int(self.ist[moving_loop.I_HUNTER]), int(self.ist[moving_loop.I_PREY])
        self.model.greedy_optimal = None
        self._write_back(base.step_reward)

    def last_info(self) -> dict[str, Any]:
        """The env's info of the last decision of the last finished episode (what its ``step`` returned)."""
        size, n_cells = self.base.size, self.base.n_cells
        hunter, prey = divmod(self.last_s2, n_cells)
        return {"cell": divmod(hunter, size), "prey": divmod(prey, size), "moved": hunter != self.last_prev}

    @property
    def state(self) -> int:
        return int(self.ist[moving_loop.I_HUNTER]) * self.base.n_cells + int(self.ist[moving_loop.I_PREY])
