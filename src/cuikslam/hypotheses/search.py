"""Unknown correspondence: a depth-first search over correspondence hypotheses, pruned only
by proof (seed, Section 5).

The log becomes a :class:`~.problem.Problem`: every constraint that holds whatever the
correspondence is propagated once, at the root. The unlabelled observations are then
decided one by one, in log order (a *decision* = which landmark it sees); a node of the
search tree is a partial hypothesis, the decisions of its depth made. Its children are
the candidate landmarks that pass the interval gate and whose constraints do not contract
to empty, plus "a new landmark"; negative information (UNSEEN constraints) joins as soon
as a pose's scan is fully decided. A node proven empty is discarded with its subtree:
that is a proof, so the true correspondence is never lost. Leaves are the survivors.

The tree is explored depth first, so memory holds one path and its pending siblings, not
every live hypothesis; a time or node budget stops the search with the exact list of the
subtrees left unexplored (each named by the decisions of its root). Expanding one node is
:class:`~.explorer.Explorer`'s; this module walks the tree, and :mod:`.finish` decides its
survivors and writes the report.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import COSTS, SCHEDULE, Budget, spend
from cuikslam.hypotheses.dive import (
    Dive,
    Prove,
    dive,
    early_hypothesis,
    join_leaf,
    keep_proof,
    prove_leaf,
)
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.finish import Rank, finish_search
from cuikslam.hypotheses.joined import joined_children, joined_leaves, lane_paths, look_ahead
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.progress import ProgressTracker
from cuikslam.hypotheses.tally import Tally
from cuikslam.hypotheses.tree import Node, SearchLimit, stop_reason
from cuikslam.log.records import Log
from cuikslam.options import SolveOptions
from cuikslam.outcome.solution import Hypothesis, Solution

__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "DEFAULT_STRENGTHEN_DURING",
    "DEFAULT_STRENGTHEN_LIMIT",
    "solve_unknown",
]

DEFAULT_MAX_HYPOTHESES = SolveOptions.max_hypotheses
"""Survivors reported in detail at most (the best-ranked); the search itself explores all."""
DEFAULT_STRENGTHEN_LIMIT = SolveOptions.strengthen_limit
"""Reported survivors narrowed to the stronger consistency level at most (else the
best-ranked)."""
DEFAULT_STRENGTHEN_DURING = SolveOptions.strengthen_during
"""Decisions (the first ones; None: all) whose nodes get ``lp`` before they branch."""
NOT_SEARCH_OPTIONS = {
    "certify_limit": "the witness search follows the search in cuikslam.solve",
    "work_budget": "the search spends the deadline it is given (deadline=Budget.start(...)); "
    "cuikslam.solve makes it from work_budget",
    "time_budget": "the search spends the deadline it is given (deadline=Budget.start(...)); "
    "cuikslam.solve makes it from time_budget",
}
"""Options of a solve that the search does not take as keywords, with why (a TypeError
says so rather than ignore them)."""
MAINTAIN_EVERY = 1024
"""Node expansions between two looks at the shared graph's housekeeping."""
REPORT_EVERY = 256
"""Node expansions between two progress reports (:class:`.progress.ProgressTracker`)."""


@dataclass
class _Outcome:
    survivors: list[Node]
    unexplored: list[Node]
    stop_reason: str | None
    reserve: list[Node] = field(default_factory=list)
    """The next best-ranked survivors, to take the place of kept ones refuted later."""
    pinned: list[Node] = field(default_factory=list)
    """The nodes given as ``pinned``, their overlays re-expressed (see :func:`explore`)."""


