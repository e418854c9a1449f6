"""What the optimisers minimise: the loop-closure equalities and the residuals built on
the checks of :class:`~.model.HypothesisModel`.

A mixin of the model (which holds the parametrisation and evaluates the checks):

* :meth:`Residuals.equalities`: the loop-closure equalities (0 when satisfied), also the
  functions :mod:`.verify` brackets with Poincaré–Miranda;
* :meth:`Residuals.sensor_residuals`: the sensor's violations per (pose, landmark) pair,
  restricted to the pairs :meth:`Residuals.focus_sensor` keeps;
* :meth:`Residuals.centre_residuals`: distances from the intervals' centres (a start);
* :meth:`Residuals.fit_residuals`: the same and the sensor's violations (the fit that
  ranks hypotheses);
* :meth:`Residuals.margin_residuals`: hinges at the aimed margins (what a witness meets).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cuikslam.log.records import SensorModel
from cuikslam.witness._numeric import finite, half_width, midpoint
from cuikslam.witness._sensor import sensor_terms
from cuikslam.witness._starts import LandmarkBoxes, PoseBoxes


class Residuals:
    """The equalities and residuals (mixed into :class:`~.model.HypothesisModel`)."""

    # the model's attributes this mixin reads (set by HypothesisModel.__init__)
    n_params: int
    param_lo: np.ndarray
    param_hi: np.ndarray
    check_lo: np.ndarray
    check_hi: np.ndarray
    check_mid: np.ndarray
    check_margin: np.ndarray
    closure_source: np.ndarray
    closure_target: np.ndarray
    equality_rows: np.ndarray
    sensor: SensorModel | None
    sensor_scales: tuple[float, float]
    observed: np.ndarray
    _sensor_rows: np.ndarray
    n_poses: Any  # properties of the model
    n_landmarks: Any

    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
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

    def focus_sensor(
        self, poses_box: PoseBoxes, landmarks_box: LandmarkBoxes, slack: float = 1.0
    ) -> None:
        """Let the optimisers see only the sensor pairs that can matter: observed pairs, and
        pairs whose boxes come within ``max_range + slack`` of each other (or lack a box).
        A speed-up only: :func:`~.verify.verify_witness` still checks every pair."""
        n, m = self.n_poses, self.n_landmarks
        if self.sensor is None or not math.isfinite(self.sensor.max_range) or n * m == 0:
            return
        P, L = self.pose_boxes(poses_box), self.landmark_boxes(landmarks_box)
        if P is None or L is None:
            return
        with np.errstate(invalid="ignore", over="ignore"):  # gaps of 1e308 m: inf, far
            gap_x = np.maximum(
                L[None, :, 0, 0] - P[:, None, 0, 1], P[:, None, 0, 0] - L[None, :, 0, 1]
            )
            gap_y = np.maximum(
                L[None, :, 1, 0] - P[:, None, 1, 1], P[:, None, 1, 0] - L[None, :, 1, 1]
            )
            gap = np.hypot(np.maximum(gap_x, 0.0), np.maximum(gap_y, 0.0))
            near = ~(gap > self.sensor.max_range + slack)  # NaN (no box) counts as near
        self._sensor_rows = np.flatnonzero(near | self.observed)

    def see_all_sensor_pairs(self) -> None:
        """Undo :meth:`focus_sensor`: every (pose, landmark) pair counts again."""
        self._sensor_rows = np.arange(self.n_poses * self.n_landmarks)

    def sensor_residuals(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """One violation per (pose, landmark) pair of the sensor model (0 when satisfied,
        with SENSOR_MARGIN clearance); empty without a sensor record."""
        n, m = self.n_poses, self.n_landmarks
        if self.sensor is None or n == 0 or m == 0:
            return np.zeros(0), (np.zeros((0, self.n_params)) if jacobian else None)
        P, JP = self.poses(p, jacobian)
        t = sensor_terms(
            self.sensor, self.observed, self._sensor_rows, P, self.landmarks(p), jacobian,
            self.sensor_scales,
        )  # fmt: skip
        if not jacobian:
            return t.residuals, None
        assert JP is not None
        # derivatives only for the violated pairs (the others' rows are zero)
        J = np.zeros((t.residuals.size, self.n_params))
        if t.active.size == 0:
            return t.residuals, J
        with np.errstate(all="ignore"):
            rows = np.einsum("kc,kcp->kp", t.d_pose, JP[t.pose])
            k = np.arange(t.active.size)
            for which, coef in ((t.landmark, t.d_landmark), (t.nearest, t.d_nearest)):
                cx, cy = self._landmark_columns(which)
                np.add.at(rows, (k, cx), coef[:, 0])
                np.add.at(rows, (k, cy), coef[:, 1])
        J[t.active] = rows
        return t.residuals, finite(J, nan=0.0)

    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
    def centre_residuals(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Smooth residuals: each check's value and each bounded parameter's distance from
        its interval's centre, in half-widths (the usual least-squares SLAM estimate), then
        the closure equalities. Their minimiser is a good start for the margins."""
        v, J = self.evaluate(p, jacobian)
        lo, hi = self.check_lo, self.check_hi
        half = half_width(lo, hi)
        bounded = np.isfinite(lo) & np.isfinite(hi) & (half > 0)
        half = np.where(bounded, half, 1.0)
        with np.errstate(over="ignore", invalid="ignore"):
            r_checks = np.where(bounded, (v - self.check_mid) / half, 0.0)
        plo, phi = self.param_lo, self.param_hi
        phalf = half_width(plo, phi)
        pbounded = np.isfinite(plo) & np.isfinite(phi) & (phalf > 0)
        phalf = np.where(pbounded, phalf, 1.0)
        pmid = midpoint(plo, phi, 0.0)
        with np.errstate(over="ignore", invalid="ignore"):
            r_params = np.where(pbounded, (p - pmid) / phalf, 0.0)
        f, Jf = self.equalities(p, jacobian)
        out = finite(np.concatenate([r_checks, r_params, f]))
        if not jacobian:
            return out, None
        assert J is not None and Jf is not None
        with np.errstate(over="ignore", invalid="ignore"):
            Jc = (bounded / half)[:, None] * J
            Jp = np.diag(pbounded / phalf)
        return out, finite(np.concatenate([Jc, Jp, Jf]), nan=0.0)

    def fit_residuals(
        self, p: np.ndarray, jacobian: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`centre_residuals`, then one sensor violation per pose (0 where the
        negative information holds): the least-squares estimate of a back end that also
        knows what the robot would have seen."""
        r, J = self.centre_residuals(p, jacobian)
        sr, Js = self._sensor_per_pose(p, jacobian)
        if not jacobian:
            return np.concatenate([r, sr]), None
        assert J is not None and Js is not None
        return np.concatenate([r, sr]), np.concatenate([J, Js])

    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
    def _sensor_per_pose(
        self, p: np.ndarray, jacobian: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """The sensor violations gathered into one residual per pose, the root of their sum
        of squares: the same least-squares objective in far fewer rows (the optimiser's
        cost grows with the rows times the parameters squared)."""
        sr, Js = self.sensor_residuals(p, jacobian)
        if sr.size == 0:
            return sr, Js
        pose = self._sensor_rows // self.n_landmarks
        norm = np.sqrt(np.bincount(pose, weights=sr * sr, minlength=self.n_poses))
        if not jacobian:
            return norm, None
        assert Js is not None
        grad = np.zeros((self.n_poses, self.n_params))
        act = np.flatnonzero(sr > 0)  # the other pairs' rows are zero
        np.add.at(grad, pose[act], sr[act, None] * Js[act])
        with np.errstate(invalid="ignore", divide="ignore"):
            grad = np.where(norm[:, None] > 0, grad / norm[:, None], 0.0)
        return norm, grad

    def margin_residuals(
        self, p: np.ndarray, jacobian: bool = False, scale_margin: float = 1.0
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Hinge residuals: how far each check's value is from ``[lo + m, hi - m]`` (in
        half-widths), then the equalities, then the sensor violations."""
        v, J = self.evaluate(p, jacobian)
        lo, hi = self.check_lo, self.check_hi
        margin = self.check_margin * scale_margin
        half = half_width(lo, hi)
        half = np.where(np.isfinite(half) & (half > 0), half, 1.0)
        with np.errstate(over="ignore", invalid="ignore"):
            below = (lo + margin - v) / half
            above = (v - (hi - margin)) / half
        below = np.where(np.isfinite(lo), below, -np.inf)
        above = np.where(np.isfinite(hi), above, -np.inf)
        res = np.maximum(below, 0.0) + np.maximum(above, 0.0)
        f, Jf = self.equalities(p, jacobian)
        sr, Js = self._sensor_per_pose(p, jacobian)
        out = finite(np.concatenate([res, f, sr]))
        if not jacobian:
            return out, None
        assert J is not None and Jf is not None and Js is not None
        sign = np.where(below > 0, -1.0, 0.0) + np.where(above > 0, 1.0, 0.0)
        with np.errstate(over="ignore", invalid="ignore"):
            Jr = (sign / half)[:, None] * J
        return out, finite(np.concatenate([Jr, Jf, Js]), nan=0.0)
