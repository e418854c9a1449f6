"""Figures of guaranteed SLAM results: pose and landmark boxes, heading fans, the truth.

Two layers, as in GTSAM's ``gtsam.utils.plot``:

* ``*_on_axes`` functions draw into a Matplotlib ``Axes`` you own, so you can compose
  them with your own plots (and with Codac or GTSAM figures);
* :func:`plot_solution` builds a whole figure (one panel, or small multiples when several
  hypotheses survive), and :func:`save_figure` writes it atomically.

Matplotlib is imported inside the functions only, never when this module is imported, and
nothing here calls ``plt.show()``: the functions work under the non-interactive ``Agg``
backend (servers, CI).  Figures are created through :mod:`matplotlib.pyplot`, so a
script may still call ``plt.show()`` itself.

Drawing conventions
-------------------
* A pose box is an unfilled rectangle ``x × y`` plus a *heading fan*: a wedge from the box
  centre spanning the heading interval (θ counter-clockwise from +x).  A heading interval
  at least 2π wide (or unbounded) means "any heading" and is drawn as a full disc.
* Landmark boxes are filled rectangles coloured by landmark class.
* Unbounded (±inf) bounds are clipped to the scene extent and the box is drawn dashed.
* The truth, when given, is drawn as black dots with a short heading tick (poses) and
  black crosses (landmarks); only poses and landmarks whose ids the hypothesis has are
  drawn, since a wrong hypothesis may use the same landmark ids for other landmarks.
"""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam._atomic import atomic_open
from cuikslam.results.solution import Hypothesis, Solution

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "class_color_map",
    "drawn_poses",
    "plot_comparison_on_axes",
    "plot_hypothesis_on_axes",
    "plot_solution",
    "plot_widths_on_axes",
    "pose_widths",
    "save_figure",
    "scene_extent",
]

Extent = tuple[float, float, float, float]
"""``(x_min, x_max, y_min, y_max)`` in metres."""

POSE_COLOR = "tab:blue"
TRUTH_COLOR = "black"
FAN_RADIUS = 0.05
"""Heading-fan radius as a fraction of the scene extent (the larger side)."""
_PAD = 0.06
"""Margin added around the finite bounds, as a fraction of the larger side."""
_MAX_POSE_LABELS = 40
"""Beyond this many poses, only every k-th pose gets a label."""
MAX_POSE_BOXES = 150
"""Beyond this many poses, every k-th pose box is drawn (and the widest), not all."""
WIDTH_PANEL_POSES = 60
"""A one-hypothesis figure of more poses than this gets a panel of widths over time."""
_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}


# --------------------------------------------------------------------------- helpers
def class_color_map(classes: Iterable[str]) -> dict[str, Any]:
    """A stable class → colour map: sorted class names get successive qualitative colours.

    The colours come from ``tab10`` without its blue (used for poses) and grey, then from
    the light half of ``tab20``; they repeat beyond 16 classes.  The map depends only on
    the set of class names, so the same classes get the same colours in every panel.
    """
    from matplotlib import colormaps

    tab10 = colormaps["tab10"].colors
    tab20 = colormaps["tab20"].colors
    palette = [c for i, c in enumerate(tab10) if i not in (0, 7)]
    palette += [c for i, c in enumerate(tab20) if i % 2 == 1 and i not in (1, 15)]
    return {name: palette[i % len(palette)] for i, name in enumerate(sorted(set(classes)))}


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


def _rectangles(ax: Axes, xy: np.ndarray, extent: Extent, **style: Any) -> tuple[list, bool]:
    """One Rectangle per box (dashed when clipped); also whether any box was clipped."""
    from matplotlib.patches import Rectangle

    clipped, unbounded = _clip_boxes(xy, extent)
    patches = []
    for box, dashed in zip(clipped, unbounded, strict=True):
        (x0, x1), (y0, y1) = box
        rect = Rectangle(
            (x0, y0),
            max(x1 - x0, 0.0),
            max(y1 - y0, 0.0),
            linestyle="--" if dashed else "-",
            **style,
        )
        ax.add_patch(rect)
        patches.append(rect)
    return patches, bool(unbounded.any())


def _fan_angles(theta: np.ndarray) -> tuple[float, float] | None:
    """Wedge angles in degrees for a heading interval; None for an empty interval."""
    lo, hi = float(theta[0]), float(theta[1])
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi - lo >= 2 * math.pi:
        return (0.0, 360.0)
    if hi < lo:
        return None
    return (math.degrees(lo), math.degrees(hi))


def _text_style() -> dict[str, Any]:
    from matplotlib import patheffects

    return {"path_effects": [patheffects.withStroke(linewidth=2.5, foreground="white")]}


