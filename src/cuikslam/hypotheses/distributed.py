"""The correspondence search on a Dask cluster: the client's side.

The search tree of :mod:`.search` is split into subtrees, each named by its *prefix* (the
decisions of its root). A worker explores a list of prefixes with
:func:`~.subtrees.explore_prefixes`, a pure function of (log, prefixes, options): it replays the
prefixes from the root, searches their subtrees depth first and returns a small
:class:`SubtreeResult` (survivors as decisions, their best-ranked, the hull of their pose
boxes, counts, and the prefixes left pending when its work quantum ran out). The client
expands the top of the tree breadth first into a few prefixes per worker, submits them,
resubmits pending prefixes (split among idle workers: large subtrees are split again) and
merges the results; :func:`~.finish.finish_search` then does what follows the search,
exactly as in one process. The result's envelope joins the survivors' boxes the workers
send; the subtrees a budget leaves unexplored (on a worker or never sent) are not
materialized on the client, so the envelope then falls back to the root's boxes, which hold
the truth whatever the correspondence (wider than one process's envelope, never wrong). A
task lost with its worker is run again by Dask (or
resubmitted here): a subtree is counted once its task's result has arrived, never before.

Dask is imported only when a search runs on a cluster; :mod:`cuikslam.cluster` makes
the client (``pip install "cuikslam[distributed]"``).
"""

from __future__ import annotations

import math
import time
import uuid
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import COSTS, SCHEDULE, Budget, deadline_after, expired, remaining, spend
from cuikslam.hypotheses.bisection import Bisection, allotment, refute_by_bisection
from cuikslam.hypotheses.dive import Dive, Prove, early_hypothesis, join_leaf, keep_proof
from cuikslam.hypotheses.explorer import Explorer
from cuikslam.hypotheses.finish import Rank, finish_search
from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.search import NOT_SEARCH_OPTIONS, _rank_key
from cuikslam.hypotheses.subtrees import (
    Material,
    Prefix,
    SubtreeResult,
    TaskOptions,
    explore_prefixes,
    replay_all,
)
from cuikslam.hypotheses.tally import Tally
from cuikslam.hypotheses.tree import Node, SearchLimit, SearchStatistics
from cuikslam.log.records import Log
from cuikslam.options import SolveOptions
from cuikslam.outcome.solution import Solution

__all__ = [
    "SubtreeResult",
    "TaskOptions",
    "explore_prefixes",
    "search_distributed",
]

DEFAULT_QUANTUM_S = 0.5
"""CPU seconds a task explores (after its replay) before it returns its pending subtrees
(to be split again): CPU, not wall, so that a loaded machine does not shorten the tasks
and multiply the replays."""
SPLIT_PER_SLOT = 3
"""Prefixes the client's breadth-first expansion aims at, per worker thread."""
MAX_BATCH = 8
"""Prefixes one task explores at most (they share the replay of their common decisions)."""


# ------------------------------------------------------------------------- the client
def _epoch(deadline: Budget | None) -> float | None:
    """The wall-clock cap of ``deadline`` as epoch seconds, for tasks on other machines
    (None without one). The work of the tasks is bounded by their quanta, and counted on
    the client as their results come back, so where a budget cuts a search on a cluster
    depends on the order in which results arrive."""
    seconds = remaining(deadline)
    return None if math.isinf(seconds) else time.time() + seconds


def _refute_on_cluster(
    client: Any,
    slots: int,
    bisections: list[Bisection],
    deadline: Budget | None,
    max_parts: int,
    max_total_parts: int,
) -> list[bool]:
    """:func:`~.bisection.refute_by_bisection` with the bisections dealt out to ``slots``
    tasks: each keeps its share of the budget (:func:`~.bisection.allotment`), so the
    result is the one process's. Only the budget's wall-clock cap travels, as seconds left
    (clocks of other machines differ): the parts bound the work."""
    if len(bisections) < 2 or slots < 2:
        return refute_by_bisection(bisections, deadline, max_parts, max_total_parts)
    each = allotment(len(bisections), max_parts, max_total_parts)
    seconds = remaining(deadline)
    seconds = None if math.isinf(seconds) else seconds
    chunks = [list(range(i, len(bisections), slots)) for i in range(slots)]
    futures = [
        client.submit(
            _refute_task, [bisections[k] for k in chunk], seconds, each, pure=False
        )
        for chunk in chunks
        if chunk
    ]  # fmt: skip
    refuted = [False] * len(bisections)
    for chunk, flags in zip([c for c in chunks if c], client.gather(futures), strict=True):
        for k, flag in zip(chunk, flags, strict=True):
            refuted[k] = flag
    return refuted


