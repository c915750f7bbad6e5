"""
How the report writes (and reads back) its own files: each through a temporary file beside it, renamed over it when
whole (a reader never sees half a file, and a symbolic link at the file's name is replaced, never written through),
into folders that are real folders (a link in place of ``tables/`` or ``figures/`` is refused: the report never
writes where one points). A cache it wrote and can not read back is redone.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

from sb3_affect.study.launcher import regular_files


def output_folder(folder: Path) -> Path:
    """``folder``, created if missing; ``ValueError`` when it is a symbolic link (or not a folder)."""
    folder = Path(folder)
    if folder.is_symlink():
        raise ValueError(f"{folder} is a symbolic link; the report writes only into real folders: remove the link")
    folder.mkdir(parents=True, exist_ok=True)
    if not folder.is_dir():
        raise ValueError(f"{folder} is not a folder; the report writes its files there: remove it")
    return folder


def replacing(path: Path) -> contextlib.AbstractContextManager[Path]:
    """
    A temporary file beside ``path`` (same suffix, so writers infer the format) for the block to write; renamed over
    ``path`` when the block ends, removed when it raises (``regular_files.replacing``, in a real folder).
    """
    path = Path(path)
    return regular_files.replacing(output_folder(path.parent) / path.name)


def write_text(path: Path, text: str) -> None:
    """``path.write_text(text)``, through a temporary file (``replacing``)."""
    with replacing(path) as tmp:
        tmp.write_text(text)
