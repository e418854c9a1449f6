"""One task of the distributed correspondence search: a pure function that explores
subtrees of the search tree and returns a small, picklable, mergeable result.

A subtree is named by its *prefix*: the decisions of its root and its position in the
tree. :func:`explore_prefixes` builds a fresh explorer of the log (the problem is cached
per worker thread and search), replays its prefixes from the root, searches their
subtrees depth first with :func:`~.search.explore` until its work quantum, a node
allowance or the deadline stops it, and returns a :class:`SubtreeResult`. The client
side is :mod:`.distributed`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import Budget, deadline_after
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.problem import Problem, build_problem
from cuikslam.hypotheses.search import _rank_key, explore
from cuikslam.hypotheses.tally import MAX_TALLIED, Tally
from cuikslam.hypotheses.tree import Node, SearchLimit, SearchStatistics
from cuikslam.log.records import Log
from cuikslam.options import SolveOptions

__all__ = [
    "Material",
    "Prefix",
    "SubtreeResult",
    "TaskOptions",
    "explore_prefixes",
    "replay_all",
]

Prefix = tuple[tuple[int, ...], tuple[int, ...]]
"""A subtree: its root's *position* (index among its siblings at each depth, so that
positions sort in depth-first order) and its *decisions* (landmark numbers)."""
_NOT_SUMMED = {
    "peak_frontier",
    "explored_fraction",
    "survivors",
    "unexplored_subtrees",
    "dive_nodes",
    "dive_discrepancies",
    "dive_leaf_added",
}
"""Statistics a task does not add to the client's (the dive runs on the client)."""


@dataclass(frozen=True)
class TaskOptions:
    """What every task of one search shares (picklable, small)."""

    key: str
    """Names the search: a worker builds the problem once per key."""
    search: SolveOptions
    """The search's options (a worker's explorer is made from them)."""
    keep: int
    """Best-ranked survivors returned."""
    all_survivors: bool
    """Return the decisions of every survivor (else the first ``MAX_TALLIED``)."""
    quantum_s: float | None
    deadline: float | None
    """Epoch seconds (:func:`time.time`) at which the whole search stops (the wall-clock
    cap of its budget; None without one)."""


@dataclass
class Material:
    """What the client needs to rebuild a survivor's node without replaying it."""

    lo: np.ndarray
    hi: np.ndarray
    rows: np.ndarray
    """Its factor rows beyond the root's."""
    blocks: tuple[int, ...]
    level: str


@dataclass
class _Quantum(SearchLimit):
    """A budget that also stops after ``cpu_until`` (:func:`time.thread_time`)."""

    cpu_until: float | None = None

    def exhausted(self, nodes: int) -> str | None:
        reason = super().exhausted(nodes)
        if reason is None and self.cpu_until is not None and time.thread_time() > self.cpu_until:
            return "work quantum"
        return reason


@dataclass
class SubtreeResult:
    """What a task found in its subtrees; results merge by concatenation and sums."""

    prefixes: list[Prefix]
    survivors: np.ndarray
    """Decisions of the survivors, one row each."""
    positions: np.ndarray
    """Their positions (one row each: they sort in depth-first order)."""
    n_survivors: int
    best: list[tuple[Any, tuple[int, ...], tuple[int, ...], Material | None]]
    """(rank key, position, decisions, material) of the best-ranked survivors; the
    material when the rank key is at most the task's ``threshold``."""
    hull_lo: np.ndarray
    hull_hi: np.ndarray
    """The envelope of the task's survivors, flat (:meth:`.envelope.Envelope.boxes_of`)."""
    counts: dict[str, int]
    """Fields of :class:`~.tree.SearchStatistics` that add up."""
    peak_frontier: int
    done: float
    """Share of the whole tree this task decided."""
    unexplored: list[Prefix]
    """Pending prefixes when the quantum or the deadline stopped it (the next one last)."""
    lost_on_replay: int
    replayed: int
    """Nodes expanded again to reach the prefixes (not counted in ``counts``)."""
    replay_s: float
    cpu_s: float
    """CPU seconds of the task's thread, replay included."""

    @property
    def expanded(self) -> int:
        return self.counts["branch_points"]


_local = threading.local()


def _problem(log: Log, key: str) -> Problem:
    """The problem of ``log``, built once per search and worker thread."""
    cached = getattr(_local, "problem", None)
    if cached is None or cached[0] != key:
        cached = (key, build_problem(log))
        _local.problem = cached
    return cached[1]


def replay_all(
    explorer: Explorer, root: Node, prefixes: list[tuple[int, ...]]
) -> list[Node | None]:
    """The nodes reached by ``prefixes`` (sorted), sharing the expansions of common
    decisions; None where a step is refuted or is not a candidate."""
    path: list[Node | None] = [root]
    current: list[int] = []
    out: list[Node | None] = []
    for prefix in prefixes:
        common = 0
        while common < min(len(current), len(prefix)) and current[common] == prefix[common]:
            common += 1
        del path[common + 1 :], current[common:]
        node = path[-1]
        for number in prefix[common:]:
            if node is not None:
                kids, _ = explorer.children(node)
                node = next((c for c in kids if c.assigned[0] == number), None)
            path.append(node)
            current.append(number)
        out.append(node)
    return out


