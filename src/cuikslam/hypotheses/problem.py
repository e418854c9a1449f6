"""A log as a correspondence problem: variables, the constraints every hypothesis shares,
and the decisions that tell hypotheses apart.

Everything that does not depend on the correspondence is built once, at the *root*:
pose priors, odometry, observations that name their landmark, landmark priors, and each
unlabelled observation's factor on its own *slot* (the landmark it would create if it saw
a new one). A hypothesis is then a sequence of *decisions*, one per unlabelled
observation in log order: the landmark it sees is a named landmark, an anonymous landmark
an earlier decision created, or new (its slot). Named landmarks exist from the root, so a
name that first appears late in the log is a candidate from the first decision on.

Landmarks are numbered: the named ones first (in order of first appearance), then the
anonymous ones in order of creation, so two hypotheses that differ only in the names of
new landmarks cannot arise.
"""

from __future__ import annotations

import math
from collections.abc import Hashable
from dataclasses import dataclass, field

import numpy as np

from cuikslam.graph.encoding import (
    ANGLE,
    KIND,
    LENGTH,
    N_SLOTS,
    OBSERVATION,
    TA,
    TB,
    UNSEEN,
    XA,
    XB,
    YA,
    YB,
)
from cuikslam.graph.variables import Variables, length_bounds, observation_row, offset_key
from cuikslam.hypotheses.outlier_option import OutlierOption, outlier_option, relax_named
from cuikslam.interval.angles import out_of_view_arc
from cuikslam.log.records import (
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)
from cuikslam.narrowing.outliers import RelaxedReport
from cuikslam.narrowing.propagation import DEFAULT_RTOL

__all__ = ["Decision", "Problem", "observation_rows", "region_of", "unseen_rows"]


@dataclass(frozen=True)
class Decision:
    """One unlabelled observation: which landmark it sees is decided by the search."""

    record: int
    """Index of the observation in ``Log.records``."""
    position: int
    """Index among all observations (the hypothesis' assignment is in this order)."""
    pose: int
    pose_x: int
    bearing_var: int
    range_var: int
    slot_x: int
    """x variable of the landmark it creates when it sees a new one."""
    landmark_class: str
    completes_scan: bool
    """True when it is the last unlabelled observation of its pose."""
    scan: Hashable = None
    """Its scan, whose observations see distinct landmarks: the pose, or ``(pose,
    offset)`` for an observation made from a sensor offset."""
    sensor_x: int = -1
    """x variable of the pose it is made from: the robot's, or its sensor's (offsets)."""


@dataclass
class Problem:
    """Variables and constraints of a log, shared by every correspondence hypothesis."""

    lo: np.ndarray
    hi: np.ndarray
    root_rows: np.ndarray
    """Factor rows that hold in every hypothesis."""
    pose_x: dict[int, int]
    named: list[str]
    """Ids of the named landmarks, landmark numbers 0..len-1."""
    named_x: np.ndarray
    named_class: list[str]
    decisions: list[Decision]
    seen_named: dict[Hashable, set[int]]
    """Scan (see :attr:`Decision.scan`) -> numbers of the named landmarks its named
    observations see."""
    named_assignment: dict[int, int]
    """Observation position -> landmark number, for observations that name their landmark."""
    first_seen: list[int]
    """Record index of the first appearance of each named landmark."""
    has_sensor: bool
    radius_var: dict[int, int] = field(default_factory=dict)
    arc_var: int = -1
    """The variable holding the bearings out of the sensor's view (a constant), or -1 for a
    sensor that sees all around: no variable ever holds an empty box, which would read as a
    proof of inconsistency wherever the whole box is checked."""
    n_observations: int = 0
    class_priors: dict[str, ClassPrior] = field(default_factory=dict)
    """The user's priors on each class of landmarks (count, separation, region)."""
    sensor_x: dict[int, list[int]] = field(default_factory=dict)
    """Pose -> x variables of its sensors' poses (observations with an offset)."""
    outlier: OutlierOption | None = None
    """The log's outliers declaration, as the search applies it (None: none)."""
    named_outliers: RelaxedReport | None = None
    """With a declaration, what the q-relaxed intersection of the named observations proved
    at the root (:func:`.outlier_option.relax_named`)."""
    named_positions: list[int] = field(default_factory=list)
    """Observation position of each named observation, in log order."""

    @property
    def refuted_at_root(self) -> bool:
        """True when the named observations alone break the outliers declaration."""
        return self.named_outliers is not None and self.named_outliers.exceeded

    @property
    def ranked_vars(self) -> np.ndarray:
        """Pose variables, whose widths rank hypotheses."""
        xs = np.array(sorted(self.pose_x.values()), dtype=np.int64)
        return np.sort(np.concatenate([xs, xs + 1, xs + 2]))

    def complete_at_root(self) -> list[int]:
        """Poses without unlabelled observations: their scans are known from the start."""
        undecided = {d.pose for d in self.decisions}
        return [p for p in self.pose_x if p not in undecided]

    def completions(self) -> tuple[list[int], np.ndarray]:
        """Poses in the order their scans are complete (those of :meth:`complete_at_root`
        first), and how many of them are complete before each decision (and after the
        last): the poses complete before decision ``k`` are the first ``before[k]``."""
        done = self.complete_at_root()
        before = np.empty(len(self.decisions) + 1, dtype=np.int64)
        for k, d in enumerate(self.decisions):
            before[k] = len(done)
            if d.completes_scan:
                done.append(d.pose)
        before[-1] = len(done)
        return done, before


