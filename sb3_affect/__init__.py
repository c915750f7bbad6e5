"""sb3-affect: affective tabular Q-learning (Badoy & Teknomo, "Q-Learning with Basic Emotions") for Stable-Baselines3."""

from sb3_affect.affectq import AffectQ
from sb3_affect.appraisal import Appraisal, Appraiser, KnownMap, PowerFit
from sb3_affect.behaviour import TABLE_III, Behaviour
from sb3_affect.broekens import BroekensCallback
from sb3_affect.callbacks import EmotionCallback
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
from sb3_affect.episode_log import EPISODE_COLUMNS
from sb3_affect.personalities import PERSONALITIES, PersonalityAppraiser
from sb3_affect.policies import TabularQPolicy
from sb3_affect.qlearning import QLearning
from sb3_affect.tabular import TabularQAlgorithm

register_envs()

__version__ = "0.1.0"

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
