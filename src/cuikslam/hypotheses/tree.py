"""The search tree's data: a node (a partial hypothesis), the limit that stops a search,
and the counts that tell how it went (:mod:`.explorer` expands nodes, :mod:`.search`
walks the tree)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, fields

from cuikslam.budget import Budget
from cuikslam.hypotheses._shared import Overlay
from cuikslam.options import AMBIGUITY_LP_MIN_DECISIONS

__all__ = [
    "AMBIGUITY_LP_GAP",
    "AMBIGUITY_LP_MIN_DECISIONS",
    "Lanes",
    "Node",
    "SearchLimit",
    "SearchStatistics",
    "aside",
    "stop_reason",
]

AMBIGUITY_LP_GAP = 8
"""Decisions after a node narrowed to ``lp`` before another node on its path may be: each
such node's box serves the next decisions of its whole subtree. The gap doubles after a
narrowing that left as many children, and is reset after one that cut some: where the level
does not help (wide odometry, say) its cost fades along the path. Rules on the node's path
only, so that exploring a subtree stays a function of its prefix (on one worker or many)."""


@dataclass
class SearchStatistics:
    """Counts that tell how the search went."""

    branch_points: int = 0
    """Nodes expanded: an unlabelled observation decided in one partial hypothesis."""
    candidates: int = 0
    """(node, landmark) pairs considered, plus each node's "new landmark" option."""
    excluded_same_scan: int = 0
    """Candidates excluded because the same scan already saw that landmark."""
    gated: int = 0
    """Candidates rejected by the interval gate, without propagation."""
    proven_empty: int = 0
    """Children whose constraints contracted to empty (a proof)."""
    refuted_by_negative_information: int = 0
    """Children refuted by UNSEEN constraints (a landmark in view that the robot did not see)."""
    unseen_constraints: int = 0
    """UNSEEN constraints added (pose-landmark pairs close enough to matter)."""
    created: int = 0
    """Children created (each a consistent-looking partial hypothesis)."""
    refuted_in_local_frame: int = 0
    """Children with a window of poses up to the decided one inconsistent in a local frame."""
    refuted_by_consistency: int = 0
    """Nodes or survivors of hull consistency refuted by the stronger consistency level."""
    refuted_by_bisection: int = 0
    """Leaves (when the search reaches them) and survivors (after it) proven impossible by
    bisecting their boxes (:mod:`.bisection`); those refuted as leaves never count as
    survivors."""
    refuted_by_class_prior: int = 0
    """Children breaking a class prior of the log: one landmark too many of a class, or two
    distinct landmarks of a class closer than its separation."""
    survivors: int = 0
    """Leaves not refuted: complete hypotheses (all of them, reported or not)."""
    unexplored_subtrees: int = 0
    """Subtrees left when a budget stopped the search (0 when complete)."""
    explored_fraction: float = 0.0
    """Share of the search tree decided (children weigh equally within their parent)."""
    peak_frontier: int = 0
    """Most nodes waiting on the depth-first stack at once."""
    operator_applications: int = 0
    ambiguity_lp: int = 0
    """Nodes about to branch that were narrowed to the ``lp`` level first."""
    outlier_options: int = 0
    """Children that take their observation as an outlier (an ``outliers`` declaration)."""
    dive_nodes: int = 0
    """Nodes the dive expanded before the exhaustive search (:mod:`.dive`)."""
    dive_discrepancies: int = -1
    """Departures from the likeliest children on the path of the leaf the dive found (-1:
    none found)."""
    dive_proven: int = 0
    """1 when the dive's leaf was proven consistent (a witness) before the exhaustive search
    went on (``prove`` of :func:`.search.solve_unknown`)."""
    dive_proven_work: int = 0
    """Work units the solve had spent when the dive's leaf was proven (0: not proven)."""
    dive_leaf_added: int = 0
    """1 when the dive's leaf lies in a subtree the exhaustive search left unexplored, and
    joined the survivors from there."""
    guess_scans: int = 0
    """Scans the guess decided at once (:mod:`.guess`)."""
    guess_repairs: int = 0
    """Scans the guess decided again reading by reading, where a scan at once was refuted."""
    guess_proven: int = 0
    """1 when the early proof is the guess's: the dive did not run."""
    joins: int = 0
    """Joined nodes made: lanes that agreed on their future, walked once (:mod:`.joined`)."""
    joined_lanes: int = 0
    """Lanes those joined nodes stand for."""


