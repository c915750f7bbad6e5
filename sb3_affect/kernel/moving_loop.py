"""
The compiled decision loop on MovingPursuit (``sb3_affect.envs.moving_pursuit``): one tabular agent pursues a prey that
random-walks or evades. ``sb3_affect/agents/reference_loop.py`` with the agent's ``_decide`` and the env's ``step`` is
the reference; this loop does the same operations in the same order, so for the same seeds both give the identical
episode log, Q-table, the agent's ``random.Random`` state (``kernel.mt19937``) and the env's NumPy generator state
(``kernel.pcg64``: the prey's draws).

The env's step, as ``MovingPursuitEnv.step``: the hunter moves one cell (``cell_trans``), a capture when it enters the
prey's cell; otherwise, with probability ``prey_speed`` (one ``random()`` draw when the speed is above 0), the prey
moves: ``"random"`` to one of its four moves (``integers(4)``), ``"evade"`` to the candidate (staying or a neighbour,
never the hunter's cell) farthest from the hunter, ties sorted and drawn with ``integers``; never onto the hunter. The
observation is ``hunter * n_cells + prey``. The appraisal's known map is over observations (``decision.obs_known_add``).
The env has no fixed goal, so the ``optimal`` and ``greedy_optimal`` columns are NaN, as the Python loop gives them.

State crosses the boundary as arrays grouped in named tuples, as ``kernel.grid_loop``'s: ``PreyEnv``, ``Config``,
``agent_settings.BehaviourRows``, ``RunState`` (its ``ist`` and ``fst`` at ``state_layout``'s indices, ``ist`` with this
module's tail, ``mt`` the agent's MT19937 state, ``pcg`` the env's PCG64 state), ``decision.ObsAppraisal``,
``grid_arrays.Episodes`` and ``Work``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from sb3_affect.kernel.affect import known_add_goal
from sb3_affect.kernel.agent_settings import AFFECT, AgentSettings
from sb3_affect.kernel.choice import insert_tie
from sb3_affect.kernel.decision import ObsAppraisal, decide, end_episode, last_decision, obs_known_add, q_update
from sb3_affect.kernel.grid_arrays import Episodes
from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.mt19937 import STATE_SIZE, TW_SIZE, seed_state, temper_all
from sb3_affect.kernel.mt19937 import N as MT_N
from sb3_affect.kernel.pcg64 import integers, random01
from sb3_affect.kernel.state_layout import (
    I_CELLS,
    I_DECISIONS,
    I_EL_CELLS,
    I_EL_DECISIONS,
    I_JOY,
    I_RANDOM,
    I_T,
    I_TL_ELAPSED,
    I_WAITS,
    N_FST,
    N_IST,
    PREY_RANDOM,
    S_LAST_ACT,
    S_NORM,
    S_REWARD,
)


class PreyEnv(NamedTuple):
    """The env's moves (read only) and the widths of the known map over its observations (``decision.known_widths``)."""

    cell_trans: np.ndarray  # int64[n_cells, n_moves]: the cells' one-move table
    far: np.ndarray  # float64[n_cells, n_cells]: far[h, c], the distance from cell c to cell h (the evading prey's)
    succ_width: int
    pred_width: int


class Config(NamedTuple):
    """The run's fixed scalars (read only): the agent's and the env's."""

    agent: AgentSettings
    n_cells: int
    hunter_start: int
    prey_start: int
    prey: int  # state_layout.PREY_STATIC, PREY_RANDOM or PREY_EVADE
    time_limit: int  # the env's TimeLimit (0: none)
    goal_reward: float
    step_reward: float
    prey_speed: float
    n_actions: int


class RunState(NamedTuple):
    """The run's state (read and written): ``grid_arrays.RunState`` (``ist`` with its tail) and the env's generator."""

    q: np.ndarray
    mt: np.ndarray
    pcg: np.ndarray  # uint64[pcg64.STATE_SIZE]: the env's PCG64 state (the prey's draws)
    ist: np.ndarray  # int64[N_MOVING_IST]
    fst: np.ndarray  # float64[state_layout.N_FST]
    ucb_n: np.ndarray
    ucb_tot: np.ndarray


class Work(NamedTuple):
    """Work space: ``work`` (n_actions floats), ``queue`` (n_states + 1), ``tw`` (the random stream's tempered words),
    ``ties`` (n_moves + 1)."""

    work: np.ndarray
    queue: np.ndarray
    tw: np.ndarray
    ties: np.ndarray


class Seeds(NamedTuple):
    """Fresh runs' seeds: the agent's ``random.Random`` seed words (``keys``, ``lengths``) and the env's generator
    state after ``reset(seed=seed)`` (``pcg``), one row per run."""

    keys: np.ndarray
    lengths: np.ndarray
    pcg: np.ndarray


# ist: the run's int state, after state_layout's: the hunter's and the prey's cells
I_HUNTER, I_PREY = range(N_IST, N_IST + 2)
N_MOVING_IST = N_IST + 2


