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


#: The registered time limit of the package's envs, in env steps (cells): the tabular agents' default decision cap
#: (``max_episode_decisions``, 20,000) at their highest speed (2 cells a decision), so that it never ends an episode
#: the agents' own cap would not, while every rollout and evaluation of other code (SB3's ``evaluate_policy``,
#: rl-zoo3) ends. ``gym.make(id, max_episode_steps=N)`` sets another.
MAX_EPISODE_STEPS = 40_000


def register_envs() -> None:
    """Register the package's envs with Gymnasium (idempotent), each with the time limit ``MAX_EPISODE_STEPS``."""
    if GRID_PURSUIT_ID not in registry:
        register(
            id=GRID_PURSUIT_ID,
            entry_point="sb3_affect.envs.grid_pursuit:GridPursuitEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
        )
    if MOVING_PURSUIT_ID not in registry:
        register(
            id=MOVING_PURSUIT_ID,
            entry_point="sb3_affect.envs.moving_pursuit:MovingPursuitEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
        )
    if MAZE_PURSUIT_ID not in registry:
        register(
            id=MAZE_PURSUIT_ID,
            entry_point="sb3_affect.envs.maze_pursuit:MazePursuitEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
        )


__all__ = [
    "ACTION_NAMES",
    "GRID_PURSUIT_ID",
    "HUNTER_PURSUIT_ID",
    "MAX_EPISODE_STEPS",
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
