"""
The compiled team of independent learners on HunterPursuit (``sb3_affect.agents.hunter_team.HunterTeam`` driving each hunter's
``DecisionStepper``, and ``envs.hunter_pursuit.HunterPursuitEnv``'s step, are the reference). For the same seeds it
gives the identical team log, each hunter's episode log, Q-table and ``random.Random`` state, the env's NumPy
generator state (``kernel.pcg64``: the prey's draws) and what the observers of the registry's emotion models record
of each hunter (``kernel.team_emotions``: each model's kernel module, as ``kernel.td_emotions`` is Broekens').

A round: every hunter decides in agent order (``decision.decide``); the round lasts as many env steps as the longest
decision, a hunter whose decision is over stays (``STAY``) and only observes. The env's step moves all hunters at
once (``"surround"``: not into the prey's cell), checks the capture, gives the prey its chance to move (``"random"``:
one of its four moves; ``"evade"``: the candidate farthest from its nearest hunter, ties sorted, never onto a hunter)
and checks a surround again. A hunter that moved in the step learns from it (``decision.q_update``, its appraisal's
known map over its observations); the episode ends for everyone at a capture, at ``max_cycles`` env steps or at the
team's cap of rounds. Hunter ``m``'s arrays are the ``m``-th of each stacked array. The env's own pieces (the
observations, the surround test, the prey's move) are in ``kernel.team_env``.
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any, NamedTuple

import numpy as np

from sb3_affect.kernel.affect import fit_add, known_add_goal, start_norm
from sb3_affect.kernel.agent_settings import AFFECT, AgentSettings, BehaviourRows
from sb3_affect.kernel.choice import row_max
from sb3_affect.kernel.decision import decide, obs_known_add, q_update
from sb3_affect.kernel.grid_arrays import RunState, Work
from sb3_affect.kernel.grid_loop import greedy_walks_shortest_path
from sb3_affect.kernel.jit import kernel_inline, kernel_jit
from sb3_affect.kernel.mt19937 import N as MT_N
from sb3_affect.kernel.mt19937 import temper_all
from sb3_affect.kernel.state_layout import (
    F_NORM,
    F_REWARD,
    I_CELLS,
    I_CHANGED,
    I_DECISIONS,
    I_EL_CELLS,
    I_EL_DECISIONS,
    I_GREEDY,
    I_JOY,
    I_LAST_S2,
    I_NFIT,
    I_RANDOM,
    I_STATE,
    I_WAITS,
    N_FST,
    N_IST,
    N_OUT_F,
    O_CELLS,
    O_DECISIONS,
    O_GREEDY,
    O_JOY,
    O_OPTIMAL,
    O_RANDOM,
    O_TRUNCATED,
    O_WAITS,
    PREY_STATIC,
    S_FIT0,
    S_LAST_ACT,
    S_LAST_REWARD,
    S_NORM,
    S_REWARD,
)
from sb3_affect.kernel.team_env import encode, surrounded, team_prey


class TeamEnv(NamedTuple):
    """The env's arrays (read only): the cells' one-move table, ``far[h, c]`` (the evading prey's distances, else a
    1 x 1 placeholder), ``tdist`` the distances to the prey's start, the hunters' start cells."""

    cell_trans: np.ndarray  # int64[n_cells, n_moves]
    far: np.ndarray  # float64[n_cells, n_cells]
    tdist: np.ndarray  # float64[n_cells]
    hunter_starts: np.ndarray  # int64[hunters]


class Config(NamedTuple):
    """The env's fixed scalars (read only)."""

    n_cells: int
    prey_start: int
    prey: int  # state_layout.PREY_STATIC, PREY_RANDOM or PREY_EVADE
    surround: bool  # capture="surround" (else "enter")
    obs_all: bool  # observation="all" (else "self")
    max_cycles: int  # 0: none
    capture_distance: int
    geometry: bool  # a static prey entered by hunters observing only themselves: optimal and greedy columns apply
    goal_reward: float
    step_reward: float
    prey_speed: float


