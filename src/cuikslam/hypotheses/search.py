"""Unknown correspondence: a collection of kinematic graphs, pruned only by proof (seed, Section 5).

The log is processed in time order. All live hypotheses (*branches*) share one variable
layout, one pool of factor rows and one set of base boxes (:mod:`._shared`); a branch holds
only where it differs from them, a few tens of variables and rows, so the memory of the
live set does not grow as branches times graph size. An observation that names no
landmark splits every branch into: each existing landmark of the same class that passes
the gate, plus "a new landmark". A child starts from its parent's boxes and runs only the
operators its new factor wakes; a child that contracts to empty is discarded, which is a
proof, so the true correspondence is never lost.

Canonical labelling: landmarks are numbered by their first observation, and a new
landmark always takes the next number, so the branches are distinct partitions of the
observations; two branches that differ only in names cannot be created.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.graph.encoding import (
    ANGLE,
    KIND,
    LENGTH,
    N_SLOTS,
    OBSERVATION,
    ODOMETRY,
    TA,
    TB,
    UNSEEN,
    XA,
    XB,
    YA,
    YB,
)
from cuikslam.hypotheses._gates import gate_many, pairs_within_reach
from cuikslam.hypotheses._shared import EMPTY_OVERLAY, Overlay, SharedGraph
from cuikslam.interval._rounding import PI_HI, TWO_PI_HI
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
)
from cuikslam.narrowing._propagate import INCONSISTENT
from cuikslam.narrowing.consistency import DEFAULT_LEVEL, resolve_level, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL
from cuikslam.results.solution import Hypothesis, Solution

__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "DEFAULT_STRENGTHEN_DURING",
    "DEFAULT_STRENGTHEN_LIMIT",
    "SearchStatistics",
    "solve_unknown",
]

DEFAULT_MAX_HYPOTHESES = 10_000
"""Live hypotheses kept at most; beyond it the best-ranked are kept and the result is incomplete."""

DEFAULT_STRENGTHEN_LIMIT = 100
BEST_ATTEMPTS = 10
"""Beyond ``strengthen_limit`` survivors, the best-ranked are tried until one is not refuted."""
DEFAULT_STRENGTHEN_DURING = 0
"""Off by default: on the seed's experiment, ``lp`` after every branch point while at most
20 hypotheses live leaves 375 survivors instead of 500, but takes 4.5 s instead of 0.2 s."""
"""Surviving hypotheses narrowed to the stronger consistency level at most."""

_ANY = (-math.inf, math.inf)


@dataclass
class SearchStatistics:
    """Counts that tell how the search went."""

    branch_points: int = 0
    """Observations without a landmark id (each splits every live hypothesis)."""
    candidates: int = 0
    """(hypothesis, landmark) pairs considered, plus each hypothesis' "new landmark" option."""
    excluded_same_scan: int = 0
    """Candidates excluded because the same scan already saw that landmark."""
    gated: int = 0
    """Candidates rejected by the interval gate, without propagation."""
    proven_empty: int = 0
    """Children whose constraints contracted to empty (a proof)."""
    refuted_by_negative_information: int = 0
    """Hypotheses refuted by UNSEEN constraints (a landmark in view that the robot did not see)."""
    unseen_constraints: int = 0
    """UNSEEN constraints added (pose-landmark pairs close enough to matter)."""
    created: int = 0
    """Children created (each a consistent-looking kinematic graph)."""
    avoided_by_labelling: int = 0
    """Label-permuted copies of the survivors that naming landmarks freely would have kept."""
    refuted_by_consistency: int = 0
    """Survivors of hull consistency refuted by the stronger consistency level."""
    peak_alive: int = 0
    dropped_by_limit: int = 0
    operator_applications: int = 0


