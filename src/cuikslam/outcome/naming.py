"""Assignments up to renaming, and the names a solve gives the landmarks a hypothesis adds.

A hypothesis assigns a landmark to every observation. Two assignments are the same
hypothesis when they group the observations alike: landmarks the log names keep their
ids, the others are known only by the observations that see them. :func:`partition`
is that canonical form; :func:`display_names` names a hypothesis' own landmarks as a
solve reports them (``+1``, ``+2``, ...).

Examples
--------
>>> partition(["+1", "+2", "+1", "door"], named={"door"})
[0, 1, 0, 'door']
>>> partition(["a", "b", "a"]) == partition(["x", "y", "x"])
True
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Sequence

from cuikslam.log.records import Log
from cuikslam.outcome.solution import OUTLIER

__all__ = [
    "anonymous_names",
    "display_names",
    "named_landmarks",
    "new_mark",
    "partition",
]


def partition(assignment: Sequence[str], named: Collection[str] = frozenset()) -> list[int | str]:
    """The assignment up to renaming: a named landmark keeps its id, the others become
    the index of their first appearance among the unnamed ones.

    Parameters
    ----------
    assignment : sequence of str
        The landmark of each observation, in log order.
    named : collection of str
        Landmark ids the log itself gives (see :func:`named_landmarks`).

    Returns
    -------
    list of int or str
        Equal for two assignments exactly when they are the same hypothesis.
    """
    first: dict[str, int] = {}
    return [
        a if a in named or a == OUTLIER else first.setdefault(a, len(first)) for a in assignment
    ]


def new_mark(named: Collection[str]) -> str:
    """The prefix of the landmarks a hypothesis adds: ``"+"``, longer while one of the log's
    ids (``named``) starts with it.

    >>> new_mark({"A"}), new_mark({"+1", "B"})
    ('+', '++')
    """
    mark = "+"
    while any(name.startswith(mark) for name in named):
        mark += "+"
    return mark


def anonymous_names(named: Collection[str]) -> Iterator[str]:
    """Names for a hypothesis' unnamed landmarks, in order of first appearance: ``+1``,
    ``+2``, ... (the k-th landmark the hypothesis adds, as ``docs/result-format.md`` and
    the ``--survivors`` file name it), never one of the log's ids (``named``: the prefix
    is ``++`` when a log id starts with ``+``, see :func:`new_mark`).

    >>> from itertools import islice
    >>> list(islice(anonymous_names({"A", "N2"}), 3))
    ['+1', '+2', '+3']
    """
    mark = new_mark(named)
    count = 0
    while True:
        count += 1
        yield f"{mark}{count}"


def display_names(assignment: Sequence[str], named: Collection[str]) -> list[str]:
    """The assignment with its unnamed landmarks named as a solve reports them
    (:func:`anonymous_names`).

    >>> display_names(["+2", "A", "+1", "+2", "outlier"], {"A", "N1"})
    ['+1', 'A', '+2', '+1', 'outlier']
    """
    fresh = anonymous_names(named)
    names: dict[str, str] = {}
    for a in assignment:
        if a not in named and a != OUTLIER and a not in names:
            names[a] = next(fresh)
    return [names.get(a, a) for a in assignment]


def named_landmarks(log: Log) -> set[str]:
    """Landmark ids the log itself gives (named sightings and landmark priors)."""
    return {r.landmark for r in log.records if getattr(r, "landmark", None) is not None}
