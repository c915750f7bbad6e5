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
#: The orders in which Table II's rows are tried: as printed (fear first), or act's rows (anger, sadness) first.
ORDERS = ("table", "act-first")

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


def table_ii_act_first(appraisal: Appraisal | None, comparison: str = "valence") -> Emotion:
    """
    Table II's rows tried with act's first, a reading of this package's (not the paper's), first match wins:

    1. ``act < norm`` and ``exp1 > act`` -> anger
    2. ``act < norm`` (``exp1 <= act``) -> sadness
    3. ``exp1 < norm`` -> fear
    4. otherwise -> joy

    As printed, Table II makes sadness unreachable whatever the appraisal: rule 3 needs ``exp1 <= act < norm``, which
    rule 1 (``exp1 < norm``) has already taken. Here what has happened (act) is judged before what is expected (exp1).
    Under ``comparison="valence"`` with ``act="remaining"`` all four emotions occur: joy (the goal known within the
    norm, the episode within it), fear (the goal within the norm, but the episode has run past it), anger (the goal
    farther than the norm, and not yet as many steps spent) and sadness (the goal farther than the norm, and as many
    steps already spent). Under ``"literal"`` it gives only joy and anger, as Table II does.
    """
    if appraisal is None:
        return Emotion.JOY
    norm, exp1, act = appraisal
    if comparison == "valence":
        norm, exp1, act = -norm, -exp1, -act
    elif comparison != "literal":
        check_choice("comparison", comparison, COMPARISONS)
    if act < norm:
        return Emotion.ANGER if exp1 > act else Emotion.SADNESS
    if exp1 < norm:
        return Emotion.FEAR
    return Emotion.JOY


def make_table_ii(comparison: str = "literal", order: str = "table") -> EmotionRule:
    """Table II as a one-argument rule for a fixed ``comparison`` option and ``order`` (``ORDERS``)."""
    check_choice("comparison", comparison, COMPARISONS)
    check_choice("order", order, ORDERS)
    if order == "act-first":

        def act_first(appraisal: Appraisal | None) -> Emotion:
            return table_ii_act_first(appraisal, comparison)

        act_first.__name__ = f"table_ii_act_first_{comparison}"
        act_first.table_ii_reading = (comparison, order)  # type: ignore[attr-defined]
        return act_first

    def rule(appraisal: Appraisal | None) -> Emotion:
        return table_ii(appraisal, comparison)

    rule.__name__ = f"table_ii_{comparison}"
    rule.table_ii_comparison = comparison  # type: ignore[attr-defined]  # tells the compiled engine it is Table II
    rule.table_ii_reading = (comparison, order)  # type: ignore[attr-defined]
    return rule
