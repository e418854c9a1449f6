"""Atomic file writes: readers see the old file or the complete new one, never a part.

The new content goes to a temporary file in the target's folder (same file system), is
flushed to disk, then renamed over the target with :func:`os.replace`. On any error the
temporary file is removed and the target is untouched.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from collections.abc import Iterator
from typing import IO, Any

__all__ = ["atomic_open", "atomic_write_text"]


@contextlib.contextmanager
def atomic_open(
    path: str | os.PathLike[str],
    mode: str = "w",
    *,
    encoding: str | None = "utf-8",
    newline: str | None = None,
) -> Iterator[IO[Any]]:
    """Open ``path`` for writing so that it is replaced only if the block succeeds.

    ``mode`` is ``"w"`` (text, default) or ``"wb"`` (binary). ``encoding`` and
    ``newline`` are as for :func:`open` and ignored in binary mode; pass
    ``newline=""`` for the :mod:`csv` module. An existing target keeps its permissions;
    a new one gets the usual ``0o666 & ~umask``.
    """
    if mode not in ("w", "wt", "wb"):
        raise ValueError(f'atomic_open mode must be "w" or "wb", got {mode!r}')
    target = os.fspath(path)
    folder, name = os.path.split(os.path.abspath(target))
    temp, fd = _create_temp(folder, name)
    try:
        try:
            if mode == "wb":
                file: IO[Any] = os.fdopen(fd, "wb")
            else:
                file = os.fdopen(fd, "w", encoding=encoding, newline=newline)
        except BaseException:
            os.close(fd)
            raise
        with file:
            yield file
            file.flush()
            os.fsync(file.fileno())
        _copy_mode(target, temp)
        os.replace(temp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str, *, encoding: str = "utf-8") -> None:
    """Replace ``path`` with ``text`` atomically, written verbatim (no newline translation)."""
    with atomic_open(path, "w", encoding=encoding, newline="") as file:
        file.write(text)


def _create_temp(folder: str, name: str) -> tuple[str, int]:
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0)
    while True:
        temp = os.path.join(folder, f".{name}.{secrets.token_hex(6)}.tmp")
        try:
            return temp, os.open(temp, flags, 0o666)
        except FileExistsError:
            continue


def _copy_mode(target: str, temp: str) -> None:
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        return
    with contextlib.suppress(OSError):
        os.chmod(temp, mode)
