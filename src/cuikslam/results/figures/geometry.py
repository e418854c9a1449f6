"""The geometry of the figures, without Matplotlib: scene extents, clipping of unbounded
bounds, heading fans, which pose boxes a long run draws, box widths.

Part of :mod:`cuikslam.results.figures` (see its docstring for the drawing conventions).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.outcome.solution import Envelope, Hypothesis
from cuikslam.results.association import paired_landmarks

if TYPE_CHECKING:
    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "MAX_POSE_BOXES",
    "ZOOM_POSES",
    "Extent",
    "drawn_poses",
    "pose_widths",
    "scene_extent",
    "spread_labels",
    "widest_stretch",
]

Extent = tuple[float, float, float, float]
"""``(x_min, x_max, y_min, y_max)`` in metres."""

_PAD = 0.06
"""Margin added around the finite bounds, as a fraction of the larger side."""
MAX_POSE_BOXES = 60
"""Beyond this many poses, every k-th pose box is drawn (and the widest), not all: more
boxes, fans and true heading ticks than this overlap into a mass on a long run's map (the
widths panel and the zoom of a long run's figure show every pose)."""
ZOOM_POSES = 30
"""Consecutive poses in the zoom on a long run's widest stretch (every box drawn)."""


def _xy_boxes(boxes: np.ndarray | Sequence[Any]) -> np.ndarray:
    """The ``(k, 2, 2)`` x/y part of an array of boxes (an empty array for none)."""
    array = np.asarray(boxes, dtype=float)
    if array.size == 0:
        return np.empty((0, 2, 2))
    if array.ndim != 3 or array.shape[1] < 2 or array.shape[2] != 2:
        raise ValueError(f"boxes must have shape (n, >=2, 2), got {array.shape}")
    return array[:, :2, :]


def scene_extent(
    boxes: Iterable[np.ndarray],
    points: Iterable[np.ndarray] = (),
) -> Extent:
    """The padded extent of the finite bounds of ``boxes`` ((k, ≥2, 2) arrays) and of
    ``points`` ((k, ≥2) arrays of x, y): a square-ish margin of 6 % of the larger side.

    Infinite and NaN bounds are ignored; with no finite value at all the extent is
    ``[-1, 1]²``, padded.
    """
    xs: list[np.ndarray] = []
    ys: list[np.ndarray] = []
    for array in boxes:
        xy = _xy_boxes(array)
        xs.append(xy[:, 0, :].ravel())
        ys.append(xy[:, 1, :].ravel())
    for array in points:
        pts = np.asarray(array, dtype=float)
        if pts.size:
            pts = pts.reshape(len(pts), -1)
            xs.append(pts[:, 0])
            ys.append(pts[:, 1])
    x = np.concatenate(xs) if xs else np.empty(0)
    y = np.concatenate(ys) if ys else np.empty(0)
    x, y = x[np.isfinite(x)], y[np.isfinite(y)]
    x_lo, x_hi = (float(x.min()), float(x.max())) if x.size else (-1.0, 1.0)
    y_lo, y_hi = (float(y.min()), float(y.max())) if y.size else (-1.0, 1.0)
    span = max(x_hi - x_lo, y_hi - y_lo)
    pad = _PAD * span if span > 0 else 1.0
    return (x_lo - pad, x_hi + pad, y_lo - pad, y_hi + pad)


def _union_extent(extents: Iterable[Extent]) -> Extent:
    ext = list(extents)
    return (
        min(e[0] for e in ext),
        max(e[1] for e in ext),
        min(e[2] for e in ext),
        max(e[3] for e in ext),
    )


def _clip_boxes(xy: np.ndarray, extent: Extent) -> tuple[np.ndarray, np.ndarray]:
    """Replace non-finite x/y bounds by the extent's edges; also say which boxes had any."""
    unbounded = ~np.isfinite(xy).all(axis=(1, 2))
    clipped = xy.copy()
    for axis, (lo, hi) in enumerate(((extent[0], extent[1]), (extent[2], extent[3]))):
        clipped[:, axis, 0] = np.nan_to_num(clipped[:, axis, 0], nan=lo, neginf=lo, posinf=hi)
        clipped[:, axis, 1] = np.nan_to_num(clipped[:, axis, 1], nan=hi, neginf=lo, posinf=hi)
    return clipped, unbounded


def _fan_angles(theta: np.ndarray) -> tuple[float, float] | None:
    """Wedge angles in degrees for a heading interval; None for an empty interval."""
    lo, hi = float(theta[0]), float(theta[1])
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= 2 * math.pi:
        return (0.0, 360.0)
    if hi < lo:
        return None
    return (math.degrees(lo), math.degrees(hi))


def _true_landmark_rows(hypothesis: Hypothesis, truth: GroundTruth) -> list[int]:
    """Rows of ``truth.landmarks_xy`` that the hypothesis' landmarks stand for (paired
    through the association, :func:`~cuikslam.results.association.paired_landmarks`)."""
    paired = {t for ts in paired_landmarks(hypothesis, truth).values() for t in ts}
    return [j for j, lid in enumerate(truth.landmark_ids) if lid in paired]


