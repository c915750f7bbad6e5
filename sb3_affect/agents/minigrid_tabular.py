"""
``TabularMiniGrid``: a MiniGrid env as a Discrete observation, so the package's tabular agents learn on it.

The state is the agent's cell, its direction, what it carries and the state of each door, numbered as one mixed-radix
integer (the cell and direction first, as ``position="minigrid-dir"`` numbers them)::

    state = (((y * width + x) * 4 + direction) * (1 + keys) + carried) * 3**doors + door states

where ``carried`` is 0 (nothing) or 1 + the index of the key carried, and each door is 0 (open), 1 (closed) or 2
(locked); keys and doors are numbered in the order a row-by-row scan of the grid finds them at ``reset``. The grid's
own layout (where walls, doors and the goal are) is not part of the state: on envs that draw a new layout at every
reset (DoorKey) the tabular agent learns one table for all of them. Nor is where a dropped key lies. Refused with one
line: envs with objects the state can not hold (balls, boxes, moving obstacles), envs that put the goal at another
cell after a reset (FourRooms, MultiRoom: the state holds the agent's cell, not the goal's, so no table can say where
to go) and envs that give another mission after a reset (GoToDoor: the state does not hold the mission). The wrapper
tells them by resetting the env with the seeds ``PROBE_SEEDS`` at construction (the env's random generator is put
back afterwards). It reads the env's attributes only; it needs ``minigrid`` installed to make the env
(``pip install "sb3-affect[minigrid]"``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium import spaces

#: The MiniGrid object types the state encodes (the others are refused).
ENCODED_OBJECTS = ("wall", "floor", "goal", "lava", "door", "key")
#: The seeds of the resets that tell whether an env keeps its goal and its mission from one episode to the next.
PROBE_SEEDS = tuple(range(8))


def _name(env: Any) -> str:
    return env.spec.id if env.spec else type(env).__name__


def _goal_cells(env: Any) -> tuple[tuple[int, int], ...]:
    grid = env.grid
    return tuple(
        (x, y) for y in range(grid.height) for x in range(grid.width) if getattr(grid.get(x, y), "type", None) == "goal"
    )


def check_task_in_state(env: Any) -> None:
    """
    A ValueError (one line) when the MiniGrid env ``env`` (unwrapped) puts its goal at other cells or gives another
    mission after a reset with one of ``PROBE_SEEDS``: the state holds neither, so the task would change unseen.
    """
    saved = env._np_random, env._np_random_seed  # the generator the user's next unseeded reset draws from
    goals: dict[tuple[tuple[int, int], ...], None] = {}
    missions: dict[str, None] = {}
    try:
        for seed in PROBE_SEEDS:
            env.reset(seed=seed)
            goals[_goal_cells(env)] = None
            missions[str(getattr(env, "mission", ""))] = None
    finally:
        env._np_random, env._np_random_seed = saved
    if len(goals) > 1:
        cells = ", ".join(str(cell) for cells in list(goals)[:3] for cell in cells)
        raise ValueError(
            f"TabularMiniGrid: {_name(env)} puts the goal at another cell after a reset ({cells}, ...) and the state "
            "holds the agent's cell, not the goal's, so a table can not learn where to go; use an env whose goal "
            "stays put (Empty, DoorKey, LavaGap) or a deep agent with position='minigrid'"
        )
    if len(missions) > 1:
        said = ", ".join(repr(mission) for mission in list(missions)[:3])
        raise ValueError(
            f"TabularMiniGrid: {_name(env)} gives another mission after a reset ({said}, ...) and the state does not "
            "hold the mission, so a table can not learn it; use an env with one mission (Empty, DoorKey, LavaGap)"
        )


def _objects(env: Any) -> tuple[list[Any], list[Any]]:
    """The keys and the doors of the current grid, in row-by-row order; a ValueError for an object not encoded."""
    keys: list[Any] = []
    doors: list[Any] = []
    grid = env.grid
    for y in range(grid.height):
        for x in range(grid.width):
            obj = grid.get(x, y)
            if obj is None:
                continue
            if obj.type not in ENCODED_OBJECTS:
                raise ValueError(
                    f"TabularMiniGrid: {_name(env)} has a {obj.type} at ({x}, {y}), "
                    f"which the state can not encode; it encodes {', '.join(ENCODED_OBJECTS)}"
                )
            (keys if obj.type == "key" else doors if obj.type == "door" else []).append(obj)
    carrying = getattr(env, "carrying", None)
    if carrying is not None:
        if carrying.type != "key":
            raise ValueError(f"TabularMiniGrid: the agent carries a {carrying.type}; the state encodes keys only")
        keys.append(carrying)
    return keys, doors


class TabularMiniGrid(gym.ObservationWrapper):
    """
    A MiniGrid env with a Discrete observation of its state (see the module docstring). Its action space is the
    env's own (``Discrete(7)``: left, right, forward, pickup, drop, toggle, done).

    :param env: a MiniGrid env (``gymnasium.make("MiniGrid-Empty-8x8-v0")``); it is reset here with ``PROBE_SEEDS``
        to check that its goal and mission stay put, then once more (as the caller's generator has it) to count its
        keys and doors
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        base: Any = env.unwrapped
        if not all(hasattr(base, name) for name in ("grid", "agent_pos", "agent_dir", "width", "height")):
            raise ValueError(f"TabularMiniGrid: {base} is not a MiniGrid env (it has no grid, agent_pos and agent_dir)")
        check_task_in_state(base)
        env.reset()
        keys, doors = _objects(base)
        self.n_keys, self.n_doors = len(keys), len(doors)
        self.width, self.height = int(base.width), int(base.height)
        n = self.width * self.height * 4 * (1 + self.n_keys) * 3**self.n_doors
        self.observation_space = spaces.Discrete(n)
        self._keys, self._doors = keys, doors

    def reset(self, **kwargs: Any) -> tuple[int, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        keys, doors = _objects(self.env.unwrapped)
        if (len(keys), len(doors)) != (self.n_keys, self.n_doors):
            raise ValueError(
                f"TabularMiniGrid: this episode's grid has {len(keys)} keys and {len(doors)} doors, the first had "
                f"{self.n_keys} and {self.n_doors}; the state needs the same number in every episode"
            )
        self._keys, self._doors = keys, doors
        return self.observation(obs), info

    def observation(self, observation: Any) -> int:
        base: Any = self.env.unwrapped
        x, y = (int(v) for v in base.agent_pos)
        state = (y * self.width + x) * 4 + int(base.agent_dir)
        carried = 0
        carrying = base.carrying
        if carrying is not None:
            carried = 1 + next((i for i, key in enumerate(self._keys) if key is carrying), -1)
            if carried == 0:
                raise ValueError(f"TabularMiniGrid: the agent carries a {carrying.type} that was not on the grid at reset")
        state = state * (1 + self.n_keys) + carried
        for door in self._doors:
            state = state * 3 + (0 if door.is_open else 2 if door.is_locked else 1)
        return state