#: Every hunter's ``AgentSettings`` as arrays, one entry per hunter (read only; ``hunter`` reads one).
Hunters: Any = namedtuple("Hunters", AgentSettings._fields)  # type: ignore[misc]


class TeamState(NamedTuple):
    """The run's state (read and written), one row per hunter first: Q-tables, random streams (``mt``, ``tw`` their
    tempered words), UCB counts, run scalars (``ist``, ``fst``); the env's generator and the hunters' cells."""

    q: np.ndarray  # float64[hunters, n_states, n_actions]
    mt: np.ndarray  # int64[hunters, mt19937.STATE_SIZE]
    tw: np.ndarray  # int64[hunters, mt19937.TW_SIZE]
    ucb_n: np.ndarray  # int64[hunters, n_states, n_actions]
    ucb_tot: np.ndarray  # int64[hunters, n_states]
    ist: np.ndarray  # int64[hunters, N_TEAM_IST]
    fst: np.ndarray  # float64[hunters, S_OBSERVER + the emotion models' state]
    pcg: np.ndarray  # uint64[pcg64.STATE_SIZE]
    cells: np.ndarray  # int64[hunters]


class TeamEpisodes(NamedTuple):
    """Per hunter and episode its parameters (read); the rows of each hunter and of the team (written)."""

    alpha: np.ndarray  # float64[hunters, episodes]
    p: np.ndarray  # float64[hunters, episodes]
    rows_i: np.ndarray  # int64[hunters, episodes, N_OUT_I]
    rows_f: np.ndarray  # float64[hunters, episodes, F_OBSERVER + the emotion models' columns]
    team_i: np.ndarray  # int64[episodes, N_TEAM_I]
    team_f: np.ndarray  # float64[episodes]: the team's reward


class TeamWork(NamedTuple):
    """Work space: ``work`` (n_actions floats), ``queue`` (n_states + 1), ``seen`` (hunters x n_states zeros),
    ``stack`` (n_states * n_actions + 1), ``ties`` (5)."""

    work: np.ndarray
    queue: np.ndarray
    seen: np.ndarray
    stack: np.ndarray
    ties: np.ndarray


@kernel_inline
def hunter(hunters: Any, m: int) -> AgentSettings:
    """Hunter ``m``'s ``AgentSettings``."""
    return AgentSettings(
        hunters.kind[m],
        hunters.cap[m],
        hunters.act_episode[m],
        hunters.units_cells[m],
        hunters.valence[m],
        hunters.tie_first[m],
        hunters.jump[m],
        hunters.compensated_sum[m],
        hunters.gamma[m],
        hunters.norm_scale[m],
        hunters.ucb_coef[m],
        hunters.q_init[m],
    )


# out_i[m, episode]: each hunter's episode row (state_layout's ints); out_f[m, episode]: its floats, then its
# emotion models' columns from F_OBSERVER (team_emotions.Observers.out_at)
F_OBSERVER = N_OUT_F
# team_i[episode]: the team's row (team_f[episode]: its reward)
T_ROUNDS, T_STEPS, T_OPTIMAL, T_TRUNCATED, T_CAPTURER = range(5)
N_TEAM_I = 5


