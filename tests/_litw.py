"""A small recording in the layout of Lost in the Woods' ``dataset2.mat``, written by the
tests themselves so that the importer and the calibration run on every machine."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import scipy.io

from _exact import angle_inside, mpf

LASER = 0.219


def write_synthetic(
    path: Path, n: int = 120, gap: tuple[int, int] = (40, 60), seed: int = 0
) -> None:
    """A small recording in the dataset's layout: a robot driving arcs among 5 posts at
    10 Hz, the wheels along the heading + DRIVE_OFFSET, speed and turn rate constant over
    each sample (so the arcs are exact), odometry and laser readings with small noise, and
    a Vicon gap over the samples ``gap``."""
    rng = np.random.default_rng(seed)
    drive = -0.079
    t = np.arange(n) * 0.1
    v = 0.3 + 0.1 * np.sin(t)
    om = 0.4 * np.cos(0.5 * t)
    x, y, th = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(n - 1):
        a, b = th[k] + drive, th[k] + drive + om[k] * 0.1
        x[k + 1] = x[k] + v[k] / om[k] * (math.sin(b) - math.sin(a))
        y[k + 1] = y[k] - v[k] / om[k] * (math.cos(b) - math.cos(a))
        th[k + 1] = th[k] + om[k] * 0.1
    posts = np.array([[1.0, 2.0], [3.0, -1.0], [-2.0, 1.5], [2.5, 3.0], [0.5, -2.5]])
    r, b = np.zeros((n, len(posts))), np.zeros((n, len(posts)))
    for k in range(n):
        sx, sy = x[k] + LASER * math.cos(th[k]), y[k] + LASER * math.sin(th[k])
        for j, (px, py) in enumerate(posts):
            rho = math.hypot(px - sx, py - sy)
            beta = math.remainder(math.atan2(py - sy, px - sx) - th[k], 2 * math.pi)
            if rho < 4.0 and abs(beta) < 1.5:
                r[k, j] = rho + rng.uniform(-0.05, 0.05)
                b[k, j] = beta + rng.uniform(-0.05, 0.05)
    valid = np.ones(n)
    valid[gap[0] : gap[1]] = 0
    scipy.io.savemat(
        path,
        {
            "t": t[:, None], "v": (v + rng.uniform(-0.02, 0.02, n))[:, None],
            "om": (om + rng.uniform(-0.02, 0.02, n))[:, None], "r": r, "b": b, "l": posts,
            "x_true": x[:, None], "y_true": y[:, None],
            "th_true": np.remainder(th + math.pi, 2 * math.pi)[:, None] - math.pi,
            "true_valid": valid[:, None], "d": np.array([[LASER]]),
            "r_var": np.array([[1e-3]]), "b_var": np.array([[1e-3]]),
            "v_var": np.array([[1e-4]]), "om_var": np.array([[1e-4]]),
        },
    )  # fmt: skip


def moves_hold_the_truth(log, truth) -> int:
    """Assert every move between two consecutive poses with truth holds it (x and y in the
    first pose's frame, the heading change modulo 2 pi, compared exactly); return how many
    were checked."""
    moves = {(m.source, m.target): m for m in log.relative_poses}
    checked = 0
    for a, b in zip(truth.pose_ids, truth.pose_ids[1:], strict=False):
        if (a, b) not in moves:
            continue
        m, pa, pb = moves[a, b], truth.pose_xyt(a), truth.pose_xyt(b)
        c, s = math.cos(pa[2]), math.sin(pa[2])
        dx, dy = pb[0] - pa[0], pb[1] - pa[1]
        assert m.dx[0] <= c * dx + s * dy <= m.dx[1], (a, m)
        assert m.dy[0] <= -s * dx + c * dy <= m.dy[1], (a, m)
        assert angle_inside(*m.dtheta, mpf(pb[2] - pa[2])), (a, m)
        checked += 1
    return checked