def explore(
    explorer: Explorer,
    start: Node | list[Node],
    budget: SearchLimit,
    keep: int,
    on_survivor: Callable[[Node], None] | None = None,
    tracker: ProgressTracker | None = None,
    reserve: int = 0,
    pinned: list[Node] | None = None,
) -> _Outcome:
    """Depth-first search of the subtree of ``start`` (of each start node in turn).

    Every survivor is counted (and passed to ``on_survivor``); the ``keep`` best-ranked are
    returned, and the ``reserve`` next ones apart. ``tracker`` (one root only) hears of
    every survivor and of the pending subtrees every ``REPORT_EVERY`` expansions. A
    budget stop returns the pending subtrees as ``unexplored``; so does Ctrl-C, which also
    stops the budget's meter, so that the stages after the search stop at once and the
    result (with its envelope) is returned. ``pinned`` nodes (the dive's leaf) stay valid:
    the shared graph's housekeeping re-expresses their overlays, and the outcome holds
    them as they are after it.
    """
    stats = explorer.stats
    stack = start[::-1] if isinstance(start, list) else [start]
    survivors: list[Node] = []
    pinned = list(pinned or [])
    done = 0.0
    expanded = 0
    reason = None
    while stack:
        reason = budget.exhausted(expanded)
        if reason is not None:
            break
        before = expanded
        try:
            done, expanded = _step(explorer, stack, survivors, done, expanded, on_survivor, budget)
        except KeyboardInterrupt:  # Ctrl-C: what is pending becomes the unexplored part
            if budget.deadline is None:
                raise
            budget.deadline.meter.stop()
            reason = stop_reason(budget.deadline)
            break
        if len(survivors) > 2 * (keep + reserve):
            survivors = _best(explorer, survivors, keep + reserve)
        stats.peak_frontier = max(stats.peak_frontier, len(stack))
        if expanded // MAINTAIN_EVERY > before // MAINTAIN_EVERY:
            stack, survivors, pinned = _maintain(explorer, stack, survivors, pinned)
        if tracker is not None and expanded // REPORT_EVERY > before // REPORT_EVERY:
            tracker.report(stack, done)
    stats.explored_fraction = min(1.0, done)
    if tracker is not None:
        tracker.report(stack, min(1.0, done))
    ranked = _best(explorer, survivors, keep + reserve)
    return _Outcome(ranked[:keep], stack if reason else [], reason, ranked[keep:], pinned)


def _step(
    explorer: Explorer,
    stack: list[Node],
    survivors: list[Node],
    done: float,
    expanded: int,
    on_survivor: Callable[[Node], None] | None,
    limit: SearchLimit,
) -> tuple[float, int]:
    """Take the next node off ``stack``: a leaf is counted and kept when not refuted, another
    node is expanded and its children pushed (those of a branching node followed ahead
    first, to be joined: :func:`.joined.look_ahead`). Returns the share of the tree decided
    and the nodes expanded, updated. A node whose step an interrupt cuts is put back on the
    stack (with its children, if they were pushed: the pending part may then overlap, which
    only widens what is left unexplored)."""
    graph = explorer.graph
    node = stack.pop()
    finished = False
    applications = graph.applications
    try:
        if node.depth == len(explorer.problem.decisions):
            leaves = [node] if node.lanes is None else joined_leaves(explorer, node)
            for leaf in leaves:
                if not explorer.refuted_leaf(leaf):
                    explorer.stats.survivors += 1
                    survivors.append(leaf)
                    if on_survivor is not None:
                        on_survivor(leaf)
            finished = True
            spend(limit.deadline, COSTS["operator"] * (graph.applications - applications))
            return done + node.share, expanded
        kids, options = explorer.children(node)
        share = node.share * (options - len(kids)) / options
        if node.lanes is not None:
            kids, decided = joined_children(explorer, kids)
            share += decided
        cost = COSTS["node"]
        if explorer.joins and len(kids) > 1 and node.lanes is None:
            spend(limit.deadline, cost + COSTS["operator"] * (graph.applications - applications))
            kids, more, decided = look_ahead(explorer, kids, limit, expanded + 1)  # spends its own
            cost, applications = 0.0, graph.applications
            expanded, share = expanded + more, share + decided
        stack.extend(reversed(kids))
        finished = True
    finally:
        if not finished:
            stack.append(node)
    spend(limit.deadline, cost + COSTS["operator"] * (graph.applications - applications))
    return done + share, expanded + 1


