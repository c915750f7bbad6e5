"""
``TabularQAlgorithm``: what QLearning and AffectQ share: set-up, ``learn`` (and which engine runs it), the Q-table,
logging; save and load come from its base class (``sb3_affect.agents.model_files.ModelFiles``).

The decision loop itself is ``reference_loop.run_loop`` (the readable reference) and ``sb3_affect.kernel`` (its
compiled twin). Both take the run from the algorithm through its public run methods (``start_run``,
``resume_episode``, ``close_episode``, ``keep_episode``, ``end_run``: the algorithm keeps its own state, the loops
never reach into it); ``num_timesteps`` counts decisions (the paper's "steps"). Subclasses say how a decision is taken
(``_decide``).
"""

from __future__ import annotations

import math
import operator
import os
import random
import time
import warnings
from typing import Any, ClassVar, TypeVar

import numpy as np
import pandas as pd
import torch as th
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import GymEnv, MaybeCallback, Schedule
from stable_baselines3.common.vec_env import DummyVecEnv

from sb3_affect.agents.agent_checks import check_episode_in_progress, check_seed, check_table_size, check_total_timesteps
from sb3_affect.agents.model_files import ModelFiles
from sb3_affect.agents.policies import TabularQPolicy, check_not_gym_tuple
from sb3_affect.agents.qtable import LoopTable, VisitedRows
from sb3_affect.agents.reference_loop import LoopParts, run_loop
from sb3_affect.core.episode_blocks import EpisodeBlocks
from sb3_affect.core.episode_log import (
    EPISODE_COLUMNS,
    Geometry,
    Rows,
    env_geometry,
    greedy_walks_shortest_path,
)
from sb3_affect.core.extras import numba_usable
from sb3_affect.core.goals import GoalTest, positive_terminal_reward
from sb3_affect.core.registry import known_settings
from sb3_affect.core.setting_checks import ENGINES, MULTI_CELLS, TIE_BREAKS, check_tabular
from sb3_affect.core.settings import TabularSettings

SelfTabular = TypeVar("SelfTabular", bound="TabularQAlgorithm")

__all__ = ["ENGINES", "MULTI_CELLS", "TIE_BREAKS", "TabularQAlgorithm"]

_S = TabularSettings  # the defaults of the settings (one source: ``sb3_affect.core.settings``)

#: A row's values in the order of ``EPISODE_COLUMNS`` (from the row by column name).
_ROW_VALUES = operator.itemgetter(*EPISODE_COLUMNS)


