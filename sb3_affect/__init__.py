"""sb3-affect: affective tabular Q-learning (Badoy & Teknomo, "Q-Learning with Basic Emotions") for Stable-Baselines3.

``import sb3_affect`` registers the envs and imports neither torch nor Stable-Baselines3: the agents, the policy and
the callbacks (which need them) are imported on first use (``sb3_affect.AffectQ``, ``from sb3_affect import
QLearning``), so a sweep of tabular runs on the compiled engine never pays for torch.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from sb3_affect.appraisal import Appraisal, Appraiser, KnownMap, PowerFit
from sb3_affect.behaviour import TABLE_III, Behaviour
from sb3_affect.emotions import EMOTION_NAMES, Emotion, make_table_ii, table_ii
from sb3_affect.envs import (
    GRID_PURSUIT_ID,
    MAZE_PURSUIT_ID,
    MOVING_PURSUIT_ID,
    GridPursuitEnv,
    MazePursuitEnv,
    MovingPursuitEnv,
    register_envs,
)
from sb3_affect.personalities import PERSONALITIES, PersonalityAppraiser

if TYPE_CHECKING:
    from sb3_affect.affectq import AffectQ
    from sb3_affect.broekens import BroekensCallback
    from sb3_affect.callbacks import EmotionCallback
    from sb3_affect.episode_log import EPISODE_COLUMNS
    from sb3_affect.policies import TabularQPolicy
    from sb3_affect.qlearning import QLearning
    from sb3_affect.tabular import TabularQAlgorithm

register_envs()

__version__ = "0.1.0"

#: Public names imported on first use (PEP 562): they import torch and SB3 (or pandas).
_LAZY: dict[str, str] = {
    "AffectQ": "sb3_affect.affectq",
    "BroekensCallback": "sb3_affect.broekens",
    "EmotionCallback": "sb3_affect.callbacks",
    "EPISODE_COLUMNS": "sb3_affect.episode_log",
    "TabularQPolicy": "sb3_affect.policies",
    "QLearning": "sb3_affect.qlearning",
    "TabularQAlgorithm": "sb3_affect.tabular",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'sb3_affect' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


__all__ = [
    "EMOTION_NAMES",
    "EPISODE_COLUMNS",
    "GRID_PURSUIT_ID",
    "MAZE_PURSUIT_ID",
    "MOVING_PURSUIT_ID",
    "PERSONALITIES",
    "TABLE_III",
    "AffectQ",
    "Appraisal",
    "Appraiser",
    "Behaviour",
    "BroekensCallback",
    "Emotion",
    "EmotionCallback",
    "GridPursuitEnv",
    "KnownMap",
    "MazePursuitEnv",
    "MovingPursuitEnv",
    "PersonalityAppraiser",
    "PowerFit",
    "QLearning",
    "TabularQAlgorithm",
    "TabularQPolicy",
    "__version__",
    "make_table_ii",
    "table_ii",
]
