"""Compiled interval tests used by the hypothesis search.

All are one-sided and sound: ``gate`` says False only when a correspondence is
impossible, and ``within_reach`` says False only when an UNSEEN constraint between a pose
and a landmark holds for every value in their boxes (so it need not be added).
"""

from __future__ import annotations

import numpy as np

from cuikslam._jit import jit
from cuikslam.interval._arith import add, mul, sqr
from cuikslam.interval._periodic import cos, sin
from cuikslam.interval._rounding import sqrt_down, sub_down


@jit
def gate(
    lo: np.ndarray, hi: np.ndarray, pose_x: int, landmark_x: int, bearing: int, distance: int
) -> bool:
    """Can the landmark (x at ``landmark_x``) be where the observation puts it from the pose box?

    Evaluates pose + range (cos(theta + bearing), sin(theta + bearing)) over the boxes and
    tests whether it meets the landmark's box.
    """
    tlo, thi = add(lo[pose_x + 2], hi[pose_x + 2], lo[bearing], hi[bearing])
    clo, chi = cos(tlo, thi)
    slo, shi = sin(tlo, thi)
    rlo, rhi = max(lo[distance], 0.0), hi[distance]
    dxlo, dxhi = mul(rlo, rhi, clo, chi)
    dylo, dyhi = mul(rlo, rhi, slo, shi)
    pxlo, pxhi = add(lo[pose_x], hi[pose_x], dxlo, dxhi)
    pylo, pyhi = add(lo[pose_x + 1], hi[pose_x + 1], dylo, dyhi)
    return (
        pxlo <= hi[landmark_x]
        and lo[landmark_x] <= pxhi
        and pylo <= hi[landmark_x + 1]
        and lo[landmark_x + 1] <= pyhi
    )


@jit
def gate_many(
    lo: np.ndarray,
    hi: np.ndarray,
    pose_x: int,
    landmark_xs: np.ndarray,
    bearing: int,
    distance: int,
) -> np.ndarray:
    """:func:`gate` for each landmark of ``landmark_xs``: one call per branch, not per pair."""
    out = np.empty(landmark_xs.shape[0], dtype=np.bool_)
    for k in range(landmark_xs.shape[0]):
        out[k] = gate(lo, hi, pose_x, landmark_xs[k], bearing, distance)
    return out


@jit
def _gap(alo: float, ahi: float, blo: float, bhi: float) -> float:
    """A lower bound of the distance between two intervals (0 when they meet)."""
    if bhi < alo:
        return max(0.0, sub_down(alo, bhi))
    if ahi < blo:
        return max(0.0, sub_down(blo, ahi))
    return 0.0


@jit
def within_reach(
    lo: np.ndarray, hi: np.ndarray, pose_x: int, landmark_x: int, radius: float
) -> bool:
    """False when the landmark's box is at least ``radius`` from the pose's box everywhere."""
    gx = _gap(lo[pose_x], hi[pose_x], lo[landmark_x], hi[landmark_x])
    gy = _gap(lo[pose_x + 1], hi[pose_x + 1], lo[landmark_x + 1], hi[landmark_x + 1])
    gx2, _ = sqr(gx, gx)
    gy2, _ = sqr(gy, gy)
    d2, _ = add(gx2, gx2, gy2, gy2)
    return sqrt_down(d2) < radius


@jit
def pairs_within_reach(
    lo: np.ndarray,
    hi: np.ndarray,
    pose_xs: np.ndarray,
    radii: np.ndarray,
    landmark_xs: np.ndarray,
    seen: np.ndarray,
) -> np.ndarray:
    """The (pose index, landmark index) pairs, not ``seen``, whose boxes are within reach."""
    out = np.empty((pose_xs.shape[0] * landmark_xs.shape[0], 2), dtype=np.int64)
    n = 0
    for i in range(pose_xs.shape[0]):
        for j in range(landmark_xs.shape[0]):
            if seen[i, j]:
                continue
            if within_reach(lo, hi, pose_xs[i], landmark_xs[j], radii[i]):
                out[n, 0] = i
                out[n, 1] = j
                n += 1
    return out[:n]
