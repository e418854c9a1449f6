"""Importer for the UTIAS "Lost in the Woods" dataset (``dataset2.mat``).

A wheeled robot drives among 17 identical posts and measures them with a laser
rangefinder; Vicon gives the true robot poses and post positions.  The importer turns a
window of the recording into a cuikslam :class:`~cuikslam.log.records.Log` and its
:class:`~cuikslam.simulate.truth.GroundTruth`.

Modelling choices (each one keeps the Vicon truth inside every interval):

* **Odometry.**  ``stride`` wheel-odometry samples (10 Hz) are merged into one step with
  turn ``T = Σ ω·dt`` and signed distance ``D = Σ v·dt``.  The robot turns *while* it
  drives, so its chord does not point along its final heading, which a single
  turn-then-drive record would require.  Each merged step therefore becomes two records
  through an auxiliary pose: pose ``2i`` → ``2i+1`` turns by about ``T/2 + drive_offset``
  (plus π when driving backwards) and drives ``|D|`` along the chord; pose ``2i+1`` →
  ``2i+2`` turns the rest (about ``T/2 − drive_offset``) and drives 0.  ``drive_offset``
  is the measured angle between the Vicon heading and the direction the wheels drive
  (about −0.079 rad in this dataset).  Both turns get ± ``turn_bound`` and the distance
  ± ``distance_bound``.  The true auxiliary pose is the next Vicon position with the
  chord direction as heading.
* **Observations.**  The rangefinder sits ``d`` ahead of the robot centre.  Each reading
  ``[r ± range_bound] × [b ± bearing_bound]`` is converted to the exact range/bearing
  box of the post as seen from the robot centre (the conversion is monotone on the box
  when ``r > d``, so the corners give the hull), widened by 1e-9 for rounding.
* **Prior.**  The first kept pose gets a ±1 cm, ±0.01 rad box around its Vicon pose.
  No :class:`~cuikslam.log.records.SensorModel` is written: the sensor misses posts.
"""

from __future__ import annotations

import math
import os

import numpy as np

from cuikslam.log.errors import LogFormatError
from cuikslam.log.records import Bounds, Log, Observation, Odometry, PosePrior
from cuikslam.simulate.truth import GroundTruth

__all__ = ["read_lost_in_the_woods"]

_VARIABLES = ("t", "v", "om", "r", "b", "l", "x_true", "y_true", "th_true", "true_valid", "d")
_EPS = 1e-9
DRIVE_OFFSET = -0.079
"""Angle [rad] from the Vicon heading to the direction the wheels drive (measured)."""


