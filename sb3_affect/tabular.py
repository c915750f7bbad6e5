"""
``TabularQAlgorithm``: what QLearning and AffectQ share, including the learning loop.

A *decision* picks a direction and a number of cells ``k``; it makes ``k`` ordinary one-cell transitions, each with
its own Eq. 1 update, all in the same direction, stopping early at the goal; ``k = 0`` is a wait. ``num_timesteps``
counts decisions (the paper's "steps"). Subclasses say how a decision is taken (``_decide``).
"""

from __future__ import annotations

import math
import random
import time
from typing import Any, ClassVar, TypeVar

import numpy as np
import pandas as pd
import torch as th
from gymnasium import spaces
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, ConvertCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.utils import safe_mean
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_affect.appraisal import check_choice
from sb3_affect.episode_log import Geometry, env_geometry, greedy_walks_shortest_path, make_frame
from sb3_affect.policies import TabularQPolicy
from sb3_affect.serialization import add_plain_description, load_safe

SelfTabular = TypeVar("SelfTabular", bound="TabularQAlgorithm")

ENGINES = ("auto", "python", "compiled")
TIE_BREAKS = ("random", "first")
MULTI_CELLS = ("steps", "jump")

_DONE = np.array([True])
_NOT_DONE = np.array([False])
_DONE.flags.writeable = False
_NOT_DONE.flags.writeable = False