class TabularQAlgorithm(ModelFiles):
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
        Both give the same episode log and Q-table for the same seed (see ``sb3_affect.kernel``). Which one the last
        ``learn`` ran on: ``engine_used`` and the logger key ``train/engine`` (said once at ``verbose=1``, with why
        ``"auto"`` ran the Python loop)
    :param tie_break: how greedy ties are broken while learning: ``"random"`` (uniformly, one random draw) or
        ``"first"`` (the lowest action, no draw)
    :param _init_setup_model: build the policy now (SB3 convention)
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {"Grid": TabularQPolicy, "TabularQPolicy": TabularQPolicy}
    policy: TabularQPolicy
    #: the agent's settings class: its defaults and checks, which the compiled engine reads without a model
    settings_class: ClassVar[type[TabularSettings]] = TabularSettings
    #: how a decision of k cells learns (agents that move several cells set it: ``"steps"`` or ``"jump"``)
    multi_cell: str = "steps"

    def __init__(
        self,
        policy: str | type[TabularQPolicy],
        env: GymEnv | str | None,
        learning_rate: float | Schedule = _S.learning_rate,
        gamma: float = _S.gamma,
        q_init: float = _S.q_init,
        max_episode_decisions: int = _S.max_episode_decisions,
        stats_window_size: int = 100,
        tensorboard_log: str | None = None,
        policy_kwargs: dict[str, Any] | None = None,
        verbose: int = 0,
        seed: int | None = None,
        device: th.device | str = "cpu",
        engine: str = _S.engine,
        tie_break: str = _S.tie_break,
        _init_setup_model: bool = True,
    ) -> None:
        self.engine, self.tie_break, self.gamma, self.q_init, max_episode_decisions = check_tabular(
            learning_rate, gamma, q_init, max_episode_decisions, engine, tie_break
        )
        #: the engine the last ``learn`` ran on, ``"compiled"`` or ``"python"`` (None before the first)
        self.engine_used: str | None = None
        self._engine_reason = ""
        seed = check_seed(seed)
        self.max_episode_decisions = max_episode_decisions
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
        self._episode_blocks = EpisodeBlocks()  # the episode log (saved as ``_episode_rows``, a list of rows)
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
        check_table_size(observation_space.n, action_space.n, f"observation space {observation_space}")

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
        self._q: LoopTable | np.ndarray | None = None  # the loop's table (the kernel's: an array), only while learn runs
        rows = self.__dict__.pop("_episode_rows", None)  # a loaded file's episode log: a list of rows
        if rows is not None:
            self._episode_blocks = EpisodeBlocks.from_rows(rows)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "_rng", "_q", "_tie_first", "_episode_blocks", "_warned_non_finite",
                "_engine_said", "_engine_reason"]

    def set_random_seed(self, seed: int | None = None) -> None:
        """Seed Python, NumPy, torch, the action space, the env and the agent's own generator (SB3 convention)."""
        seed = check_seed(seed)
        super().set_random_seed(seed)
        rng = getattr(self, "_rng", None)
        if seed is not None and rng is not None:
            rng.seed(seed)  # in place: the policy shares this generator

    # -- what subclasses define ----------------------------------------------------------------------------------
    def _decide(self, state: int, q: Rows) -> tuple[int, int, bool]:
        """Return ``(action, cells to move, whether the direction was random)`` for a decision in ``state``."""
        raise NotImplementedError

    def _start_episode(self) -> None:
        """Called when an episode starts (subclasses: reset per-episode state)."""

    def _end_episode(self, reached_goal: bool) -> tuple[list[int], float]:
        """Called when an episode ends; returns the emotion counts (joy, sadness, fear, anger) and the norm."""
        return [0, 0, 0, 0], math.nan

    def _transition_hook(self) -> Any:
        """A callable ``(s, s2, reached_goal)`` run after every one-cell transition, or None."""
        return None

    def _goal_test(self) -> GoalTest:
        """What counts as reaching the goal when an episode terminates (see ``sb3_affect.core.goals``)."""
        return positive_terminal_reward

    def _exploration_value(self) -> float:
        """The value logged as ``rollout/exploration_rate``."""
        return 0.0

    def episode_exploration(self) -> float:
        """The exploration parameter of the episode in progress as the kernel takes it (epsilon, inverse temperature)."""
        return 0.0

    # -- the compiled engine ---------------------------------------------------------------------------------------
    def compiled_settings(self) -> TabularSettings | str:
        """
        The settings (``sb3_affect.core.settings``) the compiled engine runs this model with, its hyperparameters as they
        are now; or why the kernel can not run the model (a string): a class it does not implement (a subclass of
        one of the package's agents may change the loop), or a callback or appraiser of the agent's own.
        """
        settings_cls = known_settings(type(self))
        if settings_cls is None:
            return (
                f"{type(self).__name__} is not one of the agents the kernel implements (QLearning, AffectQ and the "
                "baselines, not subclasses of them, which may change the loop)"
            )
        values = self._settings_values()
        return values if isinstance(values, str) else settings_cls(**values)

    def _settings_values(self) -> dict[str, Any] | str:
        """The model's values of its settings' fields (subclasses: as the kernel would run them, or why it can not)."""
        return {name: getattr(self, name) for name in self.settings_class.names()}

    def _update_schedules(self) -> None:
        """Called at each episode start, after the progress is updated."""
        self._alpha = float(self.lr_schedule(self._current_progress_remaining))

    # -- the learning loop ---------------------------------------------------------------------------------------
    def single_env(self) -> Any:
        """The one Gymnasium env the agent learns on (Monitor-wrapped); a TypeError for any other env."""
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
        log_interval: int | None = 4,
        tb_log_name: str | None = None,
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> SelfTabular:
        """
        Learn for ``total_timesteps`` decisions (or until a callback stops it, e.g. ``StopTrainingOnMaxEpisodes``).

        Callbacks are called once per decision, after it, with the ``locals`` of a one-env VecEnv step as SB3's
        off-policy algorithms pass them: ``new_obs`` (int array, shape (1,)), ``rewards`` (float32 array: the sum of
        the decision's one-cell rewards), ``dones`` (bool array), ``infos`` (a list of one dict: the info of the
        decision's last transition, with ``terminal_observation`` and ``TimeLimit.truncated`` at an episode end) and
        ``actions`` (int array). A wait (a decision that moves 0 cells) makes no env step: it reports reward 0 and
        the info ``{"wait": True}``. ``is_success`` in an episode's last info feeds ``rollout/success_rate``.
        While ``learn`` runs the Q-table lives in the loop; ``predict``, ``get_parameters`` and ``save`` called by a
        callback see it. Outside ``learn`` the policy's ``q_table`` tensor is the only copy.
        ``reset_num_timesteps=True`` starts a new run: the episode log and the appraisal history start afresh, the
        Q-table and the known map are kept.

        :param total_timesteps: number of decisions to take (0 is allowed and takes none)
        :param callback: SB3 callback(s) called after every decision
        :param log_interval: dump the logger every this many episodes (None: never)
        :param tb_log_name: TensorBoard run name (None: the class name, as ``QLearning_1``)
        :param reset_num_timesteps: start counting (and the episode log) from zero
        :param progress_bar: show a progress bar (tqdm and rich)
        :return: the trained model
        """
        total_timesteps = check_total_timesteps(total_timesteps)
        total_timesteps, callback = self.start_run(
            total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar, new_episode=False
        )
        env = self.single_env()
        plan = self._use_kernel(env, callback)
        self._say_engine("compiled" if plan is not None else "python")
        try:
            if plan is not None:  # the kernel's table: an array (the Python loop makes a row the first time it visits a state)
                from sb3_affect.agents.compiled import learn_compiled

                q_array = self._q = self.policy.q_table.cpu().numpy().astype(np.float64, order="C")
                learn_compiled(self, env, q_array, total_timesteps, callback, log_interval, plan)
            else:
                run_loop(self, env, total_timesteps, callback, log_interval)
        finally:
            self.end_run()
        self._warn_non_finite()
        callback.on_training_end()
        return self

    def _warn_non_finite(self) -> None:
        """Warn (once per model) when the Q-table holds NaN or infinite values: the env gave such rewards (or ones so
        large that their sums overflow), and every greedy choice over such a row is arbitrary."""
        if getattr(self, "_warned_non_finite", False):
            return
        values = self.policy.q_table.detach().numpy().reshape(-1)
        block = 1 << 20  # a block at a time: torch's isfinite of a large table takes several copies of it
        bad = sum(int(np.count_nonzero(~np.isfinite(values[i : i + block]))) for i in range(0, len(values), block))
        if bad == 0:
            return
        self._warned_non_finite = True
        warnings.warn(
            f"{type(self).__name__}: {bad:,} Q-values are NaN or infinite after learn: the env gave rewards that are NaN, "
            "infinite or large enough for their discounted sums to overflow (rewards within +-1e300 / (1 - gamma) fit)",
            RuntimeWarning,
            stacklevel=3,
        )

    # -- the run: what the loops call (the Python loop, the stepper, the compiled engine) --------------------------
    def start_run(
        self,
        total_timesteps: int,
        callback: MaybeCallback,
        reset_num_timesteps: bool,
        tb_log_name: str | None,
        progress_bar: bool,
        new_episode: bool,
    ) -> tuple[int, BaseCallback]:
        """
        What a run does before its first decision (``learn``, and ``sb3_affect.agents.stepping.DecisionStepper``): a new
        run's episode log and history, SB3's ``_setup_learn`` (a silent logger when nothing is written), the callbacks'
        ``on_training_start``, the env's geometry, the loop's Q-table (``self._q``) and the schedules. ``new_episode``:
        start a new episode even when one is in progress. Returns SB3's ``(total_timesteps, callback)``.
        """
        if reset_num_timesteps:
            self._episode_blocks = EpisodeBlocks()
            self._truncated_episodes = 0
            self._new_run()
        if new_episode or reset_num_timesteps or self._last_obs is None:
            self._episode_state = None  # SB3 resets the env: a new episode starts
        if tb_log_name is None:
            tb_log_name = type(self).__name__
        silent = not self._custom_logger and self.verbose == 0 and self.tensorboard_log is None
        if silent:  # SB3 would create an empty /tmp/SB3-<date> folder for a logger that writes nothing
            self._logger, self._custom_logger = Logger(folder=os.environ.get("SB3_LOGDIR"), output_formats=[]), True
        try:
            total_timesteps, callback = self._setup_learn(
                total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar
            )
        finally:
            if silent:
                self._custom_logger = False
        n_states, start = int(self.observation_space.n), int(self.observation_space.start)  # type: ignore[attr-defined]
        check_episode_in_progress(self._episode_state, self._last_obs, n_states, start)
        callback.on_training_start(locals(), globals())
        self._geometry: Geometry | None = env_geometry(self.single_env())
        self._greedy_optimal: bool | None = None
        # the Python loop's view of the table: a row is read from the tensor the first time its state is visited
        self._q = VisitedRows(self.policy.q_table)
        self._update_schedules()
        return total_timesteps, callback

    def _use_kernel(self, env: Any, callback: BaseCallback | None) -> Any:
        """
        Whether ``learn`` runs on the compiled kernel: ``engine="python"`` never, ``"compiled"`` always (an error
        naming the reason when it can not), ``"auto"`` when the agent, the env (one of the package's grid envs, with
        Gymnasium's and SB3's standard wrappers only) and the callbacks (none, ``StopTrainingOnMaxEpisodes``, the
        progress bar, or callbacks marked ``episode_level = True``) all allow it. Returns what the kernel runs (the
        settings and the kernel's agent: ``compiled.compiled_plan``), or None for the Python loop.
        """
        self._engine_reason = "engine='python'"
        if self.engine == "python":
            return None
        if not numba_usable(self.engine):
            self._engine_reason = "numba can not be imported"
            return None
        from sb3_affect.agents.compiled import compiled_plan

        plan = compiled_plan(self, env, callback)
        if isinstance(plan, str) and self.engine == "compiled":
            raise ValueError(f"engine='compiled' can not run this learn call: {plan}; use engine='auto' or 'python'")
        if isinstance(plan, str):
            self._engine_reason = plan
            return None
        return plan

    def _say_engine(self, engine: str) -> None:
        """Set ``engine_used``, record ``train/engine``; at ``verbose >= 1`` say which engine runs (when it changes)."""
        self.engine_used = engine
        self.logger.record("train/engine", engine, exclude="tensorboard")
        if self.verbose >= 1 and getattr(self, "_engine_said", None) != engine:
            self._engine_said = engine
            what = "on the compiled engine" if engine == "compiled" else f"the Python loop ({self._engine_reason})"
            print(f"{type(self).__name__}.learn runs {what}")

    def loop_parts(self) -> LoopParts:
        """What the Python loop takes from the agent once ``start_run`` ran: the loop's Q-table, ``_decide``, the
        transition hook and the goal test (``reference_loop.LoopParts``)."""
        q = self._q
        assert q is not None and not isinstance(q, np.ndarray), "loop_parts: after start_run, on the Python table"
        return LoopParts(q, self._decide, self._transition_hook(), self._goal_test())

    @property
    def rng(self) -> random.Random:
        """The agent's own generator (every random choice of its decisions; its policy's too)."""
        return self._rng

    @property
    def alpha(self) -> float:
        """Eq. 1's learning rate of the episode in progress (the schedule's value when it began)."""
        return self._alpha

    @property
    def episode_num(self) -> int:
        """SB3's count of the episodes the run finished (``time/episodes``)."""
        return self._episode_num

    @property
    def run_episodes(self) -> int:
        """The rows of the current run's episode log."""
        return len(self._episode_blocks)

    def last_episode_row(self) -> list[Any]:
        """The last row of the episode log, its values in the order of ``EPISODE_COLUMNS``."""
        return self._episode_blocks.last()

    @property
    def greedy_optimal(self) -> bool | None:
        """Whether the greedy path walked a shortest path at the last check (None: not checked since the run began)."""
        return self._greedy_optimal

    @greedy_optimal.setter
    def greedy_optimal(self, value: bool | None) -> None:
        self._greedy_optimal = value

    def advance_schedules(self, total_timesteps: int) -> float:
        """The training progress at ``num_timesteps`` of ``total_timesteps`` decisions and the schedules at it (``learn(0)``
        takes no decision: the progress stays where it was); returns the learning rate (``alpha``)."""
        if total_timesteps > 0:
            self._update_current_progress_remaining(self.num_timesteps, total_timesteps)
        self._update_schedules()
        return self._alpha

    def begin_episode(self, total_timesteps: int) -> float:
        """Begin an episode: the schedules (``advance_schedules``), then ``_start_episode``; returns ``alpha``."""
        alpha = self.advance_schedules(total_timesteps)
        self._start_episode()
        return alpha

    def resume_episode(self, total_timesteps: int) -> dict[str, Any]:
        """
        The episode in progress as a run's loop starts from it, ``{state, decisions, cells, random_moves, waits,
        reward}`` (``state`` counted from 0): the one the last run kept (``keep_episode``), or a new one begun now
        (``begin_episode``) in the env's last observation.
        """
        if self._episode_state is not None:
            return dict(self._episode_state)
        obs_start = int(self.observation_space.start)  # type: ignore[attr-defined]
        state = int(np.asarray(self._last_obs).reshape(-1)[0]) - obs_start
        self.begin_episode(total_timesteps)
        return {"state": state, "decisions": 0, "cells": 0, "random_moves": 0, "waits": 0, "reward": 0.0}

    def keep_episode(self, episode: dict[str, Any]) -> None:
        """Keep the episode in progress (``resume_episode``'s keys) for the next run (``reset_num_timesteps=False``)."""
        self._episode_state = episode
        self._last_obs = np.array([episode["state"] + int(self.observation_space.start)])  # type: ignore[attr-defined]

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
    ) -> None:
        """
        Close an episode of the Python loop: the appraisal's end of episode, the episode-log row, SB3's episode
        buffers, the logger.

        :param decisions: decisions taken in the episode
        :param cells: one-cell transitions made
        :param reward: sum of rewards
        :param random_moves: decisions whose direction was random
        :param waits: decisions that moved 0 cells
        :param terminated: the env ended the episode
        :param truncated: a time limit or the safety cap ended it
        :param q_changed: whether the Q-table changed since the greedy path was last checked
        :param log_interval: dump the logger every this many episodes (None: never)
        :param reached_goal: whether the termination was the goal (default: ``terminated``)
        :param info: the last transition's info (``is_success`` is read from it)
        """
        counts, norm = self._end_episode(terminated if reached_goal is None else reached_goal)
        geometry = self._geometry
        if geometry is None:
            optimal: Any = math.nan
            greedy: Any = math.nan
        else:
            optimal = terminated and cells == geometry.shortest_path_length
            if q_changed or self._greedy_optimal is None:
                assert self._q is not None, "close_episode runs inside a run, on the loop's table"
                self._greedy_optimal = greedy_walks_shortest_path(self._q, geometry)
            greedy = self._greedy_optimal
        joy, sadness, fear, anger = counts
        row = {
            "episode": len(self._episode_blocks) + 1,
            "decisions": decisions,
            "cells": cells,
            "reward": reward,
            "optimal": optimal,
            "truncated": truncated,
            "random_moves": random_moves,
            "waits": waits,
            "joy": joy,
            "sadness": sadness,
            "fear": fear,
            "anger": anger,
            "greedy_optimal": greedy,
            "norm": norm,
        }
        self._episode_blocks.append_row(list(_ROW_VALUES(row)))
        if truncated:
            self._truncated_episodes += 1
        self._episode_num += 1
        assert self.ep_info_buffer is not None
        stamp = round(time.time() - self.start_time / 1e9, 6)
        self.ep_info_buffer.append({"r": reward, "l": decisions, "c": cells, "t": stamp})
        success = None if info is None else info.get("is_success")
        if success is not None:
            assert self.ep_success_buffer is not None
            self.ep_success_buffer.append(success)
        self.log_episode_end(random_moves, decisions, log_interval)

    def close_episodes(self, block: dict[str, np.ndarray]) -> None:
        """
        ``close_episode`` for a block of episodes the compiled engine finished (the appraisal and the logger aside), in
        bulk: the episode log gets them as one block of columns (``block``, every column but ``episode``), with no
        Python work per episode.
        """
        finished = len(block["decisions"])
        first = len(self._episode_blocks) + 1
        block["episode"] = np.arange(first, first + finished, dtype=np.int64)
        self._episode_blocks.append_columns(block)
        truncated, decisions, cells, reward = block["truncated"], block["decisions"], block["cells"], block["reward"]
        self._truncated_episodes += int(truncated.sum())
        self._episode_num += finished
        buffer = self.ep_info_buffer
        assert buffer is not None
        keep = finished if buffer.maxlen is None else min(finished, buffer.maxlen)
        stamp = round(time.time() - self.start_time / 1e9, 6)
        last = slice(finished - keep, finished)  # only the episodes the buffer keeps
        for episode_reward, length, moved in zip(reward[last].tolist(), decisions[last].tolist(), cells[last].tolist()):
            buffer.append({"r": episode_reward, "l": length, "c": moved, "t": stamp})

    def log_episode_end(self, random_moves: int, decisions: int, log_interval: int | None) -> None:
        """The logger at an episode end: ``affect/equivalent_epsilon`` (per episode, never per decision), and a dump
        every ``log_interval`` episodes."""
        self.logger.record("affect/equivalent_epsilon", random_moves / decisions)
        if log_interval is not None and self._episode_num % log_interval == 0:
            self.dump_logs()

    def end_run(self) -> None:
        """End a run's loop: the loop's Q-table written back to the policy, which from now on is the one truth
        (``set_parameters``, edits, ``save``)."""
        self._sync_policy()
        self._q = None

    def dump_logs(self) -> None:
        """Write the logger: the keys SB3's DQN writes, plus rollout/ep_cells_mean and the affect/* keys."""
        buffer = self.ep_info_buffer
        assert buffer is not None
        record = self.logger.record
        time_elapsed = max((time.time_ns() - self.start_time) / 1e9, 1e-9)
        fps = int((self.num_timesteps - self._num_timesteps_at_start) / time_elapsed)
        record("time/episodes", self._episode_num, exclude="tensorboard")
        if buffer:  # plain-Python means: this runs every few episodes, also on the fast path
            n = len(buffer)
            record("rollout/ep_rew_mean", sum(map(operator.itemgetter("r"), buffer)) / n)
            record("rollout/ep_len_mean", sum(map(operator.itemgetter("l"), buffer)) / n)
            record("rollout/ep_cells_mean", sum(map(operator.itemgetter("c"), buffer)) / n)
        if self.ep_success_buffer:
            record("rollout/success_rate", sum(map(float, self.ep_success_buffer)) / len(self.ep_success_buffer))
        record("rollout/exploration_rate", self._exploration_value())
        record("rollout/truncated_episodes", self._truncated_episodes)
        record("time/fps", fps)
        record("time/time_elapsed", int(time_elapsed), exclude="tensorboard")
        record("time/total_timesteps", self.num_timesteps, exclude="tensorboard")
        record("train/learning_rate", self._alpha)
        record("train/n_updates", self.num_timesteps)
        if self.engine_used is not None:
            record("train/engine", self.engine_used, exclude="tensorboard")
        self.logger.dump(step=self.num_timesteps)

    # -- the Q-table -------------------------------------------------------------------------------------------
    @property
    def loop_table(self) -> LoopTable | np.ndarray | None:
        """The loop's Q-table while ``learn`` runs (what a callback reads mid-run; ``q_table`` is written at the end),
        else None."""
        return getattr(self, "_q", None)

    def _sync_policy(self) -> None:
        """Write the loop's Q-table (the Python loop's rows, or the kernel's array) back into the policy's tensor."""
        q = getattr(self, "_q", None)
        if isinstance(q, VisitedRows):
            q.write_back()
        elif q is not None:
            self.policy.q_table.copy_(th.as_tensor(q, dtype=th.float64))

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """
        The policy's action for ``observation`` (an int or an int array), as ``BaseAlgorithm.predict``.

        ``deterministic=True`` is the greedy action, ties going to the first maximal action, the same on every call.
        ``deterministic=False`` (subclasses: their exploration) breaks greedy ties at random with the agent's
        generator. Called from a callback during ``learn``, it uses the table being learnt.
        """
        check_not_gym_tuple(observation)
        self._sync_policy()
        return self.policy.predict(observation, state, episode_start, deterministic)

    @property
    def q_table(self) -> np.ndarray:
        """A copy of the Q-table, shape (n_states, n_actions)."""
        self._sync_policy()
        return self.policy.q_table.cpu().numpy().copy()

    def get_parameters(self) -> dict[str, dict]:
        """SB3's ``get_parameters``; called from a callback during ``learn``, it holds the table being learnt."""
        self._sync_policy()
        return super().get_parameters()

    def _new_run(self) -> None:
        """Called by ``learn(reset_num_timesteps=True)`` before anything else (subclasses: forget run history)."""

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per finished episode of the current run; columns ``sb3_affect.EPISODE_COLUMNS``."""
        return self._episode_blocks.frame()

    @property
    def truncated_episodes(self) -> int:
        """Episodes of the current run ended by the safety cap or the env's time limit."""
        return self._truncated_episodes
