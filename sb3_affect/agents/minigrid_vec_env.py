"""
``minigrid_vec_env``: MiniGrid's Empty, FourRooms and DoorKey tasks as an SB3 ``VecEnv`` on the compiled worlds
(``sb3_affect.kernel.minigrid_world``), a drop-in for
``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)``.

For the same seed and the same actions it gives what that DummyVecEnv gives, step for step: the layouts (env ``i``
seeded with ``seed + i`` at the first reset, later resets unseeded, as ``VecEnv.seed`` and ``DummyVecEnv.reset`` do),
the observations (``FlatObsWrapper``'s uint8 vector of 2,835: the 7 x 7 x 3 view, then the mission's one-hot
encoding), the rewards (float32), the dones, the auto-reset and the infos: ``TimeLimit.truncated`` at every step,
``terminal_observation`` and the ``Monitor``'s ``episode`` (``r``, ``l``, ``t``) where an episode ended. The action
space (env 0's) is seeded with ``seed`` as ``make_vec_env`` seeds it. Farama's ``minigrid`` is not needed to run it.

``obs="image"`` gives the first 147 entries of that vector, the view without the mission's one-hot encoding (2,688
entries constant on these tasks, 19 times the view's size: a network's first layer on them costs 19 times more for
nothing).

``get_attr`` gives each env's ``agent_pos``, ``agent_dir``, ``width``, ``height``, ``max_steps``, ``step_count``,
``mission``, ``see_through_walls``, ``agent_view_size`` and ``render_mode`` (None), so ``position="minigrid"`` finds
the agent's cell; ``env_method`` runs the ``Monitor``'s ``get_episode_rewards``, ``get_episode_lengths``,
``get_episode_times`` and ``get_total_steps``; ``env_is_wrapped`` is True for the wrappers that ``make_vec_env`` puts
around each env (``Monitor``, ``FlatObsWrapper`` with ``obs="flat"``, Gymnasium's ``OrderEnforcing`` and
``PassiveEnvChecker``). Setting attributes and rendering are refused with a one-line error.

``step_arrays(actions)`` is the step without the info dicts, for a trainer that steps many envs itself;
``MiniGridBatch`` steps several such VecEnvs (e.g. one per seed) by one kernel call.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from sb3_affect.kernel.minigrid_view import VIEW, VIEW_SIZE
from sb3_affect.kernel.minigrid_world import (
    AGENT_DIR,
    AGENT_X,
    AGENT_Y,
    MINIGRID_ACTIONS,
    MINIGRID_TASKS,
    STEP_COUNT,
    MiniGridTask,
    Worlds,
    new_worlds,
    reset_worlds,
    step_worlds,
)
from sb3_affect.kernel.pcg64 import seeded_state

#: The observations ``obs=`` chooses: ``FlatObsWrapper``'s vector, or its first 147 entries (the 7 x 7 x 3 view).
OBSERVATIONS = ("flat", "image")
#: ``FlatObsWrapper``'s mission encoding: 96 characters of 28 codes (a-z, space, comma).
_MISSION_CHARS, _CHAR_CODES = 96, 28


def mission_one_hot(mission: str) -> np.ndarray:
    """``FlatObsWrapper``'s encoding of a mission string (96 x 28 uint8, flattened)."""
    array = np.zeros((_MISSION_CHARS, _CHAR_CODES), dtype=np.uint8)
    for index, char in enumerate(mission.lower()):
        array[index, 26 if char == " " else 27 if char == "," else ord(char) - ord("a")] = 1
    return array.reshape(-1)


#: ``step_worlds``'s arrays after the actions: the worlds (grid, agent, carry, rng), then the step's buffers
#: (observations, rewards, terminated, truncated, dones, episode lengths, terminal observations)
StateArrays = tuple[np.ndarray, ...]


def _state_arrays(task: MiniGridTask, obs: str, n: int) -> StateArrays:
    """Zeroed ``StateArrays`` of ``n`` worlds (the mission's encoding written where ``obs="flat"``)."""
    size = VIEW_SIZE + (_MISSION_CHARS * _CHAR_CODES if obs == "flat" else 0)
    observations = np.zeros((n, size), dtype=np.uint8)
    if obs == "flat":
        observations[:, VIEW_SIZE:] = mission_one_hot(task.mission)
    flags = tuple(np.zeros(n, dtype=bool) for _ in range(3))
    return (*new_worlds(task, n), observations, np.zeros(n, dtype=np.float32), *flags, np.zeros(n, dtype=np.int64),
            observations.copy())


