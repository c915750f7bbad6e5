"""
Emotions as an SB3 callback.

``EmotionCallback`` appraises every decision, feels one emotion (Table II) and logs the emotion profile. It works in
two ways:

* **Observer** (any SB3 algorithm, e.g. DQN or PPO, on a VecEnv of any size): attach it to ``learn``. SB3 calls
  ``_on_step`` after each ``env.step``; the callback reads ``new_obs``/``dones``/``infos`` from the algorithm's
  locals, updates each env's appraisal and feels the emotion of its *next* decision. It only watches: it logs
  ``affect/*`` keys (means over the stats window) and keeps ``episode_log`` (written beside a file-writing logger).
  The appraisal's map needs each env's cell: Discrete and MultiDiscrete observations are cells; on other spaces
  ``position=`` gives it (``"minigrid"``, or a callable: ``sb3_affect.core.positions``), and without one only an
  ``emotion_rule`` that needs no map (no ``act``) can run. An agent that repeats actions (``AffectDQN``) sets
  ``decision_ends`` before each step, so that an env feels the emotion of a new decision only when its last one
  is done.
* **Driver of AffectQ** (the affect hook): an SB3 callback runs after ``env.step``, too late to steer the step it
  follows. AffectQ therefore calls the callback's hook methods directly, in this order, for every decision::

      emotion = callback.feel(state)          # before the decision: appraise, apply the emotion rule, count it
      callback.observe(s, s2, reached_goal)   # for each one-cell transition the decision makes (0, 1 or 2)
      callback.end_episode(reached_goal)      # at the end of an episode (then begin_episode() for the next)

  ``feel`` is called exactly once per decision and counts it (the appraisal of a decision sees the decisions
  before it). Call ``bind(n_states)`` first; the hooks need no SB3 model, so an agent of your own can drive them
  the same way. ``callback.emotion`` is the emotion of the next decision (what ``feel`` last returned; in observer
  mode, the one felt for the next decision of the env last updated).

  and uses the returned emotion to look up direction and speed in its behaviour table (Table III). Swap the
  appraisal by passing your own ``Appraiser`` subclass, or the emotion rule by passing ``emotion_rule``.
"""

from __future__ import annotations

import copy
import csv
import math
import warnings
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import HumanOutputFormat

from sb3_affect.agents.sb3_fields import ModelFields
from sb3_affect.core.appraisal import Appraiser
from sb3_affect.core.emotions import EMOTION_NAMES, Emotion, EmotionRule, make_table_ii
from sb3_affect.core.episode_log import EPISODE_COLUMNS, Geometry, deterministic_walk_is_shortest, env_geometry, make_frame
from sb3_affect.core.goals import GoalTest, positive_terminal_reward
from sb3_affect.core.lane_appraisal import LaneAppraisal
from sb3_affect.core.positions import MAX_MAPPED_CELLS, ObservationCells, Position, PositionSpec, check_position, make_position

if TYPE_CHECKING:
    import pandas as pd

#: Columns of ``EmotionCallback.episode_log`` (observer mode): the agents' ``EPISODE_COLUMNS`` and the env index.
EMOTION_CALLBACK_COLUMNS: tuple[str, ...] = (*EPISODE_COLUMNS, "env")
#: The logger keys of the observer's means over the stats window (each emotion's share of decisions, and the norm).
WINDOW_KEYS: tuple[str, ...] = tuple(f"affect/{name}" for name in (*EMOTION_NAMES, "norm"))