@dataclass
class _Layout:
    """Variable indices shared by every branch (poses, measurements, landmark slots)."""

    n_vars: int = 0
    pose_x: dict[int, int] = field(default_factory=dict)
    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)
    record_factor: dict[int, int] = field(default_factory=dict)
    """Record index -> factor index."""
    factor_measurements: list[tuple[int, int]] = field(default_factory=list)
    user_landmark_x: dict[str, int] = field(default_factory=dict)
    observation_slot_x: dict[int, int] = field(default_factory=dict)
    """Record index of an unlabelled observation -> x index of the landmark it may create."""
    radius_var: dict[int, int] = field(default_factory=dict)
    """Pose -> variable holding the distance within which it saw every landmark in view."""
    arc_var: int = -1
    """Variable holding the bearings outside the field of view (empty for all-round sensors)."""

    def new_vars(self, *bounds: tuple[float, float]) -> int:
        first = self.n_vars
        for lo, hi in bounds:
            self.lo.append(lo)
            self.hi.append(hi)
        self.n_vars += len(bounds)
        return first


def _build_layout(log: Log) -> _Layout:
    layout = _Layout()

    def pose(p: int) -> int:
        if p not in layout.pose_x:
            layout.pose_x[p] = layout.new_vars(_ANY, _ANY, _ANY)
        return layout.pose_x[p]

    for index, record in enumerate(log.records):
        if isinstance(record, PosePrior):
            pose(record.pose)
        elif isinstance(record, Odometry):
            pose(record.source)
            pose(record.target)
            m = layout.new_vars(record.turn, (max(0.0, record.distance[0]), record.distance[1]))
            layout.record_factor[index] = len(layout.factor_measurements)
            layout.factor_measurements.append((m, m + 1))
        elif isinstance(record, Observation):
            pose(record.pose)
            bearing = (-PI_HI, PI_HI) if record.bearing is None else record.bearing
            distance = (0.0, math.inf) if record.range is None else record.range
            m = layout.new_vars(bearing, (max(0.0, distance[0]), distance[1]))
            layout.record_factor[index] = len(layout.factor_measurements)
            layout.factor_measurements.append((m, m + 1))
            if record.landmark is None:
                layout.observation_slot_x[index] = layout.new_vars(_ANY, _ANY)
            elif record.landmark not in layout.user_landmark_x:
                layout.user_landmark_x[record.landmark] = layout.new_vars(_ANY, _ANY)
        elif isinstance(record, LandmarkPrior):
            if record.landmark not in layout.user_landmark_x:
                layout.user_landmark_x[record.landmark] = layout.new_vars(_ANY, _ANY)
    if log.sensor is not None:
        _add_sensor_variables(layout, log)
    return layout


def _add_sensor_variables(layout: _Layout, log: Log) -> None:
    """Constants of the UNSEEN constraints: a visibility radius per pose, the out-of-view arc."""
    sensor = log.sensor
    nearest: dict[int, float] = {}
    for record in log.observations:
        low = 0.0 if record.range is None else record.range[0]
        nearest[record.pose] = min(nearest.get(record.pose, math.inf), low)
    for pose in layout.pose_x:
        radius = sensor.max_range
        if sensor.nearest_margin is not None:
            limit = float(np.nextafter(nearest.get(pose, math.inf) + sensor.nearest_margin, 0.0))
            radius = min(radius, limit)
        layout.radius_var[pose] = layout.new_vars((radius, radius))
    half = sensor.fov / 2.0
    if sensor.fov >= 2 * math.pi:
        layout.arc_var = layout.new_vars((1.0, 0.0))
    else:
        arc = (float(np.nextafter(half, 0.0)), float(np.nextafter(TWO_PI_HI - half, math.inf)))
        layout.arc_var = layout.new_vars(arc)


def _pose_columns(layout: _Layout, pose: int) -> tuple[int, int, int]:
    """The x, y and theta variables of ``pose``."""
    x = layout.pose_x[pose]
    return x, x + 1, x + 2


