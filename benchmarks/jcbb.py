"""A probabilistic baseline: incremental GTSAM pose-graph SLAM with JCBB data association.

What users pick when the correspondence is unknown: an iSAM2 pose graph (Pose2 odometry
``BetweenFactor``s, ``BearingRangeFactor``s to Point2 landmarks) and, per scan, joint
compatibility branch and bound (Neira & Tardós, IEEE T-RA 2001), written here from the
idea. Each reading is first paired with the landmarks of its class that are *individually*
compatible (the Mahalanobis distance of its innovation under the 99 % chi-square gate, with
the joint marginal covariance of the pose and the landmark from ``gtsam.Marginals``); the
branch and bound then keeps the hypothesis over the whole scan with the most pairings whose
stacked innovation passes the 99 % gate of its dimension (ties: the smallest joint
distance). Readings left unpaired open new landmarks.

Noise model: the log's intervals are read as Gaussians centred on their midpoints with a
standard deviation of a third of their half-width (a 3-sigma bound); exact values get
1e-3. The factors are the library's (:mod:`cuikslam.interop.gtsam`, the same as
``cuikslam.interop.gtsam.factor_graph`` builds). The sensor's negative information and
class priors of the log are not used (GTSAM has no counterpart). Readings need both a
range and a bearing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gtsam
import numpy as np
from scipy.stats import chi2

from cuikslam.interop.estimate import landmark_key, pose_key
from cuikslam.interop.gaussian import midpoint, move_gaussian, reading_gaussian
from cuikslam.interop.gtsam import move_factor, observation_factor, pose_prior_factor
from cuikslam.log.records import Log, Observation, Odometry, PosePrior, RelativePose

__all__ = ["GATE", "SIGMA_FRACTION", "JcbbResult", "Reading", "jcbb", "run_gtsam_jcbb"]

GATE = 0.99
"""The chi-square gate's probability, for individual and joint compatibility."""

_FLOOR = 1e-3  # standard deviation given to an exact value


SIGMA_FRACTION = 1 / 3
"""Standard deviation per half-width of an interval (a 3-sigma bound)."""


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


@dataclass
class Reading:
    """One range-bearing reading: measured (bearing, range) and its 2x2 covariance."""

    z: np.ndarray
    cov: np.ndarray
    landmark_class: str


def predict(pose: np.ndarray, point: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted (bearing, range) of ``point`` from ``pose`` (x, y, theta), with its
    Jacobians wrt the pose's *local* tangent (gtsam's Pose2 convention) and the point."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rt = np.array([[c, s], [-s, c]])
    q = rt @ (point - pose[:2])
    r2 = float(q @ q)
    r = math.sqrt(r2)
    dh_dq = np.array([[-q[1] / r2, q[0] / r2], [q[0] / r, q[1] / r]])
    dq_dpose = np.array([[-1.0, 0.0, q[1]], [0.0, -1.0, -q[0]]])
    return np.array([math.atan2(q[1], q[0]), r]), dh_dq @ dq_dpose, dh_dq @ rt


