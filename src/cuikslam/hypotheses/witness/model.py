"""The forward-kinematics parametrisation of one hypothesis, and its checks in floating point.

A candidate world is given by a parameter vector (:class:`HypothesisModel`):

* the pose of an *anchor* ``(x, y, theta)``: the first prior pose (bounded by its prior
  box); poses that no odometry chain connects to a prior pose get their own, unbounded
  anchor;
* a ``(turn, distance)`` per *tree* odometry record, bounded by its measured intervals
  (distance clipped at 0, as the kinematic graph does): odometry records are taken in
  log order, and each one that links a placed pose to an unplaced one places the latter by
  forward kinematics (or backward kinematics when only its target is placed);
* ``(x, y)`` per landmark, free.

Everything else becomes a *check*: the range and bearing of each observation, every prior
(pose priors, including the anchors' own, and landmark priors), and each *loop-closing*
odometry record (into an already placed pose): its turn and distance intervals, and the
*equality* ``cross(p_t - p_s, (cos theta_t, sin theta_t)) = 0`` (the heading of the target
equals the direction of travel).

When the log declares a :class:`~cuikslam.log.records.SensorModel`, its negative
information is a check too: at every pose the observed landmarks must be exactly those the
sensor is sure to see. A landmark is *visible* from a pose when it is within
``max_range`` and its bearing within ``fov / 2`` of the heading; when ``nearest_margin``
is set, the robot sees only the visible landmarks within ``nearest_margin`` of the nearest
visible one. Observed landmarks must be seen, unobserved ones must not.

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

from cuikslam.graph.variables import length_bounds
from cuikslam.hypotheses.witness._numeric import (
    cos_sin,
    finite,
    half_width,
    midpoint,
    wrap_near,
)
from cuikslam.hypotheses.witness._residuals import Residuals
from cuikslam.hypotheses.witness._sensor import SENSOR_MARGIN as SENSOR_MARGIN
from cuikslam.hypotheses.witness._sensor import distance as _distance
from cuikslam.hypotheses.witness._starts import LandmarkBoxes as LandmarkBoxes
from cuikslam.hypotheses.witness._starts import PoseBoxes as PoseBoxes
from cuikslam.hypotheses.witness._starts import Starts
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)

AIM_FRACTION = 0.1
"""The optimiser aims this fraction of each interval's half-width inside it."""
MIN_MARGIN = 1e-9
"""...but at least this much (unless the interval is narrower)."""


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


@dataclass
class _Step:
    parent: int
    child: int
    turn: int
    distance: int
    forward: bool