def read_lost_in_the_woods(
    path: str | os.PathLike[str],
    *,
    start: int = 2770,
    steps: int = 450,
    stride: int = 10,
    unknown: bool = True,
    odometry_bound: tuple[float, float] = (0.12, 0.06),
    range_bound: float = 0.20,
    bearing_bound: float = 0.15,
    drive_offset: float = DRIVE_OFFSET,
) -> tuple[Log, GroundTruth]:
    """Import samples ``start .. start+steps`` of ``dataset2.mat``, one pose per ``stride``.

    Returns the log (landmark ids ``P0..P16`` unless ``unknown``) and the ground truth.

    Raises
    ------
    LogFormatError
        If the file cannot be read, lacks a variable, or the window is empty, leaves the
        recording, or holds a sample without a valid Vicon pose.
    """
    data = _load(path)
    t = data["t"].ravel()
    n_samples = t.size
    if stride < 1 or steps < stride:
        raise LogFormatError(path, None, f"need stride >= 1 and steps >= stride ({steps=})")
    end = start + (steps // stride) * stride
    if start < 0 or end >= n_samples:
        raise LogFormatError(
            path, None, f"window {start}..{end} leaves the recording (0..{n_samples - 1})"
        )
    valid = data["true_valid"].ravel()[start : end + 1]
    if not np.all(valid):
        bad = start + int(np.flatnonzero(valid == 0)[0])
        raise LogFormatError(
            path, None, f"no valid Vicon pose at sample {bad}: choose another window"
        )

    v, om = data["v"].ravel(), data["om"].ravel()
    ranges, bearings = np.asarray(data["r"], float), np.asarray(data["b"], float)
    d = float(np.asarray(data["d"]).ravel()[0])
    x, y = data["x_true"].ravel(), data["y_true"].ravel()
    theta = np.unwrap(data["th_true"].ravel()[start : end + 1])
    posts = np.asarray(data["l"], float)
    turn_bound, distance_bound = odometry_bound
    kept = list(range(start, end + 1, stride))

    k0 = kept[0]
    records: list = [
        PosePrior(
            0,
            (x[k0] - 0.01, x[k0] + 0.01),
            (y[k0] - 0.01, y[k0] + 0.01),
            (theta[0] - 0.01, theta[0] + 0.01),
        )
    ]
    poses: list[list[float]] = [[x[k0], y[k0], theta[0]]]
    pose_ids = [0]
    assignment: list[str] = []
    for i, k in enumerate(kept):
        pose = 2 * i
        if i > 0:
            seg = slice(k - stride, k)
            dt = np.diff(t[k - stride : k + 1])
            turn = float(np.sum(om[seg] * dt))
            dist = float(np.sum(v[seg] * dt))
            back = math.pi if dist < 0 else 0.0
            half_a = turn / 2 + drive_offset + back
            half_b = turn / 2 - drive_offset - back
            records.append(
                Odometry(
                    pose - 2,
                    pose - 1,
                    (half_a - turn_bound, half_a + turn_bound),
                    (max(abs(dist) - distance_bound, 0.0), abs(dist) + distance_bound),
                )
            )
            records.append(
                Odometry(pose - 1, pose, (half_b - turn_bound, half_b + turn_bound), (0.0, 0.0))
            )
            # True auxiliary pose: next position, heading along the chord (near prediction).
            th_prev = poses[-1][2]
            chord = math.atan2(y[k] - y[k - stride], x[k] - x[k - stride])
            chord = th_prev + half_a + math.remainder(chord - th_prev - half_a, 2 * math.pi)
            poses.append([x[k], y[k], chord])
            poses.append([x[k], y[k], theta[k - start]])
            pose_ids += [pose - 1, pose]
        for j in np.flatnonzero(ranges[k] > 0):
            box = _centre_box(
                float(ranges[k, j]), float(bearings[k, j]), d, range_bound, bearing_bound
            )
            if box is None:
                continue
            records.append(Observation(pose, "post", box[0], box[1], None if unknown else f"P{j}"))
            assignment.append(f"P{j}")

    truth = GroundTruth(
        poses_xyt=np.asarray(poses, float),
        pose_ids=pose_ids,
        landmarks_xy=posts.copy(),
        landmark_ids=[f"P{j}" for j in range(len(posts))],
        landmark_classes=["post"] * len(posts),
        assignment=assignment,
    )
    return Log(records=records, path=os.fspath(path)), truth


def _centre_box(
    r: float, b: float, d: float, range_bound: float, bearing_bound: float
) -> tuple[Bounds, Bounds] | None:
    """Range and bearing box of the post seen from the robot centre, or None if unsound.

    The post is at ``d·(1, 0) + ρ·(cos β, sin β)`` in the robot frame for the sensor's
    ``ρ ∈ [r ± range_bound]``, ``β ∈ [b ± bearing_bound]``.  For ``ρ > d`` and
    ``|β| < π`` the centre bearing increases with β and, for fixed β, is monotone in ρ;
    the centre range increases with ρ and with ``cos β``.  So the corners (and β = 0 for
    the largest range) bound both.
    """
    r_lo, r_hi = max(r - range_bound, 0.0), r + range_bound
    b_lo, b_hi = b - bearing_bound, b + bearing_bound
    if r_lo <= d or b_lo <= -math.pi or b_hi >= math.pi:
        return None

    def centre(rho: float, beta: float) -> tuple[float, float]:
        px, py = d + rho * math.cos(beta), rho * math.sin(beta)
        return math.hypot(px, py), math.atan2(py, px)

    corners = [centre(rho, beta) for rho in (r_lo, r_hi) for beta in (b_lo, b_hi)]
    bear = (min(c[1] for c in corners) - _EPS, max(c[1] for c in corners) + _EPS)
    cos_max = 1.0 if b_lo <= 0.0 <= b_hi else max(math.cos(b_lo), math.cos(b_hi))
    cos_min = min(math.cos(b_lo), math.cos(b_hi))
    rng_lo = math.sqrt(d * d + r_lo * r_lo + 2 * d * r_lo * cos_min)
    rng_hi = math.sqrt(d * d + r_hi * r_hi + 2 * d * r_hi * cos_max)
    return (max(rng_lo - _EPS, 0.0), rng_hi + _EPS), bear


def _load(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    import scipy.io

    try:
        data = scipy.io.loadmat(os.fspath(path))
    except FileNotFoundError:
        raise LogFormatError(path, None, "no such file (expected dataset2.mat)") from None
    except Exception as exc:  # scipy raises several types for a non-MAT file
        raise LogFormatError(path, None, f"cannot read MATLAB file: {exc}") from None
    missing = [name for name in _VARIABLES if name not in data]
    if missing:
        raise LogFormatError(
            path, None, f"not a Lost-in-the-Woods file: lacks variable(s) {', '.join(missing)}"
        )
    return data
