"""Expanding one node of the correspondence search: a partial hypothesis and its children.

A node of the search tree is a partial hypothesis, the decisions of its depth made (a
*decision* = which landmark an unlabelled observation sees). Its children are the
candidate landmarks that pass the interval gate and whose constraints do not contract to
empty, plus "a new landmark"; negative information (UNSEEN constraints) joins as soon as a
pose's scan is fully decided, the class priors of the log cut landmarks too many or too
close, the decided pose's window is narrowed in its own frame (:mod:`.local`), and in logs
with negative information every leaf is bisected a little (:mod:`.bisection`). A node
proven empty is discarded with its subtree: that is a proof. Every operation on a node
names the node's overlay (:class:`~._shared.SharedGraph`), so no step can act on another
hypothesis by mistake.
"""

from __future__ import annotations

import math
import time
from collections.abc import Hashable, Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from cuikslam.budget import SCHEDULE, Budget
from cuikslam.hypotheses._shared import EMPTY_OVERLAY, Overlay, SharedGraph
from cuikslam.hypotheses.ambiguity import AmbiguityLp
from cuikslam.hypotheses.bisection import Bisection, refute_by_bisection
from cuikslam.hypotheses.expansions import Expansions
from cuikslam.hypotheses.local import LocalCheck
from cuikslam.hypotheses.outlier_option import OUTLIER
from cuikslam.hypotheses.problem import Decision, Problem, observation_rows, region_of, unseen_rows
from cuikslam.hypotheses.tree import (
    AMBIGUITY_LP_GAP,
    AMBIGUITY_LP_MIN_DECISIONS,
    Node,
    SearchStatistics,
)
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS
from cuikslam.options import Level, SolveOptions

__all__ = ["Budget", "Explorer", "Node", "SearchStatistics"]

LEAF_BISECTION_PARTS = 8
"""Parts a leaf's bisection may narrow when the search reaches it, in logs with negative
information (a ``sensor`` record): many wrong leaves fall within a few parts, and those
refuted are never counted as survivors. Without negative information the constraints are
not disjunctive, narrowing loses little, and bisecting every leaf cost 1.6 to 4 times the
search on worlds of thousands of consistent survivors."""


