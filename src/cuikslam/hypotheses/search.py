"""Unknown correspondence: a collection of kinematic graphs, pruned only by proof (seed, Section 5).

The log is processed in time order. Each live hypothesis (a *branch*) holds its own
boxes and factors over one variable layout shared by all branches. An observation that
names no landmark splits every branch into: each existing landmark of the same class that
passes the gate, plus "a new landmark". A child starts from its parent's boxes and runs
only the operators its new factor wakes; a child that contracts to empty is discarded,
which is a proof, so the true correspondence is never lost.

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
    N_SLOTS,
    NO_FACTOR,
    OBSERVATION,
    ODOMETRY,
    UNSEEN,
    link_factor,
)
from cuikslam.hypotheses._gates import gate, pairs_within_reach
from cuikslam.interval._rounding import PI_HI, TWO_PI_HI
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
)
from cuikslam.narrowing._propagate import INCONSISTENT, propagate_arrays
from cuikslam.narrowing.consistency import DEFAULT_LEVEL, Arrays, resolve_level, strengthen
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL
from cuikslam.results.solution import Hypothesis, Solution

__all__ = [
    "DEFAULT_MAX_HYPOTHESES",
    "DEFAULT_STRENGTHEN_LIMIT",
    "SearchStatistics",
    "solve_unknown",
]

DEFAULT_MAX_HYPOTHESES = 10_000
"""Live hypotheses kept at most; beyond it the best-ranked are kept and the result is incomplete."""

DEFAULT_STRENGTHEN_LIMIT = 100
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


class _Branch:
    """One live hypothesis: boxes, factors and adjacency, and its landmark assignment."""

    __slots__ = (
        "assignment",
        "entry_factor",
        "entry_next",
        "factors",
        "head",
        "hi",
        "landmark_class",
        "landmark_name",
        "landmark_x",
        "lo",
        "n_entries",
        "n_factors",
    )

    def __init__(self, layout: _Layout) -> None:
        n_factors = len(layout.factor_measurements)
        self.lo = np.array(layout.lo, dtype=np.float64)
        self.hi = np.array(layout.hi, dtype=np.float64)
        self.factors = np.full((max(n_factors, 1), 1 + N_SLOTS), NO_FACTOR, dtype=np.int64)
        self.n_factors = n_factors
        """Log factors occupy [0, n_log); UNSEEN factors are appended after them."""
        self.head = np.full(layout.n_vars, -1, dtype=np.int64)
        self.entry_factor = np.zeros(N_SLOTS * max(n_factors, 1), dtype=np.int64)
        self.entry_next = np.zeros(N_SLOTS * max(n_factors, 1), dtype=np.int64)
        self.n_entries = 0
        self.landmark_x: list[int] = []
        self.landmark_class: list[str] = []
        self.landmark_name: list[str | None] = []
        self.assignment: list[int] = []

    def copy(self) -> _Branch:
        other = _Branch.__new__(_Branch)
        other.lo = self.lo.copy()
        other.hi = self.hi.copy()
        other.factors = self.factors.copy()
        other.n_factors = self.n_factors
        other.head = self.head.copy()
        other.entry_factor = self.entry_factor.copy()
        other.entry_next = self.entry_next.copy()
        other.n_entries = self.n_entries
        other.landmark_x = list(self.landmark_x)
        other.landmark_class = list(self.landmark_class)
        other.landmark_name = list(self.landmark_name)
        other.assignment = list(self.assignment)
        return other

    def add_factor(self, f: int, row: tuple[int, ...]) -> None:
        self.factors[f] = row
        self.n_entries = link_factor(
            self.factors[f], f, self.head, self.entry_factor, self.entry_next, self.n_entries
        )

    def append_factors(self, rows: np.ndarray) -> np.ndarray:
        """Append factors after the log's factors, growing the arrays; returns their indices."""
        needed = self.n_factors + len(rows)
        if needed > self.factors.shape[0]:
            capacity = max(needed, 2 * self.factors.shape[0])
            grown = np.full((capacity, 1 + N_SLOTS), NO_FACTOR, dtype=np.int64)
            grown[: self.factors.shape[0]] = self.factors
            self.factors = grown
            for name in ("entry_factor", "entry_next"):
                old = getattr(self, name)
                new = np.zeros(N_SLOTS * capacity, dtype=np.int64)
                new[: old.shape[0]] = old
                setattr(self, name, new)
        indices = np.arange(self.n_factors, needed, dtype=np.int64)
        for f, row in zip(indices, rows, strict=True):
            self.add_factor(int(f), tuple(row))
        self.n_factors = needed
        return indices

    def factors_of(self, variables: list[int]) -> np.ndarray:
        found: set[int] = set()
        for v in variables:
            e = self.head[v]
            while e >= 0:
                found.add(int(self.entry_factor[e]))
                e = self.entry_next[e]
        return np.array(sorted(found), dtype=np.int64)

    def propagate(self, touched: np.ndarray, rtol: float, stats: SearchStatistics) -> bool:
        """Narrow to the fixpoint from ``touched``; False when proven empty."""
        if touched.size == 0:
            return True
        ensure_round_to_nearest()
        status, applications = propagate_arrays(
            self.lo,
            self.hi,
            self.factors,
            self.head,
            self.entry_factor,
            self.entry_next,
            touched,
            rtol,
            DEFAULT_ROUNDS,
            2**62,
        )
        stats.operator_applications += applications
        return status != INCONSISTENT

    def box_size(self, pose_xs: np.ndarray) -> float:
        """Sum of all pose (x, y, theta) and landmark widths, as :attr:`Hypothesis.box_size`."""
        marks = np.array(self.landmark_x, dtype=np.int64)
        cols = np.concatenate([pose_xs, pose_xs + 1, pose_xs + 2, marks, marks + 1])
        return float(np.sum(self.hi[cols] - self.lo[cols]))


