"""Certified consistency of a hypothesis: a witness point found numerically, verified rigorously.

Narrowing can prove a hypothesis *impossible* (its boxes contract to empty) but never that
it is *possible*. This module does the latter: it looks for one world (poses and landmarks)
that satisfies every measured interval of the log under the hypothesis' assignment, with a
local optimiser, and then verifies that point with the interval kernel
(:mod:`cuikslam.interval`), so that a ``True`` answer is a proof.

Parametrisation
---------------
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

Verification
------------
:func:`verify_witness` recomputes the poses with interval arithmetic from the parameter
point (degenerate intervals ``[v, v]``, every operation rounded outward) and checks that
every implied quantity lies *inside* its measured interval: plain inclusion for lengths and
coordinates, inclusion modulo 2 pi for angles (the shift ``2 pi k`` is itself an enclosure).
Bearings come from :func:`cuikslam.interval.angle_of` over a window wider than 2 pi, which
encloses every representative of the true angle in the window, hence at least one.

Loop-closing odometry is an equality, which a single point cannot satisfy exactly in
floating point. It is verified with the Poincaré–Miranda theorem: one parameter per
closure (its *pivot*) is widened to a small interval; if every inequality check holds over
the whole parameter box and each closure's equality function has opposite strict signs on
the two faces of its pivot, the box contains a point where every equality holds exactly,
and that point satisfies every check. The returned witness is then the centre of that box
(within ``1e-3`` of an exact solution, in the parameters). An odometry from a pose to
itself needs no equality (it says turn ≡ 0 and distance = 0, both checked). Closures whose
equality vanishes identically otherwise (a duplicated odometry record) or whose
equalities are not independent cannot be verified this way: verification then fails,
which only leaves the hypothesis ``NOT_REFUTED``.

:func:`certify` runs both on every hypothesis of a :class:`~cuikslam.results.Solution`.
:func:`inner_hull` uses the same machinery to measure the exact solution set from inside
(every point it keeps is verified), to judge how tight the narrowed boxes are.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares, minimize

from cuikslam import interval as ia
from cuikslam.interval._rounding import TWO_PI_HI, TWO_PI_LO
from cuikslam.log.records import LandmarkPrior, Log, Observation, Odometry, PosePrior
from cuikslam.results.solution import NOT_REFUTED, PROVEN, Solution

__all__ = [
    "AIM_FRACTION",
    "MIN_MARGIN",
    "HypothesisModel",
    "InnerHull",
    "WitnessPoint",
    "certify",
    "find_witness",
    "inner_hull",
    "verify_witness",
]

AIM_FRACTION = 0.1
"""The optimiser aims this fraction of each interval's half-width inside it."""
MIN_MARGIN = 1e-9
"""...but at least this much (unless the interval is narrower)."""
SENSOR_MARGIN = 1e-6
"""Aimed clearance (m, rad) from the sensor's visibility thresholds."""
_WINDOW = 3.5
"""Half-width of the angle window given to ``angle_of``: more than pi, so the window holds
at least one representative of every angle."""
_PIVOT_STEPS = (1e-9, 1e-7, 1e-5, 1e-3)
"""Half-widths tried for the pivots of the Poincaré–Miranda box."""
_TWO_PI = ia.interval(TWO_PI_LO, TWO_PI_HI)
_HOPELESS = 0.5
"""A hinge residual (in half-widths) beyond which aiming closer to the bounds is not tried."""

PoseBoxes = Mapping[int, np.ndarray] | np.ndarray | None
LandmarkBoxes = Mapping[str, np.ndarray] | np.ndarray | None


