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
itself (:func:`.search.solve_unknown`). The search may have the leaf proven consistent at
once (:func:`prove_leaf`, by the witness search): a user then has a proven hypothesis
however far the exhaustive search gets.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Literal

from cuikslam.budget import COSTS, SCHEDULE, spend
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.guess import first_guess
from cuikslam.hypotheses.progress import ProgressTracker
from cuikslam.hypotheses.survivors import hypothesis_of
from cuikslam.hypotheses.tally import Tally
from cuikslam.hypotheses.tree import Node, SearchLimit, aside
from cuikslam.outcome.solution import PROVEN, Hypothesis, Solution

__all__ = [
    "MAX_DISCREPANCIES",
    "Dive",
    "ProofStage",
    "Prove",
    "dive",
    "early_hypothesis",
    "join_leaf",
    "keep_proof",
    "prove_leaf",
]

ProofStage = Literal["early_proof", "guess_proof"]
"""The stage of the schedule whose budget an early proof spends."""
Prove = Callable[[Hypothesis, ProofStage], None]
"""Proves a hypothesis consistent when it can (sets its status and witness), within the
budget of the given stage of the schedule: see ``prove`` of :func:`.search.solve_unknown`."""

MAX_DISCREPANCIES = 2
"""Departures from the children's order allowed on a path, at most."""
REPORT_EVERY = 64
"""Expansions between two reports of the dive's depth (a progress bar)."""


class Dive:
    """What a dive found and what it cost; it may be resumed where its budget stopped it.

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
        self._k = 0
        """Departures allowed in the probe under way."""
        self._stack: list[tuple[Node, int]] | None = None
        """The probe's pending nodes, each with the departures it may still take (None:
        the probe at ``_k`` has not started)."""

    def restart(self) -> None:
        """Start the probe under way again from the root (its pending nodes are stale:
        :meth:`.explorer.Explorer.restart`)."""
        self._stack = None

    @property
    def finished(self) -> bool:
        """True when it found a leaf or tried every probe to its end."""
        return self.leaf is not None or self._k > MAX_DISCREPANCIES


def dive(
    explorer: Explorer,
    root: Node,
    limit: SearchLimit,
    resume: Dive | None = None,
    tracker: ProgressTracker | None = None,
) -> Dive:
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
    resume : Dive, optional
        A dive that a budget stopped, to go on from where it was.
    tracker : ProgressTracker, optional
        Told the depth of the dive every ``REPORT_EVERY`` expansions.

    Returns
    -------
    Dive
        The leaf (or None) and the work done (``resume`` itself, when given).
    """
    found = Dive() if resume is None else resume
    with aside(explorer.stats, limit):
        while not found.finished:
            if found._stack is None:
                found._stack = [(root, found._k)]
            if _probe(explorer, found._stack, limit, found, tracker):
                found.discrepancies = found._k
                break
            if limit.exhausted(found.nodes) is not None:
                break  # the probe's stack stays, for a resume
            found._k, found._stack = found._k + 1, None
    return found


def _probe(
    explorer: Explorer,
    stack: list[tuple[Node, int]],
    limit: SearchLimit,
    found: Dive,
    tracker: ProgressTracker | None,
) -> bool:
    """Depth first from what ``stack`` holds, each node with the departures from the
    children's order it may still take (the first child keeps the count, a later one
    spends one); True when a leaf is found (``found.leaf``)."""
    n_decisions = len(explorer.problem.decisions)
    graph = explorer.graph
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
        kids, _ = explorer.children(node, keep=True)
        found.nodes += 1
        if tracker is not None and found.nodes % REPORT_EVERY == 0:
            tracker.diving(node.depth)
        spend(
            limit.deadline,
            COSTS["node"] + COSTS["operator"] * (graph.applications - applications),
        )
        # paths of fewer departures are visited again by the next probe: cheap beside
        # the exponential number of paths of exactly k, and simpler
        later = [(kid, left - 1) for kid in kids[1:]] if left > 0 else []
        stack.extend(reversed([(kid, left) for kid in kids[:1]] + later))
    return False


