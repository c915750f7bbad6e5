"""GridPursuit: the pursuit grid of Badoy & Teknomo, "Q-Learning with Basic Emotions" (Sec. IV, Fig. 2)."""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sb3_affect.envs.transition_table import TransitionTable

# The one place that defines the moves. Every agent, test and fast path uses these.
UP, DOWN, LEFT, RIGHT = 0, 1, 2, 3
MOVES: tuple[tuple[int, int], ...] = ((-1, 0), (1, 0), (0, -1), (0, 1))
ACTION_NAMES: tuple[str, ...] = ("up", "down", "left", "right")
#: How a prey moves (MovingPursuit, HunterPursuit), the one list of its modes (the kernel codes each by its index).
PREY_MODES: tuple[str, ...] = ("static", "random", "evade")

Cell = tuple[int, int]

#: The largest grid side: a grid of MAX_SIZE x MAX_SIZE cells (a million states) is built in Python lists, as is the
#: agents' Q-table of it; checked before anything is built.
MAX_SIZE = 1000


def check_size(size: Any) -> int:
    """A grid side: an integer in [2, ``MAX_SIZE``]."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise TypeError(f"size must be an integer in [2, {MAX_SIZE}], got {size!r}")
    if size < 2:
        raise ValueError(f"size={size} is too small: the grid needs size >= 2")
    if size > MAX_SIZE:
        raise ValueError(f"size={size} is too large: at most {MAX_SIZE} ({MAX_SIZE}x{MAX_SIZE} cells)")
    return int(size)


def _as_cell(name: str, value: Any, size: int) -> Cell:
    """Validate a (row, col) pair inside a size x size grid."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if (
        not isinstance(value, (tuple, list))
        or len(value) != 2
        or not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in value)
    ):
        raise TypeError(f"{name} must be a (row, col) pair of integers, got {value!r}")
    row, col = int(value[0]), int(value[1])
    if not (0 <= row < size and 0 <= col < size):
        raise ValueError(f"{name}={value!r} is outside the {size} x {size} grid: rows and columns must be in [0, {size - 1}]")
    return row, col


def build_transitions(size: int, blocked: Iterable[int] = ()) -> list[list[int]]:
    """``table[s][a]``: the cell reached from cell ``s`` with action ``a`` (one cell; walls and obstacles stay put)."""
    wall = set(blocked)
    table: list[list[int]] = []
    for s in range(size * size):
        row, col = divmod(s, size)
        nxt = []
        for d_row, d_col in MOVES:
            r, c = row + d_row, col + d_col
            t = r * size + c
            nxt.append(t if 0 <= r < size and 0 <= c < size and t not in wall else s)
        table.append(nxt)
    return table


def distances_to(target: int, transitions: Sequence[Sequence[int]]) -> list[float]:
    """Shortest number of one-cell moves from every cell to ``target`` (``inf`` where unreachable)."""
    n = len(transitions)
    preds: list[list[int]] = [[] for _ in range(n)]
    for s, row in enumerate(transitions):
        for t in row:
            if t != s:
                preds[t].append(s)
    dist = [float("inf")] * n
    dist[target] = 0.0
    queue = deque([target])
    while queue:
        v = queue.popleft()
        for u in preds[v]:
            if dist[u] == float("inf"):
                dist[u] = dist[v] + 1
                queue.append(u)
    return dist


