"""What the subcommands share: the user-facing error and checked, atomic output files.

Kept apart from :mod:`cuikslam.cli.main` so that ``python -m cuikslam.cli.main`` (where
``main`` runs as ``__main__``) and the subcommand modules raise and catch the same
:class:`CommandError` class.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

__all__ = [
    "EXIT_INPUT",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_RESULT",
    "FIGURE_SUFFIXES",
    "STARTED",
    "CommandError",
    "check_figure_path",
    "check_output_path",
    "int_at_least",
    "limit_or_none",
    "positive_float",
    "progress_bar",
    "write_output",
]


STARTED = time.perf_counter()
"""When the command started (near enough: :mod:`cuikslam.cli.main` imports this module
before anything slow)."""

EXIT_OK = 0
EXIT_RESULT = 1
"""The result itself reports a problem (an inconsistent log, a box that misses the truth)."""
EXIT_INPUT = 2
"""Bad input or usage."""
EXIT_INTERRUPTED = 130
"""Ctrl-C (the shell's code for SIGINT); a search it stopped still wrote its result."""


class CommandError(Exception):
    """A user-facing failure: printed as one line, exit status 2."""


def check_output_path(path: str | os.PathLike[str]) -> None:
    """Fail early, naming ``path``, when a file cannot be created there.

    Called before any work is done so that a typo in an output path costs nothing and
    leaves nothing behind.
    """
    target = Path(path)
    if target.is_dir():
        raise CommandError(f"{path}: cannot write: it is a directory")
    folder = target.parent
    if not folder.exists():
        raise CommandError(f"{path}: cannot write: the folder {folder} does not exist")
    if not folder.is_dir():
        raise CommandError(f"{path}: cannot write: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise CommandError(f"{path}: cannot write: no permission to create files in {folder}")


FIGURE_SUFFIXES = (".png", ".pdf", ".svg")
"""Figure formats ``save_figure`` writes (chosen by the file's suffix)."""


def check_figure_path(path: str | os.PathLike[str]) -> None:
    """:func:`check_output_path`, and the suffix names a figure format we can write."""
    if Path(path).suffix.lower() not in FIGURE_SUFFIXES:
        raise CommandError(
            f"{path}: cannot tell the image format from the name; "
            f"end it with {', '.join(FIGURE_SUFFIXES)}"
        )
    check_output_path(path)


def write_output(path: str | os.PathLike[str], write: Callable[[], None]) -> None:
    """Run ``write`` (an atomic write of ``path``); an OSError names ``path``, not the
    temporary file the atomic write was using."""
    try:
        write()
    except OSError as err:
        raise CommandError(f"{path}: cannot write: {err.strerror or err}") from None


@contextmanager
def progress_bar(
    description: str, *, enabled: bool = True
) -> Iterator[Callable[[int, int], None] | None]:
    """A rich progress bar on stderr when it is a terminal; ``None`` (no bar) otherwise.

    Yields the ``progress(done, total, status=None)`` callback that long solves call as
    they advance; a correspondence search's status (``SearchProgress``: readings decided,
    survivors found and proven, subtrees pending) is shown beside the bar.
    """
    if not (enabled and sys.stderr.isatty()):
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    with Progress(
        f"[bold]{description}",
        BarColumn(bar_width=24),
        MofNCompleteColumn(),
        TextColumn("{task.fields[note]}"),
        TimeElapsedColumn(),
        console=Console(stderr=True),  # stdout may be a result being piped
        transient=True,
        redirect_stdout=False,
        redirect_stderr=False,
    ) as bar:
        task = bar.add_task(description, total=None, note="")

        def advance(done: int, total: int, status: Any = None) -> None:
            note = "" if status is None else status.short()
            bar.update(task, completed=done, total=total, note=note)

        yield advance


def int_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer of at least ``minimum``."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be at least {minimum}, got {value}")
        return value

    return parse


def positive_float(text: str) -> float:
    """An argparse type: a positive finite number."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"must be a positive finite number, got {text}")
    return value


def limit_or_none(text: str, unit: str) -> float | None:
    """An argparse type's body: a positive number of ``unit``, or None (no limit) for
    ``none``, ``inf`` or ``infinity``."""
    if text.strip().lower() in ("none", "inf", "infinity"):
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number of {unit}: {text!r}") from None
    if not value > 0 or math.isnan(value):
        raise argparse.ArgumentTypeError(f"must be a positive number of {unit}, got {text}")
    return None if math.isinf(value) else value
