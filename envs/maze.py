"""
Mazes: obstacle layouts for the pursuit grid written as text maps.

A map is a square of characters, one line per grid row: ``#`` wall (obstacle), ``.`` free, ``S`` the hunter's
start, ``G`` the goal (the prey's cell; its starting cell for a moving prey). Exactly one ``S`` and one ``G``.
Lines starting with ``;`` are comments; blank lines before and after the map and trailing spaces are ignored.

Shipped maps (``shipped_mazes()``), all 15 x 15 with ``S`` at (0, 0) and ``G`` at (6, 6) unless noted:

- ``open``: the paper's task (no walls, shortest path 12 cells);
- ``wall``: a wall between hunter and prey, open only at one end;
- ``rooms``: four rooms joined by one-cell doors, goal at (11, 10);
- ``zigzag``: one long zigzag corridor, goal at (14, 14).

Use a map by name or by file path: ``gym.make("sb3_affect/MazePursuit-v0", maze="rooms")``,
``maze="path/to/my.txt"``, or ``GridPursuitEnv(**maze_kwargs("rooms"))``. Every map is validated when parsed: its
shape, its characters, one start and one goal, and that the goal is reachable from the start.
"""

from __future__ import annotations

import os
from importlib import resources
from typing import Any, NamedTuple

from sb3_affect.envs.grid_pursuit import MAX_SIZE, build_transitions, distances_to

#: The largest map file read: ``MAX_SIZE`` rows of ``MAX_SIZE`` cells, and room for comments.
MAX_MAZE_BYTES = MAX_SIZE * (MAX_SIZE + 2) + 2**16

WALL, FREE, START, GOAL = "#", ".", "S", "G"


class Maze(NamedTuple):
    """A parsed map (cells are (row, col))."""

    name: str
    size: int
    start: tuple[int, int]
    goal: tuple[int, int]
    obstacles: tuple[tuple[int, int], ...]

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``GridPursuitEnv`` (and the moving-prey env's ``start``/``prey_start``)."""
        return {"size": self.size, "start": self.start, "goal": self.goal, "obstacles": [list(o) for o in self.obstacles]}


class MazeError(ValueError):
    """A text map that can not be used (bad shape or characters, missing start or goal, unreachable goal)."""


def parse_maze(text: str, name: str = "<maze>") -> Maze:
    """
    Parse and validate a text map.

    :param text: the map (see the module docstring)
    :param name: used in error messages
    :return: the maze
    :raises MazeError: with the row and column of the problem
    """
    lines = [line.rstrip() for line in text.splitlines() if not line.lstrip().startswith(";")]
    while lines and not lines[0]:
        lines.pop(0)
    while lines and not lines[-1]:
        lines.pop()
    if not lines:
        raise MazeError(f"maze {name!r} is empty")
    widest = max(len(line) for line in lines)
    if len(lines) > MAX_SIZE or widest > MAX_SIZE:
        raise MazeError(
            f"maze {name!r} is {len(lines)} rows x {widest} columns: a map has at most {MAX_SIZE} x {MAX_SIZE} cells"
        )
    size = len(lines)
    if size < 2:
        raise MazeError(f"maze {name!r} has one row: a maze needs at least 2 x 2 cells")
    starts: list[tuple[int, int]] = []
    goals: list[tuple[int, int]] = []
    walls: list[tuple[int, int]] = []
    for r, line in enumerate(lines):
        if len(line) != size:
            raise MazeError(
                f"maze {name!r} must be square: it has {size} rows but row {r} has {len(line)} characters ({line!r})"
            )
        for c, ch in enumerate(line):
            if ch == WALL:
                walls.append((r, c))
            elif ch == START:
                starts.append((r, c))
            elif ch == GOAL:
                goals.append((r, c))
            elif ch != FREE:
                raise MazeError(f"maze {name!r}: unknown character {ch!r} at row {r}, column {c}; use '#', '.', 'S' or 'G'")
    for what, found in (("start 'S'", starts), ("goal 'G'", goals)):
        if len(found) != 1:
            raise MazeError(f"maze {name!r} needs exactly one {what}, found {len(found)}" + (f" at {found}" if found else ""))
    start, goal = starts[0], goals[0]
    transitions = build_transitions(size, (r * size + c for r, c in walls))
    distance = distances_to(goal[0] * size + goal[1], transitions)[start[0] * size + start[1]]
    if distance == float("inf"):
        raise MazeError(f"maze {name!r}: the goal G at {goal} is unreachable from the start S at {start}; walls cut it off")
    return Maze(name, size, start, goal, tuple(walls))


def shipped_mazes() -> list[str]:
    """Names of the maps shipped with the package."""
    folder = resources.files("sb3_affect.envs") / "mazes"
    return sorted(p.name[:-4] for p in folder.iterdir() if p.name.endswith(".txt"))


def load_maze(maze: str | os.PathLike[str]) -> Maze:
    """
    A shipped map by name (``"rooms"``) or a user's map file by path (anything with a path separator or a ``.txt``).

    :raises MazeError: unknown name, unreadable file or an invalid map
    """
    text_name = os.fspath(maze)
    if os.sep in text_name or "/" in text_name or text_name.endswith(".txt") or os.path.exists(text_name):
        try:
            with open(text_name, "rb") as handle:
                data = handle.read(MAX_MAZE_BYTES + 1)
        except OSError as error:
            raise MazeError(f"can not read maze file {text_name!r}: {error}") from error
        if len(data) > MAX_MAZE_BYTES:
            raise MazeError(
                f"maze file {text_name!r} is more than {MAX_MAZE_BYTES:,} bytes: a map has at most {MAX_SIZE} x "
                f"{MAX_SIZE} cells"
            )
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as error:
            raise MazeError(f"maze file {text_name!r} is not UTF-8 text (byte {error.start}: {error.reason})") from None
        return parse_maze(text, text_name)
    resource = resources.files("sb3_affect.envs") / "mazes" / f"{text_name}.txt"
    if not resource.is_file():
        raise MazeError(f"unknown maze {text_name!r}: shipped mazes are {', '.join(shipped_mazes())}; or give a file path")
    return parse_maze(resource.read_text(encoding="utf-8"), text_name)


def maze_kwargs(maze: str | os.PathLike[str]) -> dict[str, Any]:
    """``GridPursuitEnv`` keyword arguments (size, start, goal, obstacles) of a shipped map or a map file."""
    return load_maze(maze).env_kwargs()
