"""The axes layer of :mod:`cuikslam.results.figures` (whose docstring states the drawing
conventions): functions that draw into a Matplotlib ``Axes`` you own, so that they compose
with your own plots (and with Codac or GTSAM figures)."""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.outcome.solution import Hypothesis
from cuikslam.results.figures.artists import (
    FAN_RADIUS,
    POSE_COLOR,
    _draw_sightings,
    _draw_truth,
    _drawn_kinds,
    _finish_axes,
    _legend_above,
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
    _true_landmark_rows,
    _xy_boxes,
    drawn_poses,
    pose_widths,
    scene_extent,
    spread_labels,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "MAX_SIGHTINGS",
    "WIDTH_BINS",
    "plot_comparison_on_axes",
    "plot_hypothesis_on_axes",
    "plot_widths_on_axes",
]

_MAX_FILLED_BOXES = 40
"""Beyond this many pose boxes, their fills are left out (they would hide one another)."""
_LABEL_SPACING = 0.035
"""The least distance between two pose labels, as a fraction of the scene extent."""
_LONG_RUN_LABEL_SPACING = 0.12
"""The same when the pose boxes are thinned (a long run): a few labels, far apart."""
MAX_SIGHTINGS = 300
"""Beyond this many observations, the sightings (kinematic graph edges) are not drawn."""
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
    observation_poses: Sequence[int] | None = None,
    highlight: Collection[int] = (),
) -> dict[str, list]:
    """Draw one hypothesis' boxes (and the truth) into ``ax``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.  Its limits, aspect (equal), labels and title are set.
    hypothesis : Hypothesis
        The boxes: ``poses`` (n, 3, 2) and ``landmarks`` (m, 2, 2).
    truth : GroundTruth, optional
        Drawn as points: the true poses the hypothesis has, and the true landmarks its
        landmarks stand for, paired through the association whatever their names
        (:func:`~cuikslam.results.association.paired_landmarks`).
    title : str, optional
        The axes title.
    show_labels : bool
        Label landmarks, and poses with their ids, spread so that labels do not overlap
        (a pose near an earlier labelled one joins its label: ``1, 9`` where a loop
        closes; on a long run only a few, far apart).
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
        Draw at most about this many pose boxes (and fans, and true poses with their
        heading ticks): every k-th pose, the last one and the widest one
        (:func:`drawn_poses`); None draws every box. The path still runs through every
        pose, and the true path through every true pose.
    observation_poses : sequence of int, optional
        The pose id of each observation, in log order (``[o.pose for o in
        log.observations]``): draws the kinematic graph's sightings, a line from the pose's
        box to the box of the landmark the hypothesis assigns (up to
        :data:`MAX_SIGHTINGS` observations).
    highlight : collection of int
        Observations (indices in log order) whose sightings are drawn in red: those the
        survivors of a search assign differently.

    Returns
    -------
    dict[str, list]
        The artists by kind: ``pose_boxes`` (Rectangle per drawn pose), ``heading_fans``
        (Wedge per drawn pose with a non-empty heading interval), ``pose_labels`` (Text),
        ``path`` (one Line2D through the box centres), ``landmark_boxes`` (Rectangle per
        landmark), ``landmark_labels`` (Text), ``sightings`` and ``ambiguous_sightings``
        (a LineCollection each), ``truth_poses`` (one Line2D of dots),
        ``truth_headings`` (one LineCollection of ticks), ``truth_path`` (one Line2D when
        the true poses are thinned), ``truth_landmarks`` (one Line2D of crosses) and
        ``legend`` (zero or one Legend).
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
        "sightings": [],
        "ambiguous_sightings": [],
        "truth_poses": [],
        "truth_headings": [],
        "truth_path": [],
        "truth_landmarks": [],
        "legend": [],
    }

    # Landmarks: filled, coloured by class, under the poses.
    landmark_xy = _xy_boxes(hypothesis.landmarks)
    clipped_landmarks, _ = _clip_boxes(landmark_xy, extent)
    for k, (box, cls) in enumerate(
        zip(landmark_xy, hypothesis.landmark_classes[: len(landmark_xy)], strict=True)
    ):
        color = class_colors.get(cls, "0.5")
        (rect,), _ = _rectangles(
            ax,
            box[None],
            extent,
            facecolor=color,
            edgecolor=color,
            alpha=0.45,
            linewidth=1.2,
            zorder=2,
        )
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
    thinned = len(drawn) < len(all_pose_boxes)
    pose_boxes = all_pose_boxes[drawn]
    rects, _ = _rectangles(
        ax,
        pose_boxes[:, :2],
        extent,
        facecolor=POSE_COLOR,
        edgecolor=POSE_COLOR,
        linewidth=1.0,
        alpha=None,
        zorder=3,
    )
    many = len(rects) > _MAX_FILLED_BOXES  # overlapping fills would hide one another
    for rect in rects:  # a faint fill shows the area, a solid edge the outline
        rect.set_facecolor((*_rgb(POSE_COLOR), 0.0 if many else 0.06))
        if many:
            rect.set_linewidth(0.5)
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
        (line,) = ax.plot(
            all_centres[:, 0],
            all_centres[:, 1],
            color=POSE_COLOR,
            linewidth=0.5 if thinned else 0.8,
            alpha=0.4 if thinned else 0.7,
            zorder=4,
        )
        artists["path"].append(line)
    if show_labels:
        artists["pose_labels"] = _pose_labels(
            ax, centres, [hypothesis.pose_ids[i] for i in drawn], scale, thinned, text
        )
    if observation_poses is not None and len(hypothesis.assignment) <= MAX_SIGHTINGS:
        clipped_marks = clipped_landmarks.mean(axis=2)
        segments, ambiguous = _sighting_segments(
            hypothesis, all_centres, clipped_marks, observation_poses, highlight
        )
        artists.update(_draw_sightings(ax, segments, ambiguous))

    if truth is not None:
        ticked = {hypothesis.pose_ids[i] for i in drawn} if thinned else None
        rows = _true_landmark_rows(hypothesis, truth)
        artists.update(_draw_truth(ax, truth, 0.8 * radius, hypothesis.pose_ids, rows, ticked))
    _finish_axes(ax, extent, title)
    if legend:
        colors = {c: class_colors.get(c, "0.5") for c in sorted(set(hypothesis.landmark_classes))}
        handles = _legend_handles(colors, _drawn_kinds(artists))
        artists["legend"].append(_place_legend(ax, handles))
    return artists


def _pose_labels(
    ax: Axes,
    centres: np.ndarray,
    pose_ids: Sequence[int],
    scale: float,
    thinned: bool,
    text: dict[str, Any],
) -> list:
    """Pose ids at their box centres, spread (:func:`spread_labels`) so none overlap."""
    spacing = (_LONG_RUN_LABEL_SPACING if thinned else _LABEL_SPACING) * scale
    labels = []
    for group in spread_labels(centres, spacing):
        words = str(pose_ids[group[0]])
        later = [i for prev, i in pairwise(group) if i - prev > 1]
        if later and not thinned:  # the pose is visited again: a loop closes here
            words += f", {pose_ids[later[0]]}"
        labels.append(
            ax.annotate(
                words,
                tuple(centres[group[0]]),
                xytext=(4, -4),
                textcoords="offset points",
                ha="left",
                va="top",
                fontsize=7,
                color=POSE_COLOR,
                zorder=7,
                **text,
            )
        )
    return labels


def _sighting_segments(
    hypothesis: Hypothesis,
    pose_centres: np.ndarray,
    landmark_centres: np.ndarray,
    observation_poses: Sequence[int],
    highlight: Collection[int],
) -> tuple[np.ndarray, np.ndarray]:
    """For each observation the hypothesis assigns a landmark (not an outlier), a segment
    from its pose's box centre to that landmark's; and which of them to highlight."""
    if len(observation_poses) != len(hypothesis.assignment):
        raise ValueError(
            f"observation_poses has {len(observation_poses)} poses for the hypothesis' "
            f"{len(hypothesis.assignment)} observations"
        )
    pose_row = {p: i for i, p in enumerate(hypothesis.pose_ids)}
    landmark_row = {lid: j for j, lid in enumerate(hypothesis.landmark_ids)}
    marked = set(highlight)
    segments, ambiguous = [], []
    for i, (pose, landmark) in enumerate(
        zip(observation_poses, hypothesis.assignment, strict=True)
    ):
        if pose in pose_row and landmark in landmark_row:
            ends = pose_centres[pose_row[pose]], landmark_centres[landmark_row[landmark]]
            segments.append(ends)
            ambiguous.append(i in marked)
    return np.array(segments, dtype=float).reshape(-1, 2, 2), np.array(ambiguous, dtype=bool)


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
    for kind in ("truth_poses", "truth_headings", "truth_path", "truth_landmarks"):
        artists.setdefault(kind, [])
    if truth is not None:
        tick = 0.8 * FAN_RADIUS * max(extent[1] - extent[0], extent[3] - extent[2])
        drawn = _draw_truth(ax, truth, tick, None, None)
        artists.update(drawn)
        handles += _truth_handles(_drawn_kinds(drawn))
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
        top = np.nanmax(column, initial=0.0)
        axes.set_ylim(0.0, 1.05 * top if top > 0 else 1.0)
    ax.set_xlim(0, max(len(widths) - 1, 1))
    ax.set_xlabel("pose (in log order)")
    ax.set_ylabel("width [m]")
    ax.grid(True, linewidth=0.4, alpha=0.4)
    _legend_above(ax, [line_x, line_y, line_t], title)
    return {"lines": [line_x, line_y, line_t], "twin": [twin]}
