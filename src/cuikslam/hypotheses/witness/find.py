"""Finding a witness: local optimisation inside the measured intervals, then verification.

:func:`find_witness` minimises how far each check falls short of lying a little inside its
interval, from a few starting points, and keeps the first point that :mod:`.verify` proves.
:func:`certify` runs that search on every hypothesis of a
:class:`~cuikslam.results.Solution` and marks the proven ones.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from cuikslam.hypotheses.witness.model import (
    HypothesisModel,
    LandmarkBoxes,
    PoseBoxes,
    WitnessPoint,
    aim_margin,
)
from cuikslam.hypotheses.witness.verify import verified_box
from cuikslam.log.records import Log
from cuikslam.results.solution import NOT_REFUTED, PROVEN, Solution

_HOPELESS = 0.5
"""A hinge residual (in half-widths) beyond which aiming closer to the bounds is not tried."""


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
    margin = aim_margin(model.param_lo, model.param_hi)
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
        return p, shortfall(p), verified_box(model, p)
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
        box = verified_box(model, p)
        if box is not None:
            return p, shortfall(p), box
        candidates.append(p)
        if shortfall(p) > _HOPELESS:
            break  # far outside some interval: smaller margins will not help
    box = verified_box(model, candidates[0])
    best = candidates[0] if box is not None else min(candidates, key=shortfall)
    return best, shortfall(best), box


def find_point(
    model: HypothesisModel,
    poses_box: PoseBoxes,
    landmarks_box: LandmarkBoxes,
    seed: int,
    restarts: int,
) -> tuple[WitnessPoint | None, np.ndarray | None]:
    """The search of :func:`find_witness` on a built model: (point, verified parameter box),
    or (unverified point, None), or (None, None)."""
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
    point, _ = find_point(model, poses_box, landmarks_box, seed, restarts)
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
        point, box = find_point(model, poses_box, landmarks_box, seed, restarts=restarts)
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