class EmotionCallback(BaseCallback):
    """
    Appraise each decision, feel one of joy, sadness, fear or anger, count and log it.

    :param comparison: Table II reading, ``"literal"`` or ``"valence"`` (docs/definitions.md)
    :param order: the order Table II's rows are tried in: ``"table"`` (as printed) or ``"act-first"``
        (``sb3_affect.core.emotions.table_ii_act_first``: with ``comparison="valence"`` and ``act="remaining"`` all
        four emotions occur; as printed, sadness never can)
    :param act: ``"episode"`` (elapsed + known remaining) or ``"remaining"`` (known remaining only)
    :param units: ``"cells"`` or ``"decisions"``: what norm, exp1 and act count
    :param appraiser: a ready appraiser to use instead of building one from ``act`` and ``units``
        (it must be created for the env's number of cells)
    :param emotion_rule: ``rule(appraisal_or_None) -> Emotion`` replacing Table II
    :param goal: ``goal(reward, info) -> bool``, whether a terminating transition reached the goal; only
        terminations are asked, truncations never reach it (default ``sb3_affect.core.goals.positive_terminal_reward``:
        ``info["is_success"]`` if the env gives it, else reward > 0). The appraisal maps its way to the cells where
        the goal was reached, so on an env whose terminations include failures give the test that tells them apart;
        the default warns once when a termination it counts as the goal was rewarded like every step before it
        (CartPole: +1 a step, the pole falling ends it); passing any ``goal=`` silences it
    :param episode_log_path: observer mode: append each episode's row to this CSV file (default: ``emotion_episodes.csv``
        in the logger's folder when the logger writes files, e.g. csv or tensorboard; else only ``episode_log``)
    :param position: observer mode: how each env's cell is found: None (the observation, when it is a cell),
        ``"discrete"``, ``"multidiscrete"``, ``"minigrid"``, ``"minigrid-dir"``, a callable
        ``position(observation, info) -> cell`` or a ``sb3_affect.core.positions.Position``
    :param warn_after: observer mode: warn once when this many episodes have ended and none reached the goal (the
        appraisal then knows no distance to it); None: never
    :param verbose: verbosity level
    """

    def __init__(
        self,
        comparison: str = "literal",
        act: str = "episode",
        units: str = "cells",
        appraiser: Appraiser | None = None,
        emotion_rule: EmotionRule | None = None,
        goal: GoalTest | None = None,
        episode_log_path: str | Path | None = None,
        warn_after: int | None = 20,
        position: PositionSpec = None,
        verbose: int = 0,
        order: str = "table",
    ) -> None:
        super().__init__(verbose)
        self.position = check_position(position)
        if warn_after is not None and (isinstance(warn_after, bool) or not isinstance(warn_after, int) or warn_after < 1):
            raise ValueError(f"warn_after={warn_after!r} must be an integer >= 1 (episodes) or None")
        if goal is not None and not callable(goal):
            raise TypeError(f"goal must be a callable goal(reward, info) -> bool, got {goal!r}")
        self.goal: GoalTest = positive_terminal_reward if goal is None else goal
        self.comparison = comparison
        self.order = order
        self.act = act
        self.units = units
        self.emotion_rule: EmotionRule = emotion_rule if emotion_rule is not None else make_table_ii(comparison, order)
        self.appraiser: Appraiser | None = appraiser
        if appraiser is None:
            Appraiser(1, act=act, units=units)  # validate the options now, with a clear error
        #: the emotion of the next decision (what ``feel`` returned last), what an agent reads to steer
        self.emotion: Emotion = Emotion.JOY
        #: the emotion counts of the episode in progress (joy, sadness, fear, anger)
        self.counts = [0, 0, 0, 0]
        self.rows: list[list[Any]] = []
        self.episode_log_path = episode_log_path
        self.warn_after = warn_after
        # observer-mode state
        self._position: Position | None = None
        self._position_spec: PositionSpec = None
        #: set by an agent that repeats actions before each step: which envs' decisions end with it (None: all)
        self.decision_ends: np.ndarray | None = None
        #: set by an agent with the step's actions: which envs began a decision with a random direction / a wait
        #: (None: the algorithm does not say; ``random_moves`` is then NaN in the episode log)
        self.decision_random: np.ndarray | None = None
        self.decision_wait: np.ndarray | None = None
        self._lanes: list[LaneAppraisal] = []
        self._window = WindowMeans(len(WINDOW_KEYS))
        self._csv_path: Path | None = None
        self._episodes = self._goals = 0
        self._warned = False
        self._warned_goal = False  # _warn_rewarded_all_along, once per callback
        self._geometry: Geometry | None = None

    # -- set-up ------------------------------------------------------------------------------------------------
    def bind(self, n_states: int) -> None:
        """Create the appraiser for an env with ``n_states`` cells (once; later calls keep what it knows)."""
        if self.appraiser is None:
            self.appraiser = Appraiser(n_states, act=self.act, units=self.units)
        elif self.appraiser.known.n_states != n_states:
            raise ValueError(f"the appraiser was built for {self.appraiser.known.n_states} cells but the env has {n_states}")

    def _init_callback(self) -> None:
        self.prepare(self.model.observation_space, self.model.get_env())

    def prepare(self, space: Any, venv: Any = None) -> None:
        """
        Find the cells of ``space``'s observations (``position``), check them on ``venv`` when given, and create the
        appraiser; a one-line error when the position does not fit the env or Table II would have no map. Called when
        training starts, and by the deep affective agents at construction. A callable's cell numbers are kept from one
        call to the next (the appraiser's map is numbered with them).
        """
        position = self._position
        if position is None or self._position_spec is not self.position:
            position = self._position = make_position(self.position, space)
            self._position_spec = self.position
        if position is not None:
            if venv is not None:
                position.bind(venv, space)
            if venv is not None or position.n_cells:  # a position sized by its env (minigrid) waits for one: a model
                self.bind(position.n_cells)  # loaded without an env keeps its saved appraiser until it gets one
            return
        if getattr(self.emotion_rule, "table_ii_reading", None) is not None:
            raise TypeError(
                f"EmotionCallback: {type(space).__name__} observations have no cells and no position= hook was given, so "
                "the appraisal has no map and act (the known distance to the goal) is never known; Table II "
                "(comparison='literal' or 'valence') needs it. Give position='minigrid' (MiniGrid envs) or "
                "position=callable(observation, info) -> cell, or an emotion_rule(appraisal) using norm and exp1 only "
                "(act is inf), e.g. emotion_rule=lambda a: Emotion.JOY if a is None or a.exp1 <= a.norm else "
                f"Emotion.FEAR. Spaces with a map: Discrete, and MultiDiscrete up to {MAX_MAPPED_CELLS:,} cells"
            )
        if self.appraiser is None:
            self.appraiser = Appraiser(1, act=self.act, units=self.units)  # no map: one placeholder cell

    # -- the affect hook (called directly by AffectQ, and by _on_step in observer mode) -------------------------
    def begin_episode(self) -> None:
        assert self.appraiser is not None, "call bind(n_states) (or attach the callback to a model) first"
        self.appraiser.start_episode()
        self.counts = [0, 0, 0, 0]

    def feel(self, state: int) -> Emotion:
        """Appraise the decision about to be taken in ``state``, feel and count its emotion."""
        assert self.appraiser is not None
        appraiser = self.appraiser
        emotion = self.emotion_rule(appraiser.appraise(state))
        appraiser.elapsed_decisions += 1
        self.counts[emotion] += 1
        self.emotion = emotion
        return emotion

    def observe(self, s: int, s2: int, terminated: bool) -> None:
        """One one-cell transition ``s -> s2`` (``terminated``: it ended the episode at the goal, ``s2`` is a goal)."""
        assert self.appraiser is not None
        self.appraiser.observe(s, s2, terminated)

    def end_episode(self, reached_goal: bool) -> tuple[list[int], float]:
        """Close the episode: feed the norm's regression, log the profile; returns (emotion counts, norm used)."""
        assert self.appraiser is not None
        norm = self.appraiser.norm
        self.appraiser.end_episode(reached_goal)
        counts = self.counts
        total = sum(counts)
        model = getattr(self, "model", None)  # None: the hooks driven by an agent of the user's own
        if total and model is not None:  # per episode; SB3 records whenever a logger exists
            for name, count in zip(EMOTION_NAMES, counts):
                model.logger.record(f"affect/{name}", count / total)
            model.logger.record("affect/norm", norm if norm == norm else 0.0)
        self.count_episodes(1, reached_goal)
        return counts, norm

    def count_episodes(self, episodes: int, reached_goal: bool) -> None:
        """
        ``episodes`` more ended (``reached_goal``: one of them reached the goal): warn once when ``warn_after`` have
        ended and the appraisal knows no goal (``end_episode`` calls it; AffectQ's compiled engine after a run).
        """
        self._episodes += episodes
        self._goals += int(reached_goal)
        self._warn_if_degenerate()

    @property
    def norm(self) -> float:
        return math.nan if self.appraiser is None else self.appraiser.norm

    # -- observer mode -------------------------------------------------------------------------------------------
    def update_locals(self, locals_: dict[str, Any]) -> None:
        """The algorithm's variables of this step, read where they are (SB3's copies them into ``locals`` each step)."""
        self.locals = locals_

    def _on_training_start(self) -> None:
        fields = ModelFields(self.model)
        last_obs = fields.last_obs
        if last_obs is None:
            raise RuntimeError("EmotionCallback: the algorithm has no current observation at training start")
        n_envs = self.training_env.num_envs
        self._geometry = self._find_geometry()
        self._window = WindowMeans(len(WINDOW_KEYS), fields.stats_window_size)
        self._csv_path = self._episode_csv()
        # one lane per env: its own appraisal (env 0 keeps the callback's appraiser), counts and episode in progress
        assert self.appraiser is not None
        lanes = [self._lanes[i] if i < len(self._lanes) else LaneAppraisal(self._new_appraiser()) for i in range(n_envs)]
        self._lanes = lanes
        lanes[0].appraiser = self.appraiser
        cells = self._cells(last_obs, getattr(self.training_env, "reset_infos", None))
        counted = self._counted()
        for lane, cell in zip(lanes, cells):
            lane.begin(cell)
            self.emotion = lane.feel(self.emotion_rule, counted)

    def _new_appraiser(self) -> Appraiser:
        assert self.appraiser is not None
        if type(self.appraiser) is Appraiser:
            return Appraiser(self.appraiser.known.n_states, act=self.appraiser.act_mode, units=self.appraiser.units)
        return copy.deepcopy(self.appraiser)  # a custom appraiser: a fresh copy per env

    def _find_geometry(self) -> Geometry | None:
        position = self._position
        if not isinstance(position, ObservationCells) or position.nvec is not None:
            return None  # the path columns need the grid's own cell numbers
        try:
            return env_geometry(self.training_env.get_attr("unwrapped", [0])[0])
        except Exception:  # an env without the attribute, or a VecEnv that can't fetch it
            return None

    def _cells(self, obs: Any, infos: Any) -> list[int]:
        """Each env's cell (all 0 without a position hook: the appraisal then has no map)."""
        n = len(self._lanes)
        if self._position is None:
            return [0] * n
        return self._position.cells(self.training_env, obs, infos or [{} for _ in range(n)])

    def _counted(self) -> bool:
        """Whether the next decisions enter the emotion profile: not in the warm-up of the agent this callback drives
        (``learning_starts``: SB3's uniformly random actions, not the emotions'); always for an observer."""
        model = self.model
        if getattr(model, "emotion_callback", None) is not self:
            return True
        return bool(model.num_timesteps >= getattr(model, "learning_starts", 0))

    def lane_emotions(self) -> list[Emotion]:
        """Observer mode: the emotion each env of the VecEnv feels for its next decision."""
        return [lane.emotion for lane in self._lanes]

    def lane_appraisers(self) -> list[Appraiser]:
        """Each env's appraiser (its known map and norm), in env order; empty before the first training start."""
        return [lane.appraiser for lane in self._lanes]

    def set_lane_appraisers(self, appraisers: Sequence[Appraiser]) -> None:
        """One lane per appraiser, in env order (env 0's is the callback's ``appraiser``), as a saved callback had."""
        self.appraiser = appraisers[0]
        self._lanes = [LaneAppraisal(appraiser) for appraiser in appraisers]

    def episode_counts(self) -> tuple[int, int, bool]:
        """``(episodes, goals, warned)``: the episodes ended, those that reached the goal, and whether the warning that
        none did has been given."""
        return self._episodes, self._goals, self._warned

    def set_episode_counts(self, episodes: int, goals: int, warned: bool) -> None:
        """The counts ``episode_counts`` gave (a saved callback's)."""
        self._episodes, self._goals, self._warned = episodes, goals, warned

    def forget_run(self) -> None:
        """Drop what ties the callback to a run (the model, its env's position and geometry, the step's locals and
        decision hooks), keeping its settings, appraisers and records: a saved model's copy is made with it."""
        self.model, self.parent = None, None  # type: ignore[assignment]
        self._position, self._position_spec, self._geometry = None, None, None
        self.decision_ends, self.decision_random, self.decision_wait = None, None, None
        self.locals, self.globals = {}, {}

    def _on_step(self) -> bool:
        check_step_locals(self)
        locals_ = self.locals
        dones = flat_array(locals_["dones"]).tolist()
        rewards = flat_array(locals_["rewards"]).tolist()
        infos = locals_["infos"]
        position = self._position
        new_cells = self._cells(locals_["new_obs"], self._start_infos(dones, infos))
        actions = locals_.get("actions")
        if actions is not None:
            actions = np.asarray(actions).reshape(len(self._lanes), -1)
        ends, randoms, waits = self.decision_ends, self.decision_random, self.decision_wait
        counted = self._counted()
        rule = self.emotion_rule
        for index, lane in enumerate(self._lanes):
            if randoms is not None and lane.deciding:
                lane.note_decision(bool(randoms[index]), waits is not None and bool(waits[index]))
            done = bool(dones[index])
            info = infos[index]
            reward = rewards[index]
            truncated = done and bool(info.get("TimeLimit.truncated", False))
            terminated = done and not truncated
            reached_goal = terminated and bool(self.goal(reward, info))
            if reached_goal and lane.reward > 0 and not self._warned_goal and self.goal is positive_terminal_reward:
                self._warn_rewarded_all_along(reward, lane.reward, info)
            s2 = new_cells[index]
            action = None if actions is None else actions[index]
            if done and position is not None:  # the VecEnv has reset: the cell reached is the episode's last
                s2 = position.terminal_cell(index, info, lane.state, action, terminated)
            move = position is None or action is None or position.is_move(action)
            lane.step(s2, reward, reached_goal, position is not None, move)
            if done:
                self._close_lane(index, lane, terminated, truncated, reached_goal)
                lane.begin(new_cells[index])
            if done or ends is None or ends[index]:
                self.emotion = lane.feel(rule, counted)
        return True

    def _start_infos(self, dones: list[bool], infos: Sequence[dict[str, Any]]) -> Sequence[dict[str, Any]]:
        """
        The infos that go with each env's new observation: for an env that has just reset, its reset's info (SB3's
        VecEnvs keep it in ``reset_infos``; the step's ``infos`` hold the ended episode's last info), else the step's.
        """
        if not any(dones):
            return infos
        reset_infos = getattr(self.training_env, "reset_infos", None)
        if reset_infos is None or len(reset_infos) != len(infos):
            return infos
        return [reset_infos[index] if done else info for index, (done, info) in enumerate(zip(dones, infos))]

    def _on_rollout_end(self) -> None:
        self._window.record(self.logger, WINDOW_KEYS, again=False)

    def _on_training_end(self) -> None:
        self._window.record(self.logger, WINDOW_KEYS)

    def _close_lane(self, index: int, lane: LaneAppraisal, terminated: bool, truncated: bool, reached_goal: bool) -> None:
        counts, norm = lane.close(reached_goal)
        self.counts = counts
        shares = lane.shares()
        if shares is not None:  # an episode wholly in the warm-up has no counted decision
            self._window.append([*shares, norm])
            self._window.record(self.logger, WINDOW_KEYS)
        self._episodes += 1
        self._goals += int(reached_goal)
        self._warn_if_degenerate()
        geometry = self._geometry
        optimal: Any = math.nan
        greedy: Any = math.nan
        if geometry is not None:
            optimal = terminated and lane.steps == geometry.shortest_path_length
            actions, _ = self.model.predict(np.arange(len(geometry.transitions)), deterministic=True)
            greedy = deterministic_walk_is_shortest(np.asarray(actions).reshape(-1).tolist(), geometry)
        told = self.decision_random is not None
        row = [len(self.rows) + 1, lane.decisions, lane.steps, lane.reward, optimal, truncated,
               lane.random_moves if told else math.nan, lane.waits, *counts, greedy, norm, index]
        self.rows.append(row)
        if self._csv_path is not None:
            self._append_csv(row)

    def _warn_rewarded_all_along(self, reward: float, before: float, info: dict[str, Any]) -> None:
        """
        Warn once when the default goal test takes a termination for the goal although its reward is not set apart
        from the episode's: the rewards before it were positive too (CartPole's +1 a step, whose termination is the
        pole falling). The env's ``is_success`` settles it without a warning.
        """
        if "is_success" in info:
            return
        self._warned_goal = True
        warnings.warn(
            f"EmotionCallback: an episode terminated with reward {reward:g} after rewards summing to {before:g}: the "
            "default goal test (terminated with a reward > 0) counts it as reaching the goal, but a terminal reward of "
            "the same sign as the rest of the return may end a failure (CartPole's pole falling), and the appraisal "
            "then maps its way to that state. If this env's terminations are not its goal, pass "
            "EmotionCallback(goal=lambda reward, info: ...) (see sb3_affect.core.goals); passing goal= silences this",
            RuntimeWarning,
            stacklevel=3,
        )

    def _warn_if_degenerate(self) -> None:
        if self._warned or self._goals or self.warn_after is None or self._episodes < self.warn_after:
            return
        if self._lanes == [] and self.appraiser is not None and _knows_a_goal(self.appraiser):
            return  # driven by an agent whose appraisal learnt the goal before (an earlier learn, a loaded model)
        self._warned = True
        model = getattr(self, "model", None)
        driver = type(model).__name__ if model is not None and getattr(model, "emotion_callback", None) is self else ""
        option = "EmotionCallback(goal=lambda reward, info: ...)"
        where = f"{driver}(..., emotion_callback={option})" if driver else option
        warnings.warn(
            f"{driver or 'EmotionCallback'}: none of the first {self._episodes} episodes reached the goal, so the "
            "appraisal knows no distance to it (act) and Table II can only give joy (fear or anger "
            "under comparison='valence'). If this env's success is not 'terminated with a reward > 0' (or "
            f"info['is_success']), pass {where} (see sb3_affect.core.goals, e.g. every_termination)",
            RuntimeWarning,
            stacklevel=3,
        )

    def _episode_csv(self) -> Path | None:
        """Where the episode log is written: ``episode_log_path``, else beside a logger that writes files, else None."""
        if self.episode_log_path is not None:
            return Path(self.episode_log_path)
        folder = logger_file_folder(self.logger)
        return None if folder is None else folder / "emotion_episodes.csv"

    def _append_csv(self, row: list[Any]) -> None:
        assert self._csv_path is not None
        new = not self._csv_path.exists()
        self._csv_path.parent.mkdir(parents=True, exist_ok=True)
        with self._csv_path.open("a", newline="") as handle:
            writer = csv.writer(handle)
            if new:
                writer.writerow(EMOTION_CALLBACK_COLUMNS)
            writer.writerow(row)

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per episode observed (observer mode), columns ``EMOTION_CALLBACK_COLUMNS`` (``env``: the env index)."""
        frame = make_frame([row[:-1] for row in self.rows])
        frame["env"] = np.asarray([row[-1] for row in self.rows], dtype=np.int64)
        return frame


def _knows_a_goal(appraiser: Appraiser) -> bool:
    """Whether the appraiser's known map has a goal (the compiled engine's map is read without building it)."""
    kept = appraiser.deferred("known")
    goal = getattr(kept, "goal", None)
    return bool(np.any(goal)) if goal is not None else bool(appraiser.known.goals)


class WindowMeans:
    """
    The mean of each column over the last ``size`` rows (an episode's figures each), NaN values left out, as the
    callbacks log their keys over SB3's stats window. Running sums make a row and a read O(1); they are summed afresh
    every ``size`` rows, so rounding never accumulates.
    """

    def __init__(self, columns: int, size: int = 100) -> None:
        self.size = size
        self.rows: deque[list[float]] = deque(maxlen=size)
        self._sums = [0.0] * columns
        self._counts = [0] * columns
        self._added = 0
        self._recorded = -1  # rows appended when the means were last recorded in a logger

    def __len__(self) -> int:
        return len(self.rows)

    def append(self, row: list[float]) -> None:
        rows = self.rows
        if len(rows) == self.size:
            self._add(rows[0], -1)
        rows.append(row)
        self._added += 1
        if self._added % self.size == 0:
            self._sums = [math.fsum(value for value in column if value == value) for column in zip(*rows)]
            self._counts = [sum(value == value for value in column) for column in zip(*rows)]
        else:
            self._add(row, 1)

    def resized(self, size: int) -> WindowMeans:
        """A window of ``size`` rows holding this one's last rows."""
        window = WindowMeans(len(self._sums), size)
        for row in self.rows:
            window.append(row)
        return window

    def _add(self, row: list[float], sign: int) -> None:
        for column, value in enumerate(row):
            if value == value:
                self._sums[column] += sign * value
                self._counts[column] += sign

    def means(self) -> list[float]:
        """Each column's mean over the window (NaN for a column with no value in it)."""
        return [total / count if count else math.nan for total, count in zip(self._sums, self._counts)]

    def record(self, logger: Any, keys: Sequence[str], again: bool = True) -> None:
        """
        Record each column's mean under its key in an SB3 logger (a NaN mean is left out); ``again=False``: only if a
        row was appended since they were last recorded or the logger has written them out since (an off-policy
        rollout is a few steps: most rollouts have neither, and recording costs more than the step's own work).
        """
        unchanged = not again and self._recorded == self._added
        if unchanged and (not self._added or keys[0] in getattr(logger, "name_to_value", ())):
            return  # unchanged and still in the logger, or no row yet (every mean NaN: nothing to record)
        for key, mean in zip(keys, self.means()):
            if mean == mean:
                logger.record(key, mean)
        self._recorded = self._added


def flat_array(values: Any, dtype: type | None = None) -> np.ndarray:
    """A VecEnv's per-env array as a 1-d array (``dtype``: converted to it), not copied when it is one already."""
    if type(values) is np.ndarray and values.ndim == 1 and (dtype is None or values.dtype == dtype):
        return values
    return np.asarray(values, dtype=dtype).reshape(-1)


def check_step_locals(callback: BaseCallback) -> None:
    """A RuntimeError when the algorithm calls ``on_step`` without the step's VecEnv results (ARS does)."""
    if "dones" not in callback.locals or "new_obs" not in callback.locals:
        raise RuntimeError(
            f"{type(callback).__name__}: {type(callback.model).__name__} calls its callbacks without the step's "
            "observations (new_obs, rewards, dones, infos: SB3's on-policy and off-policy algorithms pass them, ARS "
            "does not), so there is nothing to appraise"
        )


def logger_file_folder(logger: Any) -> Path | None:
    """The folder of an SB3 logger that writes files (csv, tensorboard, json, log.txt); None for stdout only."""
    folder = logger.get_dir() if logger is not None else None
    if folder is None:
        return None
    for output in logger.output_formats:
        if not (isinstance(output, HumanOutputFormat) and not getattr(output, "own_file", True)):
            return Path(folder)
    return None
