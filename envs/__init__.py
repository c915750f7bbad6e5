"""Gymnasium environments of sb3-affect, installed as ``sb3_affect.envs``."""

from typing import Any

from gymnasium.envs.registration import register, registry

from sb3_affect.envs.grid_pursuit import ACTION_NAMES, MOVES, GridPursuitEnv, build_transitions, distances_to
from sb3_affect.envs.maze import Maze, MazeError, load_maze, maze_kwargs, parse_maze, shipped_mazes
from sb3_affect.envs.maze_pursuit import MazePursuitEnv
from sb3_affect.envs.moving_pursuit import MovingPursuitEnv
from sb3_affect.envs.transition_table import TransitionTable

GRID_PURSUIT_ID = "sb3_affect/GridPursuit-v0"
MOVING_PURSUIT_ID = "sb3_affect/MovingPursuit-v0"
MAZE_PURSUIT_ID = "sb3_affect/MazePursuit-v0"
HUNTER_PURSUIT_ID = "sb3_affect/HunterPursuit-v0"

#: Multi-agent (PettingZoo ``ParallelEnv``) envs by id: ``"module:factory"``. Gymnasium's registry holds single-agent
#: envs only, so the package keeps this small one; ``make_parallel`` builds from it.
PARALLEL_ENVS: dict[str, str] = {HUNTER_PURSUIT_ID: "sb3_affect.envs.hunter_pursuit:HunterPursuitEnv"}


def make_parallel(env_id: str, **kwargs: Any) -> Any:
    """
    Build a registered multi-agent env: ``make_parallel("sb3_affect/HunterPursuit-v0")`` is Kuremoto's layout
    (17 x 17, prey at (9, 9), hunters from (2, 2) and (14, 14)); keywords change it.
    """
    import importlib

    if env_id not in PARALLEL_ENVS:
        raise ValueError(f"multi-agent env id {env_id!r} is not registered; known: {', '.join(sorted(PARALLEL_ENVS))}")
    module, _, name = PARALLEL_ENVS[env_id].partition(":")
    return getattr(importlib.import_module(module), name)(**kwargs)


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
    "HUNTER_PURSUIT_ID",
    "MAZE_PURSUIT_ID",
    "MOVES",
    "MOVING_PURSUIT_ID",
    "PARALLEL_ENVS",
    "GridPursuitEnv",
    "Maze",
    "MazeError",
    "MazePursuitEnv",
    "MovingPursuitEnv",
    "TransitionTable",
    "build_transitions",
    "distances_to",
    "load_maze",
    "make_parallel",
    "maze_kwargs",
    "parse_maze",
    "register_envs",
    "shipped_mazes",
]
