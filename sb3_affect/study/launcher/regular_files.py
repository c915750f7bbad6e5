"""
The one rule for every file the study reads from a folder it did not write just now (results folders, forensics
folders, replications, sweep records): a regular file only, never a symbolic link (a link may lead out of the folder,
to ``/dev/zero`` or to another user's file), a FIFO, a device or a folder. Each is checked with ``os.lstat`` before
it is opened, and opened without following a link and without blocking (a FIFO put there between the check and the
open does not hang the reader), then checked again on the open file. Anything else is an ``UnreadableFile``: one
line naming the file and what it is.

It also holds the one way the study writes a file (``replacing``, ``write_file``; many at once, ``write_files``): a
unique temporary name in the same folder, written, synced to disk, then renamed over the file: a reader, even after a
crash or with a second writer at work, sees a whole file or none, and a symbolic link at the file's name is replaced,
never written through.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any


class UnreadableFile(ValueError):
    """A file the study does not read (not a regular file, too large, or unreadable); its text names the file."""

    def __init__(self, path: Path | str, reason: str) -> None:
        super().__init__(f"{path}: {reason}")
        self.path = Path(path)
        self.reason = reason


_NOT_REGULAR = "is not a regular file ({what}); only regular files are read, never links, FIFOs, devices or folders"


def _kind(mode: int) -> str:
    for test, what in (
        (stat.S_ISLNK, "a symbolic link"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISCHR, "a device"),
        (stat.S_ISBLK, "a device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return what
    return "not a file"


def check_regular(path: Path | str, limit: int | None = None, root: Path | str | None = None) -> os.stat_result:
    """
    ``path``'s ``os.lstat`` when it is a regular file of at most ``limit`` bytes (None: any size) and, given ``root``,
    inside ``root`` once every link of its folders is followed; otherwise ``UnreadableFile`` (a missing file too:
    ``reason`` "does not exist").
    """
    if root is not None and not Path(os.path.realpath(path)).is_relative_to(os.path.realpath(root)):
        raise UnreadableFile(path, f"lies outside {root} (a folder on its way is a link); only files inside it are read")
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        raise UnreadableFile(path, "does not exist") from None
    except OSError as error:
        raise UnreadableFile(path, f"can not be read ({error.strerror or error})") from None
    if not stat.S_ISREG(info.st_mode):
        raise UnreadableFile(path, _NOT_REGULAR.format(what=_kind(info.st_mode)))
    if limit is not None and info.st_size > limit:
        raise UnreadableFile(path, f"is {info.st_size:,} bytes, more than the {limit:,} a file of this kind can be")
    return info


def open_regular(path: Path | str, limit: int | None = None, root: Path | str | None = None) -> IO[bytes]:
    """``path`` opened for reading in binary, after ``check_regular`` (no link followed, never blocking on a FIFO)."""
    check_regular(path, limit, root)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as error:
        raise UnreadableFile(path, f"can not be read ({error.strerror or error})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):  # replaced between the check and the open
        os.close(fd)
        raise UnreadableFile(path, _NOT_REGULAR.format(what=_kind(info.st_mode)))
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


def read_bytes(path: Path | str, limit: int | None = None, root: Path | str | None = None) -> bytes:
    """The bytes of a regular file (``open_regular``), at most ``limit``."""
    with open_regular(path, limit, root) as handle:
        data = handle.read() if limit is None else handle.read(limit + 1)
    if limit is not None and len(data) > limit:
        raise UnreadableFile(path, f"is more than the {limit:,} bytes a file of this kind can be")
    return data


def read_json(path: Path | str, limit: int | None = None, root: Path | str | None = None) -> Any:
    """The JSON of a regular file; ``UnreadableFile`` when it is not one or is not JSON."""
    data = read_bytes(path, limit, root)
    try:
        return json.loads(data)
    except (ValueError, UnicodeDecodeError) as error:
        raise UnreadableFile(path, f"is not valid JSON ({' '.join(str(error).split())})") from None


def read_text(path: Path | str, limit: int | None = None) -> str:
    """The UTF-8 text of a regular file."""
    try:
        return read_bytes(path, limit).decode()
    except UnicodeDecodeError as error:
        raise UnreadableFile(path, f"is not UTF-8 text ({error})") from None


@contextlib.contextmanager
def replacing(path: Path | str) -> Iterator[Path]:
    """
    A new temporary file beside ``path`` (a unique name, ``path``'s suffix so writers infer the format) for the block
    to write; synced and renamed over ``path`` when the block ends, removed when it raises (``OSError`` passes on).
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:  # a full disk, or Ctrl-C mid-write: never leave a partial file behind
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_file(path: Path | str, data: bytes | str) -> None:
    """``path`` holding ``data`` (text: UTF-8), written through ``replacing``."""
    with replacing(path) as tmp:
        tmp.write_bytes(data.encode() if isinstance(data, str) else data)


def write_files(files: Sequence[tuple[Path, bytes]]) -> None:
    """
    Many files at once, as ``write_file`` writes one: each to a unique temporary name beside it, the file system synced
    once (instead of once per file), then each renamed into place; every temporary file removed when one fails.
    """
    temporary: list[str] = []
    try:
        for path, data in files:
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=path.suffix)
            temporary.append(tmp)
            with os.fdopen(fd, "wb") as handle:
                handle.write(data)
        os.sync()
        for (path, _), tmp in zip(files, temporary):
            os.replace(tmp, path)
    except BaseException:  # a full disk, or Ctrl-C mid-write: never leave a partial file behind
        for tmp in temporary:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise
