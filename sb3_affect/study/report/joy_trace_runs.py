"""
Tracing the affective agent decision by decision (``report.joy_trace`` reads the traces; this module runs them): an
``EmotionCallback`` that records each decision's emotion, on the Python loop (the compiled engine does not call back).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.core.appraisal import Appraisal
from sb3_affect.core.emotions import Emotion


class TraceCallback(EmotionCallback):
    """An ``EmotionCallback`` that keeps, per episode, the norm and each decision's emotion and ``act``."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.episodes: list[tuple[float, list[int], list[float]]] = []
        self._sequence: list[int] = []
        self._acts: list[float] = []
        rule = self.emotion_rule

        def recording(appraisal: Appraisal | None) -> Emotion:
            self._acts.append(math.nan if appraisal is None else float(appraisal.act))
            return rule(appraisal)

        self.emotion_rule = recording

    def begin_episode(self) -> None:
        super().begin_episode()
        self._sequence = []
        self._acts = []

    def feel(self, state: int) -> Emotion:
        emotion = super().feel(state)
        self._sequence.append(int(emotion))
        return emotion

    def end_episode(self, reached_goal: bool) -> tuple[list[int], float]:
        counts, norm = super().end_episode(reached_goal)
        self.episodes.append((norm, self._sequence, self._acts))
        return counts, norm


def trace(seed: int, episodes: int, env_kwargs: dict[str, Any] | None = None) -> pd.DataFrame:
    """
    One traced run: per episode the norm, decisions, joy decisions, the first joy decision, ``act`` at that decision
    (the cells the appraisal counts when the episode crosses the norm) and joy's exits.
    """
    import gymnasium as gym
    from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes

    from sb3_affect import AffectQ
    from sb3_affect.study.report.engine_studies import COMMON, PAPER_ENV

    env = gym.make(PAPER_ENV[0], **(env_kwargs or PAPER_ENV[1]))
    callback = TraceCallback()
    kwargs: dict[str, Any] = dict(COMMON)
    AffectQ("Grid", env, **kwargs, emotion_callback=callback, seed=seed).learn(
        10**9, callback=StopTrainingOnMaxEpisodes(episodes)
    )
    rows = []
    for number, (norm, sequence, acts) in enumerate(callback.episodes, start=1):
        joy = np.asarray(sequence) == int(Emotion.JOY)
        first = int(np.argmax(joy)) if joy.any() else None
        rows.append(
            {
                "seed": seed,
                "episode": number,
                "norm": norm,
                "decisions": len(joy),
                "joy": int(joy.sum()),
                "first_joy": np.nan if first is None else first + 1,
                "act_at_first_joy": np.nan if first is None else acts[first],
                "joy_exits": int((joy[:-1] & ~joy[1:]).sum()),
            }
        )
    return pd.DataFrame(rows)
