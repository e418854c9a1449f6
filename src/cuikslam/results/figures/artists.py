"""Drawing primitives shared by the layers of :mod:`cuikslam.results.figures`: colours,
rectangles (dashed when clipped), the truth's markers, legends, the finish of an axes."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.results.figures.geometry import Extent, _clip_boxes

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["FAN_RADIUS", "POSE_COLOR", "TRUTH_COLOR", "class_color_map"]

POSE_COLOR = "tab:blue"
TRUTH_COLOR = "black"
FAN_RADIUS = 0.05
"""Heading-fan radius as a fraction of the scene extent (the larger side)."""


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


def _rgb(color: Any) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(color)
