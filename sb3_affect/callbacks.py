"""
Emotions as an SB3 callback.

``EmotionCallback`` appraises every decision, feels one emotion (Table II) and logs the emotion profile. It works in
two ways:

* **Observer** (any SB3 algorithm on a Discrete-observation env, e.g. DQN): attach it to ``learn``. SB3 calls
  ``_on_step`` after each ``env.step``; the callback reads ``new_obs``/``dones``/``infos`` from the algorithm's
  locals, updates its appraisal and feels the emotion of the *next* decision. It only watches: it logs ``affect/*``
  keys and keeps ``episode_log``.
* **Driver of AffectQ** (the affect hook): an SB3 callback runs after ``env.step``, too late to steer the step it
  follows. AffectQ therefore calls the callback's hook methods directly, in this order, for every decision::

      emotion = callback.feel(state)          # before the decision: appraise, apply the emotion rule, count it
      callback.observe(s, s2, reached_goal)   # for each one-cell transition the decision makes (0, 1 or 2)
      callback.end_episode(reached_goal)      # at the end of an episode (then begin_episode() for the next)

  ``feel`` is called exactly once per decision and counts it (the appraisal of a decision sees the decisions
  before it).

  and uses the returned emotion to look up direction and speed in its behaviour table (Table III). Swap the
  appraisal by passing your own ``Appraiser`` subclass, or the emotion rule by passing ``emotion_rule``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from sb3_affect.appraisal import Appraiser
from sb3_affect.emotions import EMOTION_NAMES, Emotion, EmotionRule, make_table_ii
from sb3_affect.episode_log import Geometry, deterministic_walk_is_shortest, env_geometry, make_frame
from sb3_affect.goals import GoalTest, positive_terminal_reward

if TYPE_CHECKING:
    import pandas as pd


class EmotionCallback(BaseCallback):
    """
    Appraise each decision, feel one of joy, sadness, fear or anger, count and log it.

    :param comparison: Table II reading, ``"literal"`` or ``"valence"`` (docs/definitions.md)
    :param act: ``"episode"`` (elapsed + known remaining) or ``"remaining"`` (known remaining only)
    :param units: ``"cells"`` or ``"decisions"``: what norm, exp1 and act count
    :param appraiser: a ready appraiser to use instead of building one from ``act`` and ``units``
        (it must be created for the env's number of cells)
    :param emotion_rule: ``rule(appraisal_or_None) -> Emotion`` replacing Table II
    :param goal: ``goal(reward, info) -> bool``, whether a terminating transition reached the goal (default
        ``sb3_affect.goals.positive_terminal_reward``: ``info["is_success"]`` if the env gives it, else reward > 0)
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
        verbose: int = 0,
    ) -> None:
        super().__init__(verbose)
        if goal is not None and not callable(goal):
            raise TypeError(f"goal must be a callable goal(reward, info) -> bool, got {goal!r}")
        self.goal: GoalTest = positive_terminal_reward if goal is None else goal
        self.comparison = comparison
        self.act = act
        self.units = units
        self.emotion_rule: EmotionRule = emotion_rule if emotion_rule is not None else make_table_ii(comparison)
        self.appraiser: Appraiser | None = appraiser
        if appraiser is None:
            Appraiser(1, act=act, units=units)  # validate the options now, with a clear error
        self.emotion: Emotion = Emotion.JOY
        self.counts = [0, 0, 0, 0]
        self.rows: list[list[Any]] = []
        # observer-mode state
        self._state: int | None = None
        self._decisions = 0
        self._cells = 0
        self._reward = 0.0
        self._geometry: Geometry | None = None

    # -- set-up ------------------------------------------------------------------------------------------------
    def bind(self, n_states: int) -> None:
        """Create the appraiser for an env with ``n_states`` cells (once; later calls keep what it knows)."""
        if self.appraiser is None:
            self.appraiser = Appraiser(n_states, act=self.act, units=self.units)
        elif self.appraiser.known.n_states != n_states:
            raise ValueError(f"the appraiser was built for {self.appraiser.known.n_states} cells but the env has {n_states}")

    def _init_callback(self) -> None:
        space = self.model.observation_space
        if not hasattr(space, "n"):
            raise TypeError(f"EmotionCallback needs a Discrete observation space (one cell per observation), got {space}")
        self.bind(int(space.n))

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
        if total and self.model is not None:  # per episode; SB3 records whenever a logger exists
            for name, count in zip(EMOTION_NAMES, counts):
                self.logger.record(f"affect/{name}", count / total)
            self.logger.record("affect/norm", norm if norm == norm else 0.0)
        return counts, norm

    @property
    def norm(self) -> float:
        return math.nan if self.appraiser is None else self.appraiser.norm

    # -- observer mode -------------------------------------------------------------------------------------------
    def _on_training_start(self) -> None:
        last_obs = getattr(self.model, "_last_obs", None)
        if last_obs is None:
            raise RuntimeError("EmotionCallback: the algorithm has no current observation at training start")
        self._geometry = self._find_geometry()
        self._state = int(np.asarray(last_obs).reshape(-1)[0])
        self._decisions = self._cells = 0
        self._reward = 0.0
        self.begin_episode()
        self.feel(self._state)

    def _find_geometry(self) -> Geometry | None:
        try:
            return env_geometry(self.training_env.get_attr("unwrapped", [0])[0])
        except Exception:  # an env without the attribute, or a VecEnv that can't fetch it
            return None

    def _on_step(self) -> bool:
        if self.training_env.num_envs != 1:
            raise ValueError("EmotionCallback observes a single env; this VecEnv has several")
        assert self._state is not None
        done = bool(self.locals["dones"][0])
        info = self.locals["infos"][0]
        new_state = int(np.asarray(self.locals["new_obs"]).reshape(-1)[0])
        truncated = done and bool(info.get("TimeLimit.truncated", False))
        terminated = done and not truncated
        reward = float(np.asarray(self.locals["rewards"]).reshape(-1)[0])
        reached_goal = terminated and bool(self.goal(reward, info))
        s2 = (
            int(np.asarray(info["terminal_observation"]).reshape(-1)[0])
            if done and "terminal_observation" in info
            else new_state
        )
        self.observe(self._state, s2, reached_goal)
        self._decisions += 1
        self._cells += 1
        self._reward += reward
        if done:
            self._close_observed_episode(terminated, truncated, reached_goal)
            self._decisions = self._cells = 0
            self._reward = 0.0
            self.begin_episode()
        self._state = new_state
        self.feel(new_state)
        return True

    def _close_observed_episode(self, terminated: bool, truncated: bool, reached_goal: bool) -> None:
        counts, norm = self.end_episode(reached_goal)
        geometry = self._geometry
        optimal: Any = math.nan
        greedy: Any = math.nan
        if geometry is not None:
            optimal = terminated and self._cells == geometry.shortest_path_length
            actions, _ = self.model.predict(np.arange(len(geometry.transitions)), deterministic=True)
            greedy = deterministic_walk_is_shortest(np.asarray(actions).reshape(-1).tolist(), geometry)
        self.rows.append(
            [
                len(self.rows) + 1,
                self._decisions,
                self._cells,
                self._reward,
                optimal,
                truncated,
                math.nan,
                0,
                *counts,
                greedy,
                norm,
            ]
        )

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per episode observed (observer mode), columns ``EPISODE_COLUMNS``."""
        return make_frame(self.rows)
