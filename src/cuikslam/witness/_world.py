"""The world form of a hypothesis: every frame and landmark a parameter, every motion a check.

:class:`~.model.HypothesisModel` parametrises a world by its motions (forward kinematics
along the tree), so every pose depends on every step before it: its Jacobian is dense,
and one evaluation on a 200-pose log costs ``checks x parameters`` (0.05 s of CPU).
Here the parameters are the frames ``(x, y, theta)`` (robot poses, then sensor poses)
and the landmarks ``(x, y)``, and each tree step becomes checks between its two frames,
like a loop-closing record of its kind:

* an odometry step from ``src`` to ``dst``: the turn ``theta_dst - theta_src`` and the
  distance ``(p_dst - p_src) . u(theta_dst)`` in the step's intervals, and the equality
  ``(p_dst - p_src) x u(theta_dst) = 0`` (the robot moves along its new heading);
* a relative step (a ``relative_pose`` record or a sensor's offset): the pose of ``dst``
  in the frame of ``src`` in its three intervals.

Every row depends on two frames, or on a frame and one or two landmarks, so the Jacobian
is sparse and an evaluation costs in proportion to its rows (4 ms of CPU at 200 poses,
15 ms at 1,000, with the factorisation of the normal equations). The witness search
minimises the same hinge residuals in this form (:meth:`WorldForm.residuals`, with the
equalities weighed heavily); :meth:`WorldForm.to_params` maps its point back to the
model's parameters (each step's parameters read off its two frames; the equality's
residue is dropped, so the model's forward kinematics moves the later frames by as
much), and only :mod:`.verify`, on the model, decides.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from cuikslam.budget import COSTS
from cuikslam.witness._levenberg import fill_reducing_order
from cuikslam.witness._numeric import finite, half_width, midpoint, wrap_near
from cuikslam.witness._sensor import SENSOR_MARGIN, distance, sensor_terms

if TYPE_CHECKING:
    from cuikslam.witness.model import HypothesisModel

__all__ = ["DENSE_COLUMNS", "EQUALITY_WEIGHT", "WorldForm"]

EQUALITY_WEIGHT = 10.0
"""The equalities' residuals are their values in tenths of a distance interval's
half-width: heavier than any check, so the least squares meet them first (the model's
forward kinematics carries their residue into every later frame)."""
DENSE_COLUMNS = 120
"""Up to this many free parameters the Jacobian is returned dense (Cholesky of dense
normal equations costs less than building and factorising sparse matrices)."""
VERIFY_OPERATIONS_PER_FRAME = 40
"""Interval operations counted for one frame's step in the verification's forward
kinematics (about ten operations on single intervals, each called from Python: 20 us a
frame measured on the whole Lost in the Woods run)."""
UNITS_PER_RECORD = 5.0
"""Work units of building a hypothesis' model and world form, per observation and frame;
and of a start's parameters (the model's kinematics, step by step), per frame: Python
loops over the log (0.6 s for the 61,086 readings and 13,795 frames of the whole Lost in
the Woods run)."""


class _Rows:
    """Blocks of rows as they are evaluated: values, and the Jacobian's entries (the
    pattern of rows and columns is recorded once: it depends on the model only)."""

    def __init__(self, jacobian: bool, record: bool) -> None:
        self.jacobian, self.record = jacobian, record
        self.values: list[np.ndarray] = []
        self.derivatives: list[np.ndarray] = []
        self.rows: list[np.ndarray] = []
        self.cols: list[np.ndarray] = []
        self.n = 0

    def add(self, value: np.ndarray, entries: list[tuple[np.ndarray, np.ndarray | float]]) -> None:
        size = value.size
        self.values.append(value)
        if self.jacobian:
            rows = self.n + np.arange(size) if self.record else None
            for col, d in entries:
                self.derivatives.append(d if np.ndim(d) else np.full(size, d))
                if self.record:
                    self.rows.append(rows)
                    self.cols.append(np.broadcast_to(col, (size,)))
        self.n += size


def _relative(F: np.ndarray, src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(ddx, ddy, cos, sin, rx, ry)``: the offset of ``dst`` from ``src`` in the world,
    the cosine and sine of ``src``'s heading, and the offset in ``src``'s frame."""
    ddx = F[dst, 0] - F[src, 0]
    ddy = F[dst, 1] - F[src, 1]
    c, s = np.cos(F[src, 2]), np.sin(F[src, 2])
    return ddx, ddy, c, s, c * ddx + s * ddy, -s * ddx + c * ddy


