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
1e-3. The sensor's negative information and class priors of the log are not used (GTSAM
has no counterpart). Readings need both a range and a bearing and no sensor offset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import gtsam
import numpy as np
from scipy.stats import chi2

from cuikslam.log.records import Log, Observation, Odometry, PosePrior, RelativePose

__all__ = ["GATE", "SIGMA_FRACTION", "JcbbResult", "Reading", "jcbb", "run_gtsam_jcbb"]

GATE = 0.99
"""The chi-square gate's probability, for individual and joint compatibility."""

_FLOOR = 1e-3  # standard deviation given to an exact value


SIGMA_FRACTION = 1 / 3
"""Standard deviation per half-width of an interval (a 3-sigma bound)."""


def _sigma(bounds: tuple[float, float], fraction: float = SIGMA_FRACTION) -> float:
    """``fraction`` of the half-width, at least ``_FLOOR``."""
    return max(0.5 * (bounds[1] - bounds[0]) * fraction, _FLOOR)


def _mid(bounds: tuple[float, float]) -> float:
    return 0.5 * (bounds[0] + bounds[1])


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


def _x(pose: int) -> int:
    return gtsam.symbol("x", pose)


def _l(index: int) -> int:
    return gtsam.symbol("l", index)


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
        self.values.insert(_x(pose), gtsam.Pose2(*value))
        self.guess[_x(pose)] = value

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

    def relative(self, source: int, target: int, delta: np.ndarray, cov: np.ndarray) -> None:
        noise = gtsam.noiseModel.Gaussian.Covariance(cov + _FLOOR**2 * np.eye(3))
        self.add(gtsam.BetweenFactorPose2(_x(source), _x(target), gtsam.Pose2(*delta), noise))
        if _x(target) not in self.guess:
            start = gtsam.Pose2(*self.guess[_x(source)])
            end = start.compose(gtsam.Pose2(*delta))
            self.new_pose(target, np.array([end.x(), end.y(), end.theta()]))

    def scan(self, pose: int, observations: list[Observation]) -> list[str]:
        """Associate one scan by JCBB, add its factors; the landmark id of each reading."""
        self.update()
        readings = []
        for o in observations:
            if o.range is None or o.bearing is None or o.offset is not None:
                raise ValueError("the GTSAM baseline needs range and bearing, without offset")
            z = np.array([_mid(o.bearing), _mid(o.range)])
            f = self.fraction
            cov = np.diag([_sigma(o.bearing, f) ** 2, _sigma(o.range, f) ** 2])
            readings.append(Reading(z, cov, o.landmark_class))
        wanted = {o.landmark_class for o in observations}
        candidates = [lm for lm, c in self.classes.items() if c in wanted]
        labels: list[str | None] = [o.landmark for o in observations]
        free = [i for i, lab in enumerate(labels) if lab is None]
        pose_xyt = self.guess[_x(pose)]
        if free and candidates:
            keys = [_x(pose)] + [self.keys[lm] for lm in candidates]
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
                key = _l(len(self.keys))
                self.keys[lm], self.classes[lm] = key, o.landmark_class
                b, r = pose_xyt[2] + readings[i].z[0], readings[i].z[1]
                point = pose_xyt[:2] + r * np.array([math.cos(b), math.sin(b)])
                self.values.insert(key, gtsam.Point2(*point))
                self.guess[key] = point
            noise = gtsam.noiseModel.Gaussian.Covariance(readings[i].cov)
            self.add(
                gtsam.BearingRangeFactor2D(
                    _x(pose),
                    self.keys[lm],
                    gtsam.Rot2.fromAngle(readings[i].z[0]),
                    float(readings[i].z[1]),
                    noise,
                )
            )
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
            value = np.array([_mid(r.x), _mid(r.y), _mid(r.theta)])
            sigmas = np.array([_sigma(r.x, f), _sigma(r.y, f), _sigma(r.theta, f)])
            noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
            slam.add(gtsam.PriorFactorPose2(_x(r.pose), gtsam.Pose2(*value), noise))
            if _x(r.pose) not in slam.guess:
                slam.new_pose(r.pose, value)
        elif isinstance(r, Odometry):
            t, d = _mid(r.turn), _mid(r.distance)
            # local tangent of the move: (d, t) -> (dx, dy, dtheta) = (δd, d δt, δt)
            jac = np.array([[1.0, 0.0], [0.0, d], [0.0, 1.0]])
            cov = jac @ np.diag([_sigma(r.distance, f) ** 2, _sigma(r.turn, f) ** 2]) @ jac.T
            delta = np.array([d * math.cos(t), d * math.sin(t), t])
            slam.relative(r.source, r.target, delta, cov)
        elif isinstance(r, RelativePose):
            delta = np.array([_mid(r.dx), _mid(r.dy), _mid(r.dtheta)])
            cov = np.diag([_sigma(r.dx, f) ** 2, _sigma(r.dy, f) ** 2, _sigma(r.dtheta, f) ** 2])
            slam.relative(r.source, r.target, delta, cov)
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