def _draw_truth(
    ax: Axes,
    truth: GroundTruth,
    tick: float,
    pose_ids: Sequence[int] | None,
    landmark_ids: Sequence[str] | None,
) -> dict[str, list]:
    """Truth poses (dots + heading ticks) and landmarks (crosses), filtered by id."""
    from matplotlib.collections import LineCollection

    artists: dict[str, list] = {"truth_poses": [], "truth_headings": [], "truth_landmarks": []}
    poses = np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3)
    keep = [i for i, pid in enumerate(truth.pose_ids) if pose_ids is None or pid in pose_ids]
    poses = poses[keep]
    if len(poses):
        (dots,) = ax.plot(
            poses[:, 0],
            poses[:, 1],
            linestyle="none",
            marker="o",
            markersize=3,
            color=TRUTH_COLOR,
            zorder=6,
        )
        ends = poses[:, :2] + tick * np.column_stack((np.cos(poses[:, 2]), np.sin(poses[:, 2])))
        ticks = LineCollection(
            np.stack((poses[:, :2], ends), axis=1), colors=TRUTH_COLOR, linewidths=1.0, zorder=6
        )
        ax.add_collection(ticks)
        artists["truth_poses"].append(dots)
        artists["truth_headings"].append(ticks)
    landmarks = np.asarray(truth.landmarks_xy, dtype=float).reshape(-1, 2)
    keep = [
        j for j, lid in enumerate(truth.landmark_ids) if landmark_ids is None or lid in landmark_ids
    ]
    landmarks = landmarks[keep]
    if len(landmarks):
        (crosses,) = ax.plot(
            landmarks[:, 0],
            landmarks[:, 1],
            linestyle="none",
            marker="x",
            markersize=6,
            markeredgewidth=1.5,
            color=TRUTH_COLOR,
            zorder=6,
        )
        artists["truth_landmarks"].append(crosses)
    return artists


def _legend_handles(
    colors: dict[str, Any],
    *,
    poses: bool,
    fans: bool,
    unbounded: bool,
    truth_poses: bool,
    truth_landmarks: bool,
) -> list:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list = [
        Patch(facecolor=color, edgecolor=color, alpha=0.5, label=f"landmark: {name}")
        for name, color in colors.items()
    ]
    if poses:
        handles.append(Patch(facecolor="none", edgecolor=POSE_COLOR, label="pose box"))
    if fans:
        handles.append(
            Patch(facecolor=POSE_COLOR, alpha=0.25, edgecolor="none", label="heading interval")
        )
    if unbounded:
        handles.append(Line2D([], [], color="0.3", linestyle="--", label="unbounded (clipped)"))
    handles += _truth_handles(bool(truth_poses), bool(truth_landmarks))
    return handles


def _finish_axes(ax: Axes, extent: Extent, title: str | None) -> None:
    # Fixed limits (a margin of 2.5 % keeps dashed clipped edges off the spines) and
    # equal aspect by shrinking the axes box: axes given the same extent show the same
    # region.  (Widening the limits instead, "datalim", compounds over the draws of a
    # constrained layout.)
    margin = 0.025 * max(extent[1] - extent[0], extent[3] - extent[2])
    ax.set_xlim(extent[0] - margin, extent[1] + margin)
    ax.set_ylim(extent[2] - margin, extent[3] + margin)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, linewidth=0.4, alpha=0.4)
    if title is not None:
        ax.set_title(title, fontsize="small")


def _place_legend(ax: Axes, handles: list) -> Any:
    """An axes legend outside the plot, on the right, so it never hides boxes."""
    return ax.legend(
        handles=handles,
        loc="upper left",
        bbox_to_anchor=(1.02, 1.0),
        borderaxespad=0.0,
        fontsize="small",
        frameon=False,
    )


def _hypothesis_extent(hypothesis: Hypothesis, truth: GroundTruth | None) -> Extent:
    points = []
    if truth is not None:
        pose_ids = set(hypothesis.pose_ids)
        landmark_ids = set(hypothesis.landmark_ids)
        poses = np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3)
        points.append(poses[[i for i, p in enumerate(truth.pose_ids) if p in pose_ids]])
        marks = np.asarray(truth.landmarks_xy, dtype=float).reshape(-1, 2)
        points.append(marks[[j for j, m in enumerate(truth.landmark_ids) if m in landmark_ids]])
    return scene_extent([hypothesis.poses, hypothesis.landmarks], points)


# --------------------------------------------------------------------------- axes layer
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


WIDTH_BINS = 500
"""Beyond this many poses, the widths panel draws the largest width of each bin of poses."""


