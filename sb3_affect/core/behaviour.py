"""Table III (Sec. III): how each emotion sets the direction and the speed of a decision."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

from sb3_affect.core.emotions import Emotion


class Behaviour(NamedTuple):
    """
    :param random_direction: ``True``: the direction is drawn uniformly at random; ``False``: greedy (ties at random)
    :param speeds: cells moved this decision, drawn uniformly from these (0 is a wait)
    """

    random_direction: bool
    speeds: tuple[int, ...]


#: Table III with the project's speeds (docs/definitions.md): "fast" = 1 or 2 cells, "slow" = 0 or 1 cell.
TABLE_III: dict[Emotion, Behaviour] = {
    Emotion.JOY: Behaviour(random_direction=True, speeds=(1, 2)),
    Emotion.SADNESS: Behaviour(random_direction=False, speeds=(0, 1)),
    Emotion.FEAR: Behaviour(random_direction=False, speeds=(0, 1)),
    Emotion.ANGER: Behaviour(random_direction=False, speeds=(1, 2)),
}


#: Table III with its directions swapped (joy greedy; sadness, fear and anger random), the speeds kept: the opposite
#: hypothesis of Broekens et al. 2007 (positive affect exploits, negative affect explores).
TABLE_III_REVERSED: dict[Emotion, Behaviour] = {
    emotion: Behaviour(not behaviour.random_direction, behaviour.speeds) for emotion, behaviour in TABLE_III.items()
}

#: Behaviour tables by name: what ``behaviour_table=`` takes as a string (a sweep file names a table this way).
BEHAVIOUR_TABLES: dict[str, dict[Emotion, Behaviour]] = {"table-iii": TABLE_III, "table-iii-reversed": TABLE_III_REVERSED}


def stored_behaviour_table(table: Mapping[Any, Any] | str | None) -> dict[str, list]:
    """
    A user's table (None: Table III; a name of ``BEHAVIOUR_TABLES``), checked, as the plain data a model saves:
    ``{"joy": [random, speeds], ...}``.
    """
    if isinstance(table, str):
        if table not in BEHAVIOUR_TABLES:
            raise ValueError(f"behaviour_table={table!r} is not a named table; the names are {', '.join(BEHAVIOUR_TABLES)}")
        table = BEHAVIOUR_TABLES[table]
    checked = validate_behaviour_table(TABLE_III if table is None else table)
    return {emotion.name.lower(): list(behaviour) for emotion, behaviour in checked.items()}


def behaviour_by_emotion(stored: Mapping[str, Any]) -> list[Behaviour]:
    """A saved table (``stored_behaviour_table``) as a list indexed by emotion, for the hot loop."""
    return [Behaviour(bool(r), tuple(int(k) for k in speeds)) for r, speeds in (stored[e.name.lower()] for e in Emotion)]


#: The most cells a decision may move (each cell is one env step; the largest grid is 1,000 cells wide).
MAX_SPEED = 10_000


def validate_behaviour_table(table: Mapping[Any, Any]) -> dict[Emotion, Behaviour]:
    """
    Check a user's emotion-to-behaviour table: one entry per emotion, keyed by ``Emotion`` or by its name (``"joy"``,
    as a sweep file writes it), each ``Behaviour(random_direction, speeds)`` or ``[random_direction, speeds]``, speeds
    non-empty ints >= 0.
    """
    if not isinstance(table, Mapping):
        raise TypeError(f"behaviour_table must be a mapping from Emotion to Behaviour, got {type(table).__name__}")
    names = {emotion.name.lower() for emotion in Emotion}
    unknown = [key for key in table if key not in set(Emotion) and key not in names]
    if unknown:
        raise ValueError(f"behaviour_table: {unknown[0]!r} is not an emotion; the keys are joy, sadness, fear, anger")
    checked: dict[Emotion, Behaviour] = {}
    for emotion in Emotion:
        key: Emotion | str = emotion if emotion in table else emotion.name.lower()
        if key not in table:
            raise ValueError(
                f"behaviour_table has no entry for {emotion.name.lower()}; it needs all of joy, sadness, fear, anger"
            )
        entry = table[key]
        if isinstance(entry, (str, bytes)) or not isinstance(entry, Sequence) or len(entry) != 2 or isinstance(
                entry[1], (str, bytes)) or not isinstance(entry[1], Sequence):
            raise ValueError(
                f"behaviour_table[{emotion.name.lower()}]={repr(entry)[:80]} is invalid: use Behaviour(random_direction, "
                "speeds) or [random_direction, speeds] (a bool and a list of ints)"
            )
        random_direction, speeds = Behaviour(*entry)
        speeds = tuple(speeds)
        if not speeds or not all(isinstance(k, int) and not isinstance(k, bool) and 0 <= k <= MAX_SPEED for k in speeds):
            raise ValueError(
                f"behaviour_table[{emotion.name.lower()}].speeds={speeds!r} is invalid: use a non-empty tuple of ints "
                f"in [0, {MAX_SPEED:,}]"
            )
        checked[emotion] = Behaviour(bool(random_direction), speeds)
    return checked
