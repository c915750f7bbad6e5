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

Everything else is SB3's loop: ``learning_starts`` warms the buffer up with SB3's uniformly random actions (the
appraisal watches them), the buffer stores the executed action, and training, target updates, saving and loading are
the base algorithm's. Logged besides ``affect/*`` (the emotion profile, from the callback): ``affect/random_share``
(the share of decisions after ``learning_starts`` that took a random action, the equivalent epsilon, also logged as
``rollout/exploration_rate``) and ``affect/mean_repeat`` (their mean speed k), over the decisions since the last log.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces
from stable_baselines3 import DQN
from stable_baselines3.common.callbacks import BaseCallback, ConvertCallback
from stable_baselines3.common.type_aliases import MaybeCallback

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.core.behaviour import Behaviour, behaviour_by_emotion, stored_behaviour_table
from sb3_affect.core.emotions import Emotion
from sb3_affect.core.positions import PositionSpec, check_position

#: The base algorithm's epsilon arguments, fixed at 0 by the mixin (the emotions explore).
_EPSILON_ARGUMENTS = ("exploration_initial_eps", "exploration_final_eps")


class AffectiveExploration:
    """
    A mixin giving an ``OffPolicyAlgorithm`` with a Discrete action space emotion-driven exploration (see the module
    docstring). Put it first: ``class MyAgent(AffectiveExploration, MyOffPolicyAlgorithm)``. The algorithm's greedy
    action is its ``predict(obs, deterministic=False)`` with ``exploration_rate`` 0.

    :param behaviour_table: emotion -> ``Behaviour(random_direction, speeds)``; default Table III
    :param emotion_callback: the ``EmotionCallback`` whose appraisal and emotion rule drive the agent (default: a
        Table II one); it is added to the callbacks of ``learn``
    :param position: how each env's cell is found for the appraisal's map (``sb3_affect.core.positions``): None (the
        observation, when it is a cell), ``"discrete"``, ``"multidiscrete"``, ``"minigrid"``, ``"minigrid-dir"``, a
        callable ``position(observation, info) -> cell`` or a ``Position``; given to the emotion callback
    :param wait_action: the action a wait (speed 0) takes, e.g. MiniGrid's ``done`` (6); None: waits move at speed 1
    """

    # attributes of the base algorithm the mixin uses
    action_space: spaces.Space
    num_timesteps: int
    learning_starts: int
    exploration_rate: float
    logger: Any
    _last_obs: Any
    n_envs: int

    def __init__(
        self,
        *args: Any,
        behaviour_table: Mapping[Emotion, Behaviour] | None = None,
        emotion_callback: EmotionCallback | None = None,
        position: PositionSpec = None,
        wait_action: int | None = None,
        **kwargs: Any,
    ) -> None:
        name = type(self).__name__
        given = [key for key in (*_EPSILON_ARGUMENTS, "exploration_fraction") if key in kwargs]
        if given:
            raise TypeError(f"{name} has no epsilon ({given[0]}={kwargs[given[0]]!r}): the emotions choose random actions")
        if emotion_callback is not None and not isinstance(emotion_callback, EmotionCallback):
            raise TypeError(f"emotion_callback must be an EmotionCallback, got {type(emotion_callback).__name__}")
        self.behaviour_table = stored_behaviour_table(behaviour_table)  # plain data, saved with the model
        if wait_action is not None and (isinstance(wait_action, bool) or not isinstance(wait_action, (int, np.integer))):
            raise TypeError(f"wait_action must be an integer action or None, got {wait_action!r}")
        self.wait_action = None if wait_action is None else int(wait_action)
        self.position = check_position(position)
        self.emotion_callback = emotion_callback
        parameters = inspect.signature(super().__init__).parameters
        for key in _EPSILON_ARGUMENTS:
            if key in parameters:
                kwargs[key] = 0.0
        super().__init__(*args, **kwargs)

    # -- set-up ----------------------------------------------------------------------------------------------------
    def _setup_model(self) -> None:
        super()._setup_model()  # type: ignore[misc]
        name = type(self).__name__
        space = self.action_space
        if not isinstance(space, spaces.Discrete):
            raise TypeError(f"{name} needs a Discrete action space (its random actions are uniform), got {space}")
        if self.wait_action is not None and not space.contains(np.int64(self.wait_action)):
            raise ValueError(
                f"wait_action={self.wait_action} is outside the action space {space}: give an action "
                f"{int(space.start)}..{int(space.start) + int(space.n) - 1} or None"
            )
        if self.emotion_callback is None:
            self.emotion_callback = EmotionCallback()
        if self.position is not None:
            self.emotion_callback.position = self.position
        self._behaviour = behaviour_by_emotion(self.behaviour_table)
        self._affect_rng = np.random.default_rng(getattr(self, "seed", None))
        self._remaining = np.zeros(0, dtype=np.int64)
        self._repeated = np.zeros(0, dtype=np.int64)
        self._decisions = self._random_decisions = self._speed_sum = 0

    def _excluded_save_params(self) -> list[str]:
        excluded: list[str] = super()._excluded_save_params()  # type: ignore[misc]
        return [*excluded, "emotion_callback", "_behaviour", "_affect_rng", "_remaining", "_repeated"]

    def set_random_seed(self, seed: int | None = None) -> None:
        super().set_random_seed(seed)  # type: ignore[misc]
        if seed is not None:
            self._affect_rng = np.random.default_rng(seed)

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

    # -- the decisions -----------------------------------------------------------------------------------------------
    def _sample_action(self, learning_starts: int, action_noise: Any = None, n_envs: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """SB3's action (random in the warm-up, else greedy: epsilon is 0), replaced by each env's affective decision."""
        actions, _ = super()._sample_action(learning_starts, action_noise, n_envs)  # type: ignore[misc]
        callback = self.emotion_callback
        assert callback is not None
        if len(self._remaining) != n_envs:
            self._remaining = np.zeros(n_envs, dtype=np.int64)
            self._repeated = np.zeros(n_envs, dtype=np.int64)
        remaining = self._remaining
        if self.num_timesteps < learning_starts:  # SB3's warm-up: every step is a random decision of its own
            remaining[:] = 0
            callback.decision_ends = None
            return actions, actions
        actions = np.array(actions, copy=True).reshape(n_envs)
        emotions = callback.lane_emotions()
        rng = self._affect_rng
        n_actions = int(self.action_space.n)  # type: ignore[attr-defined]
        start = int(self.action_space.start)  # type: ignore[attr-defined]
        for index in range(n_envs):
            if remaining[index] > 0:  # repeating: the action of the decision in progress
                remaining[index] -= 1
                actions[index] = self._repeated[index]
                continue
            random_direction, speeds = self._behaviour[emotions[index]]
            speed = speeds[0] if len(speeds) == 1 else speeds[int(rng.integers(len(speeds)))]
            if random_direction:
                actions[index] = start + int(rng.integers(n_actions))
            if speed == 0 and self.wait_action is not None:
                actions[index] = self.wait_action
            self._decisions += 1
            self._random_decisions += random_direction
            self._speed_sum += speed if self.wait_action is not None else max(speed, 1)
            remaining[index] = max(speed, 1) - 1
            self._repeated[index] = actions[index]
        callback.decision_ends = remaining == 0
        return actions, actions

    def _store_transition(self, replay_buffer: Any, buffer_action: np.ndarray, new_obs: Any, reward: np.ndarray,
                          dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)  # type: ignore[misc]
        if len(self._remaining) == len(dones):
            self._remaining[np.asarray(dones, dtype=bool)] = 0  # an episode's end ends the repeat

    # -- logging ---------------------------------------------------------------------------------------------------
    def dump_logs(self) -> None:
        if self._decisions:
            share = self._random_decisions / self._decisions
            self.logger.record("affect/random_share", share)
            self.logger.record("affect/mean_repeat", self._speed_sum / self._decisions)
            self.logger.record("rollout/exploration_rate", share)
            self._decisions = self._random_decisions = self._speed_sum = 0
        super().dump_logs()  # type: ignore[misc]


class AffectDQN(AffectiveExploration, DQN):
    """
    SB3's DQN whose exploration is the paper's emotions instead of epsilon (``sb3_affect.agents.deep_affect``): each env's
    emotion chooses a random (joy) or greedy action and how many env steps it lasts. Arguments: DQN's (without
    ``exploration_*``) and ``behaviour_table``, ``emotion_callback``, ``position``, ``wait_action``
    (``AffectiveExploration``).
    """
