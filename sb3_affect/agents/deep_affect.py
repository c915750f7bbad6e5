"""
Affective exploration for SB3's off-policy discrete agents: ``AffectDQN`` (SB3's DQN) and the mixin
``AffectiveExploration`` it is made of, which goes on any ``OffPolicyAlgorithm`` subclass with a Discrete action space
(``AffectQRDQN`` in ``sb3_affect.agents.deep_affect_qrdqn`` puts it on sb3-contrib's QR-DQN).

SB3 calls its callbacks after ``env.step``, too late to choose the step's action, so the emotions enter where SB3
chooses it: ``_sample_action``. Each env of the VecEnv has its own appraisal (an ``EmotionCallback`` in observer mode,
which the agent adds to the callbacks of ``learn``) and so its own emotion; the emotion's behaviour (Table III by
default) gives the decision's direction (joy: a uniformly random action; anger, sadness, fear: the Q-network's greedy
action; there is no epsilon) and its speed k:

* k = 1 or 2: the action is taken for the next k env steps of that env, each stored in the replay buffer as its own
  one-step transition; the env makes no new decision until the repeat is done, and an episode's end ends the repeat;
* k = 0: a wait, the env's ``wait_action`` (a no-op, e.g. MiniGrid's ``done``) for one step; without a
  ``wait_action`` the decision is taken at speed 1 (the emotion's direction for one step), because an env step with
  no action does not exist.

The repeats, the waits and their logging are ``sb3_affect.agents.action_repeat.ActionRepeat``'s, which the exploration
controls of ``sb3_affect.agents.deep_controls`` share: the emotions are one decision rule among them. Everything else
is SB3's loop: ``learning_starts`` warms the buffer up with SB3's uniformly random actions (the appraisal learns from
them; the emotions felt then stay out of the emotion profile), the buffer stores the executed action, and training and
target updates are the base algorithm's. ``save`` adds the emotion callback (its settings, each env's appraisal, the
episode log: ``sb3_affect.agents.affect_state``) and ``load`` unpickles nothing unless asked
(``sb3_affect.agents.deep_model_files``). The episode log is ``model.episode_log``. Logged besides ``affect/*``
(the emotion profile, from the callback): ``affect/random_share`` (the share of decisions after ``learning_starts``
that took a random action, the equivalent epsilon, also logged as ``rollout/exploration_rate``) and
``affect/mean_repeat`` (their mean speed k), over the decisions since the last log.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback, ConvertCallback
from stable_baselines3.common.type_aliases import MaybeCallback

from sb3_affect.agents.action_repeat import ActionRepeat
from sb3_affect.agents.affect_state import callback_state, restore_callback
from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.core.behaviour import Behaviour, behaviour_by_emotion, stored_behaviour_table
from sb3_affect.core.emotions import Emotion
from sb3_affect.core.positions import PositionSpec, check_position

if TYPE_CHECKING:
    import pandas as pd

#: The base algorithm's epsilon arguments, fixed at 0 by the mixin (the emotions explore).
_EPSILON_ARGUMENTS = ("exploration_initial_eps", "exploration_final_eps")


#: the ``EmotionCallback`` arguments a dict may give: plain settings (no code, no file paths)
READING_ARGUMENTS = ("comparison", "act", "units", "order", "warn_after")


def emotion_callback_from(arguments: Mapping[str, Any]) -> EmotionCallback:
    """``EmotionCallback(**arguments)`` from plain settings; any other key refused with one line."""
    unknown = [key for key in arguments if key not in READING_ARGUMENTS]
    if unknown:
        raise ValueError(f"emotion_callback.{unknown[0]} can not be given as data: a dict gives "
                         f"{', '.join(READING_ARGUMENTS)}")
    return EmotionCallback(**arguments)


class AffectiveExploration(ActionRepeat):
    """
    A mixin giving an ``OffPolicyAlgorithm`` with a Discrete action space emotion-driven exploration (see the module
    docstring). Put it first: ``class MyAgent(AffectiveExploration, MyOffPolicyAlgorithm)``. The algorithm's greedy
    action is its ``predict(obs, deterministic=False)`` with ``exploration_rate`` 0. The repeats and waits are
    ``sb3_affect.agents.action_repeat.ActionRepeat``'s; the emotion of each env is the decision rule.

    :param behaviour_table: emotion -> ``Behaviour(random_direction, speeds)``, or a table's name (``"table-iii"``,
        ``"table-iii-reversed"``: ``sb3_affect.core.behaviour.BEHAVIOUR_TABLES``); default Table III
    :param emotion_callback: the ``EmotionCallback`` whose appraisal and emotion rule drive the agent (default: a
        Table II one), or a dict of its arguments (``{"comparison": "valence", "act": "remaining", "order": "act-first"}``:
        the form a hyperparameter or sweep file can hold); it is added to the callbacks of ``learn``
    :param position: how each env's cell is found for the appraisal's map (``sb3_affect.core.positions``): None (the
        observation, when it is a cell), ``"discrete"``, ``"multidiscrete"``, ``"minigrid"``, ``"minigrid-dir"``, a
        callable ``position(observation, info) -> cell`` or a ``Position``; given to the emotion callback
    :param wait_action: the action a wait (speed 0) takes, e.g. MiniGrid's ``done`` (6); None: waits move at speed 1
    """

    LOG_PREFIX = "affect"

    def __init__(
        self,
        *args: Any,
        behaviour_table: Mapping[Emotion, Behaviour] | str | None = None,
        emotion_callback: EmotionCallback | Mapping[str, Any] | None = None,
        position: PositionSpec = None,
        wait_action: int | None = None,
        **kwargs: Any,
    ) -> None:
        name = type(self).__name__
        given = [key for key in (*_EPSILON_ARGUMENTS, "exploration_fraction") if key in kwargs]
        if given:
            raise TypeError(f"{name} has no epsilon ({given[0]}={kwargs[given[0]]!r}): the emotions choose random actions")
        if isinstance(emotion_callback, Mapping):
            emotion_callback = emotion_callback_from(emotion_callback)
        if emotion_callback is not None and not isinstance(emotion_callback, EmotionCallback):
            raise TypeError(f"emotion_callback must be an EmotionCallback or a dict of its arguments, "
                            f"got {type(emotion_callback).__name__}")
        self.behaviour_table = stored_behaviour_table(behaviour_table)  # plain data, saved with the model
        self.position = check_position(position)
        self.emotion_callback = emotion_callback
        parameters = inspect.signature(super(ActionRepeat, self).__init__).parameters  # the algorithm's own
        for key in _EPSILON_ARGUMENTS:
            if key in parameters:
                kwargs[key] = 0.0
        super().__init__(*args, wait_action=wait_action, **kwargs)

    # -- set-up ----------------------------------------------------------------------------------------------------
    def _setup_model(self) -> None:
        super()._setup_model()
        # a loaded model's values come from its file: checked as the constructor checks them
        self.behaviour_table = stored_behaviour_table(self.behaviour_table)
        self.position = check_position(self.position)
        saved, objects = self.__dict__.pop("_affect_state", None), self.__dict__.pop("_affect_objects", None)
        if self.emotion_callback is None:
            self.emotion_callback = EmotionCallback() if saved is None else restore_callback(saved, objects)
        callback = self.emotion_callback
        if self.position is not None:
            callback.position = self.position
        callback.prepare(self.observation_space, self.env)  # a position that does not fit the env: refused now
        self._behaviour = behaviour_by_emotion(self.behaviour_table)
        self._emotions: list[Emotion] = []

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "emotion_callback", "_behaviour", "_emotions"]

    @property
    def decision_emotions(self) -> list[Emotion]:
        """The emotion each env decided its current action by (empty in the warm-up and before the first step)."""
        return self._emotions

    def save(self, path: Any, exclude: Any = None, include: Any = None) -> None:
        """
        Save as SB3 does, with the emotion callback: its settings, each env's appraisal (known map, the norm's history)
        and the episode log, as plain data. A custom emotion rule, goal test or appraiser class is pickled by SB3, so
        only ``load(path, safe=False)`` restores such a file.
        """
        assert self.emotion_callback is not None
        self._affect_state, objects = callback_state(self.emotion_callback)
        if objects:
            self._affect_objects = objects
        try:
            super().save(path, exclude=exclude, include=include)
        finally:
            self.__dict__.pop("_affect_state", None)
            self.__dict__.pop("_affect_objects", None)

    @property
    def episode_log(self) -> pd.DataFrame:
        """One row per episode of training (``EMOTION_CALLBACK_COLUMNS``: the agents' columns and the env index), as
        ``AffectQ.episode_log``; the emotion callback's."""
        assert self.emotion_callback is not None
        return self.emotion_callback.episode_log

    def _init_callback(self, callback: MaybeCallback, progress_bar: bool = False) -> BaseCallback:
        """The emotion callback first, then the user's (SB3 makes them one ``CallbackList``)."""
        if callback is None:
            given: list[BaseCallback] = []
        elif isinstance(callback, list):
            given = list(callback)
        else:
            given = [callback if isinstance(callback, BaseCallback) else ConvertCallback(callback)]
        assert self.emotion_callback is not None
        others = [c for c in given if c is not self.emotion_callback]
        return super()._init_callback([self.emotion_callback, *others], progress_bar)  # type: ignore[misc]

    # -- the decisions: each env's emotion ---------------------------------------------------------------------------
    def _begin_decisions(self, n_envs: int) -> None:
        assert self.emotion_callback is not None
        self._emotions = self.emotion_callback.lane_emotions()

    def _decide(self, index: int) -> tuple[bool, int]:
        random_direction, speeds = self._behaviour[self._emotions[index]]
        speed = speeds[0] if len(speeds) == 1 else speeds[int(self._decision_rng.integers(len(speeds)))]
        return random_direction, speed

    def _decisions_taken(self, ends: np.ndarray | None, random_direction: np.ndarray, wait: np.ndarray) -> None:
        callback = self.emotion_callback
        assert callback is not None
        callback.decision_ends, callback.decision_random, callback.decision_wait = ends, random_direction, wait

    # -- logging ---------------------------------------------------------------------------------------------------
    def dump_logs(self) -> None:
        if self._decisions:
            self.logger.record("rollout/exploration_rate", self._random_decisions / self._decisions)
        super().dump_logs()


class AffectDQN(AffectiveExploration, DQN):
    """
    SB3's DQN whose exploration is the paper's emotions instead of epsilon (``sb3_affect.agents.deep_affect``): each env's
    emotion chooses a random (joy) or greedy action and how many env steps it lasts. Arguments: DQN's (without
    ``exploration_*``) and ``behaviour_table``, ``emotion_callback``, ``position``, ``wait_action``
    (``AffectiveExploration``).
    """
