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
subtrees left unexplored (each named by the decisions of its root). Every operation on a
node names the node's overlay (:class:`~._shared.SharedGraph`), so no step can act on
another hypothesis by mistake.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from dataclasses import asdict, dataclass, replace

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import portion
from cuikslam.hypotheses._shared import EMPTY_OVERLAY, Overlay, SharedGraph
from cuikslam.hypotheses.bisection import Bisection, refute_by_bisection
from cuikslam.hypotheses.local import LocalCheck
from cuikslam.hypotheses.problem import (
    Decision,
    Problem,
    build_problem,
    observation_rows,
    unseen_rows,
)
from cuikslam.log.records import Log
from cuikslam.narrowing.consistency import (
    DEFAULT_LEVEL,
    StrengthenReport,
    resolve_level,
    strengthen,
)
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL
from cuikslam.options import SolveOptions
from cuikslam.results.solution import Hypothesis, Solution
from cuikslam.results.summary import describe, summarize, summary_to_json

__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "DEFAULT_STRENGTHEN_DURING",
    "DEFAULT_STRENGTHEN_LIMIT",
    "SearchStatistics",
    "solve_unknown",
]

DEFAULT_MAX_HYPOTHESES = SolveOptions.max_hypotheses
"""Survivors reported in detail at most (the best-ranked); the search itself explores all."""
DEFAULT_STRENGTHEN_LIMIT = SolveOptions.strengthen_limit
"""Survivors narrowed to the stronger consistency level at most (else the best-ranked)."""
BEST_ATTEMPTS = 10
"""Beyond ``strengthen_limit`` survivors, the best-ranked are tried until one is not refuted."""
DEFAULT_STRENGTHEN_DURING = SolveOptions.strengthen_during
"""Decisions (the first ones) whose children get ``lp`` during the search when ambiguous."""
SEARCH_SHARE = 0.8
"""Share of the time budget the search itself may use: the rest is left to deciding its
survivors (bisection, the stronger level), even when the search is cut short."""
BISECTION_SHARE = 0.5
"""Share of the search's time left that bisection may use on the survivors."""
BISECTION_PARTS = 512
"""Parts each survivor's bisection may narrow at most."""
BISECTION_TOTAL_PARTS = 4096
"""Parts the bisections of all survivors together may narrow at most."""
BISECTION_PARTS_PER_NODE = 4
"""Parts the bisections may narrow per node the search created (at least
``BISECTION_MIN_PARTS``): bisection costs about as much as the search itself did."""
BISECTION_MIN_PARTS = 256
LEAF_BISECTION_PARTS = 8
"""Parts a leaf's bisection may narrow when the search reaches it, in logs with negative
information (a ``sensor`` record): many wrong leaves fall within a few parts, and those
refuted are never counted as survivors. Without negative information the constraints are
not disjunctive, narrowing loses little, and bisecting every leaf cost 1.6 to 4 times the
search on worlds of thousands of consistent survivors."""
MAINTAIN_EVERY = 1024
"""Node expansions between two looks at the shared graph's housekeeping."""
MAX_TALLIED = 100_000
"""Survivors whose assignments the correspondence summary holds at most."""
SHOWN_PREFIXES = 5
"""Unexplored subtrees named in the message of a search stopped by its budget."""


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
    """Children whose window around the decided pose is inconsistent in that pose's frame."""
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

    def decisions(self) -> list[int]:
        """Landmark number of every decision made, oldest first."""
        out = []
        node = self.assigned
        while node is not None:
            out.append(node[0])
            node = node[1]
        return out[::-1]


@dataclass
class Budget:
    """When the search stops before it is complete (None: no limit)."""

    deadline: float | None = None
    """A :func:`time.perf_counter` value."""
    max_nodes: int | None = None

    def exhausted(self, nodes: int) -> str | None:
        """Why the search must stop now, or None."""
        if self.deadline is not None and time.perf_counter() > self.deadline:
            return "time budget"
        if self.max_nodes is not None and nodes >= self.max_nodes:
            return "node budget"
        return None