def _check_number(name: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    """Validate a float hyperparameter in ``[low, high]`` (``(low, high]`` when ``low_open``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {value!r} ({type(value).__name__})")
    value = float(value)
    bad = not math.isfinite(value) or value > high or (value <= low if low_open else value < low)
    if bad:
        interval = f"{'(' if low_open else '['}{low:g}, {high:g}]"
        raise ValueError(f"{name}={value!r} is out of range: it must be in {interval}")
    return value


def _check_rate(name: str, value: float | Schedule, low: float, high: float, low_open: bool = False) -> None:
    """A rate may be a number or an SB3-style schedule (a callable of the remaining progress)."""
    if callable(value):
        for progress in (1.0, 0.0):
            _check_number(f"{name}({progress:g})", value(progress), low, high, low_open)
    else:
        _check_number(name, value, low, high, low_open)


class TabularQAlgorithm(BaseAlgorithm):
    """
    Tabular Q-learning (Eq. 1) on a single env with Discrete observations and actions.

    :param policy: ``"Grid"`` (alias of ``TabularQPolicy``) or a policy class
    :param env: the environment (a Gymnasium env, a registered id or a one-env DummyVecEnv)
    :param learning_rate: alpha in Eq. 1, in (0, 1]; a float or a schedule of the remaining progress
    :param gamma: discount factor, in [0, 1]
    :param q_init: initial value of every Q-table entry
    :param max_episode_decisions: safety cap: an episode that reaches this many decisions is truncated (and counted)
    :param stats_window_size: window of the rollout/ep_*_mean logger keys (episodes)
    :param tensorboard_log: folder for TensorBoard logs (None: none)
    :param policy_kwargs: extra arguments for the policy
    :param verbose: 0 silent, 1 training logs on stdout
    :param seed: seed of every random choice (Python, NumPy, torch and the agent's own generator)
    :param device: torch device of the Q-table (``"cpu"`` is all a table needs)
    :param engine: ``"auto"`` (default: the compiled kernel where it applies, else the Python loop), ``"python"``
        (always the readable Python loop) or ``"compiled"`` (the kernel; an error says why when it can not apply).
        Both give the same episode log and Q-table for the same seed (see ``sb3_affect.kernel``)
    :param tie_break: how greedy ties are broken while learning: ``"random"`` (uniformly, one random draw) or
        ``"first"`` (the lowest action, no draw)
    :param _init_setup_model: build the policy now (SB3 convention)
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"Grid": TabularQPolicy, "TabularQPolicy": TabularQPolicy}
    policy: TabularQPolicy
    #: how a decision of k cells learns (agents that move several cells set it: ``"steps"`` or ``"jump"``)
    multi_cell: str = "steps"

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = 1.0,
        gamma: float = 0.8,
        q_init: float = 0.0,
        max_episode_decisions: int = 20_000,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "cpu",
        engine: str = "auto",
        tie_break: str = "random",
        _init_setup_model: bool = True,
    ) -> None:
        self.engine = check_choice("engine", engine, ENGINES)
        self.tie_break = check_choice("tie_break", tie_break, TIE_BREAKS)
        _check_rate("learning_rate", learning_rate, 0.0, 1.0, low_open=True)
        self.gamma = _check_number("gamma", gamma, 0.0, 1.0)
        self.q_init = _check_number("q_init", q_init, -1e300, 1e300)
        if isinstance(max_episode_decisions, bool) or not isinstance(max_episode_decisions, (int, np.integer)):
            raise TypeError(f"max_episode_decisions must be an integer >= 1, got {max_episode_decisions!r}")
        if max_episode_decisions < 1:
            raise ValueError(f"max_episode_decisions={max_episode_decisions} must be >= 1")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise TypeError(f"seed must be an integer or None, got {seed!r}")
        self.max_episode_decisions = int(max_episode_decisions)
        if env is not None and not isinstance(env, str):
            self._check_spaces(env.observation_space, env.action_space)
        super().__init__(
            policy,
            env,
            learning_rate,
            policy_kwargs=policy_kwargs,
            stats_window_size=stats_window_size,
            tensorboard_log=tensorboard_log,
            verbose=verbose,
            device=device,
            seed=seed,
            support_multi_env=False,
        )
        if self.env is not None:
            self._check_spaces(self.observation_space, self.action_space)
        # run state (plain data, saved with the model)
        self._episode_rows: list[list[Any]] = []
        self._episode_state: dict[str, Any] | None = None
        self._rng_state: list[Any] | None = None
        self._truncated_episodes = 0
        if _init_setup_model:
            self._setup_model()

    @staticmethod
    def _check_spaces(observation_space: spaces.Space, action_space: spaces.Space) -> None:
        if not isinstance(observation_space, spaces.Discrete):
            raise TypeError(
                f"observation space {observation_space} is not supported: tabular agents need a Discrete observation "
                "space (one integer per state), such as sb3_affect/GridPursuit-v0's Discrete(size * size)"
            )
        if not isinstance(action_space, spaces.Discrete):
            raise TypeError(f"action space {action_space} is not supported: tabular agents need a Discrete action space")

    # -- set-up ------------------------------------------------------------------------------------------------
    def _setup_model(self) -> None:
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy = self.policy_class(  # type: ignore[assignment]
            self.observation_space, self.action_space, self.lr_schedule, q_init=self.q_init, **self.policy_kwargs
        )
        self.policy = self.policy.to(self.device)
        self._tie_first = self.tie_break == "first"
        self._rng = random.Random(self.seed)
        if self._rng_state is not None:
            version, internal, gauss = self._rng_state
            self._rng.setstate((version, tuple(internal), gauss))
        self.policy.rng = self._rng

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_rng", "_tie_first"]

    # -- what subclasses define ----------------------------------------------------------------------------------
    def _decide(self, state: int, q: list[list[float]]) -> tuple[int, int, bool]:
        """Return ``(action, cells to move, whether the direction was random)`` for a decision in ``state``."""
        raise NotImplementedError

    def _start_episode(self) -> None:
        """Called when an episode starts (subclasses: reset per-episode state)."""

    def _end_episode(self, reached_goal: bool) -> tuple[list[int], float]:
        """Called when an episode ends; returns the emotion counts (joy, sadness, fear, anger) and the norm."""
        return [0, 0, 0, 0], math.nan

    def _transition_hook(self) -> Any:
        """A callable ``(s, s2, terminated)`` run after every one-cell transition, or None."""
        return None

    def _exploration_value(self) -> float:
        """The value logged as ``rollout/exploration_rate``."""
        return 0.0

    def _update_schedules(self) -> None:
        """Called at each episode start, after the progress is updated."""
        self._alpha = float(self.lr_schedule(self._current_progress_remaining))

    # -- the learning loop ---------------------------------------------------------------------------------------
    def _single_env(self) -> Any:
        if not isinstance(self.env, DummyVecEnv) or self.env.num_envs != 1:
            raise TypeError(
                f"{type(self).__name__} learns on a single env; pass a Gymnasium env, an env id or a one-env DummyVecEnv "
                f"(got {type(self.env).__name__})"
            )
        return self.env.envs[0]

    def learn(
        self: SelfTabular,
        total_timesteps: int,
        callback: MaybeCallback = None,
        log_interval: int = 4,
        tb_log_name: str = "run",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfTabular:
        """
        Learn for ``total_timesteps`` decisions (or until a callback stops it, e.g. ``StopTrainingOnMaxEpisodes``).

        Callbacks are called once per decision, after it; their ``locals`` hold ``new_obs``, ``rewards``, ``dones``
        (a 1-element bool array), ``infos`` and ``actions`` of the decision's last transition, as for a one-env VecEnv.
        ``reset_num_timesteps=True`` starts a new run: the episode log and the appraisal history start afresh, the
        Q-table and the known map are kept.

        :param total_timesteps: number of decisions to take
        :param callback: SB3 callback(s) called after every decision
        :param log_interval: dump the logger every this many episodes (None: never)
        :param tb_log_name: TensorBoard run name
        :param reset_num_timesteps: start counting (and the episode log) from zero
        :param progress_bar: show a progress bar (tqdm and rich)
        :return: the trained model
        """
        if reset_num_timesteps:
            self._episode_rows = []
            self._truncated_episodes = 0
            self._new_run()
        if reset_num_timesteps or self._last_obs is None:
            self._episode_state = None  # SB3 resets the env: a new episode starts
        silent = not self._custom_logger and self.verbose == 0 and self.tensorboard_log is None
        if silent:  # SB3 would create an empty /tmp/SB3-<date> folder for a logger that writes nothing
            self._logger, self._custom_logger = Logger(folder=None, output_formats=[]), True
        try:
            total_timesteps, callback = self._setup_learn(
                total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar
            )
        finally:
            if silent:
                self._custom_logger = False
        callback.on_training_start(locals(), globals())
        env = self._single_env()
        self._geometry: Geometry | None = env_geometry(env)
        self._greedy_optimal: bool | None = None
        q: list[list[float]] = self.policy.q_table.tolist()
        self._q = q
        self._update_schedules()
        try:
            if self._use_kernel(env, callback):
                from sb3_affect.kernel.bridge import learn_compiled

                learn_compiled(self, env, total_timesteps, callback, log_interval)
            else:
                self._run_loop(env, q, total_timesteps, callback, log_interval)
        finally:
            self._sync_policy()
        callback.on_training_end()
        return self

    def _use_kernel(self, env: Any, callback: BaseCallback | None) -> bool:
        """
        Whether ``learn`` runs on the compiled kernel: ``engine="python"`` never, ``"compiled"`` always (an error
        naming the reason when it can not), ``"auto"`` when the agent, the env (one of the package's grid envs, with
        Gymnasium's and SB3's standard wrappers only) and the callbacks (none, ``StopTrainingOnMaxEpisodes``, the
        progress bar, or callbacks marked ``episode_level = True``) all allow it.
        """
        if self.engine == "python":
            return False
        from sb3_affect.kernel.bridge import compiled_reason

        reason = compiled_reason(self, env, callback)
        if reason is not None and self.engine == "compiled":
            raise ValueError(f"engine='compiled' can not run this learn call: {reason}; use engine='auto' or 'python'")
        return reason is None

    def _run_loop(
        self, env: Any, q: list[list[float]], total_timesteps: int, callback: BaseCallback, log_interval: int | None
    ) -> None:
        gamma = self.gamma
        cap = self.max_episode_decisions
        decide = self._decide
        observe = self._transition_hook()
        jump = self.multi_cell == "jump"
        obs_start = int(self.observation_space.start)  # type: ignore[attr-defined]
        act_start = int(self.action_space.start)  # type: ignore[attr-defined]
        cb_locals: dict[str, Any] = {"self": self, "total_timesteps": total_timesteps, "callback": callback}
        update_locals = callback.update_locals
        on_step = callback.on_step
        # learn(callback=None) without a progress bar: nothing to call per decision
        call_back = not (isinstance(callback, ConvertCallback) and callback.callback is None)

        # the episode in progress (continued across learn(reset_num_timesteps=False) calls)
        if self._episode_state is None:
            s = int(np.asarray(self._last_obs).reshape(-1)[0]) - obs_start
            decisions = cells = random_moves = waits = 0
            reward_sum = 0.0
            self._begin_episode(total_timesteps)
        else:
            st = self._episode_state
            s, decisions, cells, random_moves, waits, reward_sum = (
                st["state"],
                st["decisions"],
                st["cells"],
                st["random_moves"],
                st["waits"],
                st["reward"],
            )
        alpha = self._alpha
        s2, reward, terminated, truncated, info, action = s, 0.0, False, False, {}, 0

        t = self.num_timesteps
        changed = True  # whether the Q-table changed since the last greedy-path check
        while t < total_timesteps:
            # 1. decide: direction and speed (epsilon-greedy, or the emotion's behaviour)
            action, k, explored = decide(s, q)
            # 2. move k cells, one Eq. 1 update per cell (multi_cell="jump": one for the whole move, below)
            start_cell, jump_reward = s, 0.0
            for _ in range(k):
                obs, r, terminated, truncated, info = env.step(action + act_start)
                s2 = int(obs) - obs_start
                reward = float(r)
                if jump:
                    jump_reward += reward
                else:
                    row = q[s]
                    old = row[action]
                    new = old + alpha * ((reward if terminated else reward + gamma * max(q[s2])) - old)
                    if new != old:
                        row[action] = new
                        changed = True
                if observe is not None:
                    observe(s, s2, terminated)
                cells += 1
                reward_sum += reward
                s = s2
                if terminated or truncated:
                    break
            if jump and k > 0:
                row = q[start_cell]
                old = row[action]
                new = old + alpha * ((jump_reward if terminated else jump_reward + gamma * max(q[s])) - old)
                if new != old:
                    row[action] = new
                    changed = True
            if k == 0:
                waits += 1
            if explored:
                random_moves += 1
            decisions += 1
            t += 1
            # 3. episode end: at the goal, by the env's time limit, or by the safety cap
            done = terminated or truncated or decisions >= cap
            if done:
                at_goal = terminated  # for the callbacks' info below, after the reset clears ``terminated``
                self.num_timesteps = t
                self._close_episode(
                    decisions, cells, reward_sum, random_moves, waits, terminated, not terminated, changed, log_interval
                )
                changed = False
                obs, _ = env.reset()
                s = int(obs) - obs_start
                decisions = cells = random_moves = waits = 0
                reward_sum = 0.0
                terminated = truncated = False
                self._begin_episode(total_timesteps)
                alpha = self._alpha
            # 4. callbacks, once per decision, with the locals of a one-env VecEnv step
            if call_back:
                self.num_timesteps = t
                if done:
                    info = {**info, "terminal_observation": s2 + obs_start}
                    if not at_goal:
                        info["TimeLimit.truncated"] = True
                cb_locals["new_obs"] = [s + obs_start]
                cb_locals["rewards"] = [reward]
                cb_locals["dones"] = _DONE if done else _NOT_DONE
                cb_locals["infos"] = [info]
                cb_locals["actions"] = [action + act_start]
                update_locals(cb_locals)
                if not on_step():
                    break
        self.num_timesteps = t

        self._episode_state = {
            "state": s,
            "decisions": decisions,
            "cells": cells,
            "random_moves": random_moves,
            "waits": waits,
            "reward": reward_sum,
        }
        self._last_obs = np.array([s + obs_start])

    def _begin_episode(self, total_timesteps: int) -> None:
        self._update_current_progress_remaining(self.num_timesteps, total_timesteps)
        self._update_schedules()
        self._start_episode()

    def _close_episode(
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
    ) -> None:
        counts, norm = self._end_episode(terminated)
        geometry = self._geometry
        if geometry is None:
            optimal: Any = math.nan
            greedy: Any = math.nan
        else:
            optimal = terminated and cells == geometry.shortest_path_length
            if q_changed or self._greedy_optimal is None:
                self._greedy_optimal = greedy_walks_shortest_path(self._q, geometry)
            greedy = self._greedy_optimal
        self._episode_rows.append(
            [
                len(self._episode_rows) + 1,
                decisions,
                cells,
                reward,
                optimal,
                truncated,
                random_moves,
                waits,
                *counts,
                greedy,
                norm,
            ]
        )
        if truncated:
            self._truncated_episodes += 1
        self._episode_num += 1
        assert self.ep_info_buffer is not None
        self.ep_info_buffer.append(
            {"r": reward, "l": decisions, "c": cells, "t": round(time.time() - self.start_time / 1e9, 6)}
        )
        if self.logger.output_formats:  # no logger work when nothing would be written
            self.logger.record("affect/equivalent_epsilon", random_moves / decisions)
            if log_interval is not None and self._episode_num % log_interval == 0:
                self.dump_logs()

    def dump_logs(self) -> None:
        """Write the logger: the keys SB3's DQN writes, plus rollout/ep_cells_mean and the affect/* keys."""
        assert self.ep_info_buffer is not None
        time_elapsed = max((time.time_ns() - self.start_time) / 1e9, 1e-9)
        fps = int((self.num_timesteps - self._num_timesteps_at_start) / time_elapsed)
        self.logger.record("time/episodes", self._episode_num, exclude="tensorboard")
        if len(self.ep_info_buffer) > 0:
            self.logger.record("rollout/ep_rew_mean", safe_mean([ep["r"] for ep in self.ep_info_buffer]))
            self.logger.record("rollout/ep_len_mean", safe_mean([ep["l"] for ep in self.ep_info_buffer]))
            self.logger.record("rollout/ep_cells_mean", safe_mean([ep["c"] for ep in self.ep_info_buffer]))
        self.logger.record("rollout/exploration_rate", self._exploration_value())
        self.logger.record("rollout/truncated_episodes", self._truncated_episodes)
        self.logger.record("time/fps", fps)
        self.logger.record("time/time_elapsed", int(time_elapsed), exclude="tensorboard")
        self.logger.record("time/total_timesteps", self.num_timesteps, exclude="tensorboard")
        self.logger.record("train/learning_rate", self._alpha)
        self.logger.record("train/n_updates", self.num_timesteps)
        self.logger.dump(step=self.num_timesteps)

    # -- the Q-table -------------------------------------------------------------------------------------------
    def _sync_policy(self) -> None:
        """Write the loop's Python Q-table back into the policy's tensor."""
        q = getattr(self, "_q", None)
        if q is not None:
            self.policy.q_table.copy_(th.tensor(q, dtype=th.float64))

    @property
    def q_table(self) -> np.ndarray:
        """A copy of the Q-table, shape (n_states, n_actions)."""
        return self.policy.q_table.cpu().numpy().copy()

    def _new_run(self) -> None:
        """Called by ``learn(reset_num_timesteps=True)`` before anything else (subclasses: forget run history)."""

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per finished episode of the current run; columns ``sb3_affect.EPISODE_COLUMNS``."""
        return make_frame(self._episode_rows)

    @property
    def truncated_episodes(self) -> int:
        """Episodes of the current run ended by the safety cap or the env's time limit."""
        return self._truncated_episodes

    # -- save ----------------------------------------------------------------------------------------------------
    def save(self, path: Any, exclude: Any = None, include: Any = None) -> None:
        """Save as SB3 does; the agent's random generator and run state are stored as plain data."""
        self._sync_policy()
        version, internal, gauss = self._rng.getstate()
        self._rng_state = [version, list(internal), gauss]
        try:
            super().save(path, exclude=exclude, include=include)
            add_plain_description(path, self)
        finally:
            self._rng_state = None

    @classmethod
    def load(
        cls: type[SelfTabular],
        path: Any,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        safe: bool = True,
        **kwargs: Any,
    ) -> SelfTabular:
        """
        Load a model saved with ``save``.

        By default (``safe=True``) nothing in the file is unpickled: spaces, schedules and buffers are rebuilt from the
        file's plain-JSON description and the Q-table is read with ``torch.load(weights_only=True)``; files that need
        unpickling (saved by other code, custom policies or schedules) are refused with a ``ModelFileError``.
        ``safe=False`` uses SB3's legacy loader, which runs pickled code: only for files you trust.

        :param path: the model file (``.zip`` may be left out)
        :param env: the env to continue training on (its spaces must match); None to only predict
        :param device: torch device
        :param custom_objects: legacy loader only: objects replacing pickled ones
        :param print_system_info: legacy loader only: print the saving and the current system info
        :param force_reset: reset the env before the next ``learn`` (SB3 convention)
        :param safe: load without unpickling (default); False for SB3's legacy loader
        :param kwargs: attributes to change on the loaded model
        :return: the loaded model
        """
        if not safe:
            return super().load(
                path,
                env=env,
                device=device,
                custom_objects=custom_objects,
                print_system_info=print_system_info,
                force_reset=force_reset,
                **kwargs,
            )
        if custom_objects:
            raise ValueError("custom_objects only applies to the legacy loader: pass safe=False for a file you trust")
        return load_safe(cls, path, env=env, device=device, force_reset=force_reset, **kwargs)