def _odometry(F: np.ndarray, src: np.ndarray, dst: np.ndarray, out: _Rows) -> None:
    """Turn and distance of odometry from ``src`` to ``dst``."""
    ddx = F[dst, 0] - F[src, 0]
    ddy = F[dst, 1] - F[src, 1]
    ct, st = np.cos(F[dst, 2]), np.sin(F[dst, 2])
    out.add(F[dst, 2] - F[src, 2], [(3 * dst + 2, 1.0), (3 * src + 2, -1.0)])
    out.add(ddx * ct + ddy * st,
            [(3 * dst, ct), (3 * dst + 1, st), (3 * src, -ct), (3 * src + 1, -st),
             (3 * dst + 2, ddy * ct - ddx * st)])  # fmt: skip


def _lateral(
    F: np.ndarray, src: np.ndarray, dst: np.ndarray, scale: np.ndarray, out: _Rows
) -> None:
    """The equality of odometry from ``src`` to ``dst``: no sideways move, over ``scale``."""
    ddx = F[dst, 0] - F[src, 0]
    ddy = F[dst, 1] - F[src, 1]
    ct, st = np.cos(F[dst, 2]) / scale, np.sin(F[dst, 2]) / scale
    out.add(ddx * st - ddy * ct,
            [(3 * dst, st), (3 * dst + 1, -ct), (3 * src, -st), (3 * src + 1, ct),
             (3 * dst + 2, ddx * ct + ddy * st)])  # fmt: skip


def _relative_pose(F: np.ndarray, src: np.ndarray, dst: np.ndarray, out: _Rows) -> None:
    """``dx``, ``dy``, ``dtheta`` of the pose of ``dst`` in the frame of ``src``."""
    _, _, c, s, rx, ry = _relative(F, src, dst)
    out.add(rx, [(3 * dst, c), (3 * dst + 1, s), (3 * src, -c), (3 * src + 1, -s),
                 (3 * src + 2, ry)])  # fmt: skip
    out.add(ry, [(3 * dst, -s), (3 * dst + 1, c), (3 * src, s), (3 * src + 1, -c),
                 (3 * src + 2, -rx)])  # fmt: skip
    out.add(F[dst, 2] - F[src, 2], [(3 * dst + 2, 1.0), (3 * src + 2, -1.0)])


def _ends(steps: list) -> tuple[np.ndarray, np.ndarray]:
    """The frames each step runs from and to, in its record's direction."""
    src = [st.parent if st.forward else st.child for st in steps]
    dst = [st.child if st.forward else st.parent for st in steps]
    return np.array(src, dtype=np.int64), np.array(dst, dtype=np.int64)