def pose_widths(hypothesis: Hypothesis) -> np.ndarray:
    """The ``(n, 3)`` widths of the pose boxes (x, y in metres; θ in radians, at most 2π)."""
    boxes = np.asarray(hypothesis.poses, dtype=float).reshape(-1, 3, 2)
    with np.errstate(invalid="ignore"):
        widths = boxes[..., 1] - boxes[..., 0]
    widths[:, 2] = np.minimum(widths[:, 2], 2 * math.pi)
    return widths


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


# --------------------------------------------------------------------------- figure layer
def _assignment_text(assignment: Sequence[str], width: int, max_lines: int = 3) -> str:
    """``obs→L: 1 1 2 …`` with the landmark ids' common non-digit prefix moved to the head."""
    if not assignment:
        return "no observations"
    ids = [str(a) for a in assignment]
    prefix = _common_prefix(ids).rstrip("0123456789")
    if prefix and all(len(a) > len(prefix) for a in ids):
        head, tokens = f"obs→{prefix}:", [a[len(prefix) :] for a in ids]
    else:
        head, tokens = "obs→landmark:", ids
    lines = textwrap.wrap(" ".join([head, *tokens]), width=width, break_long_words=False)
    if len(lines) > max_lines:
        lines = lines[:max_lines]
        lines[-1] = lines[-1] + " …"
    return "\n".join(lines)


def _common_prefix(texts: Sequence[str]) -> str:
    first, last = min(texts), max(texts)
    n = 0
    while n < min(len(first), len(last)) and first[n] == last[n]:
        n += 1
    return first[:n]


_MAX_TITLE_OBSERVATIONS = 30
"""Beyond this many observations, a one-panel title counts them instead of listing them
(in small multiples the assignment tells the panels apart, so it stays, shortened)."""


def _panel_title(
    rank: int, hypothesis: Hypothesis, width: int, max_observations: int | None = None
) -> str:
    """Rank, landmarks, status, level (and poses drawn, for long runs), then the
    assignment, or only its length beyond ``max_observations`` observations."""
    n = hypothesis.n_landmarks
    head = f"#{rank} · {n} landmark{'s' if n != 1 else ''} · {hypothesis.status}"
    if hypothesis.consistency:
        head += f" · {hypothesis.consistency}"
    poses = len(hypothesis.pose_ids)
    if poses > MAX_POSE_BOXES:
        head += f" · {poses:,} poses, {len(drawn_poses(hypothesis.poses))} boxes drawn"
    if max_observations is not None and len(hypothesis.assignment) > max_observations:
        return head + f"\n{len(hypothesis.assignment):,} observations (assignment in the result)"
    return head + "\n" + _assignment_text(hypothesis.assignment, width)


def _suptitle(solution: Solution, shown: int) -> str:
    n = len(solution.hypotheses)
    if n == 1 and "candidates" not in solution.statistics:  # no correspondence search ran
        return f"known correspondence · level {solution.consistency}"
    if n == 0:
        text = "no hypothesis survived"
        text += ": the log is proven inconsistent" if solution.complete else ""
    else:
        text = f"{n} hypothes{'is' if n == 1 else 'es'} survived"
    if n > shown:
        text += f" (+{n - shown} more not shown)"
    if solution.complete:
        return text + " · search complete"
    return text + "\nsearch INCOMPLETE: limits dropped hypotheses, the true one may be missing"


