"""
The episode log of a run, kept column by column (``EpisodeBlocks``): the one place every reader of a model's
episode rows goes through.

The compiled engine appends whole blocks of episodes as NumPy arrays (one array per column of ``EPISODE_COLUMNS``),
with no Python work per episode; the Python loop appends one row (a list) at a time into a small buffer, which
becomes a block when something reads the log column-wise. The DataFrame (``frame``) is made only when asked for. Model
files keep the log as a list of rows (``rows``), as they always have, so files of either layout load the same.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from sb3_affect.core.episode_log import EPISODE_COLUMNS, FLAG_COLUMNS, FLOAT_COLUMNS, INT_COLUMNS, make_frame

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["EpisodeBlocks"]

_INTS, _FLAGS, _FLOATS = INT_COLUMNS, FLAG_COLUMNS, FLOAT_COLUMNS
_INDEX = {name: i for i, name in enumerate(EPISODE_COLUMNS)}
_MAX_BLOCKS = 256


def _column(values: Sequence[Any]) -> np.ndarray:
    """One column of Python values as an array that gives the same values back (``tolist``): bool, int64, float64 or
    object (a mix of flags and NaN)."""
    kinds = {type(v) for v in values}
    if kinds <= {bool, np.bool_}:
        return np.array(values, dtype=np.bool_)
    if kinds <= {int, np.int64}:
        return np.array(values, dtype=np.int64)
    if kinds <= {float, np.float64}:
        return np.array(values, dtype=np.float64)
    return np.array(values, dtype=object)


class EpisodeBlocks:
    """
    A run's episode log: blocks of columns (``{column: array}``, all of one length) and a buffer of rows.

    ``len`` is the number of episodes; ``last()`` the last row; ``columns()`` the whole log as one array per column;
    ``frame()`` the DataFrame ``model.episode_log`` returns; ``rows()`` the log as lists (the saved form).
    """

    def __init__(self) -> None:
        self._blocks: list[dict[str, np.ndarray]] = []
        self._rows: list[list[Any]] = []
        self._count = 0

    @classmethod
    def from_rows(cls, rows: Iterable[Sequence[Any]]) -> EpisodeBlocks:
        """A log of the given rows (each in the order of ``EPISODE_COLUMNS``), e.g. read from a model file."""
        blocks = cls()
        for row in rows:
            blocks.append_row(list(row))
        return blocks

    def __len__(self) -> int:
        return self._count

    def append_row(self, row: list[Any]) -> None:
        """One episode's row, in the order of ``EPISODE_COLUMNS`` (the Python loop)."""
        self._rows.append(row)
        self._count += 1

    def append_columns(self, columns: Mapping[str, np.ndarray]) -> None:
        """A block of episodes, one array per column of ``EPISODE_COLUMNS`` (the compiled engine; arrays are kept)."""
        block = {name: columns[name] for name in EPISODE_COLUMNS}
        n = len(block["episode"])
        if any(len(values) != n for values in block.values()):
            raise ValueError("the columns of a block of episodes must all have the same length")
        if n:
            self._flush()
            self._blocks.append(block)
            self._count += n
            if len(self._blocks) >= _MAX_BLOCKS:  # many small blocks (one-episode chunks): join them now and then
                self.columns()

    def _flush(self) -> None:
        """The buffered rows as one block."""
        if self._rows:
            rows, self._rows = self._rows, []
            self._blocks.append({name: _column([row[i] for row in rows]) for i, name in enumerate(EPISODE_COLUMNS)})

    def last(self) -> list[Any]:
        """The last episode's row (Python values, in the order of ``EPISODE_COLUMNS``); IndexError when empty."""
        if self._rows:
            return self._rows[-1]
        if not self._blocks:
            raise IndexError("the episode log is empty")
        block = self._blocks[-1]
        return [block[name][-1:].tolist()[0] for name in EPISODE_COLUMNS]

    def value(self, name: str) -> Any:
        """One column's value in the last episode's row."""
        return self.last()[_INDEX[name]]

    def rows(self) -> list[list[Any]]:
        """Every row as a list of Python values (the form model files store)."""
        out: list[list[Any]] = []
        for block in self._blocks:
            out.extend(map(list, zip(*(block[name].tolist() for name in EPISODE_COLUMNS))))
        out.extend(list(row) for row in self._rows)
        return out

    def columns(self) -> dict[str, np.ndarray]:
        """The whole log, one array per column (the blocks joined; kept as one block from then on)."""
        self._flush()
        if len(self._blocks) > 1:
            self._blocks = [{name: np.concatenate([b[name] for b in self._blocks]) for name in EPISODE_COLUMNS}]
        if not self._blocks:
            return {name: np.empty(0) for name in EPISODE_COLUMNS}
        return dict(self._blocks[0])

    def frame(self) -> pd.DataFrame:
        """The log as ``model.episode_log`` gives it: typed columns, as ``episode_log.make_frame`` types rows."""
        import pandas as pd

        if not self._count:
            return make_frame([])
        frame = pd.DataFrame(self.columns(), copy=True)  # the frame never shares memory with the log
        for column in _INTS:
            frame[column] = frame[column].astype("int64")
        for column in _FLAGS:
            if frame[column].dtype == object and frame[column].notna().all():
                frame[column] = frame[column].astype(bool)
        for column in _FLOATS:
            frame[column] = frame[column].astype("float64")
        return frame