def _refute_task(bisections: list[Bisection], seconds: float | None, each: int) -> list[bool]:
    """A worker's share of the survivors' bisections."""
    ensure_round_to_nearest()
    deadline = deadline_after(seconds)
    return refute_by_bisection(bisections, deadline, each, each * len(bisections))


def search_distributed(
    log: Log,
    options: SolveOptions | None = None,
    *,
    client: Any,
    progress: Callable[[int, int], None] | None = None,
    deadline: Budget | None = None,
    on_survivor: Callable[[list[str]], None] | None = None,
    quantum_s: float | None = DEFAULT_QUANTUM_S,
    quantum_nodes: int | None = None,
    on_result: Callable[[SubtreeResult], None] | None = None,
    on_unexplored: Callable[[list[Prefix]], None] | None = None,
    rank: Rank | None = None,
    prove: Prove | None = None,
    **overrides: Any,
) -> Solution:
    """:func:`~cuikslam.hypotheses.solve_unknown` with its subtrees explored on ``client``'s
    workers (a :class:`distributed.Client`); the same parameters, and:

    Parameters
    ----------
    client : distributed.Client
        The cluster.
    quantum_s, quantum_nodes : float or int, optional
        A task returns its pending subtrees after this many CPU seconds or node
        expansions; they are submitted again, split among idle workers.
    on_result : callable, optional
        Called with each task's result as it arrives (for tests and benchmarks).
    on_unexplored : callable, optional
        Called with every prefix a budget stop left unexplored (the message names five).

    Returns
    -------
    Solution
        As :func:`~cuikslam.hypotheses.solve_unknown`'s; ``statistics`` also holds
        ``tasks``, ``resubmitted`` (tasks lost with a worker and run again),
        ``lost_on_replay`` and ``worker_cpu_s``; ``peak_frontier`` is the largest of
        any task.
    """
    options = SolveOptions.merged(options, overrides, "search_distributed", NOT_SEARCH_OPTIONS)
    max_nodes = options.max_nodes
    start = time.perf_counter()
    ensure_round_to_nearest()
    explorer = Explorer.of(build_problem(log), options)
    explorer.deadline = deadline
    messages: list[str] = []
    root = explorer.root()
    tally = Tally(explorer, on_survivor)
    tally.envelope.set_root(root)  # the fallback for unexplored prefixes
    keep = max(1, options.max_hypotheses)
    with explorer.walking(deadline) as searching:  # the rest decides its survivors
        run = _Run(explorer, searching, max_nodes, keep)
        found: list[Node] = []
        split_s = merge_s = 0.0
        slots = max(1, sum(client.nthreads().values()))
        early = Dive()
        proof = None
        if root is not None:
            diving = SearchLimit(SCHEDULE.share(searching, "dive"), max_nodes)
            early, proof = early_hypothesis(explorer, root, diving, prove)
            prefixes = run.split(root, SPLIT_PER_SLOT * slots)
            split_s = time.perf_counter() - start
            task = TaskOptions(
                key=uuid.uuid4().hex, search=options, keep=keep,
                all_survivors=on_survivor is not None, quantum_s=quantum_s,
                deadline=_epoch(searching),
            )  # fmt: skip
            results = run.on_cluster(
                client, log, prefixes, task, slots, quantum_nodes, progress, on_result
            )
            merge_start = time.perf_counter()
            found = _merge(explorer, root, tally, results, run.best)
            merge_s = time.perf_counter() - merge_start
    stats = explorer.stats
    stats.explored_fraction = min(1.0, run.done)
    if join_leaf(explorer, tally, early, run.unexplored()):
        found = sorted([*found, early.leaf], key=lambda n: _rank_key(explorer, n))[:keep]
    if on_unexplored is not None:
        on_unexplored(sorted(run.left))
    finish_start = time.perf_counter()
    solution = finish_search(
        log, explorer, tally, found, run.unexplored(), run.stop_reason(), options,
        progress, start, messages,
        lambda *job: _refute_on_cluster(client, slots, *job), rank,
    )  # fmt: skip
    if proof is not None:
        keep_proof(solution, proof)
    solution.statistics.update(
        tasks=run.tasks, resubmitted=run.resubmitted, lost_on_replay=run.lost_on_replay,
        worker_cpu_s=run.cpu_s,
    )  # fmt: skip
    solution.timings.update(
        split_s=split_s, client_s=run.client_s, merge_s=merge_s,
        finish_s=time.perf_counter() - finish_start,
    )  # fmt: skip
    return solution


