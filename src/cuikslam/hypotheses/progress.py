"""What a running correspondence search can tell its user, and what stays true whatever
the rest of the search finds.

The share of the tree explored (``SearchStatistics.explored_fraction``) weighs the
children of a node equally: on the unbalanced trees of long logs it reads 99.99 % while
most of the work is left, and says nothing of what was learnt. A
:class:`SearchProgress` says instead:

* how many readings are *decided*: associated alike (with the same earlier sighting, the
  same named landmark first seen, a new landmark, or as an outlier: the result's
  "associated for certain") by every survivor found so far and every hypothesis under a
  subtree still pending, so that no later finding can change them;
* how many survivors were found (at ``hull``: the stages after the search may still
  refute some) and how many of them are proven consistent (a lower bound on the
  consistent hypotheses);
* an upper bound on the number of survivors: those found, plus for each pending subtree
  the product of the options each of its remaining decisions can have at most (a named
  or earlier landmark of its class, a new one, an outlier when declared).

A depth-first search pends the alternatives of the decisions on its path, so readings are
decided from the first ones on, as the alternatives of early decisions are closed.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.problem import Problem
from cuikslam.hypotheses.tree import Node

__all__ = [
    "ProgressTracker",
    "SearchProgress",
    "association_keys",
    "decided_after_stop",
    "takes_status",
]

_OUTLIER_KEY = -2
_NEW_KEY = -1


@dataclass(frozen=True)
class SearchProgress:
    """The state of a correspondence search, as :func:`cuikslam.solve` reports it.

    Attributes
    ----------
    stage : str
        ``"dive"`` (looking for a first hypothesis along the likeliest associations),
        ``"search"`` (the exhaustive search) or ``"done"``.
    readings : int
        Readings whose landmark the search decides (the unlabelled ones).
    decided : int
        Readings associated alike by every survivor found and every pending subtree.
    found : int
        Survivors found so far (at ``hull``).
    proven : int
        Hypotheses proven consistent so far (a witness verified).
    pending : int
        Subtrees still to explore.
    upper_log10 : float
        Base-10 logarithm of an upper bound on the number of survivors (``-inf``: none can
        be left).
    depth : int
        Decisions on the path the search (or the dive) is at.
    explored : float
        The share of the tree explored, children weighing equally (for comparison only).
    decided_positions : tuple of int
        The decided readings, as indices among all observations (the order of a
        hypothesis' ``assignment``). Once decided, a reading stays decided.

    Examples
    --------
    >>> SearchProgress("search", 13, 12, 2, 1, 0, math.log10(2), 13, 1.0).describe()
    '12 of 13 readings decided · 2 survivors found, 1 proven · exactly 2 left'
    """

    stage: str
    readings: int
    decided: int
    found: int
    proven: int
    pending: int
    upper_log10: float
    depth: int
    explored: float
    decided_positions: tuple[int, ...] = ()

    def short(self) -> str:
        """What :meth:`describe` says, for beside a bar that counts the readings decided.

        Examples
        --------
        >>> SearchProgress("search", 1052, 480, 3, 1, 52, 17.5, 900, 0.9).short()
        'decided · 3 found, 1 proven · at most 10^17 · 52 pending'
        """
        if self.stage == "dive":
            return f"associated on a first path · {self.proven} proven"
        proven = f", {self.proven:,} proven" if self.proven else ""
        head = f"decided · {self.found:,} found{proven}"
        if self.pending == 0:
            return f"{head} · exactly {self.found:,} left"
        return f"{head} · at most {_power(self.upper_log10)} · {self.pending:,} pending"

    def describe(self) -> str:
        """One line: readings decided, survivors found and proven, their upper bound."""
        if self.stage == "dive":
            return (
                f"looking for a first hypothesis: {self.depth:,} of {self.readings:,} "
                f"readings associated · {self.proven} proven"
            )
        found = f"{self.found:,} survivor{'' if self.found == 1 else 's'} found"
        proven = f", {self.proven:,} proven" if self.proven else ""
        head = f"{self.decided:,} of {self.readings:,} readings decided · {found}{proven}"
        if self.pending == 0:
            return f"{head} · exactly {self.found:,} left"
        return f"{head} · at most {_power(self.upper_log10)} · {self.pending:,} subtrees pending"


def _power(log10: float) -> str:
    """``10 ** log10`` for a reader: digits while they fit, else a power of ten."""
    if log10 < 9:
        return f"{math.floor(10**log10 + 1e-9):,}"
    return f"10^{math.floor(log10)}"


def association_keys(
    decisions: list[int], positions: np.ndarray, labelled: dict[int, int], n_named: int
) -> np.ndarray:
    """What each decision associates its reading with, as the result's correspondence
    summary does (``outcome.summary``): the observation that saw the same landmark last
    before it (labelled ones included), or for a first sighting ``-3 - n`` (named landmark
    ``n``) or -1 (a new landmark); -2 for an outlier.

    ``positions`` are the decisions' observation indices, ``labelled`` maps the index of
    each labelled observation to its named landmark.

    Examples
    --------
    >>> association_keys([0, 2, 2, -1, 0], np.array([1, 2, 3, 4, 5]), {0: 0}, 2).tolist()
    [0, -1, 2, -2, 1]
    """
    keys = np.empty(len(decisions), dtype=np.int64)
    last: dict[int, int] = {}
    events = sorted(
        [(int(p), n, -1) for p, n in labelled.items()]
        + [(int(p), n, j) for j, (p, n) in enumerate(zip(positions, decisions, strict=True))]
    )
    for position, n, j in events:
        if n == OUTLIER:
            keys[j] = _OUTLIER_KEY
            continue
        if j >= 0:
            keys[j] = last.get(n, -3 - n if n < n_named else _NEW_KEY)
        last[n] = position
    return keys


def decided_after_stop(
    problem: Problem, pending: list[list[int]], survivors: list[tuple[int, ...]]
) -> tuple[int, ...]:
    """Readings a stopped search decided, as indices among all observations: associated
    alike by every survivor found and every hypothesis under a ``pending`` subtree (each
    given by the decisions of its root, which fix the readings it names and leave those
    after it open).

    Examples
    --------
    >>> from types import SimpleNamespace as Ns
    >>> problem = Ns(decisions=[Ns(position=k) for k in range(4)], named_assignment={},
    ...              named=[])
    >>> decided_after_stop(problem, [[0, 0, 1], [0, 0, 2]], [(0, 0, 0, 0)])
    (0, 1)
    >>> decided_after_stop(problem, [[0, 0, 1]], [(0, 1, 0, 0)])
    (0,)
    """
    positions = np.array([d.position for d in problem.decisions], dtype=np.int64)
    if not pending:
        return tuple(positions.tolist())
    labelled, n_named = dict(problem.named_assignment), len(problem.named)
    boundary = min(len(prefix) for prefix in pending)

    def keys(decisions: list[int] | tuple[int, ...]) -> np.ndarray:
        head = list(decisions[:boundary])
        return association_keys(head, positions[:boundary], labelled, n_named)

    reference = keys(pending[0])
    agree = np.ones(boundary, dtype=np.bool_)
    for decisions in [*pending[1:], *survivors]:
        agree &= keys(decisions) == reference
    return tuple(positions[:boundary][agree].tolist())


def takes_status(progress: Callable[..., object]) -> bool:
    """Whether a progress callback takes a third argument (a :class:`SearchProgress`)."""
    try:
        inspect.signature(progress).bind(0, 0, None)
    except (TypeError, ValueError):
        return False
    return True


class ProgressTracker:
    """Keeps what :class:`SearchProgress` needs as a depth-first search from one root
    advances, and reports it to ``callback(done, total[, status])`` (readings decided of
    readings; the status when the callback takes it, see :func:`takes_status`)."""

    def __init__(self, problem: Problem, callback: Callable[..., object]) -> None:
        self.callback = callback
        self._with_status = takes_status(callback)
        self.readings = len(problem.decisions)
        self.n_named = len(problem.named)
        self.found = 0
        self.proven = 0
        self._first: np.ndarray | None = None
        """Association keys of the first survivor found."""
        self._varies = np.zeros(self.readings, dtype=np.bool_)
        """Readings that two survivors found associate differently."""
        self._suffix = _options_suffix(problem)
        self._positions = np.array([d.position for d in problem.decisions], dtype=np.int64)
        self._labelled = dict(problem.named_assignment)

    def survivor(self, node: Node) -> None:
        """Count a survivor the search found (a leaf not refuted)."""
        keys = self._keys(node.decisions())
        if self._first is None:
            self._first = keys
        else:
            self._varies |= keys != self._first
        self.found += 1

    def diving(self, depth: int) -> None:
        """The dive is ``depth`` decisions deep."""
        self._send(SearchProgress("dive", self.readings, 0, 0, self.proven, 1, 0.0, depth, 0.0))

    def report(self, stack: list[Node], explored: float) -> SearchProgress:
        """Report the search with ``stack`` pending (one root's: nodes that share the
        decisions of a common ancestor)."""
        status = self.status(stack, explored)
        self._send(status)
        return status

    def status(self, stack: list[Node], explored: float) -> SearchProgress:
        """The :class:`SearchProgress` of the search with ``stack`` pending."""
        if stack:
            boundary, common = _common_prefix(stack)
            reference = self._keys(_listed(common))
            depth = stack[-1].depth
            bounds = [self._suffix[n.depth] + math.log10(_lanes(n)) for n in stack]
        else:
            boundary, reference, depth, bounds = self.readings, None, self.readings, []
        agree = np.ones(boundary, dtype=np.bool_)
        if self._first is not None:
            agree &= ~self._varies[:boundary]
            if reference is not None:
                agree &= self._first[:boundary] == reference
        positions = tuple(self._positions[:boundary][agree].tolist())
        if self.found:
            bounds.append(math.log10(self.found))
        upper = _log10_sum(bounds)
        stage = "search" if stack else "done"
        return SearchProgress(
            stage, self.readings, len(positions), self.found, self.proven, len(stack), upper,
            depth, explored, positions,
        )  # fmt: skip

    def _keys(self, decisions: list[int]) -> np.ndarray:
        n = len(decisions)
        return association_keys(decisions, self._positions[:n], self._labelled, self.n_named)

    def _send(self, status: SearchProgress) -> None:
        """The dive's depth goes only to a callback that takes the status (a bar of
        decided readings should not run ahead, then back)."""
        if self._with_status:
            done = status.depth if status.stage == "dive" else status.decided
            self.callback(done, status.readings, status)
        elif status.stage != "dive":
            self.callback(status.decided, status.readings)


def _lanes(node: Node) -> int:
    return 1 if node.lanes is None else len(node.lanes.nodes)


def _common_prefix(stack: list[Node]) -> tuple[int, tuple | None]:
    """The decisions every node of ``stack`` shares (a joined node: each of its lanes),
    as their depth and the common ancestor's ``assigned`` list, but the last decision of
    the shallowest (its siblings may differ there). Children share their parent's list
    object, so a common ancestor is found by identity (lists equal but distinct only make
    the prefix shorter)."""
    chains = []
    for n in stack:
        if n.lanes is None:
            chains.append((n.depth, n.assigned))
        else:
            chains.extend((n.lanes.depth, lane.assigned) for lane in n.lanes.nodes)
    depth = max(0, min(d for d, _ in chains) - 1)
    at = []
    for d, chain in chains:
        for _ in range(d - depth):
            chain = chain[1]
        at.append(chain)
    while depth > 0 and any(a is not at[0] for a in at):
        at = [a[1] for a in at]
        depth -= 1
    return depth, at[0]


def _listed(chain: tuple | None) -> list[int]:
    out = []
    while chain is not None:
        out.append(chain[0])
        chain = chain[1]
    return out[::-1]


def _options_suffix(problem: Problem) -> np.ndarray:
    """``suffix[j]``: log10 of the product, over decisions ``j`` on, of the options a
    decision can have at most (the named landmarks of its class, one per earlier decision
    of its class, a new one, an outlier when the log declares outliers)."""
    named = {}
    for cls in problem.named_class:
        named[cls] = named.get(cls, 0) + 1
    earlier: dict[str, int] = {}
    outlier = problem.outlier is not None
    logs = np.empty(len(problem.decisions))
    for j, d in enumerate(problem.decisions):
        cls = d.landmark_class
        logs[j] = math.log10(named.get(cls, 0) + earlier.get(cls, 0) + 1 + outlier)
        earlier[cls] = earlier.get(cls, 0) + 1
    suffix = np.zeros(len(logs) + 1)
    suffix[:-1] = np.cumsum(logs[::-1])[::-1]
    return suffix


def _log10_sum(values: list[float]) -> float:
    """log10 of the sum of ``10 ** v`` (``-inf`` for none)."""
    if not values:
        return -math.inf
    top = max(values)
    return top + math.log10(sum(10 ** (v - top) for v in values))