class _Search:
    """The incremental search over one log."""

    def __init__(self, log: Log, rtol: float, max_hypotheses: int) -> None:
        self.log = log
        self.rtol = rtol
        self.max_hypotheses = max_hypotheses
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
        self.completes_after: dict[int, list[int]] = self._scan_completion()
        self.branches = [_Branch(self.layout)]
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
    def _all(self, apply: Callable[[_Branch], bool]) -> None:
        survivors = []
        for branch in self.branches:
            if apply(branch):
                survivors.append(branch)
            else:
                self.stats.proven_empty += 1
        self.branches = survivors

    def _narrow_and_propagate(
        self, first: Callable[[_Branch], int], bounds: list[tuple[float, float]]
    ) -> None:
        """Intersect consecutive variables (from ``first(branch)``) with ``bounds``; propagate."""

        def apply(branch: _Branch) -> bool:
            start = first(branch)
            variables = list(range(start, start + len(bounds)))
            for v, (lo, hi) in zip(variables, bounds, strict=True):
                branch.lo[v] = max(branch.lo[v], lo)
                branch.hi[v] = min(branch.hi[v], hi)
                if branch.lo[v] > branch.hi[v]:
                    return False
            return branch.propagate(branch.factors_of(variables), self.rtol, self.stats)

        self._all(apply)

    def _fixed_factor(self, index: int, row: Callable[[_Branch], tuple[int, ...]]) -> None:
        """Add the factor of record ``index`` (its row may differ by branch) everywhere."""
        f = self.layout.record_factor[index]
        touched = np.array([f], dtype=np.int64)

        def apply(branch: _Branch) -> bool:
            branch.add_factor(f, row(branch))
            return branch.propagate(touched, self.rtol, self.stats)

        self._all(apply)

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
            seen_here = {branch.assignment[self.observation_position[o]] for o in same_scan}
            for number, (name, cls) in enumerate(
                zip(branch.landmark_name, branch.landmark_class, strict=True)
            ):
                if name is not None or cls != landmark_class:
                    continue
                self.stats.candidates += 1
                if number in seen_here:
                    self.stats.excluded_same_scan += 1
                    continue
                child = branch.copy()
                child.landmark_name[number] = landmark
                self.stats.created += 1
                children.append(child)
            self.stats.candidates += 1
            branch.landmark_x.append(self.layout.user_landmark_x[landmark])
            branch.landmark_class.append(landmark_class)
            branch.landmark_name.append(landmark)
            number = len(branch.landmark_x) - 1
            if self.has_sensor and not self._add_unseen(branch, self.scan_done, [number]):
                self.stats.refuted_by_negative_information += 1
                continue
            children.append(branch)
        self.branches = children

    @staticmethod
    def _landmark_x(branch: _Branch, landmark: str) -> int:
        return branch.landmark_x[branch.landmark_name.index(landmark)]

    def _observation_row(self, index: int, record: Observation, landmark_x: int) -> tuple[int, ...]:
        a = self.layout.pose_x[record.pose]
        m, n = self.layout.factor_measurements[self.layout.record_factor[index]]
        return (OBSERVATION, a, a + 1, a + 2, landmark_x, landmark_x + 1, -1, m, n)

    def _branch(self, index: int, record: Observation) -> None:
        """Split every branch over the landmarks this observation may be."""
        self.stats.branch_points += 1
        f = self.layout.record_factor[index]
        touched = np.array([f], dtype=np.int64)
        pose_x = self.layout.pose_x[record.pose]
        bearing_var, range_var = self.layout.factor_measurements[f]
        slot_x = self.layout.observation_slot_x[index]
        same_scan = self.observations_at.get(record.pose, [])
        children: list[_Branch] = []
        for branch in self.branches:
            seen_here = {branch.assignment[self.observation_position[o]] for o in same_scan}
            for number, cls in enumerate(branch.landmark_class):
                if cls != record.landmark_class:
                    continue
                self.stats.candidates += 1
                if number in seen_here:
                    self.stats.excluded_same_scan += 1
                    continue
                landmark_x = branch.landmark_x[number]
                if not gate(branch.lo, branch.hi, pose_x, landmark_x, bearing_var, range_var):
                    self.stats.gated += 1
                    continue
                child = branch.copy()
                child.add_factor(f, self._observation_row(index, record, landmark_x))
                if not child.propagate(touched, self.rtol, self.stats):
                    self.stats.proven_empty += 1
                    continue
                child.assignment.append(number)
                self.stats.created += 1
                children.append(child)
            # the new landmark: the parent itself becomes this child (no copy)
            self.stats.candidates += 1
            branch.add_factor(f, self._observation_row(index, record, slot_x))
            if not branch.propagate(touched, self.rtol, self.stats):
                self.stats.proven_empty += 1
                continue
            branch.landmark_x.append(slot_x)
            branch.landmark_class.append(record.landmark_class)
            branch.landmark_name.append(None)
            branch.assignment.append(len(branch.landmark_x) - 1)
            if self.has_sensor and not self._add_unseen(
                branch,
                [p for p in self.scan_done if p != record.pose],
                [len(branch.landmark_x) - 1],
            ):
                self.stats.refuted_by_negative_information += 1
                continue
            self.stats.created += 1
            children.append(branch)
        self.branches = children

    # ---------------------------------------------------------- negative information
    def _add_unseen(self, branch: _Branch, poses: list[int], landmarks: list[int]) -> bool:
        """Add UNSEEN constraints between ``poses`` and the landmark numbers ``landmarks`` that
        the poses did not observe and that are within reach; False when that proves the
        branch impossible."""
        if not poses or not landmarks:
            return True
        seen = np.zeros((len(poses), len(landmarks)), dtype=np.bool_)
        column = {number: j for j, number in enumerate(landmarks)}
        for i, pose in enumerate(poses):
            for o in self.observations_at.get(pose, []):
                j = column.get(branch.assignment[self.observation_position[o]])
                if j is not None:
                    seen[i, j] = True
        pose_xs = np.array([self.layout.pose_x[p] for p in poses], dtype=np.int64)
        radius_vars = np.array([self.layout.radius_var[p] for p in poses], dtype=np.int64)
        landmark_xs = np.array([branch.landmark_x[n] for n in landmarks], dtype=np.int64)
        pairs = pairs_within_reach(
            branch.lo, branch.hi, pose_xs, branch.lo[radius_vars], landmark_xs, seen
        )
        if len(pairs) == 0:
            return True
        a = pose_xs[pairs[:, 0]]
        b = landmark_xs[pairs[:, 1]]
        rows = np.column_stack(
            [
                np.full(len(pairs), UNSEEN),
                a, a + 1, a + 2, b, b + 1,
                np.full(len(pairs), -1),
                np.full(len(pairs), self.layout.arc_var),
                radius_vars[pairs[:, 0]],
            ]
        )  # fmt: skip
        self.stats.unseen_constraints += len(rows)
        return branch.propagate(branch.append_factors(rows), self.rtol, self.stats)

    def _scans_done(self, poses: list[int]) -> None:
        """The scans of ``poses`` are complete: every landmark they missed gets an UNSEEN."""
        self.scan_done.extend(poses)
        if not self.has_sensor:
            return
        survivors = []
        for branch in self.branches:
            if self._add_unseen(branch, poses, list(range(len(branch.landmark_x)))):
                survivors.append(branch)
            else:
                self.stats.refuted_by_negative_information += 1
        self.branches = survivors

    # ------------------------------------------------------------------ ranking
    def strengthen(self, level: str, limit: int) -> None:
        """Narrow the live branches to ``level``; drop the ones that become empty (a proof).

        Skipped (with a message) when more than ``limit`` branches live: the stronger
        levels cost a fraction of a second per branch.
        """
        if level != "hull" and len(self.branches) > limit:
            self.messages.append(
                f"{len(self.branches)} hypotheses survived hull consistency: the '{level}' "
                f"level was not applied to them (it is applied to at most {limit}; raise "
                "--strengthen-limit to apply it); their boxes are hull-consistent"
            )
            self.level_applied = "hull"
            return
        self.level_applied = level
        survivors = []
        for branch in self.branches:
            arrays = Arrays(
                branch.factors[: branch.n_factors],
                branch.head,
                branch.entry_factor,
                branch.entry_next,
            )
            status, applications = strengthen(
                arrays, branch.lo, branch.hi, level, self.rtol, DEFAULT_ROUNDS
            )
            self.stats.operator_applications += applications
            if status == INCONSISTENT:
                self.stats.refuted_by_consistency += 1
            else:
                survivors.append(branch)
        self.branches = survivors

    def _ranked(self) -> list[_Branch]:
        pose_xs = np.array(sorted(self.layout.pose_x.values()), dtype=np.int64)
        return sorted(self.branches, key=lambda b: (len(b.landmark_x), b.box_size(pose_xs)))

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

    # ------------------------------------------------------------------ driver
    def run(self, progress: Callable[[int, int], None] | None) -> None:
        total = len(self.log.records)
        for index, record in enumerate(self.log.records):
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
                        branch.assignment.append(branch.landmark_name.index(name))
                self.observation_position[index] = len(self.observation_position)
                self.observations_at.setdefault(record.pose, []).append(index)
            completed = self.completes_after.get(index, [])
            if completed:
                self._scans_done(completed)
            self.stats.peak_alive = max(self.stats.peak_alive, len(self.branches))
            self._enforce_limit(index)
            if progress is not None:
                progress(index + 1, total)
            if not self.branches:
                break

    # ------------------------------------------------------------------ results
    def hypotheses(self) -> list[Hypothesis]:
        pose_ids = sorted(self.layout.pose_x)
        pose_xs = np.array([self.layout.pose_x[p] for p in pose_ids], dtype=np.int64)
        has_user_ids = bool(self.layout.user_landmark_x)
        result = []
        for branch in self._ranked():
            names = []
            new_count = 0
            for name in branch.landmark_name:
                if name is None:
                    new_count += 1
                    name = f"N{new_count}" if has_user_ids else f"L{new_count}"
                names.append(name)
            cols = pose_xs[:, None] + np.arange(3)[None, :]
            poses = np.stack([branch.lo[cols], branch.hi[cols]], axis=-1)
            lx = np.array(branch.landmark_x, dtype=np.int64).reshape(-1)
            lcols = lx[:, None] + np.arange(2)[None, :]
            landmarks = np.stack([branch.lo[lcols], branch.hi[lcols]], axis=-1).reshape(-1, 2, 2)
            result.append(
                Hypothesis(
                    assignment=[names[k] for k in branch.assignment],
                    pose_ids=pose_ids,
                    poses=poses,
                    landmark_ids=names,
                    landmark_classes=list(branch.landmark_class),
                    landmarks=landmarks,
                )
            )
        return result


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
    rtol: float = DEFAULT_RTOL,
    progress: Callable[[int, int], None] | None = None,
) -> Solution:
    """Solve a log whose observations may lack landmark ids; return every surviving hypothesis.

    Hypotheses are ranked by fewest landmarks, then smallest total box size.
    ``Solution.complete`` is False when ``max_hypotheses`` forced dropping some.
    """
    start = time.perf_counter()
    consistency = resolve_level(consistency, len(log.pose_ids))
    search = _Search(log, rtol, max_hypotheses)
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