class _Run:
    """The client's side of one search: splitting, submitting, budgets, the account."""

    def __init__(
        self, explorer: Explorer, deadline: Budget | None, max_nodes: int | None, keep: int
    ):
        self.explorer = explorer
        self.keep = keep
        self.best: list = []
        """The best-ranked survivors so far, as in :attr:`SubtreeResult.best`."""
        self.deadline = deadline
        self.max_nodes = max_nodes
        self.done = 0.0
        self.expanded = 0
        self.pending: deque[list[Prefix]] = deque()
        self.left: list[Prefix] = []
        """Prefixes a budget stop leaves unexplored."""
        self.tasks = self.resubmitted = self.lost_on_replay = 0
        self.cpu_s = 0.0
        self.client_s = 0.0
        """Seconds the client spent on the tasks' results (receiving, splitting, submitting)."""
        self._budget_hit: str | None = None

    def split(self, root: Node, target: int) -> list[Prefix]:
        """Expand the tree breadth first until ``target`` nodes wait; their prefixes."""
        n = len(self.explorer.problem.decisions)
        frontier: deque[tuple[Node, tuple[int, ...]]] = deque([(root, ())])
        leaves = []
        while frontier and len(frontier) + len(leaves) < target:
            if self._exhausted():
                break
            node, at = frontier.popleft()
            if node.depth == n:
                leaves.append((node, at))
                continue
            kids, options = self.explorer.children(node)
            self.expanded += 1
            self.done += node.share * (options - len(kids)) / options
            frontier.extend((kid, (*at, i)) for i, kid in enumerate(kids))
        return sorted((at, tuple(node.decisions())) for node, at in [*frontier, *leaves])

    def _exhausted(self) -> bool:
        if expired(self.deadline):
            self._budget_hit = f"{self.deadline.meter.bound} budget"
        elif self.max_nodes is not None and self.expanded >= self.max_nodes:
            self._budget_hit = "node budget"
        return self._budget_hit is not None

    def on_cluster(
        self,
        client: Any,
        log: Log,
        prefixes: list[Prefix],
        options: TaskOptions,
        slots: int,
        quantum_nodes: int | None,
        progress: Callable[[int, int], None] | None,
        on_result: Callable[[SubtreeResult], None] | None,
    ) -> list[SubtreeResult]:
        from distributed import as_completed
        from distributed.scheduler import KilledWorker

        log_future = client.scatter(log, broadcast=True)
        self.pending.extend([p] for p in prefixes)
        results: list[SubtreeResult] = []
        running = as_completed()
        batches: dict[Any, tuple[list[Prefix], int | None]] = {}
        allotted = 0

        def submit() -> None:
            nonlocal allotted
            while self.pending and len(batches) < 2 * slots and not self._exhausted():
                allowance = quantum_nodes
                if self.max_nodes is not None:
                    spare = self.max_nodes - self.expanded - allotted
                    if spare <= 0:
                        break
                    allowance = spare if allowance is None else min(allowance, spare)
                    allotted += allowance
                batch = self.pending.popleft()
                future = client.submit(
                    explore_prefixes, log_future, batch, options, allowance, self.threshold(),
                    pure=False,
                )  # fmt: skip
                batches[future] = (batch, allowance)
                running.add(future)
                self.tasks += 1

        submit()
        for future in running:
            batch, allowance = batches.pop(future)
            if self.max_nodes is not None:
                allotted -= allowance
            received = time.perf_counter()
            try:
                result = future.result()
            except KilledWorker:  # Dask gave up on it after several lost workers: again
                self.resubmitted += 1
                self.pending.appendleft(batch)
                submit()
                continue
            results.append(result)
            self._account(result, slots - len(batches))
            submit()
            self.client_s += time.perf_counter() - received
            if on_result is not None:
                on_result(result)
            if progress is not None:
                progress(int(1000 * min(1.0, self.done)), 1000)
            if not batches and self.pending and self._exhausted():
                break
        for batch in self.pending:
            self.left.extend(batch)
        self.pending.clear()
        return results

    def threshold(self) -> Any:
        """The rank key of the ``keep``-th best survivor so far (None: fewer so far)."""
        return self.best[-1][0] if len(self.best) >= self.keep else None

    def _account(self, result: SubtreeResult, idle: int) -> None:
        """Count a task's work; its pending prefixes wait, split among idle workers."""
        merged = sorted([*self.best, *result.best], key=lambda b: (b[0], b[1]))
        self.best = merged[: self.keep]
        self.done += result.done
        self.expanded += result.expanded
        spend(
            self.deadline,
            COSTS["node"] * result.expanded
            + COSTS["operator"] * result.counts.get("operator_applications", 0),
        )
        self.lost_on_replay += result.lost_on_replay
        self.cpu_s += result.cpu_s
        todo = sorted(result.unexplored)
        if not todo:
            return
        chunks = max(1, min(len(todo), idle + 1 if not self.pending else 1))
        chunks = max(chunks, math.ceil(len(todo) / MAX_BATCH))
        self.pending.extend(todo[i::chunks] for i in range(chunks))

    def unexplored(self) -> list[list[int]]:
        """The decisions of the prefixes left, the next one (depth first) last."""
        return [list(p[1]) for p in sorted(self.left, reverse=True)]

    def stop_reason(self) -> str | None:
        if not self.left:
            return None
        return self._budget_hit or "work budget"


