"""The figure of ``cuikslam evaluate``: boxes against the truth, and widths over time."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cuikslam.results.evaluate import Evaluation
from cuikslam.results.figures import POSE_COLOR, TRUTH_COLOR, scene_extent
from cuikslam.results.solution import Solution
from cuikslam.simulate.truth import GroundTruth

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_evaluation"]

MISS_COLOR = "tab:red"


def _box_polygons(xy: np.ndarray) -> np.ndarray:
    """(n, 2, 2) x/y boxes as (n, 4, 2) rectangle corners (finite boxes only)."""
    (x0, x1), (y0, y1) = xy[:, 0].T, xy[:, 1].T
    return np.stack([np.column_stack(c) for c in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))], axis=1)


def plot_evaluation(solution: Solution, truth: GroundTruth, ev: Evaluation) -> Figure:
    """Left: the evaluated hypothesis' pose and landmark boxes, the true trajectory and
    landmarks, and the poses whose truth misses its box (red). Right: the pose box widths
    (x, y; θ on its own axis) along the run, with the poses that lacked truth shaded.

    The figure is not shown; pass it to :func:`cuikslam.results.figures.save_figure`.
    """
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    h = solution.hypotheses[ev.evaluated_rank - 1]
    fig, (ax, aw) = plt.subplots(
        1, 2, figsize=(13, 5.5), layout="constrained", width_ratios=(1.1, 1)
    )

    finite = np.isfinite(h.poses[:, :2]).all(axis=(1, 2))
    ax.add_collection(
        PolyCollection(
            _box_polygons(h.poses[finite, :2]),
            facecolors="none",
            edgecolors=POSE_COLOR,
            linewidths=0.4,
            alpha=0.6,
            label="pose boxes",
        )
    )
    marks = h.landmarks[np.isfinite(h.landmarks).all(axis=(1, 2))]
    if len(marks):
        ax.add_collection(
            PolyCollection(
                _box_polygons(marks),
                facecolors="tab:orange",
                edgecolors="tab:orange",
                alpha=0.35,
                label="landmark boxes",
            )
        )
    order = {p: i for i, p in enumerate(truth.pose_ids)}
    rows = [order[p] for p in h.pose_ids if p in order]
    path = truth.poses_xyt[rows] if rows else np.zeros((0, 3))
    ax.plot(path[:, 0], path[:, 1], ".", color=TRUTH_COLOR, markersize=1.5, label="true poses")
    if len(truth.landmarks_xy):
        ax.plot(
            truth.landmarks_xy[:, 0],
            truth.landmarks_xy[:, 1],
            "x",
            color=TRUTH_COLOR,
            markersize=6,
            label="true landmarks",
        )
    missed = [order[p] for p, ok in zip(ev.pose_ids, ev.pose_inside, strict=True) if ok is False]
    if missed:
        pts = truth.poses_xyt[missed]
        ax.plot(pts[:, 0], pts[:, 1], "o", color=MISS_COLOR, markersize=4, label="truth outside")
    extent = scene_extent([h.poses[finite], marks], [path[:, :2], truth.landmarks_xy])
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, linewidth=0.4, alpha=0.4)
    ax.legend(fontsize="small", loc="best")
    ax.set_title(
        f"hypothesis {ev.evaluated_rank}: {ev.poses_inside} of {ev.poses_with_truth} poses "
        f"with truth inside ({ev.poses_without_truth} without truth)",
        fontsize="small",
    )

    index = np.arange(len(ev.pose_ids))
    aw.plot(index, ev.pose_widths[:, 0], lw=0.8, label="x width [m]")
    aw.plot(index, ev.pose_widths[:, 1], lw=0.8, label="y width [m]")
    at = aw.twinx()
    at.plot(index, ev.pose_widths[:, 2], lw=0.8, color="tab:green", label="θ width [rad]")
    at.set_ylabel("θ width [rad]")
    without = np.array([v is None for v in ev.pose_inside])
    if without.any():
        aw.fill_between(
            index, 0, 1, where=without, transform=aw.get_xaxis_transform(),
            color="0.85", step="mid", label="no truth",
        )  # fmt: skip
    bad = [i for i, v in enumerate(ev.pose_inside) if v is False]
    for i in bad[:200]:
        aw.axvline(i, color=MISS_COLOR, lw=0.5, alpha=0.6)
    aw.set_xlabel("pose (in log order)")
    aw.set_ylabel("width [m]")
    aw.grid(True, linewidth=0.4, alpha=0.4)
    handles = aw.get_legend_handles_labels()[0] + at.get_legend_handles_labels()[0]
    aw.legend(handles=handles, fontsize="small", loc="upper left")
    aw.set_title("box widths along the run", fontsize="small")
    return fig