class Explorer:
    """Expands nodes of the search tree of one problem."""

    def __init__(
        self, problem: Problem, rtol: float, level: str, during: int, local: bool = True
    ) -> None:
        self.problem = problem
        self.stats = SearchStatistics()
        self.graph = SharedGraph(problem.lo, problem.hi, problem.ranked_vars, rtol, DEFAULT_ROUNDS)
        self.level = level
        self.during = during
        """The children of the first ``during`` decisions get ``lp`` when ambiguous."""
        self.n_named = len(problem.named)
        self.deadline: float | None = None
        """When the stronger level must stop (it then reports the level it reached)."""
        self.local = (
            LocalCheck(problem.pose_x, len(problem.lo), rtol, DEFAULT_ROUNDS, problem.sensor_x)
            if local
            else None
        )
        self._decisions_of: dict[Hashable, list[int]] = {}
        """Scan (a pose, or a pose and a sensor offset) -> its decisions, in order."""
        for k, d in enumerate(problem.decisions):
            self._decisions_of.setdefault(d.scan, []).append(k)
        self._done_xs, self._done_radii = self._completed_poses()
        self.leaf_parts = LEAF_BISECTION_PARTS if problem.has_sensor else 0
        """Parts of the bisection of each leaf (0: leaves are not bisected)."""
        self._pose_xs = np.array(sorted(problem.pose_x.values()), dtype=np.int64)

    # ---------------------------------------------------------------- precomputed
    def _completed_poses(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """x and radius variables of the poses whose scans are complete before decision k."""
        p = self.problem
        xs, radii = [], []
        for k in range(len(p.decisions) + 1):
            poses = p.completed_before(k) if p.has_sensor else []
            xs.append(np.array([p.pose_x[q] for q in poses], dtype=np.int64))
            radii.append(np.array([p.radius_var[q] for q in poses], dtype=np.int64))
        return xs, radii

    # ---------------------------------------------------------------- landmarks
    def landmark_xs(self, node: Node) -> np.ndarray:
        """x variable of every landmark of ``node``, by landmark number."""
        blocks = [self.problem.decisions[k].slot_x for k in node.blocks]
        return np.concatenate([self.problem.named_x, np.array(blocks, dtype=np.int64)])

    def bisection(self, node: Node) -> Bisection:
        """A bisection of ``node``'s box (:mod:`.bisection`)."""
        lo, hi, arrays = self.graph.standalone(node.overlay)
        return Bisection(lo, hi, arrays, self._pose_xs, self.landmark_xs(node))

    def refuted_leaf(self, node: Node) -> bool:
        """True when a bisection of ``leaf_parts`` parts proves the leaf ``node`` impossible."""
        if self.leaf_parts <= 0:
            return False
        refuted = refute_by_bisection([self.bisection(node)], self.deadline, self.leaf_parts)[0]
        self.stats.refuted_by_bisection += refuted
        return refuted

    def landmark_class(self, node: Node, number: int) -> str:
        if number < self.n_named:
            return self.problem.named_class[number]
        return self.problem.decisions[node.blocks[number - self.n_named]].landmark_class

    def seen_by(self, node: Node, scan: Hashable) -> set[int]:
        """Landmark numbers the ``scan`` (a pose, or a pose and a sensor offset: see
        :attr:`Decision.scan`) sees in ``node``: its named observations' landmarks and those
        of its unlabelled observations decided so far."""
        seen = set(self.problem.seen_named.get(scan, ()))
        mine = [j for j in self._decisions_of.get(scan, ()) if j < node.depth]
        if mine:
            wanted = set(mine)
            entry = node.assigned
            for j in range(node.depth - 1, mine[0] - 1, -1):
                if j in wanted:
                    seen.add(entry[0])
                entry = entry[1]
        return seen

    # ---------------------------------------------------------------- the tree
    def root(self) -> Node | None:
        """The node of no decisions: every shared constraint propagated; None when even that
        is proven empty (the log is inconsistent whatever the correspondence)."""
        graph = self.graph
        ids = graph.intern(self.problem.root_rows)
        overlay = graph.add_rows(EMPTY_OVERLAY, ids)
        if overlay is None:
            return None
        [overlay] = graph.rebase([overlay])  # the root becomes the base, its rows the base set
        node = Node(0, overlay, (), None)
        if self._breaks_class_prior(node):
            return None
        if self.problem.has_sensor:
            node = self._unseen_scans(node, self.problem.complete_at_root())
        return node

    def children(self, node: Node) -> tuple[list[Node], int]:
        """The children of ``node`` that are not proven impossible, in the order to explore
        them, and the number of options considered."""
        p, graph, stats = self.problem, self.graph, self.stats
        k = node.depth
        d = p.decisions[k]
        stats.branch_points += 1
        all_xs = self.landmark_xs(node)
        numbers = [
            n for n in range(len(all_xs)) if self.landmark_class(node, n) == d.landmark_class
        ]
        seen = self.seen_by(node, d.scan)
        kept = [n for n in numbers if n not in seen]
        stats.candidates += len(numbers) + 1
        stats.excluded_same_scan += len(numbers) - len(kept)
        options = len(kept) + 1
        xs = all_xs[kept]
        passed = graph.gate(node.overlay, d.sensor_x, xs, d.bearing_var, d.range_var)
        stats.gated += int(np.count_nonzero(~passed))
        order = self._nearest_first(node, d, xs[passed])
        ids = graph.intern(observation_rows(p, d, xs[passed][order]))
        out: list[Node] = []
        for i, number in enumerate(np.array(kept, dtype=np.int64)[passed][order].tolist()):
            overlay = graph.add_rows(node.overlay, ids[i : i + 1])
            if overlay is None:
                stats.proven_empty += 1
                continue
            child = self._after_decision(Node(k + 1, overlay, node.blocks, (number, node.assigned)))
            if child is not None:
                out.append(child)
        new: Node | None = Node(
            k + 1, node.overlay, (*node.blocks, k), (len(all_xs), node.assigned)
        )
        prior = p.class_priors.get(d.landmark_class)
        if prior is not None and prior.at_most is not None and len(numbers) >= prior.at_most:
            stats.refuted_by_class_prior += 1
            new = None
        if new is not None and p.has_sensor and len(self._done_xs[k]):
            overlay = self._add_unseen(
                new.overlay, self._done_xs[k], self._done_radii[k], np.array([d.slot_x])
            )
            new = None if overlay is None else replace(new, overlay=overlay)
        if new is not None:
            new = self._after_decision(new)
        if new is not None:
            out.append(new)
        stats.created += len(out)
        if len(out) > 1 and k < self.during and self.level != "hull":
            out = [c for c in (self.strengthen_node(c, "lp") for c in out) if c is not None]
        share = node.share / options
        return [replace(c, share=share) for c in out], options

    def _nearest_first(self, node: Node, d: Decision, xs: np.ndarray) -> np.ndarray:
        """The order in which to explore the candidate landmarks at x ``xs``: nearest first
        to where the observation puts the landmark (its slot's box), centre to centre.

        Depth-first, the first survivor is then usually found without backtracking (on a
        long log, a wrong early choice can survive hundreds of decisions in wide boxes).
        The order changes nothing else: every child is explored.
        """
        if len(xs) < 2:
            return np.arange(len(xs))
        slot = np.array([d.slot_x, d.slot_x + 1], dtype=np.int64)
        lo, hi = self.graph.values(node.overlay, np.concatenate([slot, xs, xs + 1]))
        with np.errstate(invalid="ignore", over="ignore"):
            centre = np.nan_to_num(0.5 * lo + 0.5 * hi, nan=0.0, posinf=0.0, neginf=0.0)
        n = len(xs)
        gap = np.hypot(centre[2 : 2 + n] - centre[0], centre[2 + n :] - centre[1])
        return np.argsort(gap, kind="stable")

    def _after_decision(self, child: Node) -> Node | None:
        """The class prior's separation, negative information once the decided observation
        completes its pose's scan, then the window of its pose narrowed in that pose's
        frame."""
        d = self.problem.decisions[child.depth - 1]
        if self._too_close(child, child.assigned[0]):
            self.stats.refuted_by_class_prior += 1
            return None
        if self.problem.has_sensor and d.completes_scan:
            child = self._unseen_scans(child, [d.pose])
        if child is None or self.local is None:
            return child
        if self.local.refutes(self.graph, child.overlay, d.pose, d.pose_x):
            self.stats.refuted_in_local_frame += 1
            return None
        return child

    def _breaks_class_prior(self, node: Node) -> bool:
        """The named landmarks alone break a class prior: too many of a class, two too close,
        or one outside its region (an empty box)."""
        p = self.problem
        for cls, prior in p.class_priors.items():
            if prior.at_most is not None and p.named_class.count(cls) > prior.at_most:
                self.stats.refuted_by_class_prior += 1
                return True
        lo, hi = self.graph.values(node.overlay, np.concatenate([p.named_x, p.named_x + 1]))
        if np.any(lo > hi) or any(self._too_close(node, n) for n in range(self.n_named)):
            self.stats.refuted_by_class_prior += 1
            return True
        return False

    def _too_close(self, node: Node, number: int) -> bool:
        """True when landmark ``number`` of ``node`` is proven closer to another landmark of
        its class than the class prior's ``min_separation``: the farthest points of their
        boxes are nearer than that (compared with a relative margin far above rounding)."""
        cls = self.landmark_class(node, number)
        prior = self.problem.class_priors.get(cls)
        if prior is None or prior.min_separation is None:
            return False
        xs = self.landmark_xs(node)
        others = [n for n in range(len(xs)) if n != number and self.landmark_class(node, n) == cls]
        if not others:
            return False
        mine = np.array([xs[number], xs[number] + 1], dtype=np.int64)
        cols = np.array([[xs[n], xs[n] + 1] for n in others], dtype=np.int64).ravel()
        a_lo, a_hi = self.graph.values(node.overlay, mine)
        o_lo, o_hi = self.graph.values(node.overlay, cols)
        o_lo, o_hi = o_lo.reshape(-1, 2), o_hi.reshape(-1, 2)
        with np.errstate(invalid="ignore", over="ignore"):
            span = np.maximum(a_hi - o_lo, o_hi - a_lo)  # farthest gap per axis, >= 0
            far2 = span[:, 0] * span[:, 0] + span[:, 1] * span[:, 1]
        d = prior.min_separation
        return bool(np.any(far2 * (1 + 1e-9) < d * d * (1 - 1e-9)))

    def _unseen_scans(self, node: Node, poses: list[int]) -> Node | None:
        """Add UNSEEN constraints between each of ``poses`` (whose scans ``node`` has fully
        decided) and every landmark it did not see; None when that proves ``node`` empty."""
        if not poses:
            return node
        p = self.problem
        landmark_xs = self.landmark_xs(node)
        seen = np.zeros((len(poses), len(landmark_xs)), dtype=np.bool_)
        for i, pose in enumerate(poses):
            for n in self.seen_by(node, pose):
                seen[i, n] = True
        pose_xs = np.array([p.pose_x[q] for q in poses], dtype=np.int64)
        radii = np.array([p.radius_var[q] for q in poses], dtype=np.int64)
        overlay = self._add_unseen(node.overlay, pose_xs, radii, landmark_xs, seen)
        return None if overlay is None else replace(node, overlay=overlay)

    def _add_unseen(
        self,
        overlay: Overlay,
        pose_xs: np.ndarray,
        radius_vars: np.ndarray,
        landmark_xs: np.ndarray,
        seen: np.ndarray | None = None,
    ) -> Overlay | None:
        """The branch of ``overlay`` plus UNSEEN constraints between the poses and the
        landmarks they did not see (``seen``: none by default) that are within reach."""
        if seen is None:
            seen = np.zeros((len(pose_xs), len(landmark_xs)), dtype=np.bool_)
        graph = self.graph
        pairs = graph.pairs_within_reach(overlay, pose_xs, radius_vars, landmark_xs, seen)
        if len(pairs) == 0:
            return overlay
        rows = unseen_rows(
            self.problem, pose_xs[pairs[:, 0]], radius_vars[pairs[:, 0]], landmark_xs[pairs[:, 1]]
        )
        self.stats.unseen_constraints += len(rows)
        out = graph.add_rows(overlay, graph.intern(rows))
        if out is None:
            self.stats.refuted_by_negative_information += 1
        return out

    # ---------------------------------------------------------------- stronger level
    def strengthen_node(self, node: Node, level: str) -> Node | None:
        """``node`` narrowed to ``level``; None when that proves it empty."""
        if level == "hull":
            return node
        graph = self.graph
        lo, hi, arrays = graph.standalone(node.overlay)
        report = StrengthenReport()
        result = strengthen(
            arrays, lo, hi, level, graph.rtol, DEFAULT_ROUNDS, deadline=self.deadline, report=report
        )
        self.stats.operator_applications += result.applications
        if result.is_empty:
            self.stats.refuted_by_consistency += 1
            return None
        overlay = graph.overlay_of(lo, hi, node.overlay.rows)
        return replace(node, overlay=overlay, level=report.level)

    # ---------------------------------------------------------------- replay
    def replay(self, prefix: list[int]) -> Node | None:
        """The node reached by the decisions ``prefix`` (landmark numbers); None when a step
        is proven impossible or not a candidate."""
        node = self.root()
        for number in prefix:
            if node is None:
                return None
            kids, _ = self.children(node)
            node = next((c for c in kids if c.assigned[0] == number), None)
        return node


@dataclass
class _Outcome:
    survivors: list[Node]
    unexplored: list[Node]
    stop_reason: str | None


def explore(
    explorer: Explorer,
    start: Node | list[Node],
    budget: Budget,
    keep: int,
    on_survivor: Callable[[Node], None] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> _Outcome:
    """Depth-first search of the subtree of ``start`` (of each start node in turn).

    Every survivor is counted (and passed to ``on_survivor``); the ``keep`` best-ranked are
    returned. A budget stop returns the pending subtrees as ``unexplored``.
    """
    stats, graph = explorer.stats, explorer.graph
    n_decisions = len(explorer.problem.decisions)
    stack = start[::-1] if isinstance(start, list) else [start]
    survivors: list[Node] = []
    done = 0.0
    expanded = 0
    reason = None
    while stack:
        reason = budget.exhausted(expanded)
        if reason is not None:
            break
        node = stack.pop()
        if node.depth == n_decisions:
            done += node.share
            if explorer.refuted_leaf(node):
                continue
            stats.survivors += 1
            survivors.append(node)
            if on_survivor is not None:
                on_survivor(node)
            if len(survivors) > 2 * keep:
                survivors = _best(explorer, survivors, keep)
            continue
        kids, options = explorer.children(node)
        expanded += 1
        done += node.share * (options - len(kids)) / options
        stack.extend(reversed(kids))
        stats.peak_frontier = max(stats.peak_frontier, len(stack))
        if expanded % MAINTAIN_EVERY == 0:
            stack, survivors = _maintain(graph, stack, survivors)
            if progress is not None:
                progress(int(1000 * done), 1000)
    stats.explored_fraction = min(1.0, done)
    return _Outcome(_best(explorer, survivors, keep), stack if reason else [], reason)


class _Tally:
    """What every survivor contributes to the summary, reported in detail or not."""

    def __init__(self, explorer: Explorer, on_survivor: Callable[[list[str]], None] | None):
        self.explorer = explorer
        self.on_survivor = on_survivor
        self.assignments: list[list[str] | None] = []
        self.new_mark = "+"
        """Prefix of the landmarks a hypothesis adds (longer if a log id starts with it)."""
        while any(name.startswith(self.new_mark) for name in explorer.problem.named):
            self.new_mark += "+"
        self._position: dict[tuple[int, ...], int] = {}
        pose_ids = sorted(explorer.problem.pose_x)
        xs = np.array([explorer.problem.pose_x[q] for q in pose_ids], dtype=np.int64)
        self._cols = (xs[:, None] + np.arange(3)).ravel()
        self._lo = np.full(len(self._cols), np.inf)
        self._hi = np.full(len(self._cols), -np.inf)

    def add(self, node: Node) -> None:
        self.add_assignment(node.decisions())
        self.add_boxes(*self.explorer.graph.values(node.overlay, self._cols))

    def add_assignment(self, decisions: list[int]) -> None:
        """A survivor's assignment, given by its decisions (landmark numbers)."""
        p = self.explorer.problem
        tallied = len(self.assignments) < MAX_TALLIED
        if tallied or self.on_survivor is not None:
            assignment = [""] * p.n_observations
            for position, n in p.named_assignment.items():
                assignment[position] = p.named[n]
            n_named, mark = len(p.named), self.new_mark
            for d, n in zip(p.decisions, decisions, strict=True):
                # new landmarks are numbered in the order the log first sees them
                assignment[d.position] = p.named[n] if n < n_named else f"{mark}{n - n_named + 1}"
            if self.on_survivor is not None:
                self.on_survivor(assignment)
            if tallied:
                self._position[tuple(decisions)] = len(self.assignments)
                self.assignments.append(assignment)

    def add_boxes(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Pose boxes (at the columns ``_cols``) of survivors, joined into the hull."""
        np.minimum(self._lo, lo, out=self._lo)
        np.maximum(self._hi, hi, out=self._hi)

    def discard(self, node: Node) -> None:
        """Forget a survivor proven impossible after the search (its pose boxes stay in the
        hull, which remains a sound outer bound)."""
        where = self._position.pop(tuple(node.decisions()), None)
        if where is not None:
            self.assignments[where] = None

    def kept(self) -> list[list[str]]:
        """The assignments of the survivors not discarded."""
        return [a for a in self.assignments if a is not None]

    def poses(self) -> np.ndarray:
        """Hull over the survivors of every pose box, shape (n_poses, 3, 2)."""
        return np.stack([self._lo, self._hi], axis=-1).reshape(-1, 3, 2)


def _maintain(
    graph: SharedGraph, stack: list[Node], survivors: list[Node]
) -> tuple[list[Node], list[Node]]:
    """Let the shared graph rebase and compact; the nodes re-expressed, same boxes."""
    nodes = stack + survivors
    overlays = graph.maintain([n.overlay for n in nodes])
    nodes = [replace(n, overlay=o) for n, o in zip(nodes, overlays, strict=True)]
    return nodes[: len(stack)], nodes[len(stack) :]


def _prefix(decisions: list[int], ends: int = 4) -> str:
    """A subtree's decisions for a message: whole when short, else both ends and the depth.

    >>> _prefix([0, 1, 2])
    '[0, 1, 2]'
    >>> _prefix(list(range(100)))
    '[0, 1, 2, 3, ... 92 more ..., 96, 97, 98, 99] (depth 100)'
    """
    if len(decisions) <= 3 * ends:
        return str(list(decisions))
    head = ", ".join(map(str, decisions[:ends]))
    tail = ", ".join(map(str, decisions[-ends:]))
    return f"[{head}, ... {len(decisions) - 2 * ends} more ..., {tail}] (depth {len(decisions)})"


def _rank_key(explorer: Explorer, node: Node) -> tuple[int, int, float]:
    """Fewest landmarks, then fewest unbounded widths, then smallest total width."""
    extra = explorer.landmark_xs(node)
    n_inf, total = explorer.graph.size_key(node.overlay, np.concatenate([extra, extra + 1]))
    return (len(extra), n_inf, total)


def _best(explorer: Explorer, nodes: list[Node], keep: int) -> list[Node]:
    return sorted(nodes, key=lambda n: _rank_key(explorer, n))[:keep]


def _hypothesis(explorer: Explorer, node: Node) -> Hypothesis:
    """A survivor as the user sees it: landmark names, assignment in log order, boxes."""
    p = explorer.problem
    lo, hi = explorer.graph.materialize(node.overlay)
    xs = explorer.landmark_xs(node)
    first = [*p.first_seen, *(p.decisions[k].record for k in node.blocks)]
    order = sorted(range(len(xs)), key=lambda n: first[n])
    prefix = "N" if p.named else "L"
    taken = set(p.named)
    names: dict[int, str] = {}
    count = 0
    for n in order:
        if n < explorer.n_named:
            names[n] = p.named[n]
        else:
            count += 1
            while f"{prefix}{count}" in taken:  # a user's id is never reused
                count += 1
            names[n] = f"{prefix}{count}"
    assignment = [""] * p.n_observations
    for position, n in p.named_assignment.items():
        assignment[position] = names[n]
    for d, n in zip(p.decisions, node.decisions(), strict=True):
        assignment[d.position] = names[n]
    pose_ids = sorted(p.pose_x)
    cols = np.array([p.pose_x[q] for q in pose_ids], dtype=np.int64)[:, None] + np.arange(3)
    lcols = xs[order][:, None] + np.arange(2)
    return Hypothesis(
        assignment=assignment,
        pose_ids=pose_ids,
        poses=np.stack([lo[cols], hi[cols]], axis=-1),
        landmark_ids=[names[n] for n in order],
        landmark_classes=[explorer.landmark_class(node, n) for n in order],
        landmarks=np.stack([lo[lcols], hi[lcols]], axis=-1).reshape(-1, 2, 2),
        consistency=node.level,
    )


def _bisect_survivors(explorer: Explorer, survivors: list[Node], limit: int) -> list[Node]:
    """The survivors that bisection does not prove impossible (:mod:`.bisection`), when
    there are 2 to ``limit`` of them; it may use ``BISECTION_SHARE`` of the time left to
    the deadline and ``BISECTION_PARTS`` parts per survivor, in all
    ``BISECTION_PARTS_PER_NODE`` per node created by the search, between
    ``BISECTION_MIN_PARTS`` and ``BISECTION_TOTAL_PARTS``."""
    if len(survivors) < 2 or len(survivors) > limit:
        return survivors  # a lone survivor is left to the witness search to prove
    deadline = portion(explorer.deadline, BISECTION_SHARE)
    bisections = [explorer.bisection(node) for node in survivors]
    total = BISECTION_PARTS_PER_NODE * explorer.stats.created
    total = min(BISECTION_TOTAL_PARTS, max(BISECTION_MIN_PARTS, total))
    refuted = refute_by_bisection(bisections, deadline, BISECTION_PARTS, total)
    explorer.stats.refuted_by_bisection += sum(refuted)
    return [n for n, r in zip(survivors, refuted, strict=True) if not r]


def _strengthen_survivors(
    explorer: Explorer, survivors: list[Node], level: str, limit: int, messages: list[str]
) -> tuple[list[Node], str]:
    """Narrow the survivors to ``level`` (all when at most ``limit``, else the best-ranked
    until one is not refuted); returns them and the level all of them reach."""
    if level == "hull" or not survivors:
        return survivors, level
    if len(survivors) <= limit:
        out = [explorer.strengthen_node(n, level) for n in survivors]
        kept = [n for n in out if n is not None]
        short = [n.level for n in kept if n.level != level]  # a deadline cut them short
        return kept, short[0] if short else level
    messages.append(
        f"{len(survivors)} hypotheses survived: the '{level}' level was applied to the "
        f"best-ranked one only (to all when at most {limit} survive; raise "
        "--strengthen-limit); the others' boxes are at least hull-consistent"
    )
    for _ in range(BEST_ATTEMPTS):
        if not survivors:
            break
        best = explorer.strengthen_node(survivors[0], level)
        if best is not None:
            return [best, *survivors[1:]], "hull"
        survivors = survivors[1:]
    return survivors, "hull"


def solve_unknown(
    log: Log,
    *,
    consistency: str = DEFAULT_LEVEL,
    max_hypotheses: int = DEFAULT_MAX_HYPOTHESES,
    strengthen_limit: int = DEFAULT_STRENGTHEN_LIMIT,
    strengthen_during: int = DEFAULT_STRENGTHEN_DURING,
    rtol: float = DEFAULT_RTOL,
    progress: Callable[[int, int], None] | None = None,
    deadline: float | None = None,
    max_nodes: int | None = None,
    on_survivor: Callable[[list[str]], None] | None = None,
    local_frame: bool = True,
) -> Solution:
    """Solve a log whose observations may lack landmark ids; return the surviving hypotheses.

    Parameters
    ----------
    log : Log
        The log; observations without ``landmark`` are decided by the search.
    consistency : str
        Level applied to the survivors (``auto``, ``hull``, ``lp``, ``lp-split``).
    max_hypotheses : int
        Survivors reported in detail (the best-ranked: fewest landmarks, then smallest
        boxes). It never limits the search: every survivor is counted.
    strengthen_limit : int
        The level is applied to all survivors when at most this many, else to the best.
    strengthen_during : int
        The children of the first ``strengthen_during`` decisions get ``lp`` (when the
        decision is ambiguous and ``consistency`` is not ``hull``), so that narrower boxes
        refute whole subtrees early and gate the next decisions.
    rtol : float
        Relative shrink below which propagation stops requeueing an operator.
    progress : callable, optional
        Called with (done, total) as the explored share of the tree grows.
    deadline : float, optional
        :func:`time.perf_counter` value at which the search stops, incomplete.
    max_nodes : int, optional
        Node expansions after which the search stops, incomplete.
    on_survivor : callable, optional
        Called with the assignment of every survivor of the search as it is found (a
        landmark per observation, in log order: the log's ids, and ``"+k"`` for the k-th
        landmark the hypothesis adds, in the order the log first sees them). The stronger
        level may still refute some of them afterwards (``statistics['survivors']`` counts
        those left).
    local_frame : bool
        Narrow the window of each decided pose in that pose's frame, where relative
        geometry is tight although absolute boxes are wide (:mod:`.local`); off only to
        measure what it prunes.

    Returns
    -------
    Solution
        ``complete`` is False when a budget stopped the search; its messages then name the
        unexplored subtrees and ``statistics['unexplored_subtrees']`` counts them.
    """
    start = time.perf_counter()
    ensure_round_to_nearest()
    consistency = resolve_level(consistency, len(log.pose_ids))
    problem = build_problem(log)
    explorer = Explorer(problem, rtol, consistency, strengthen_during, local_frame)
    explorer.deadline = deadline
    messages: list[str] = []
    root = explorer.root()
    tally = _Tally(explorer, on_survivor)
    outcome = _Outcome([], [], None)
    if root is not None:
        outcome = explore(
            explorer,
            root,
            Budget(portion(deadline, SEARCH_SHARE), max_nodes),
            max(1, max_hypotheses),
            tally.add,
            progress,
        )
    unexplored = [n.decisions() for n in outcome.unexplored]
    return finish_search(
        log, explorer, tally, outcome.survivors, unexplored, outcome.stop_reason,
        consistency, strengthen_limit, progress, start, messages,
    )  # fmt: skip


def finish_search(
    log: Log,
    explorer: Explorer,
    tally: _Tally,
    found: list[Node],
    unexplored: list[list[int]],
    stop_reason: str | None,
    consistency: str,
    strengthen_limit: int,
    progress: Callable[[int, int], None] | None,
    start: float,
    messages: list[str],
) -> Solution:
    """What follows the search, wherever it ran: the survivors' stronger level, the
    reported hypotheses, the summary, the statistics and the account of a budget stop.

    ``found`` are the best-ranked survivors (nodes of ``explorer``), ``explorer.stats``
    counts the whole search, ``unexplored`` names the subtrees left by a budget stop
    (``stop_reason``), the next one to explore last.
    """
    problem = explorer.problem
    stats = explorer.stats
    complete = stop_reason is None
    if not complete:
        stats.unexplored_subtrees = len(unexplored)
        shown = "; ".join(_prefix(d) for d in unexplored[-SHOWN_PREFIXES:][::-1])
        messages.append(
            f"the search stopped on its {stop_reason} with {len(unexplored)} "
            f"subtrees unexplored ({100 * (1 - stats.explored_fraction):.1f}% of the tree; "
            f"first: {shown}); the result is INCOMPLETE: the true hypothesis may be in them"
        )
    as_leaves = stats.refuted_by_bisection
    survivors = _bisect_survivors(explorer, found, strengthen_limit)
    if stats.refuted_by_bisection:
        after = stats.refuted_by_bisection - as_leaves
        messages.append(
            f"bisection proved {stats.refuted_by_bisection} hypotheses impossible that "
            f"narrowing their whole boxes left ({as_leaves} as the search reached them, "
            f"{after} of {len(found)} survivors after it): every part of their boxes "
            "contracts to empty"
        )
    survivors, level = _strengthen_survivors(
        explorer, survivors, consistency, strengthen_limit, messages
    )
    alive = {tuple(n.decisions()) for n in survivors}
    for node in found:
        if tuple(node.decisions()) not in alive:  # refuted by the stronger level
            tally.discard(node)  # (or by bisection)
            stats.survivors -= 1
    hypotheses = sorted(
        (_hypothesis(explorer, n) for n in survivors), key=lambda h: h.rank_key
    )
    if stats.survivors > len(found):
        messages.append(
            f"{stats.survivors} hypotheses survived; the {len(hypotheses)} best-ranked are "
            "reported (raise --max-hypotheses to see more)"
        )
    correspondence = None
    if hypotheses:
        summary = summarize(tally.kept(), set(problem.named), tally.poses())
        messages.append(describe(summary, stats.survivors, complete))
        correspondence = {
            **summary_to_json(summary),
            "reported": len(hypotheses),
            "survivors": stats.survivors,
            "complete": complete,
        }
    if not hypotheses:
        messages.append(
            "every correspondence hypothesis is proven impossible: the log is inconsistent"
            if complete
            else "no hypothesis found in the explored part of the search (not a proof)"
        )
    stats.operator_applications += explorer.graph.applications
    statistics = {key: float(v) if isinstance(v, float) else v for key, v in asdict(stats).items()}
    statistics.update(
        poses=len(problem.pose_x),
        observations=problem.n_observations,
        hypotheses=len(hypotheses),
    )
    if progress is not None and complete:
        progress(1000, 1000)
    return Solution(
        hypotheses=hypotheses,
        complete=complete,
        statistics=statistics,
        timings={"solve_s": time.perf_counter() - start},
        log_path=log.path,
        consistency=level if hypotheses else consistency,
        messages=messages,
        correspondence=correspondence,
    )