class _Branch:
    """One live hypothesis: its overlay on the shared graph, and its landmark assignment.

    The assignment is a persistent list (``(number, previous)`` pairs, newest first), so
    a child shares its parent's history and only adds its newest entry.
    """

    __slots__ = (
        "assigned",
        "landmark_class",
        "landmark_name",
        "landmark_x",
        "level",
        "n_assigned",
        "overlay",
    )

    def __init__(self) -> None:
        self.overlay = EMPTY_OVERLAY
        self.level = "hull"
        """The consistency level the boxes are known to reach."""
        self.landmark_x: list[int] = []
        self.landmark_class: list[str] = []
        self.landmark_name: list[str | None] = []
        self.assigned: tuple[int, tuple] | None = None
        self.n_assigned = 0

    def fork(self, overlay: Overlay) -> _Branch:
        """A child with ``overlay``; landmark lists copied, assignment history shared."""
        other = _Branch.__new__(_Branch)
        other.overlay = overlay
        other.level = "hull"  # a new factor: only the propagation's fixpoint is known
        other.landmark_x = list(self.landmark_x)
        other.landmark_class = list(self.landmark_class)
        other.landmark_name = list(self.landmark_name)
        other.assigned = self.assigned
        other.n_assigned = self.n_assigned
        return other

    def assign(self, number: int) -> None:
        """The next observation is landmark ``number``."""
        self.assigned = (number, self.assigned)
        self.n_assigned += 1

    def assignment_from(self, position: int) -> list[int]:
        """Landmark numbers of the observations from ``position`` on (walks back from the
        newest, so recent positions are cheap)."""
        out = []
        node = self.assigned
        for _ in range(self.n_assigned - position):
            out.append(node[0])
            node = node[1]
        return out[::-1]

    def new_landmark(self, x: int, landmark_class: str, name: str | None) -> int:
        """Add a landmark whose x variable is ``x``; returns its number."""
        self.landmark_x.append(x)
        self.landmark_class.append(landmark_class)
        self.landmark_name.append(name)
        return len(self.landmark_x) - 1

    def landmark_vars(self) -> np.ndarray:
        """The x and y variables of every landmark."""
        x = np.array(self.landmark_x, dtype=np.int64)
        return np.concatenate([x, x + 1])