def _maintain(
    explorer: Explorer, stack: list[Node], survivors: list[Node], pinned: list[Node]
) -> tuple[list[Node], list[Node], list[Node]]:
    """Let the shared graph rebase and compact; the nodes re-expressed, same boxes (those
    of the dive's kept expansions too, each node object once, so that a node on the stack
    is still the one its kept expansion names; a joined node's lanes too)."""
    held = [*stack, *survivors, *pinned, *explorer.expansions.nodes()]
    lanes = {id(n.lanes): n.lanes for n in held if n.lanes is not None}
    held += [lane for group in lanes.values() for lane in group.nodes]
    unique = {id(n): n for n in held}
    overlays = explorer.graph.maintain([n.overlay for n in unique.values()])
    new = {key: replace(n, overlay=o) for (key, n), o in zip(unique.items(), overlays, strict=True)}
    moved = {
        key: replace(group, nodes=tuple(new[id(lane)] for lane in group.nodes))
        for key, group in lanes.items()
    }
    for key, n in new.items():
        if n.lanes is not None:
            new[key] = replace(n, lanes=moved[id(n.lanes)])
    explorer.expansions.renamed(new)
    return (
        [new[id(n)] for n in stack],
        [new[id(n)] for n in survivors],
        [new[id(n)] for n in pinned],
    )


def _rank_key(explorer: Explorer, node: Node) -> tuple[int, int, int, float]:
    """Fewest outliers, fewest landmarks, then fewest unbounded widths, then smallest total
    width."""
    extra = explorer.landmark_xs(node)
    n_inf, total = explorer.graph.size_key(node.overlay, np.concatenate([extra, extra + 1]))
    return (len(node.outliers), len(extra), n_inf, total)


def _best(explorer: Explorer, nodes: list[Node], keep: int) -> list[Node]:
    return sorted(nodes, key=lambda n: _rank_key(explorer, n))[:keep]


