"""Drawing primitives shared by the layers of :mod:`cuikslam.results.figures`: colours,
rectangles (dashed when clipped), the truth's markers, legends, the finish of an axes."""

from __future__ import annotations

from collections.abc import Collection, Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.results.figures.geometry import Extent, _clip_boxes

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["ENVELOPE_COLOR", "FAN_RADIUS", "POSE_COLOR", "TRUTH_COLOR", "class_color_map"]

POSE_COLOR = "tab:blue"
TRUTH_COLOR = "black"
ENVELOPE_COLOR = "0.6"
"""The envelope's outlines (boxes that hold the truth whatever the correspondence)."""
ENVELOPE_WIDTH = 0.7
SIGHTING_COLOR = "0.55"
AMBIGUOUS_COLOR = "tab:red"
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
    landmark_rows: Sequence[int] | None,
    ticked: Collection[int] | None = None,
) -> dict[str, list]:
    """Truth poses (dots + heading ticks) and landmarks (crosses).

    ``pose_ids`` and ``landmark_rows`` (rows of ``truth.landmarks_xy``) select what is
    drawn (None: all). With ``ticked``, only those poses get a dot and a tick (the poses
    whose boxes are drawn), and a thin line (the true path) runs through all of them.
    """
    from matplotlib.collections import LineCollection

    artists: dict[str, list] = {
        "truth_poses": [],
        "truth_headings": [],
        "truth_path": [],
        "truth_landmarks": [],
    }
    poses = np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3)
    keep = [i for i, pid in enumerate(truth.pose_ids) if pose_ids is None or pid in pose_ids]
    dotted = [i for i in keep if ticked is None or truth.pose_ids[i] in ticked]
    if len(dotted) < len(keep):
        (line,) = ax.plot(
            poses[keep, 0], poses[keep, 1], color=TRUTH_COLOR, linewidth=0.6, alpha=0.6, zorder=5
        )
        artists["truth_path"].append(line)
    poses = poses[dotted]
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
    if landmark_rows is not None:
        landmarks = landmarks[list(landmark_rows)]
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


def _draw_sightings(
    ax: Axes,
    segments: np.ndarray,
    highlight: np.ndarray,
) -> dict[str, list]:
    """The kinematic graph's observation edges: ``segments`` (k, 2, 2) from a pose to the
    landmark it sees, thin; those where ``highlight`` (k,) is true in the ambiguity colour."""
    from matplotlib.collections import LineCollection

    artists: dict[str, list] = {"sightings": [], "ambiguous_sightings": []}
    if len(segments) and not highlight.all():
        plain = LineCollection(
            segments[~highlight], colors=SIGHTING_COLOR, linewidths=0.6, alpha=0.7, zorder=2.5
        )
        ax.add_collection(plain)
        artists["sightings"].append(plain)
    if highlight.any():
        strong = LineCollection(
            segments[highlight], colors=AMBIGUOUS_COLOR, linewidths=1.4, zorder=4.5
        )
        ax.add_collection(strong)
        artists["ambiguous_sightings"].append(strong)
    return artists


def _truth_handles(kinds: Collection[str]) -> list:
    """Legend entries for the truth markers that were drawn (``kinds``: artist kinds)."""
    from matplotlib.lines import Line2D

    handles = []
    if "truth_poses" in kinds:
        handles.append(
            Line2D([], [], color=TRUTH_COLOR, marker="o", markersize=3, label="true pose")
        )
    if "truth_path" in kinds:
        handles.append(
            Line2D([], [], color=TRUTH_COLOR, linewidth=0.6, alpha=0.6, label="true path")
        )
    if "truth_landmarks" in kinds:
        handles.append(
            Line2D([], [], color=TRUTH_COLOR, marker="x", linestyle="none", markersize=6,
                   markeredgewidth=1.5, label="true landmark")
        )  # fmt: skip
    return handles


def _drawn_kinds(*drawn: dict[str, list]) -> set[str]:
    """The artist kinds that some of the ``drawn`` dicts hold an artist of, plus
    ``"unbounded"`` when a box was clipped (drawn dashed)."""
    kinds = {kind for d in drawn for kind, artists in d.items() if artists}
    boxes = ("pose_boxes", "landmark_boxes", "envelope_poses", "envelope_landmarks")
    if any(r.get_linestyle() == "--" for d in drawn for k in boxes for r in d.get(k, [])):
        kinds.add("unbounded")
    return kinds


def _legend_handles(colors: dict[str, Any], kinds: Collection[str]) -> list:
    """Legend entries: the landmark classes in ``colors``, then each kind of artist drawn
    (``kinds``, see :func:`_drawn_kinds`)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list = [
        Patch(facecolor=color, edgecolor=color, alpha=0.5, label=f"landmark: {name}")
        for name, color in colors.items()
    ]
    if "pose_boxes" in kinds:
        handles.append(Patch(facecolor="none", edgecolor=POSE_COLOR, label="pose box"))
    if "heading_fans" in kinds:
        handles.append(
            Patch(facecolor=POSE_COLOR, alpha=0.25, edgecolor="none", label="heading interval")
        )
    if "sightings" in kinds:
        handles.append(Line2D([], [], color=SIGHTING_COLOR, linewidth=0.6, label="sighting"))
    if "ambiguous_sightings" in kinds:
        handles.append(
            Line2D([], [], color=AMBIGUOUS_COLOR, linewidth=1.4,
                   label="sighting the survivors assign differently")
        )  # fmt: skip
    if "envelope_poses" in kinds:
        past = ",\nsome past the frame" if "envelope_past_frame" in kinds else ""
        handles.append(
            Patch(facecolor="none", edgecolor=ENVELOPE_COLOR, linewidth=ENVELOPE_WIDTH,
                  label=f"pose envelope (any correspondence{past})")
        )  # fmt: skip
    if "envelope_landmarks" in kinds:
        handles.append(
            Patch(facecolor="none", edgecolor=ENVELOPE_COLOR, linewidth=ENVELOPE_WIDTH,
                  linestyle=":", label="sighted landmark envelope")
        )  # fmt: skip
    if "unbounded" in kinds:
        handles.append(Line2D([], [], color="0.3", linestyle="--", label="unbounded (clipped)"))
    handles += _truth_handles(kinds)
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
    if title is not None:  # at a fixed height: nothing sits on top of the axes to avoid
        ax.set_title(title, fontsize="small", y=1.0)


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


def _legend_above(ax: Axes, handles: list, title: str | None) -> Any:
    """An axes legend in one row above the plot, under ``title`` (which it replaces as the
    axes title), so that it never hides the curves."""
    return ax.legend(
        handles=handles,
        loc="lower left",
        bbox_to_anchor=(0.0, 1.01),
        borderaxespad=0.0,
        ncols=len(handles),
        fontsize="small",
        title=title,
        title_fontsize="small",
        alignment="left",
        frameon=False,
        handlelength=1.5,
        columnspacing=1.0,
    )


def _rgb(color: Any) -> tuple[float, float, float]:
    from matplotlib.colors import to_rgb

    return to_rgb(color)