@kernel_inline
def move_prey(
    pcg: np.ndarray,
    cell_trans: np.ndarray,
    far: np.ndarray,
    prey_kind: int,
    speed: float,
    hunter: int,
    prey: int,
    ties: np.ndarray,
) -> int:
    """
    ``MovingPursuitEnv._move_prey``: the prey's cell after its chance to move (``far[h, c]``: distance c -> h;
    ``ties``: work space of ``n_moves + 1`` entries).
    """
    if speed <= 0.0 or random01(pcg) >= speed:
        return prey
    if prey_kind == PREY_RANDOM:
        target = cell_trans[prey, integers(pcg, cell_trans.shape[1])]
    else:
        target = evade_target(pcg, cell_trans, far, hunter, prey, prey, ties)
    return prey if target == hunter else target


@kernel_jit
def evade_target(
    pcg: np.ndarray, cell_trans: np.ndarray, far: np.ndarray, hunter: int, prey: int, fallback: int, ties: np.ndarray
) -> int:
    """
    The evading prey's move away from one hunter: among staying and the prey's moves, the cells other than the
    hunter's farthest from it; ties sorted ascending (in ``ties``, ``n_moves + 1`` entries of work space), one drawn
    with ``integers``. ``fallback`` when there is no candidate.
    """
    n_moves = cell_trans.shape[1]
    best = -math.inf
    count = 0
    for j in range(n_moves + 1):
        c = prey if j == 0 else cell_trans[prey, j - 1]
        if c == hunter:
            continue
        d = far[hunter, c]
        if d > best:
            best = d
            count = 0
        if d == best:
            count = insert_tie(ties, count, c)
    if count == 0:
        return fallback
    return ties[integers(pcg, count)]


@kernel_jit
def moving_loop(env, config, behaviour, state, appraisal, episodes, work, total_timesteps, max_episodes):
    """
    Run decisions until ``state.ist[I_T]`` reaches ``total_timesteps`` or ``max_episodes`` episodes have finished;
    episode ``j`` of this call (``j = 0``: the one in progress) learns with ``episodes.alpha[j]`` and explores with
    ``episodes.p[j]``. Finished episodes go to ``episodes.rows_i``/``rows_f``. The arguments: ``PreyEnv``, ``Config``,
    ``agent_settings.BehaviourRows``, ``RunState``, ``decision.ObsAppraisal``, ``grid_arrays.Episodes`` and ``Work``.
    Returns the
    episodes finished.
    """
    cell_trans, far = env.cell_trans, env.far
    q, mt, pcg, ist, fst = state.q, state.mt, state.pcg, state.ist, state.fst
    dist, succ, succ_n, pred, pred_n, goal, fit_vals = appraisal
    alpha_e, p_e, out_i, out_f = episodes
    queue, tw, ties = work.queue, work.tw, work.ties
    agent = config.agent
    kind = agent.kind
    n_cells = config.n_cells
    prey_kind = config.prey
    time_limit = config.time_limit
    cap = agent.cap
    units_cells = agent.units_cells
    jump = agent.jump
    gamma = agent.gamma
    goal_reward = config.goal_reward
    step_reward = config.step_reward
    speed = config.prey_speed

    r = mt[MT_N]
    temper_all(mt, tw)
    t = ist[I_T]
    hunter = ist[I_HUNTER]
    prey = ist[I_PREY]
    decisions = ist[I_DECISIONS]
    cells = ist[I_CELLS]
    random_moves = ist[I_RANDOM]
    waits = ist[I_WAITS]
    tl_elapsed = ist[I_TL_ELAPSED]
    el_cells = ist[I_EL_CELLS]
    el_decisions = ist[I_EL_DECISIONS]
    reward_sum = fst[S_REWARD]
    norm = fst[S_NORM]
    last_act = fst[S_LAST_ACT]
    episode = 0
    alpha = alpha_e[0]
    p = p_e[0]
    while t < total_timesteps:
        s = hunter * n_cells + prey
        elapsed = el_cells if units_cells else el_decisions
        action, k, explored, emotion, last_act, r = decide(
            agent, behaviour, state, work, s, r, p, norm, elapsed, last_act, dist
        )
        if kind == AFFECT:
            el_decisions += 1
            ist[I_JOY + emotion] += 1
        start_state = s
        jump_reward = 0.0
        before = reward_sum
        reward = 0.0
        prev = hunter
        terminated = truncated = False
        for _ in range(k):
            # the env's step
            prev = hunter
            hunter = cell_trans[hunter, action]
            terminated = hunter == prey
            if not terminated:
                prey = move_prey(pcg, cell_trans, far, prey_kind, speed, hunter, prey, ties)
            s2 = hunter * n_cells + prey
            reward = goal_reward if terminated else step_reward
            tl_elapsed += 1
            truncated = time_limit > 0 and tl_elapsed >= time_limit
            # the agent's update and appraisal
            if jump:
                jump_reward += reward
            else:
                q_update(q, s, action, reward, s2, terminated, alpha, gamma)
            if kind == AFFECT:
                el_cells += 1
                if terminated and reward > 0.0:
                    known_add_goal(dist, goal, pred, pred_n, s2, queue)
                obs_known_add(dist, succ, succ_n, pred, pred_n, s, s2, queue)
            cells += 1
            reward_sum += reward
            s = s2
            if terminated or truncated:
                break
        if jump and k > 0:
            q_update(q, start_state, action, jump_reward, s, terminated, alpha, gamma)
        if k == 0:
            waits += 1
        if explored:
            random_moves += 1
        decisions += 1
        t += 1
        if terminated or truncated or decisions >= cap:
            elapsed = el_cells if units_cells else el_decisions
            norm = end_episode(
                agent, out_i[episode], out_f[episode], ist, fst, fit_vals, decisions, cells, terminated, random_moves,
                waits, reward_sum, norm, elapsed,
            )  # fmt: skip
            episode += 1
            last_decision(ist, fst, action, prev, s, terminated, reward if k == 1 else reward_sum - before)
            # the next episode starts: the env's reset (its generator goes on)
            hunter = config.hunter_start
            prey = config.prey_start
            decisions = cells = random_moves = waits = tl_elapsed = 0
            reward_sum = 0.0
            if kind == AFFECT:
                el_cells = 0
                el_decisions = 0
            if episode >= max_episodes:
                break
            alpha = alpha_e[episode]
            p = p_e[episode]
    mt[MT_N] = r
    ist[I_T] = t
    ist[I_HUNTER] = hunter
    ist[I_PREY] = prey
    ist[I_DECISIONS] = decisions
    ist[I_CELLS] = cells
    ist[I_RANDOM] = random_moves
    ist[I_WAITS] = waits
    ist[I_TL_ELAPSED] = tl_elapsed
    ist[I_EL_CELLS] = el_cells
    ist[I_EL_DECISIONS] = el_decisions
    fst[S_REWARD] = reward_sum
    fst[S_NORM] = norm
    fst[S_LAST_ACT] = last_act
    return episode


