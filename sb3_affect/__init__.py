"""sb3-affect: affective tabular Q-learning for Stable-Baselines3."""

from sb3_affect.envs import GRID_PURSUIT_ID, GridPursuitEnv, register_envs

register_envs()

__version__ = "0.1.0"

__all__ = ["GRID_PURSUIT_ID", "GridPursuitEnv", "__version__"]
