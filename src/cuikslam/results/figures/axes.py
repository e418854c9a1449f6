"""The axes layer of :mod:`cuikslam.results.figures` (whose docstring states the drawing
conventions): functions that draw into a Matplotlib ``Axes`` you own, so that they compose
with your own plots (and with Codac or GTSAM figures)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.results.figures.artists import (
    FAN_RADIUS,
    POSE_COLOR,
    _draw_truth,
    _finish_axes,
    _legend_handles,
    _place_legend,
    _rectangles,
    _rgb,
    _text_style,
    _truth_handles,
    class_color_map,
)
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    Extent,
    _clip_boxes,
    _fan_angles,
    _hypothesis_extent,
    _xy_boxes,
    drawn_poses,
    pose_widths,
    scene_extent,
)
from cuikslam.results.solution import Hypothesis

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "WIDTH_BINS",
    "plot_comparison_on_axes",
    "plot_hypothesis_on_axes",
    "plot_widths_on_axes",
]

_MAX_POSE_LABELS = 40
"""Beyond this many poses, only every k-th pose gets a label."""
WIDTH_BINS = 500
"""Beyond this many poses, the widths panel draws the largest width of each bin of poses."""


def plot_hypothesis_on_axes(
    ax: Axes,
    hypothesis: Hypothesis,
    truth: GroundTruth | None = None,
    *,
    title: str | None = None,
    show_labels: bool = True,
    heading_fan: bool = True,
    legend: bool = True,
    extent: Extent | None = None,
    class_colors: dict[str, Any] | None = None,
    max_pose_boxes: int | None = MAX_POSE_BOXES,
) -> dict[str, list]:
    """Draw one hypothesis' boxes (and the truth) into ``ax``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.  Its limits, aspect (equal), labels and title are set.
    hypothesis : Hypothesis
        The boxes: ``poses`` (n, 3, 2) and ``landmarks`` (m, 2, 2).
    truth : GroundTruth, optional
        Drawn as points; only poses and landmarks whose ids the hypothesis has.
    title : str, optional
        The axes title.
    show_labels : bool
        Label poses (with their id; every k-th pose beyond 40 poses) and landmarks.
    heading_fan : bool
        Draw each pose's heading interval as a wedge from its box centre.
    legend : bool
        Add a legend (landmark classes and symbols) to the right of the axes.
    extent : (x_min, x_max, y_min, y_max), optional
        The scene extent: axes limits, clip box for unbounded boxes, and the scale of the
        fans.  Default: the finite bounds of the hypothesis and the truth, padded.  Pass
        the same extent to several axes to make them comparable.
    class_colors : dict, optional
        Class → colour; default :func:`class_color_map` of the hypothesis' classes.
    max_pose_boxes : int or None
        Draw at most about this many pose boxes (and fans): every k-th pose, the last one
        and the widest one (:func:`drawn_poses`); None draws every box. The path still
        runs through every pose.

    Returns
    -------
    dict[str, list]
        The artists by kind: ``pose_boxes`` (Rectangle per drawn pose), ``heading_fans``
        (Wedge per drawn pose with a non-empty heading interval), ``pose_labels`` (Text),
        ``path`` (one Line2D through the box centres), ``landmark_boxes`` (Rectangle per
        landmark), ``landmark_labels`` (Text), ``truth_poses`` (one Line2D of dots),
        ``truth_headings`` (one LineCollection of ticks), ``truth_landmarks`` (one
        Line2D of crosses) and ``legend`` (zero or one Legend).
    """
    from matplotlib.patches import Wedge

    if extent is None:
        extent = _hypothesis_extent(hypothesis, truth)
    if class_colors is None:
        class_colors = class_color_map(hypothesis.landmark_classes)
    scale = max(extent[1] - extent[0], extent[3] - extent[2])
    radius = FAN_RADIUS * scale
    text = _text_style() if show_labels else {}
    artists: dict[str, list] = {
        "pose_boxes": [],
        "heading_fans": [],
        "pose_labels": [],
        "path": [],
        "landmark_boxes": [],
        "landmark_labels": [],
        "truth_poses": [],
        "truth_headings": [],
        "truth_landmarks": [],
        "legend": [],
    }

    # Landmarks: filled, coloured by class, under the poses.
    landmark_xy = _xy_boxes(hypothesis.landmarks)
    clipped_landmarks, _ = _clip_boxes(landmark_xy, extent)
    any_unbounded = False
    for k, (box, cls) in enumerate(
        zip(landmark_xy, hypothesis.landmark_classes[: len(landmark_xy)], strict=True)
    ):
        color = class_colors.get(cls, "0.5")
        (rect,), unbounded = _rectangles(
            ax,
            box[None],
            extent,
            facecolor=color,
            edgecolor=color,
            alpha=0.45,
            linewidth=1.2,
            zorder=2,
        )
        any_unbounded |= unbounded
        artists["landmark_boxes"].append(rect)
        if show_labels:
            (x0, x1), (_, y1) = clipped_landmarks[k]
            label = ax.annotate(
                str(hypothesis.landmark_ids[k]),
                ((x0 + x1) / 2, y1),
                xytext=(0, 3),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=8,
                fontweight="bold",
                color=color,
                zorder=7,
                **text,
            )
            artists["landmark_labels"].append(label)

    # Poses: unfilled boxes, heading fans, the path through the centres, labels.
    all_pose_boxes = np.asarray(hypothesis.poses, dtype=float).reshape(-1, 3, 2)
    drawn = drawn_poses(all_pose_boxes, max_pose_boxes)
    pose_boxes = all_pose_boxes[drawn]
    rects, unbounded = _rectangles(
        ax,
        pose_boxes[:, :2],
        extent,
        facecolor=POSE_COLOR,
        edgecolor=POSE_COLOR,
        linewidth=1.0,
        alpha=None,
        zorder=3,
    )
    many = len(rects) > _MAX_POSE_LABELS  # overlapping fills would hide one another
    for rect in rects:  # a faint fill shows the area, a solid edge the outline
        rect.set_facecolor((*_rgb(POSE_COLOR), 0.0 if many else 0.06))
        if many:
            rect.set_linewidth(0.5)
    any_unbounded |= unbounded
    artists["pose_boxes"] = rects
    clipped_poses, _ = _clip_boxes(all_pose_boxes[:, :2], extent)
    all_centres = clipped_poses.mean(axis=2)
    centres = all_centres[drawn]
    if heading_fan:
        for centre, box in zip(centres, pose_boxes, strict=True):
            angles = _fan_angles(box[2])
            if angles is None:
                continue
            wedge = Wedge(
                tuple(centre),
                radius,
                *angles,
                facecolor=POSE_COLOR,
                edgecolor=POSE_COLOR,
                alpha=0.3,
                linewidth=0.6,
                zorder=4,
            )
            ax.add_patch(wedge)
            artists["heading_fans"].append(wedge)
    if len(all_centres) > 1:
        thin = len(all_centres) > len(centres)
        (line,) = ax.plot(
            all_centres[:, 0],
            all_centres[:, 1],
            color=POSE_COLOR,
            linewidth=0.5 if thin else 0.8,
            alpha=0.4 if thin else 0.7,
            zorder=4,
        )
        artists["path"].append(line)
    if show_labels and len(centres):
        stride = math.ceil(len(centres) / _MAX_POSE_LABELS)
        for k in range(0, len(centres), stride):
            label = ax.annotate(
                str(hypothesis.pose_ids[drawn[k]]),
                tuple(centres[k]),
                xytext=(4, -4),
                textcoords="offset points",
                ha="left",
                va="top",
                fontsize=7,
                color=POSE_COLOR,
                zorder=7,
                **text,
            )
            artists["pose_labels"].append(label)

    if truth is not None:
        artists.update(
            _draw_truth(ax, truth, 0.8 * radius, hypothesis.pose_ids, hypothesis.landmark_ids)
        )
    _finish_axes(ax, extent, title)
    if legend:
        handles = _legend_handles(
            {c: class_colors.get(c, "0.5") for c in sorted(set(hypothesis.landmark_classes))},
            poses=bool(rects),
            fans=bool(artists["heading_fans"]),
            unbounded=any_unbounded,
            truth_poses=bool(artists["truth_poses"]),
            truth_landmarks=bool(artists["truth_landmarks"]),
        )
        artists["legend"].append(_place_legend(ax, handles))
    return artists


def plot_comparison_on_axes(
    ax: Axes,
    boxes_by_label: dict[str, np.ndarray],
    truth: GroundTruth | None = None,
    *,
    title: str | None = None,
    colors: dict[str, Any] | None = None,
    extent: Extent | None = None,
    legend: bool = True,
    linewidth: float = 1.2,
) -> dict[str, list]:
    """Overlay several sets of pose boxes (e.g. consistency levels, inner vs outer boxes).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    boxes_by_label : dict[str, np.ndarray]
        Label → (n, ≥2, 2) array of boxes; only the x and y bounds are used.  Sets are
        drawn unfilled in the given order, each in its own edge colour.
    truth : GroundTruth, optional
        All true poses (dots with heading ticks) and landmarks (crosses).
    title : str, optional
        The axes title.
    colors : dict, optional
        Label → edge colour; default ``tab10`` colours in label order.
    extent : (x_min, x_max, y_min, y_max), optional
        Axes limits and clip box for unbounded bounds; default from the finite bounds.
    legend : bool
        Add a legend of the labels to the right of the axes.
    linewidth : float
        Box edge width.

    Returns
    -------
    dict[str, list]
        The Rectangles of each label under that label's key, then ``truth_poses``,
        ``truth_headings``, ``truth_landmarks`` and ``legend`` as in
        :func:`plot_hypothesis_on_axes`.
    """
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    arrays = {label: _xy_boxes(boxes) for label, boxes in boxes_by_label.items()}
    if extent is None:
        points = []
        if truth is not None:
            points = [np.asarray(truth.poses_xyt), np.asarray(truth.landmarks_xy)]
        extent = scene_extent(arrays.values(), points)
    if colors is None:
        palette = colormaps["tab10"].colors
        colors = {label: palette[i % len(palette)] for i, label in enumerate(arrays)}
    artists: dict[str, list] = {}
    handles: list = []
    any_unbounded = False
    for i, (label, xy) in enumerate(arrays.items()):
        color = colors.get(label, "0.3")
        rects, unbounded = _rectangles(
            ax, xy, extent, facecolor="none", edgecolor=color, linewidth=linewidth, zorder=3 + i
        )
        any_unbounded |= unbounded
        artists[label] = rects
        handles.append(Line2D([], [], color=color, linewidth=2.0, label=label))
    artists.setdefault("truth_poses", [])
    artists.setdefault("truth_headings", [])
    artists.setdefault("truth_landmarks", [])
    if truth is not None:
        tick = 0.8 * FAN_RADIUS * max(extent[1] - extent[0], extent[3] - extent[2])
        drawn = _draw_truth(ax, truth, tick, None, None)
        artists.update(drawn)
        handles += _truth_handles(bool(drawn["truth_poses"]), bool(drawn["truth_landmarks"]))
    if any_unbounded:
        handles.append(Line2D([], [], color="0.3", linestyle="--", label="unbounded (clipped)"))
    _finish_axes(ax, extent, title)
    artists["legend"] = [_place_legend(ax, handles)] if legend else []
    return artists


def plot_widths_on_axes(ax: Axes, hypothesis: Hypothesis, *, title: str | None = None) -> dict:
    """Draw the pose box widths along the run (pose index in the hypothesis' order).

    x and y widths in metres on ``ax``; heading widths in radians on a twin axis (capped
    at 2π: "any heading"). Beyond :data:`WIDTH_BINS` poses, each point is the largest
    width over a bin of consecutive poses. Unbounded widths leave gaps in the lines.
    Returns the artists: ``lines`` (x, y, θ) and ``twin`` (the heading axes).
    """
    widths = pose_widths(hypothesis)
    shown = np.where(np.isfinite(widths), widths, np.nan)
    index = np.arange(len(widths))
    note = ""
    if len(widths) > WIDTH_BINS:  # one point per bin: its largest width (a gap if unbounded)
        size = math.ceil(len(widths) / WIDTH_BINS)
        starts = np.arange(0, len(widths), size)
        binned = np.maximum.reduceat(np.nan_to_num(widths, posinf=np.inf), starts, axis=0)
        shown = np.where(np.isfinite(binned), binned, np.nan)
        index = starts
        note = f" (largest of {size} poses)"
    (line_x,) = ax.plot(index, shown[:, 0], linewidth=0.8, color="tab:blue", label="x width" + note)
    (line_y,) = ax.plot(index, shown[:, 1], linewidth=0.8, color="tab:orange", label="y width")
    twin = ax.twinx()
    (line_t,) = twin.plot(
        index, shown[:, 2], linewidth=0.6, color="tab:green", alpha=0.7, label="θ width"
    )
    twin.set_ylabel("θ width [rad]", fontsize="small")
    for axes, column in ((ax, shown[:, :2]), (twin, shown[:, 2])):
        top = np.nanmax(column, initial=0.0)  # room above the lines for the legend
        axes.set_ylim(0.0, 1.3 * top if top > 0 else 1.0)
    ax.set_xlim(0, max(len(widths) - 1, 1))
    ax.set_xlabel("pose (in log order)")
    ax.set_ylabel("width [m]")
    ax.grid(True, linewidth=0.4, alpha=0.4)
    ax.legend(handles=[line_x, line_y, line_t], fontsize="small", loc="upper left", ncols=3)
    if title is not None:
        ax.set_title(title, fontsize="small")
    return {"lines": [line_x, line_y, line_t], "twin": [twin]}
