"""
Reading ahead: the next part of a folder read in a background thread while the caller reduces the current one.

Reading a part is mostly work outside the interpreter's lock (Parquet decoding, the compiled moves of ``reading``), and
so is much of reducing one (numpy and compiled loops): on two cores the two overlap. One part is read ahead at most,
so memory holds two parts, never more; an error of the reader is raised in the caller, at the part it concerns.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

_T = TypeVar("_T")
_END = object()


def read_ahead(items: Iterable[_T]) -> Iterator[_T]:
    """``items`` in order, each next one made in a background thread while the caller works on the current one."""
    source = iter(items)
    with ThreadPoolExecutor(1, thread_name_prefix="read-ahead") as pool:
        pending = pool.submit(next, source, _END)
        while True:
            item = pending.result()
            if item is _END:
                return
            pending = pool.submit(next, source, _END)
            yield item  # type: ignore[misc]
            del item  # the caller's part is let go before the next one is waited for