def build_problem(log: Log) -> Problem:
    """Lay out the variables of ``log`` and the factor rows every hypothesis shares."""
    b = Variables()
    pose_x: dict[int, int] = {}
    named: dict[str, int] = {}
    named_class: list[str] = []
    first_seen: list[int] = []
    rows: list[tuple[int, ...]] = []
    pending: list[tuple[int, Observation, int, int, int]] = []
    seen_named: dict[Hashable, set[int]] = {}
    sensor_of: dict[tuple[int, tuple[tuple[float, float], ...]], int] = {}
    sensor_x: dict[int, list[int]] = {}
    named_assignment: dict[int, int] = {}
    named_rows: list[int] = []

    def pose(p: int) -> int:
        if p not in pose_x:
            pose_x[p] = b.pose()
        return pose_x[p]

    def sensor(record: Observation) -> tuple[Hashable, int]:
        """The scan of an observation and the x variable of the pose it is made from: with
        an offset, the sensor's pose, tied to the robot's by a relative pose (one per
        pose and offset, as in :meth:`KinematicGraph.add_observation`)."""
        a = pose(record.pose)
        if record.offset is None:
            return record.pose, a
        key = (record.pose, offset_key(record.offset))
        if key not in sensor_of:
            x, sensor_rows = b.sensor_pose(a, key[1])
            sensor_of[key] = x
            sensor_x.setdefault(record.pose, []).append(x)
            rows.extend(sensor_rows)
        return key, sensor_of[key]

    def landmark(name: str, cls: str, index: int) -> int:
        if name not in named:
            named[name] = len(named)
            named_class.append(cls)
            first_seen.append(index)
            named_x.append(b.landmark())
        return named[name]

    named_x: list[int] = []
    position = 0
    for index, record in enumerate(log.records):
        if isinstance(record, PosePrior):
            b.meet_pose(pose(record.pose), record.x, record.y, record.theta)
        elif isinstance(record, LandmarkPrior):
            n = landmark(record.landmark, record.landmark_class, index)
            b.meet_point(named_x[n], record.x, record.y)
        elif isinstance(record, Odometry):
            a, c = pose(record.source), pose(record.target)
            rows.append(b.odometry(a, c, record.turn, record.distance))
        elif isinstance(record, RelativePose):
            a, c = pose(record.source), pose(record.target)
            rows.extend(b.relative_pose(a, c, record.dx, record.dy, record.dtheta))
        elif isinstance(record, Observation):
            scan, a = sensor(record)
            m = b.measurement(record.bearing, record.range)
            if record.landmark is None:
                slot = b.landmark()
                rows.append(observation_row(a, slot, m))
                pending.append((index, record, position, m, slot, scan, a))
            else:
                n = landmark(record.landmark, record.landmark_class, index)
                named_rows.append(len(rows))
                rows.append(observation_row(a, named_x[n], m))
                seen_named.setdefault(scan, set()).add(n)
                named_assignment[position] = n
            position += 1
    last_decision: dict[int, int] = {}
    for k, (_, record, *_) in enumerate(pending):
        last_decision[record.pose] = k
    decisions = [
        Decision(
            record=index,
            position=pos,
            pose=record.pose,
            pose_x=pose_x[record.pose],
            bearing_var=m,
            range_var=m + 1,
            slot_x=slot,
            landmark_class=record.landmark_class,
            completes_scan=last_decision[record.pose] == k,
            scan=scan,
            sensor_x=sensor_x,
        )
        for k, (index, record, pos, m, slot, scan, sensor_x) in enumerate(pending)
    ]
    option = outlier_option(log, [d.pose for d in decisions])
    if option is not None:
        seen_named = {}  # a named observation may be an outlier: it excludes nothing
    problem = Problem(
        lo=np.zeros(0),
        hi=np.zeros(0),
        root_rows=np.array(rows, dtype=np.int64).reshape(-1, 1 + N_SLOTS),
        pose_x=pose_x,
        named=list(named),
        named_x=np.array(named_x, dtype=np.int64),
        named_class=named_class,
        decisions=decisions,
        seen_named=seen_named,
        named_assignment=named_assignment,
        first_seen=first_seen,
        has_sensor=log.sensor is not None,
        n_observations=position,
        sensor_x=sensor_x,
        outlier=option,
        named_positions=sorted(named_assignment),
    )
    if log.sensor is not None:
        _add_sensor_variables(problem, b, log)
    problem.class_priors = log.class_priors
    _restrict_to_regions(problem, b)
    problem.lo, problem.hi = b.arrays()
    if option is not None and named_rows:
        problem.root_rows, problem.named_outliers = relax_named(
            problem.root_rows, np.array(named_rows), problem.lo, problem.hi, option, DEFAULT_RTOL
        )
    return problem