def solve_unknown(
    log: Log,
    options: SolveOptions | None = None,
    *,
    progress: Callable[[int, int], None] | None = None,
    deadline: Budget | None = None,
    on_survivor: Callable[[list[str]], None] | None = None,
    rank: Rank | None = None,
    prove: Prove | None = None,
    **overrides: Any,
) -> Solution:
    """Solve a log whose observations may lack landmark ids; return the surviving hypotheses.

    Parameters
    ----------
    log : Log
        The log; observations without ``landmark`` are decided by the search.
    options : SolveOptions, optional
        The options (defaults: ``SolveOptions()``); the search uses ``consistency`` (the
        level applied to the survivors), ``max_hypotheses`` (survivors reported in detail,
        the best-ranked: fewest outliers, fewest landmarks, then smallest boxes; it never
        limits the search, every survivor is counted), ``strengthen_limit``,
        ``strengthen_during`` (during the first decisions, a node that would branch is
        narrowed to ``lp`` first, whatever ``consistency``, so that narrower boxes gate
        its candidates: :meth:`.explorer.Explorer.children`), ``rtol``, ``threads``,
        ``max_nodes`` (node expansions after which it stops, incomplete) and
        ``local_frame``. Its budget is ``deadline``.
    progress : callable, optional
        Called with (done, total) as the search advances: the readings decided (associated
        alike by every survivor found and every subtree still pending) of those to decide.
        A callable that takes a third argument also gets a
        :class:`~.progress.SearchProgress` (survivors found and proven, an upper bound on
        their number, subtrees pending), and the dive's depth while it looks for a first
        hypothesis.
    deadline : Budget, optional
        The budget at which the search stops, incomplete (None: no limit).
    on_survivor : callable, optional
        Called with the assignment of every survivor of the search as it is found (a
        landmark per observation, in log order: the log's ids, ``"+k"`` for the k-th
        landmark the hypothesis adds, in the order the log first sees them, and
        ``"outlier"`` for an observation it takes as an outlier). The stronger
        level may still refute some of them afterwards (``statistics['survivors']`` counts
        those left).
    rank : callable, optional
        Called with the survivors' report at ``hull`` (a :class:`Solution`) before the
        stronger level: it may order it and put unreported survivors in it (see
        :data:`Rank`); the stronger level then follows its order. Without it, the report
        is ranked by fewest outliers, fewest landmarks, then smallest boxes, and
        ``Solution.unreported`` holds the other survivors' assignments.
    prove : callable, optional
        Called with a full assignment found before the exhaustive search goes on (the
        guess's leaf, :mod:`.guess`, then the dive's, :mod:`.dive`) as a hypothesis, and
        the stage of the schedule whose budget it may spend on it (``"guess_proof"`` for
        the guess, else ``"early_proof"``): it may prove it consistent (set its
        ``status`` to proven and its ``witness``), as the witness search does. A proven
        leaf is then reported proven whatever the budget leaves for the stages after the
        search (a witness lies in every sound box of its hypothesis). Without it there is
        no guess.
    **overrides
        Fields of :class:`~cuikslam.options.SolveOptions` replacing those of ``options``
        (``solve_unknown(log, consistency="hull", max_nodes=1000)``); those of the stages
        after the search (``NOT_SEARCH_OPTIONS``) are refused.

    Returns
    -------
    Solution
        ``complete`` is False when a budget stopped the search; its messages then name the
        unexplored subtrees and ``statistics['unexplored_subtrees']`` counts them.
    """
    options = SolveOptions.merged(options, overrides, "solve_unknown", NOT_SEARCH_OPTIONS)
    start = time.perf_counter()
    ensure_round_to_nearest()
    problem = build_problem(log)
    explorer = Explorer.of(problem, options)
    explorer.deadline = deadline
    max_nodes = options.max_nodes
    messages: list[str] = []
    explorer.joins = True
    root = explorer.root()
    tally = Tally(explorer, on_survivor)
    tally.envelope.set_root(root)
    tracker = None if progress is None else ProgressTracker(problem, progress)
    found = tally.add if tracker is None else _both(tally.add, tracker.survivor)
    outcome = _Outcome([], [], None)
    keep = max(1, options.max_hypotheses)
    if root is not None:
        with explorer.walking(deadline) as walk:
            limit = SearchLimit(walk, max_nodes)
            diving = SearchLimit(SCHEDULE.share(limit.deadline, "dive"), max_nodes)
            early, proof = early_hypothesis(explorer, root, diving, prove, tracker)
            if proof is not None and tracker is not None:
                tracker.proven = 1
            maintenances = explorer.graph.maintenances
            outcome = explore(
                explorer, root, limit, keep, found, tracker, reserve=keep,
                pinned=[] if early.leaf is None else [early.leaf],
            )  # fmt: skip
        if early.leaf is not None:
            [early.leaf] = outcome.pinned
        explorer.expansions.clear()  # what the search did not take back: its memory
        for node in outcome.unexplored:  # the truth may lie under any of them
            tally.envelope.add(node)
        unexplored = [p for n in outcome.unexplored for p in lane_paths(n, explorer.n_named)]
        if outcome.stop_reason is not None and not outcome.survivors and not early.finished:
            # nothing found: the stages after the search have nothing to decide, so the
            # dive goes on with what they would have had (less a reserve for its leaf)
            if explorer.graph.maintenances != maintenances:
                root = explorer.restart()
                early.restart()
            more = SearchLimit(SCHEDULE.share(deadline, "walk"), max_nodes)
            early = dive(explorer, root, more, early, tracker=tracker)
            proof = proof or _proven(explorer, early, prove, tracker)
        if join_leaf(explorer, tally, early, unexplored):
            ranked = _best(explorer, [*outcome.survivors, *outcome.reserve, early.leaf], 2 * keep)
            outcome.survivors, outcome.reserve = ranked[:keep], ranked[keep:]
    else:
        proof, unexplored = None, []
    solution = finish_search(
        log, explorer, tally, outcome.survivors, unexplored, outcome.stop_reason, options,
        None, start, messages, rank=rank, reserve=outcome.reserve, unexplored_covered=True,
    )  # fmt: skip
    if proof is not None:
        keep_proof(solution, proof)
    return solution


def _both(first: Callable[[Node], None], second: Callable[[Node], None]) -> Callable[[Node], None]:
    def call(node: Node) -> None:
        first(node)
        second(node)

    return call


def _proven(
    explorer: Explorer,
    early: Dive,
    prove: Prove | None,
    tracker: ProgressTracker | None,
) -> Hypothesis | None:
    """:func:`.dive.prove_leaf`, the proof counted by ``tracker``."""
    proof = prove_leaf(explorer, early.leaf, prove)
    if proof is not None and tracker is not None:
        tracker.proven = 1
    return proof
