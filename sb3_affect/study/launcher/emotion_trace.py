"""
Traced runs (an agent's ``trace: true`` in a sweep file): the affective agent's emotion and ``act`` recorded decision by
decision by ``TraceCallback`` and stored per episode as ``TRACE_COLUMNS`` beside the episode log's columns. The episode
log keeps counts only; the compiled engine does not call back, so a traced run runs on the Python loop, on its own.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sb3_affect.agents.callbacks import EmotionCallback
from sb3_affect.core.appraisal import Appraisal
from sb3_affect.core.emotions import Emotion
from sb3_affect.core.episode_log import TRACE_COLUMNS


class TraceCallback(EmotionCallback):
    """An ``EmotionCallback`` that keeps, per episode, ``TRACE_COLUMNS`` from each decision's emotion and ``act``."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        #: per finished episode: (first joy decision or NaN, act at it or NaN, joy's exits)
        self.episodes: list[tuple[float, float, int]] = []
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
        joy = np.asarray(self._sequence) == int(Emotion.JOY)
        first = int(np.argmax(joy)) if joy.any() else None
        exits = int((joy[:-1] & ~joy[1:]).sum())
        self.episodes.append((math.nan, math.nan, exits) if first is None else (float(first + 1), self._acts[first], exits))
        return counts, norm

    def trace_columns(self) -> dict[str, list[Any]]:
        """The episodes' ``TRACE_COLUMNS`` (``sb3_affect.core.episode_log``), as a run's record stores them."""
        return {name: [episode[i] for episode in self.episodes] for i, name in enumerate(TRACE_COLUMNS)}
