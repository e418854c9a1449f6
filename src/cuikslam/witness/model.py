"""The forward-kinematics parametrisation of one hypothesis, and its checks in floating point.

A candidate world is given by a parameter vector (:class:`HypothesisModel`):

* the pose of an *anchor* ``(x, y, theta)``: the pose with the narrowest prior, bounded by
  that prior's box (the other priors are checks: a point prior anchors exactly, where a
  check could never be verified); poses that no motion chain connects to a prior pose get
  their own, unbounded anchor;
* per *tree* motion record, bounded by its measured intervals: ``(turn, distance)`` for an
  ``odometry`` record (distance clipped at 0, as the kinematic graph does), ``(dx, dy,
  dtheta)`` for a ``relative_pose`` record. Motion records are taken in log order, and each
  one that links a placed pose to an unplaced one places the latter by forward kinematics
  (or backward kinematics when only its target is placed; see :mod:`._kinematics`);
* ``(dx, dy, dtheta)`` per sensor pose, bounded by the offset's intervals: observations
  with an ``offset`` are made from the robot pose composed with it, one sensor pose per
  pose and offset (one scan), as the kinematic graph builds them (a degenerate offset is a
  fixed parameter);
* ``(x, y)`` per landmark, free.

Everything else becomes a *check*: the range and bearing of each observation (from its
sensor's pose), every prior (pose priors, including the anchors' own, and landmark
priors), each *loop-closing* odometry record (into an already placed pose): its turn and
distance intervals, and the *equality* ``cross(p_t - p_s, (cos theta_t, sin theta_t)) = 0``
(the heading of the target equals the direction of travel), and each loop-closing
``relative_pose`` record: the pose of its target in the frame of its source must lie in its
``dx``, ``dy`` and ``dtheta`` intervals (three inequalities, the heading modulo 2 pi; no
equality).

When the log declares a :class:`~cuikslam.log.records.SensorModel`, its negative
information is a check too: at every pose the observed landmarks must be exactly those the
sensor is sure to see. A landmark is *visible* from a pose when it is within
``max_range`` and its bearing within ``fov / 2`` of the heading; when ``nearest_margin``
is set, the robot sees only the visible landmarks within ``nearest_margin`` of the nearest
visible one. Observed landmarks must be seen, unobserved ones must not. (A log cannot
combine a sensor record with observation offsets, so the robot's pose is the sensor's.)

The model evaluates all of this in floating point, with Jacobians, for the optimisers of
:mod:`.find` and :mod:`.hull`, gives them starting points (:mod:`._starts`) and the
equalities and residuals they minimise (:mod:`._residuals`); :mod:`.verify` re-does
the forward kinematics in interval arithmetic from the same parameters.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cuikslam.graph.variables import length_bounds, offset_key
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)
from cuikslam.witness._kinematics import Tree, kinematics, relative_values
from cuikslam.witness._numeric import finite, half_width, midpoint, wrap_near
from cuikslam.witness._residuals import Residuals
from cuikslam.witness._sensor import SENSOR_MARGIN as SENSOR_MARGIN
from cuikslam.witness._sensor import distance as _distance
from cuikslam.witness._starts import LandmarkBoxes as LandmarkBoxes
from cuikslam.witness._starts import PoseBoxes as PoseBoxes
from cuikslam.witness._starts import Starts

AIM_FRACTION = 0.1
"""The optimiser aims this fraction of each interval's half-width inside it."""
MIN_MARGIN = 1e-9
"""...but at least this much (unless the interval is narrower)."""
FIXED_WIDTH = 1e-12
"""A parameter whose interval is narrower than this (relative) is not optimised."""


