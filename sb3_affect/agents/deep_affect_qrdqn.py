"""``AffectQRDQN``: sb3-contrib's QR-DQN exploring with the emotions (``sb3_affect.agents.deep_affect``); needs sb3-contrib."""

from __future__ import annotations

try:
    from sb3_contrib import QRDQN
except ImportError:  # pragma: no cover - depends on what is installed
    raise ImportError("AffectQRDQN needs sb3-contrib: pip install sb3-contrib") from None

from sb3_affect.agents.deep_affect import AffectiveExploration


class AffectQRDQN(AffectiveExploration, QRDQN):
    """
    sb3-contrib's QR-DQN whose exploration is the paper's emotions instead of epsilon: each env's emotion chooses a
    random (joy) or greedy action (the largest mean of the quantiles) and how many env steps it lasts. Arguments:
    QRDQN's (without ``exploration_*``) and ``behaviour_table``, ``emotion_callback``, ``position``, ``wait_action``
    (``sb3_affect.agents.deep_affect.AffectiveExploration``).
    """
