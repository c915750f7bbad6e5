"""
``DecisionStepper``: drive a tabular agent one decision at a time, for worlds its ``learn`` can not step itself.

``TabularQAlgorithm.learn`` steps one Gymnasium env in a tight loop. When several agents share one world (the
hunters of ``hunter_team``), each needs to take a decision, wait while the world moves everyone, and learn from
its own transitions. The stepper exposes exactly the pieces of ``learn`` for that, calling the same code through the
agent's run methods: ``learn``'s set-up (``start_run``), the agent's decision rule (``loop_parts``: epsilon-greedy, the
emotion's behaviour, ...), Eq. 1 (``sb3_affect.agents.reference_loop.q_update``), the transition hook (the appraisal's
``observe``), ``begin_episode`` and ``close_episode`` (schedules, emotions, the episode log, the logger) and the SB3
callbacks with the locals ``learn`` gives them (``sb3_affect.agents.reference_loop.step_locals``). Driving a single
env with it gives the same episode log, Q-table and random draws as ``learn`` (tests/agents/test_hunters.py checks
this)::

    stepper = DecisionStepper(model, total_timesteps=10**6)          # starts a run, as learn() does
    action, cells, explored = stepper.decide()                     # one decision in the current state
    for _ in range(cells):                                         # its one-cell transitions
        obs, reward, terminated, truncated, info = env.step(action)
        stepper.transition(obs, reward, terminated, truncated, info)
        if terminated or truncated: break
    stepper.end_decision(terminated, truncated, reset=lambda: env.reset()[0])
    ...
    stepper.close()                                                # as learn() ends: Q-table synced, callbacks told
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from stable_baselines3.common.callbacks import ConvertCallback
from stable_baselines3.common.type_aliases import MaybeCallback

from sb3_affect.agents.qtable import LoopTable
from sb3_affect.agents.reference_loop import episode_end_info, q_update, step_locals
from sb3_affect.agents.tabular import TabularQAlgorithm


class DecisionStepper:
    """
    One run of a tabular agent, advanced one decision at a time by the caller (see the module docstring).

    :param model: a ``TabularQAlgorithm`` (QLearning, AffectQ, a baseline) with an env whose ``reset`` returns the
        agent's current observation (a single env, or a hunter's view of a team)
    :param total_timesteps: the run's budget in decisions (schedules' progress is measured against it)
    :param callback: SB3 callback(s), called once per decision as in ``learn``
    :param reset_num_timesteps: start a new run (episode log and appraisal history afresh), as in ``learn``
    :param log_interval: dump the logger every this many episodes (None: never)
    :param tb_log_name: TensorBoard run name (None: the agent's class name, as ``learn``)
    """

    def __init__(
        self,
        model: TabularQAlgorithm,
        total_timesteps: int,
        callback: MaybeCallback = None,
        reset_num_timesteps: bool = True,
        log_interval: int | None = 4,
        tb_log_name: str | None = None,
    ) -> None:
        if not isinstance(model, TabularQAlgorithm):
            raise TypeError(f"model must be a tabular agent of this package, got {type(model).__name__}")
        self.model = m = model
        self.total_timesteps, self.callback = m.start_run(  # what learn() does before its loop
            total_timesteps, callback, reset_num_timesteps, tb_log_name, False, new_episode=True
        )
        # what run_loop does before its loop
        self.q: LoopTable
        self.q, self._decide, self._observe, self._is_goal = m.loop_parts()
        self.log_interval = log_interval
        self._jump = m.multi_cell == "jump"  # one Eq. 1 update per decision, made in end_decision
        self._obs_start = int(m.observation_space.start)  # type: ignore[attr-defined]
        self._act_start = int(m.action_space.start)  # type: ignore[attr-defined]
        self._call_back = not (isinstance(self.callback, ConvertCallback) and self.callback.callback is None)
        self._locals: dict[str, Any] = {"self": m, "total_timesteps": self.total_timesteps, "callback": self.callback}
        self.t = m.num_timesteps
        self._changed = True
        self.continue_training = True
        # start_run began a new episode: resume_episode begins it in the env's first observation
        self._start(m.resume_episode(self.total_timesteps)["state"], m.alpha)

    def _start(self, s: int, alpha: float) -> None:
        """Counters of a new episode in state ``s`` (counted from 0) that learns with ``alpha``."""
        self.s = s
        self.decisions = self.cells = self.random_moves = self.waits = 0
        self.reward_sum = 0.0
        self._alpha = alpha
        self._last: tuple[int, float, dict[str, Any]] = (self.s, 0.0, {})
        self._action = 0
        self._explored = False
        self._decision_reward = 0.0

    @property
    def state(self) -> int:
        """The agent's current observation (in the env's numbering)."""
        return self.s + self._obs_start

    def set_state(self, obs: int) -> None:
        """The world changed while the agent stood still (others moved): its next decision starts from ``obs``."""
        self.s = int(obs) - self._obs_start

    def decide(self) -> tuple[int, int, bool]:
        """``(action, cells to move, whether the direction was random)`` for a decision in the current state."""
        action, k, explored = self._decide(self.s, self.q)
        self._action, self._explored, self._k = action, explored, k
        self._decision_reward = 0.0
        self._start_cell, self._jump_reward = self.s, 0.0
        return action + self._act_start, k, explored

    def transition(self, obs: int, reward: float, terminated: bool, truncated: bool = False, info: Any = None) -> None:
        """One one-cell transition of the current decision: the Eq. 1 update and the transition hook, as ``learn``."""
        s, s2, action, q = self.s, int(obs) - self._obs_start, self._action, self.q
        reward = float(reward)
        if self._jump:
            self._jump_reward += reward
        elif q_update(q, s, action, reward, s2, terminated, self._alpha, self.model.gamma):
            self._changed = True
        info = info if info is not None else {}
        if self._observe is not None:
            self._observe(s, s2, terminated and self._is_goal(reward, info))
        self.cells += 1
        self.reward_sum += reward
        self._decision_reward += reward
        self.s = s2
        self._last = (s2, reward, info)

    def end_decision(self, terminated: bool, truncated: bool, reset: Callable[[], Any]) -> bool:
        """
        Close the current decision; ends the episode at the goal (``terminated``), when cut off (``truncated``) or at
        the agent's safety cap, then calls ``reset()`` for the next episode's first observation. Calls the callbacks.

        :return: whether the episode ended
        """
        m = self.model
        # multi_cell="jump": one update from the decision's start cell to its end cell
        jump = self._jump and self._k > 0
        if jump and q_update(
            self.q, self._start_cell, self._action, self._jump_reward, self.s, terminated, self._alpha, m.gamma
        ):
            self._changed = True
        if self._k == 0:  # a wait: no env step, nothing of the previous step to report again
            self.waits += 1
            self._last = (self.s, 0.0, {"wait": True})
        if self._explored:
            self.random_moves += 1
        self.decisions += 1
        self.t += 1
        s2, reward, info = self._last
        done = terminated or truncated or self.decisions >= m.max_episode_decisions
        if done and self._call_back:  # what a VecEnv adds to the last info of an episode
            info = episode_end_info(info, s2 + self._obs_start, terminated)
        decision_reward, action = self._decision_reward, self._action  # before a reset starts the next episode
        if done:
            m.num_timesteps = self.t
            m.close_episode(
                self.decisions,
                self.cells,
                self.reward_sum,
                self.random_moves,
                self.waits,
                terminated,
                not terminated,
                self._changed,
                self.log_interval,
                reached_goal=terminated and self._is_goal(reward, info),
                info=info,
            )
            self._changed = False
            s = int(reset()) - self._obs_start
            self._start(s, m.begin_episode(self.total_timesteps))
        if self._call_back:
            m.num_timesteps = self.t
            step_locals(self._locals, self.s + self._obs_start, decision_reward, done, info, action + self._act_start)
            self.callback.update_locals(self._locals)
            if not self.callback.on_step():
                self.continue_training = False
        return done

    def close(self) -> None:
        """End the run as ``learn`` does: the Q-table written back to the policy, ``on_training_end`` called."""
        m = self.model
        m.num_timesteps = self.t
        m.keep_episode(
            {
                "state": self.s,
                "decisions": self.decisions,
                "cells": self.cells,
                "random_moves": self.random_moves,
                "waits": self.waits,
                "reward": self.reward_sum,
            }
        )
        m.end_run()  # from now on the policy's tensor is the one truth, as after learn
        self.callback.on_training_end()