def explore_prefixes(
    log: Log,
    prefixes: list[Prefix],
    options: TaskOptions,
    max_nodes: int | None,
    threshold: Any = None,
) -> SubtreeResult:
    """Explore the subtrees of ``prefixes``: a pure function of its arguments (but for
    where a time quantum or the deadline stops it, which ``unexplored`` reports).

    Parameters
    ----------
    log : Log
        The log being solved.
    prefixes : list of Prefix
        Roots of the subtrees: (position, decisions) each, in depth-first order.
    options : TaskOptions
        The search's options.
    max_nodes : int or None
        Node expansions this task may make (the work quantum in nodes).
    threshold : rank key, optional
        Best-ranked survivors whose rank key is at most this (all without one) come with
        their :class:`Material`.

    Returns
    -------
    SubtreeResult
        Counts exclude the replay of the prefixes (the client counted those nodes).
    """
    cpu = time.thread_time()
    ensure_round_to_nearest()
    problem = _problem(log, options.key)
    explorer = Explorer.of(problem, options.search)
    deadline = _local_deadline(options.deadline)
    explorer.deadline = deadline
    root = explorer.root()
    root_rows = (
        set() if root is None else {r.tobytes() for r in explorer.graph.rows_of(root.overlay)}
    )
    by_decisions = sorted(prefixes, key=lambda p: p[1])  # common decisions replayed once
    starts = [None] * len(prefixes)
    if root is not None:
        starts = replay_all(explorer, root, [p[1] for p in by_decisions])
    order = sorted(range(len(prefixes)), key=lambda i: by_decisions[i][0])
    kept = [starts[i] for i in order if starts[i] is not None]
    replayed, replay_s = explorer.stats.branch_points, time.thread_time() - cpu
    explorer.stats = SearchStatistics()
    applications = explorer.graph.applications
    tally = Tally(explorer, None)
    decided: list[list[int]] = []
    placed: list[tuple[int, ...]] = []
    position = {tuple(d): pos for pos, d in prefixes}
    expand = explorer.children

    def children(node: Node) -> tuple[list[Node], int]:
        kids, n_options = expand(node)
        here = position.pop(tuple(node.decisions()), ())
        for i, kid in enumerate(kids):
            position[tuple(kid.decisions())] = (*here, i)
        return kids, n_options

    explorer.children = children  # each node's position, while it waits on the stack

    def found(node: Node) -> None:
        at = position.pop(tuple(node.decisions()), ())
        if options.all_survivors or len(decided) < MAX_TALLIED:
            decided.append(node.decisions())
            placed.append(at)
        best_at[tuple(node.decisions())] = at
        tally.envelope.add(node)

    best_at: dict[tuple[int, ...], tuple[int, ...]] = {}

    quantum = None if options.quantum_s is None else time.thread_time() + options.quantum_s
    outcome = explore(explorer, kept, _Quantum(deadline, max_nodes, quantum), options.keep, found)
    stats = explorer.stats
    stats.operator_applications += explorer.graph.applications - applications

    counts = {k: v for k, v in asdict(stats).items() if k not in _NOT_SUMMED}
    n = len(problem.decisions)
    return SubtreeResult(
        prefixes=list(prefixes),
        survivors=np.array(decided, dtype=np.int32).reshape(len(decided), n),
        positions=np.array(placed, dtype=np.int32).reshape(len(placed), n),
        n_survivors=stats.survivors,
        best=[
            (key, best_at[d], d, _material(explorer, s, root_rows, key, threshold))
            for s in outcome.survivors
            for d, key in [(tuple(s.decisions()), _rank_key(explorer, s))]
        ],
        hull_lo=tally.envelope.lo,
        hull_hi=tally.envelope.hi,
        counts=counts,
        peak_frontier=stats.peak_frontier,
        done=float(stats.explored_fraction),
        unexplored=[(position[d], d) for u in outcome.unexplored for d in [tuple(u.decisions())]],
        lost_on_replay=len(starts) - len(kept),
        replayed=replayed,
        replay_s=replay_s,
        cpu_s=time.thread_time() - cpu,
    )


def _material(
    explorer: Explorer, node: Node, root_rows: set[bytes], key: Any, threshold: Any
) -> Material | None:
    if threshold is not None and key > threshold:
        return None
    lo, hi = explorer.graph.materialize(node.overlay)
    rows = explorer.graph.rows_of(node.overlay)
    own = np.array([r.tobytes() not in root_rows for r in rows], dtype=np.bool_)
    return Material(lo, hi, rows[own], node.blocks, node.level)


def _local_deadline(epoch: float | None) -> Budget | None:
    """A budget of the wall clock left before ``epoch`` (None: none; the task's quantum
    bounds its work)."""
    return None if epoch is None else deadline_after(epoch - time.time())