def aim_margin(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How far inside ``[lo, hi]`` the optimiser aims: 10 % of the half-width, >= 1e-9."""
    half = half_width(lo, hi)
    with np.errstate(invalid="ignore"):
        margin = np.minimum(np.maximum(AIM_FRACTION * half, MIN_MARGIN), 0.5 * half)
    return np.where(np.isfinite(half), np.maximum(margin, 0.0), MIN_MARGIN)


def _typical_half_width(lo: np.ndarray, hi: np.ndarray) -> float:
    """The median half-width of the bounded, non-degenerate intervals (1.0 without any)."""
    half = half_width(lo, hi)
    half = half[np.isfinite(half) & (half > 0)]
    return float(np.median(half)) if half.size else 1.0


def _width(prior: PosePrior | None) -> float:
    """The summed widths of a pose prior's x, y and heading intervals (inf: none)."""
    if prior is None:
        return math.inf
    with np.errstate(over="ignore", invalid="ignore"):
        return float(sum(hi - lo for lo, hi in (prior.x, prior.y, prior.theta)))


def _pair(bounds: tuple[float, float] | None) -> tuple[float, float]:
    if bounds is None:
        return (math.nan, math.nan)
    return (float(bounds[0]), float(bounds[1]))


@dataclass
class WitnessPoint:
    """A candidate solution: the parameter vector and the world it implies.

    ``poses_xyt`` (rows in ``pose_ids`` order) and ``landmarks_xy`` (rows in
    ``landmark_ids`` order) are the floating-point forward kinematics of ``params``.
    """

    params: np.ndarray
    pose_ids: list[int]
    poses_xyt: np.ndarray
    landmark_ids: list[str]
    landmarks_xy: np.ndarray
    residual: float = 0.0
    """Largest floating-point violation of the aimed margins (0 when all are met)."""

    def pose(self, pose_id: int) -> np.ndarray:
        return self.poses_xyt[self.pose_ids.index(pose_id)]

    def landmark(self, landmark_id: str) -> np.ndarray:
        return self.landmarks_xy[self.landmark_ids.index(landmark_id)]


class HypothesisModel(Starts, Residuals):
    """The parametrisation of a hypothesis and its checks (see the module docstring).

    Poses and landmarks are numbered in the order the kinematic graph uses (first
    appearance in the log), so that arrays of a :class:`~cuikslam.outcome.solution.Hypothesis` of a
    known-correspondence solve line up; mappings by id are accepted everywhere too.
    ``problems`` lists structural contradictions (a landmark of two classes, one landmark
    twice in a scan, an empty interval): a hypothesis with problems never gets a witness.

    The optimisers and :mod:`.verify` work on *frames*: the ``n_poses`` robot poses, then
    one sensor pose per (pose, offset) of the observations with an offset
    (``sensor_frames``); ``obs_pose`` holds each observation's frame, ``obs_robot`` its
    robot pose.
    """

    def __init__(self, log: Log, assignment: Sequence[str], use_sensor: bool = True) -> None:
        observations = log.observations
        if len(assignment) != len(observations):
            raise ValueError(
                f"assignment has {len(assignment)} entries for {len(observations)} observations"
            )
        self.problems: list[str] = []
        self.pose_ids: list[int] = []
        self.landmark_ids: list[str] = []
        self.landmark_classes: list[str] = []
        self._pose_index: dict[int, int] = {}
        self._landmark_index: dict[str, int] = {}

        def add_pose(pose: int) -> int:
            if pose not in self._pose_index:
                self._pose_index[pose] = len(self.pose_ids)
                self.pose_ids.append(pose)
            return self._pose_index[pose]

        def add_landmark(landmark: str, cls: str) -> int:
            if landmark not in self._landmark_index:
                self._landmark_index[landmark] = len(self.landmark_ids)
                self.landmark_ids.append(landmark)
                self.landmark_classes.append(cls)
            elif cls and self.landmark_classes[self._landmark_index[landmark]] != cls:
                known = self.landmark_classes[self._landmark_index[landmark]]
                if known:
                    self.problems.append(f"landmark {landmark} has classes {known} and {cls}")
                else:
                    self.landmark_classes[self._landmark_index[landmark]] = cls
            return self._landmark_index[landmark]

        anchor_prior: dict[int, PosePrior] = {}
        pose_priors: list[PosePrior] = []
        landmark_priors: list[LandmarkPrior] = []
        motions: list[Odometry | RelativePose] = []
        obs_robot: list[int] = []
        obs_offset: list[tuple | None] = []
        obs_landmark: list[int] = []
        obs_range: list[tuple[float, float]] = []
        obs_bearing: list[tuple[float, float]] = []
        scans: dict[tuple, set[int]] = {}
        k = 0
        for record in log.records:
            if isinstance(record, PosePrior):
                add_pose(record.pose)
                if _width(record) < _width(anchor_prior.get(record.pose)):
                    anchor_prior[record.pose] = record
                pose_priors.append(record)
            elif isinstance(record, (Odometry, RelativePose)):
                add_pose(record.source)
                add_pose(record.target)
                motions.append(record)
            elif isinstance(record, LandmarkPrior):
                add_landmark(record.landmark, record.landmark_class)
                landmark_priors.append(record)
            elif isinstance(record, Observation):
                i = add_pose(record.pose)
                j = add_landmark(str(assignment[k]), record.landmark_class)
                k += 1
                offset = None if record.offset is None else offset_key(record.offset)
                if j in scans.setdefault((i, offset), set()):
                    self.problems.append(
                        f"landmark {assignment[k - 1]} observed twice from pose {record.pose}"
                    )
                scans[(i, offset)].add(j)
                obs_robot.append(i)
                obs_offset.append(offset)
                obs_landmark.append(j)
                obs_range.append(_pair(record.range))
                obs_bearing.append(_pair(record.bearing))
        n = len(self.pose_ids)
        m = len(self.landmark_ids)

        # ---- parameters: anchors, tree motions, sensor offsets, landmarks
        tree = Tree()
        # anchored at the narrowest prior: a point prior anchors exactly, where as a check
        # it would be an equality no interval enclosure can verify
        narrowest = sorted(pose_priors, key=_width)
        order = [self._pose_index[p.pose] for p in narrowest] + list(range(n))
        tree.grow(self.pose_ids, self._pose_index, order, anchor_prior, motions)
        tree.add_sensors(self.pose_ids, obs_robot, obs_offset)
        self.anchors, self.steps, used = tree.anchors, tree.steps, tree.used
        self.sensor_frames = tree.sensor_frames
        self.n_frames = n + len(self.sensor_frames)
        self.landmark_param0 = len(tree.lo)
        for lid in self.landmark_ids:
            tree.new_param(f"landmark {lid} x", (-math.inf, math.inf))
            tree.new_param(f"landmark {lid} y", (-math.inf, math.inf))
        lo, hi, names, obs_pose = tree.lo, tree.hi, tree.names, tree.obs_frame
        self.param_lo = np.array(lo) + 0.0  # -0.0 -> 0.0
        self.param_hi = np.array(hi) + 0.0
        self.param_names = names
        self.n_params = len(lo)
        if np.any(self.param_lo > self.param_hi):
            self.problems.append("a motion, offset or prior interval is empty")

        # ---- checks
        self.obs_pose = np.array(obs_pose, dtype=np.int64)
        self.obs_robot = np.array(obs_robot, dtype=np.int64)
        self.obs_landmark = np.array(obs_landmark, dtype=np.int64)
        obs_range_a = np.array(obs_range, dtype=float).reshape(-1, 2)
        obs_bearing_a = np.array(obs_bearing, dtype=float).reshape(-1, 2)
        self.range_sel = np.flatnonzero(~np.isnan(obs_range_a[:, 0]))
        self.bearing_sel = np.flatnonzero(~np.isnan(obs_bearing_a[:, 0]))
        self.prior_pose = np.array(
            [self._pose_index[p.pose] for p in pose_priors for _ in range(3)], dtype=np.int64
        )
        self.prior_coord = np.tile(np.arange(3), len(pose_priors)).astype(np.int64)
        prior_b = [b for p in pose_priors for b in (p.x, p.y, p.theta)]
        self.lprior_landmark = np.array(
            [self._landmark_index[p.landmark] for p in landmark_priors for _ in range(2)],
            dtype=np.int64,
        )
        self.lprior_coord = np.tile(np.arange(2), len(landmark_priors)).astype(np.int64)
        lprior_b = [b for p in landmark_priors for b in (p.x, p.y)]
        closures = [r for e, r in enumerate(motions) if e not in used and isinstance(r, Odometry)]
        loops = [r for e, r in enumerate(motions) if e not in used and isinstance(r, RelativePose)]
        self.loop_source = np.array([self._pose_index[r.source] for r in loops], dtype=np.int64)
        self.loop_target = np.array([self._pose_index[r.target] for r in loops], dtype=np.int64)
        self.closure_source = np.array(
            [self._pose_index[r.source] for r in closures], dtype=np.int64
        )
        self.closure_target = np.array(
            [self._pose_index[r.target] for r in closures], dtype=np.int64
        )
        closure_turn = [r.turn for r in closures]
        closure_distance = [length_bounds(r.distance) for r in closures]
        self.equality_rows = np.flatnonzero(self.closure_source != self.closure_target)

        parts = [
            (obs_range_a[self.range_sel], False, "range"),
            (obs_bearing_a[self.bearing_sel], True, "bearing"),
            (np.array(prior_b, dtype=float).reshape(-1, 2), None, "pose prior"),
            (np.array(lprior_b, dtype=float).reshape(-1, 2), False, "landmark prior"),
            (np.array(closure_turn, dtype=float).reshape(-1, 2), True, "closure turn"),
            (np.array(closure_distance, dtype=float).reshape(-1, 2), False, "closure distance"),
        ]
        for c, ang in (("dx", False), ("dy", False), ("dtheta", True)):
            b = np.array([getattr(r, c) for r in loops], dtype=float).reshape(-1, 2)
            parts.append((b, ang, f"relative {c}"))
        bounds = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2))
        angular = []
        labels: list[str] = []
        for b, ang, label in parts:
            if ang is None:
                angular.extend([c == 2 for c in self.prior_coord])
            else:
                angular.extend([ang] * len(b))
            labels.extend([f"{label} {q}" for q in range(len(b))])
        self.check_lo = bounds[:, 0] + 0.0
        self.check_hi = bounds[:, 1] + 0.0
        self.check_angular = np.array(angular, dtype=bool)
        self.check_labels = labels
        self.check_margin = aim_margin(self.check_lo, self.check_hi)
        self.check_mid = midpoint(self.check_lo, self.check_hi, 0.0)
        if np.any(self.check_lo > self.check_hi):
            self.problems.append("a measured interval is empty")

        # ---- negative information
        self.sensor = log.sensor if use_sensor else None
        if self.sensor is not None and self.sensor_frames:  # the reader refuses these logs
            self.problems.append("observation offsets with a sensor record")
        self.class_priors = log.class_priors
        self.observed = np.zeros((n, m), dtype=bool)
        self.observed[self.obs_robot, self.obs_landmark] = True
        self._sensor_rows = np.arange(n * m)
        """The (pose, landmark) pairs, flattened, whose sensor violation the optimisers see."""
        self._rows = np.arange(len(obs_pose))
        self.sensor_scales = (
            _typical_half_width(
                self.check_lo[: len(self.range_sel)], self.check_hi[: len(self.range_sel)]
            ),
            _typical_half_width(
                obs_bearing_a[self.bearing_sel, 0], obs_bearing_a[self.bearing_sel, 1]
            ),
        )
        """Sensor violations (m, rad) are measured in these lengths and angles for the
        optimisers: the median half-widths of the ranges and bearings (1 without any)."""
        self._memo: tuple[bytes, np.ndarray, np.ndarray | None] | None = None

    # ------------------------------------------------------------------ sizes
    @property
    def n_poses(self) -> int:
        return len(self.pose_ids)

    @property
    def n_landmarks(self) -> int:
        return len(self.landmark_ids)

    @property
    def n_checks(self) -> int:
        return len(self.check_lo)

    @property
    def free(self) -> np.ndarray:
        """Parameters with room to move: wider than ``FIXED_WIDTH`` times their magnitude
        (at least 1). The others, a degenerate interval or one a few ulps wide (the Lost in
        the Woods laser mount, written with outward rounding), stay where the start puts
        them, inside their interval: fewer columns for the optimisers, and nothing lost."""
        lo, hi = self.param_lo, self.param_hi
        with np.errstate(over="ignore", invalid="ignore"):
            scale = np.maximum(1.0, np.maximum(np.abs(lo), np.abs(hi)))
            wide = (hi - lo) > FIXED_WIDTH * scale
        return np.where(np.isfinite(scale), wide, lo < hi)  # unbounded: free

    def pose_index(self, pose_id: int) -> int:
        return self._pose_index[pose_id]

    def landmark_index(self, landmark_id: str) -> int:
        return self._landmark_index[landmark_id]

    # ------------------------------------------------------------------ floats
    def frames(self, p: np.ndarray, jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Forward kinematics: frames (n_frames, 3), robot poses then sensor poses, and,
        optionally, their Jacobian (n_frames, 3, n_params).

        The last result is memoised (callers must not modify the arrays).
        """
        key = np.asarray(p, dtype=float).tobytes()
        memo = self._memo
        if memo is not None and memo[0] == key and (memo[2] is not None or not jacobian):
            return memo[1], (memo[2] if jacobian else None)
        with np.errstate(all="ignore"):  # overflow is clipped (see _numeric.finite)
            P, J = kinematics(self.n_frames, self.n_params, self.anchors, self.steps, p, jacobian)
        self._memo = (key, P, J)
        return P, J

    def release(self) -> None:
        """Forget the memoised kinematics: a dense Jacobian, about 12 MB at 200 poses,
        which :func:`~.certification.certify` would otherwise keep for every hypothesis."""
        self._memo = None

    def poses(self, p: np.ndarray, jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Forward kinematics: the robot poses (n, 3) and, optionally, their Jacobian
        (n, 3, n_params) (views of :meth:`frames`: callers must not modify them)."""
        P, J = self.frames(p, jacobian)
        n = self.n_poses
        return P[:n], (None if J is None else J[:n])

    def landmarks(self, p: np.ndarray) -> np.ndarray:
        """Landmark positions (m, 2)."""
        return np.asarray(p[self.landmark_param0 :], dtype=float).reshape(-1, 2)

    def _landmark_columns(self, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        cx = self.landmark_param0 + 2 * j
        return cx, cx + 1

    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
    def evaluate(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Every check's implied value (angles as the representative nearest the interval's
        centre) and, optionally, the Jacobian (n_checks, n_params)."""
        P, JP = self.frames(p, jacobian)
        L = self.landmarks(p)
        values: list[np.ndarray] = []
        jacs: list[np.ndarray] = []
        i, j = self.obs_pose, self.obs_landmark
        dx = L[j, 0] - P[i, 0]
        dy = L[j, 1] - P[i, 1]
        r, r_safe, r2 = _distance(dx, dy)
        values.append(r[self.range_sel])
        values.append((np.arctan2(dy, dx) - P[i, 2])[self.bearing_sel])
        values.append(P[self.prior_pose, self.prior_coord])
        values.append(L[self.lprior_landmark, self.lprior_coord])
        s_, t_ = self.closure_source, self.closure_target
        ddx = P[t_, 0] - P[s_, 0]
        ddy = P[t_, 1] - P[s_, 1]
        ct, st = np.cos(P[t_, 2]), np.sin(P[t_, 2])
        values.append(P[t_, 2] - P[s_, 2])
        values.append(ddx * ct + ddy * st)
        R, JR = relative_values(P, JP, self.loop_source, self.loop_target)
        values += [R[:, 0], R[:, 1], R[:, 2]]
        v = np.concatenate(values)
        ang = self.check_angular
        v[ang] = wrap_near(v[ang], self.check_mid[ang])
        if not jacobian:
            return v, None
        assert JP is not None
        cx, cy = self._landmark_columns(j)
        rows = self._rows
        Jr = -(dx / r_safe)[:, None] * JP[i, 0] - (dy / r_safe)[:, None] * JP[i, 1]
        Jr[rows, cx] += dx / r_safe
        Jr[rows, cy] += dy / r_safe
        Jb = (dy / r2)[:, None] * JP[i, 0] - (dx / r2)[:, None] * JP[i, 1] - JP[i, 2]
        Jb[rows, cx] -= dy / r2
        Jb[rows, cy] += dx / r2
        jacs.append(Jr[self.range_sel])
        jacs.append(Jb[self.bearing_sel])
        jacs.append(JP[self.prior_pose, self.prior_coord])
        Jl = np.zeros((len(self.lprior_landmark), self.n_params))
        Jl[
            np.arange(len(Jl)), self.landmark_param0 + 2 * self.lprior_landmark + self.lprior_coord
        ] = 1
        jacs.append(Jl)
        jacs.append(JP[t_, 2] - JP[s_, 2])
        jdx = JP[t_, 0] - JP[s_, 0]
        jdy = JP[t_, 1] - JP[s_, 1]
        jacs.append(
            ct[:, None] * jdx + st[:, None] * jdy + (-ddx * st + ddy * ct)[:, None] * JP[t_, 2]
        )
        assert JR is not None
        jacs += [JR[:, 0], JR[:, 1], JR[:, 2]]
        return v, finite(np.concatenate(jacs).reshape(-1, self.n_params), nan=0.0)

    def point(self, p: np.ndarray, residual: float = 0.0) -> WitnessPoint:
        """The :class:`WitnessPoint` of a parameter vector."""
        P, _ = self.poses(p)
        return WitnessPoint(
            params=np.array(p, dtype=float),
            pose_ids=list(self.pose_ids),
            poses_xyt=P.copy(),
            landmark_ids=list(self.landmark_ids),
            landmarks_xy=self.landmarks(p).copy(),
            residual=residual,
        )