def jcbb(
    pose: np.ndarray,
    points: list[np.ndarray],
    point_classes: list[str],
    cov: np.ndarray,
    readings: list[Reading],
    gate: float = GATE,
) -> list[int | None]:
    """JCBB over one scan: for each reading the index into ``points`` it is paired with, or
    None (a new landmark).

    ``cov`` is the joint covariance of the state ``[pose (3, local tangent), point 0 (2),
    point 1 (2), ...]``. Each point is used at most once (a scan sees distinct landmarks).
    """
    n = len(readings)
    preds = [predict(pose, p) for p in points]

    def rows(i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Innovation of reading i paired with point j and its Jacobian wrt the state."""
        h, hp, hl = preds[j]
        nu = readings[i].z - h
        nu[0] = _wrap(nu[0])
        jac = np.zeros((2, cov.shape[0]))
        jac[:, :3] = hp
        jac[:, 3 + 2 * j : 5 + 2 * j] = hl
        return nu, jac

    def distance(pairs: list[tuple[int, int]]) -> float:
        """Joint Mahalanobis distance of the pairings ``pairs``."""
        blocks = [rows(i, j) for i, j in pairs]
        nu = np.concatenate([b[0] for b in blocks])
        jac = np.vstack([b[1] for b in blocks])
        noise = np.zeros((len(nu), len(nu)))
        for k, (i, _) in enumerate(pairs):
            noise[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = readings[i].cov
        s = jac @ cov @ jac.T + noise
        return float(nu @ np.linalg.solve(s, nu))

    individual = [
        [
            j
            for j in range(len(points))
            if point_classes[j] == readings[i].landmark_class
            and distance([(i, j)]) < chi2.ppf(gate, 2)
        ]
        for i in range(n)
    ]
    best: list = [[None] * n, 0, math.inf]  # hypothesis, pairings, joint distance

    def branch(i: int, hyp: list[int | None], pairs: list[tuple[int, int]], d2: float) -> None:
        if i == n:
            if len(pairs) > best[1] or (len(pairs) == best[1] and d2 < best[2]):
                best[:] = [list(hyp), len(pairs), d2]
            return
        used = {j for _, j in pairs}
        for j in individual[i]:
            if j in used:
                continue
            trial = [*pairs, (i, j)]
            d = distance(trial)
            if d < chi2.ppf(gate, 2 * len(trial)):
                branch(i + 1, [*hyp, j], trial, d)
        if len(pairs) + (n - i - 1) >= best[1]:  # leaving reading i unpaired can still win
            branch(i + 1, [*hyp, None], pairs, d2)

    branch(0, [], [], 0.0)
    return best[0]


@dataclass
class JcbbResult:
    """The baseline's answer: a landmark id per observation (log order) and the estimate."""

    assignment: list[str]
    poses: dict[int, np.ndarray] = field(default_factory=dict)
    landmarks: dict[str, np.ndarray] = field(default_factory=dict)


class _Slam:
    """The iSAM2 pose graph, grown record by record."""

    def __init__(self, fraction: float) -> None:
        self.fraction = fraction
        self.isam = gtsam.ISAM2(gtsam.ISAM2Params())
        self.full = gtsam.NonlinearFactorGraph()
        self.pending = gtsam.NonlinearFactorGraph()
        self.values = gtsam.Values()
        self.guess: dict[int, np.ndarray] = {}  # latest estimate of every variable
        self.keys: dict[str, int] = {}  # landmark id -> gtsam key
        self.classes: dict[str, str] = {}

    def add(self, factor: gtsam.NonlinearFactor) -> None:
        self.pending.add(factor)
        self.full.add(factor)

    def new_pose(self, pose: int, value: np.ndarray) -> None:
        self.values.insert(pose_key(pose), gtsam.Pose2(*value))
        self.guess[pose_key(pose)] = value

    def update(self) -> None:
        if self.pending.size() or self.values.size():
            self.isam.update(self.pending, self.values)
            self.pending, self.values = gtsam.NonlinearFactorGraph(), gtsam.Values()
            est = self.isam.calculateEstimate()
            for key in self.guess:
                if gtsam.Symbol(key).chr() == ord("x"):
                    v = est.atPose2(key)
                    self.guess[key] = np.array([v.x(), v.y(), v.theta()])
                else:
                    self.guess[key] = np.asarray(est.atPoint2(key))

    def relative(self, record: Odometry | RelativePose) -> None:
        self.add(move_factor(record, self.fraction, _FLOOR))
        if pose_key(record.target) not in self.guess:
            start = gtsam.Pose2(*self.guess[pose_key(record.source)])
            end = start.compose(gtsam.Pose2(*move_gaussian(record, self.fraction, _FLOOR).mean))
            self.new_pose(record.target, np.array([end.x(), end.y(), end.theta()]))

    def scan(self, pose: int, observations: list[Observation]) -> list[str]:
        """Associate one scan by JCBB, add its factors; the landmark id of each reading."""
        self.update()
        readings = []
        for o in observations:
            reading = reading_gaussian(o, self.fraction, _FLOOR)
            if reading.kind != "bearing-range":
                raise ValueError("the GTSAM baseline needs both a range and a bearing")
            readings.append(Reading(reading.mean, reading.covariance, o.landmark_class))
        wanted = {o.landmark_class for o in observations}
        candidates = [lm for lm, c in self.classes.items() if c in wanted]
        labels: list[str | None] = [o.landmark for o in observations]
        free = [i for i, lab in enumerate(labels) if lab is None]
        pose_xyt = self.guess[pose_key(pose)]
        if free and candidates:
            keys = [pose_key(pose)] + [self.keys[lm] for lm in candidates]
            joint = gtsam.Marginals(self.full, self.isam.calculateEstimate())
            cov = joint.jointMarginalCovariance(gtsam.KeyVector(keys)).fullMatrix()
            points = [self.guess[self.keys[lm]] for lm in candidates]
            pairing = jcbb(
                pose_xyt,
                points,
                [self.classes[lm] for lm in candidates],
                cov,
                [readings[i] for i in free],
            )
            taken = {lab for lab in labels if lab is not None}
            for i, j in zip(free, pairing, strict=True):
                if j is not None and candidates[j] not in taken:
                    labels[i] = candidates[j]
        for i, o in enumerate(observations):
            if labels[i] is None:
                labels[i] = f"J{len(self.keys)}"
            lm = labels[i]
            if lm not in self.keys:
                key = landmark_key(len(self.keys))
                self.keys[lm], self.classes[lm] = key, o.landmark_class
                b, r = pose_xyt[2] + readings[i].z[0], readings[i].z[1]
                point = pose_xyt[:2] + r * np.array([math.cos(b), math.sin(b)])
                self.values.insert(key, gtsam.Point2(*point))
                self.guess[key] = point
            self.add(observation_factor(o, self.keys[lm], self.fraction, _FLOOR))
        return [str(lab) for lab in labels]


def run_gtsam_jcbb(log: Log, fraction: float = SIGMA_FRACTION) -> JcbbResult:
    """Incremental GTSAM with JCBB association over ``log``, scan by scan; standard
    deviations are ``fraction`` of the intervals' half-widths."""
    if log.landmark_priors:
        raise ValueError("the GTSAM baseline does not read landmark priors")
    slam = _Slam(fraction)
    f = fraction
    assignment: list[str] = []
    scan: list[Observation] = []

    def flush() -> None:
        if scan:
            assignment.extend(slam.scan(scan[0].pose, scan))
            scan.clear()

    for r in log.records:
        if isinstance(r, Observation):
            if scan and (r.pose != scan[0].pose):
                flush()
            scan.append(r)
            continue
        flush()
        if isinstance(r, PosePrior):
            slam.add(pose_prior_factor(r, f, _FLOOR))
            if pose_key(r.pose) not in slam.guess:
                slam.new_pose(r.pose, np.array([midpoint(b) for b in (r.x, r.y, r.theta)]))
        elif isinstance(r, Odometry | RelativePose):
            slam.relative(r)
    flush()
    slam.update()
    est = slam.isam.calculateEstimate()
    poses = {
        gtsam.Symbol(k).index(): np.array([p.x(), p.y(), p.theta()])
        for k in slam.guess
        if gtsam.Symbol(k).chr() == ord("x")
        for p in [est.atPose2(k)]
    }
    landmarks = {lm: np.asarray(est.atPoint2(key)) for lm, key in slam.keys.items()}
    return JcbbResult(assignment=assignment, poses=poses, landmarks=landmarks)