class WorldForm:
    """The world form of ``model`` (see the module docstring).

    Variables: ``3 * n_frames`` frame coordinates, then ``2 * n_landmarks`` landmark
    coordinates; an anchor's coordinates are bounded by its parameters' intervals (fixed
    where those are degenerate), every other one is unbounded. Rows: the model's checks
    (in its order), the tree's odometry turns and distances and its relative steps'
    ``dx``, ``dy``, ``dtheta``, the equalities (the tree's odometry, then the model's
    loop closures), then the sensor's violations of the model's focused pairs.
    """

    def __init__(self, model: HypothesisModel) -> None:
        from cuikslam.witness.model import aim_margin

        m = self.model = model
        self.landmark_var0 = 3 * m.n_frames
        self.n_vars = self.landmark_var0 + 2 * m.n_landmarks
        odo = [st for st in m.steps if not st.relative]
        rel = [st for st in m.steps if st.relative]
        self.odo, self.rel = _ends(odo), _ends(rel)
        self.odo_params = np.array([st.params for st in odo], dtype=np.int64).reshape(-1, 2).T
        self.rel_params = np.array([st.params for st in rel], dtype=np.int64).reshape(-1, 3).T
        self.param_mid = midpoint(m.param_lo, m.param_hi, 0.0)
        sensor = [st for st in rel if st.child >= m.n_poses]  # each from its robot pose
        self.sensor_steps = _ends(sensor)
        self.sensor_params = np.array([st.params for st in sensor], dtype=np.int64).reshape(-1, 3).T
        step_params = np.concatenate([*self.odo_params, *self.rel_params])
        step_angular = np.repeat([True, False, False, False, True], [len(odo)] * 2 + [len(rel)] * 3)
        self.lo = np.concatenate([m.check_lo, m.param_lo[step_params]])
        self.hi = np.concatenate([m.check_hi, m.param_hi[step_params]])
        self.angular = np.concatenate([m.check_angular, step_angular])
        self.mid = midpoint(self.lo, self.hi, 0.0)
        self.margin = aim_margin(self.lo, self.hi)
        half = half_width(self.lo, self.hi)
        self.bounded = np.isfinite(half) & (half > 0)
        self.half = np.where(self.bounded, half, 1.0)
        # a step whose parameter the model holds fixed (a degenerate interval, or one a few
        # ulps wide) is an equality to its midpoint, weighed like the others: in its
        # half-width it would make the least squares ill-conditioned
        length, angle = m.sensor_scales
        self.pinned = np.concatenate([np.zeros(m.n_checks, bool), ~m.free[step_params]])
        pin_scale = np.where(self.angular, angle, length) / EQUALITY_WEIGHT
        self.half = np.where(self.pinned, pin_scale, self.half)
        self.bounded &= ~self.pinned
        # the equalities in tenths of the half-width of the distances they go with
        dist_half = half_width(m.param_lo[self.odo_params[1]], m.param_hi[self.odo_params[1]])
        ok = np.isfinite(dist_half) & (dist_half > 0)
        self.lateral_scale = np.where(ok, dist_half, length) / EQUALITY_WEIGHT
        self.closure = (m.closure_source[m.equality_rows], m.closure_target[m.equality_rows])
        self.closure_scale = np.full(len(m.equality_rows), length / EQUALITY_WEIGHT)
        self.var_lo = np.full(self.n_vars, -np.inf)
        self.var_hi = np.full(self.n_vars, np.inf)
        self.free = np.ones(self.n_vars, dtype=bool)
        for a, k in m.anchors:
            self.var_lo[3 * a : 3 * a + 3] = m.param_lo[k : k + 3]
            self.var_hi[3 * a : 3 * a + 3] = m.param_hi[k : k + 3]
            self.free[3 * a : 3 * a + 3] = m.free[k : k + 3]
        self.n_free = int(self.free.sum())
        self._column = np.cumsum(self.free) - 1
        self._pattern: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._ordering: np.ndarray | None = None
        self._set_costs(len(odo), len(rel))

    def _set_costs(self, n_odo: int, n_rel: int) -> None:
        """Work units of an evaluation and of a verification (:data:`~cuikslam.budget.COSTS`)."""
        m = self.model
        focused = len(m._sensor_rows) if m.sensor is not None else 0
        self.entries = (
            4 * len(m.range_sel) + 5 * len(m.bearing_sel) + len(m.prior_pose)
            + len(m.lprior_landmark) + 7 * len(m.closure_source) + 12 * len(m.loop_source)
            + 12 * n_odo + 12 * n_rel + 5 * len(m.equality_rows) + 7 * focused
        )  # fmt: skip
        """Entries of the Jacobian when every row is active (an odometry step: 7 for its
        turn and distance, 5 for its equality; a sensor pair: 7)."""
        pairs = m.n_poses * m.n_landmarks if m.sensor is not None else 0
        self.evaluation_cost = COSTS["world_evaluation"] + COSTS["jacobian_entry"] * (
            self.entries + pairs
        )
        """Work units of one evaluation with its least-squares step: its Jacobian's entries
        (computed, multiplied into the normal equations), and every (pose, landmark) pair,
        whose sensor violations are computed before the focused ones are kept. A sparse
        factorisation is counted apart, by its multiply-adds."""
        self.check_cost = 0.5 * COSTS["world_evaluation"] + COSTS["jacobian_entry"] * (
            m.n_checks + m.n_params + pairs
        )
        """Work units of :meth:`to_params` and :meth:`holds`: the model's forward kinematics,
        checks and sensor pairs in floating point."""
        self.build_cost = UNITS_PER_RECORD * (len(m.obs_pose) + m.n_frames)
        """Work units of building the model and this form."""
        self.start_cost = COSTS["start"] + UNITS_PER_RECORD * m.n_frames
        """Work units of a start's parameters and world (beside its landmarks' fits)."""
        self.verify_cost = COSTS["verification"] + COSTS["interval_entry"] * (
            VERIFY_OPERATIONS_PER_FRAME * m.n_frames + m.n_checks + pairs
        )
        """Work units of one rigorous verification: interval kinematics frame by frame, then
        every check and (pose, landmark) pair in interval arithmetic."""

    # ----------------------------------------------------------------- conversions
    def from_params(self, p: np.ndarray, poses_xyt: np.ndarray | None = None) -> np.ndarray:
        """The world of the model's parameters ``p`` (its forward kinematics), with the
        robot poses moved to ``poses_xyt`` (rows in the model's order) where those are
        finite, and the sensor frames with them.

        The centres of narrowed boxes are a better start than the forward kinematics of
        the parameters they give, whose error grows along the log: on the whole Lost in
        the Woods run (1,262 poses) the search from the latter was stuck 15 half-widths
        outside a bearing after 230 evaluations, while the former met every check after
        the 9 of its centre estimate."""
        m = self.model
        F, _ = m.frames(p)
        if poses_xyt is not None:
            F = F.copy()
            known = np.all(np.isfinite(poses_xyt), axis=1)
            F[: m.n_poses][known] = poses_xyt[known]
            (src, dst), (ka, kb, kc) = self.sensor_steps, self.sensor_params
            c, s = np.cos(F[src, 2]), np.sin(F[src, 2])
            F[dst, 0] = F[src, 0] + p[ka] * c - p[kb] * s
            F[dst, 1] = F[src, 1] + p[ka] * s + p[kb] * c
            F[dst, 2] = F[src, 2] + p[kc]
        return np.concatenate([F.ravel(), m.landmarks(p).ravel()])

    def to_params(self, w: np.ndarray) -> np.ndarray:
        """The model's parameters that reproduce the world ``w`` as nearly as they can:
        each step's parameters read off its two frames (angles mod 2 pi nearest their
        intervals' centres), clipped to their intervals."""
        m = self.model
        F = w[: self.landmark_var0].reshape(-1, 3)
        p = np.zeros(m.n_params)
        for a, k in m.anchors:
            p[k : k + 3] = F[a]
        (src, dst), (kt, kd) = self.odo, self.odo_params
        with np.errstate(all="ignore"):
            p[kt] = wrap_near(F[dst, 2] - F[src, 2], self.param_mid[kt])
            ddx, ddy = F[dst, 0] - F[src, 0], F[dst, 1] - F[src, 1]
            p[kd] = ddx * np.cos(F[dst, 2]) + ddy * np.sin(F[dst, 2])
            (src, dst), (ka, kb, kc) = self.rel, self.rel_params
            p[ka], p[kb] = _relative(F, src, dst)[4:]
            p[kc] = wrap_near(F[dst, 2] - F[src, 2], self.param_mid[kc])
        p[m.landmark_param0 :] = w[self.landmark_var0 :]
        return np.clip(np.where(np.isfinite(p), p, 0.0), m.param_lo, m.param_hi)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the free variables: the anchors' intervals narrowed by their aimed
        margins, the other variables unbounded."""
        from cuikslam.witness.model import aim_margin

        margin = aim_margin(self.var_lo, self.var_hi)
        lb = np.where(np.isfinite(self.var_lo), self.var_lo + margin, -np.inf)
        ub = np.where(np.isfinite(self.var_hi), self.var_hi - margin, np.inf)
        return lb[self.free], ub[self.free]

    def holds(self, p: np.ndarray) -> bool:
        """Whether every check and the sensor's negative information hold at the model's
        parameters ``p`` in floating point: a filter before the rigorous verification.
        The sensor's violations are measured with ``SENSOR_MARGIN`` of clearance, so
        those below half of it are taken to hold."""
        m = self.model
        r = m.margin_residuals(p, False, 0.0)[0]
        n, e = m.n_checks, len(m.equality_rows)
        slack = 0.5 * SENSOR_MARGIN / max(m.sensor_scales)
        return not (np.any(r[:n] > 0) or np.any(r[n + e :] > slack))

    # ----------------------------------------------------------------- evaluation
    @np.errstate(all="ignore")  # overflow is clipped (see _numeric.finite)
    def _values(self, w: np.ndarray, jacobian: bool) -> tuple[np.ndarray, int, _Rows]:
        """Every check's value (angles nearest their intervals' centres), then the
        equalities; the number of checks; the rows' Jacobian entries."""
        m = self.model
        F = w[: self.landmark_var0].reshape(-1, 3)
        L = w[self.landmark_var0 :].reshape(-1, 2)
        out = _Rows(jacobian, record=jacobian and self._pattern is None)
        i, j = m.obs_pose, m.obs_landmark
        dx = L[j, 0] - F[i, 0]
        dy = L[j, 1] - F[i, 1]
        r, r_safe, r2 = distance(dx, dy)
        fi, lj = 3 * i, self.landmark_var0 + 2 * j
        s = m.range_sel
        cx, cy = dx[s] / r_safe[s], dy[s] / r_safe[s]
        out.add(r[s], [(fi[s], -cx), (fi[s] + 1, -cy), (lj[s], cx), (lj[s] + 1, cy)])
        s = m.bearing_sel
        bx, by = dx[s] / r2[s], dy[s] / r2[s]
        out.add(np.arctan2(dy[s], dx[s]) - F[i[s], 2],
                [(fi[s], by), (fi[s] + 1, -bx), (fi[s] + 2, -1.0), (lj[s], -by),
                 (lj[s] + 1, bx)])  # fmt: skip
        out.add(F[m.prior_pose, m.prior_coord], [(3 * m.prior_pose + m.prior_coord, 1.0)])
        k = self.landmark_var0 + 2 * m.lprior_landmark + m.lprior_coord
        out.add(L[m.lprior_landmark, m.lprior_coord], [(k, 1.0)])
        _odometry(F, m.closure_source, m.closure_target, out)
        _relative_pose(F, m.loop_source, m.loop_target, out)
        _odometry(F, *self.odo, out)
        _relative_pose(F, *self.rel, out)
        n_checks = out.n
        _lateral(F, *self.odo, self.lateral_scale, out)
        _lateral(F, *self.closure, self.closure_scale, out)
        v = np.concatenate(out.values)
        ang = self.angular
        v[:n_checks][ang] = wrap_near(v[:n_checks][ang], self.mid[ang])
        if out.record:
            rows, cols = np.concatenate(out.rows), np.concatenate(out.cols)
            keep = self.free[cols]
            self._pattern = (keep, rows[keep], self._column[cols[keep]])
        return v, n_checks, out

    def residuals(
        self, w: np.ndarray, jacobian: bool = True, scale_margin: float | None = 1.0
    ) -> tuple[np.ndarray, np.ndarray | sp.csr_matrix | None]:
        """Residuals at the world point ``w``: each check's hinge at ``scale_margin``
        times its aimed margin, in half-widths (None: its smooth distance from its
        interval's centre), the weighed equalities, the sensor's violations; and the
        Jacobian of the free variables (dense up to ``DENSE_COLUMNS`` of them, else CSR)."""
        v, n_checks, out = self._values(w, jacobian)
        vc = v[:n_checks]
        lo, hi, half = self.lo, self.hi, self.half
        with np.errstate(over="ignore", invalid="ignore"):
            if scale_margin is None:
                centred = self.bounded | self.pinned
                res = np.where(centred, (vc - self.mid) / half, 0.0)
                slope = centred / half
            else:
                margin = self.margin * scale_margin
                below = np.where(np.isfinite(lo), (lo + margin - vc) / half, -np.inf)
                above = np.where(np.isfinite(hi), (vc - (hi - margin)) / half, -np.inf)
                res = np.maximum(below, 0.0) + np.maximum(above, 0.0)
                slope = (np.where(above > 0, 1.0, 0.0) - np.where(below > 0, 1.0, 0.0)) / half
                pinned = self.pinned
                res[pinned] = (vc[pinned] - self.mid[pinned]) / half[pinned]
                slope[pinned] = 1.0 / half[pinned]
        sr, sensor = self._sensor(w, jacobian)
        r = finite(np.concatenate([res, v[n_checks:], sr]))
        if not jacobian:
            return r, None
        assert self._pattern is not None
        keep, rows, cols = self._pattern
        row_slope = np.concatenate([slope, np.ones(v.size - n_checks)])
        vals = np.concatenate(out.derivatives)[keep] * row_slope[rows]
        if sensor is not None:
            s_rows, s_cols, s_vals = sensor
            s_keep = self.free[s_cols]
            rows = np.concatenate([rows, s_rows[s_keep] + v.size])
            cols = np.concatenate([cols, self._column[s_cols[s_keep]]])
            vals = np.concatenate([vals, s_vals[s_keep]])
        vals = finite(vals, nan=0.0)
        shape = (r.size, self.n_free)
        if self.n_free <= DENSE_COLUMNS:
            flat = rows * self.n_free + cols
            return r, np.bincount(flat, weights=vals, minlength=r.size * self.n_free).reshape(shape)
        J = sp.csr_matrix((vals, (rows, cols)), shape=shape)
        J.eliminate_zeros()  # the rows of hinges met: fewer entries in the normal equations
        return r, J

    def ordering(self) -> tuple[np.ndarray | None, float]:
        """The order in which the least squares' factorisations eliminate the free
        variables (None when the Jacobian is dense), computed on first use from the
        pattern of every row, and the work units of computing it (0 once known)."""
        if self.n_free <= DENSE_COLUMNS:
            return None, 0.0
        if self._ordering is not None:
            return self._ordering, 0.0
        if self._pattern is None:
            self._values(np.zeros(self.n_vars), jacobian=True)
        assert self._pattern is not None
        _, rows, cols = self._pattern
        m = self.model
        pairs = m._sensor_rows if m.sensor is not None and m.n_landmarks else np.zeros(0, int)
        pose, landmark = np.divmod(pairs, max(m.n_landmarks, 1))
        k = rows.max(initial=-1) + 1 + np.arange(len(pairs))
        s_cols = np.concatenate([3 * pose[:, None] + np.arange(3),
                                 self.landmark_var0 + 2 * landmark[:, None] + np.arange(2)],
                                axis=1)  # fmt: skip
        s_keep = self.free[s_cols]
        rows = np.concatenate([rows, np.repeat(k, 5).reshape(-1, 5)[s_keep]])
        cols = np.concatenate([cols, self._column[s_cols[s_keep]]])
        jp = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(rows.max() + 1, self.n_free))
        self._ordering, work = fill_reducing_order(jp.T @ jp)
        return self._ordering, self.evaluation_cost + COSTS["factor_flop"] * work

    def _sensor(
        self, w: np.ndarray, jacobian: bool
    ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
        """The sensor's violations of the model's focused pairs, and their Jacobian's
        entries (rows from 0, columns of all variables, values) where violated."""
        m = self.model
        n = m.n_poses
        if m.sensor is None or n == 0 or m.n_landmarks == 0:
            return np.zeros(0), None
        F = w[: self.landmark_var0].reshape(-1, 3)[:n]
        L = w[self.landmark_var0 :].reshape(-1, 2)
        t = sensor_terms(m.sensor, m.observed, m._sensor_rows, F, L, jacobian, m.sensor_scales)
        if not jacobian or t.active.size == 0:
            return t.residuals, None
        k, lv = t.active, self.landmark_var0
        rows = np.concatenate([np.repeat(k, 3), np.repeat(k, 2), np.repeat(k, 2)])
        cols = np.concatenate([
            (3 * t.pose[:, None] + np.arange(3)).ravel(),
            (lv + 2 * t.landmark[:, None] + np.arange(2)).ravel(),
            (lv + 2 * t.nearest[:, None] + np.arange(2)).ravel(),
        ])  # fmt: skip
        vals = np.concatenate([t.d_pose.ravel(), t.d_landmark.ravel(), t.d_nearest.ravel()])
        return t.residuals, (rows, cols, vals)
