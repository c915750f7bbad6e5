"""Gymnasium environments of sb3-affect, installed as ``sb3_affect.envs``."""

from gymnasium.envs.registration import register, registry

from sb3_affect.envs.grid_pursuit import ACTION_NAMES, MOVES, GridPursuitEnv, build_transitions, distances_to
from sb3_affect.envs.maze import Maze, MazeError, load_maze, maze_kwargs, parse_maze, shipped_mazes
from sb3_affect.envs.maze_pursuit import MazePursuitEnv
from sb3_affect.envs.moving_pursuit import MovingPursuitEnv

GRID_PURSUIT_ID = "sb3_affect/GridPursuit-v0"
MOVING_PURSUIT_ID = "sb3_affect/MovingPursuit-v0"
MAZE_PURSUIT_ID = "sb3_affect/MazePursuit-v0"


def register_envs() -> None:
    """Register the package's envs with Gymnasium (idempotent)."""
    if GRID_PURSUIT_ID not in registry:
        register(id=GRID_PURSUIT_ID, entry_point="sb3_affect.envs.grid_pursuit:GridPursuitEnv")
    if MOVING_PURSUIT_ID not in registry:
        register(id=MOVING_PURSUIT_ID, entry_point="sb3_affect.envs.moving_pursuit:MovingPursuitEnv")
    if MAZE_PURSUIT_ID not in registry:
        register(id=MAZE_PURSUIT_ID, entry_point="sb3_affect.envs.maze_pursuit:MazePursuitEnv")


__all__ = [
    "ACTION_NAMES",
    "GRID_PURSUIT_ID",
    "MAZE_PURSUIT_ID",
    "MOVES",
    "MOVING_PURSUIT_ID",
    "GridPursuitEnv",
    "Maze",
    "MazeError",
    "MazePursuitEnv",
    "MovingPursuitEnv",
    "build_transitions",
    "distances_to",
    "load_maze",
    "maze_kwargs",
    "parse_maze",
    "register_envs",
    "shipped_mazes",
]
