"""A hypothesis early: a dive along what the data makes likely, before the exhaustive search.

The exhaustive search (:func:`.search.explore`) is depth first and chronological: a wrong
early decision that survives hundreds of later ones keeps it backtracking deep in a
subtree that holds no leaf, and a budget then stops it with nothing found. The dive looks
for one leaf first, with *limited discrepancy search*: follow the children in the
explorer's order (the candidate landmark nearest to where the reading puts it first, a new
landmark after the known ones: what a nearest-neighbour or JCBB association would pick,
with the fewest new landmarks), allowing at most ``k`` departures from that order on the
whole path, for k = 0, 1, ... up to ``MAX_DISCREPANCIES``. A departure near the root costs
no more than one near a leaf, which is what chronological backtracking gets wrong.

Every node it expands is expanded by the same rules as the exhaustive search, so a leaf
it reaches is a survivor of the same search: the truth is never cut by it (it cuts
nothing), and the leaf joins the result whenever the exhaustive search did not reach it
itself (:func:`.search.solve_unknown`).
"""

from __future__ import annotations

from dataclasses import asdict, fields

from cuikslam.budget import COSTS, spend
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.tree import Node, SearchLimit

__all__ = ["DIVE_SHARE", "MAX_DISCREPANCIES", "Dive", "dive"]

DIVE_SHARE = 0.25
"""Share of the search's budget the dive may use (what it does not use goes to the
exhaustive search)."""
MAX_DISCREPANCIES = 2
"""Departures from the children's order allowed on a path, at most."""


class Dive:
    """What a dive found and what it cost.

    Attributes
    ----------
    leaf : Node or None
        The first leaf not refuted, or None.
    discrepancies : int
        Departures from the children's order on its path (-1 without a leaf).
    nodes : int
        Nodes it expanded.
    """

    def __init__(self) -> None:
        self.leaf: Node | None = None
        self.discrepancies = -1
        self.nodes = 0


def dive(explorer: Explorer, root: Node, limit: SearchLimit) -> Dive:
    """The first leaf of a limited discrepancy search from ``root``, within ``limit``.

    The explorer's statistics are left as they were: the exhaustive search that follows
    counts its own nodes (the dive's are in :attr:`Dive.nodes`). Ctrl-C stops the budget's
    meter and returns what the dive has.

    Parameters
    ----------
    explorer : Explorer
        Expands nodes (the same rules as the exhaustive search).
    root : Node
        Where the dive starts.
    limit : SearchLimit
        Its budget; the dive stops with no leaf when it is spent.

    Returns
    -------
    Dive
        The leaf (or None) and the work done.
    """
    stats = explorer.stats
    saved = asdict(stats)
    found = Dive()
    try:
        for k in range(MAX_DISCREPANCIES + 1):
            if _probe(explorer, root, k, limit, found):
                found.discrepancies = k
                break
            if limit.exhausted(found.nodes) is not None:
                break
    except KeyboardInterrupt:  # Ctrl-C: the search that follows stops at once too
        if limit.deadline is None:
            raise
        limit.deadline.meter.stop()
    finally:
        for f in fields(stats):
            setattr(stats, f.name, saved[f.name])
    return found


def _probe(explorer: Explorer, root: Node, k: int, limit: SearchLimit, found: Dive) -> bool:
    """Depth first from ``root`` with at most ``k`` departures from the children's order
    (the first child keeps the count, a later one spends one); True when a leaf is found."""
    n_decisions = len(explorer.problem.decisions)
    graph = explorer.graph
    stack: list[tuple[Node, int]] = [(root, k)]
    while stack:
        if limit.exhausted(found.nodes) is not None:
            return False
        node, left = stack.pop()
        if node.depth == n_decisions:
            if not explorer.refuted_leaf(node):
                found.leaf = node
                return True
            continue
        applications = graph.applications
        kids, _ = explorer.children(node)
        found.nodes += 1
        spend(
            limit.deadline,
            COSTS["node"] + COSTS["operator"] * (graph.applications - applications),
        )
        # a probe at k visits only paths of exactly k departures once k > 0 would be
        # tighter; paths of fewer departures are cheap to revisit and keep this simple
        later = [(kid, left - 1) for kid in kids[1:]] if left > 0 else []
        stack.extend(reversed([(kid, left) for kid in kids[:1]] + later))
    return False