@dataclass(frozen=True, slots=True)
class Node:
    """A partial hypothesis: the first ``depth`` decisions made."""

    depth: int
    overlay: Overlay
    blocks: tuple[int, ...]
    """Decision that created each anonymous landmark, in order (their landmark numbers
    follow the named landmarks')."""
    assigned: tuple | None
    """Landmark number of each decision as a persistent list ``(number, previous)``, newest
    first, so a child shares its parent's history."""
    share: float = 1.0
    """Fraction of the whole tree under this node (for progress and the budget account)."""
    level: str = "hull"
    """The consistency level its boxes are known to reach."""
    lp_depth: int = -AMBIGUITY_LP_GAP
    """Depth of the last node on its path narrowed to ``lp`` before it branched."""
    lp_gap: int = AMBIGUITY_LP_GAP
    """Decisions from that node to the next one that may be (see ``AMBIGUITY_LP_GAP``)."""
    outliers: tuple[int, ...] = ()
    """Decisions on its path taken as outliers (landmark number ``OUTLIER``)."""
    lanes: Lanes | None = None
    """A joined node's lanes (:mod:`.joined`): then ``assigned`` holds only the decisions
    made after them, ``blocks`` every lane's anonymous landmarks and those made since."""

    def decisions(self) -> list[int]:
        """Landmark number of every decision made, oldest first (of a joined node: those
        made after its lanes, in its own numbering)."""
        out = []
        node = self.assigned
        while node is not None:
            out.append(node[0])
            node = node[1]
        return out[::-1]


@dataclass(frozen=True, slots=True)
class Lanes:
    """Nodes of one depth whose common future is walked once, from their join
    (:mod:`.joined`)."""

    nodes: tuple[Node, ...]
    depth: int
    blocks: tuple[int, ...]
    """Decisions that create an anonymous landmark in some lane, in order (the joined
    node's landmark numbers follow the named landmarks' in this order)."""
    common: frozenset[int]
    """The joined node's landmark numbers that every lane holds."""
    class_count: dict[str, int]
    """Fewest landmarks of each class that a lane holds."""


def stop_reason(deadline: Budget) -> str:
    """Why a spent budget stopped the search, in words (``"work budget"``, ``"time
    budget"``, ``"interrupt (Ctrl-C)"``)."""
    if deadline.meter.bound == "interrupt":
        return "interrupt (Ctrl-C)"
    return f"{deadline.meter.bound} budget"


@dataclass
class SearchLimit:
    """When the search stops before it is complete (None: no limit)."""

    deadline: Budget | None = None
    """The search's share of the solve's budget."""
    max_nodes: int | None = None

    def exhausted(self, nodes: int) -> str | None:
        """Why the search must stop now (``"work budget"``, ``"time budget"``, ``"node
        budget"``), or None."""
        if self.deadline is not None and self.deadline.expired():
            return stop_reason(self.deadline)
        if self.max_nodes is not None and nodes >= self.max_nodes:
            return "node budget"
        return None


@contextmanager
def aside(stats: SearchStatistics, limit: SearchLimit) -> Iterator[None]:
    """A walk beside the search (the guess, the dive): ``stats`` are left as they were,
    and Ctrl-C stops ``limit``'s meter (the search that follows stops at once too) and
    ends the walk quietly; without a budget it goes up."""
    saved = asdict(stats)
    try:
        yield
    except KeyboardInterrupt:
        if limit.deadline is None:
            raise
        limit.deadline.meter.stop()
    finally:
        for f in fields(stats):
            setattr(stats, f.name, saved[f.name])
