"""Sound composition of motion: many high-rate steps become one keyframe relative pose.

A robot's wheel odometry arrives at 10-100 Hz; a graph with one pose per sample is large
and slow. These functions enclose the motion between two keyframes in one relative pose
(``dx``, ``dy``, ``dtheta`` in the frame of the first keyframe, each an interval; the
``relative_pose`` record of ``docs/log-format.md``). It is interval composition with
outward rounding (the kernel of :mod:`cuikslam.interval`), not a midpoint: whenever each
step's speed and turn rate lie in their intervals, the true relative pose lies in the
result.

The step model of :func:`compose_steps` assumes only that, during step k, the forward
speed stays in ``v[k]`` and the turn rate in ``omega[k]`` at every instant (they may vary
inside the step), and that the robot drives along its heading plus ``drive_angle`` (a
wheel frame that is not the frame of the pose, e.g. a tracker mounted askew). Then the
heading change of the step is in ``omega[k] · dt`` and its displacement, an integral of
``v (cos, sin)(heading + drive_angle)``, lies in ``dt · v[k] · (cos, sin)`` of the hull of
the headings it passed through (the mean value of an integral lies in the convex hull of
the integrand's values).

Keyframe spacing trades time for width: n samples per keyframe divide the graph's poses
(and the solver's time, which grows with them) by n, while the keyframe's heading width
grows linearly in n and its position width quadratically (the heading error is carried
along each later step), so the composed interval is wider than chaining the n steps in
the graph only by what the graph's observations between the keyframes would have cut.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from cuikslam._jit import jit
from cuikslam.interval._arith import add, mul, sub
from cuikslam.interval._periodic import cos, sin
from cuikslam.log.records import Bounds

__all__ = ["compose_relative", "compose_steps"]

RelativeBounds = tuple[Bounds, Bounds, Bounds]
"""``(dx, dy, dtheta)`` intervals: a pose in the frame of another one."""


@jit
def _compose_steps(
    vlo: np.ndarray,
    vhi: np.ndarray,
    wlo: np.ndarray,
    whi: np.ndarray,
    tlo: np.ndarray,
    thi: np.ndarray,
    alo: float,
    ahi: float,
) -> tuple[float, float, float, float, float, float]:
    xlo, xhi, ylo, yhi, hlo, hhi = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(vlo.shape[0]):
        dtlo, dthi = sub(tlo[k + 1], thi[k + 1], tlo[k], thi[k])
        dtlo = max(dtlo, 0.0)
        turnlo, turnhi = mul(wlo[k], whi[k], dtlo, dthi)
        # headings passed through during the step, relative to its start: hull(0, omega t)
        plo, phi = add(hlo, hhi, min(turnlo, 0.0), max(turnhi, 0.0))
        plo, phi = add(plo, phi, alo, ahi)
        clo, chi = cos(plo, phi)
        slo, shi = sin(plo, phi)
        dlo, dhi = mul(vlo[k], vhi[k], dtlo, dthi)
        qlo, qhi = mul(dlo, dhi, clo, chi)
        xlo, xhi = add(xlo, xhi, qlo, qhi)
        qlo, qhi = mul(dlo, dhi, slo, shi)
        ylo, yhi = add(ylo, yhi, qlo, qhi)
        hlo, hhi = add(hlo, hhi, turnlo, turnhi)
    return xlo, xhi, ylo, yhi, hlo, hhi


def _bounds_array(values: np.typing.ArrayLike, n: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(values, dtype=np.float64)
    if a.shape != (n, 2):
        raise ValueError(f"{name} must have shape ({n}, 2) (one [lo, hi] per step), got {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a[:, 0] > a[:, 1]):
        raise ValueError(f"{name} must hold finite intervals with lo <= hi")
    return np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(a[:, 1])


def compose_steps(
    v: np.typing.ArrayLike,
    omega: np.typing.ArrayLike,
    times: np.typing.ArrayLike,
    drive_angle: Bounds = (0.0, 0.0),
) -> RelativeBounds:
    """Enclose n high-rate steps in one relative pose from the pose at ``times[0]``.

    Parameters
    ----------
    v, omega : array_like, shape (n, 2)
        Per step, an interval holding the forward speed (m/s, negative backwards) and the
        turn rate (rad/s, counter-clockwise) at every instant of the step.
    times : array_like, shape (n + 1,) or (n + 1, 2)
        Time stamps of the step boundaries (s), exact or as intervals.
    drive_angle : (float, float)
        Interval of the angle from the pose's heading to the direction the wheels drive.

    Returns
    -------
    ((float, float), (float, float), (float, float))
        ``(dx, dy, dtheta)``: the pose at ``times[n]`` in the frame of the pose at
        ``times[0]``, rounded outward.
    """
    t = np.asarray(times, dtype=np.float64)
    n = t.shape[0] - 1
    if n < 0:
        raise ValueError("times needs at least one time stamp")
    t = np.stack([t, t], axis=-1) if t.ndim == 1 else t
    tlo, thi = _bounds_array(t, n + 1, "times")
    vlo, vhi = _bounds_array(v, n, "v")
    wlo, whi = _bounds_array(omega, n, "omega")
    a_lo, a_hi = float(drive_angle[0]), float(drive_angle[1])
    if not (math.isfinite(a_lo) and math.isfinite(a_hi) and a_lo <= a_hi):
        raise ValueError("drive_angle must be a finite interval with lo <= hi")
    xlo, xhi, ylo, yhi, hlo, hhi = _compose_steps(vlo, vhi, wlo, whi, tlo, thi, a_lo, a_hi)
    return (xlo, xhi), (ylo, yhi), (hlo, hhi)


@jit
def _compose_two(
    ax: Bounds, ay: Bounds, at: Bounds, bx: Bounds, by: Bounds, bt: Bounds
) -> tuple[float, float, float, float, float, float]:
    clo, chi = cos(at[0], at[1])
    slo, shi = sin(at[0], at[1])
    plo, phi = mul(bx[0], bx[1], clo, chi)
    qlo, qhi = mul(by[0], by[1], slo, shi)
    xlo, xhi = sub(plo, phi, qlo, qhi)
    xlo, xhi = add(ax[0], ax[1], xlo, xhi)
    plo, phi = mul(bx[0], bx[1], slo, shi)
    qlo, qhi = mul(by[0], by[1], clo, chi)
    ylo, yhi = add(plo, phi, qlo, qhi)
    ylo, yhi = add(ay[0], ay[1], ylo, yhi)
    tlo, thi = add(at[0], at[1], bt[0], bt[1])
    return xlo, xhi, ylo, yhi, tlo, thi


def compose_relative(moves: Sequence[RelativeBounds]) -> RelativeBounds:
    """Compose relative poses A ⊕ B ⊕ ...: each is in the frame of the pose the previous
    one reaches. Returns the last pose in the frame of the first, rounded outward.

    Each move is rotated by the interval of the heading accumulated before it and added;
    the correlation between the moves' terms is not kept, so for the steps of a velocity
    log :func:`compose_steps` (which carries headings, not boxes) is as tight or tighter.
    """
    x, y, t = (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)
    for dx, dy, dt in moves:
        for name, b in (("dx", dx), ("dy", dy), ("dtheta", dt)):
            if not (math.isfinite(b[0]) and math.isfinite(b[1]) and b[0] <= b[1]):
                raise ValueError(f"{name} must be a finite interval with lo <= hi, got {b}")
        xlo, xhi, ylo, yhi, tlo, thi = _compose_two(
            x, y, t, (float(dx[0]), float(dx[1])), (float(dy[0]), float(dy[1])),
            (float(dt[0]), float(dt[1])),
        )  # fmt: skip
        x, y, t = (xlo, xhi), (ylo, yhi), (tlo, thi)
    return x, y, t