def _restrict_to_regions(problem: Problem, b: Variables) -> None:
    """Every landmark of a class with a region lies in it: its named landmarks, and the slot
    of each of its unlabelled observations (whichever landmark that one sees). With an
    outliers declaration the slots are left free: an outlier's slot, tied to its pose by the
    observation's wrong value, must constrain nothing; the region then joins a slot when it
    becomes a new landmark (:func:`region_of`)."""
    located = [(x, c) for x, c in zip(problem.named_x.tolist(), problem.named_class, strict=True)]
    if problem.outlier is None:
        located += [(d.slot_x, d.landmark_class) for d in problem.decisions]
    for x, cls in located:
        prior = problem.class_priors.get(cls)
        if prior is not None and prior.x is not None and prior.y is not None:
            b.meet_point(x, prior.x, prior.y)


def region_of(problem: Problem, landmark_class: str) -> tuple[np.ndarray, np.ndarray] | None:
    """The region of a class's landmarks as (lo, hi) of (x, y); None without one."""
    prior = problem.class_priors.get(landmark_class)
    if prior is None or prior.x is None or prior.y is None:
        return None
    return np.array([prior.x[0], prior.y[0]]), np.array([prior.x[1], prior.y[1]])


def _add_sensor_variables(problem: Problem, b: Variables, log: Log) -> None:
    """Constants of the UNSEEN constraints: a visibility radius per pose, the out-of-view arc.

    The radius is a lower bound of the distance within which the pose saw every landmark
    in view: ``max_range``, and with ``nearest_margin`` the nearest observed range's lower
    bound plus the margin, rounded down.
    """
    sensor = log.sensor
    nearest: dict[int, float] = {}
    for record in log.observations:
        low = length_bounds(record.range)[0]
        nearest[record.pose] = min(nearest.get(record.pose, math.inf), low)
    for pose in problem.pose_x:
        radius = sensor.max_range
        if sensor.nearest_margin is not None:
            limit = float(np.nextafter(nearest.get(pose, math.inf) + sensor.nearest_margin, 0.0))
            radius = min(radius, limit)
        problem.radius_var[pose] = b.new((radius, radius))
    arc = out_of_view_arc(sensor.fov)
    problem.arc_var = -1 if arc is None else b.new(arc)


def observation_rows(problem: Problem, decision: Decision, landmark_xs: np.ndarray) -> np.ndarray:
    """Factor rows of ``decision``'s observation seeing the landmarks at x ``landmark_xs``."""
    rows = np.empty((len(landmark_xs), 1 + N_SLOTS), dtype=np.int64)
    a = decision.sensor_x
    rows[:, [KIND, XA, YA, TA, TB]] = (OBSERVATION, a, a + 1, a + 2, -1)
    rows[:, XB], rows[:, YB] = landmark_xs, landmark_xs + 1
    rows[:, [ANGLE, LENGTH]] = (decision.bearing_var, decision.range_var)
    return rows


def unseen_rows(
    problem: Problem, pose_xs: np.ndarray, radius_vars: np.ndarray, landmark_xs: np.ndarray
) -> np.ndarray:
    """UNSEEN rows: pose ``pose_xs[i]`` (visibility radius ``radius_vars[i]``) did not see the
    landmark at x ``landmark_xs[i]``; their angle slot is the out-of-view arc's variable, -1
    when the sensor sees all around."""
    rows = np.empty((len(pose_xs), 1 + N_SLOTS), dtype=np.int64)
    rows[:, [KIND, TB, ANGLE]] = (UNSEEN, -1, problem.arc_var)
    rows[:, XA], rows[:, YA], rows[:, TA] = pose_xs, pose_xs + 1, pose_xs + 2
    rows[:, XB], rows[:, YB] = landmark_xs, landmark_xs + 1
    rows[:, LENGTH] = radius_vars
    return rows
