"""The sensor's negative information as floating-point violations, with their derivatives.

At every pose the observed landmarks must be exactly those the sensor is sure to see (see
:mod:`.model`). :func:`sensor_terms` measures, for chosen (pose, landmark) pairs, how far
each pair is from meeting its clause with ``SENSOR_MARGIN`` clearance, and the derivatives
of the violated ones with respect to the pose ``(x, y, theta)``, the landmark ``(x, y)``
and the pose's nearest visible landmark (the ``nearest_margin`` clause), in world
coordinates: :class:`~.model.HypothesisModel` chains them through the poses' Jacobians
(forward kinematics) into the Jacobian of its parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuikslam.interval.angles import out_of_view_arc
from cuikslam.log.records import SensorModel
from cuikslam.witness._numeric import BIG, wrap_near

SENSOR_MARGIN = 1e-6
"""Aimed clearance (m, rad) from the sensor's visibility thresholds."""


def distance(dx: np.ndarray, dy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(r, r_safe, r2_safe)``: ``r = hypot(dx, dy)`` (no under- or overflow), then ``r``
    and its square made positive and finite (for the Jacobians' ``dx / r`` and
    ``dy / r**2``; where ``r`` is 0 the Jacobian is meaningless anyway)."""
    r = np.hypot(dx, dy)
    r_safe = np.where(r > 0, r, 1e-300)
    with np.errstate(over="ignore", under="ignore"):
        r2 = r * r
    r2 = np.where((r2 > 0) & np.isfinite(r2), r2, np.where(r > 1.0, BIG, 1e-300))
    return r, r_safe, r2


@dataclass
class SensorTerms:
    """Violations of the kept pairs, and the derivatives of the violated ones."""

    residuals: np.ndarray
    """One violation (>= 0) per kept pair, in the kept pairs' order."""
    active: np.ndarray
    """Positions (in ``residuals``) of the violated pairs; the derivatives below are theirs."""
    pose: np.ndarray
    landmark: np.ndarray
    nearest: np.ndarray
    """Pose, landmark and nearest visible landmark of each violated pair."""
    d_pose: np.ndarray
    """(k, 3): derivative with respect to the pose's ``(x, y, theta)``."""
    d_landmark: np.ndarray
    """(k, 2): with respect to the landmark's ``(x, y)``."""
    d_nearest: np.ndarray
    """(k, 2): with respect to the nearest visible landmark's ``(x, y)`` (0 without a
    ``nearest_margin`` clause)."""


@np.errstate(all="ignore")  # overflow is clipped by the callers (see _numeric.finite)
def sensor_terms(
    sensor: SensorModel,
    observed: np.ndarray,
    kept: np.ndarray,
    P: np.ndarray,
    L: np.ndarray,
    jacobian: bool,
    scales: tuple[float, float] = (1.0, 1.0),
) -> SensorTerms:
    """The sensor violations of the pairs ``kept`` (flat indices ``pose * m + landmark``)
    for poses ``P`` (n, 3) and landmarks ``L`` (m, 2), ``observed`` (n, m) saying which
    pairs are observed; derivatives only when ``jacobian``. Distance violations are
    divided by ``scales[0]``, angle violations by ``scales[1]`` (the optimisers weigh them
    against checks measured in half-widths)."""
    length, angle = scales
    n, m = observed.shape
    dx = L[None, :, 0] - P[:, None, 0]
    dy = L[None, :, 1] - P[:, None, 1]
    d, d_safe, r2 = distance(dx, dy)
    beta = wrap_near(np.arctan2(dy, dx) - P[:, None, 2], 0.0)  # in [-pi, pi)
    delta = SENSOR_MARGIN
    inf = np.full((n, m), np.inf)
    all_round = out_of_view_arc(sensor.fov) is None
    half = sensor.fov / 2.0
    # violations (> 0: violated) of "in view" and "out of view" clauses, with their kinds
    in_range = (d - (sensor.max_range - delta)) / length
    out_range = (
        ((sensor.max_range + delta) - d) / length if math.isfinite(sensor.max_range) else inf
    )
    in_fov = -inf if all_round else (np.abs(beta) - (half - delta)) / angle
    out_fov = inf if all_round else ((half + delta) - np.abs(beta)) / angle
    visible = (d <= sensor.max_range) & (all_round | (np.abs(beta) <= half))
    if sensor.nearest_margin is not None:
        dv = np.where(visible, d, np.inf)
        nearest_j = np.argmin(dv, axis=1)
        nearest = dv[np.arange(n), nearest_j]
        limit = nearest[:, None] + sensor.nearest_margin
        in_near = np.where(np.isfinite(limit), (d - (limit - delta)) / length, -np.inf)
        out_near = np.where(np.isfinite(limit), ((limit + delta) - d) / length, np.inf)
    else:
        nearest_j = np.zeros(n, dtype=np.int64)
        in_near = -inf
        out_near = inf
    pos = lambda a: np.maximum(a, 0.0)  # noqa: E731
    seen_res = pos(in_range) + pos(in_fov) + pos(in_near)
    unseen_stack = np.stack([out_range, out_fov, out_near])
    unseen_kind = np.argmin(unseen_stack, axis=0)
    unseen_res = pos(np.min(unseen_stack, axis=0))
    res = np.where(observed, seen_res, unseen_res)
    res = np.where(np.isfinite(res), res, 0.0).ravel()[kept]
    where = np.flatnonzero(res > 0) if jacobian else np.zeros(0, dtype=np.int64)
    i, j = np.divmod(kept[where], m)
    k = len(where)
    if k == 0:
        z = np.zeros(0, dtype=np.int64)
        return SensorTerms(
            res, where, z, z, z, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2))
        )
    u, v, s_ = dx[i, j], dy[i, j], d_safe[i, j]
    q = r2[i, j]
    # d(distance), d(bearing), d(|bearing|), d(distance - nearest distance): pose, landmark
    dd_pose = np.stack([-u / s_, -v / s_, np.zeros(k)], axis=1) / length
    dd_land = np.stack([u / s_, v / s_], axis=1) / length
    db_pose = np.stack([v / q, -u / q, -np.ones(k)], axis=1) / angle
    db_land = np.stack([-v / q, u / q], axis=1) / angle
    sign = np.sign(beta[i, j])[:, None]
    jn = nearest_j[i]
    un, vn, sn = dx[i, jn], dy[i, jn], d_safe[i, jn]
    dn_pose = dd_pose - np.stack([-un / sn, -vn / sn, np.zeros(k)], axis=1) / length
    dn_near = -np.stack([un / sn, vn / sn], axis=1) / length
    obs = observed[i, j][:, None]
    kind = unseen_kind[i, j][:, None]
    w_range = np.where(obs, 1.0 * (in_range[i, j] > 0)[:, None], -1.0 * (kind == 0))
    w_fov = np.where(obs, 1.0 * (in_fov[i, j] > 0)[:, None], -1.0 * (kind == 1))
    w_near = np.where(obs, 1.0 * (in_near[i, j] > 0)[:, None], -1.0 * (kind == 2))
    d_pose = w_range * dd_pose + w_fov * sign * db_pose + w_near * dn_pose
    d_land = w_range * dd_land + w_fov * sign * db_land + w_near * dd_land
    d_near = w_near * dn_near
    return SensorTerms(res, where, i, j, jn, d_pose, d_land, d_near)
