"""The emotions and Table II (Sec. III): which emotion an appraisal gives."""

from __future__ import annotations

from collections.abc import Callable
from enum import IntEnum

from sb3_affect.core.appraisal import Appraisal, check_choice


class Emotion(IntEnum):
    """The four basic emotions of the paper (ints, so they index count lists in the hot loop)."""

    JOY = 0
    SADNESS = 1
    FEAR = 2
    ANGER = 3


EMOTION_NAMES: tuple[str, ...] = tuple(e.name.lower() for e in Emotion)
COMPARISONS = ("literal", "valence")

#: An emotion rule maps an appraisal (or ``None`` when there is nothing to appraise yet) to an emotion.
EmotionRule = Callable[[Appraisal | None], Emotion]


def table_ii(appraisal: Appraisal | None, comparison: str = "literal") -> Emotion:
    """
    Table II applied to the appraisal, first match wins:

    1. ``exp1 < norm`` -> fear
    2. ``act < norm`` and ``exp1 > act`` -> anger
    3. ``act < norm`` (``exp1 <= act``) -> sadness
    4. otherwise -> joy

    ``comparison="literal"`` compares the step counts as they are; ``"valence"`` compares their negations
    (Korsten & Taylor's values are rewards: fewer steps is better). No appraisal (first episode) -> joy.
    """
    if appraisal is None:
        return Emotion.JOY
    norm, exp1, act = appraisal
    if comparison == "valence":
        norm, exp1, act = -norm, -exp1, -act
    elif comparison != "literal":
        check_choice("comparison", comparison, COMPARISONS)
    if exp1 < norm:
        return Emotion.FEAR
    if act < norm:
        return Emotion.ANGER if exp1 > act else Emotion.SADNESS
    return Emotion.JOY


def make_table_ii(comparison: str = "literal") -> EmotionRule:
    """Table II as a one-argument rule for a fixed ``comparison`` option."""
    check_choice("comparison", comparison, COMPARISONS)

    def rule(appraisal: Appraisal | None) -> Emotion:
        return table_ii(appraisal, comparison)

    rule.__name__ = f"table_ii_{comparison}"
    rule.table_ii_comparison = comparison  # type: ignore[attr-defined]  # tells the compiled engine it is Table II
    return rule