def _sighted_landmark_rows(truth: GroundTruth) -> list[int]:
    """Rows of the true landmarks some observation sees (all of them without an assignment)."""
    if not truth.assignment:
        return list(range(len(truth.landmark_ids)))
    seen = set(truth.assignment)
    return [j for j, lid in enumerate(truth.landmark_ids) if lid in seen]


def _truth_points(
    truth: GroundTruth | None, pose_ids: Iterable[int], landmark_rows: Sequence[int]
) -> list[np.ndarray]:
    """The true positions of ``pose_ids`` and the true landmarks of ``landmark_rows``."""
    if truth is None:
        return []
    ids = set(pose_ids)
    poses = np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3)
    marks = np.asarray(truth.landmarks_xy, dtype=float).reshape(-1, 2)
    return [poses[[i for i, p in enumerate(truth.pose_ids) if p in ids]], marks[landmark_rows]]


def _hypothesis_extent(hypothesis: Hypothesis, truth: GroundTruth | None) -> Extent:
    rows = [] if truth is None else _true_landmark_rows(hypothesis, truth)
    points = _truth_points(truth, hypothesis.pose_ids, rows)
    return scene_extent([hypothesis.poses, hypothesis.landmarks], points)


def _envelope_extent(envelope: Envelope, truth: GroundTruth | None) -> Extent:
    rows = [] if truth is None else _sighted_landmark_rows(truth)
    points = _truth_points(truth, envelope.pose_ids, rows)
    return scene_extent([envelope.poses, envelope.observations], points)


def spread_labels(points_xy: np.ndarray, min_distance: float) -> list[list[int]]:
    """Group points for labels that do not overlap: each group is labelled at its first
    point, and a point within ``min_distance`` of a group's first point joins that group.

    Points are taken in order (a later point near an earlier one joins the earlier one's
    group, as a loop's last pose joins its first); non-finite points get no label.

    Parameters
    ----------
    points_xy : numpy.ndarray
        (n, 2) label anchors.
    min_distance : float
        The least distance between two groups' first points (metres).

    Returns
    -------
    list of list of int
        The groups, each a list of indices into ``points_xy``, first point first.

    Examples
    --------
    >>> spread_labels(np.array([[0.0, 0.0], [5.0, 0.0], [0.1, 0.0], [np.nan, 0.0]]), 1.0)
    [[0, 2], [1]]
    """
    points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    anchors = np.empty((0, 2))
    groups: list[list[int]] = []
    for i, point in enumerate(points):
        if not np.isfinite(point).all():
            continue
        near = np.hypot(*(anchors - point).T) < min_distance if len(anchors) else []
        if np.any(near):
            groups[int(np.argmax(near))].append(i)
        else:
            anchors = np.vstack([anchors, point])
            groups.append([i])
    return groups


def drawn_poses(pose_boxes: np.ndarray, max_boxes: int | None = MAX_POSE_BOXES) -> np.ndarray:
    """Indices of the pose boxes a figure draws: all of them up to ``max_boxes``, else
    every k-th (k chosen to draw about ``max_boxes``), the last one and the widest one
    (largest of the x and y widths), in pose order."""
    n = len(pose_boxes)
    if max_boxes is None or n <= max_boxes:
        return np.arange(n)
    stride = _prime_at_least(math.ceil(n / max(max_boxes - 2, 1)))
    widths = np.diff(np.asarray(pose_boxes, dtype=float)[:, :2], axis=2)[..., 0]
    widest = int(np.argmax(np.nan_to_num(widths.max(axis=1), nan=np.inf)))
    return np.unique(np.concatenate([np.arange(0, n, stride), [n - 1, widest]]))


def _prime_at_least(k: int) -> int:
    """The least prime >= ``k``: a stride that no short period of the run divides, so that
    a robot driving laps shows boxes from every part of its lap, not from one corner."""
    k = max(k, 2)
    while any(k % d == 0 for d in range(2, math.isqrt(k) + 1)):
        k += 1
    return k


def pose_widths(hypothesis: Hypothesis) -> np.ndarray:
    """The ``(n, 3)`` widths of the pose boxes (x, y in metres; θ in radians, at most 2π)."""
    boxes = np.asarray(hypothesis.poses, dtype=float).reshape(-1, 3, 2)
    with np.errstate(invalid="ignore"):
        widths = boxes[..., 1] - boxes[..., 0]
    widths[:, 2] = np.minimum(widths[:, 2], 2 * math.pi)
    return widths


def widest_stretch(hypothesis: Hypothesis, size: int = ZOOM_POSES) -> slice:
    """The ``size`` consecutive poses whose position boxes are widest in total (the wider
    of x and y per pose; an unbounded one counts as the widest finite width, so that the
    zoom still has boxes to show)."""
    widths = pose_widths(hypothesis)[:, :2].max(axis=1)
    finite = np.isfinite(widths)
    cap = float(widths[finite].max()) if finite.any() else 1.0
    widths = np.where(finite, widths, cap)
    size = min(size, len(widths))
    totals = np.convolve(widths, np.ones(size), mode="valid")
    start = int(np.argmax(totals))
    return slice(start, start + size)
