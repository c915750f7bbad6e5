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

``obs="image"`` gives ``ImgObsWrapper``'s observation instead, the 7 x 7 x 3 view as a uint8 image (for a
``CnnPolicy``); ``obs="view"`` the same view flattened, the first 147 entries of ``FlatObsWrapper``'s vector, without
the mission's one-hot encoding (2,688 entries constant on these tasks, 19 times the view's size: a network's first
layer on them costs 19 times more for nothing). ``env_kwargs`` are the keyword arguments Farama's env takes
(``make_vec_env``'s ``env_kwargs``): ``max_steps``, ``agent_view_size``, ``see_through_walls`` (DoorKey, FourRooms),
``size`` (Empty, DoorKey), ``agent_start_pos`` (Empty: ``(1, 1)`` or None, the random start), the rendering's
``render_mode`` (``"rgb_array"``, as ``make_vec_env`` sets it, or None), ``highlight``, ``tile_size``, ``agent_pov``
and ``screen_size``; anything else is refused in one line.

``get_attr`` gives each env's ``agent_pos``, ``agent_dir``, ``width``, ``height``, ``max_steps``, ``step_count``,
``mission``, ``see_through_walls``, ``agent_view_size``, ``render_mode``, ``spec`` and ``metadata``, so
``position="minigrid"`` finds the agent's cell; ``env_method`` runs the ``Monitor``'s ``get_episode_rewards``,
``get_episode_lengths``, ``get_episode_times`` and ``get_total_steps``; ``env_is_wrapped`` is True for the wrappers
that ``make_vec_env`` puts around each env (``Monitor``, ``FlatObsWrapper`` with ``obs="flat"``, ``ImgObsWrapper``
with ``obs="image"``, Gymnasium's ``OrderEnforcing`` and ``PassiveEnvChecker``). ``render()`` and ``get_images()``
give Farama's frames of the same worlds (drawn by Farama's ``minigrid``, which rendering needs), so SB3's
``VecVideoRecorder`` records it. Setting attributes is refused with a one-line error. The VecEnv pickles (for
``SubprocVecEnv``-style workers, Ray): a copy continues as the original would.

``step_arrays(actions)`` is the step without the info dicts, for a trainer that steps many envs itself;
``MiniGridBatch`` steps several such VecEnvs (e.g. one per seed) by one kernel call, through each one's public
``kernel_args``, ``state_arrays`` and ``bind`` (its rows of the batch's arrays), ``require_started``,
``record_episodes`` and ``ended_info``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from sb3_affect.kernel.jit import announce_compile
from sb3_affect.kernel.minigrid_view import VIEW
from sb3_affect.kernel.minigrid_world import (
    AGENT_DIR,
    AGENT_X,
    AGENT_Y,
    DOOR_KEY,
    EMPTY_FIXED,
    EMPTY_RANDOM,
    FOUR_ROOMS,
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

#: The observations ``obs=`` chooses: ``FlatObsWrapper``'s vector, ``ImgObsWrapper``'s 7 x 7 x 3 image, or that image
#: flattened (the vector's first 147 entries).
OBSERVATIONS = ("flat", "image", "view")
#: The CPU time of compiling the MiniGrid kernels on a cold cache (measured on the 2-core machine, idle: 5.3 s).
COMPILE_CPU_SECONDS = 10
#: Farama's env classes of the layouts (``spec.entry_point``).
_ENTRY_POINTS = {EMPTY_FIXED: "minigrid.envs:EmptyEnv", EMPTY_RANDOM: "minigrid.envs:EmptyEnv",
                 FOUR_ROOMS: "minigrid.envs:FourRoomsEnv", DOOR_KEY: "minigrid.envs:DoorKeyEnv"}
#: ``MiniGridEnv.metadata``.
METADATA: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 10}
#: The env keyword arguments of every task (``MiniGridEnv.__init__``'s), and those of some layouts only.
_COMMON_KWARGS = ("max_steps", "agent_view_size", "render_mode", "screen_size", "highlight", "tile_size", "agent_pov")
_LAYOUT_KWARGS = {EMPTY_FIXED: ("size", "agent_start_pos", "agent_start_dir"),
                  EMPTY_RANDOM: ("size", "agent_start_pos", "agent_start_dir"),
                  FOUR_ROOMS: ("see_through_walls", "agent_pos", "goal_pos"), DOOR_KEY: ("size", "see_through_walls")}
#: ``FlatObsWrapper``'s mission encoding: 96 characters of 28 codes (a-z, space, comma).
_MISSION_CHARS, _CHAR_CODES = 96, 28


def mission_one_hot(mission: str) -> np.ndarray:
    """``FlatObsWrapper``'s encoding of a mission string (96 x 28 uint8, flattened)."""
    array = np.zeros((_MISSION_CHARS, _CHAR_CODES), dtype=np.uint8)
    for index, char in enumerate(mission.lower()):
        array[index, 26 if char == " " else 27 if char == "," else ord(char) - ord("a")] = 1
    return array.reshape(-1)


class Rendering(NamedTuple):
    """``MiniGridEnv``'s rendering settings."""

    render_mode: str | None
    highlight: bool
    tile_size: int
    agent_pov: bool
    screen_size: int | None


def _is_int(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _configure(env_id: str, task: MiniGridTask, env_kwargs: dict[str, Any]) -> tuple[MiniGridTask, int, Rendering]:
    """
    The task, view size and rendering ``gym.make(env_id, **env_kwargs)`` builds; anything it does not compile (or Farama's
    env refuses) is refused in one line.
    """
    allowed = (*_LAYOUT_KWARGS[task.layout], *_COMMON_KWARGS)
    for key in env_kwargs:
        if key not in allowed:
            raise ValueError(f"minigrid_vec_env: env_kwargs key {key!r} is not taken by {env_id}; it takes "
                             f"{', '.join(allowed)}")
    kwargs = {"render_mode": "rgb_array", **env_kwargs}  # make_vec_env's default

    def refuse(key: str, allowed_values: str) -> ValueError:
        return ValueError(f"minigrid_vec_env: env_kwargs {key}={kwargs[key]!r} is not allowed; {allowed_values}")

    layout, size = task.layout, task.size
    if "size" in kwargs:
        least = 5 if layout == DOOR_KEY else 4
        if not _is_int(kwargs["size"]) or not least <= kwargs["size"] <= 64:
            raise refuse("size", f"an integer from {least} to 64")
        size = int(kwargs["size"])
    if "agent_start_pos" in kwargs:
        start = kwargs["agent_start_pos"]
        if start is None:
            layout = EMPTY_RANDOM
        elif isinstance(start, (tuple, list)) and len(start) == 2 and tuple(start) == (1, 1):
            layout = EMPTY_FIXED
        else:
            raise refuse("agent_start_pos", "the compiled worlds start the agent at (1, 1) or at random (None)")
    if kwargs.get("agent_start_dir", 0) != 0 or isinstance(kwargs.get("agent_start_dir"), bool):
        raise refuse("agent_start_dir", "the compiled worlds start the agent facing right (0)")
    for key in ("agent_pos", "goal_pos"):
        if kwargs.get(key) is not None:
            raise refuse(key, "the compiled worlds place them at random (None)")
    default_steps = 4 * size**2 if layout in (EMPTY_FIXED, EMPTY_RANDOM) else 10 * size**2 if layout == DOOR_KEY else 100
    max_steps = kwargs.get("max_steps", default_steps)
    if not _is_int(max_steps) or max_steps < 1:
        raise refuse("max_steps", "a positive integer")
    see_through = kwargs.get("see_through_walls", task.see_through_walls)
    if not isinstance(see_through, (bool, np.bool_)):
        raise refuse("see_through_walls", "True or False")
    view = kwargs.get("agent_view_size", VIEW)
    if not _is_int(view) or view < 3 or view % 2 == 0 or view > 31:
        raise refuse("agent_view_size", "an odd integer from 3 to 31")
    if kwargs["render_mode"] not in (None, "rgb_array"):
        raise refuse("render_mode", "'rgb_array' or None (the compiled worlds open no window; 'human' needs Farama's env)")
    for key in ("highlight", "agent_pov"):
        if not isinstance(kwargs.get(key, False), (bool, np.bool_)):
            raise refuse(key, "True or False")
    tile_size = kwargs.get("tile_size", 32)
    if not _is_int(tile_size) or not 1 <= tile_size <= 256:
        raise refuse("tile_size", "an integer from 1 to 256")
    screen_size = kwargs.get("screen_size", 640)
    if screen_size is not None and (not _is_int(screen_size) or screen_size < 1):
        raise refuse("screen_size", "a positive integer or None")
    configured = task._replace(layout=layout, size=size, max_steps=int(max_steps), see_through_walls=bool(see_through))
    rendering = Rendering(kwargs["render_mode"], bool(kwargs.get("highlight", True)), int(tile_size),
                          bool(kwargs.get("agent_pov", False)), screen_size)
    return configured, int(view), rendering


def _spec(env_id: str, task: MiniGridTask, obs: str, env_kwargs: dict[str, Any]) -> gym.envs.registration.EnvSpec:
    """The ``spec`` of ``make_vec_env``'s envs: Farama's registration of ``env_id``, its kwargs updated as
    ``make_vec_env`` updates them, and the ``Monitor`` and observation wrappers around it."""
    from gymnasium.envs.registration import EnvSpec, WrapperSpec

    if task.layout == EMPTY_RANDOM:
        registered: dict[str, Any] = {"size": task.size, "agent_start_pos": None}
    elif task.layout == FOUR_ROOMS or (task.layout == EMPTY_FIXED and task.size == 8):
        registered = {}
    else:
        registered = {"size": task.size}
    wrappers = [WrapperSpec("Monitor", "stable_baselines3.common.monitor:Monitor", None)]
    if obs != "view":
        name = "FlatObsWrapper" if obs == "flat" else "ImgObsWrapper"
        wrappers.append(WrapperSpec(name, f"minigrid.wrappers:{name}", None))
    return EnvSpec(id=env_id, entry_point=_ENTRY_POINTS[task.layout],
                   kwargs={**registered, "render_mode": "rgb_array", **env_kwargs}, additional_wrappers=tuple(wrappers))


#: ``step_worlds``'s arrays after the actions: the worlds (grid, agent, carry, rng), then the step's buffers
#: (observations, rewards, terminated, truncated, dones, episode lengths, terminal observations)
StateArrays = tuple[np.ndarray, ...]


def _state_arrays(task: MiniGridTask, obs: str, view: int, n: int) -> StateArrays:
    """Zeroed ``StateArrays`` of ``n`` worlds (the mission's encoding written where ``obs="flat"``)."""
    view_size = view * view * 3
    size = view_size + (_MISSION_CHARS * _CHAR_CODES if obs == "flat" else 0)
    observations = np.zeros((n, size), dtype=np.uint8)
    if obs == "flat":
        observations[:, view_size:] = mission_one_hot(task.mission)
    flags = tuple(np.zeros(n, dtype=bool) for _ in range(3))
    return (*new_worlds(task, n), observations, np.zeros(n, dtype=np.float32), *flags, np.zeros(n, dtype=np.int64),
            observations.copy())


class MiniGridVecEnv(VecEnv):
    """The compiled MiniGrid VecEnv (see the module's docstring); build it with ``minigrid_vec_env``."""

    def __init__(self, env_id: str, n_envs: int = 1, seed: int | None = None, obs: str = "flat",
                 env_kwargs: dict[str, Any] | None = None) -> None:
        registered = MINIGRID_TASKS.get(env_id) if isinstance(env_id, str) else None
        if registered is None:
            raise ValueError(f"minigrid_vec_env: env_id={env_id!r} is not implemented; supported: {', '.join(MINIGRID_TASKS)}")
        if obs not in OBSERVATIONS:
            choices = ", ".join(map(repr, OBSERVATIONS))
            raise ValueError(f"minigrid_vec_env: obs={obs!r} is not supported; choose one of {choices}")
        if isinstance(n_envs, bool) or not isinstance(n_envs, (int, np.integer)) or n_envs < 1:
            raise ValueError(f"minigrid_vec_env: n_envs={n_envs!r} must be a positive integer")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"minigrid_vec_env: seed={seed!r} must be None or a non-negative integer")
        if env_kwargs is not None and not isinstance(env_kwargs, dict):
            raise ValueError(f"minigrid_vec_env: env_kwargs={env_kwargs!r} must be a dict or None")
        env_kwargs = dict(env_kwargs or {})
        task, view, self.rendering = _configure(env_id, registered, env_kwargs)
        n = int(n_envs)
        self.env_id, self.task, self.obs, self.view = env_id, task, obs, view
        #: What ``gym.make(env_id, ...)`` of each env would give as its ``spec`` (``make_vec_env``'s envs' ``spec``).
        self.spec = _spec(env_id, registered, obs, env_kwargs)
        announce_compile("the MiniGrid worlds (minigrid_vec_env)", (reset_worlds, step_worlds), COMPILE_CPU_SECONDS)
        self.bind(_state_arrays(task, obs, view, n))
        self._actions: Any = None
        self._started = False
        self._closed = False
        # the Monitor's records, per env
        self._t_start = time.time()
        self._episode_rewards: list[list[float]] = [[] for _ in range(n)]
        self._episode_lengths: list[list[int]] = [[] for _ in range(n)]
        self._episode_times: list[list[float]] = [[] for _ in range(n)]
        self._abandoned = np.zeros(n, dtype=np.int64)  # the steps of episodes cut short by reset()
        #: ``step_worlds``'s arguments before the actions (the task's layout, walls, step limit and view size).
        self.kernel_args = (task.layout, task.see_through_walls, task.max_steps, view)
        shape = (view, view, 3) if obs == "image" else self._obs.shape[1:]
        observation_space = spaces.Box(low=0, high=255, shape=shape, dtype=np.uint8)
        super().__init__(n, observation_space, spaces.Discrete(MINIGRID_ACTIONS))
        self.metadata = dict(METADATA)
        if seed is not None:
            self.action_space.seed(int(seed))
        self.seed(None if seed is None else int(seed))

    @property
    def state_arrays(self) -> StateArrays:
        """The worlds' state and the step's buffers it holds (``StateArrays``: its own, or its rows of a batch's)."""
        return self._arrays

    def bind(self, arrays: StateArrays) -> None:
        """Hold ``arrays`` as the worlds' state and the step's buffers (its own, or its rows of a ``MiniGridBatch``'s)."""
        self._arrays = arrays
        self.worlds = Worlds(*arrays[:4])
        self._obs, self._rewards, self._terminated, self._truncated, self._dones, self._lengths = arrays[4:10]
        n = self._obs.shape[0]
        #: The observations as SB3 sees them (``obs="image"``: the buffer's rows as images, the same memory).
        self._seen = self._obs.reshape(n, self.view, self.view, 3) if self.obs == "image" else self._obs
        #: Each env's last observation of the episode that ended at the last step (rows where ``dones``).
        self.terminal_observations = arrays[10].reshape(self._seen.shape) if self.obs == "image" else arrays[10]
        self._getters = self._attributes()

    def __getstate__(self) -> dict[str, Any]:
        """Its state without the views and getters ``_bind`` derives (a batch's rows become the copy's own arrays)."""
        derived = ("worlds", "_obs", "_rewards", "_terminated", "_truncated", "_dones", "_lengths", "_seen",
                   "terminal_observations", "_getters")
        state = {key: value for key, value in self.__dict__.items() if key not in derived}
        state["_arrays"] = tuple(np.array(array) for array in self._arrays)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.bind(state["_arrays"])

    # ---- stepping --------------------------------------------------------------------------------------------------

    def reset(self) -> VecEnvObs:
        self._refuse_closed()
        for index, seed in enumerate(self._seeds):  # set at the first reset (__init__ calls seed), then None
            if seed is not None:
                self.worlds.rng[index] = seeded_state(seed)
        if self._started:
            self._abandoned += self.worlds.agent[:, STEP_COUNT]
        task = self.task
        reset_worlds(task.layout, task.see_through_walls, self.view, np.ones(self.num_envs, dtype=bool), *self.worlds,
                     self._obs)
        self._started = True
        self._reset_seeds()
        self._reset_options()
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return self._seen.copy()

    def _refuse_closed(self) -> None:
        if self._closed:
            raise RuntimeError("minigrid_vec_env: the VecEnv is closed (close() was called); build a new one")

    def require_started(self, refusal: str = "minigrid_vec_env: call reset() before step()") -> None:
        """Refuse a step unless the VecEnv was reset and is not closed (a closed one's line, or ``refusal``)."""
        if not self._started:
            self._refuse_closed()
            raise RuntimeError(refusal)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        self.step_arrays(self._actions)
        return self._seen.copy(), self._rewards.copy(), self._dones.copy(), self.step_infos()

    def step_infos(self) -> list[dict[str, Any]]:
        """The infos of the last step, as ``step`` gives them."""
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": False} for _ in range(self.num_envs)]
        if self._dones.any():
            for index in np.flatnonzero(self._dones).tolist():
                infos[index] = self.ended_info(index)
        return infos

    def ended_info(self, index: int) -> dict[str, Any]:
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
            self.require_started()
        if not (type(actions) is np.ndarray and actions.dtype == np.int64 and actions.shape == self._dones.shape):
            actions = checked_actions(actions, self.num_envs)
        ended = step_worlds(*self.kernel_args, actions, *self._arrays)
        if ended < 0:
            raise _bad_action(actions[-1 - ended].item(), -1 - ended)
        if ended:
            self.record_episodes(np.flatnonzero(self._dones).tolist())
        return self._seen, self._rewards, self._terminated, self._truncated

    def record_episodes(self, indices: list[int]) -> None:
        """The ``Monitor``'s records of the episodes of envs ``indices``, which ended at the last step."""
        now = time.time() - self._t_start
        for index in indices:
            length = int(self._lengths[index])
            # the Monitor's sum of the episode's rewards: 0 until the goal's 1 - 0.9 * step_count / max_steps
            reward = 1 - 0.9 * (length / self.task.max_steps) if self._terminated[index] else 0.0
            self._episode_rewards[index].append(reward)
            self._episode_lengths[index].append(length)
            self._episode_times[index].append(now)

    def close(self) -> None:
        """Nothing to release (the worlds are arrays); later steps and resets are refused."""
        self._closed = True
        self._started = False

    # ---- the envs' attributes and methods --------------------------------------------------------------------------

    def _attributes(self) -> dict[str, Callable[[int], Any]]:
        agent, task, view, rendering = self.worlds.agent, self.task, self.view, self.rendering
        return {
            "agent_pos": lambda i: (int(agent[i, AGENT_X]), int(agent[i, AGENT_Y])),
            "agent_dir": lambda i: int(agent[i, AGENT_DIR]),
            "step_count": lambda i: int(agent[i, STEP_COUNT]),
            "width": lambda i: task.size,
            "height": lambda i: task.size,
            "max_steps": lambda i: task.max_steps,
            "mission": lambda i: task.mission,
            "see_through_walls": lambda i: task.see_through_walls,
            "agent_view_size": lambda i: view,
            "render_mode": lambda i: rendering.render_mode,
            "highlight": lambda i: rendering.highlight,
            "tile_size": lambda i: rendering.tile_size,
            "agent_pov": lambda i: rendering.agent_pov,
            "screen_size": lambda i: rendering.screen_size,
            "spec": lambda i: self.spec,
            "metadata": lambda i: dict(METADATA),
        }

    def _indices(self, indices: VecEnvIndices) -> list[int]:
        """``_get_indices``, each index checked: one line naming a bad one and the envs there are."""
        chosen = self._get_indices(indices)
        for index in chosen:
            if not _is_int(index) or not -self.num_envs <= index < self.num_envs:
                raise IndexError(f"minigrid_vec_env: indices has {index!r}; its {self.num_envs} envs are "
                                 f"0..{self.num_envs - 1}")
        return [int(index) % self.num_envs for index in chosen]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        getter = self._getters.get(attr_name)
        if getter is None:
            raise AttributeError(
                f"minigrid_vec_env: its envs have no attribute {attr_name!r}; it gives {', '.join(sorted(self._getters))}"
            )
        return [getter(index) for index in self._indices(indices)]

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
            "render": self._frame,
        }
        if method_name not in methods or method_args or method_kwargs:
            raise AttributeError(
                f"minigrid_vec_env: env_method({method_name!r}) is not supported; it runs {', '.join(methods)} "
                "without arguments"
            )
        return [methods[method_name](index) for index in self._indices(indices)]

    def _total_steps(self, index: int) -> int:
        """The ``Monitor``'s ``total_steps``: every step of the env, of episodes ended, cut short and under way."""
        return int(self._abandoned[index] + sum(self._episode_lengths[index]) + self.worlds.agent[index, STEP_COUNT])

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        wrapped = issubclass(Monitor, wrapper_class) or wrapper_class in _gymnasium_wrappers()
        name = {"flat": "FlatObsWrapper", "image": "ImgObsWrapper"}.get(self.obs)
        wrapped = wrapped or (wrapper_class.__module__, wrapper_class.__name__) == ("minigrid.wrappers", name)
        return [bool(wrapped) for _ in self._indices(indices)]

    # ---- rendering -------------------------------------------------------------------------------------------------

    def _frame(self, index: int) -> np.ndarray | None:
        """Env ``index``'s ``render()``: Farama's ``get_frame`` of its world (None unless ``render_mode="rgb_array"``)."""
        if self.rendering.render_mode != "rgb_array":
            return None
        view = self._obs[index, : self.view * self.view * 3].reshape(self.view, self.view, 3)
        agent = self.worlds.agent[index]
        return render_frame(self.worlds.grid[index], (int(agent[AGENT_X]), int(agent[AGENT_Y])), int(agent[AGENT_DIR]),
                            view, self.rendering)

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.rendering.render_mode != "rgb_array":
            import warnings

            warnings.warn(f"minigrid_vec_env: render_mode={self.rendering.render_mode!r}: no images (make it with "
                          "env_kwargs={'render_mode': 'rgb_array'}, the default)", stacklevel=2)
            return [None for _ in range(self.num_envs)]
        return [self._frame(index) for index in range(self.num_envs)]


def render_frame(grid: np.ndarray, agent_pos: tuple[int, int], agent_dir: int, view: np.ndarray,
                 rendering: Rendering) -> np.ndarray:
    """
    ``MiniGridEnv.get_frame(highlight, tile_size, agent_pov)`` of a world: ``grid`` its cell encodings (``x, y``), the
    agent at ``agent_pos`` facing ``agent_dir``, ``view`` its encoded view (``v, v, 3``; unseen cells type 0). Drawn
    by Farama's ``Grid.render`` (the ``[minigrid]`` extra), so the frames are Farama's pixel for pixel.
    """
    try:
        from minigrid.core.grid import Grid
    except ImportError as error:
        raise ImportError("minigrid_vec_env: rendering draws with Farama's minigrid: pip install 'sb3-affect[minigrid]'") \
            from error
    size = view.shape[0]
    visible = view[:, :, 0] != 0
    if rendering.agent_pov:
        pov, _ = Grid.decode(view)
        return pov.render(rendering.tile_size, agent_pos=(size // 2, size - 1), agent_dir=3, highlight_mask=visible)
    world, _ = Grid.decode(grid)
    highlight = np.zeros(grid.shape[:2], dtype=bool)
    if rendering.highlight:  # get_full_render: the world's cells of the visible view cells
        forward = np.array([(1, 0), (0, 1), (-1, 0), (0, -1)][agent_dir])
        right = np.array([-forward[1], forward[0]])
        top_left = np.array(agent_pos) + forward * (size - 1) - right * (size // 2)
        for j in range(size):
            for i in range(size):
                x, y = top_left - forward * j + right * i
                if visible[i, j] and 0 <= x < grid.shape[0] and 0 <= y < grid.shape[1]:
                    highlight[x, y] = True
    return world.render(rendering.tile_size, agent_pos, agent_dir, highlight_mask=highlight if rendering.highlight else None)


def checked_actions(actions: Any, count: int) -> np.ndarray:
    """
    ``actions`` as the kernel takes them (int64, one per env), cast once; refused in one line unless they are ``count``
    integers (an array of shape ``(count,)`` or ``(count, 1)``, or a list) of 0..6: floats with a fraction, bools,
    complex numbers and other objects are refused.
    """
    array = np.asarray(actions)
    if array.size != count or array.shape not in ((count,), (count, 1)):
        raise ValueError(f"minigrid_vec_env: actions of shape {array.shape} for {count} envs; give one integer per env "
                         f"(shape ({count},))")
    flat = array.reshape(count)
    kind = flat.dtype.kind
    if kind not in "iuf":
        raise ValueError(f"minigrid_vec_env: actions of dtype {flat.dtype} ({flat[0]!r}...); give integers 0..6")
    bad = np.flatnonzero((flat < 0) | (flat >= MINIGRID_ACTIONS) | ((flat != np.floor(flat)) if kind == "f" else False))
    if bad.size:
        raise _bad_action(flat[bad[0]].item(), int(bad[0]))
    return flat.astype(np.int64)


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
            if not isinstance(env, MiniGridVecEnv) or (env.env_id, env.obs, env.kernel_args) != (
                    first.env_id, first.obs, first.kernel_args):
                raise ValueError(f"MiniGridBatch: every env must be a minigrid_vec_env of {first.env_id} with "
                                 f"obs={first.obs!r} and env 0's env_kwargs, got {env!r}")
        counts = [env.num_envs for env in self.envs]
        self.offsets = np.cumsum([0, *counts]).tolist()
        self._owner = np.repeat(np.arange(len(counts)), counts)
        self.arrays = _state_arrays(first.task, first.obs, first.view, self.offsets[-1])
        for env, start, stop in zip(self.envs, self.offsets, self.offsets[1:]):
            for joined, own in zip(self.arrays, env.state_arrays):
                joined[start:stop] = own
            env.bind(tuple(array[start:stop] for array in self.arrays))
        self.kernel_args = first.kernel_args
        count, view = self.offsets[-1], first.view
        self._seen = self.arrays[4].reshape(count, view, view, 3) if first.obs == "image" else self.arrays[4]

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        One step of every env, as each env's ``step_arrays``: ``actions`` has one integer per env (the envs' rows in
        order; checked and cast to int64 as ``step_arrays`` does); returns the observations, rewards and dones of all
        envs (this batch's buffers, the observations shaped as each env's: copy what you keep).
        """
        count = self.offsets[-1]
        if not (type(actions) is np.ndarray and actions.dtype == np.int64 and actions.shape == (count,)):
            actions = checked_actions(actions, count)
        for env in self.envs:
            env.require_started("MiniGridBatch: call each env's reset() before step()")
        ended = step_worlds(*self.kernel_args, actions, *self.arrays)
        if ended < 0:
            raise _bad_action(actions[-1 - ended].item(), -1 - ended)
        dones = self.arrays[8]
        if ended:
            for row in np.flatnonzero(dones).tolist():
                owner = int(self._owner[row])
                self.envs[owner].record_episodes([row - self.offsets[owner]])
        return self._seen, self.arrays[5], dones

    def infos(self, ended_only: bool = False) -> list[list[dict[str, Any]]]:
        """
        Each env's infos of the last step, as its ``step`` gives them; ``ended_only``: those of the VecEnvs where an
        episode ended only, the others' lists empty (for a trainer that reads the infos of ended episodes only).
        """
        rows = np.flatnonzero(self.arrays[8])
        if ended_only:
            ended: list[list[dict[str, Any]]] = [[] for _ in self.envs]
            for owner in sorted(set(self._owner[rows].tolist())):
                ended[owner] = self.envs[owner].step_infos()
            return ended
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": False} for _ in range(self.offsets[-1])]
        for row in rows.tolist():
            owner = int(self._owner[row])
            infos[row] = self.envs[owner].ended_info(row - self.offsets[owner])
        return [infos[start:stop] for start, stop in zip(self.offsets, self.offsets[1:])]


def _bad_action(value: Any, index: int) -> ValueError:
    return ValueError(f"minigrid_vec_env: action {value!r} of env {index} is not a MiniGrid action (0..6)")


def _gymnasium_wrappers() -> tuple[type, ...]:
    """The wrappers ``gym.make`` puts around a MiniGrid env."""
    from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker

    return (OrderEnforcing, PassiveEnvChecker)


def minigrid_vec_env(env_id: str, n_envs: int = 1, seed: int | None = None, obs: str = "flat",
                     env_kwargs: dict[str, Any] | None = None) -> MiniGridVecEnv:
    """
    MiniGrid ``env_id`` (Empty-NxN and Empty-Random-NxN, FourRooms, DoorKey-NxN: ``MINIGRID_TASKS``) compiled, as an SB3
    ``VecEnv`` of ``n_envs`` envs that gives, for the same seed and actions, what
    ``make_vec_env(env_id, n_envs, seed=seed, wrapper_class=FlatObsWrapper, env_kwargs=env_kwargs)`` gives;
    ``obs="image"``: ``ImgObsWrapper``'s 7 x 7 x 3 image instead; ``obs="view"``: that image flattened (the first 147
    entries of ``FlatObsWrapper``'s vector). See ``sb3_affect.agents.minigrid_vec_env``.
    """
    return MiniGridVecEnv(env_id, n_envs, seed=seed, obs=obs, env_kwargs=env_kwargs)
