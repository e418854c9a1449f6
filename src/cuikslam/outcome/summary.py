"""What the surviving hypotheses agree on, and how their disagreements factor.

A user of an unknown-correspondence solve first wants to know: which observations are
associated for certain, which are ambiguous and between what, and whether the ambiguities
interact. Each observation is described by the observation it *follows*: the previous
observation of the same landmark (or the named landmark itself, or nothing when it is the
landmark's first sighting). That description changes only where two hypotheses differ,
so independent ambiguities stay apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuikslam.outcome.solution import OUTLIER, Solution

__all__ = [
    "NEW",
    "Ambiguity",
    "CorrespondenceSummary",
    "ambiguous_observations",
    "describe",
    "summarize",
    "summary_from_json",
    "summary_holds",
    "summary_to_json",
]

NEW = "new"
"""An observation that is the first sighting of an anonymous landmark."""


@dataclass
class Ambiguity:
    """A group of observations whose associations vary together, independently of the rest."""

    observations: list[int]
    """Indices of the observations (in log order)."""
    choices: list[list[str]]
    """The distinct joint choices: for each, what every observation of the group follows."""


@dataclass
class CorrespondenceSummary:
    """Agreement across survivors (see :func:`summarize`)."""

    follows: list[list[str]]
    """For each observation, what it can follow across the survivors: ``"#j"`` (the
    observation j saw the same landmark last), a named landmark's id, ``"new"``, or
    ``"outlier"`` (it sees nothing: an ``outliers`` declaration)."""
    certain: list[bool]
    """True where every survivor agrees."""
    factors: list[Ambiguity]
    """Independent groups of ambiguous observations: the survivors are exactly every
    combination of one choice per group."""
    poses: np.ndarray | None = None
    """Hull over survivors of each pose box, shape (n_poses, 3, 2), when known."""

    @property
    def outliers(self) -> tuple[list[int], list[int]]:
        """Observations every survivor takes as an outlier, and those only some do."""
        every = [i for i, f in enumerate(self.follows) if f == [OUTLIER]]
        some = [i for i, f in enumerate(self.follows) if OUTLIER in f and len(f) > 1]
        return every, some

    @property
    def combinations(self) -> int:
        """Survivors the factors describe (their choices multiplied)."""
        return math.prod(len(f.choices) for f in self.factors)


def _follows(assignment: list[str], named: set[str]) -> list[str]:
    last: dict[str, int] = {}
    out = []
    for i, landmark in enumerate(assignment):
        if landmark == OUTLIER:  # sees nothing: follows nothing, followed by nothing
            out.append(OUTLIER)
            continue
        if landmark in last:
            out.append(f"#{last[landmark]}")
        else:
            out.append(landmark if landmark in named else NEW)
        last[landmark] = i
    return out


def summarize(
    assignments: list[list[str]], named: set[str] | None = None, poses: np.ndarray | None = None
) -> CorrespondenceSummary:
    """Summarise the survivors given by their assignments (landmark id per observation).

    Parameters
    ----------
    assignments : list of list of str
        Every survivor's assignment (at least one), all over the same observations.
    named : set of str, optional
        Landmark ids given in the log (they keep their names across hypotheses).
    poses : numpy.ndarray, optional
        The hull over survivors of each pose box, passed through.

    Returns
    -------
    CorrespondenceSummary

    Examples
    --------
    >>> s = summarize([["A", "A", "B", "C"], ["A", "B", "B", "C"],
    ...                ["A", "A", "B", "B"], ["A", "B", "B", "B"]])
    >>> s.certain
    [True, False, False, False]
    >>> [f.observations for f in s.factors], s.combinations
    ([[1, 2], [3]], 4)
    """
    named = named or set()
    table = [_follows(a, named) for a in assignments]
    n_obs = len(table[0]) if table else 0
    follows = [sorted({row[i] for row in table}) for i in range(n_obs)]
    certain = [len(f) == 1 for f in follows]
    ambiguous = [i for i in range(n_obs) if not certain[i]]
    groups = _independent_groups(table, ambiguous)
    distinct = len({tuple(row) for row in table})
    if math.prod(len(_choices(table, g)) for g in groups) != distinct:
        groups = [ambiguous] if ambiguous else []  # a dependence beyond pairs: one group
    factors = [Ambiguity(g, [list(c) for c in _choices(table, g)]) for g in groups]
    return CorrespondenceSummary(follows, certain, factors, poses)


def _choices(table: list[list[str]], group: list[int]) -> list[tuple[str, ...]]:
    return sorted({tuple(row[i] for i in group) for row in table})


def _independent_groups(table: list[list[str]], ambiguous: list[int]) -> list[list[int]]:
    """Join ambiguous observations whose choices are not independent (union-find over pairs
    whose joint choices are not every combination of their own)."""
    parent = {i: i for i in ambiguous}

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    values = {i: {row[i] for row in table} for i in ambiguous}
    for a_pos, a in enumerate(ambiguous):
        for b in ambiguous[a_pos + 1 :]:
            if root(a) == root(b):
                continue
            joint = {(row[a], row[b]) for row in table}
            if len(joint) != len(values[a]) * len(values[b]):
                parent[root(b)] = root(a)
    groups: dict[int, list[int]] = {}
    for i in ambiguous:
        groups.setdefault(root(i), []).append(i)
    return sorted(groups.values())


def summary_to_json(summary: CorrespondenceSummary) -> dict:
    """The summary as plain JSON-ready objects (the result file's ``correspondence``)."""
    return {
        "follows": summary.follows,
        "certain": summary.certain,
        "factors": [
            {"observations": f.observations, "choices": f.choices} for f in summary.factors
        ],
        **({} if summary.poses is None else {"pose_hull": summary.poses.tolist()}),
        **_outliers_json(summary),
    }


def summary_from_json(document: dict) -> CorrespondenceSummary:
    """The summary read back from a result's ``correspondence`` document (the inverse of
    :func:`summary_to_json`; the pose hull, when there is one, is left out).

    Examples
    --------
    >>> s = summarize([["A", "A"], ["A", "B"]])
    >>> back = summary_from_json(summary_to_json(s))
    >>> back.follows == s.follows and back.factors == s.factors
    True
    """
    factors = [
        Ambiguity(list(f["observations"]), [list(c) for c in f["choices"]])
        for f in document.get("factors", [])
    ]
    follows = [list(f) for f in document.get("follows", [])]
    return CorrespondenceSummary(follows, list(document.get("certain", [])), factors)


def _outliers_json(summary: CorrespondenceSummary) -> dict:
    every, some = summary.outliers
    if not every and not some:
        return {}
    return {"outliers": {"every_survivor": every, "some_survivors": some}}


def summary_holds(document: dict, assignment: list[str], named: set[str]) -> bool | None:
    """Whether a result's ``correspondence`` document holds ``assignment`` as a survivor.

    Parameters
    ----------
    document : dict
        The ``correspondence`` of a result (:func:`summary_to_json` plus ``survivors``).
    assignment : list of str
        A landmark id per observation (e.g. the true one).
    named : set of str
        Landmark ids the log names.

    Returns
    -------
    bool or None
        True or False when the document's factors describe every survivor (their
        combinations number ``survivors``); None when it cannot tell.
    """
    factors = document.get("factors", [])
    combinations = math.prod(len(f["choices"]) for f in factors)
    follows = document.get("follows", [])
    if combinations != document.get("survivors") or len(follows) != len(assignment):
        return None
    row = _follows(assignment, named)
    if any(c and row[i] != follows[i][0] for i, c in enumerate(document["certain"])):
        return False
    return all(
        [row[i] for i in f["observations"]] in [list(c) for c in f["choices"]] for f in factors
    )


def describe(
    summary: CorrespondenceSummary,
    survivors: int,
    complete: bool = True,
    summarised: int | None = None,
) -> str:
    """One line a user reads first: certain associations, independent ambiguities.

    When the search was cut short (``complete`` False) the line speaks of the survivors
    found, since unexplored subtrees may hold other associations; when the summary covers
    only ``summarised`` of the ``survivors`` (a tally has a cap), it says so, since the
    others may associate differently.
    """
    n = len(summary.certain)
    certain = sum(summary.certain)
    scope = "" if complete else "in the survivors found so far (the search is incomplete), "
    if summarised is not None and summarised < survivors:
        scope += f"in the first {summarised} of the {survivors} survivors (the rest counted only), "
        survivors = summarised
    every, some = summary.outliers
    outliers = (
        f" ({len(every)} taken as outliers by every survivor, {len(some)} by some)"
        if every or some
        else ""
    )
    if not summary.factors:
        return f"{scope}all {n} observations are associated for certain{outliers}"
    sizes = " x ".join(str(len(f.choices)) for f in summary.factors)
    groups = len(summary.factors)
    ambiguous = f"{n - certain} {'is' if n - certain == 1 else 'are'} ambiguous"
    combinations = f"{summary.combinations} combinations: the {survivors} survivors"
    if groups == 1:
        how = f" ({combinations})" if n - certain == 1 else f", in one group ({combinations})"
    else:
        how = f", in {groups} independent groups ({sizes} = {combinations})"
    return (
        f"{scope}{certain} of {n} observations are associated for certain; "
        f"{ambiguous}{how}{outliers}"
    )


def ambiguous_observations(solution: Solution) -> list[int]:
    """The observations (indices in log order) that the survivors of ``solution`` assign
    differently: from its ``correspondence`` summary when it has one (it covers every
    survivor the search kept), else from the reported hypotheses' assignments (landmark
    ids taken as anonymous). Empty for known correspondence.

    Examples
    --------
    >>> from cuikslam.outcome.solution import Solution
    >>> ambiguous_observations(Solution([], correspondence={"certain": [True, False, True]}))
    [1]
    """
    certain = (solution.correspondence or {}).get("certain")
    if certain is None:
        if len(solution.hypotheses) < 2:
            return []
        certain = summarize([h.assignment for h in solution.hypotheses]).certain
    return [i for i, c in enumerate(certain) if not c]