class HypothesisModel(Starts, Residuals):
    """The parametrisation of a hypothesis and its checks (see the module docstring).

    Poses and landmarks are numbered in the order the kinematic graph uses (first
    appearance in the log), so that arrays of a :class:`~cuikslam.results.Hypothesis` of a
    known-correspondence solve line up; mappings by id are accepted everywhere too.
    ``problems`` lists structural contradictions (a landmark of two classes, one landmark
    twice in a scan), and records the model cannot express (``relative_pose``): a
    hypothesis with problems never gets a witness.
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

        first_prior: dict[int, PosePrior] = {}
        pose_priors: list[PosePrior] = []
        landmark_priors: list[LandmarkPrior] = []
        odometry: list[Odometry] = []
        obs_pose: list[int] = []
        obs_landmark: list[int] = []
        obs_range: list[tuple[float, float]] = []
        obs_bearing: list[tuple[float, float]] = []
        scans: dict[int, set[int]] = {}
        k = 0
        for record in log.records:
            if isinstance(record, PosePrior):
                add_pose(record.pose)
                first_prior.setdefault(record.pose, record)
                pose_priors.append(record)
            elif isinstance(record, Odometry):
                add_pose(record.source)
                add_pose(record.target)
                odometry.append(record)
            elif isinstance(record, RelativePose):
                # not parametrised yet: no witness, so never a wrong "proven"
                if not any(p.startswith("relative_pose") for p in self.problems):
                    self.problems.append("relative_pose records are not modelled by the witness")
            elif isinstance(record, LandmarkPrior):
                add_landmark(record.landmark, record.landmark_class)
                landmark_priors.append(record)
            elif isinstance(record, Observation):
                if record.offset is not None and "observation offsets" not in self.problems:
                    self.problems.append("observation offsets")  # not modelled: no witness
                i = add_pose(record.pose)
                j = add_landmark(str(assignment[k]), record.landmark_class)
                k += 1
                if j in scans.setdefault(i, set()):
                    self.problems.append(
                        f"landmark {assignment[k - 1]} observed twice from pose {record.pose}"
                    )
                scans[i].add(j)
                obs_pose.append(i)
                obs_landmark.append(j)
                obs_range.append(_pair(record.range))
                obs_bearing.append(_pair(record.bearing))
        n = len(self.pose_ids)
        m = len(self.landmark_ids)

        # ---- parameters: anchors, tree odometry, landmarks
        lo: list[float] = []
        hi: list[float] = []
        names: list[str] = []

        def new_param(name: str, bounds: tuple[float, float]) -> int:
            lo.append(float(bounds[0]))
            hi.append(float(bounds[1]))
            names.append(name)
            return len(lo) - 1

        placed = [False] * n
        self.anchors: list[tuple[int, int]] = []
        self.steps: list[_Step] = []
        used: set[int] = set()
        candidates = [self._pose_index[p.pose] for p in pose_priors] + list(range(n))
        for a in candidates:
            if placed[a]:
                continue
            prior = first_prior.get(self.pose_ids[a])
            box = (
                [prior.x, prior.y, prior.theta]
                if prior is not None
                else [(-math.inf, math.inf)] * 3
            )
            first = len(lo)
            for c, b in zip("xyt", box, strict=True):
                new_param(f"pose {self.pose_ids[a]} {c}", b)
            self.anchors.append((a, first))
            placed[a] = True
            changed = True
            while changed:
                changed = False
                for e, r in enumerate(odometry):
                    if e in used:
                        continue
                    s, t = self._pose_index[r.source], self._pose_index[r.target]
                    if placed[s] == placed[t]:
                        continue
                    turn = new_param(f"turn {r.source}->{r.target}", r.turn)
                    dist = new_param(
                        f"distance {r.source}->{r.target}",
                        length_bounds(r.distance),
                    )
                    if placed[s]:
                        self.steps.append(_Step(s, t, turn, dist, True))
                        placed[t] = True
                    else:
                        self.steps.append(_Step(t, s, turn, dist, False))
                        placed[s] = True
                    used.add(e)
                    changed = True
        self.landmark_param0 = len(lo)
        for lid in self.landmark_ids:
            new_param(f"landmark {lid} x", (-math.inf, math.inf))
            new_param(f"landmark {lid} y", (-math.inf, math.inf))
        self.param_lo = np.array(lo) + 0.0  # -0.0 -> 0.0
        self.param_hi = np.array(hi) + 0.0
        self.param_names = names
        self.n_params = len(lo)
        if np.any(self.param_lo > self.param_hi):
            self.problems.append("an odometry or prior interval is empty")

        # ---- checks
        self.obs_pose = np.array(obs_pose, dtype=np.int64)
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
        closures = [r for e, r in enumerate(odometry) if e not in used]
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
        self.class_priors = log.class_priors
        self.observed = np.zeros((n, m), dtype=bool)
        self.observed[self.obs_pose, self.obs_landmark] = True
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
        """Parameters with room to move (not fixed by a degenerate interval)."""
        return self.param_lo < self.param_hi

    def pose_index(self, pose_id: int) -> int:
        return self._pose_index[pose_id]

    def landmark_index(self, landmark_id: str) -> int:
        return self._landmark_index[landmark_id]

    # ------------------------------------------------------------------ floats
    def poses(self, p: np.ndarray, jacobian: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
        """Forward kinematics: poses (n, 3) and, optionally, their Jacobian (n, 3, n_params).

        The last result is memoised (callers must not modify the arrays).
        """
        key = np.asarray(p, dtype=float).tobytes()
        memo = self._memo
        if memo is not None and memo[0] == key and (memo[2] is not None or not jacobian):
            return memo[1], (memo[2] if jacobian else None)
        P, J = self._kinematics(p, jacobian)
        self._memo = (key, P, J)
        return P, J

    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
    def _kinematics(self, p: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        n = self.n_poses
        P = np.empty((n, 3))
        J = np.zeros((n, 3, self.n_params)) if jacobian else None
        for a, k in self.anchors:
            P[a] = p[k : k + 3]
            if J is not None:
                J[a, 0, k] = J[a, 1, k + 1] = J[a, 2, k + 2] = 1.0
        for st in self.steps:
            x, y, t = P[st.parent]
            d = p[st.distance]
            if st.forward:
                th = t + p[st.turn]
                c, s = cos_sin(th)
                P[st.child] = (x + d * c, y + d * s, th)
                if J is not None:
                    jt = J[st.parent, 2].copy()
                    jt[st.turn] += 1.0
                    J[st.child, 2] = jt
                    J[st.child, 0] = J[st.parent, 0] - d * s * jt
                    J[st.child, 1] = J[st.parent, 1] + d * c * jt
                    J[st.child, 0, st.distance] += c
                    J[st.child, 1, st.distance] += s
            else:
                c, s = cos_sin(t)
                P[st.child] = (x - d * c, y - d * s, t - p[st.turn])
                if J is not None:
                    jt = J[st.parent, 2]
                    J[st.child, 2] = jt
                    J[st.child, 2, st.turn] -= 1.0
                    J[st.child, 0] = J[st.parent, 0] + d * s * jt
                    J[st.child, 1] = J[st.parent, 1] - d * c * jt
                    J[st.child, 0, st.distance] -= c
                    J[st.child, 1, st.distance] -= s
        return P, J

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
        P, JP = self.poses(p, jacobian)
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
