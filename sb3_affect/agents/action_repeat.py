"""
Decisions that last several env steps, on SB3's off-policy discrete agents: ``ActionRepeat``, the mixin under
``AffectiveExploration`` (the emotions decide) and the exploration controls of ``sb3_affect.agents.deep_controls``
(ez-greedy, epsilon-greedy with speeds).

A subclass gives one decision rule, ``_decide(index) -> (random_direction, speed)`` for env ``index`` of the VecEnv,
and the mixin does the rest in SB3's ``_sample_action``, per env:

* ``random_direction``: a uniformly random action, else the base algorithm's greedy action (its ``predict`` with
  ``exploration_rate`` 0);
* ``speed`` k >= 1: the action is taken for the next k env steps of that env, each stored in the replay buffer as its
  own one-step transition; the env makes no new decision until the repeat is done, and an episode's end ends it;
* ``speed`` 0: a wait, the env's ``wait_action`` for one step; without a ``wait_action`` the decision is taken at
  speed 1 (an env step with no action does not exist).

SB3's warm-up (``learning_starts``) keeps SB3's uniformly random actions, one step each. Logged under ``<prefix>/``
(``LOG_PREFIX``): ``random_share``, the share of decisions after the warm-up that took a random action, and
``mean_repeat``, their mean speed, over the decisions since the last log.
"""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.type_aliases import GymEnv

from sb3_affect.agents.deep_model_files import add_deep_description, load_deep_safe
from sb3_affect.agents.serialization import WRITE_PATHS, paths_from_caller

SelfRepeat = TypeVar("SelfRepeat", bound="ActionRepeat")


def check_wait_action(wait_action: Any) -> int | None:
    """A ``wait_action`` as an int, or a one-line error (the space's range is checked once the env is known)."""
    if wait_action is None:
        return None
    if isinstance(wait_action, bool) or not isinstance(wait_action, (int, np.integer)):
        raise TypeError(f"wait_action must be an integer action or None, got {wait_action!r}")
    return int(wait_action)


