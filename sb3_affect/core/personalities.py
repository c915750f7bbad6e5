"""
Personalities: optimistic and pessimistic variants of the appraisal (the paper's Sec. VI future work).

A personality is a bias on the appraisal's ``norm``, the number of steps the agent expects an episode to take
(the power-law trend of its past episodes). An *optimistic* agent expects to do better than its history says
(``norm`` scaled down, ``norm_scale < 1``); a *pessimistic* one expects to do worse (``norm_scale > 1``). ``exp1 =
max(norm, elapsed)`` uses the biased norm; ``act`` is unchanged. The bias is applied at each episode start, after
the regression, so the history itself stays unbiased.

What it does to the emotions, under the default (``comparison="literal"``) reading of Table II, where joy is felt
when ``act >= norm`` and anger or sadness when ``act < norm``: the optimist's lower norm is reached sooner, so it
feels more joy (and explores more, joy's direction being random); the pessimist's higher norm leaves ``act`` below
it for longer, so it feels more anger and sadness (greedy moves) and less joy. Fear (``exp1 < norm``) can not occur
under the literal reading whatever the bias. Under ``comparison="valence"`` the directions flip (joy when
``act <= norm``), so there the pessimist feels more joy; the presets keep the same meaning (the expectation), not the
same emotion profile.

Use a preset by name: ``AffectQ("Grid", env, personality="optimistic")`` (saved with the model), or pass an
appraiser directly: ``AffectQ(..., emotion_callback=EmotionCallback(appraiser=PersonalityAppraiser(n, norm_scale=0.5)))``.
"""

from __future__ import annotations

import math
from typing import Any

from sb3_affect.core.appraisal import Appraiser

#: Named presets: personality -> norm scale.
PERSONALITIES: dict[str, float] = {"neutral": 1.0, "optimistic": 0.8, "pessimistic": 1.25}


def check_personality(name: Any) -> str:
    """Return ``name`` if it is a preset; otherwise raise a ValueError listing them."""
    if name not in PERSONALITIES:
        raise ValueError(f"personality={name!r} is not supported; choose one of {', '.join(map(repr, PERSONALITIES))}")
    return str(name)


class PersonalityAppraiser(Appraiser):
    """
    An ``Appraiser`` whose norm is scaled by ``norm_scale`` (see the module docstring).

    :param n_states: number of cells (Discrete observation size)
    :param act: ``"episode"`` or ``"remaining"``
    :param units: ``"cells"`` or ``"decisions"``
    :param norm_scale: the bias, > 0: below 1 optimistic, above 1 pessimistic, 1 neutral
    """

    def __init__(self, n_states: int, act: str = "episode", units: str = "cells", norm_scale: float = 1.0) -> None:
        if isinstance(norm_scale, bool) or not isinstance(norm_scale, (int, float)) or not 0 < norm_scale < math.inf:
            raise ValueError(f"norm_scale={norm_scale!r} must be a finite number > 0")
        super().__init__(n_states, act=act, units=units)
        self.norm_scale = float(norm_scale)

    @classmethod
    def preset(cls, personality: str, n_states: int, act: str = "episode", units: str = "cells") -> PersonalityAppraiser:
        """The appraiser of a named preset (``PERSONALITIES``)."""
        return cls(n_states, act=act, units=units, norm_scale=PERSONALITIES[check_personality(personality)])

    def start_episode(self) -> None:
        super().start_episode()
        self.norm *= self.norm_scale  # NaN (nothing known yet) stays NaN

    def get_state(self) -> dict[str, Any]:
        return {**super().get_state(), "norm_scale": self.norm_scale}

    def set_state(self, state: dict[str, Any]) -> None:
        super().set_state(state)
        self.norm_scale = float(state.get("norm_scale", self.norm_scale))
