"""The inner hull: the exact solution set of a hypothesis measured from inside.

:func:`inner_hull` minimises and maximises every pose and landmark coordinate over the
solutions, from the witness of :mod:`.find` and from random points of the boxes, and keeps
only points that :mod:`.verify` proves; the hull of those points lies inside the exact hull.
The tightness benchmark (``benchmarks/bench_tightness.py``) compares it with the narrowed
boxes.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cuikslam.budget import blas_single_thread
from cuikslam.log.records import Log
from cuikslam.witness._numeric import half_width, uniform
from cuikslam.witness.find import find_point
from cuikslam.witness.model import (
    AIM_FRACTION,
    HypothesisModel,
    LandmarkBoxes,
    PoseBoxes,
    WitnessPoint,
    aim_margin,
)
from cuikslam.witness.verify import verified_box


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
    Returns None when no witness is found. Headings are unwrapped along the kinematic tree
    from the anchor.

    SLSQP calls BLAS on tiny matrices: it runs with one BLAS thread
    (:func:`cuikslam.budget.blas_single_thread`; measured 4.4 times faster on a 30-pose
    world at load 3.5-4 on 2 cores).
    """
    with blas_single_thread():
        return _inner_hull(
            log, assignment, poses_box, landmarks_box, n_random=n_random, refine=refine,
            seed=seed, margin=margin, use_sensor=use_sensor, max_iterations=max_iterations,
        )  # fmt: skip


def _inner_hull(
    log: Log,
    assignment: Sequence[str],
    poses_box: PoseBoxes,
    landmarks_box: LandmarkBoxes,
    *,
    n_random: int,
    refine: int,
    seed: int,
    margin: float,
    use_sensor: bool,
    max_iterations: int,
) -> InnerHull | None:
    start_time = time.perf_counter()
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    witness, _box = find_point(model, poses_box, landmarks_box, seed, restarts=3)
    if witness is None or _box is None:
        return None
    rng = np.random.default_rng(seed)
    free = model.free
    lo_c, hi_c = model.check_lo, model.check_hi
    half = half_width(lo_c, hi_c)
    half = np.where(np.isfinite(half), half, 0.0)
    low_side = np.isfinite(lo_c)
    high_side = np.isfinite(hi_c)
    pm = aim_margin(model.param_lo, model.param_hi) * (margin / AIM_FRACTION)
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
        if verified_box(model, p) is None:
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
            from scipy.optimize import minimize  # loaded when a witness is sought

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
    if refine > 0:  # one round of restarts from the most extreme points
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
    boxes = model.pose_boxes(poses_box)
    if boxes is None:
        return q
    P, _ = model.poses(q)
    pts = _uniform_in(boxes, rng, P)
    landmark_boxes = model.landmark_boxes(landmarks_box)
    lm = model.landmarks(q)
    if landmark_boxes is not None:
        lm = _uniform_in(landmark_boxes, rng, lm)
    return model.params_from_world(pts, lm)


def _uniform_in(boxes: np.ndarray, rng: np.random.Generator, fallback: np.ndarray) -> np.ndarray:
    """A random point of each box (..., 2); ``fallback`` where a bound is not finite."""
    finite = np.isfinite(boxes).all(axis=-1)
    pts = uniform(rng, np.where(finite, boxes[..., 0], 0), np.where(finite, boxes[..., 1], 0))
    return np.where(finite, pts, fallback)
