"""Unknown correspondence online: every hypothesis of the records so far that is not proven
impossible, updated as each pose is finished.

The batch search's pieces do the work: the records so far become a correspondence problem
(:func:`~cuikslam.hypotheses.problem.build_problem`), each live hypothesis is replayed in
it (its decisions taken again, so that what the new records say about its earlier
decisions is applied: a new odometry, prior or ``class`` record narrows or refutes it),
and every one is extended, depth first, with the decisions of the new readings
(:func:`~cuikslam.hypotheses.search.explore`, :class:`~cuikslam.hypotheses.explorer.Explorer`:
gating, negative information once a scan is complete, class priors, the local frame, the
bisection of leaves). A hypothesis goes only when that proves it impossible, so the truth
stays among the live ones whenever every record holds its truth, as in the batch search.

Two events make the earlier decisions' options change, and then the live set is searched
again from the root: a landmark named for the first time while some readings were already
decided (a name is a candidate for every reading, earlier ones included), and, with a
``sensor`` record, a reading from a pose finished earlier (its scan, taken as complete
for negative information, was not).

Each update rebuilds the problem and replays the live hypotheses: its cost grows with the
log (about the batch search of the records so far, restricted to the live paths).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.search import explore
from cuikslam.hypotheses.survivors import hypothesis_of
from cuikslam.hypotheses.tree import Node, SearchLimit
from cuikslam.log.records import Log

__all__ = ["LiveHypotheses"]

_ALL = 2**62
"""Survivors kept by :func:`~cuikslam.hypotheses.search.explore`: every one."""


class LiveHypotheses:
    """The live correspondence hypotheses of a growing log, at level ``hull``.

    Examples
    --------
    >>> from cuikslam.log import parse_log_lines
    >>> seen = '"type": "observation", "class": "c", '
    >>> lines = [
    ...     '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
    ...     '{' + seen + '"pose": 0, "range": [1, 1.1], "bearing": [0, 0.1]}',
    ...     '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [0.5, 0.6]}',
    ...     '{' + seen + '"pose": 1, "range": [0.4, 0.6], "bearing": [-0.1, 0.1]}',
    ... ]
    >>> live = LiveHypotheses(rtol=1e-3)
    >>> live.update(parse_log_lines(lines[:2]))
    >>> live.update(parse_log_lines(lines), complete=False)
    >>> sorted(live.assignments())
    [['+1', '+1'], ['+1', '+2']]
    >>> live.pose_box(1)[0].round(6).tolist()  # x of pose 1, whichever landmark it saw
    [0.5, 0.6]
    """

    def __init__(self, rtol: float) -> None:
        self.rtol = rtol
        self.explorer: Explorer | None = None
        self.nodes: list[Node] = []
        """The live hypotheses, as nodes of ``explorer`` (empty once all are refuted)."""
        self.refuted = False
        """True once every hypothesis is proven impossible."""
        self._named = 0

    def __len__(self) -> int:
        return len(self.nodes)

    def update(self, log: Log, complete: bool = False) -> None:
        """Bring the live set up to the records of ``log`` (the records so far, of which
        those of the last update are the first). ``complete``: search again from the
        root (see the module docstring)."""
        if self.refuted:
            return
        problem = build_problem(log)
        explorer = Explorer(problem, self.rtol, "hull", 0)
        root = explorer.root()
        if root is None:
            self._refute()
            return
        if self.explorer is None or complete or len(problem.named) != self._named:
            starts = [root]
        else:
            starts = _replay(explorer, root, [tuple(n.decisions()) for n in self.nodes])
        outcome = explore(explorer, starts, SearchLimit(), _ALL)
        self.explorer, self.nodes, self._named = explorer, outcome.survivors, len(problem.named)
        if not self.nodes:
            self._refute()

    def _refute(self) -> None:
        self.refuted, self.nodes = True, []

    def pose_box(self, pose: int) -> np.ndarray:
        """The (3, 2) hull of ``pose``'s boxes over the live hypotheses (as of the last
        update), as plain intervals (headings too: a sound enclosure modulo 2π).

        Raises
        ------
        KeyError
            For a pose the last update did not have.
        ValueError
            Once every hypothesis is refuted.
        """
        if not self.nodes or self.explorer is None:
            raise ValueError("no live hypothesis")
        x = self.explorer.problem.pose_x[pose]
        variables = np.arange(x, x + 3, dtype=np.int64)
        bounds = [self.explorer.graph.values(n.overlay, variables) for n in self.nodes]
        lo = np.min([b[0] for b in bounds], axis=0)
        hi = np.max([b[1] for b in bounds], axis=0)
        return np.stack([lo, hi], axis=-1)

    def assignments(self) -> list[list[str]]:
        """Each live hypothesis' landmark per observation, in log order: the log's ids, the
        landmarks it adds named as a solve names them (``+1``, ``+2``, ... in order of
        first sight), ``"outlier"``."""
        explorer = self.explorer
        if explorer is None:
            return []
        return [hypothesis_of(explorer, node).assignment for node in self.nodes]


def _replay(explorer: Explorer, root: Node, prefixes: list[tuple[int, ...]]) -> list[Node]:
    """The nodes of ``explorer`` reached by the decisions ``prefixes`` (landmark numbers,
    all of one length), each shared step taken once; a step no longer possible (proven
    impossible by the new records) drops every prefix through it."""
    reached: list[Node] = []
    stack: list[tuple[Node, list[tuple[int, ...]]]] = [(root, prefixes)]
    while stack:
        node, tails = stack.pop()
        if not tails[0]:
            reached.append(node)
            continue
        kids = {child.assigned[0]: child for child in explorer.children(node, narrow=False)[0]}
        groups: dict[int, list[tuple[int, ...]]] = defaultdict(list)
        for tail in tails:
            groups[tail[0]].append(tail[1:])
        for number in sorted(groups, reverse=True):
            if number in kids:
                stack.append((kids[number], groups[number]))
    return reached[::-1]
