"""The one exception cuikslam raises for a bad input file: a log, a result, a truth file,
a dataset's ``.mat`` or text file.

Its message names the file and, when there is one, the line: ``trip.jsonl:12: ...``.
"""

from __future__ import annotations

import os

__all__ = ["InputFileError"]


class InputFileError(ValueError):
    """An input file that cannot be read, or that breaks its format.

    Attributes
    ----------
    path : str
        The file (or ``"<memory>"``) the problem is in.
    line : int or None
        1-based line of the offending record; ``None`` for whole-file problems
        (unreadable file, empty log, no prior).
    problem : str
        What is wrong, in one sentence, for a human.

    Examples
    --------
    >>> str(InputFileError("trip.jsonl", 12, "'range' must be [lo, hi]"))
    "trip.jsonl:12: 'range' must be [lo, hi]"
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
