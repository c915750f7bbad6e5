"""
``ModelFields``: the state SB3 keeps private on an algorithm (``BaseAlgorithm`` and its off- and on-policy loops) that
the plugin reads or drives, each field read and written here only, under SB3's name for it. The lockstep trainers
(``sb3_affect.engine``) run SB3's ``learn`` loop for several models and keep its counts in the models as SB3 keeps them;
the callbacks read the observation a run starts from and the episode window; the model files rebuild a model as SB3's
``load`` does. SB3 has no public accessor for these.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import MaybeCallback


class ModelFields:
    """
    SB3's private fields of ``model`` as properties, and SB3's private steps of ``learn``, ``save`` and ``load`` as
    methods (see the module docstring).
    """

    __slots__ = ("model",)

    def __init__(self, model: BaseAlgorithm) -> None:
        self.model = model

    # -- the loop's observation ----------------------------------------------------------------------------------------
    @property
    def last_obs(self) -> Any:
        """The observation the next step acts on (None before the env's first reset)."""
        return getattr(self.model, "_last_obs", None)

    @last_obs.setter
    def last_obs(self, value: Any) -> None:
        self.model._last_obs = value

    @property
    def last_episode_starts(self) -> Any:
        """Which envs began an episode with ``last_obs`` (the on-policy loop's)."""
        return getattr(self.model, "_last_episode_starts", None)

    @last_episode_starts.setter
    def last_episode_starts(self, value: Any) -> None:
        self.model._last_episode_starts = value

    @property
    def last_lstm_states(self) -> Any:
        """RecurrentPPO's LSTM states the next rollout begins with (None for another algorithm)."""
        return getattr(self.model, "_last_lstm_states", None)

    @property
    def stats_window_size(self) -> int:
        """The episodes ``ep_info_buffer`` averages over: its length, as ``learn``'s set-up made it (``stats_window_size``);
        SB3's default, 100, before that."""
        buffer = getattr(self.model, "ep_info_buffer", None)
        return int(buffer.maxlen) if buffer is not None and buffer.maxlen is not None else 100

    # -- the loop's counts ---------------------------------------------------------------------------------------------
    @property
    def n_calls(self) -> int:
        """The off-policy loop's ``_on_step`` calls (the target network's clock)."""
        return self.model._n_calls  # type: ignore[attr-defined]

    @n_calls.setter
    def n_calls(self, value: int) -> None:
        self.model._n_calls = value  # type: ignore[attr-defined]

    @property
    def n_updates(self) -> int:
        """The gradient steps (off-policy) or epochs (on-policy) taken, logged as ``train/n_updates``."""
        return self.model._n_updates

    @n_updates.setter
    def n_updates(self, value: int) -> None:
        self.model._n_updates = value

    @property
    def progress(self) -> float:
        """``_current_progress_remaining``: 1 at the start of ``learn``, 0 at its end (the schedules' argument)."""
        return self.model._current_progress_remaining

    @progress.setter
    def progress(self, value: float) -> None:
        self.model._current_progress_remaining = value

    @property
    def episode_num(self) -> int:
        """The episodes ended since ``learn`` began (the off-policy loop's ``log_interval`` counts them)."""
        return self.model._episode_num

    @episode_num.setter
    def episode_num(self, value: int) -> None:
        self.model._episode_num = value

    # -- SB3's steps of learn ------------------------------------------------------------------------------------------
    def setup_learn(self, total_timesteps: int, callback: MaybeCallback, tb_log_name: str) -> tuple[int, BaseCallback]:
        """``learn``'s set-up (``reset_num_timesteps=True``, no progress bar): the total steps and the callback."""
        return self.model._setup_learn(total_timesteps, callback, True, tb_log_name, False)

    def update_progress(self, num_timesteps: int, total_timesteps: int) -> None:
        """``progress`` for ``num_timesteps`` of ``total_timesteps``, as SB3 computes it."""
        self.model._update_current_progress_remaining(num_timesteps, total_timesteps)

    def update_info_buffer(self, infos: list[dict[str, Any]], dones: np.ndarray) -> None:
        """The Monitor's episode infos into ``ep_info_buffer`` (and the successes), as the loop does after a step."""
        self.model._update_info_buffer(infos, dones)

    def sample_action(self, learning_starts: int, n_envs: int) -> tuple[np.ndarray, np.ndarray]:
        """The off-policy loop's actions of the next step: ``(actions, buffer_actions)``."""
        return self.model._sample_action(learning_starts, None, n_envs)  # type: ignore[attr-defined]

    def store_transition(self, buffer_actions: np.ndarray, new_obs: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
                         infos: list[dict[str, Any]]) -> None:
        """The off-policy loop's storage of a step into the model's replay buffer (it moves ``last_obs`` on)."""
        self.model._store_transition(self.model.replay_buffer, buffer_actions,  # type: ignore[attr-defined]
                                     new_obs, rewards, dones, infos)

    # -- SB3's steps of save and load ----------------------------------------------------------------------------------
    def torch_save_params(self) -> tuple[list[str], list[str]]:
        """The names of the state dicts and of the other tensors SB3 saves as ``.pth`` members."""
        return self.model._get_torch_save_params()

    def setup_model(self) -> None:
        """Build the policy, buffers and schedules from the model's settings (the constructor's last step)."""
        self.model._setup_model()


def policy_actions(policy: BasePolicy, observations: th.Tensor) -> th.Tensor:
    """The policy's deterministic actions of a batch of observations already a tensor (``predict`` without numpy)."""
    return policy._predict(observations, deterministic=True)