class _Search:
    """The incremental search over one log."""

    def __init__(
        self, log: Log, rtol: float, max_hypotheses: int, level: str = "hull", limit: int = 0
    ) -> None:
        self.log = log
        self.max_hypotheses = max_hypotheses
        self.level = level
        """Level (above hull, ``lp`` is used) applied after each branch point to at most
        ``limit`` live branches."""
        self.limit = limit
        self.layout = _build_layout(log)
        self.stats = SearchStatistics()
        self.complete = True
        self.messages: list[str] = []
        self.has_sensor = log.sensor is not None
        self.level_applied = "hull"
        self.observations_at: dict[int, list[int]] = {}
        """Pose -> record indices of its observations so far."""
        self.scan_done: list[int] = []
        """Poses whose scan is complete (all their observations processed)."""
        self.done_xs = np.zeros(0, dtype=np.int64)
        self.done_radii = np.zeros(0, dtype=np.int64)
        """x and visibility-radius variables of the poses of ``scan_done``."""
        self.completes_after: dict[int, list[int]] = self._scan_completion()
        pose_xs = np.array(sorted(self.layout.pose_x.values()), dtype=np.int64)
        self.graph = SharedGraph(
            np.array(self.layout.lo, dtype=np.float64),
            np.array(self.layout.hi, dtype=np.float64),
            np.sort(np.concatenate([pose_xs, pose_xs + 1, pose_xs + 2])),
            rtol,
            DEFAULT_ROUNDS,
        )
        self.branches = [_Branch()]
        self.observation_position: dict[int, int] = {}
        """Record index of an observation -> its position among the observations."""

    def _scan_completion(self) -> dict[int, list[int]]:
        """Record index -> poses whose last observation (or introduction) is that record."""
        last: dict[int, int] = {}
        for index, record in enumerate(self.log.records):
            if isinstance(record, PosePrior):
                last.setdefault(record.pose, index)
            elif isinstance(record, Odometry):
                last.setdefault(record.source, index)
                last.setdefault(record.target, index)
            elif isinstance(record, Observation):
                last[record.pose] = index
        completes: dict[int, list[int]] = {}
        for pose, index in last.items():
            completes.setdefault(index, []).append(pose)
        return completes

    # ------------------------------------------------------------------ records
    def _all(self, apply: Callable[[int, _Branch], Overlay | None]) -> None:
        """Check out each branch and apply (with its position); a branch whose new overlay is
        None is proven empty."""
        survivors = []
        for k, branch in enumerate(self.branches):
            self.graph.checkout(branch.overlay)
            overlay = apply(k, branch)
            if overlay is None:
                self.stats.proven_empty += 1
            else:
                branch.overlay = overlay
                survivors.append(branch)
        self.branches = survivors

    def _narrow_and_propagate(
        self, first: Callable[[_Branch], int], bounds: list[tuple[float, float]]
    ) -> None:
        """Intersect consecutive variables (from ``first(branch)``) with ``bounds``; propagate."""
        lo = np.array([b[0] for b in bounds], dtype=np.float64)
        hi = np.array([b[1] for b in bounds], dtype=np.float64)

        def apply(_: int, branch: _Branch) -> Overlay | None:
            variables = np.arange(first(branch), first(branch) + len(bounds), dtype=np.int64)
            return self.graph.restrict(variables, lo, hi)

        self._all(apply)

    def _fixed_factor(self, index: int, row: Callable[[_Branch], tuple[int, ...]]) -> None:
        """Add the factor of record ``index`` (its row may differ by branch) everywhere.

        A row that every branch gets joins the shared base set at once.
        """
        rows = [row(branch) for branch in self.branches]
        ids = self.graph.intern(np.array(rows, dtype=np.int64))
        if len(set(ids.tolist())) == 1:
            self.graph.add_to_base(ids[:1])
        self._all(lambda k, _: self.graph.extend(ids[k : k + 1]))

    def _name_landmark(self, landmark: str, landmark_class: str, pose: int | None) -> None:
        """The user's landmark ``landmark`` appears: in each branch where it is not yet known,
        it is one of the anonymous landmarks of its class, or a new one.

        ``pose`` is the pose whose scan names it (anonymous landmarks that scan already saw
        are excluded), or None for a landmark prior.
        """
        children = []
        same_scan = self.observations_at.get(pose, []) if pose is not None else []
        for branch in self.branches:
            if landmark in branch.landmark_name:
                children.append(branch)
                continue
            seen_here = self._seen(branch, same_scan)
            for number, (name, cls) in enumerate(
                zip(branch.landmark_name, branch.landmark_class, strict=True)
            ):
                if name is not None or cls != landmark_class:
                    continue
                self.stats.candidates += 1
                if number in seen_here:
                    self.stats.excluded_same_scan += 1
                    continue
                child = branch.fork(branch.overlay)
                child.landmark_name[number] = landmark
                self.stats.created += 1
                children.append(child)
            self.stats.candidates += 1
            number = branch.new_landmark(
                self.layout.user_landmark_x[landmark], landmark_class, landmark
            )
            if self.has_sensor and not self._add_unseen(
                branch, self.done_xs, self.done_radii, [number]
            ):
                self.stats.refuted_by_negative_information += 1
                continue
            children.append(branch)
        self.branches = children

    def _seen(self, branch: _Branch, observations: list[int]) -> set[int]:
        """Landmark numbers that ``branch`` assigns to the given observation records."""
        if not observations:
            return set()
        positions = [self.observation_position[o] for o in observations]
        first = min(positions)
        recent = branch.assignment_from(first)
        return {recent[p - first] for p in positions}

    @staticmethod
    def _landmark_x(branch: _Branch, landmark: str) -> int:
        return branch.landmark_x[branch.landmark_name.index(landmark)]

    def _observation_rows(self, index: int, record: Observation, xs: np.ndarray) -> np.ndarray:
        """Factor rows of observation record ``index`` seeing the landmarks at x ``xs``."""
        rows = np.empty((len(xs), 1 + N_SLOTS), dtype=np.int64)
        pose = _pose_columns(self.layout, record.pose)
        rows[:, [KIND, XA, YA, TA, TB]] = (OBSERVATION, *pose, -1)
        rows[:, XB], rows[:, YB] = xs, xs + 1
        rows[:, [ANGLE, LENGTH]] = self.layout.factor_measurements[self.layout.record_factor[index]]
        return rows

    def _observation_row(self, index: int, record: Observation, landmark_x: int) -> tuple[int, ...]:
        return tuple(self._observation_rows(index, record, np.array([landmark_x]))[0].tolist())

    def _branch(self, index: int, record: Observation) -> None:
        """Split every branch over the landmarks this observation may be."""
        self.stats.branch_points += 1
        pose_x = self.layout.pose_x[record.pose]
        bearing_var, range_var = self.layout.factor_measurements[self.layout.record_factor[index]]
        slot_x = self.layout.observation_slot_x[index]
        same_scan = self.observations_at.get(record.pose, [])
        others = self.done_xs != pose_x
        done_xs, done_radii = self.done_xs[others], self.done_radii[others]
        graph = self.graph
        children: list[_Branch] = []
        for branch in self.branches:
            graph.checkout(branch.overlay)
            numbers = [
                n for n, cls in enumerate(branch.landmark_class) if cls == record.landmark_class
            ]
            self.stats.candidates += len(numbers)
            seen_here = self._seen(branch, same_scan)
            kept = [n for n in numbers if n not in seen_here]
            self.stats.excluded_same_scan += len(numbers) - len(kept)
            numbers = kept
            candidates = np.array([branch.landmark_x[n] for n in numbers], dtype=np.int64)
            passed = gate_many(graph.lo, graph.hi, pose_x, candidates, bearing_var, range_var)
            self.stats.gated += int(np.count_nonzero(~passed))
            # rows of the passing landmarks, then of the new one, pooled in that order
            xs = np.append(candidates[passed], slot_x)
            ids = graph.intern(self._observation_rows(index, record, xs))
            numbers = np.array(numbers, dtype=np.int64)[passed].tolist()
            for k, number in enumerate(numbers):
                overlay = graph.trial(ids[k : k + 1])
                if overlay is None:
                    self.stats.proven_empty += 1
                    continue
                child = branch.fork(overlay)
                child.assign(number)
                self.stats.created += 1
                children.append(child)
            # the new landmark: the parent itself becomes this child (no copy)
            self.stats.candidates += 1
            overlay = graph.extend(ids[-1:])
            if overlay is None:
                self.stats.proven_empty += 1
                continue
            branch.overlay = overlay
            branch.assign(branch.new_landmark(slot_x, record.landmark_class, None))
            if self.has_sensor and not self._add_unseen(
                branch, done_xs, done_radii, [len(branch.landmark_x) - 1]
            ):
                self.stats.refuted_by_negative_information += 1
                continue
            self.stats.created += 1
            children.append(branch)
        self.branches = children

    # ---------------------------------------------------------- negative information
    def _add_unseen(
        self,
        branch: _Branch,
        pose_xs: np.ndarray,
        radius_vars: np.ndarray,
        landmarks: list[int],
        seen: np.ndarray | None = None,
    ) -> bool:
        """Add UNSEEN constraints to the checked-out ``branch`` between the poses (x and
        radius variables) and the landmark numbers ``landmarks`` that the poses did not
        observe (``seen``; none by default) and that are within reach; False when that
        proves the branch impossible."""
        if len(pose_xs) == 0 or not landmarks:
            return True
        if seen is None:
            seen = np.zeros((len(pose_xs), len(landmarks)), dtype=np.bool_)
        graph = self.graph
        landmark_xs = np.array([branch.landmark_x[n] for n in landmarks], dtype=np.int64)
        pairs = pairs_within_reach(
            graph.lo, graph.hi, pose_xs, graph.lo[radius_vars], landmark_xs, seen
        )
        if len(pairs) == 0:
            return True
        a = pose_xs[pairs[:, 0]]
        b = landmark_xs[pairs[:, 1]]
        rows = np.empty((len(pairs), 1 + N_SLOTS), dtype=np.int64)
        rows[:, [KIND, TB, ANGLE]] = (UNSEEN, -1, self.layout.arc_var)
        rows[:, XA], rows[:, YA], rows[:, TA] = a, a + 1, a + 2
        rows[:, XB], rows[:, YB] = b, b + 1
        rows[:, LENGTH] = radius_vars[pairs[:, 0]]
        self.stats.unseen_constraints += len(rows)
        overlay = graph.extend(graph.intern(rows))
        if overlay is None:
            return False
        branch.overlay = overlay
        return True

    def _scans_done(self, poses: list[int]) -> None:
        """The scans of ``poses`` are complete: every landmark they missed gets an UNSEEN."""
        self.scan_done.extend(poses)
        if not self.has_sensor:
            return
        pose_xs = np.array([self.layout.pose_x[p] for p in poses], dtype=np.int64)
        radius_vars = np.array([self.layout.radius_var[p] for p in poses], dtype=np.int64)
        self.done_xs = np.concatenate([self.done_xs, pose_xs])
        self.done_radii = np.concatenate([self.done_radii, radius_vars])
        observed = [self.observations_at.get(p, []) for p in poses]
        survivors = []
        for branch in self.branches:
            self.graph.checkout(branch.overlay)
            seen = np.zeros((len(poses), len(branch.landmark_x)), dtype=np.bool_)
            for i, records in enumerate(observed):
                for number in self._seen(branch, records):
                    seen[i, number] = True
            landmarks = list(range(len(branch.landmark_x)))
            if self._add_unseen(branch, pose_xs, radius_vars, landmarks, seen):
                survivors.append(branch)
            else:
                self.stats.refuted_by_negative_information += 1
        self.branches = survivors

    # ------------------------------------------------------------------ ranking
    def strengthen(self, level: str, limit: int) -> None:
        """Narrow the survivors to ``level``; drop the ones that become empty (a proof).

        All of them when at most ``limit`` survive; otherwise (a fraction of a second per
        hypothesis) only the best-ranked one that is not refuted, with a message.
        """
        self.level_applied = level
        if level == "hull":
            return
        self.branches = self._ranked()
        if len(self.branches) <= limit:
            self._strengthen_live(level)
            return
        self.level_applied = "hull"
        self.messages.append(
            f"{len(self.branches)} hypotheses survived: the '{level}' level was applied to "
            f"the best-ranked one only (to all when at most {limit} survive; raise "
            "--strengthen-limit); the others' boxes are at least hull-consistent"
        )
        for _ in range(BEST_ATTEMPTS):
            best = self.branches[0]
            self._strengthen_live(level, [best])
            if self.branches and self.branches[0] is best:
                return

    def _strengthen_live(self, level: str, chosen: list[_Branch] | None = None) -> None:
        """Narrow the ``chosen`` live branches (all by default) to ``level``.

        Branches proven empty are dropped; the others keep their order.
        """
        chosen_ids = {id(b) for b in (self.branches if chosen is None else chosen)}
        self.graph.release()
        survivors = []
        for branch in self.branches:
            if id(branch) in chosen_ids:
                lo, hi, arrays = self.graph.standalone(branch.overlay)
                status, applications = strengthen(
                    arrays, lo, hi, level, self.graph.rtol, DEFAULT_ROUNDS
                )
                self.stats.operator_applications += applications
                if status == INCONSISTENT:
                    self.stats.refuted_by_consistency += 1
                    continue
                branch.overlay = self.graph.overlay_of(lo, hi, branch.overlay.rows)
                branch.level = level
            survivors.append(branch)
        self.branches = survivors

    def _ranked(self) -> list[_Branch]:
        """Fewest landmarks first, then fewest unbounded widths, then smallest total width."""
        keys = {
            id(b): (len(b.landmark_x), *self.graph.size_key(b.overlay, b.landmark_vars()))
            for b in self.branches
        }
        return sorted(self.branches, key=lambda b: keys[id(b)])

    def _enforce_limit(self, index: int) -> None:
        if len(self.branches) <= self.max_hypotheses:
            return
        dropped = len(self.branches) - self.max_hypotheses
        self.branches = self._ranked()[: self.max_hypotheses]
        self.stats.dropped_by_limit += dropped
        if self.complete:
            line = self.log.records[index].line
            self.messages.append(
                f"more than {self.max_hypotheses} hypotheses at log line {line}: kept the "
                "best-ranked, dropped the rest; the result is INCOMPLETE (the true hypothesis "
                "may be missing). Raise --max-hypotheses to search fully."
            )
        self.complete = False

    def _maintain(self) -> None:
        """Let the shared graph rebase and compact when the overlays have grown."""
        overlays = self.graph.maintain([b.overlay for b in self.branches])
        for branch, overlay in zip(self.branches, overlays, strict=True):
            branch.overlay = overlay

    # ------------------------------------------------------------------ driver
    def run(self, progress: Callable[[int, int], None] | None) -> None:
        total = len(self.log.records)
        for index, record in enumerate(self.log.records):
            ensure_round_to_nearest()
            if isinstance(record, PosePrior):
                x = self.layout.pose_x[record.pose]
                self._narrow_and_propagate(lambda _, x=x: x, [record.x, record.y, record.theta])
            elif isinstance(record, LandmarkPrior):
                name = record.landmark
                self._name_landmark(name, record.landmark_class, None)
                self._narrow_and_propagate(
                    lambda b, name=name: self._landmark_x(b, name), [record.x, record.y]
                )
            elif isinstance(record, Odometry):
                a = self.layout.pose_x[record.source]
                b = self.layout.pose_x[record.target]
                m, n = self.layout.factor_measurements[self.layout.record_factor[index]]
                row = (ODOMETRY, a, a + 1, a + 2, b, b + 1, b + 2, m, n)
                self._fixed_factor(index, lambda _, row=row: row)
            elif isinstance(record, Observation):
                if record.landmark is None:
                    self._branch(index, record)
                else:
                    name = record.landmark
                    self._name_landmark(name, record.landmark_class, record.pose)
                    self._fixed_factor(
                        index,
                        lambda b, name=name, record=record, index=index: self._observation_row(
                            index, record, self._landmark_x(b, name)
                        ),
                    )
                    for branch in self.branches:
                        branch.assign(branch.landmark_name.index(name))
                self.observation_position[index] = len(self.observation_position)
                self.observations_at.setdefault(record.pose, []).append(index)
            completed = self.completes_after.get(index, [])
            if completed:
                self._scans_done(completed)
            self.stats.peak_alive = max(self.stats.peak_alive, len(self.branches))
            self._enforce_limit(index)
            if (
                isinstance(record, Observation)
                and record.landmark is None
                and self.level != "hull"
                and len(self.branches) <= self.limit
            ):
                self._strengthen_live("lp")
            self._maintain()
            if progress is not None:
                progress(index + 1, total)
            if not self.branches:
                break
        self.stats.operator_applications += self.graph.applications

    # ------------------------------------------------------------------ results
    def hypotheses(self) -> list[Hypothesis]:
        pose_ids = sorted(self.layout.pose_x)
        pose_xs = np.array([self.layout.pose_x[p] for p in pose_ids], dtype=np.int64)
        has_user_ids = bool(self.layout.user_landmark_x)
        result = []
        for branch in self.branches:
            lo, hi = self.graph.materialize(branch.overlay)
            names = []
            new_count = 0
            for name in branch.landmark_name:
                if name is None:
                    new_count += 1
                    name = f"N{new_count}" if has_user_ids else f"L{new_count}"
                names.append(name)
            cols = pose_xs[:, None] + np.arange(3)[None, :]
            poses = np.stack([lo[cols], hi[cols]], axis=-1)
            lx = np.array(branch.landmark_x, dtype=np.int64).reshape(-1)
            lcols = lx[:, None] + np.arange(2)[None, :]
            landmarks = np.stack([lo[lcols], hi[lcols]], axis=-1).reshape(-1, 2, 2)
            result.append(
                Hypothesis(
                    assignment=[names[k] for k in branch.assignment_from(0)],
                    pose_ids=pose_ids,
                    poses=poses,
                    landmark_ids=names,
                    landmark_classes=list(branch.landmark_class),
                    landmarks=landmarks,
                    consistency=branch.level,
                )
            )
        return sorted(result, key=lambda h: (h.n_landmarks, h.box_size))