class Explorer:
    """Expands nodes of the search tree of one problem."""

    def __init__(
        self,
        problem: Problem,
        rtol: float,
        level: Level | str,
        during: int | None,
        local: bool = True,
        threads: int | None = None,
    ) -> None:
        self.problem = problem
        self.stats = SearchStatistics()
        self.graph = SharedGraph(problem.lo, problem.hi, problem.ranked_vars, rtol, DEFAULT_ROUNDS)
        self.level = Level.parse(level)
        self.threads = threads
        """Threads of the ``lp`` sweeps of :meth:`strengthen_node` (None: the idle cores)."""
        self.during = math.inf if during is None else during
        """Nodes of the first ``during`` decisions get ``lp`` before they branch (see
        :meth:`children`)."""
        self.n_named = len(problem.named)
        self.deadline: Budget | None = None
        """When the stronger level must stop (it then reports the level it reached)."""
        self.ambiguity_lp_s = 0.0
        """Seconds the ``lp`` level took on nodes about to branch (a timing: kept apart
        from the statistics, which are the same on every machine)."""
        self.proven_at: float | None = None
        """perf_counter() when the dive's leaf was proven consistent (:func:`.dive.prove_leaf`)."""
        self.local = (
            LocalCheck(problem.pose_x, len(problem.lo), rtol, DEFAULT_ROUNDS, problem.sensor_x)
            if local
            else None
        )
        self._decisions_of: dict[Hashable, list[int]] = {}
        """Scan (a pose, or a pose and a sensor offset) -> its decisions, in order."""
        for k, d in enumerate(problem.decisions):
            self._decisions_of.setdefault(d.scan, []).append(k)
        self._done_xs, self._done_radii, self._done_before = self._completed_poses()
        self.ambiguity = AmbiguityLp(problem.pose_x, len(problem.lo), rtol, problem.sensor_x)
        self.leaf_parts = LEAF_BISECTION_PARTS if problem.has_sensor else 0
        """Parts of the bisection of each leaf (0: leaves are not bisected)."""
        self._pose_xs = np.array(sorted(problem.pose_x.values()), dtype=np.int64)
        self.expansions = Expansions()
        """The dive's expansions, for the exhaustive search to take back (:mod:`.expansions`)."""
        self.joins = False
        """Whether the exhaustive search joins lanes that agree on their future
        (:mod:`.joined`); not on a cluster, whose tasks are named by their prefixes."""

    @classmethod
    def of(cls, problem: Problem, options: SolveOptions) -> Explorer:
        """The explorer of ``problem`` with a solve's ``options`` (its level, ``rtol``,
        ``strengthen_during``, ``local_frame`` and ``threads``)."""
        return cls(
            problem, options.rtol, options.consistency, options.strengthen_during,
            options.local_frame, options.threads,
        )  # fmt: skip

    @contextmanager
    def walking(self, budget: Budget | None) -> Iterator[Budget | None]:
        """The walk's share of ``budget`` (:meth:`.budget.Schedule.walking`), which the
        explorer spends inside (its nodes' ``lp`` windows and its leaves' bisections, whose
        caps are then measured where their spending is seen); ``budget`` again after."""
        with SCHEDULE.walking(budget) as walk:
            self.deadline = walk
            try:
                yield walk
            finally:
                self.deadline = budget

    # ---------------------------------------------------------------- precomputed
    def _completed_poses(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x and radius variables of the poses in the order their scans are complete
        (none without negative information), and how many are complete before each
        decision: those before decision k are the first ``before[k]``."""
        p = self.problem
        poses, before = p.completions()
        if not p.has_sensor:
            poses, before = [], np.zeros_like(before)
        tainted = p.outlier.tainted if p.outlier is not None else frozenset()
        if tainted:
            kept = np.cumsum([0] + [q not in tainted for q in poses])
            poses, before = [q for q in poses if q not in tainted], kept[before]
        xs = np.array([p.pose_x[q] for q in poses], dtype=np.int64)
        radii = np.array([p.radius_var[q] for q in poses], dtype=np.int64)
        return xs, radii, before

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
                if j in wanted and entry[0] != OUTLIER:
                    seen.add(entry[0])
                entry = entry[1]
        return seen

    # ---------------------------------------------------------------- the tree
    def root(self) -> Node | None:
        """The node of no decisions: every shared constraint propagated; None when even that
        is proven empty (the log is inconsistent whatever the correspondence)."""
        graph = self.graph
        if self.problem.refuted_at_root:  # the named observations break the declaration
            return None
        ids = graph.intern(self.problem.root_rows)
        overlay = graph.add_rows(EMPTY_OVERLAY, ids)
        if overlay is None:
            return None
        [overlay] = graph.rebase([overlay])  # the root becomes the base, its rows the base set
        node = Node(0, overlay, (), None, lp_depth=-AMBIGUITY_LP_GAP, lp_gap=AMBIGUITY_LP_GAP)
        if self._breaks_class_prior(node):
            return None
        if self.problem.has_sensor:
            node = self.unseen_scans(node, self.problem.complete_at_root())
        return node

    def restart(self) -> Node | None:
        """The root again, on a fresh shared graph: once the search's housekeeping moved
        the graph's base and pool (:meth:`SharedGraph.maintain`), a node it did not
        re-express (the root, the dive's pending ones) no longer names its box: its
        overlay would read the moved base, narrowed by other branches' decisions."""
        p, old = self.problem, self.graph
        self.graph = SharedGraph(p.lo, p.hi, p.ranked_vars, old.rtol, DEFAULT_ROUNDS)
        self.graph.applications = old.applications
        self.expansions.clear()
        return self.root()

    def children(
        self, node: Node, keep: bool = False, narrow: bool = True
    ) -> tuple[list[Node], int]:
        """The children of ``node`` that are not proven impossible, in the order to explore
        them, and the number of options considered.

        A node that would branch (two children or more) first gets the ``lp`` level on
        the window of poses leading to its decision (:mod:`.ambiguity`; at most every
        ``AMBIGUITY_LP_GAP`` decisions along a path), and its children are made again from
        the tighter box, which gates most of the candidates out (dense world, 100 poses,
        seed 6: about 300 nodes instead of more than 35,000). ``narrow=False`` skips that
        step (an online session replaying its live hypotheses, which follows one child of
        each node).

        ``keep`` keeps the expansion (the dive's: :mod:`.dive`) for a later call on the
        same node object, by the dive again or by the exhaustive search, which takes it
        back (:mod:`.expansions`) instead of expanding the node again.
        """
        if not keep:
            kept = self.expansions.take(node, self.stats)
            return kept if kept is not None else self._expand(node, narrow)
        kept = self.expansions.peek(node)
        if kept is None:
            before = replace(self.stats)
            kept = self._expand(node, narrow)
            self.expansions.keep(node, *kept, before, self.stats)
        return kept

    def _expand(self, node: Node, narrow: bool) -> tuple[list[Node], int]:
        out, options = self._children(node)
        if (
            not narrow
            or len(out) < 2
            or len(self.problem.decisions) < AMBIGUITY_LP_MIN_DECISIONS
            or node.depth >= self.during
            or node.depth - node.lp_depth < node.lp_gap
        ):
            return out, options
        started = time.perf_counter()
        d = self.problem.decisions[node.depth]
        overlay, applications = self.ambiguity.narrow(
            self.graph, node.overlay, d.pose, self.deadline
        )
        self.stats.ambiguity_lp += 1
        self.ambiguity_lp_s += time.perf_counter() - started
        self.stats.operator_applications += applications
        self.stats.created -= len(out)  # replaced (or refuted with the node): never explored
        self.stats.outlier_options -= sum(c.assigned[0] == OUTLIER for c in out)
        if overlay is None:
            self.stats.refuted_by_consistency += 1
            return [], options
        self.stats.branch_points -= 1  # the same node, expanded again
        kids, options = self._children(replace(node, overlay=overlay))
        gap = AMBIGUITY_LP_GAP if len(kids) < len(out) else 2 * node.lp_gap
        return [replace(c, lp_depth=node.depth, lp_gap=gap) for c in kids], options

    def _children(self, node: Node) -> tuple[list[Node], int]:
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
        outlier = p.outlier is not None and p.outlier.allows(node.outliers, k)
        stats.candidates += len(numbers) + 1 + outlier
        stats.excluded_same_scan += len(numbers) - len(kept)
        options = len(kept) + 1 + outlier
        xs = all_xs[kept]
        passed = graph.gate(node.overlay, d.sensor_x, xs, d.bearing_var, d.range_var)
        stats.gated += int(np.count_nonzero(~passed))
        order = self.nearest_first(node, d, xs[passed])
        ids = graph.intern(observation_rows(p, d, xs[passed][order]))
        out: list[Node] = []
        for i, number in enumerate(np.array(kept, dtype=np.int64)[passed][order].tolist()):
            overlay = graph.add_rows(node.overlay, ids[i : i + 1])
            if overlay is None:
                stats.proven_empty += 1
                continue
            made = Node(
                k + 1,
                overlay,
                node.blocks,
                (number, node.assigned),
                lp_depth=node.lp_depth,
                lp_gap=node.lp_gap,
                outliers=node.outliers,
                lanes=node.lanes,
            )
            child = self._after_decision(made)
            if child is not None:
                out.append(child)
        new: Node | None = None
        of_class = len(numbers) if node.lanes is None else self._fewest(node, d.landmark_class)
        overlay = self.new_landmark(node.overlay, k, of_class, node.outliers)
        if overlay is not None:
            new = Node(
                k + 1,
                overlay,
                (*node.blocks, k),
                (len(all_xs), node.assigned),
                lp_depth=node.lp_depth,
                lp_gap=node.lp_gap,
                outliers=node.outliers,
                lanes=node.lanes,
            )
            new = self._after_decision(new)
        if new is not None:
            out.append(new)
        if outlier:  # explains nothing, adds no constraint: explored last
            made = replace(node, depth=k + 1, assigned=(OUTLIER, node.assigned))
            made = self._after_decision(replace(made, outliers=(*node.outliers, k)))
            out.extend([] if made is None else [made])
        stats.created += len(out)
        stats.outlier_options += sum(c.assigned[0] == OUTLIER for c in out)
        share = node.share / options
        return [replace(c, share=share) for c in out], options

    def new_landmark(
        self, overlay: Overlay, k: int, of_class: int, outliers: tuple[int, ...] = ()
    ) -> Overlay | None:
        """``overlay`` with decision ``k``'s slot taken as a new landmark, when ``of_class``
        landmarks of its class exist already: the class prior's count and region, and
        negative information from every pose whose scan is complete (but those of the
        decisions in ``outliers``); None when that is proven impossible."""
        p, graph, stats = self.problem, self.graph, self.stats
        d = p.decisions[k]
        prior = p.class_priors.get(d.landmark_class)
        if prior is not None and prior.at_most is not None and of_class >= prior.at_most:
            stats.refuted_by_class_prior += 1
            return None
        region = region_of(p, d.landmark_class) if p.outlier is not None else None
        if region is not None:  # slots are free with a declaration
            overlay = graph.restrict(overlay, np.array([d.slot_x, d.slot_x + 1]), *region)
            if overlay is None:
                stats.refuted_by_class_prior += 1
                return None
        n_done = self._done_before[k]
        done_xs, done_radii = self._done_xs[:n_done], self._done_radii[:n_done]
        if outliers and len(done_xs):  # no UNSEEN on a pose with an outlier
            keep = ~np.isin(done_xs, [p.decisions[j].pose_x for j in outliers])
            done_xs, done_radii = done_xs[keep], done_radii[keep]
        if p.has_sensor and len(done_xs):
            return self._add_unseen(overlay, done_xs, done_radii, np.array([d.slot_x]))
        return overlay

    def _fewest(self, node: Node, cls: str) -> int:
        """Fewest landmarks of class ``cls`` that a lane of the joined ``node`` holds: its
        lanes' count and those made since the join."""
        lanes = node.lanes
        assert lanes is not None
        made = range(self.n_named + len(lanes.blocks), self.n_named + len(node.blocks))
        since = sum(self.landmark_class(node, n) == cls for n in made)
        return lanes.class_count.get(cls, 0) + since

    def held_by_all(self, node: Node) -> np.ndarray:
        """Which landmark numbers of ``node`` every hypothesis it stands for holds (all but
        the landmarks only some lanes of a joined node hold)."""
        held = np.ones(self.n_named + len(node.blocks), dtype=np.bool_)
        if node.lanes is not None:
            partial = self.n_named + np.arange(len(node.lanes.blocks))
            held[partial] = [n in node.lanes.common for n in partial.tolist()]
        return held

    def nearest_first(self, node: Node, d: Decision, xs: np.ndarray) -> np.ndarray:
        """The order in which to explore the candidate landmarks at x ``xs``: nearest first
        to where the observation puts the landmark (its slot's box), centre to centre.

        Depth-first, the first survivor is then usually found without backtracking (on a
        long log, a wrong early choice can survive hundreds of decisions in wide boxes).
        The order changes nothing else: every child is explored.
        """
        if len(xs) < 2:
            return np.arange(len(xs))
        return np.argsort(self.gaps(node, d, xs), kind="stable")

    def gaps(self, node: Node, d: Decision, xs: np.ndarray) -> np.ndarray:
        """Distances from where decision ``d``'s observation puts its landmark (its slot's
        box) to the landmarks at x ``xs``, centre to centre, in ``node``."""
        slot = np.array([d.slot_x, d.slot_x + 1], dtype=np.int64)
        lo, hi = self.graph.values(node.overlay, np.concatenate([slot, xs, xs + 1]))
        with np.errstate(invalid="ignore", over="ignore"):
            centre = np.nan_to_num(0.5 * lo + 0.5 * hi, nan=0.0, posinf=0.0, neginf=0.0)
        n = len(xs)
        return np.hypot(centre[2 : 2 + n] - centre[0], centre[2 + n :] - centre[1])

    def _after_decision(self, child: Node) -> Node | None:
        """The class prior's separation, negative information once the decided observation
        completes its pose's scan, then windows up to its pose narrowed in a local frame
        (more of them once the scan is decided)."""
        d = self.problem.decisions[child.depth - 1]
        if child.assigned[0] != OUTLIER and self.too_close(child, child.assigned[0]):
            self.stats.refuted_by_class_prior += 1
            return None
        if self.problem.has_sensor and d.completes_scan:
            child = self.unseen_scans(child, [d.pose])
        if child is None or self.local is None:
            return child
        if self.local.refutes(self.graph, child.overlay, d.pose, d.completes_scan):
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
        if np.any(lo > hi) or any(self.too_close(node, n) for n in range(self.n_named)):
            self.stats.refuted_by_class_prior += 1
            return True
        return False

    def too_close(self, node: Node, number: int) -> bool:
        """True when landmark ``number`` of ``node`` is proven closer to another landmark of
        its class than the class prior's ``min_separation``: the farthest points of their
        boxes are nearer than that (compared with a relative margin far above rounding)."""
        cls = self.landmark_class(node, number)
        prior = self.problem.class_priors.get(cls)
        if prior is None or prior.min_separation is None:
            return False
        xs = self.landmark_xs(node)
        held = self.held_by_all(node)  # a joined node's others: their lanes check them
        if not held[number]:
            return False
        others = [
            n
            for n in range(len(xs))
            if n != number and held[n] and self.landmark_class(node, n) == cls
        ]
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

    def unseen_scans(
        self, node: Node, poses: list[int], only: np.ndarray | None = None
    ) -> Node | None:
        """Add UNSEEN constraints between each of ``poses`` (whose scans ``node`` has fully
        decided) and every landmark it did not see (of a joined node, that all its lanes
        hold; of landmark numbers ``only`` when given); None when that proves ``node``
        empty."""
        p = self.problem
        if p.outlier is not None:  # a pose with an outlier: its true detections are unknown
            outlying = {p.decisions[j].pose for j in node.outliers} | p.outlier.tainted
            poses = [q for q in poses if q not in outlying]
        if not poses:
            return node
        landmark_xs = self.landmark_xs(node)
        seen = np.zeros((len(poses), len(landmark_xs)), dtype=np.bool_)
        for i, pose in enumerate(poses):
            for n in self.seen_by(node, pose):
                seen[i, n] = True
        if only is not None:
            wanted = np.zeros(len(landmark_xs), dtype=np.bool_)
            wanted[only] = True
            seen[:, ~wanted] = True
        seen[:, ~self.held_by_all(node)] = True  # no constraint on what a lane lacks
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
    def strengthen_node(self, node: Node, level: Level) -> Node | None:
        """``node`` narrowed to ``level``; None when that proves it empty."""
        if level is Level.HULL:
            return node
        graph = self.graph
        lo, hi, arrays = graph.standalone(node.overlay, canonical=True)
        report = StrengthenReport()
        result = strengthen(
            arrays, lo, hi, level, graph.rtol, DEFAULT_ROUNDS, deadline=self.deadline,
            report=report, threads=self.threads,
        )  # fmt: skip
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