def _merge(
    explorer: Explorer, root: Node, tally: Tally, results: list[SubtreeResult], best: list
) -> list[Node]:
    """Fold the tasks' results into ``explorer.stats`` and ``tally`` as one depth-first
    search would; return the ``best`` survivors as nodes of ``explorer``."""
    stats = explorer.stats
    for result in results:
        for key, value in result.counts.items():
            setattr(stats, key, getattr(stats, key) + value)
        stats.survivors += result.n_survivors
        stats.peak_frontier = max(stats.peak_frontier, result.peak_frontier)
        tally.add_boxes(result.hull_lo, result.hull_hi)
    kept = [r for r in results if len(r.survivors)]
    if kept:
        decided = np.concatenate([r.survivors for r in kept])
        placed = np.concatenate([r.positions for r in kept])
        for i in np.lexsort(placed.T[::-1]):  # depth-first order
            tally.add_assignment(decided[i].tolist())
    nodes = {b[2]: _rebuilt(explorer, b[2], b[3]) for b in best if b[3] is not None}
    missing = sorted(b[2] for b in best if b[3] is None)
    if missing:  # replayed, outside the search's counts
        saved, applications = explorer.stats, explorer.graph.applications
        explorer.stats = SearchStatistics()
        replayed = replay_all(explorer, root, missing)
        explorer.stats, explorer.graph.applications = saved, applications
        nodes.update((tuple(n.decisions()), n) for n in replayed if n is not None)
    return [nodes[b[2]] for b in best if b[2] in nodes]


def _rebuilt(explorer: Explorer, decisions: tuple[int, ...], material: Material) -> Node:
    """The node a worker found, in the client's graph (whose base set is the root's rows)."""
    ids = explorer.graph.intern(material.rows) if len(material.rows) else np.zeros(0, np.int64)
    overlay = explorer.graph.overlay_of(material.lo, material.hi, np.unique(ids))
    assigned = None
    for number in decisions:
        assigned = (number, assigned)
    outliers = tuple(k for k, number in enumerate(decisions) if number == OUTLIER)
    return Node(
        len(decisions), overlay, material.blocks, assigned, level=material.level, outliers=outliers
    )
