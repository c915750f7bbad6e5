"""
The compiled decision loop on a transition table (GridPursuit, MazePursuit): ``sb3_affect.agents.reference_loop.run_loop``
with the agent's ``_decide``, the appraisal and the env's moves, in numba; the decision and Eq. 1 are ``kernel.decision``'s,
which the moving-prey and team loops call too. ``agents/reference_loop.py`` is the readable reference; this file does
the same operations in the same order (same random draws, same floating-point expressions), so both give the same
episode log and Q-table.

State crosses the boundary as arrays, grouped in a few named tuples (``sb3_affect.kernel.grid_arrays``; numba passes
each as one argument): ``EnvTable``, ``Config``, ``agent_settings.BehaviourRows``, ``RunState``, ``Appraisal``,
``Episodes`` and
``Work``. The caller fills them and reads them back after the call.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sb3_affect.kernel.affect import known_add, known_add_goal
from sb3_affect.kernel.agent_settings import AFFECT
from sb3_affect.kernel.choice import row_max
from sb3_affect.kernel.decision import decide, end_episode, last_decision, q_update
from sb3_affect.kernel.grid_arrays import STOP_EPISODES, STOP_TIMESTEPS, work_space
from sb3_affect.kernel.jit import kernel_jit
from sb3_affect.kernel.mt19937 import N as MT_N
from sb3_affect.kernel.mt19937 import temper_all
from sb3_affect.kernel.state_layout import (
    I_CELLS,
    I_CHANGED,
    I_DECISIONS,
    I_EL_CELLS,
    I_EL_DECISIONS,
    I_GREEDY,
    I_JOY,
    I_RANDOM,
    I_STATE,
    I_T,
    I_TL_ELAPSED,
    I_WAITS,
    O_GREEDY,
    O_OPTIMAL,
    S_LAST_ACT,
    S_NORM,
    S_REWARD,
)


@kernel_jit
def greedy_walks_shortest_path(
    q: np.ndarray, trans: np.ndarray, tdist: np.ndarray, start: int, seen: np.ndarray, stamp: int, stack: np.ndarray
) -> bool:
    """
    ``episode_log.greedy_walks_shortest_path`` (its answer does not depend on the visiting order). ``seen`` (int64,
    one entry per cell) marks the cells this call visited with ``stamp``, which the caller makes new on every call
    (no clearing); ``stack`` (``n_states * n_actions + 1`` entries) is work space.
    """
    stack[0] = start
    top = 1
    while top > 0:
        top -= 1
        s = stack[top]
        d = tdist[s]
        if d == 0 or seen[s] == stamp:
            continue
        seen[s] = stamp
        best = row_max(q, s)
        for a in range(q.shape[1]):
            if q[s, a] == best:
                t = trans[s, a]
                if tdist[t] != d - 1:
                    return False
                stack[top] = t
                top += 1
    return True


@njit(cache=True)
def run(env, config, behaviour, state, appraisal, episodes, total_timesteps, max_episodes):
    """
    Run decisions until ``num_timesteps`` reaches ``total_timesteps`` or ``max_episodes`` episodes have finished.

    Episode ``j`` of this call (``j = 0``: the one in progress) learns with ``episodes.alpha[j]`` and explores with
    ``episodes.p[j]`` (epsilon, or the inverse temperature). After an episode ends the next one is started (the env
    reset to its start, the appraisal's new norm), as the Python loop does. Returns ``(episodes finished,
    STOP_TIMESTEPS or STOP_EPISODES)``.

    This allocates the work space and calls ``decision_loop``, the loop itself.
    """
    n_states, n_actions = state.q.shape
    work = work_space(n_states, n_actions)
    return decision_loop(env, config, behaviour, state, appraisal, episodes, work, total_timesteps, max_episodes)


@kernel_jit
def decision_loop(env, config, behaviour, state, appraisal, episodes, work, total_timesteps, max_episodes):
    """
    ``run``'s loop (the arguments: the named tuples of this module).

    Writes: ``state`` (the Q-table ``q``; the random stream ``mt``; ``ist`` and ``fst``, the run's scalars, which live
    in locals during the loop and go back when it returns; UCB's ``ucb_n`` and ``ucb_tot``), ``appraisal`` (the
    known map and the power fit, AffectQ only), ``episodes.rows_i`` and ``episodes.rows_f`` (one row per finished
    episode) and ``work``. Reads only: ``env``, ``config``, ``behaviour``, ``episodes.alpha`` and ``episodes.p``.
    Q-table changes mark the greedy walk's answer out of date only in rows that walk read (``seen[s] == walks``):
    the walk reads no other row, so a change elsewhere can not change its answer.
    """
    trans, tdist = env.trans, env.tdist
    q, mt, ist, fst = state.q, state.mt, state.ist, state.fst
    dist, edge, pred, pred_n, goal, fit_vals = appraisal
    alpha_e, p_e, out_i, out_f = episodes
    seen, stack, queue, tw = work.seen, work.stack, work.queue, work.tw
    agent = config.agent
    kind = agent.kind
    goal_state = config.goal
    start_state = config.start
    shortest = config.shortest
    time_limit = config.time_limit
    cap = agent.cap
    units_cells = agent.units_cells
    jump = agent.jump
    gamma = agent.gamma
    goal_reward = config.goal_reward
    step_reward = config.step_reward

    r = mt[MT_N]  # the random stream's index
    temper_all(mt, tw)
    t = ist[I_T]
    s = ist[I_STATE]
    decisions = ist[I_DECISIONS]
    cells = ist[I_CELLS]
    random_moves = ist[I_RANDOM]
    waits = ist[I_WAITS]
    changed = ist[I_CHANGED] != 0
    greedy_optimal = ist[I_GREEDY]
    tl_elapsed = ist[I_TL_ELAPSED]
    el_cells = ist[I_EL_CELLS]
    el_decisions = ist[I_EL_DECISIONS]
    reward_sum = fst[S_REWARD]
    norm = fst[S_NORM]
    last_act = fst[S_LAST_ACT]
    episode = 0
    walks = 0
    alpha = alpha_e[0]
    p = p_e[0]
    s2 = s
    reward = 0.0
    terminated = False
    truncated = False
    action = 0
    prev = s
    stop = STOP_TIMESTEPS
    while t < total_timesteps:
        # 1. decide: the emotion (AffectQ), direction and speed
        elapsed = el_cells if units_cells else el_decisions
        action, k, explored, emotion, last_act, r = decide(
            agent, behaviour, state, work, s, r, p, norm, elapsed, last_act, dist
        )
        if kind == AFFECT:
            el_decisions += 1
            ist[I_JOY + emotion] += 1
        # 2. move k cells, one Eq. 1 update per cell (or one for the whole move)
        start_cell = s
        jump_reward = 0.0
        before = reward_sum
        for _ in range(k):
            s2 = trans[s, action]
            terminated = s2 == goal_state
            reward = goal_reward if terminated else step_reward
            tl_elapsed += 1
            truncated = time_limit > 0 and tl_elapsed >= time_limit
            if jump:
                jump_reward += reward
            else:
                if q_update(q, s, action, reward, s2, terminated, alpha, gamma):
                    changed |= seen[s] == walks  # (only a row the last greedy walk read can change its answer)
            if kind == AFFECT:
                el_cells += 1
                if terminated:
                    known_add_goal(dist, goal, pred, pred_n, s2, queue)
                if s != s2 and not edge[s, action]:  # (known_add's own first check, without the call)
                    known_add(dist, edge, pred, pred_n, trans, s, action, s2, queue)
            cells += 1
            reward_sum += reward
            prev = s
            s = s2
            if terminated or truncated:
                break
        if jump and k > 0 and q_update(q, start_cell, action, jump_reward, s, terminated, alpha, gamma):
            changed |= seen[start_cell] == walks
        if k == 0:
            waits += 1
        if explored:
            random_moves += 1
        decisions += 1
        t += 1
        # 3. episode end: at the goal, by the env's time limit, or by the safety cap
        if terminated or truncated or decisions >= cap:
            row = out_i[episode]
            row[O_OPTIMAL] = 1 if terminated and cells == shortest else 0
            if changed or greedy_optimal < 0:
                walks += 1
                greedy_optimal = 1 if greedy_walks_shortest_path(q, trans, tdist, start_state, seen, walks, stack) else 0
            row[O_GREEDY] = greedy_optimal
            changed = False
            elapsed = el_cells if units_cells else el_decisions
            norm = end_episode(
                agent, row, out_f[episode], ist, fst, fit_vals, decisions, cells, terminated, random_moves, waits,
                reward_sum, norm, elapsed,
            )  # fmt: skip
            episode += 1
            # the decision's reward, as callbacks get it
            last_decision(ist, fst, action, prev, s2, terminated, reward if k == 1 else reward_sum - before)
            # the next episode starts
            s = start_state
            decisions = cells = random_moves = waits = tl_elapsed = 0
            reward_sum = 0.0
            terminated = truncated = False
            if kind == AFFECT:
                el_cells = 0
                el_decisions = 0
            if episode >= max_episodes:
                stop = STOP_EPISODES
                break
            alpha = alpha_e[episode]
            p = p_e[episode]
    mt[MT_N] = r
    ist[I_T] = t
    ist[I_STATE] = s
    ist[I_DECISIONS] = decisions
    ist[I_CELLS] = cells
    ist[I_RANDOM] = random_moves
    ist[I_WAITS] = waits
    ist[I_CHANGED] = 1 if changed else 0
    ist[I_GREEDY] = greedy_optimal
    ist[I_TL_ELAPSED] = tl_elapsed
    ist[I_EL_CELLS] = el_cells
    ist[I_EL_DECISIONS] = el_decisions
    fst[S_REWARD] = reward_sum
    fst[S_NORM] = norm
    fst[S_LAST_ACT] = last_act
    return episode, stop