class GridPursuitEnv(gym.Env[Any, Any]):
    """
    A hunter (the agent) pursues a static prey (the goal) on a square grid.

    The paper's task: a 15 x 15 grid, the hunter starts at (0, 0), the prey sits at (6, 6); the shortest path is
    12 cells (Manhattan distance).

    ## Action space
    ``Discrete(4)``: 0 up (row - 1), 1 down (row + 1), 2 left (col - 1), 3 right (col + 1). A move off the grid or
    into an obstacle leaves the hunter where it is.

    ## Observation space
    ``Discrete(size * size)``: the hunter's cell as ``row * size + col``.

    ## Rewards
    ``goal_reward`` (default +100) on entering the goal cell, ``step_reward`` (default 0) on every other move.

    ## Starting state
    The hunter at ``start``.

    ## Episode end
    Terminates when the hunter enters the goal. Not truncated by the env unless ``max_episode_steps`` is given
    to ``gym.make``; the algorithms of this package keep their own safety cap (counted in decisions).

    ## Info
    ``{"cell": (row, col)}``; after a move also ``"moved"``: whether the hunter changed cell.

    ## Arguments
    :param size: grid side (int >= 2)
    :param start: the hunter's first cell (row, col)
    :param goal: the prey's cell (row, col)
    :param obstacles: cells the hunter can not enter
    :param goal_reward: reward on entering the goal (> 0)
    :param step_reward: reward of every other move
    :param render_mode: ``None``, ``"ansi"`` or ``"rgb_array"``
    """

    metadata = {"render_modes": ["ansi", "rgb_array"], "render_fps": 8}

    def __init__(
        self,
        size: int = 15,
        start: Sequence[int] = (0, 0),
        goal: Sequence[int] = (6, 6),
        obstacles: Iterable[Sequence[int]] = (),
        goal_reward: float = 100.0,
        step_reward: float = 0.0,
        render_mode: str | None = None,
    ) -> None:
        self.size = check_size(size)
        start_cell = _as_cell("start", start, self.size)
        goal_cell = _as_cell("goal", goal, self.size)
        if start_cell == goal_cell:
            raise ValueError(f"start={start_cell} equals goal={goal_cell}: the episode would be over before it begins")
        if isinstance(obstacles, (str, bytes)):
            raise TypeError(f"obstacles must be a list of (row, col) pairs, got {obstacles!r}")
        obstacle_cells = [_as_cell(f"obstacles[{i}]", o, self.size) for i, o in enumerate(obstacles)]
        if start_cell in obstacle_cells:
            raise ValueError(f"start={start_cell} is on an obstacle")
        if goal_cell in obstacle_cells:
            raise ValueError(f"goal={goal_cell} is on an obstacle")
        for name, value in (("goal_reward", goal_reward), ("step_reward", step_reward)):
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.integer, np.floating))
                or not np.isfinite(value)
            ):
                raise TypeError(f"{name} must be a finite number, got {value!r}")
        if goal_reward <= 0:
            raise ValueError(f"goal_reward={goal_reward} must be > 0 (the goal must be worth reaching)")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r} is not supported; use None, 'ansi' or 'rgb_array'")

        self.start = start_cell
        self.goal = goal_cell
        self.obstacles: tuple[Cell, ...] = tuple(sorted(set(obstacle_cells)))
        self.goal_reward = float(goal_reward)
        self.step_reward = float(step_reward)
        self.render_mode = render_mode

        self.start_state = self.to_state(start_cell)
        self.goal_state = self.to_state(goal_cell)
        self.transitions = build_transitions(self.size, (self.to_state(o) for o in self.obstacles))
        self.distances = distances_to(self.goal_state, self.transitions)
        if self.distances[self.start_state] == float("inf"):
            raise ValueError(f"goal={goal_cell} is unreachable from start={start_cell}: the obstacles wall it off")
        self.shortest_path_length = int(self.distances[self.start_state])

        self.observation_space = spaces.Discrete(self.size * self.size)
        self.action_space = spaces.Discrete(len(MOVES))
        self.state = self.start_state

    def transition_table(self) -> TransitionTable:
        """The env's moves as a table (``sb3_affect.envs.transition_table``): what lets the compiled engine step it."""
        return TransitionTable(
            self.transitions, self.distances, self.start_state, self.goal_state, self.goal_reward, self.step_reward, self.size
        )

    # -- helpers ---------------------------------------------------------------------------------------------
    def to_state(self, cell: Sequence[int]) -> int:
        return int(cell[0]) * self.size + int(cell[1])

    def to_cell(self, state: int) -> Cell:
        row, col = divmod(int(state), self.size)
        return row, col

    # -- gymnasium API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        self.state = self.start_state
        return self.state, {"cell": self.start}

    def step(self, action: Any) -> tuple[int, SupportsFloat, bool, bool, dict[str, Any]]:
        s = self.state
        t = self.transitions[s][int(action)]
        self.state = t
        terminated = t == self.goal_state
        reward = self.goal_reward if terminated else self.step_reward
        return t, reward, terminated, False, {"cell": divmod(t, self.size), "moved": t != s}

    def render(self) -> str | np.ndarray | None:
        if self.render_mode == "ansi":
            return self._render_text()
        if self.render_mode == "rgb_array":
            return self._render_rgb()
        return None

    def _render_text(self) -> str:
        blocked = {self.to_state(o) for o in self.obstacles}
        lines = []
        for r in range(self.size):
            row = []
            for c in range(self.size):
                s = r * self.size + c
                row.append("H" if s == self.state else "P" if s == self.goal_state else "#" if s in blocked else ".")
            lines.append(" ".join(row))
        return "\n".join(lines) + "\n"

    def _render_rgb(self, cell_px: int = 16) -> np.ndarray:
        img = np.full((self.size * cell_px, self.size * cell_px, 3), 255, dtype=np.uint8)
        img[::cell_px, :, :] = 200
        img[:, ::cell_px, :] = 200

        def paint(state: int, colour: tuple[int, int, int]) -> None:
            r, c = self.to_cell(state)
            img[r * cell_px + 1 : (r + 1) * cell_px, c * cell_px + 1 : (c + 1) * cell_px] = colour

        for o in self.obstacles:
            paint(self.to_state(o), (60, 60, 60))
        paint(self.goal_state, (220, 40, 40))
        paint(self.state, (40, 90, 220))
        return img
