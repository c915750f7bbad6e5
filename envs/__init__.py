"""Gymnasium environments of sb3-affect, installed as ``sb3_affect.envs``."""

from gymnasium.envs.registration import register, registry
from sb3_affect.envs.grid_pursuit import ACTION_NAMES, MOVES, GridPursuitEnv, build_transitions, distances_to

GRID_PURSUIT_ID = "sb3_affect/GridPursuit-v0"


def register_envs() -> None:
    """Register the package's envs with Gymnasium (idempotent)."""
    if GRID_PURSUIT_ID not in registry:
        register(id=GRID_PURSUIT_ID, entry_point="sb3_affect.envs.grid_pursuit:GridPursuitEnv")


__all__ = ["ACTION_NAMES", "GRID_PURSUIT_ID", "MOVES", "GridPursuitEnv", "build_transitions", "distances_to", "register_envs"]
