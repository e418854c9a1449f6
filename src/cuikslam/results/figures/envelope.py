"""The envelope of an unknown-correspondence result drawn into an ``Axes`` (the axes layer of
:mod:`cuikslam.results.figures`): each pose's box whatever the correspondence, and where
each sighted landmark lies. It is the guaranteed answer even when the search stopped on its
budget, so a figure draws it under the hypotheses, or alone when there are none."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cuikslam.outcome.solution import Envelope
from cuikslam.results.figures.artists import (
    ENVELOPE_COLOR,
    ENVELOPE_WIDTH,
    FAN_RADIUS,
    _draw_truth,
    _drawn_kinds,
    _finish_axes,
    _legend_handles,
    _place_legend,
    _rectangles,
)
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    Extent,
    _envelope_extent,
    _sighted_landmark_rows,
    _xy_boxes,
    drawn_poses,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["plot_envelope_on_axes"]


def plot_envelope_on_axes(
    ax: Axes,
    envelope: Envelope,
    truth: GroundTruth | None = None,
    *,
    landmarks: bool = True,
    title: str | None = None,
    legend: bool = False,
    extent: Extent | None = None,
    max_pose_boxes: int | None = MAX_POSE_BOXES,
) -> dict[str, list]:
    """Draw an envelope's boxes (and the truth) into ``ax``, under anything drawn later.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw. Its limits, aspect (equal), labels and title are set.
    envelope : Envelope
        ``Solution.envelope``: pose boxes, and the box of the landmark each observation sees.
    truth : GroundTruth, optional
        Drawn as points: the true poses and the true landmarks the observations see.
    landmarks : bool
        Also draw where the sighted landmarks lie: each distinct bounded observation box
        once, a dotted outline (an unbounded one, an observation that may be an outlier or
        has no range, is left out; beyond ``max_pose_boxes`` of them every k-th and the
        widest).
    title : str, optional
        The axes title.
    legend : bool
        Add a legend to the right of the axes.
    extent : (x_min, x_max, y_min, y_max), optional
        Axes limits and clip box; default: the finite bounds of the envelope and the truth.
        A box wider than it runs past the axes' edges (unbounded sides are drawn dashed).
    max_pose_boxes : int or None
        Draw at most about this many pose boxes (:func:`drawn_poses`); None draws all.

    Returns
    -------
    dict[str, list]
        ``envelope_poses`` (Rectangle per drawn pose box, light outlines),
        ``envelope_past_frame`` (those of them that run past the extent: the axes cut
        them),
        ``envelope_landmarks`` (Rectangle per drawn observation box, dotted), the truth
        as :func:`plot_hypothesis_on_axes` gives it, and ``legend``.
    """
    if extent is None:
        extent = _envelope_extent(envelope, truth)
    poses = np.asarray(envelope.poses, dtype=float).reshape(-1, 3, 2)
    drawn = drawn_poses(poses, max_pose_boxes)
    style = {"edgecolor": ENVELOPE_COLOR, "linewidth": ENVELOPE_WIDTH, "zorder": 1.5}
    rects, _ = _rectangles(ax, poses[drawn, :2], extent, facecolor="none", **style)
    frame = np.array([[extent[0], extent[1]], [extent[2], extent[3]]])
    finite = np.nan_to_num(poses[drawn, :2], posinf=np.inf, neginf=-np.inf)
    past = (finite[:, :, 0] < frame[:, 0]).any(axis=1) | (finite[:, :, 1] > frame[:, 1]).any(axis=1)
    artists: dict[str, list] = {
        "envelope_poses": rects,
        "envelope_past_frame": [r for r, out in zip(rects, past, strict=True) if out],
        "envelope_landmarks": [],
    }
    if landmarks:
        boxes = _xy_boxes(envelope.observations)
        bounded = np.unique(boxes[np.isfinite(boxes).all(axis=(1, 2))], axis=0)
        bounded = bounded[drawn_poses(bounded, max_pose_boxes)]  # every k-th, and the widest
        rects, _ = _rectangles(ax, bounded, extent, facecolor="none", **style)
        for rect in rects:  # all bounded: dotted tells them from the poses' outlines
            rect.set_linestyle(":")
        artists["envelope_landmarks"] = rects
    if truth is not None:
        tick = 0.8 * FAN_RADIUS * max(extent[1] - extent[0], extent[3] - extent[2])
        ticked = {envelope.pose_ids[i] for i in drawn}
        rows = _sighted_landmark_rows(truth) if landmarks else []
        artists.update(_draw_truth(ax, truth, tick, envelope.pose_ids, rows, ticked))
    _finish_axes(ax, extent, title)
    artists["legend"] = (
        [_place_legend(ax, _legend_handles({}, _drawn_kinds(artists)))] if legend else []
    )
    return artists
