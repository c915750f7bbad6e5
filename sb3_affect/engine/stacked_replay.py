"""
The replay buffers of S seeds in one set of arrays, ``(S, rows, E, ...)``, each seed's SB3 ``ReplayBuffer`` a view of
its slice while training, so a step's transitions of all seeds are stored by one write per array and a gradient step's
batches of all seeds are gathered by one read per array.

Each seed's slice has the buffer's own ``buffer_size // n_envs`` rows, in one anonymous memory map whose pages the
system provides only as they are first written: a run touches the rows training reaches (the VecEnv steps of
``total_timesteps`` plus one rollout), and ``release`` hands each model its slice, a buffer of its full size holding its
transitions, without copying anything. Where the system refuses to map that much (the rows no run reaches counted too),
the slices hold only the rows training can reach (a buffer that never wraps samples from ``[0, pos)`` whatever its size,
so SB3's sampling is unchanged) and ``release`` copies each seed's into its model's own arrays, freeing its slice
(their pages, the process's own anonymous memory) as it copies it, so that the process never holds much more than the
stacked arrays while it gives them back; a seed that stops early is copied out so (the others store on).
"""

from __future__ import annotations

import mmap
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import DQN
from stable_baselines3.common.preprocessing import get_action_dim

#: the arrays of SB3's ``ReplayBuffer`` (``optimize_memory_usage=False``), in ``ReplayBufferSamples``' order of use
ARRAYS = ("observations", "actions", "next_observations", "dones", "rewards", "timeouts")


#: SB3's ``ReplayBuffer`` arrays of one float32 per row and env: rewards, dones, timeouts
_FLOAT_ARRAYS = 3


def replay_bytes(observation_space: spaces.Space, action_space: spaces.Space, n_envs: int, rows: int) -> int:
    """The bytes of ``rows`` rows of SB3's ``ReplayBuffer`` (``optimize_memory_usage=False``) on ``n_envs`` envs."""
    observation = int(np.prod(observation_space.shape or (1,))) * np.dtype(observation_space.dtype).itemsize
    action_dtype = np.dtype(np.float32 if action_space.dtype == np.float64 else action_space.dtype)
    action = get_action_dim(action_space) * action_dtype.itemsize
    return rows * n_envs * (2 * observation + action + 4 * _FLOAT_ARRAYS)


def available_memory() -> int | None:
    """The bytes of memory the kernel says are available to new allocations (``MemAvailable``), None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


class _Pages:
    """An anonymous memory map holding arrays, whose pages can be given back to the system a range at a time."""

    def __init__(self, nbytes: int) -> None:
        # private: a shared anonymous map keeps a page ``free`` gives back (it is the system's shared memory's)
        self.map = mmap.mmap(-1, max(nbytes, 1), flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
        self.used = 0

    def array(self, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        """A zeroed array in the map, aligned to a page."""
        nbytes = int(np.prod(shape)) * dtype.itemsize
        array = np.frombuffer(self.map, dtype=dtype, count=int(np.prod(shape)), offset=self.used).reshape(shape)
        self.used += -(-nbytes // mmap.PAGESIZE) * mmap.PAGESIZE
        return array

    def free(self, array: np.ndarray) -> None:
        """Give back the whole pages of a contiguous array of the map (they read as zeros after)."""
        start = array.__array_interface__["data"][0] - np.frombuffer(self.map, dtype=np.uint8).__array_interface__["data"][0]
        first = -(-start // mmap.PAGESIZE) * mmap.PAGESIZE
        last = (start + array.nbytes) // mmap.PAGESIZE * mmap.PAGESIZE
        if last > first and hasattr(self.map, "madvise"):
            self.map.madvise(mmap.MADV_DONTNEED, first, last - first)


class StackedReplay:
    """
    The replay buffers of ``models`` stacked (see the module docstring); ``pos`` and ``full`` are shared (the seeds step
    in lockstep).

    :param models: the models, one per seed, whose buffers become views of the stacked arrays, of the rows of the
        models' ``buffer_size`` (``max(buffer_size // n_envs, 1)``, as SB3's ``ReplayBuffer``), whatever the rows their
        buffers were built with
    :param rows: the rows training can reach (the slices' rows where the buffers' own size cannot be mapped)
    """

    def __init__(self, models: Sequence[DQN], rows: int) -> None:
        self.models = list(models)
        first: Any = self.models[0].replay_buffer
        self.n_envs = first.n_envs
        self.size = max(self.models[0].buffer_size // self.n_envs, 1)
        try:
            self.rows, self.pages = self.size, self._map(self.size)
        except (OSError, OverflowError):  # more than the system maps: the rows training reaches
            self.rows = min(rows, self.size)
            self.pages = self._map(self.rows)
        self.arrays = {name: self.pages.array((len(self.models), self.rows, *getattr(first, name).shape[1:]),
                                              getattr(first, name).dtype) for name in ARRAYS}
        self.released: set[int] = set()
        for index, model in enumerate(self.models):
            buffer: Any = model.replay_buffer
            for name, array in self.arrays.items():
                setattr(buffer, name, array[index])
            buffer.buffer_size = self.rows
        self.handle_timeout_termination = first.handle_timeout_termination
        self.pos, self.full = first.pos, first.full

    def _map(self, rows: int) -> _Pages:
        """The memory map of the stacked arrays at ``rows`` rows per seed."""
        first: Any = self.models[0].replay_buffer
        arrays = [getattr(first, name) for name in ARRAYS]
        size = sum(-(-len(self.models) * rows * int(np.prod(a.shape[1:])) * a.dtype.itemsize // mmap.PAGESIZE)
                   for a in arrays)
        return _Pages(size * mmap.PAGESIZE)

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

    def follow(self, index: int = 0) -> None:
        """Take ``pos`` and ``full`` from model ``index``'s buffer (when each model stored its own transitions)."""
        buffer: Any = self.models[index].replay_buffer
        self.pos, self.full = buffer.pos, buffer.full

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

    def release_one(self, index: int) -> None:
        """
        Give seed ``index`` its buffer's own arrays back now, holding its transitions so far, and free its slice of the
        stacked arrays (a seed that stops early; the others store on).
        """
        buffer: Any = self.models[index].replay_buffer
        for name, array in self.arrays.items():
            own = np.zeros((self.size, *array.shape[2:]), dtype=array.dtype)  # SB3's ``ReplayBuffer`` arrays
            own[: self.rows] = array[index]
            setattr(buffer, name, own)
            self.pages.free(array[index])
        buffer.buffer_size = self.size
        buffer.pos, buffer.full = self.pos, self.full
        self.released.add(index)

    def release(self) -> None:
        """
        Give each model its buffer of ``buffer_size // n_envs`` rows holding its transitions: its slice of the stacked
        arrays, theirs from now on, or (where the slices are shorter) its own arrays, each seed's slice freed as it is
        copied; then the trainer holds no stacked arrays.
        """
        for index in range(len(self.models)):
            if index in self.released:
                continue
            if self.rows < self.size:
                self.release_one(index)
                continue
            buffer: Any = self.models[index].replay_buffer
            buffer.pos, buffer.full = self.pos, self.full
        self.arrays = {}
