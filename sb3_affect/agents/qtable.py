"""
The Python loop's view of the Q-table: rows made from the policy's tensor on first use and written back when asked,
so that ``learn`` on a large observation space holds the table plus the rows it has visited (not a Python list per
state of the whole table).
"""

from __future__ import annotations

from typing import TypeAlias

import numpy as np
import torch as th


class VisitedRows(dict):
    """
    ``rows[state]``: the Q-values of ``state`` as a Python list (what the loop reads and updates in place), read from
    ``table`` the first time the state is used. ``write_back`` copies the visited rows into ``table``.
    """

    def __init__(self, table: th.Tensor) -> None:
        super().__init__()
        self.table = table
        self.n_states = int(table.shape[0])

    def __missing__(self, state: int) -> list[float]:
        if not 0 <= state < self.n_states:
            raise IndexError(f"state {state} is outside the Q-table's {self.n_states} states")
        row: list[float] = self.table[state].tolist()
        self[state] = row
        return row

    def write_back(self) -> None:
        """Copy every visited row into the tensor (the one truth outside ``learn``)."""
        if self:
            # Through NumPy (the tensor's own memory): torch's indexed assignment may run on its thread pool, which
            # hangs in a process forked from one that used the pool (the launcher's workers).
            table = self.table.detach().numpy()
            states = np.fromiter(self.keys(), dtype=np.int64, count=len(self))
            table[states] = np.array(list(self.values()), dtype=table.dtype)

    def __repr__(self) -> str:
        return f"VisitedRows({len(self)} of {self.n_states} states)"



#: The Python loop's Q-table: every row (``tolist`` of the tensor) or the rows visited so far; ``q[state][action]``.
LoopTable: TypeAlias = "list[list[float]] | VisitedRows"
