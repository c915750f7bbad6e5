"""
The reference decision loop of the tabular agents, readable top to bottom.

A *decision* picks a direction and a number of cells ``k``; it makes ``k`` ordinary one-cell transitions, each with
its own Eq. 1 update (``multi_cell="jump"``: one update for the whole move), all in the same direction, stopping
early at the goal; ``k = 0`` is a wait. ``num_timesteps`` counts decisions. ``TabularQAlgorithm.learn`` runs this
loop (``engine="python"``) or its compiled twin in ``sb3_affect.kernel`` (same seed, same results).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback, ConvertCallback

if TYPE_CHECKING:  # (annotations only: the loop's helpers import neither torch nor the algorithm)
    from sb3_affect.agents.qtable import LoopTable
    from sb3_affect.core.episode_log import Rows
    from sb3_affect.core.goals import GoalTest

#: The ``dones`` of a one-env VecEnv step (read-only, shared).
DONE = np.array([True])
NOT_DONE = np.array([False])
DONE.flags.writeable = False
NOT_DONE.flags.writeable = False


class LoopParts(NamedTuple):
    """What a run's Python loop takes from its agent (``TabularQAlgorithm.loop_parts``)."""

    #: the loop's Q-table, a list of rows (synced to the policy's tensor by ``end_run``)
    q: LoopTable
    #: ``(state, q) -> (action, cells to move, whether the direction was random)``
    decide: Callable[[int, Rows], tuple[int, int, bool]]
    #: ``(s, s2, reached_goal)`` after every one-cell transition (the appraisal's), or None
    observe: Callable[[int, int, bool], Any] | None
    #: whether a terminal transition reached the goal
    is_goal: GoalTest


class LoopAgent(Protocol):
    """The public run methods of ``TabularQAlgorithm`` the loop calls (the agent keeps its state; see its docs)."""

    gamma: float
    max_episode_decisions: int
    multi_cell: str
    num_timesteps: int
    observation_space: Any
    action_space: Any

    @property
    def alpha(self) -> float: ...

    def loop_parts(self) -> LoopParts: ...

    def resume_episode(self, total_timesteps: int) -> dict[str, Any]: ...

    def begin_episode(self, total_timesteps: int) -> float: ...

    def keep_episode(self, episode: dict[str, Any]) -> None: ...

    def close_episode(
        self,
        decisions: int,
        cells: int,
        reward: float,
        random_moves: int,
        waits: int,
        terminated: bool,
        truncated: bool,
        q_changed: bool,
        log_interval: int | None,
        reached_goal: bool | None = None,
        info: dict[str, Any] | None = None,
    ) -> None: ...


