"""sb3-affect: affective tabular Q-learning (Badoy & Teknomo, "Q-Learning with Basic Emotions") for Stable-Baselines3.

``import sb3_affect`` registers the envs and imports neither torch nor Stable-Baselines3: the agents, the policy and
the callbacks (which need them) are imported on first use (``sb3_affect.AffectQ``, ``from sb3_affect import
QLearning``), so a sweep of tabular runs on the compiled engine never pays for torch.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from sb3_affect.core.appraisal import Appraisal, Appraiser, KnownMap, PowerFit
from sb3_affect.core.behaviour import TABLE_III, Behaviour
from sb3_affect.core.emotions import EMOTION_NAMES, Emotion, make_table_ii, table_ii
from sb3_affect.core.personalities import PERSONALITIES, PersonalityAppraiser
from sb3_affect.core.registry import AGENT_ENTRIES
from sb3_affect.envs import (
    GRID_PURSUIT_ID,
    MAZE_PURSUIT_ID,
    MOVING_PURSUIT_ID,
    GridPursuitEnv,
    MazePursuitEnv,
    MovingPursuitEnv,
    register_envs,
)

if TYPE_CHECKING:
    from sb3_affect.agents.affectq import AffectQ
    from sb3_affect.agents.broekens import BroekensCallback
    from sb3_affect.agents.callbacks import EmotionCallback
    from sb3_affect.agents.deep_affect import AffectDQN, AffectiveExploration
    from sb3_affect.agents.deep_affect_qrdqn import AffectQRDQN
    from sb3_affect.agents.deep_controls import (
        EzGreedyDQN,
        EzGreedyExploration,
        SpeedEpsilonGreedyDQN,
        SpeedEpsilonGreedyExploration,
    )
    from sb3_affect.agents.minigrid_tabular import TabularMiniGrid
    from sb3_affect.agents.minigrid_vec_env import minigrid_vec_env
    from sb3_affect.agents.policies import TabularQPolicy
    from sb3_affect.agents.qlearning import QLearning
    from sb3_affect.agents.tabular import TabularQAlgorithm
    from sb3_affect.core.episode_log import EPISODE_COLUMNS
    from sb3_affect.engine.many_seeds import train_many

register_envs()

__version__ = "0.1.0"

#: Public names imported on first use (PEP 562): they import torch and SB3 (or pandas). The agents' come from their
#: entries in the registry (``sb3_affect.core.registry.AGENT_ENTRIES``); the names above are for type checkers.
_LAZY: dict[str, str] = {
    **{name: entry.module for entry in AGENT_ENTRIES for name in entry.exports},
    "BroekensCallback": "sb3_affect.agents.broekens",
    "EmotionCallback": "sb3_affect.agents.callbacks",
    "EPISODE_COLUMNS": "sb3_affect.core.episode_log",
    "TabularQPolicy": "sb3_affect.agents.policies",
    "TabularMiniGrid": "sb3_affect.agents.minigrid_tabular",
    "minigrid_vec_env": "sb3_affect.agents.minigrid_vec_env",
    "TabularQAlgorithm": "sb3_affect.agents.tabular",
    "train_many": "sb3_affect.engine.many_seeds",
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
    "AffectDQN",
    "AffectQ",
    "AffectQRDQN",
    "AffectiveExploration",
    "Appraisal",
    "Appraiser",
    "Behaviour",
    "BroekensCallback",
    "Emotion",
    "EmotionCallback",
    "EzGreedyDQN",
    "EzGreedyExploration",
    "GridPursuitEnv",
    "KnownMap",
    "MazePursuitEnv",
    "MovingPursuitEnv",
    "PersonalityAppraiser",
    "PowerFit",
    "QLearning",
    "SpeedEpsilonGreedyDQN",
    "SpeedEpsilonGreedyExploration",
    "TabularMiniGrid",
    "TabularQAlgorithm",
    "TabularQPolicy",
    "__version__",
    "make_table_ii",
    "minigrid_vec_env",
    "table_ii",
    "train_many",
]
