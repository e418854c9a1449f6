"""Starting points of the witness search: parameters from boxes, midpoints, random points.

A mixin of :class:`~.model.HypothesisModel` (which holds the parametrisation and the
checks): it turns pose and landmark boxes (or a whole world) into parameter vectors,
and places landmarks from their observations when no box says where they are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from cuikslam.budget import COSTS, Budget, OutOfTime, expired, spend
from cuikslam.witness._kinematics import step_from_world
from cuikslam.witness._numeric import (
    cos_sin,
    finite,
    half_width,
    midpoint,
    uniform,
    wrap_near,
)

PoseBoxes = Mapping[int, np.ndarray] | np.ndarray | None
LandmarkBoxes = Mapping[str, np.ndarray] | np.ndarray | None

LANDMARK_FITS = 16
"""Least-squares fits (each from one observation's projection, of at most 50 evaluations)
that place a landmark no box places."""


def _by_id(
    values: Mapping[Any, Any] | np.ndarray, index: dict, shape: tuple[int, ...]
) -> np.ndarray:
    """``values`` (a mapping by id, or an array in the model's order) as an array of
    ``shape``, rows in the model's order: NaN rows for ids not given, unknown ids ignored."""
    if isinstance(values, Mapping):
        out = np.full(shape, np.nan)
        for key, v in values.items():
            if key in index:
                out[index[key]] = np.asarray(v, dtype=float)[: shape[1]]
        return out
    return np.asarray(values, dtype=float).reshape(shape)


def _centres(boxes: np.ndarray | None) -> np.ndarray | None:
    """Centres of boxes (..., 2), NaN where a bound is missing or infinite."""
    if boxes is None:
        return None
    return midpoint(boxes[..., 0], boxes[..., 1])


class Starts:
    """Starting points (mixed into :class:`~.model.HypothesisModel`)."""

    # the model's attributes this mixin reads (set by HypothesisModel.__init__)
    n_params: int
    param_lo: np.ndarray
    param_hi: np.ndarray
    anchors: list[tuple[int, int]]
    steps: list[Any]
    landmark_param0: int
    check_lo: np.ndarray
    check_hi: np.ndarray
    check_mid: np.ndarray
    obs_pose: np.ndarray
    obs_landmark: np.ndarray
    range_sel: np.ndarray
    bearing_sel: np.ndarray
    prior_pose: np.ndarray
    lprior_landmark: np.ndarray
    lprior_coord: np.ndarray
    _pose_index: dict[int, int]
    _landmark_index: dict[str, int]

    def params_from_world(
        self,
        poses_xyt: Mapping[int, np.ndarray] | np.ndarray,
        landmarks_xy: Mapping[str, np.ndarray] | np.ndarray,
        clip: bool = True,
    ) -> np.ndarray:
        """Parameters that reproduce a world as nearly as they can (turns and headings mod
        2 pi near their intervals; sensor offsets, which the world does not give, at their
        intervals' centres; with ``clip`` each parameter is clipped to its bounds).

        The world need not be consistent: pose values drive the tree's parameters one step
        at a time, so a box centre gives a sensible starting point.
        """
        P = self._pose_array(poses_xyt)
        L = self._landmark_array(landmarks_xy)
        p = np.zeros(self.n_params)
        for a, k in self.anchors:
            p[k : k + 3] = P[a]
        for st in self.steps:
            k = list(st.params)
            if st.child >= self.n_poses:  # a sensor's offset: its intervals' centres
                p[k] = midpoint(self.param_lo[k], self.param_hi[k], 0.0)
                continue
            p[k] = step_from_world(st, P[st.parent], P[st.child], self.param_lo, self.param_hi)
        p[self.landmark_param0 :] = L.ravel()
        p = np.where(np.isfinite(p), p, 0.0)
        if clip:
            p = np.clip(p, self.param_lo, self.param_hi)
        return p

    def _pose_array(self, poses: Mapping[int, np.ndarray] | np.ndarray) -> np.ndarray:
        return _by_id(poses, self._pose_index, (self.n_poses, 3))

    def _landmark_array(self, landmarks: Mapping[str, np.ndarray] | np.ndarray) -> np.ndarray:
        return _by_id(landmarks, self._landmark_index, (self.n_landmarks, 2))

    def pose_boxes(self, boxes: PoseBoxes) -> np.ndarray | None:
        """Pose boxes as an array (n, 3, 2) in the model's order (NaN where not given)."""
        if boxes is None:
            return None
        return _by_id(boxes, self._pose_index, (self.n_poses, 3, 2))

    def landmark_boxes(self, boxes: LandmarkBoxes) -> np.ndarray | None:
        """Landmark boxes as an array (m, 2, 2) in the model's order (NaN where not given)."""
        if boxes is None:
            return None
        return _by_id(boxes, self._landmark_index, (self.n_landmarks, 2, 2))

    def initial_params(
        self,
        poses_box: PoseBoxes = None,
        landmarks_box: LandmarkBoxes = None,
        rng: np.random.Generator | None = None,
        deadline: Budget | None = None,
    ) -> np.ndarray:
        """A starting point: interval midpoints (or random points of the intervals when
        ``rng`` is given), refined by the boxes' centres where given; landmarks at their box
        or prior centre, else where their first observation's midpoint puts them.

        Raises :class:`~cuikslam.budget.OutOfTime` when ``deadline`` passes while fitting
        landmarks (a few small least-squares fits each)."""
        finite = np.isfinite(self.param_lo) & np.isfinite(self.param_hi)
        lo = np.where(finite, self.param_lo, 0.0)
        hi = np.where(finite, self.param_hi, 0.0)
        p = midpoint(lo, hi, 0.0) if rng is None else uniform(rng, lo, hi)
        pose_c = _centres(self.pose_boxes(poses_box))
        if pose_c is not None and rng is None:
            q = self.params_from_world(
                np.where(np.isnan(pose_c), 0.0, pose_c), np.zeros((self.n_landmarks, 2)), clip=True
            )
            ok = self._params_known(pose_c)
            p = np.where(ok & np.isfinite(q), q, p)
        # anchors without a prior: the box centre or the origin
        land = _centres(self.landmark_boxes(landmarks_box))
        P, _ = self.frames(p)
        L = np.full((self.n_landmarks, 2), np.nan)
        for lo_, hi_, j, c in zip(*self._landmark_prior_rows(), strict=True):
            if np.isnan(L[j, c]) and math.isfinite(lo_) and math.isfinite(hi_):
                L[j, c] = midpoint(lo_, hi_)
        if land is not None:
            L = np.where(np.isnan(land), L, land)
        for j in range(self.n_landmarks):
            if np.any(np.isnan(L[j])):
                if expired(deadline):
                    raise OutOfTime
                L[j], evaluated = self._fit_landmark(j, P, rng)
                spend(deadline, evaluated)
        L = np.where(np.isnan(L), 0.0, L)
        p[self.landmark_param0 :] = L.ravel()
        return p

    def _fit_landmark(
        self, j: int, P: np.ndarray, rng: np.random.Generator | None = None
    ) -> tuple[np.ndarray, float]:
        """Where the observations of landmark ``j`` put it, seen from the poses ``P``: the
        best of small least-squares fits started from each observation's midpoint
        projection (at a few guessed ranges when the range is unmeasured, a few guessed
        bearings when the bearing is); and the work units spent (each evaluation of the
        fits: a fixed cost and one per observation)."""
        rows = []
        for q in np.flatnonzero(self.obs_landmark == j):
            i = int(self.obs_pose[q])
            rr, bb = self._obs_mid(q, "range"), self._obs_mid(q, "bearing")
            rows.append((i, rr, bb, self._obs_half(q, "range"), self._obs_half(q, "bearing")))
        if not rows:
            return np.zeros(2), 0.0
        starts = []
        for i, rr, bb, _, _ in rows:
            ranges = [rr] if rr is not None else [1.0, 3.0, 10.0]
            bearings = [bb] if bb is not None else [0.0, math.pi / 2, math.pi, -math.pi / 2]
            if rng is not None and bb is None:
                bearings = [b + rng.normal(0.0, 0.3) for b in bearings]
            for r in ranges:
                for b in bearings:
                    a = P[i, 2] + b
                    starts.append(finite(P[i, :2] + r * np.array(cos_sin(a))))
        if len(rows) == 1 and rows[0][1] is not None and rows[0][2] is not None:
            return starts[0], 0.0
        pose_i = np.array([r[0] for r in rows])
        rng_mid = np.array([np.nan if r[1] is None else r[1] for r in rows])
        brg_mid = np.array([np.nan if r[2] is None else r[2] for r in rows])
        rng_w = np.array([1.0 if r[3] is None else max(r[3], 1e-3) for r in rows])
        brg_w = np.array([1.0 if r[4] is None else max(r[4], 1e-3) for r in rows])
        has_r, has_b = ~np.isnan(rng_mid), ~np.isnan(brg_mid)

        @np.errstate(all="ignore")
        def residuals(xy: np.ndarray) -> np.ndarray:
            dx = xy[0] - P[pose_i, 0]
            dy = xy[1] - P[pose_i, 1]
            dist = np.hypot(dx, dy)
            brg = np.arctan2(dy, dx) - P[pose_i, 2]
            res_r = (dist - rng_mid)[has_r] / rng_w[has_r]
            res_b = wrap_near(brg, brg_mid)[has_b] - brg_mid[has_b]
            return finite(np.concatenate([res_r, res_b / brg_w[has_b]]))

        best, best_cost = starts[0], math.inf
        evaluations = 0
        for xy in starts[:LANDMARK_FITS]:
            try:
                from scipy.optimize import least_squares  # loaded when a witness is sought

                with np.errstate(all="ignore"):  # huge magnitudes: overflow, no warning
                    fit = least_squares(residuals, xy, method="trf", max_nfev=50)
            except ValueError:
                continue
            evaluations += fit.nfev + 2 * fit.njev  # its Jacobian by differences: 2 more
            if fit.cost < best_cost and np.all(np.isfinite(fit.x)):
                best, best_cost = fit.x, fit.cost
        work = evaluations * (COSTS["evaluation"] + COSTS["jacobian_entry"] * len(rows))
        return np.asarray(best, dtype=float), work

    def _obs_row(self, q: int, kind: str) -> int | None:
        """The check row of observation ``q``'s ``"range"`` or ``"bearing"`` (None when it
        is not measured)."""
        rows = getattr(self, "_obs_rows", None)
        if rows is None:  # each observation's rows, once (a search per call was quadratic)
            n, r, b = len(self.obs_pose), len(self.range_sel), len(self.bearing_sel)
            rows = np.full((2, n), -1, dtype=np.int64)
            rows[0, self.range_sel] = np.arange(r)
            rows[1, self.bearing_sel] = r + np.arange(b)
            self._obs_rows = rows
        row = int(rows[0 if kind == "range" else 1, q])
        return None if row < 0 else row

    def _obs_half(self, q: int, kind: str) -> float | None:
        row = self._obs_row(q, kind)
        return None if row is None else float(half_width(self.check_lo[row], self.check_hi[row]))

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
            both = st.child < self.n_poses and known[st.parent] and known[st.child]
            ok[list(st.params)] = both
        return ok

    def _obs_mid(self, q: int, kind: str) -> float | None:
        row = self._obs_row(q, kind)
        return None if row is None else float(self.check_mid[row])
