"""The one exception the log layer raises for bad input."""

from __future__ import annotations

import os

__all__ = ["LogFormatError"]


class LogFormatError(ValueError):
    """A log file that cannot be read, or that breaks the log format.

    Attributes
    ----------
    path : str
        The file (or ``"<memory>"``) the problem is in.
    line : int or None
        1-based line of the offending record; ``None`` for whole-file problems
        (unreadable file, empty log, no prior).
    problem : str
        What is wrong, in one sentence, for a human.
    """

    def __init__(self, path: str | os.PathLike[str], line: int | None, problem: str) -> None:
        super().__init__(os.fspath(path), line, problem)
        self.path = os.fspath(path)
        self.line = line
        self.problem = problem

    def __str__(self) -> str:
        if self.line is None:
            return f"{self.path}: {self.problem}"
        return f"{self.path}:{self.line}: {self.problem}"