@kernel_jit
def team_loop(env, config, hunters, behaviour, state, appraisal, episodes, work, observers, n_episodes):
    """
    Run ``n_episodes`` team episodes of a fresh run (the arrays as a new team has them). The arguments: ``TeamEnv``,
    ``Config``, ``Hunters``, ``agent_settings.BehaviourRows`` (one row per hunter first), ``TeamState``,
    ``decision.ObsAppraisal`` (one row per hunter first), ``TeamEpisodes``, ``TeamWork`` and the emotion models'
    ``team_emotions.Observers``.
    """
    cell_trans, far, tdist, hunter_starts = env
    q, mt, tw, ucb_n, ucb_tot, ist, fst, pcg, cells_of = state
    dist, succ, succ_n, pred, pred_n, goal, fit_vals = appraisal
    alpha_e, p_e, out_i, out_f, team_i, team_f = episodes
    state_at, out_at = observers.state_at, observers.out_at
    queue, seen, stack, ties = work.queue, work.seen, work.stack, work.ties
    n_cells = config.n_cells
    prey_kind = config.prey
    surround = config.surround
    obs_all = config.obs_all
    max_cycles = config.max_cycles
    geometry = config.geometry
    prey_moves = prey_kind != PREY_STATIC
    goal_reward = config.goal_reward
    step_reward = config.step_reward
    speed = config.prey_speed
    n = cells_of.shape[0]
    team_cap = hunters.cap[0]
    for m in range(1, n):
        team_cap = min(team_cap, hunters.cap[m])
    shortest = np.int64(-1)
    # the run starts: the env at its start, each hunter's first observation and its observers' first value
    prey = config.prey_start
    for m in range(n):
        cells_of[m] = hunter_starts[m]
    for m in range(n):
        temper_all(mt[m], tw[m])
        ist[m, I_R] = mt[m, MT_N]
        ist[m, I_STATE] = encode(cells_of, prey, m, n_cells, obs_all, prey_moves)
        ist[m, I_GREEDY] = -1
        ist[m, I_CHANGED] = 1
        fst[m, S_NORM] = math.nan
        fst[m, S_LAST_ACT] = math.inf
        observers_start(observers, fst[m, S_OBSERVER:], row_max(q[m], ist[m, I_STATE]))
    episode = 0
    rounds = 0
    steps = 0
    team_reward = 0.0
    while episode < n_episodes:
        # every hunter decides
        length = 0
        for m in range(n):
            h = hunter(hunters, m)
            s = ist[m, I_STATE]
            elapsed = ist[m, I_EL_CELLS] if h.units_cells else ist[m, I_EL_DECISIONS]
            action, k, explored, emotion, last_act, r = decide(
                h,
                BehaviourRows(behaviour.random[m], behaviour.speeds[m], behaviour.n[m]),
                RunState(q[m], mt[m], ist[m], fst[m], ucb_n[m], ucb_tot[m]),
                Work(work.work, seen[m], stack, queue, tw[m]),
                s,
                ist[m, I_R],
                p_e[m, episode],
                fst[m, S_NORM],
                elapsed,
                fst[m, S_LAST_ACT],
                dist[m],
            )
            ist[m, I_R] = r
            fst[m, S_LAST_ACT] = last_act
            if h.kind == AFFECT:
                ist[m, I_EL_DECISIONS] += 1
                ist[m, I_JOY + emotion] += 1
            ist[m, I_ACTION] = action
            ist[m, I_K] = k
            ist[m, I_EXPLORED] = 1 if explored else 0
            ist[m, I_START] = s
            ist[m, I_ENDED] = 0
            fst[m, S_DECISION_REWARD] = 0.0
            fst[m, S_JUMP_REWARD] = 0.0
            length = max(length, k)
        captured = truncated = False
        capturer = -1
        for j in range(length):
            # the env's step: every hunter at once
            for m in range(n):
                before = cells_of[m]
                target = before if j >= ist[m, I_K] else cell_trans[before, ist[m, I_ACTION]]
                if surround and target == prey:
                    target = before
                cells_of[m] = target
            steps += 1
            if surround:
                captured = surrounded(cells_of, prey, cell_trans)
            else:
                for m in range(n):
                    if cells_of[m] == prey:
                        captured = True
            if not captured:
                prey = team_prey(pcg, cell_trans, far, prey_kind, speed, cells_of, prey, ties)
                if surround:
                    captured = surrounded(cells_of, prey, cell_trans)
            truncated = not captured and max_cycles > 0 and steps >= max_cycles
            step_sum = 0.0
            for m in range(n):
                rewarded = captured and (surround or cells_of[m] == prey)
                reward = goal_reward if rewarded else step_reward
                step_sum += reward
                s2 = encode(cells_of, prey, m, n_cells, obs_all, prey_moves)
                if j < ist[m, I_K]:
                    # the hunter's transition (DecisionStepper.transition)
                    ended = captured and rewarded
                    ist[m, I_ENDED] = 1 if ended else 0
                    s = ist[m, I_STATE]
                    action = ist[m, I_ACTION]
                    if hunters.jump[m]:
                        fst[m, S_JUMP_REWARD] += reward
                    elif q_update(q[m], s, action, reward, s2, ended, alpha_e[m, episode], hunters.gamma[m]):
                        ist[m, I_CHANGED] = 1
                    if hunters.kind[m] == AFFECT:
                        ist[m, I_EL_CELLS] += 1
                        if ended and reward > 0.0:
                            known_add_goal(dist[m], goal[m], pred[m], pred_n[m], s2, queue)
                        obs_known_add(dist[m], succ[m], succ_n[m], pred[m], pred_n[m], s, s2, queue)
                    ist[m, I_CELLS] += 1
                    fst[m, S_REWARD] += reward
                    fst[m, S_DECISION_REWARD] += reward
                    ist[m, I_LAST_S2] = s2
                    fst[m, S_LAST_REWARD] = reward
                ist[m, I_STATE] = s2
                if captured and rewarded and capturer < 0:
                    capturer = m
            team_reward += step_sum
            if captured or truncated:
                break
        rounds += 1
        over = captured or truncated or rounds >= team_cap
        if over:  # the env's reset (its generator goes on)
            prey = config.prey_start
            for m in range(n):
                cells_of[m] = hunter_starts[m]
        # every hunter closes its decision (DecisionStepper.end_decision), then its observers see it
        for m in range(n):
            h = hunter(hunters, m)
            ended = ist[m, I_ENDED] != 0
            k = ist[m, I_K]
            jump = h.jump and k > 0
            if jump and q_update(
                q[m], ist[m, I_START], ist[m, I_ACTION], fst[m, S_JUMP_REWARD], ist[m, I_STATE], ended,
                alpha_e[m, episode], h.gamma,
            ):  # fmt: skip
                ist[m, I_CHANGED] = 1
            if k == 0:
                ist[m, I_WAITS] += 1
                ist[m, I_LAST_S2] = ist[m, I_STATE]
                fst[m, S_LAST_REWARD] = 0.0
            if ist[m, I_EXPLORED] != 0:
                ist[m, I_RANDOM] += 1
            ist[m, I_DECISIONS] += 1
            # the observers: the decision's reward and the value reached
            observer = fst[m, S_OBSERVER:]
            cut = over and not ended
            reached = 0.0 if over and not cut else row_max(q[m], ist[m, I_LAST_S2] if over else ist[m, I_STATE])
            for o in range(len(observers.observe)):
                observers.observe[o](observer[state_at[o] :], fst[m, S_DECISION_REWARD], h.gamma, reached)
            if over:
                row = out_i[m, episode]
                cells = ist[m, I_CELLS]
                row[O_DECISIONS] = ist[m, I_DECISIONS]
                row[O_CELLS] = cells
                row[O_TRUNCATED] = 0 if ended else 1
                row[O_RANDOM] = ist[m, I_RANDOM]
                row[O_WAITS] = ist[m, I_WAITS]
                for e in range(4):
                    row[O_JOY + e] = ist[m, I_JOY + e]
                    ist[m, I_JOY + e] = 0
                if geometry:
                    shortest = np.int64(tdist[hunter_starts[m]])
                    row[O_OPTIMAL] = 1 if ended and cells == shortest else 0
                    if ist[m, I_CHANGED] != 0 or ist[m, I_GREEDY] < 0:
                        ist[m, I_WALKS] += 1
                        walked = greedy_walks_shortest_path(
                            q[m], cell_trans, tdist, hunter_starts[m], seen[m], ist[m, I_WALKS], stack
                        )
                        ist[m, I_GREEDY] = 1 if walked else 0
                    row[O_GREEDY] = ist[m, I_GREEDY]
                ist[m, I_CHANGED] = 0
                decisions = float(ist[m, I_DECISIONS])
                frow = out_f[m, episode]
                frow[F_REWARD] = fst[m, S_REWARD]
                frow[F_NORM] = fst[m, S_NORM] if h.kind == AFFECT else math.nan
                for o in range(len(observers.close_episode)):
                    observers.close_episode[o](observer[state_at[o] :], frow[F_OBSERVER + out_at[o] :], decisions, cut)
                if h.kind == AFFECT:
                    fsum = fst[m, S_FIT0 : S_FIT0 + 4]
                    y = ist[m, I_EL_CELLS] if h.units_cells else ist[m, I_EL_DECISIONS]
                    ist[m, I_NFIT] = fit_add(fit_vals[m], fsum, ist[m, I_NFIT], float(y))
                    ist[m, I_EL_CELLS] = 0
                    ist[m, I_EL_DECISIONS] = 0
                    fst[m, S_NORM] = start_norm(fit_vals[m], fsum, ist[m, I_NFIT], h.norm_scale)
                # the next episode
                ist[m, I_STATE] = encode(cells_of, prey, m, n_cells, obs_all, prey_moves)
                ist[m, I_DECISIONS] = ist[m, I_CELLS] = ist[m, I_RANDOM] = ist[m, I_WAITS] = 0
                fst[m, S_REWARD] = 0.0
                observers_start(observers, observer, row_max(q[m], ist[m, I_STATE]))
        if over:
            team_i[episode, T_ROUNDS] = rounds
            team_i[episode, T_STEPS] = steps
            team_i[episode, T_TRUNCATED] = 0 if captured else 1
            team_i[episode, T_CAPTURER] = capturer
            team_i[episode, T_OPTIMAL] = 1 if captured and team_optimal(out_i, episode, config) else 0
            team_f[episode] = team_reward
            episode += 1
            rounds = 0
            steps = 0
            team_reward = 0.0
    for m in range(n):
        mt[m, MT_N] = ist[m, I_R]