def early_hypothesis(
    explorer: Explorer,
    root: Node,
    limit: SearchLimit,
    prove: Prove | None,
    tracker: ProgressTracker | None = None,
) -> tuple[Dive, Hypothesis | None]:
    """A leaf before the exhaustive search, and its proof when ``prove`` proves it.

    The guess (:func:`.guess.first_guess`, a scan at a time, on its share of ``limit``)
    comes first; when the witness search proves its leaf, that is the early hypothesis.
    Otherwise the dive looks for a leaf of the search itself within what is left of
    ``limit``, and its leaf is proven when it differs from the guess. Without ``prove``
    there is no guess (its leaf would prove nothing).

    Returns
    -------
    Dive, Hypothesis or None
        The leaf found (that of the guess when it was proven: it then holds no dive's
        work) and the proven hypothesis (None: none proven).
    """
    stats = explorer.stats
    guessed = None
    if prove is not None:
        share = SearchLimit(SCHEDULE.share(limit.deadline, "guess"), limit.max_nodes)
        guessed = first_guess(explorer, root, share)
        stats.guess_scans, stats.guess_repairs = guessed.scans, guessed.repairs
        if guessed.leaf is not None:
            proof = prove_leaf(explorer, guessed.leaf, prove, "guess_proof")
            if proof is not None:
                stats.guess_proven = 1
                found = Dive()
                found.leaf = guessed.leaf
                return found, proof
    early = dive(explorer, root, limit, tracker=tracker)
    if guessed is not None and guessed.leaf is not None and early.leaf is not None:
        if early.leaf.decisions() == guessed.leaf.decisions():
            return early, None  # its proof failed already
    return early, prove_leaf(explorer, early.leaf, prove)


def prove_leaf(
    explorer: Explorer,
    leaf: Node | None,
    prove: Prove | None,
    stage: ProofStage = "early_proof",
) -> Hypothesis | None:
    """``leaf`` as a hypothesis, when ``prove`` proves it consistent within ``stage``'s
    budget (else None)."""
    if leaf is None or prove is None:
        return None
    hypothesis = hypothesis_of(explorer, leaf)
    prove(hypothesis, stage)
    if hypothesis.status != PROVEN:
        return None
    explorer.stats.dive_proven = 1
    if explorer.deadline is not None:
        explorer.stats.dive_proven_work = round(explorer.deadline.meter.spent)
    explorer.proven_at = time.perf_counter()
    return hypothesis


def join_leaf(explorer: Explorer, tally: Tally, early: Dive, unexplored: list[list[int]]) -> bool:
    """Count the early leaf among the survivors when it lies under one of the
    ``unexplored`` prefixes (the search never reached it; a complete search reached it
    itself, or refuted it: then it was no proven leaf). Also records the dive's
    statistics. True when it was added."""
    stats = explorer.stats
    stats.dive_nodes, stats.dive_discrepancies = early.nodes, early.discrepancies
    leaf = early.leaf
    if leaf is None or not unexplored:
        return False
    decisions = leaf.decisions()
    if not any(decisions[: len(u)] == u for u in unexplored):
        return False
    tally.add(leaf)
    stats.survivors += 1
    stats.dive_leaf_added = 1
    return True


def keep_proof(solution: Solution, proof: Hypothesis) -> None:
    """The early proof in the report: its witness on the hypothesis of the same assignment
    (its boxes are the report's, narrowed further), or the hypothesis itself at the head
    when the report left it out (a proven hypothesis ranks first)."""
    for h in solution.hypotheses:
        if h.assignment == proof.assignment:
            h.status, h.witness = PROVEN, proof.witness
            break
    else:
        solution.hypotheses.insert(0, proof)
    solution.hypotheses.sort(key=lambda h: h.rank_key)