def plot_solution(
    solution: Solution,
    truth: GroundTruth | None = None,
    *,
    max_hypotheses: int = 12,
    figsize: tuple[float, float] | None = None,
) -> Figure:
    """A figure of a solve's surviving hypotheses.

    One panel when a single hypothesis survived; otherwise small multiples (a grid, best
    rank first) of at most ``max_hypotheses`` panels sharing the same axes limits, each
    titled with its rank, number of landmarks, status and assignment (the landmark of
    each observation, in log order).  The figure title gives the number of hypotheses,
    whether the search was complete, and how many were left out.

    The figure is created with :mod:`matplotlib.pyplot` (so ``plt.show()`` can display
    it) but never shown here; pass it to :func:`save_figure`, which also closes it.
    """
    import matplotlib.pyplot as plt

    if max_hypotheses < 1:
        raise ValueError(f"max_hypotheses must be at least 1, got {max_hypotheses}")
    shown = solution.hypotheses[:max_hypotheses]
    classes = {c for h in shown for c in h.landmark_classes}
    if truth is not None:
        classes |= set(truth.landmark_classes)
    colors = class_color_map(classes)

    # Figure sizes follow the scene's aspect ratio so that equal-aspect panels fill them.
    # Panels are anchored at the top: constrained layout measures titles from where the
    # axes would be before its aspect shrinks it, so a centred (lowered) axes lets titles
    # collide with the figure title.
    if shown:
        extent = _union_extent(_hypothesis_extent(h, truth) for h in shown)
    else:
        extent = scene_extent([], [] if truth is None else [truth.poses_xyt, truth.landmarks_xy])
    aspect = (extent[3] - extent[2]) / (extent[1] - extent[0])

    if len(shown) <= 1:
        height = min(max(5.3 * aspect, 3.0), 9.0) + 1.4
        long_run = bool(shown) and len(shown[0].pose_ids) > WIDTH_PANEL_POSES
        if long_run:
            fig, (ax, aw) = plt.subplots(
                2,
                1,
                figsize=figsize or (8.0, height + 2.6),
                layout="constrained",
                height_ratios=(height, 2.2),
            )
        else:
            fig = plt.figure(figsize=figsize or (8.0, height), layout="constrained")
            ax = fig.add_subplot()
        ax.set_anchor("N")
        if shown:
            title = _panel_title(1, shown[0], 80, _MAX_TITLE_OBSERVATIONS)
            plot_hypothesis_on_axes(ax, shown[0], truth, title=title, class_colors=colors)
        if long_run:
            plot_widths_on_axes(aw, shown[0], title="pose box widths along the run")
        else:
            if truth is not None:
                _draw_truth(ax, truth, 0.8 * FAN_RADIUS * (extent[1] - extent[0]), None, None)
            _finish_axes(ax, extent, None)
            ax.text(
                0.5,
                0.5,
                "no hypothesis to draw",
                transform=ax.transAxes,
                ha="center",
                va="center",
                fontsize="large",
                color="0.4",
            )
        fig.suptitle(_suptitle(solution, len(shown)))
        return fig

    ncols = math.ceil(math.sqrt(len(shown)))
    nrows = math.ceil(len(shown) / ncols)
    fig, axes = plt.subplots(
        nrows,
        ncols,
        figsize=figsize or (3.9 * ncols, (min(max(2.8 * aspect, 1.4), 5.0) + 1.0) * nrows + 1.0),
        layout="constrained",
        squeeze=False,
    )
    fig.get_layout_engine().set(hspace=0.05, wspace=0.04)  # keep titles off the row above
    width = 44 if ncols <= 3 else 36
    any_unbounded = fans = truth_poses = truth_landmarks = False
    for rank, (ax, hypothesis) in enumerate(zip(axes.flat, shown, strict=False), start=1):
        ax.set_anchor("N")
        drawn = plot_hypothesis_on_axes(
            ax,
            hypothesis,
            truth,
            title=_panel_title(rank, hypothesis, width),
            legend=False,
            extent=extent,
            class_colors=colors,
        )
        any_unbounded |= any(r.get_linestyle() == "--" for r in drawn["pose_boxes"])
        any_unbounded |= any(r.get_linestyle() == "--" for r in drawn["landmark_boxes"])
        fans |= bool(drawn["heading_fans"])
        truth_poses |= bool(drawn["truth_poses"])
        truth_landmarks |= bool(drawn["truth_landmarks"])
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    handles = _legend_handles(
        colors,
        poses=True,
        fans=fans,
        unbounded=any_unbounded,
        truth_poses=truth_poses,
        truth_landmarks=truth_landmarks,
    )
    fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=min(len(handles), 4),
        fontsize="small",
        frameon=False,
    )
    fig.suptitle(_suptitle(solution, len(shown)))
    return fig


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: int = 150) -> None:
    """Write ``fig`` to ``path`` atomically (png, pdf or svg, from the suffix), then close it.

    The image is rendered into a temporary file in the target's folder and renamed over
    the target only when complete, so readers never see a partial image.  The saved area
    is the figure's tight bounding box (so legends outside the axes are kept whole).

    Raises
    ------
    ValueError
        If the suffix is not ``.png``, ``.pdf`` or ``.svg`` (the figure stays open).
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _FORMATS:
        raise ValueError(
            f"cannot infer the image format of {os.fspath(path)!r}: "
            f"use one of {', '.join(_FORMATS)}"
        )
    with atomic_open(path, "wb") as stream:
        # A tight bounding box keeps outside legends whole whatever the dpi's text metrics.
        fig.savefig(stream, format=_FORMATS[suffix], dpi=dpi, bbox_inches="tight", pad_inches=0.1)
    import matplotlib.pyplot as plt

    plt.close(fig)


def _rgb(color: Any) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(color)


def _truth_handles(poses: bool, landmarks: bool) -> list:
    """Legend entries for the truth markers that were drawn."""
    from matplotlib.lines import Line2D

    handles = []
    if poses:
        handles.append(
            Line2D([], [], color=TRUTH_COLOR, marker="o", markersize=3, label="true pose")
        )
    if landmarks:
        handles.append(
            Line2D([], [], color=TRUTH_COLOR, marker="x", linestyle="none", markersize=6,
                   markeredgewidth=1.5, label="true landmark")
        )  # fmt: skip
    return handles