class MiniGridVecEnv(VecEnv):
    """The compiled MiniGrid VecEnv (see the module's docstring); build it with ``minigrid_vec_env``."""

    def __init__(self, env_id: str, n_envs: int = 1, seed: int | None = None, obs: str = "flat") -> None:
        task = MINIGRID_TASKS.get(env_id) if isinstance(env_id, str) else None
        if task is None:
            raise ValueError(f"minigrid_vec_env: env_id={env_id!r} is not implemented; supported: {', '.join(MINIGRID_TASKS)}")
        if obs not in OBSERVATIONS:
            choices = ", ".join(map(repr, OBSERVATIONS))
            raise ValueError(f"minigrid_vec_env: obs={obs!r} is not supported; choose one of {choices}")
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"minigrid_vec_env: n_envs={n_envs!r} must be a positive integer")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"minigrid_vec_env: seed={seed!r} must be None or a non-negative integer")
        n = int(n_envs)
        self.env_id, self.task, self.obs = env_id, task, obs
        self._bind(_state_arrays(task, obs, n))
        self._actions: Any = None
        self._started = False
        # the Monitor's records, per env
        self._t_start = time.time()
        self._episode_rewards: list[list[float]] = [[] for _ in range(n)]
        self._episode_lengths: list[list[int]] = [[] for _ in range(n)]
        self._episode_times: list[list[float]] = [[] for _ in range(n)]
        self._abandoned = np.zeros(n, dtype=np.int64)  # the steps of episodes cut short by reset()
        self._task_args = (task.layout, task.see_through_walls, task.max_steps)  # step_worlds's before the actions
        observation_space = spaces.Box(low=0, high=255, shape=self._obs.shape[1:], dtype=np.uint8)
        super().__init__(n, observation_space, spaces.Discrete(MINIGRID_ACTIONS))
        if seed is not None:
            self.action_space.seed(int(seed))
        self.seed(None if seed is None else int(seed))

    def _bind(self, arrays: StateArrays) -> None:
        """Hold ``arrays`` as the worlds' state and the step's buffers (its own, or its rows of a ``MiniGridBatch``'s)."""
        self._arrays = arrays
        self.worlds = Worlds(*arrays[:4])
        self._obs, self._rewards, self._terminated, self._truncated, self._dones, self._lengths = arrays[4:10]
        #: Each env's last observation of the episode that ended at the last step (rows where ``dones``).
        self.terminal_observations = arrays[10]
        self._getters = self._attributes()

    # ---- stepping --------------------------------------------------------------------------------------------------

    def reset(self) -> VecEnvObs:
        for index, seed in enumerate(self._seeds):  # set at the first reset (__init__ calls seed), then None
            if seed is not None:
                self.worlds.rng[index] = seeded_state(seed)
        if self._started:
            self._abandoned += self.worlds.agent[:, STEP_COUNT]
        task = self.task
        reset_worlds(task.layout, task.see_through_walls, np.ones(self.num_envs, dtype=bool), *self.worlds, self._obs)
        self._started = True
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return self._obs.copy()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, _, _ = self.step_arrays(self._actions)
        return obs.copy(), rewards.copy(), self._dones.copy(), self.step_infos()

    def step_infos(self) -> list[dict[str, Any]]:
        """The infos of the last step, as ``step`` gives them."""
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": False} for _ in range(self.num_envs)]
        if self._dones.any():
            for index in np.flatnonzero(self._dones).tolist():
                infos[index] = self._ended_info(index)
        return infos

    def _ended_info(self, index: int) -> dict[str, Any]:
        """The info of env ``index``, whose episode ended at the last step."""
        return {
            "episode": {"r": round(self._episode_rewards[index][-1], 6), "l": self._episode_lengths[index][-1],
                        "t": round(self._episode_times[index][-1], 6)},
            "TimeLimit.truncated": bool(self._truncated[index] and not self._terminated[index]),
            "terminal_observation": self.terminal_observations[index].copy(),
        }

    def step_arrays(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """
        One step of every env with ``actions`` (one integer per env; an int64 array of ``num_envs`` is taken as it
        is), without building info dicts: returns ``(observations, rewards, terminated, truncated)``, arrays of
        ``num_envs`` rows (uint8, float32, bool, bool). An env whose episode ended has already been reset: its row of
        ``observations`` is the next episode's first observation and its last one is in ``self.terminal_observations``.
        The arrays are this env's own buffers, overwritten by the next step: copy what you keep. The ``Monitor``'s
        records (``env_method``) are kept.
        """
        if not self._started:
            raise RuntimeError("minigrid_vec_env: call reset() before step()")
        if not (type(actions) is np.ndarray and actions.dtype == np.int64 and actions.shape == self._dones.shape):
            actions = self._check_actions(actions)
        ended = step_worlds(*self._task_args, actions, *self._arrays)
        if ended < 0:
            raise _bad_action(actions[-1 - ended].item(), -1 - ended)
        if ended:
            self._record_episodes(np.flatnonzero(self._dones).tolist())
        return self._obs, self._rewards, self._terminated, self._truncated

    def _record_episodes(self, indices: list[int]) -> None:
        """The ``Monitor``'s records of the episodes of envs ``indices``, which ended at the last step."""
        now = time.time() - self._t_start
        for index in indices:
            length = int(self._lengths[index])
            # the Monitor's sum of the episode's rewards: 0 until the goal's 1 - 0.9 * step_count / max_steps
            reward = 1 - 0.9 * (length / self.task.max_steps) if self._terminated[index] else 0.0
            self._episode_rewards[index].append(reward)
            self._episode_lengths[index].append(length)
            self._episode_times[index].append(now)

    def _check_actions(self, actions: Any) -> np.ndarray:
        array = np.asarray(actions)
        if array.size != self.num_envs:
            raise ValueError(f"minigrid_vec_env: {array.size} actions for {self.num_envs} envs")
        flat = array.reshape(self.num_envs)
        ints = flat.astype(np.int64)
        bad = np.flatnonzero(ints != flat)
        if bad.size:
            raise _bad_action(flat[bad[0]].item(), int(bad[0]))
        return ints

    def close(self) -> None:
        """Nothing to release (the worlds are arrays)."""

    # ---- the envs' attributes and methods --------------------------------------------------------------------------

    def _attributes(self) -> dict[str, Callable[[int], Any]]:
        agent, task = self.worlds.agent, self.task
        return {
            "agent_pos": lambda i: (int(agent[i, AGENT_X]), int(agent[i, AGENT_Y])),
            "agent_dir": lambda i: int(agent[i, AGENT_DIR]),
            "step_count": lambda i: int(agent[i, STEP_COUNT]),
            "width": lambda i: task.size,
            "height": lambda i: task.size,
            "max_steps": lambda i: task.max_steps,
            "mission": lambda i: task.mission,
            "see_through_walls": lambda i: task.see_through_walls,
            "agent_view_size": lambda i: VIEW,
            "render_mode": lambda i: None,
        }

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        getter = self._getters.get(attr_name)
        if getter is None:
            raise AttributeError(
                f"minigrid_vec_env: its envs have no attribute {attr_name!r}; it gives {', '.join(sorted(self._getters))}"
            )
        return [getter(index) for index in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise AttributeError(f"minigrid_vec_env: its envs' attributes can not be set (set_attr({attr_name!r}))")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        methods: dict[str, Callable[[int], Any]] = {
            "get_episode_rewards": lambda i: list(self._episode_rewards[i]),
            "get_episode_lengths": lambda i: list(self._episode_lengths[i]),
            "get_episode_times": lambda i: list(self._episode_times[i]),
            "get_total_steps": self._total_steps,
        }
        if method_name not in methods or method_args or method_kwargs:
            raise AttributeError(
                f"minigrid_vec_env: env_method({method_name!r}) is not supported; it runs {', '.join(methods)} "
                "without arguments"
            )
        return [methods[method_name](index) for index in self._get_indices(indices)]

    def _total_steps(self, index: int) -> int:
        """The ``Monitor``'s ``total_steps``: every step of the env, of episodes ended, cut short and under way."""
        return int(self._abandoned[index] + sum(self._episode_lengths[index]) + self.worlds.agent[index, STEP_COUNT])

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        wrapped = issubclass(Monitor, wrapper_class) or wrapper_class in _gymnasium_wrappers()
        if self.obs == "flat":
            wrapped = wrapped or (wrapper_class.__module__, wrapper_class.__name__) == ("minigrid.wrappers", "FlatObsWrapper")
        return [bool(wrapped) for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        raise NotImplementedError("minigrid_vec_env renders no images; make_vec_env(env_id, ...) on Farama's env does")

    def render(self, mode: str | None = None) -> np.ndarray | None:
        raise NotImplementedError("minigrid_vec_env renders no images; make_vec_env(env_id, ...) on Farama's env does")


class MiniGridBatch:
    """
    ``MiniGridVecEnv``s of one task and observation stepped by one kernel call, for a trainer of many seeds: their
    worlds and step buffers become consecutive rows of shared arrays, each env keeping views of its own rows, so each
    stays a VecEnv of its own (its ``get_attr``, ``env_method`` and ``Monitor`` records see every batched step).

    :param envs: the VecEnvs, each reset before the first ``step``
    """

    def __init__(self, envs: Sequence[MiniGridVecEnv]) -> None:
        self.envs = list(envs)
        first = self.envs[0]
        for env in self.envs:
            if not isinstance(env, MiniGridVecEnv) or (env.env_id, env.obs) != (first.env_id, first.obs):
                raise ValueError(f"MiniGridBatch: every env must be a minigrid_vec_env of {first.env_id} with "
                                 f"obs={first.obs!r}, got {env!r}")
        counts = [env.num_envs for env in self.envs]
        self.offsets = np.cumsum([0, *counts]).tolist()
        self._owner = np.repeat(np.arange(len(counts)), counts)
        self.arrays = _state_arrays(first.task, first.obs, self.offsets[-1])
        for env, start, stop in zip(self.envs, self.offsets, self.offsets[1:]):
            for joined, own in zip(self.arrays, env._arrays):
                joined[start:stop] = own
            env._bind(tuple(array[start:stop] for array in self.arrays))
        self._task_args = first._task_args

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        One step of every env, as each env's ``step_arrays``: ``actions`` has one int64 per env (the envs' rows in
        order); returns the observations, rewards and dones of all envs (this batch's buffers: copy what you keep).
        """
        ended = step_worlds(*self._task_args, actions, *self.arrays)
        if ended < 0:
            raise _bad_action(actions[-1 - ended].item(), -1 - ended)
        dones = self.arrays[8]
        if ended:
            for row in np.flatnonzero(dones).tolist():
                owner = int(self._owner[row])
                self.envs[owner]._record_episodes([row - self.offsets[owner]])
        return self.arrays[4], self.arrays[5], dones

    def infos(self) -> list[list[dict[str, Any]]]:
        """Each env's infos of the last step, as its ``step`` gives them."""
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": False} for _ in range(self.offsets[-1])]
        for row in np.flatnonzero(self.arrays[8]).tolist():
            owner = int(self._owner[row])
            infos[row] = self.envs[owner]._ended_info(row - self.offsets[owner])
        return [infos[start:stop] for start, stop in zip(self.offsets, self.offsets[1:])]


def _bad_action(value: Any, index: int) -> ValueError:
    return ValueError(f"minigrid_vec_env: action {value!r} of env {index} is not a MiniGrid action (0..6)")


def _gymnasium_wrappers() -> tuple[type, ...]:
    """The wrappers ``gym.make`` puts around a MiniGrid env."""
    from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker

    return (OrderEnforcing, PassiveEnvChecker)


def minigrid_vec_env(env_id: str, n_envs: int = 1, seed: int | None = None, obs: str = "flat") -> MiniGridVecEnv:
    """
    MiniGrid ``env_id`` (Empty-NxN and Empty-Random-NxN, FourRooms, DoorKey-NxN: ``MINIGRID_TASKS``) compiled, as an SB3
    ``VecEnv`` of ``n_envs`` envs that gives, for the same seed and actions, what
    ``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper)`` gives; ``obs="image"``: only the first
    147 entries of each observation (the 7 x 7 x 3 view). See ``sb3_affect.agents.minigrid_vec_env``.
    """
    return MiniGridVecEnv(env_id, n_envs, seed=seed, obs=obs)
