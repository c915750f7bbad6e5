"""
MiniGrid's Empty, FourRooms and DoorKey worlds (Farama's ``minigrid``) in numba: many worlds stepped in one call.

The kernels copy ``minigrid``'s semantics draw for draw and cell for cell:

- layouts (``reset_worlds``): each world's ``_gen_grid`` (``envs/empty.py``, ``fourrooms.py``, ``doorkey.py``) with
  its draws from the env's ``np_random`` (``_rand_int(low, high)`` is ``integers(high - low)`` plus ``low`` on
  ``kernel.pcg64``; ``place_obj`` draws ``x`` then ``y`` until the cell is empty and not the agent's; ``place_agent``
  draws its cell so, then its direction);
- ``MiniGridEnv.step`` (``step_worlds``): left, right, forward (onto an empty cell, the goal or an open door; the goal
  ends the episode with reward ``1 - 0.9 * step_count / max_steps``), pickup (a key, when carrying nothing), drop (onto
  an empty cell), toggle (a locked door opens with the key; a closed door opens, an open one closes), done (nothing);
  truncation when ``step_count >= max_steps``;
- the observation: the 7 x 7 view (``kernel.minigrid_view``).

A batch of ``n`` worlds of one task is a ``Worlds`` tuple of arrays, row ``i`` world ``i``: ``grid`` (``n, size,
size, 3``, uint8 cell encodings), ``agent`` (``n, 4``, int64: x, y, direction, step count), ``carry`` (``n, 3``, uint8:
the carried object's encoding, type 0 for nothing), ``rng`` (``n, pcg64.STATE_SIZE``, uint64: each env's PCG64 state).
The kernels allocate nothing; the caller owns every array.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from sb3_affect.kernel.jit import kernel_jit
from sb3_affect.kernel.minigrid_view import (
    DIR_X,
    DIR_Y,
    DOOR,
    EMPTY,
    GOAL,
    GREEN,
    GREY,
    KEY,
    LOCKED,
    OPEN,
    VIEW,
    VIEW_SIZE,
    WALL,
    YELLOW,
    write_view,
)
from sb3_affect.kernel.pcg64 import STATE_SIZE, integers

#: The layouts a world kernel generates.
EMPTY_FIXED, EMPTY_RANDOM, FOUR_ROOMS, DOOR_KEY = range(4)
#: ``minigrid.core.actions.Actions``.
LEFT, RIGHT, FORWARD, PICKUP, DROP, TOGGLE, DONE = range(7)
MINIGRID_ACTIONS = 7
#: The columns of ``Worlds.agent``.
AGENT_X, AGENT_Y, AGENT_DIR, STEP_COUNT = range(4)


class MiniGridTask(NamedTuple):
    """What a registered MiniGrid id builds: its layout kind, size, step limit, mission and whether walls hide."""

    layout: int
    size: int
    max_steps: int
    mission: str
    see_through_walls: bool


def _tasks() -> dict[str, MiniGridTask]:
    empty_mission, four_mission = "get to the green goal square", "reach the goal"
    door_mission = "use the key to open the door and then get to the goal"
    tasks = {}
    for size in (5, 6, 8, 16):
        tasks[f"MiniGrid-Empty-{size}x{size}-v0"] = MiniGridTask(EMPTY_FIXED, size, 4 * size**2, empty_mission, True)
        tasks[f"MiniGrid-DoorKey-{size}x{size}-v0"] = MiniGridTask(DOOR_KEY, size, 10 * size**2, door_mission, False)
    for size in (5, 6):
        tasks[f"MiniGrid-Empty-Random-{size}x{size}-v0"] = MiniGridTask(EMPTY_RANDOM, size, 4 * size**2, empty_mission, True)
    tasks["MiniGrid-FourRooms-v0"] = MiniGridTask(FOUR_ROOMS, 19, 100, four_mission, False)
    return dict(sorted(tasks.items()))


#: The MiniGrid ids the compiled worlds implement (as ``minigrid`` registers them) and what each builds.
MINIGRID_TASKS: dict[str, MiniGridTask] = _tasks()


class Worlds(NamedTuple):
    """The state of a batch of worlds (see the module's docstring)."""

    grid: np.ndarray
    agent: np.ndarray
    carry: np.ndarray
    rng: np.ndarray


def new_worlds(task: MiniGridTask, n: int) -> Worlds:
    """Arrays for ``n`` worlds of ``task`` (zeros: give each a generator state, then ``reset_worlds``)."""
    return Worlds(
        np.zeros((n, task.size, task.size, 3), dtype=np.uint8),
        np.zeros((n, 4), dtype=np.int64),
        np.zeros((n, 3), dtype=np.uint8),
        np.zeros((n, STATE_SIZE), dtype=np.uint64),
    )


@kernel_jit
def _rand_int(rng: np.ndarray, low: int, high: int) -> Any:
    """``MiniGridEnv._rand_int``: ``np_random.integers(low, high)``."""
    return low + integers(rng, high - low)


@kernel_jit
def _put(grid: np.ndarray, n: int, x: int, y: int, kind: int, color: int, state: int) -> None:
    grid[n, x, y, 0] = kind
    grid[n, x, y, 1] = color
    grid[n, x, y, 2] = state


@kernel_jit
def _walls(grid: np.ndarray, n: int, x: int, y: int, dx: int, dy: int, length: int) -> None:
    """``Grid.horz_wall`` (``dx = 1``) or ``vert_wall`` (``dy = 1``) of ``length`` cells from ``(x, y)``."""
    for k in range(length):
        _put(grid, n, x + dx * k, y + dy * k, WALL, GREY, 0)


@kernel_jit
def _place(grid: np.ndarray, n: int, rng: np.ndarray, agent: np.ndarray, top_x: int, top_y: int, size_x: int,
           size_y: int) -> Any:
    """``MiniGridEnv.place_obj``'s cell: drawn until empty and not the agent's; returns ``x * height + y``."""
    width, height = grid.shape[1], grid.shape[2]
    while True:
        x = _rand_int(rng, top_x, min(top_x + size_x, width))
        y = _rand_int(rng, top_y, min(top_y + size_y, height))
        if grid[n, x, y, 0] != EMPTY:
            continue
        if x == agent[n, AGENT_X] and y == agent[n, AGENT_Y]:
            continue
        return x * height + y


@kernel_jit
def _place_agent(grid: np.ndarray, n: int, rng: np.ndarray, agent: np.ndarray, size_x: int, size_y: int) -> None:
    """``MiniGridEnv.place_agent(size=(size_x, size_y))``: a cell, then a direction."""
    height = grid.shape[2]
    agent[n, AGENT_X] = -1
    agent[n, AGENT_Y] = -1
    cell = _place(grid, n, rng, agent, 0, 0, size_x, size_y)
    agent[n, AGENT_X] = cell // height
    agent[n, AGENT_Y] = cell % height
    agent[n, AGENT_DIR] = _rand_int(rng, 0, 4)


@kernel_jit
def _generate(layout: int, grid: np.ndarray, n: int, rng: np.ndarray, agent: np.ndarray) -> None:
    """The task's ``_gen_grid`` for world ``n``."""
    width, height = grid.shape[1], grid.shape[2]
    for x in range(width):
        for y in range(height):
            _put(grid, n, x, y, EMPTY, 0, 0)
    agent[n, AGENT_X] = -1
    agent[n, AGENT_Y] = -1
    if layout == FOUR_ROOMS:
        _walls(grid, n, 0, 0, 1, 0, width)
        _walls(grid, n, 0, height - 1, 1, 0, width)
        _walls(grid, n, 0, 0, 0, 1, height)
        _walls(grid, n, width - 1, 0, 0, 1, height)
        room_w, room_h = width // 2, height // 2
        for j in range(2):
            for i in range(2):
                x_left, y_top = i * room_w, j * room_h
                x_right, y_bottom = x_left + room_w, y_top + room_h
                if i + 1 < 2:
                    _walls(grid, n, x_right, y_top, 0, 1, room_h)
                    _put(grid, n, x_right, _rand_int(rng, y_top + 1, y_bottom), EMPTY, 0, 0)
                if j + 1 < 2:
                    _walls(grid, n, x_left, y_bottom, 1, 0, room_w)
                    _put(grid, n, _rand_int(rng, x_left + 1, x_right), y_bottom, EMPTY, 0, 0)
        _place_agent(grid, n, rng, agent, width, height)
        cell = _place(grid, n, rng, agent, 0, 0, width, height)
        _put(grid, n, cell // height, cell % height, GOAL, GREEN, 0)
        return
    _walls(grid, n, 0, 0, 1, 0, width)  # wall_rect(0, 0, width, height)
    _walls(grid, n, 0, height - 1, 1, 0, width)
    _walls(grid, n, 0, 0, 0, 1, height)
    _walls(grid, n, width - 1, 0, 0, 1, height)
    _put(grid, n, width - 2, height - 2, GOAL, GREEN, 0)
    if layout == EMPTY_FIXED:
        agent[n, AGENT_X] = 1
        agent[n, AGENT_Y] = 1
        agent[n, AGENT_DIR] = 0
    elif layout == EMPTY_RANDOM:
        _place_agent(grid, n, rng, agent, width, height)
    else:  # DOOR_KEY
        split = _rand_int(rng, 2, width - 2)
        _walls(grid, n, split, 0, 0, 1, height)
        _place_agent(grid, n, rng, agent, split, height)
        _put(grid, n, split, _rand_int(rng, 1, height - 2), DOOR, YELLOW, LOCKED)
        cell = _place(grid, n, rng, agent, 0, 0, split, height)
        _put(grid, n, cell // height, cell % height, KEY, YELLOW, 0)


@kernel_jit
def _reset_one(layout: int, see_through: bool, view: int, n: int, grid: np.ndarray, agent: np.ndarray,
               carry: np.ndarray, rng: np.ndarray, obs: np.ndarray) -> None:
    _generate(layout, grid, n, rng[n], agent)
    agent[n, STEP_COUNT] = 0
    carry[n, 0] = 0
    carry[n, 1] = 0
    carry[n, 2] = 0
    write_view(grid, n, agent[n, AGENT_X], agent[n, AGENT_Y], agent[n, AGENT_DIR], carry, see_through, view, obs)


@kernel_jit
def reset_worlds(layout: int, see_through: bool, view: int, which: np.ndarray, grid: np.ndarray, agent: np.ndarray,
                 carry: np.ndarray, rng: np.ndarray, obs: np.ndarray) -> None:
    """``reset`` of every world ``n`` with ``which[n]``: a new layout from its generator, its ``view`` x ``view`` view into
    ``obs[n]``'s first ``view * view * 3`` entries."""
    for n in range(which.shape[0]):
        if which[n]:
            _reset_one(layout, see_through, view, n, grid, agent, carry, rng, obs)


@kernel_jit
def step_worlds(layout: int, see_through: bool, max_steps: int, view: int, actions: np.ndarray, grid: np.ndarray,
                agent: np.ndarray, carry: np.ndarray, rng: np.ndarray, obs: np.ndarray, rewards: np.ndarray,
                terminated: np.ndarray, truncated: np.ndarray, dones: np.ndarray, lengths: np.ndarray,
                terminal_obs: np.ndarray) -> int:
    """
    One ``step`` of every world with ``actions[n]``, then, as SB3's VecEnvs do, a ``reset`` of each world whose
    episode ended: ``rewards`` (float32), ``terminated``, ``truncated``, ``dones`` (either) and ``obs[n, :147]`` (the
    first observation of the next episode where one ended, whose last observation is then in ``terminal_obs[n, :147]``
    and its length in ``lengths[n]``; ``view * view * 3`` entries for another ``view`` size).

    Returns the number of episodes that ended, or ``-1 - n`` for the first action ``n`` outside ``0..6`` (then no world
    has moved).
    """
    count = actions.shape[0]
    for n in range(count):
        if actions[n] < 0 or actions[n] >= MINIGRID_ACTIONS:
            return -1 - n
    ended = 0
    for n in range(count):
        action = actions[n]
        agent[n, STEP_COUNT] += 1
        reward = 0.0
        done = False
        x, y, direction = agent[n, AGENT_X], agent[n, AGENT_Y], agent[n, AGENT_DIR]
        fx, fy = x + DIR_X[direction], y + DIR_Y[direction]
        kind = grid[n, fx, fy, 0]
        if action == LEFT:
            agent[n, AGENT_DIR] = (direction + 3) % 4
        elif action == RIGHT:
            agent[n, AGENT_DIR] = (direction + 1) % 4
        elif action == FORWARD:
            if kind in (EMPTY, GOAL) or (kind == DOOR and grid[n, fx, fy, 2] == OPEN):
                agent[n, AGENT_X] = fx
                agent[n, AGENT_Y] = fy
            if kind == GOAL:
                done = True
                reward = 1.0 - 0.9 * (agent[n, STEP_COUNT] / max_steps)
        elif action == PICKUP:
            if kind == KEY and carry[n, 0] == 0:
                carry[n, 0] = grid[n, fx, fy, 0]
                carry[n, 1] = grid[n, fx, fy, 1]
                carry[n, 2] = grid[n, fx, fy, 2]
                _put(grid, n, fx, fy, EMPTY, 0, 0)
        elif action == DROP:
            if kind == EMPTY and carry[n, 0] != 0:
                _put(grid, n, fx, fy, carry[n, 0], carry[n, 1], carry[n, 2])
                carry[n, 0] = 0
                carry[n, 1] = 0
                carry[n, 2] = 0
        elif action == TOGGLE and kind == DOOR:
            state = grid[n, fx, fy, 2]
            if state == LOCKED:
                if carry[n, 0] == KEY and carry[n, 1] == grid[n, fx, fy, 1]:
                    grid[n, fx, fy, 2] = OPEN
            else:
                grid[n, fx, fy, 2] = 1 - state
        rewards[n] = reward
        terminated[n] = done
        truncated[n] = agent[n, STEP_COUNT] >= max_steps
        dones[n] = done or truncated[n]
        if dones[n]:
            ended += 1
            lengths[n] = agent[n, STEP_COUNT]
            write_view(grid, n, agent[n, AGENT_X], agent[n, AGENT_Y], agent[n, AGENT_DIR], carry, see_through, view,
                       terminal_obs)
            _reset_one(layout, see_through, view, n, grid, agent, carry, rng, obs)
        else:
            write_view(grid, n, agent[n, AGENT_X], agent[n, AGENT_Y], agent[n, AGENT_DIR], carry, see_through, view, obs)
    return ended


def warm_up() -> None:
    """Load (the first time on a machine: compile) the MiniGrid kernels, on one world of each layout."""
    from sb3_affect.kernel.pcg64 import seeded_state

    for name in ("Empty-5x5", "Empty-Random-5x5", "FourRooms", "DoorKey-5x5"):
        task = MINIGRID_TASKS[f"MiniGrid-{name}-v0"]
        worlds = new_worlds(task, 1)
        worlds.rng[0] = seeded_state(0)
        obs, terminal = np.zeros((1, VIEW_SIZE), dtype=np.uint8), np.zeros((1, VIEW_SIZE), dtype=np.uint8)
        reset_worlds(task.layout, task.see_through_walls, VIEW, np.ones(1, dtype=np.bool_), *worlds, obs)
        flags = [np.zeros(1, dtype=np.bool_) for _ in range(3)]
        step_worlds(task.layout, task.see_through_walls, task.max_steps, VIEW, np.zeros(1, dtype=np.int64), *worlds, obs,
                    np.zeros(1, dtype=np.float32), *flags, np.zeros(1, dtype=np.int64), terminal)