@kernel_inline
def observers_start(observers: Any, observer: np.ndarray, value: float) -> None:
    """Every emotion model's observer of a hunter (``observer``: its floats) starts an episode in a state of ``value``."""
    for o in range(len(observers.start)):
        observers.start[o](observer[observers.state_at[o] :], value)


@kernel_inline
def team_optimal(out_i: np.ndarray, episode: int, config: Config) -> bool:
    """
    ``HunterPursuitEnv.optimal_capture`` of the episode's rows: with ``"enter"`` the fewest moves of a hunter
    rewarded for the capture (a hunter's row ended at the goal: ``truncated`` 0), with ``"surround"`` the most moves
    of any hunter, at most the capture distance.
    """
    bound = config.capture_distance
    if config.surround:
        most = 0
        for m in range(out_i.shape[0]):
            most = max(most, out_i[m, episode, O_CELLS])
        return most <= bound
    fewest = -1
    for m in range(out_i.shape[0]):
        if out_i[m, episode, O_TRUNCATED] == 0:
            cells = out_i[m, episode, O_CELLS]
            fewest = cells if fewest < 0 else min(fewest, cells)
    return 0 <= fewest <= bound


# ist[m]: hunter m's run state (int), after state_layout's: its random stream's index and its decision in progress
(I_R, I_ACTION, I_K, I_EXPLORED, I_START, I_ENDED, I_WALKS) = range(N_IST, N_IST + 7)
N_TEAM_IST = N_IST + 7
# fst[m]: hunter m's run state (float), after state_layout's: its decision's rewards, then its emotion models' states
S_DECISION_REWARD, S_JUMP_REWARD = range(N_FST, N_FST + 2)
S_OBSERVER = N_FST + 2  # S_OBSERVER..: the observers' states (team_emotions.Observers.state_at)