def _label_permutations(h: Hypothesis, user_ids: set[str]) -> int:
    """How many ways of naming the hypothesis' new landmarks give the same partition."""
    counts: dict[str, int] = {}
    for name, cls in zip(h.landmark_ids, h.landmark_classes, strict=True):
        if name not in user_ids:
            counts[cls] = counts.get(cls, 0) + 1
    return math.prod(math.factorial(c) for c in counts.values())


def solve_unknown(
    log: Log,
    *,
    consistency: str = DEFAULT_LEVEL,
    max_hypotheses: int = DEFAULT_MAX_HYPOTHESES,
    strengthen_limit: int = DEFAULT_STRENGTHEN_LIMIT,
    strengthen_during: int = DEFAULT_STRENGTHEN_DURING,
    rtol: float = DEFAULT_RTOL,
    progress: Callable[[int, int], None] | None = None,
) -> Solution:
    """Solve a log whose observations may lack landmark ids; return every surviving hypothesis.

    Hypotheses are ranked by fewest landmarks, then smallest total box size.
    ``Solution.complete`` is False when ``max_hypotheses`` forced dropping some. The
    ``consistency`` level is applied to the survivors when at most ``strengthen_limit``
    remain; with a level other than ``hull``, ``lp`` is also applied after every branch
    point while at most ``strengthen_during`` hypotheses live, so that the narrower boxes
    gate and refute the next observations' candidates.
    """
    start = time.perf_counter()
    consistency = resolve_level(consistency, len(log.pose_ids))
    search = _Search(log, rtol, max_hypotheses, consistency, strengthen_during)
    search.run(progress)
    search.strengthen(consistency, strengthen_limit)
    hypotheses = search.hypotheses()
    user_ids = set(search.layout.user_landmark_x)
    search.stats.avoided_by_labelling = sum(
        _label_permutations(h, user_ids) - 1 for h in hypotheses
    )
    elapsed = time.perf_counter() - start
    messages = list(search.messages)
    if not hypotheses:
        if search.complete:
            messages.append(
                "every correspondence hypothesis is proven impossible: the log is inconsistent"
            )
        else:
            messages.append("no hypothesis left among those kept within the limit")
    statistics = {
        k: float(v) if isinstance(v, float) else v for k, v in asdict(search.stats).items()
    }
    statistics.update(
        poses=len(search.layout.pose_x),
        observations=len(log.observations),
        hypotheses=len(hypotheses),
    )
    return Solution(
        hypotheses=hypotheses,
        complete=search.complete,
        statistics=statistics,
        timings={"solve_s": elapsed},
        log_path=log.path,
        consistency=search.level_applied,
        messages=messages,
    )