@njit(cache=True)
def run_seeds(seeds, env, config, behaviour, episodes, n_episodes):
    """
    ``n_episodes`` episodes of a fresh run for each of ``seeds`` (``Seeds``); rows of run ``r`` go to
    ``episodes.rows_*[r * n_episodes ...]``, each run's episode ``j`` with ``episodes.alpha[j]``, ``episodes.p[j]``.
    The run's arrays are allocated once and reset for each run; returns the last run's ``(q, mt, pcg, dist)``.
    """
    n_cells = env.cell_trans.shape[0]
    n_states = n_cells * n_cells
    n_actions = config.n_actions
    state = RunState(
        np.empty((n_states, n_actions)),
        np.zeros(STATE_SIZE, dtype=np.int64),
        np.zeros(seeds.pcg.shape[1], dtype=np.uint64),
        np.empty(N_MOVING_IST, dtype=np.int64),
        np.empty(N_FST),
        np.empty((n_states, n_actions), dtype=np.int64),
        np.empty(n_states, dtype=np.int64),
    )
    appraisal = ObsAppraisal(
        np.empty(n_states),
        np.zeros((n_states, env.succ_width), dtype=np.int32),
        np.empty(n_states, dtype=np.int64),
        np.zeros((n_states, env.pred_width), dtype=np.int32),
        np.empty(n_states, dtype=np.int64),
        np.empty(n_states, dtype=np.bool_),
        np.zeros(n_episodes),
    )
    work = Work(
        np.empty(n_actions),
        np.empty(n_states + 1, dtype=np.int64),
        np.empty(TW_SIZE, dtype=np.int64),
        np.empty(env.cell_trans.shape[1] + 1, dtype=np.int64),
    )
    ist, fst = state.ist, state.fst
    affect = config.agent.kind == AFFECT
    for r in range(seeds.keys.shape[0]):
        state.q[:] = config.agent.q_init
        seed_state(state.mt, seeds.keys[r], seeds.lengths[r])
        state.pcg[:] = seeds.pcg[r]
        ist[:] = 0
        ist[I_HUNTER] = config.hunter_start
        ist[I_PREY] = config.prey_start
        fst[:] = 0.0
        fst[S_NORM] = math.nan
        fst[S_LAST_ACT] = math.inf
        appraisal.dist[:] = math.inf
        if affect:
            appraisal.succ_n[:] = 0
            appraisal.pred_n[:] = 0
            appraisal.goal[:] = False
        state.ucb_n[:] = 0
        state.ucb_tot[:] = 0
        lo, hi = r * n_episodes, (r + 1) * n_episodes
        rows = Episodes(episodes.alpha, episodes.p, episodes.rows_i[lo:hi], episodes.rows_f[lo:hi])
        moving_loop(env, config, behaviour, state, appraisal, rows, work, n_episodes * config.agent.cap, n_episodes)
    return state.q, state.mt, state.pcg, appraisal.dist
