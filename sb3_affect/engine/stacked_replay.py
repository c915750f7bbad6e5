"""
The replay buffers of S seeds in one set of arrays, ``(S, rows, E, ...)``, each seed's SB3 ``ReplayBuffer`` a view of
its slice while training, so a step's transitions of all seeds are stored by one write per array and a gradient step's
batches of all seeds are gathered by one read per array.

``rows`` is the buffer's own ``buffer_size // n_envs`` when training fills it, else the rows training can reach
(the VecEnv steps of ``total_timesteps`` plus one rollout): a buffer that never wraps samples from ``[0, pos)`` whatever
its size, so SB3's sampling is unchanged, and a short run of many seeds does not reserve a million rows per seed.
``release`` gives each model back a buffer of its full size holding its transitions.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
from stable_baselines3 import DQN

#: the arrays of SB3's ``ReplayBuffer`` (``optimize_memory_usage=False``), in ``ReplayBufferSamples``' order of use
ARRAYS = ("observations", "actions", "next_observations", "dones", "rewards", "timeouts")


class StackedReplay:
    """
    The replay buffers of ``models`` stacked (see the module docstring); ``pos`` and ``full`` are shared (the seeds step
    in lockstep).

    :param models: the models, one per seed, whose buffers become views of the stacked arrays until ``release``
    :param rows: the rows training can reach (capped at the buffers' own size)
    """

    def __init__(self, models: Sequence[DQN], rows: int) -> None:
        self.models = list(models)
        first: Any = self.models[0].replay_buffer
        self.size = first.buffer_size
        self.rows = min(rows, self.size)
        self.n_envs = first.n_envs
        self.arrays = {name: np.zeros((len(self.models), self.rows, *getattr(first, name).shape[1:]),
                                      dtype=getattr(first, name).dtype) for name in ARRAYS}
        self.own: list[dict[str, np.ndarray]] = []  # each buffer's own arrays, given back by ``release``
        for index, model in enumerate(self.models):
            buffer: Any = model.replay_buffer
            self.own.append({name: getattr(buffer, name) for name in ARRAYS})
            for name, array in self.arrays.items():
                setattr(buffer, name, array[index])
            buffer.buffer_size = self.rows
        self.handle_timeout_termination = first.handle_timeout_termination
        self.pos, self.full = first.pos, first.full

    def add(self, obs: np.ndarray, next_obs: np.ndarray, actions: np.ndarray, rewards: np.ndarray, dones: np.ndarray,
            timeouts: np.ndarray) -> None:
        """Every seed's ``ReplayBuffer.add`` at once (arrays ``(S, E, ...)``)."""
        arrays, pos = self.arrays, self.pos
        arrays["observations"][:, pos] = obs
        arrays["next_observations"][:, pos] = next_obs
        arrays["actions"][:, pos] = actions.reshape(arrays["actions"].shape[0], self.n_envs, -1)
        arrays["rewards"][:, pos] = rewards
        arrays["dones"][:, pos] = dones
        if self.handle_timeout_termination:
            arrays["timeouts"][:, pos] = timeouts
        self.pos += 1
        if self.pos == self.rows:
            self.full, self.pos = True, 0

    def follow(self) -> None:
        """Take ``pos`` and ``full`` from the models' buffers (when each model stored its own transitions)."""
        first: Any = self.models[0].replay_buffer
        self.pos, self.full = first.pos, first.full

    def sample(self, rngs: Sequence[np.random.RandomState], batch_size: int) -> tuple[th.Tensor, ...]:
        """
        Each seed's ``ReplayBuffer.sample(batch_size)``, its indices from its own stream in SB3's order (the rows, then
        the envs), as tensors ``(S, batch_size, ...)`` in ``ReplayBufferSamples``' order.
        """
        upper_bound = self.rows if self.full else self.pos
        batch_inds = np.empty((len(rngs), batch_size), dtype=np.int64)
        env_indices = np.empty((len(rngs), batch_size), dtype=np.int64)
        for index, rng in enumerate(rngs):
            batch_inds[index] = rng.randint(0, upper_bound, size=batch_size)
            env_indices[index] = rng.randint(0, high=self.n_envs, size=(batch_size,))
        # each array's rows (seed, row, env) flattened: one ``take`` per array
        flat = (np.arange(len(rngs))[:, None] * self.rows + batch_inds) * self.n_envs + env_indices
        arrays = self.arrays

        def gather(name: str) -> np.ndarray:
            array = arrays[name]
            return array.reshape(-1, *array.shape[3:]).take(flat, axis=0)

        dones = (gather("dones") * (1 - gather("timeouts")))[..., None]
        parts = (gather("observations"), gather("actions"), gather("next_observations"), dones, gather("rewards")[..., None])
        return tuple(th.as_tensor(part) for part in parts)

    def release(self) -> None:
        """Give each model its buffer's own arrays back (``buffer_size // n_envs`` rows), holding its transitions."""
        for index, (model, own) in enumerate(zip(self.models, self.own)):
            buffer: Any = model.replay_buffer
            for name, array in self.arrays.items():
                own[name][: self.rows] = array[index]
                setattr(buffer, name, own[name])
            buffer.buffer_size = self.size
            buffer.pos, buffer.full = self.pos, self.full