class ActionRepeat:
    """
    A mixin for an ``OffPolicyAlgorithm`` with a Discrete action space whose ``predict(obs, deterministic=False)`` is
    greedy when its ``exploration_rate`` is 0 (DQN, QR-DQN): decisions of a rule (``_decide``) that last ``speed``
    env steps. Put it first among the bases.

    :param wait_action: the action a wait (speed 0) takes, e.g. MiniGrid's ``done`` (6); None: waits move at speed 1
    """

    #: the logger's section of ``random_share`` and ``mean_repeat``
    LOG_PREFIX = "exploration"

    # attributes of the base algorithm the mixin uses
    action_space: spaces.Space
    observation_space: spaces.Space
    env: Any
    num_timesteps: int
    exploration_rate: float
    logger: Any
    n_envs: int

    def __init__(self, *args: Any, wait_action: int | None = None, **kwargs: Any) -> None:
        self.wait_action = check_wait_action(wait_action)
        super().__init__(*args, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()  # type: ignore[misc]
        name = type(self).__name__
        space = self.action_space
        if not isinstance(space, spaces.Discrete):
            raise TypeError(f"{name} needs a Discrete action space (its random actions are uniform), got {space}")
        self.wait_action = check_wait_action(self.wait_action)  # again: a loaded model's value comes from its file
        first, last = int(space.start), int(space.start) + int(space.n) - 1
        if self.wait_action is not None and not first <= self.wait_action <= last:
            raise ValueError(f"wait_action={self.wait_action} is outside the action space {space}: give an action "
                             f"{first}..{last} or None")
        self._decision_rng = np.random.default_rng(getattr(self, "seed", None))
        self._remaining = np.zeros(0, dtype=np.int64)
        self._repeated = np.zeros(0, dtype=np.int64)
        self._began_random = np.zeros(0, dtype=bool)
        self._began_wait = np.zeros(0, dtype=bool)
        self._decisions = self._random_decisions = self._speed_sum = 0

    def _excluded_save_params(self) -> list[str]:
        excluded: list[str] = super()._excluded_save_params()  # type: ignore[misc]
        return [*excluded, "_decision_rng", "_remaining", "_repeated", "_began_random", "_began_wait"]

    # -- model files: safe loading --------------------------------------------------------------------------------
    def save(self, path: Any, exclude: Any = None, include: Any = None) -> None:
        """Save as SB3 does, with a plain-data description of what SB3 pickles (``deep_model_files``)."""
        super().save(path, exclude=exclude, include=include)  # type: ignore[misc]
        add_deep_description(path, self)

    @classmethod
    def load(
        cls: type[SelfRepeat],
        path: Any,
        env: GymEnv | None = None,
        device: th.device | str = "auto",
        custom_objects: dict[str, Any] | None = None,
        print_system_info: bool = False,
        force_reset: bool = True,
        safe: bool = True,
        **kwargs: Any,
    ) -> SelfRepeat:
        """
        Load a model saved with ``save``. By default (``safe=True``) nothing in the file is unpickled: it is rebuilt
        from the file's plain-JSON description and its weights are read with ``torch.load(weights_only=True)``; a file
        that needs unpickling (saved by other code, with a custom policy, emotion rule, goal test or ``position``
        callable) is refused with a ``ModelFileError``. ``safe=False`` is SB3's own loader, which runs pickled code:
        only for files you trust.

        :param safe: load without unpickling (default); False for SB3's loader
        :param kwargs: attributes to change on the loaded model (as SB3's ``load``); ``tensorboard_log`` and
            ``episode_log_path`` (the emotion callback's CSV) are None unless given here, whatever the file says (a
            model file does not choose where ``learn`` writes)
        """
        if not safe:
            model = super().load(  # type: ignore[misc]
                path, env=env, device=device, custom_objects=custom_objects, print_system_info=print_system_info,
                force_reset=force_reset, **{key: value for key, value in kwargs.items() if key not in WRITE_PATHS},
            )
            return paths_from_caller(model, kwargs)
        return load_deep_safe(cls, path, env=env, device=device, force_reset=force_reset, custom_objects=custom_objects,
                              **kwargs)

    def set_random_seed(self, seed: int | None = None) -> None:
        super().set_random_seed(seed)  # type: ignore[misc]
        if seed is not None:
            self._decision_rng = np.random.default_rng(seed)

    # -- the rule (a subclass's) -------------------------------------------------------------------------------------
    def _begin_decisions(self, n_envs: int) -> None:
        """Called once per step after the warm-up, before ``_decide`` for the envs that decide (none: nothing)."""

    def _decide(self, index: int) -> tuple[bool, int]:
        """The decision of env ``index``: ``(random_direction, speed)``; draw from ``self._decision_rng``."""
        raise NotImplementedError

    def _decisions_taken(self, ends: np.ndarray | None, random_direction: np.ndarray, wait: np.ndarray) -> None:
        """
        After the step's actions are chosen: which envs' decisions end with this step (None: SB3's warm-up, where every
        step is a decision), and which envs began a decision with a random direction, and which a wait.
        """

    # -- the loop ----------------------------------------------------------------------------------------------------
    def _sample_action(self, learning_starts: int, action_noise: Any = None, n_envs: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """SB3's action (random in the warm-up, else greedy), replaced by each env's decision or its repeat."""
        epsilon = self.exploration_rate
        self.exploration_rate = 0.0  # the base's own epsilon-greedy off: the rule explores
        try:
            actions, _ = super()._sample_action(learning_starts, action_noise, n_envs)  # type: ignore[misc]
        finally:
            self.exploration_rate = epsilon
        if len(self._remaining) != n_envs:
            self._remaining = np.zeros(n_envs, dtype=np.int64)
            self._repeated = np.zeros(n_envs, dtype=np.int64)
            self._began_random = np.zeros(n_envs, dtype=bool)
            self._began_wait = np.zeros(n_envs, dtype=bool)
        remaining, began_random, began_wait = self._remaining, self._began_random, self._began_wait
        if self.num_timesteps < learning_starts:  # SB3's warm-up: every step is a random decision of its own
            remaining[:] = 0
            began_random[:] = True
            began_wait[:] = False
            self._decisions_taken(None, began_random, began_wait)
            return actions, actions
        began_random[:] = False
        began_wait[:] = False
        actions = np.array(actions, copy=True).reshape(n_envs)
        rng = self._decision_rng
        n_actions = int(self.action_space.n)  # type: ignore[attr-defined]
        start = int(self.action_space.start)  # type: ignore[attr-defined]
        self._begin_decisions(n_envs)
        for index in range(n_envs):
            if remaining[index] > 0:  # repeating: the action of the decision in progress
                remaining[index] -= 1
                actions[index] = self._repeated[index]
                continue
            random_direction, speed = self._decide(index)
            if random_direction:
                actions[index] = start + int(rng.integers(n_actions))
            if speed == 0 and self.wait_action is not None:
                actions[index] = self.wait_action
                began_wait[index] = True
            began_random[index] = random_direction
            self._decisions += 1
            self._random_decisions += random_direction
            self._speed_sum += speed if self.wait_action is not None else max(speed, 1)
            remaining[index] = max(speed, 1) - 1
            self._repeated[index] = actions[index]
        self._decisions_taken(remaining == 0, began_random, began_wait)
        return actions, actions

    def _store_transition(self, replay_buffer: Any, buffer_action: np.ndarray, new_obs: Any, reward: np.ndarray,
                          dones: np.ndarray, infos: list[dict[str, Any]]) -> None:
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)  # type: ignore[misc]
        self.end_repeats(dones)

    def end_repeats(self, dones: np.ndarray) -> None:
        """An episode's end ends the repeat of its env (after the step's transition is stored)."""
        if len(self._remaining) == len(dones):
            self._remaining[np.asarray(dones, dtype=bool)] = 0

    @property
    def decision_counts(self) -> tuple[int, int]:
        """``(random decisions, decisions)`` since the last ``dump_logs`` (which logs their share and restarts them)."""
        return self._random_decisions, self._decisions

    def dump_logs(self) -> None:
        if self._decisions:
            share = self._random_decisions / self._decisions
            self.logger.record(f"{self.LOG_PREFIX}/random_share", share)
            self.logger.record(f"{self.LOG_PREFIX}/mean_repeat", self._speed_sum / self._decisions)
            self._decisions = self._random_decisions = self._speed_sum = 0
        super().dump_logs()  # type: ignore[misc]