# --------------------------------------------------------------------------- helpers
def _aim_margin(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How far inside ``[lo, hi]`` the optimiser aims: 10 % of the half-width, >= 1e-9."""
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    with np.errstate(invalid="ignore"):
        half = (hi - lo) / 2.0
        margin = np.minimum(np.maximum(AIM_FRACTION * half, MIN_MARGIN), 0.5 * half)
    return np.where(np.isfinite(half), np.maximum(margin, 0.0), MIN_MARGIN)


def _wrap_near(value: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The representative of ``value`` (mod 2 pi) nearest ``centre``."""
    return centre + np.remainder(value - centre + np.pi, 2 * np.pi) - np.pi


def _inside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """True where the interval ``x`` lies inside ``[lo, hi]`` (False for NaN or empty)."""
    return (x[..., 0] >= lo) & (x[..., 1] <= hi) & (x[..., 0] <= x[..., 1])


def _inside_mod(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """True where the angle interval ``x`` lies inside ``[lo, hi] + 2 pi k`` for one integer k.

    The shift ``2 pi k`` is an outward-rounded enclosure, so a True is rigorous.
    """
    x = np.asarray(x, dtype=float)
    lo = np.broadcast_to(np.asarray(lo, dtype=float), x.shape[:-1])
    hi = np.broadcast_to(np.asarray(hi, dtype=float), x.shape[:-1])
    width = ia.sub(ia.interval(hi), ia.interval(lo))[..., 0]
    any_angle = width >= TWO_PI_HI
    with np.errstate(invalid="ignore", over="ignore"):
        k = np.round(((lo + hi) / 2.0 - (x[..., 0] + x[..., 1]) / 2.0) / (2 * math.pi))
    k = np.where(np.isfinite(k), k, 0.0)
    ok = np.zeros(x.shape[:-1], dtype=bool)
    for step in (0.0, -1.0, 1.0):
        shifted = ia.add(x, ia.mul(ia.interval(k + step), _TWO_PI))
        ok |= _inside(shifted, lo, hi)
    return (ok | any_angle) & (x[..., 0] <= x[..., 1])


def _pair(bounds: tuple[float, float] | None) -> tuple[float, float]:
    if bounds is None:
        return (math.nan, math.nan)
    return (float(bounds[0]), float(bounds[1]))


# --------------------------------------------------------------------------- results
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
class InnerHull:
    """Hull of verified solution points: an inner approximation of the exact hull.

    ``poses`` has shape (n, 3, 2) and ``landmarks`` (m, 2, 2), last axis (min, max) found.
    """

    pose_ids: list[int]
    poses: np.ndarray
    landmark_ids: list[str]
    landmarks: np.ndarray
    verified_points: int
    optimisations: int
    seconds: float
    witness: WitnessPoint | None = None
    statistics: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {
            "pose_ids": list(self.pose_ids),
            "poses": self.poses.tolist(),
            "landmark_ids": list(self.landmark_ids),
            "landmarks": self.landmarks.tolist(),
            "verified_points": self.verified_points,
            "optimisations": self.optimisations,
            "seconds": self.seconds,
        }


@dataclass
class _Step:
    parent: int
    child: int
    turn: int
    distance: int
    forward: bool


# --------------------------------------------------------------------------- the model
class HypothesisModel:
    """The parametrisation of a hypothesis and its checks (see the module docstring).

    Poses and landmarks are numbered in the order the kinematic graph uses (first
    appearance in the log), so that arrays of a :class:`~cuikslam.results.Hypothesis` of a
    known-correspondence solve line up; mappings by id are accepted everywhere too.
    ``problems`` lists structural contradictions (a landmark of two classes, one landmark
    twice in a scan): a hypothesis with problems is never consistent.
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
            elif isinstance(record, LandmarkPrior):
                add_landmark(record.landmark, record.landmark_class)
                landmark_priors.append(record)
            elif isinstance(record, Observation):
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
                        (max(0.0, r.distance[0]), r.distance[1]),
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
        self.param_lo = np.array(lo)
        self.param_hi = np.array(hi)
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
        closure_distance = [(max(0.0, r.distance[0]), r.distance[1]) for r in closures]
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
        self.check_lo = bounds[:, 0].copy()
        self.check_hi = bounds[:, 1].copy()
        self.check_angular = np.array(angular, dtype=bool)
        self.check_labels = labels
        self.check_margin = _aim_margin(self.check_lo, self.check_hi)
        self.check_mid = np.where(
            np.isfinite(self.check_lo + self.check_hi), (self.check_lo + self.check_hi) / 2, 0.0
        )
        if np.any(self.check_lo > self.check_hi):
            self.problems.append("a measured interval is empty")

        # ---- negative information
        self.sensor = log.sensor if use_sensor else None
        self.observed = np.zeros((n, m), dtype=bool)
        self.observed[self.obs_pose, self.obs_landmark] = True
        self._rows = np.arange(len(obs_pose))
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
                c, s = math.cos(th), math.sin(th)
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
                c, s = math.cos(t), math.sin(t)
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
        r2 = np.maximum(dx * dx + dy * dy, 1e-300)
        r = np.sqrt(r2)
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
        v[ang] = _wrap_near(v[ang], self.check_mid[ang])
        if not jacobian:
            return v, None
        assert JP is not None
        cx, cy = self._landmark_columns(j)
        rows = self._rows
        Jr = -(dx / r)[:, None] * JP[i, 0] - (dy / r)[:, None] * JP[i, 1]
        Jr[rows, cx] += dx / r
        Jr[rows, cy] += dy / r
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
        return v, np.concatenate(jacs).reshape(-1, self.n_params)

    def equalities(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The loop-closure equalities ``cross(p_t - p_s, u(theta_t))`` (0 when satisfied)."""
        P, JP = self.poses(p, jacobian)
        s_ = self.closure_source[self.equality_rows]
        t_ = self.closure_target[self.equality_rows]
        ddx = P[t_, 0] - P[s_, 0]
        ddy = P[t_, 1] - P[s_, 1]
        ct, st = np.cos(P[t_, 2]), np.sin(P[t_, 2])
        f = ddx * st - ddy * ct
        if not jacobian:
            return f, None
        assert JP is not None
        jdx = JP[t_, 0] - JP[s_, 0]
        jdy = JP[t_, 1] - JP[s_, 1]
        J = st[:, None] * jdx - ct[:, None] * jdy + (ddx * ct + ddy * st)[:, None] * JP[t_, 2]
        return f, J.reshape(-1, self.n_params)

    def sensor_residuals(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """One violation per (pose, landmark) pair of the sensor model (0 when satisfied,
        with SENSOR_MARGIN clearance); empty without a sensor record."""
        n, m = self.n_poses, self.n_landmarks
        if self.sensor is None or n == 0 or m == 0:
            return np.zeros(0), (np.zeros((0, self.n_params)) if jacobian else None)
        sensor = self.sensor
        P, JP = self.poses(p, jacobian)
        L = self.landmarks(p)
        dx = L[None, :, 0] - P[:, None, 0]
        dy = L[None, :, 1] - P[:, None, 1]
        r2 = np.maximum(dx * dx + dy * dy, 1e-300)
        d = np.sqrt(r2)
        beta = np.remainder(np.arctan2(dy, dx) - P[:, None, 2] + np.pi, 2 * np.pi) - np.pi
        delta = SENSOR_MARGIN
        inf = np.full((n, m), np.inf)
        all_round = sensor.fov >= 2 * math.pi
        half = sensor.fov / 2.0
        # violations (> 0: violated) of "in view" and "out of view" clauses, with their kinds
        in_range = d - (sensor.max_range - delta)
        out_range = (sensor.max_range + delta) - d if math.isfinite(sensor.max_range) else inf
        in_fov = -inf if all_round else np.abs(beta) - (half - delta)
        out_fov = inf if all_round else (half + delta) - np.abs(beta)
        visible = (d <= sensor.max_range) & (all_round | (np.abs(beta) <= half))
        if sensor.nearest_margin is not None:
            dv = np.where(visible, d, np.inf)
            nearest_j = np.argmin(dv, axis=1)
            nearest = dv[np.arange(n), nearest_j]
            limit = nearest[:, None] + sensor.nearest_margin
            in_near = np.where(np.isfinite(limit), d - (limit - delta), -np.inf)
            out_near = np.where(np.isfinite(limit), (limit + delta) - d, np.inf)
        else:
            nearest_j = np.zeros(n, dtype=np.int64)
            in_near = -inf
            out_near = inf
        obs = self.observed
        pos = lambda a: np.maximum(a, 0.0)  # noqa: E731
        seen_res = pos(in_range) + pos(in_fov) + pos(in_near)
        unseen_stack = np.stack([out_range, out_fov, out_near])
        unseen_kind = np.argmin(unseen_stack, axis=0)
        unseen_res = pos(np.min(unseen_stack, axis=0))
        res = np.where(obs, seen_res, unseen_res)
        res = np.where(np.isfinite(res), res, 0.0)
        if not jacobian:
            return res.ravel(), None
        assert JP is not None
        # derivatives of d and |beta| for every pair
        Jd = -(dx / d)[..., None] * JP[:, None, 0] - (dy / d)[..., None] * JP[:, None, 1]
        Jb = (dy / r2)[..., None] * JP[:, None, 0] - (dx / r2)[..., None] * JP[:, None, 1]
        Jb = Jb - JP[:, None, 2]
        jj = np.arange(m)
        cx, cy = self._landmark_columns(jj)
        Jd[:, jj, cx] += dx / d
        Jd[:, jj, cy] += dy / d
        Jb[:, jj, cx] -= dy / r2
        Jb[:, jj, cy] += dx / r2
        Jab = np.sign(beta)[..., None] * Jb
        Jnear = Jd - Jd[np.arange(n), nearest_j][:, None, :]
        Jseen = (
            (in_range > 0)[..., None] * Jd
            + (in_fov > 0)[..., None] * Jab
            + (in_near > 0)[..., None] * Jnear
        )
        Junseen = np.where((unseen_kind == 0)[..., None], -Jd, 0.0)
        Junseen = Junseen + np.where((unseen_kind == 1)[..., None], -Jab, 0.0)
        Junseen = Junseen + np.where((unseen_kind == 2)[..., None], -Jnear, 0.0)
        Junseen = Junseen * (unseen_res > 0)[..., None]
        J = np.where(obs[..., None], Jseen, Junseen)
        return res.ravel(), J.reshape(n * m, self.n_params)

    # ------------------------------------------------------------------ starts
    def params_from_world(
        self,
        poses_xyt: Mapping[int, np.ndarray] | np.ndarray,
        landmarks_xy: Mapping[str, np.ndarray] | np.ndarray,
        clip: bool = True,
    ) -> np.ndarray:
        """Parameters that reproduce a world as nearly as they can (turns and headings mod
        2 pi near their intervals; with ``clip`` each parameter is clipped to its bounds).

        The world need not be consistent: pose values drive the tree's parameters one step
        at a time, so a box centre gives a sensible starting point.
        """
        P = self._pose_array(poses_xyt)
        L = self._landmark_array(landmarks_xy)
        p = np.zeros(self.n_params)
        for a, k in self.anchors:
            p[k : k + 3] = P[a]
        for st in self.steps:
            parent, child = P[st.parent], P[st.child]
            if st.forward:
                turn = child[2] - parent[2]
                u = (math.cos(child[2]), math.sin(child[2]))
                delta = child[:2] - parent[:2]
            else:
                turn = parent[2] - child[2]
                u = (math.cos(parent[2]), math.sin(parent[2]))
                delta = parent[:2] - child[:2]
            centre = (self.param_lo[st.turn] + self.param_hi[st.turn]) / 2
            p[st.turn] = float(_wrap_near(np.array(turn), np.array(centre)))
            p[st.distance] = float(delta[0] * u[0] + delta[1] * u[1])
        p[self.landmark_param0 :] = L.ravel()
        p = np.where(np.isfinite(p), p, 0.0)
        if clip:
            p = np.clip(p, self.param_lo, self.param_hi)
        return p

    def _pose_array(self, poses: Mapping[int, np.ndarray] | np.ndarray) -> np.ndarray:
        if isinstance(poses, Mapping):
            out = np.full((self.n_poses, 3), np.nan)
            for pid, v in poses.items():
                if pid in self._pose_index:
                    out[self._pose_index[pid]] = np.asarray(v, dtype=float)[:3]
            return out
        return np.asarray(poses, dtype=float).reshape(self.n_poses, 3)

    def _landmark_array(self, landmarks: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
        if isinstance(landmarks, Mapping):
            out = np.full((self.n_landmarks, 2), np.nan)
            for lid, v in landmarks.items():
                if lid in self._landmark_index:
                    out[self._landmark_index[lid]] = np.asarray(v, dtype=float)[:2]
            return out
        return np.asarray(landmarks, dtype=float).reshape(self.n_landmarks, 2)

    def _box_centres(self, boxes: Any, n: int, k: int, index: dict) -> np.ndarray | None:
        if boxes is None:
            return None
        if isinstance(boxes, Mapping):
            out = np.full((n, k), np.nan)
            for key, box in boxes.items():
                if key in index:
                    b = np.asarray(box, dtype=float)
                    out[index[key]] = (b[:k, 0] + b[:k, 1]) / 2
        else:
            b = np.asarray(boxes, dtype=float).reshape(n, k, 2)
            out = (b[..., 0] + b[..., 1]) / 2
        return np.where(np.isfinite(out), out, np.nan)

    def initial_params(
        self,
        poses_box: PoseBoxes = None,
        landmarks_box: LandmarkBoxes = None,
        rng: np.random.Generator | None = None,
    ) -> np.ndarray:
        """A starting point: interval midpoints (or random points of the intervals when
        ``rng`` is given), refined by the boxes' centres where given; landmarks at their box
        or prior centre, else where their first observation's midpoint puts them."""
        finite = np.isfinite(self.param_lo) & np.isfinite(self.param_hi)
        lo = np.where(finite, self.param_lo, 0.0)
        hi = np.where(finite, self.param_hi, 0.0)
        p = (lo + hi) / 2 if rng is None else rng.uniform(lo, hi)
        pose_c = self._box_centres(poses_box, self.n_poses, 3, self._pose_index)
        if pose_c is not None and rng is None:
            q = self.params_from_world(
                np.where(np.isnan(pose_c), 0.0, pose_c), np.zeros((self.n_landmarks, 2)), clip=True
            )
            ok = self._params_known(pose_c)
            p = np.where(ok & np.isfinite(q), q, p)
        # anchors without a prior: the box centre or the origin
        land = self._box_centres(landmarks_box, self.n_landmarks, 2, self._landmark_index)
        P, _ = self.poses(p)
        L = np.full((self.n_landmarks, 2), np.nan)
        for lo_, hi_, j, c in zip(*self._landmark_prior_rows(), strict=True):
            if np.isnan(L[j, c]) and math.isfinite(lo_) and math.isfinite(hi_):
                L[j, c] = (lo_ + hi_) / 2
        if land is not None:
            L = np.where(np.isnan(land), L, land)
        for j in range(self.n_landmarks):
            if np.any(np.isnan(L[j])):
                L[j] = self._fit_landmark(j, P, rng)
        L = np.where(np.isnan(L), 0.0, L)
        p[self.landmark_param0 :] = L.ravel()
        return p

    def _fit_landmark(
        self, j: int, P: np.ndarray, rng: np.random.Generator | None = None
    ) -> np.ndarray:
        """Where the observations of landmark ``j`` put it, seen from the poses ``P``: the
        best of small least-squares fits started from each observation's midpoint
        projection (at a few guessed ranges when the range is unmeasured, a few guessed
        bearings when the bearing is)."""
        rows = []
        for q in np.flatnonzero(self.obs_landmark == j):
            i = int(self.obs_pose[q])
            rr, bb = self._obs_mid(q, "range"), self._obs_mid(q, "bearing")
            rows.append((i, rr, bb, self._obs_half(q, "range"), self._obs_half(q, "bearing")))
        if not rows:
            return np.zeros(2)
        starts = []
        for i, rr, bb, _, _ in rows:
            ranges = [rr] if rr is not None else [1.0, 3.0, 10.0]
            bearings = [bb] if bb is not None else [0.0, math.pi / 2, math.pi, -math.pi / 2]
            if rng is not None and bb is None:
                bearings = [b + rng.normal(0.0, 0.3) for b in bearings]
            for r in ranges:
                for b in bearings:
                    a = P[i, 2] + b
                    starts.append(P[i, :2] + r * np.array([math.cos(a), math.sin(a)]))
        if len(rows) == 1 and rows[0][1] is not None and rows[0][2] is not None:
            return starts[0]
        pose_i = np.array([r[0] for r in rows])
        rng_mid = np.array([np.nan if r[1] is None else r[1] for r in rows])
        brg_mid = np.array([np.nan if r[2] is None else r[2] for r in rows])
        rng_w = np.array([1.0 if r[3] is None else max(r[3], 1e-3) for r in rows])
        brg_w = np.array([1.0 if r[4] is None else max(r[4], 1e-3) for r in rows])
        has_r, has_b = ~np.isnan(rng_mid), ~np.isnan(brg_mid)

        def residuals(xy: np.ndarray) -> np.ndarray:
            dx = xy[0] - P[pose_i, 0]
            dy = xy[1] - P[pose_i, 1]
            dist = np.hypot(dx, dy)
            brg = np.arctan2(dy, dx) - P[pose_i, 2]
            res_r = (dist - rng_mid)[has_r] / rng_w[has_r]
            res_b = _wrap_near(brg, brg_mid)[has_b] - brg_mid[has_b]
            return np.concatenate([res_r, res_b / brg_w[has_b]])

        best, best_cost = starts[0], math.inf
        for xy in starts[:16]:
            try:
                fit = least_squares(residuals, xy, method="trf", max_nfev=50)
            except ValueError:
                continue
            if fit.cost < best_cost and np.all(np.isfinite(fit.x)):
                best, best_cost = fit.x, fit.cost
        return np.asarray(best, dtype=float)

    def _obs_half(self, q: int, kind: str) -> float | None:
        sel = self.range_sel if kind == "range" else self.bearing_sel
        pos = np.flatnonzero(sel == q)
        if len(pos) == 0:
            return None
        row = int(pos[0]) + (0 if kind == "range" else len(self.range_sel))
        return float((self.check_hi[row] - self.check_lo[row]) / 2)

    def _landmark_prior_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        start = len(self.range_sel) + len(self.bearing_sel) + len(self.prior_pose)
        stop = start + len(self.lprior_landmark)
        return (
            self.check_lo[start:stop],
            self.check_hi[start:stop],
            self.lprior_landmark,
            self.lprior_coord,
        )

    def _params_known(self, pose_c: np.ndarray) -> np.ndarray:
        """Which parameters ``params_from_world`` can take from (possibly NaN) pose centres."""
        ok = np.zeros(self.n_params, dtype=bool)
        known = ~np.any(np.isnan(pose_c), axis=1)
        for a, k in self.anchors:
            ok[k : k + 3] = known[a]
        for st in self.steps:
            both = known[st.parent] and known[st.child]
            ok[st.turn] = ok[st.distance] = both
        return ok

    def _obs_mid(self, q: int, kind: str) -> float | None:
        sel = self.range_sel if kind == "range" else self.bearing_sel
        pos = np.flatnonzero(sel == q)
        if len(pos) == 0:
            return None
        row = int(pos[0]) + (0 if kind == "range" else len(self.range_sel))
        return float((self.check_lo[row] + self.check_hi[row]) / 2)

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

    # ------------------------------------------------------------------ residuals
    def centre_residuals(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Smooth residuals: each check's value and each bounded parameter's distance from
        its interval's centre, in half-widths (the usual least-squares SLAM estimate), then
        the closure equalities. Their minimiser is a good start for the margins."""
        v, J = self.evaluate(p, jacobian)
        lo, hi = self.check_lo, self.check_hi
        finite = np.isfinite(lo) & np.isfinite(hi) & (hi > lo)
        half = np.where(finite, (hi - lo) / 2, 1.0)
        r_checks = np.where(finite, (v - self.check_mid) / half, 0.0)
        plo, phi = self.param_lo, self.param_hi
        pfinite = np.isfinite(plo) & np.isfinite(phi) & (phi > plo)
        with np.errstate(invalid="ignore"):
            phalf = np.where(pfinite, (phi - plo) / 2, 1.0)
            pmid = np.where(pfinite, (plo + phi) / 2, 0.0)
        r_params = np.where(pfinite, (p - pmid) / phalf, 0.0)
        f, Jf = self.equalities(p, jacobian)
        out = np.concatenate([r_checks, r_params, f])
        if not jacobian:
            return out, None
        assert J is not None and Jf is not None
        Jc = (finite / half)[:, None] * J
        Jp = np.diag(pfinite / phalf)
        return out, np.concatenate([Jc, Jp, Jf])

    def margin_residuals(
        self, p: np.ndarray, jacobian: bool = False, scale_margin: float = 1.0
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Hinge residuals: how far each check's value is from ``[lo + m, hi - m]`` (in
        half-widths), then the equalities, then the sensor violations."""
        v, J = self.evaluate(p, jacobian)
        lo, hi = self.check_lo, self.check_hi
        margin = self.check_margin * scale_margin
        half = np.where(np.isfinite(hi - lo) & (hi > lo), (hi - lo) / 2, 1.0)
        with np.errstate(invalid="ignore"):
            below = (lo + margin - v) / half
            above = (v - (hi - margin)) / half
        below = np.where(np.isfinite(lo), below, -np.inf)
        above = np.where(np.isfinite(hi), above, -np.inf)
        res = np.maximum(below, 0.0) + np.maximum(above, 0.0)
        f, Jf = self.equalities(p, jacobian)
        sr, Js = self.sensor_residuals(p, jacobian)
        out = np.concatenate([res, f, sr])
        if not jacobian:
            return out, None
        assert J is not None and Jf is not None and Js is not None
        sign = np.where(below > 0, -1.0, 0.0) + np.where(above > 0, 1.0, 0.0)
        Jr = (sign / half)[:, None] * J
        return out, np.concatenate([Jr, Jf, Js])


# --------------------------------------------------------------------------- verification
def _interval_world(model: HypothesisModel, box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Poses (n, 3, 2) and landmarks (m, 2, 2) enclosing the world of every parameter in the
    parameter box ``box`` (n_params, 2), by outward-rounded forward kinematics."""
    P = np.full((model.n_poses, 3, 2), np.nan)
    for a, k in model.anchors:
        P[a] = box[k : k + 3]
    for st in model.steps:
        parent = P[st.parent]
        d = box[st.distance]
        if st.forward:
            th = ia.add(parent[2], box[st.turn])
            c, s = ia.cos(th), ia.sin(th)
            P[st.child, 0] = ia.add(parent[0], ia.mul(d, c))
            P[st.child, 1] = ia.add(parent[1], ia.mul(d, s))
            P[st.child, 2] = th
        else:
            c, s = ia.cos(parent[2]), ia.sin(parent[2])
            P[st.child, 0] = ia.sub(parent[0], ia.mul(d, c))
            P[st.child, 1] = ia.sub(parent[1], ia.mul(d, s))
            P[st.child, 2] = ia.sub(parent[2], box[st.turn])
    L = box[model.landmark_param0 :].reshape(-1, 2, 2)
    return P, L


def _angle_enclosure(dy: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """An enclosure of one representative of the angle of the vector (dx, dy).

    ``angle_of`` encloses every representative inside a window; the window is centred on
    the floating-point angle of the boxes' midpoints and is 7 wide, more than 2 pi, so it
    holds at least one representative, and only one unless the boxes are wide.
    """
    centre = np.arctan2(_mid(dy), _mid(dx))
    centre = np.where(np.isfinite(centre), centre, 0.0)
    window = ia.interval(centre - _WINDOW, centre + _WINDOW)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return ia.angle_of(dy, dx, window)[2]


def _mid(x: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        return (x[..., 0] + x[..., 1]) / 2


def _checks_hold(model: HypothesisModel, box: np.ndarray) -> bool:
    """Every inequality check holds for every parameter in ``box`` (rigorous)."""
    if np.any(box[:, 0] < model.param_lo) or np.any(box[:, 1] > model.param_hi):
        return False
    if np.any(box[:, 0] > box[:, 1]):
        return False
    P, L = _interval_world(model, box)
    lo, hi = model.check_lo, model.check_hi
    pieces: list[np.ndarray] = []
    i, j = model.obs_pose, model.obs_landmark
    if len(i):
        dx = ia.sub(L[j, 0], P[i, 0])
        dy = ia.sub(L[j, 1], P[i, 1])
        rng = ia.sqrt(ia.add(ia.sqr(dx), ia.sqr(dy)))
        pieces.append(rng[model.range_sel])
        b = model.bearing_sel
        if len(b):
            phi = _angle_enclosure(dy[b], dx[b])
            pieces.append(ia.sub(phi, P[i[b], 2]))
    pieces.append(P[model.prior_pose, model.prior_coord].reshape(-1, 2))
    pieces.append(L[model.lprior_landmark, model.lprior_coord].reshape(-1, 2))
    s_, t_ = model.closure_source, model.closure_target
    if len(s_):
        same = (s_ == t_)[:, None]  # an odometry into its own pose: no turn, no move
        turn = np.where(same, 0.0, ia.sub(P[t_, 2], P[s_, 2]))
        ddx = np.where(same, 0.0, ia.sub(P[t_, 0], P[s_, 0]))
        ddy = np.where(same, 0.0, ia.sub(P[t_, 1], P[s_, 1]))
        dist = ia.add(ia.mul(ddx, ia.cos(P[t_, 2])), ia.mul(ddy, ia.sin(P[t_, 2])))
        pieces += [turn, dist]
    values = np.concatenate([q.reshape(-1, 2) for q in pieces]) if pieces else np.zeros((0, 2))
    if values.shape[0] != model.n_checks:
        raise AssertionError("check layout mismatch")
    ang = model.check_angular
    ok_plain = _inside(values[~ang], lo[~ang], hi[~ang])
    ok_ang = _inside_mod(values[ang], lo[ang], hi[ang])
    if not (np.all(ok_plain) and np.all(ok_ang)):
        return False
    return _sensor_holds(model, P, L)


def _sensor_holds(model: HypothesisModel, P: np.ndarray, L: np.ndarray) -> bool:
    """Negative information (rigorous): at every pose the observed landmarks are exactly the
    ones the sensor is sure to see."""
    sensor = model.sensor
    n, m = model.n_poses, model.n_landmarks
    if sensor is None or n == 0 or m == 0:
        return True
    dx = ia.sub(L[None, :, 0], P[:, None, 0])
    dy = ia.sub(L[None, :, 1], P[:, None, 1])
    dist = ia.sqrt(ia.add(ia.sqr(dx), ia.sqr(dy)))
    in_range = dist[..., 1] <= sensor.max_range
    out_range = dist[..., 0] > sensor.max_range
    if sensor.fov >= 2 * math.pi:
        in_view = np.ones((n, m), dtype=bool)
        out_view = np.zeros((n, m), dtype=bool)
    else:
        half = sensor.fov / 2.0
        theta = np.broadcast_to(P[:, None, 2], (n, m, 2))
        bearing = ia.sub(_angle_enclosure(dy, dx), theta)
        in_view = _inside_mod(bearing, -half, half)
        beyond = float(np.nextafter(half, math.inf))
        before = float(np.nextafter(ia.sub(_TWO_PI, ia.interval(half))[0], -math.inf))
        out_view = _inside_mod(bearing, beyond, before)
    visible = in_range & in_view
    hidden = out_range | out_view
    if not np.all(visible | hidden):
        return False
    observed = model.observed
    if sensor.nearest_margin is None:
        return bool(np.all(np.where(observed, visible, hidden)))
    margin = ia.interval(sensor.nearest_margin)
    for a in range(n):
        vis = visible[a]
        if not np.any(vis):
            if np.any(observed[a]):
                return False
            continue
        nearest = np.array([dist[a, vis, 0].min(), dist[a, vis, 1].min()])
        limit = ia.add(nearest, margin)
        seen = vis & (dist[a, :, 1] <= limit[0])
        unseen = hidden[a] | (dist[a, :, 0] > limit[1])
        if not np.all(np.where(observed[a], seen, unseen)):
            return False
    return True


def _equality_signs(model: HypothesisModel, box: np.ndarray) -> np.ndarray:
    """Enclosures (e, 2) of the closure equalities over a parameter box."""
    P, _ = _interval_world(model, box)
    s_ = model.closure_source[model.equality_rows]
    t_ = model.closure_target[model.equality_rows]
    ddx = ia.sub(P[t_, 0], P[s_, 0])
    ddy = ia.sub(P[t_, 1], P[s_, 1])
    return ia.sub(ia.mul(ddx, ia.sin(P[t_, 2])), ia.mul(ddy, ia.cos(P[t_, 2])))


def _pivots(model: HypothesisModel, p: np.ndarray) -> list[int] | None:
    """One distinct free parameter per closure equality, greedily the most sensitive."""
    _, J = model.equalities(p, jacobian=True)
    assert J is not None
    J = np.abs(J) * model.free[None, :]
    chosen: list[int] = []
    order = np.argsort(-J.max(axis=1)) if len(J) else []
    pivots = [0] * len(J)
    for c in order:
        row = J[c].copy()
        row[chosen] = 0.0
        k = int(np.argmax(row))
        if row[k] <= 0.0:
            return None
        chosen.append(k)
        pivots[c] = k
    return pivots


def _verified_box(model: HypothesisModel, p: np.ndarray) -> np.ndarray | None:
    """A parameter box around ``p`` proven to contain a solution, or None."""
    if model.problems:
        return None
    p = np.asarray(p, dtype=float)
    if p.shape != (model.n_params,) or not np.all(np.isfinite(p)):
        return None
    box = np.stack([p, p], axis=-1)
    if len(model.equality_rows) == 0:
        return box if _checks_hold(model, box) else None
    pivots = _pivots(model, p)
    if pivots is None:
        return None
    for step in _PIVOT_STEPS:
        wide = box.copy()
        for k in pivots:
            wide[k] = (p[k] - step, p[k] + step)
        if not _checks_hold(model, wide):
            continue
        ok = True
        for c, k in enumerate(pivots):
            low = wide.copy()
            low[k] = (wide[k, 0], wide[k, 0])
            high = wide.copy()
            high[k] = (wide[k, 1], wide[k, 1])
            f_low = _equality_signs(model, low)[c]
            f_high = _equality_signs(model, high)[c]
            if not ((f_low[1] < 0.0 < f_high[0]) or (f_high[1] < 0.0 < f_low[0])):
                ok = False
                break
        if ok:
            return wide
    return None


def verify_witness(
    log: Log, assignment: Sequence[str], point: WitnessPoint | np.ndarray, use_sensor: bool = True
) -> bool:
    """Whether ``point`` (or a parameter vector) is proven to satisfy every check.

    Rigorous: the decision rests on outward-rounded interval arithmetic only. With
    loop-closing odometry, a True means that a small box around the point contains an
    exact solution (Poincaré–Miranda; see the module docstring).
    """
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    params = point.params if isinstance(point, WitnessPoint) else point
    return _verified_box(model, np.asarray(params, dtype=float)) is not None


# --------------------------------------------------------------------------- search
def _polish_equalities(model: HypothesisModel, p: np.ndarray, iterations: int = 4) -> np.ndarray:
    """A few Gauss-Newton steps on the closure equalities (minimum-norm, free parameters)."""
    if len(model.equality_rows) == 0:
        return p
    free = model.free
    p = p.copy()
    for _ in range(iterations):
        f, J = model.equalities(p, jacobian=True)
        assert J is not None
        if np.max(np.abs(f)) < 1e-15:
            break
        step, *_ = np.linalg.lstsq(J[:, free], -f, rcond=None)
        p[free] += step
        p = np.clip(p, model.param_lo, model.param_hi)
    return p


def _solve_margins(
    model: HypothesisModel, x0: np.ndarray, max_nfev: int = 200
) -> tuple[np.ndarray, float, np.ndarray | None]:
    """Least squares from ``x0``: the centre estimate, then the hinge residuals of the
    aimed margins; returns (params, largest hinge residual, verified box or None)."""
    free = model.free
    margin = _aim_margin(model.param_lo, model.param_hi)
    lb = np.where(np.isfinite(model.param_lo), model.param_lo + margin, -np.inf)[free]
    ub = np.where(np.isfinite(model.param_hi), model.param_hi - margin, np.inf)[free]
    fixed = x0.copy()

    def full(z: np.ndarray) -> np.ndarray:
        q = fixed.copy()
        q[free] = z
        return q

    def least_squares_on(residuals: Any, z0: np.ndarray) -> np.ndarray:
        memo: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

        def both(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            key = z.tobytes()
            if key not in memo:
                memo.clear()
                r, J = residuals(full(z), jacobian=True)
                memo[key] = (r, J[:, free])
            return memo[key]

        result = least_squares(
            lambda z: both(z)[0], z0, jac=lambda z: both(z)[1], bounds=(lb, ub),
            method="trf", xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=max_nfev,
        )  # fmt: skip
        return result.x

    def shortfall(p: np.ndarray) -> float:
        res = model.margin_residuals(p)[0]
        return float(np.max(np.abs(res))) if len(res) else 0.0

    z = np.clip(x0[free], lb, ub)
    p = full(z)
    if not np.any(free) or shortfall(p) == 0.0:
        return p, shortfall(p), _verified_box(model, p)
    # the least-squares estimate first (smooth, so it escapes the hinges' flat spots), then
    # the margins from there; when the aimed margins do not fit together (a thin solution
    # set), aim closer to the bounds
    z = least_squares_on(model.centre_residuals, z)
    candidates = [_polish_equalities(model, full(z))]
    for scale in (1.0, 0.1, 0.01):

        def hinge(q: np.ndarray, jacobian: bool, s: float = scale) -> Any:
            return model.margin_residuals(q, jacobian, s)

        z = least_squares_on(hinge, z)
        p = _polish_equalities(model, full(z))
        box = _verified_box(model, p)
        if box is not None:
            return p, shortfall(p), box
        candidates.append(p)
        if shortfall(p) > _HOPELESS:
            break  # far outside some interval: smaller margins will not help
    box = _verified_box(model, candidates[0])
    best = candidates[0] if box is not None else min(candidates, key=shortfall)
    return best, shortfall(best), box


def _find(
    model: HypothesisModel,
    poses_box: PoseBoxes,
    landmarks_box: LandmarkBoxes,
    seed: int,
    restarts: int,
) -> tuple[WitnessPoint | None, np.ndarray | None]:
    if model.problems:
        return None, None
    rng = np.random.default_rng(seed)
    starts = []
    if poses_box is not None or landmarks_box is not None:
        starts.append(lambda: model.initial_params(poses_box, landmarks_box))
    starts.append(lambda: model.initial_params())
    for _ in range(restarts):
        starts.append(lambda: model.initial_params(None, landmarks_box, rng=rng))
    best: tuple[float, np.ndarray] | None = None
    for start in starts:
        p, residual, box = _solve_margins(model, start())
        if box is not None:
            return model.point(p, residual), box
        if best is None or residual < best[0]:
            best = (residual, p)
    if best is not None and best[0] <= 1e-12:
        return model.point(best[1], best[0]), None
    return None, None


def find_witness(
    log: Log,
    assignment: Sequence[str],
    poses_box: PoseBoxes = None,
    landmarks_box: LandmarkBoxes = None,
    seed: int = 0,
    *,
    restarts: int = 3,
    use_sensor: bool = True,
) -> WitnessPoint | None:
    """Look for a solution point of the hypothesis ``(log, assignment)``.

    Minimises, over the parameters (within their intervals), how far each check falls short
    of lying 10 % of its half-width inside its interval (at least 1e-9), plus the closure
    equalities and the sensor's negative information. Starts from the centres of
    ``poses_box`` / ``landmarks_box`` when given (mappings by id, or arrays in the kinematic
    graph's order: a Hypothesis' ``poses`` / ``landmarks``), then from interval midpoints,
    then from ``restarts`` random points (``numpy.random.default_rng(seed)``).

    Returns the first point that :func:`verify_witness` accepts; failing that, a point that
    meets every aimed margin in floating point (unverified), or None.
    """
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    point, _ = _find(model, poses_box, landmarks_box, seed, restarts)
    return point


def certify(
    log: Log,
    solution: Solution,
    *,
    seed: int = 0,
    restarts: int = 2,
    max_hypotheses: int | None = None,
    use_sensor: bool = True,
) -> None:
    """Mark every hypothesis of ``solution`` whose consistency is proven.

    For each hypothesis (the first ``max_hypotheses`` when given), the search of
    :func:`find_witness` (started from its boxes, then midpoints, then ``restarts`` random
    points) and :func:`verify_witness`; on success ``status`` becomes ``PROVEN`` and
    ``witness`` holds ``poses_xyt`` (rows in the hypothesis' ``pose_ids`` order) and
    ``landmarks_xy`` (rows in its ``landmark_ids`` order); otherwise they become (or stay)
    ``NOT_REFUTED`` without a witness. Hypotheses beyond ``max_hypotheses`` are untouched.
    A proven hypothesis takes well under a second; one that is not proven costs every
    start (about 1 s for the paper's log).
    """
    start = time.perf_counter()
    proven = 0
    chosen = solution.hypotheses if max_hypotheses is None else solution.hypotheses[:max_hypotheses]
    for h in chosen:
        model = HypothesisModel(log, h.assignment, use_sensor=use_sensor)
        poses_box = {pid: h.poses[k] for k, pid in enumerate(h.pose_ids)}
        landmarks_box = {lid: h.landmarks[k] for k, lid in enumerate(h.landmark_ids)}
        point, box = _find(model, poses_box, landmarks_box, seed, restarts=restarts)
        if point is None or box is None:
            h.status = NOT_REFUTED
            h.witness = None
            continue
        poses = np.full((len(h.pose_ids), 3), np.nan)
        for k, pid in enumerate(h.pose_ids):
            if pid in point.pose_ids:
                poses[k] = point.pose(pid)
        landmarks = np.full((len(h.landmark_ids), 2), np.nan)
        for k, lid in enumerate(h.landmark_ids):
            if lid in point.landmark_ids:
                landmarks[k] = point.landmark(lid)
        h.status = PROVEN
        h.witness = {"poses_xyt": poses, "landmarks_xy": landmarks}
        proven += 1
    solution.timings["certify_s"] = time.perf_counter() - start
    solution.statistics["proven_hypotheses"] = proven


# --------------------------------------------------------------------------- inner hull
def _variables(model: HypothesisModel, p: np.ndarray) -> np.ndarray:
    """All pose coordinates then all landmark coordinates, flat."""
    P, _ = model.poses(p)
    return np.concatenate([P.ravel(), model.landmarks(p).ravel()])


def inner_hull(
    log: Log,
    assignment: Sequence[str],
    poses_box: PoseBoxes = None,
    landmarks_box: LandmarkBoxes = None,
    *,
    n_random: int = 2,
    refine: int = 3,
    seed: int = 0,
    margin: float = 1e-7,
    use_sensor: bool = True,
    max_iterations: int = 200,
) -> InnerHull | None:
    """An inner approximation of the exact hull of every pose and landmark coordinate.

    For each coordinate, minimises and maximises it (SLSQP: checks as inequalities kept
    ``margin`` half-widths inside their intervals, closures as equalities, parameters within
    their intervals) from the witness and from ``n_random`` random starts (points of the
    boxes, when given, else of the parameter intervals); then, against local optima, again
    from the ``refine`` most extreme solution points found so far for that coordinate and
    direction (other runs' optima are spread over the solution set's boundary). A result
    counts only when :func:`verify_witness` accepts it, else the largest step towards it
    from the witness that verifies. Every verified point widens the hull of every
    coordinate, so the result is the hull of proven solutions: inside the exact hull.
    Returns None when no witness is found. Headings are unwrapped along the odometry tree
    from the anchor.

    SLSQP calls BLAS on tiny matrices: set ``OPENBLAS_NUM_THREADS=1`` (before NumPy is
    imported) or it may run ten times slower.
    """
    start_time = time.perf_counter()
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    witness, _box = _find(model, poses_box, landmarks_box, seed, restarts=3)
    if witness is None or _box is None:
        return None
    rng = np.random.default_rng(seed)
    free = model.free
    lo_c, hi_c = model.check_lo, model.check_hi
    half = np.where(np.isfinite(hi_c - lo_c), (hi_c - lo_c) / 2, 0.0)
    low_side = np.isfinite(lo_c)
    high_side = np.isfinite(hi_c)
    pm = _aim_margin(model.param_lo, model.param_hi) * (margin / AIM_FRACTION)
    lb = np.where(np.isfinite(model.param_lo), model.param_lo + pm, -np.inf)[free]
    ub = np.where(np.isfinite(model.param_hi), model.param_hi - pm, np.inf)[free]
    bounds = [
        (a if np.isfinite(a) else None, b if np.isfinite(b) else None)
        for a, b in zip(lb, ub, strict=True)
    ]
    base = witness.params.copy()

    def full(z: np.ndarray) -> np.ndarray:
        q = base.copy()
        q[free] = z
        return q

    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def evaluated(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = z.tobytes()
        if key not in cache:
            if len(cache) > 8:
                cache.clear()
            v, J = model.evaluate(full(z), jacobian=True)
            assert J is not None
            cache[key] = (v, J[:, free])
        return cache[key]

    def ineq(z: np.ndarray) -> np.ndarray:
        v, _ = evaluated(z)
        return np.concatenate(
            [(v - lo_c - margin * half)[low_side], (hi_c - margin * half - v)[high_side]]
        )

    def ineq_jac(z: np.ndarray) -> np.ndarray:
        _, J = evaluated(z)
        return np.concatenate([J[low_side], -J[high_side]])

    def eq(z: np.ndarray) -> np.ndarray:
        return model.equalities(full(z))[0]

    def eq_jac(z: np.ndarray) -> np.ndarray:
        J = model.equalities(full(z), jacobian=True)[1]
        assert J is not None
        return J[:, free]

    constraints: list[dict[str, Any]] = [{"type": "ineq", "fun": ineq, "jac": ineq_jac}]
    if len(model.equality_rows):
        constraints.append({"type": "eq", "fun": eq, "jac": eq_jac})

    n_pose_vars = 3 * model.n_poses
    n_vars = n_pose_vars + 2 * model.n_landmarks
    points: list[np.ndarray] = [base[free].copy()]
    values: list[np.ndarray] = [_variables(model, base)]
    runs = 0

    def accept(p: np.ndarray) -> bool:
        if _verified_box(model, p) is None:
            return False
        points.append(p[free].copy())
        values.append(_variables(model, p))
        return True

    def objective(index: int, sign: float) -> Any:
        def fun(z: np.ndarray) -> tuple[float, np.ndarray]:
            q = full(z)
            if index < n_pose_vars:
                P, JP = model.poses(q, jacobian=True)
                assert JP is not None
                a, c = divmod(index, 3)
                return sign * P[a, c], sign * JP[a, c, free]
            k = model.landmark_param0 + index - n_pose_vars
            g = np.zeros(model.n_params)
            g[k] = 1.0
            return sign * q[k], sign * g[free]

        return fun

    def optimise(index: int, sign: float, z0: np.ndarray) -> None:
        nonlocal runs
        runs += 1
        try:
            res = minimize(
                objective(index, sign), z0, jac=True, method="SLSQP", bounds=bounds,
                constraints=constraints, options={"maxiter": max_iterations, "ftol": 1e-13},
            )  # fmt: skip
        except (ValueError, np.linalg.LinAlgError):
            return
        if not np.all(np.isfinite(res.x)):
            return
        p = full(res.x)
        if accept(p):
            return
        for t in (1 - 1e-6, 1 - 1e-4, 1 - 1e-2, 0.9, 0.5):
            if accept(base + t * (p - base)):
                return

    starts = [base[free]]
    for _ in range(n_random):
        starts.append(_random_start(model, poses_box, landmarks_box, rng)[free])
    starts = [np.clip(z, np.where(np.isfinite(lb), lb, -np.inf), ub) for z in starts]
    for index in range(n_vars):
        for sign in (1.0, -1.0):
            for z0 in starts:
                optimise(index, sign, z0)
    for _ in range(min(refine, 1)):
        table = np.array(values)
        for index in range(n_vars):
            for sign in (1.0, -1.0):
                order = np.argsort(sign * table[:, index], kind="stable")
                tried: list[np.ndarray] = []
                for k in order:
                    if len(tried) >= refine:
                        break
                    if any(np.array_equal(points[k], z) for z in tried):
                        continue
                    tried.append(points[k])
                    optimise(index, sign, points[k])
    table = np.array(values)
    hull_lo, hull_hi = table.min(axis=0), table.max(axis=0)
    n = model.n_poses
    poses = np.stack([hull_lo[: 3 * n], hull_hi[: 3 * n]], axis=-1).reshape(n, 3, 2)
    landmarks = np.stack([hull_lo[3 * n :], hull_hi[3 * n :]], axis=-1).reshape(-1, 2, 2)
    return InnerHull(
        pose_ids=list(model.pose_ids),
        poses=poses,
        landmark_ids=list(model.landmark_ids),
        landmarks=landmarks,
        verified_points=len(points),
        optimisations=runs,
        seconds=time.perf_counter() - start_time,
        witness=witness,
    )


def _random_start(
    model: HypothesisModel,
    poses_box: PoseBoxes,
    landmarks_box: LandmarkBoxes,
    rng: np.random.Generator,
) -> np.ndarray:
    """Parameters of a random point of the boxes (random parameters where no box is given)."""
    q = model.initial_params(None, landmarks_box, rng=rng)
    boxes = _box_array(model, poses_box)
    if boxes is None:
        return q
    finite = np.isfinite(boxes).all(axis=-1)
    pts = rng.uniform(np.where(finite, boxes[..., 0], 0), np.where(finite, boxes[..., 1], 0))
    P, _ = model.poses(q)
    pts = np.where(finite, pts, P)
    lm = _landmark_random(model, landmarks_box, rng, model.landmarks(q))
    return model.params_from_world(pts, lm)


def _box_array(model: HypothesisModel, poses_box: PoseBoxes) -> np.ndarray | None:
    if poses_box is None:
        return None
    if isinstance(poses_box, Mapping):
        out = np.full((model.n_poses, 3, 2), np.nan)
        for pid, box in poses_box.items():
            if pid in model._pose_index:
                out[model._pose_index[pid]] = np.asarray(box, dtype=float)[:3]
        return out
    return np.asarray(poses_box, dtype=float).reshape(model.n_poses, 3, 2)


def _landmark_random(
    model: HypothesisModel,
    landmarks_box: LandmarkBoxes,
    rng: np.random.Generator,
    fallback: np.ndarray,
) -> np.ndarray:
    if landmarks_box is None:
        return fallback
    if isinstance(landmarks_box, Mapping):
        boxes = np.full((model.n_landmarks, 2, 2), np.nan)
        for lid, box in landmarks_box.items():
            if lid in model._landmark_index:
                boxes[model._landmark_index[lid]] = np.asarray(box, dtype=float)[:2]
    else:
        boxes = np.asarray(landmarks_box, dtype=float).reshape(model.n_landmarks, 2, 2)
    finite = np.isfinite(boxes).all(axis=-1)
    pts = rng.uniform(np.where(finite, boxes[..., 0], 0), np.where(finite, boxes[..., 1], 0))
    return np.where(finite, pts, fallback)