def run_loop(
    model: LoopAgent,
    env: Any,
    total_timesteps: int,
    callback: BaseCallback,
    log_interval: int | None,
) -> None:
    """
    Take decisions until ``total_timesteps`` (or a callback stops): decide, move ``k`` cells with their Eq. 1
    updates, close finished episodes, call the callbacks. (``sb3_affect.agents.stepping.DecisionStepper`` takes the same
    steps one decision at a time, with the same calls.)

    :param model: the agent, after its ``start_run`` (its ``loop_parts``, its episode in progress, its episode ends)
    :param env: the single (Monitor-wrapped) Gymnasium env
    :param total_timesteps: stop once ``model.num_timesteps`` reaches this many decisions
    :param callback: SB3 callback(s), called once per decision with a one-env VecEnv's locals
    :param log_interval: dump the logger every this many episodes (None: never)
    """
    gamma = model.gamma
    cap = model.max_episode_decisions
    q, decide, observe, is_goal = model.loop_parts()
    jump = model.multi_cell == "jump"
    obs_start = int(model.observation_space.start)
    act_start = int(model.action_space.start)
    cb_locals: dict[str, Any] = {"self": model, "total_timesteps": total_timesteps, "callback": callback}
    update_locals = callback.update_locals
    on_step = callback.on_step
    # learn(callback=None) without a progress bar: nothing to call per decision
    call_back = not (isinstance(callback, ConvertCallback) and callback.callback is None)

    # the episode in progress (continued across learn(reset_num_timesteps=False) calls, or begun now)
    episode = model.resume_episode(total_timesteps)
    s, decisions, cells, random_moves, waits, reward_sum = (
        episode["state"],
        episode["decisions"],
        episode["cells"],
        episode["random_moves"],
        episode["waits"],
        episode["reward"],
    )
    alpha = model.alpha
    s2, reward, terminated, truncated, info, action = s, 0.0, False, False, {}, 0

    t = model.num_timesteps
    changed = True  # whether the Q-table changed since the last greedy-path check
    while t < total_timesteps:
        # 1. decide: direction and speed (epsilon-greedy, or the emotion's behaviour)
        action, k, explored = decide(s, q)
        before = reward_sum
        # 2. move k cells, one Eq. 1 update per cell (multi_cell="jump": one for the whole move, below)
        start_cell, jump_reward = s, 0.0
        cell_rewards: list[float] = []  # this decision's rewards, one per cell (callbacks that discount per cell)
        for _ in range(k):
            obs, r, terminated, truncated, info = env.step(action + act_start)
            s2 = int(obs) - obs_start
            reward = float(r)
            cell_rewards.append(reward)
            if jump:
                jump_reward += reward
            elif q_update(q, s, action, reward, s2, terminated, alpha, gamma):
                changed = True
            if observe is not None:
                observe(s, s2, terminated and is_goal(reward, info))
            cells += 1
            reward_sum += reward
            s = s2
            if terminated or truncated:
                break
        if jump and k > 0 and q_update(q, start_cell, action, jump_reward, s, terminated, alpha, gamma):
            changed = True
        if k == 0:  # a wait: no env step, nothing of the previous step to report again
            waits += 1
            s2, reward, info = s, 0.0, {"wait": True}
        if explored:
            random_moves += 1
        decisions += 1
        t += 1
        # 3. episode end: at the goal, by the env's time limit, or by the safety cap
        done = terminated or truncated or decisions >= cap
        if call_back:
            step_reward = reward if k == 1 else reward_sum - before
            if done:  # what a VecEnv adds to the last info of an episode (before the reset below)
                info = episode_end_info(info, s2 + obs_start, terminated)
        if done:
            model.num_timesteps = t
            model.close_episode(
                decisions,
                cells,
                reward_sum,
                random_moves,
                waits,
                terminated,
                not terminated,
                changed,
                log_interval,
                reached_goal=terminated and is_goal(reward, info),
                info=info,
            )
            changed = False
            obs, _ = env.reset()
            s = int(obs) - obs_start
            decisions = cells = random_moves = waits = 0
            reward_sum = 0.0
            terminated = truncated = False
            alpha = model.begin_episode(total_timesteps)
        # 4. callbacks, once per decision, with the locals of a one-env VecEnv step
        if call_back:
            model.num_timesteps = t
            step_locals(cb_locals, s + obs_start, step_reward, done, info, action + act_start)
            cb_locals["cell_rewards"] = cell_rewards  # each cell's reward (an emotion model may discount per cell)
            update_locals(cb_locals)
            if not on_step():
                break
    model.num_timesteps = t
    model.keep_episode(
        {
            "state": s,
            "decisions": decisions,
            "cells": cells,
            "random_moves": random_moves,
            "waits": waits,
            "reward": reward_sum,
        }
    )


def q_update(
    q: LoopTable, s: int, action: int, reward: float, s2: int, terminated: bool, alpha: float, gamma: float
) -> bool:
    """
    Eq. 1 for ``q[s][action]`` after a move to ``s2`` with ``reward`` (``multi_cell="jump"``: the whole move, its
    summed reward); returns whether the entry changed. (The kernel's twin: ``sb3_affect.kernel.decision.q_update``.)
    """
    row = q[s]
    old = row[action]
    new = old + alpha * ((reward if terminated else reward + gamma * max(q[s2])) - old)
    if new != old:
        row[action] = new
        return True
    return False


def episode_end_info(info: dict[str, Any], terminal_obs: int, terminated: bool) -> dict[str, Any]:
    """The info of an episode's last decision as a one-env VecEnv reports it (``terminal_observation``, truncation)."""
    info = {**info, "terminal_observation": terminal_obs}
    if not terminated:
        info["TimeLimit.truncated"] = True
    return info


def step_locals(cb_locals: dict[str, Any], obs: int, reward: float, done: bool, info: dict[str, Any], action: int) -> None:
    """Fill ``cb_locals`` with what a one-env VecEnv step gives SB3's callbacks after a decision."""
    cb_locals["new_obs"] = np.array([obs])
    cb_locals["rewards"] = np.array([reward], dtype=np.float32)
    cb_locals["dones"] = DONE if done else NOT_DONE
    cb_locals["infos"] = [info]
    cb_locals["actions"] = np.array([action])
