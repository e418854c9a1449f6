"""The figure of ``cuikslam evaluate``: boxes against the truth, and widths over time."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cuikslam.outcome.solution import Solution
from cuikslam.results.evaluate import Evaluation
from cuikslam.results.figures import class_color_map, plot_widths_on_axes
from cuikslam.results.figures.artists import (
    _drawn_kinds,
    _legend_above,
    _legend_handles,
    _place_legend,
)
from cuikslam.results.figures.figure import _Panel, _solution_extent
from cuikslam.simulate.truth import GroundTruth

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["plot_evaluation"]

MISS_COLOR = "tab:red"
MAX_MISS_LINES = 200
"""Poses whose truth misses its box marked on the widths panel at most."""


def plot_evaluation(solution: Solution, truth: GroundTruth, ev: Evaluation) -> Figure:
    """Left: the evaluated hypothesis as :func:`~cuikslam.results.figures.plot_solution`
    draws it (over the envelope, with unknown correspondence; on a long run every k-th
    pose box, the true path through every true pose), and the true poses that miss their
    box (red, all of them). Right: the pose box widths
    (x, y; θ on its own axis) along the run, the poses without truth shaded and those whose
    truth misses its box marked. Legends sit outside the plots.

    The figure is not shown; pass it to :func:`cuikslam.results.figures.save_figure`.
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    h = solution.hypotheses[ev.evaluated_rank - 1]
    fig, (ax, aw) = plt.subplots(
        1, 2, figsize=(13, 5.5), layout="constrained", width_ratios=(1.25, 1)
    )
    title = (
        f"hypothesis {ev.evaluated_rank}: {ev.poses_inside} of {ev.poses_with_truth} poses "
        f"with truth inside ({ev.poses_without_truth} without truth)"
    )
    colors = class_color_map(h.landmark_classes)
    extent = _solution_extent([h], solution.envelope, truth)
    drawn = _Panel(solution, truth, extent, colors).draw(ax, h, title)
    order = {p: i for i, p in enumerate(truth.pose_ids)}
    missed = [order[p] for p, ok in zip(ev.pose_ids, ev.pose_inside, strict=True) if ok is False]
    handles = _legend_handles(colors, _drawn_kinds(*drawn))
    if missed:
        pts = truth.poses_xyt[missed]
        ax.plot(pts[:, 0], pts[:, 1], "o", color=MISS_COLOR, markersize=4, zorder=8)
        handles.append(
            Line2D([], [], color=MISS_COLOR, marker="o", linestyle="none", markersize=4,
                   label="true pose outside its box")
        )  # fmt: skip
    _place_legend(ax, handles)

    lines = plot_widths_on_axes(aw, h)["lines"]
    index = np.arange(len(ev.pose_ids))
    extra = []
    without = np.array([v is None for v in ev.pose_inside])
    if without.any():
        aw.fill_between(
            index, 0, 1, where=without, transform=aw.get_xaxis_transform(),
            color="0.85", step="mid", zorder=0,
        )  # fmt: skip
        extra.append(Patch(color="0.85", label="no truth"))
    bad = [i for i, v in enumerate(ev.pose_inside) if v is False]
    for i in bad[:MAX_MISS_LINES]:
        aw.axvline(i, color=MISS_COLOR, lw=0.5, alpha=0.6)
    if bad:
        extra.append(Line2D([], [], color=MISS_COLOR, lw=0.5, label="truth outside"))
    _legend_above(aw, lines + extra, "box widths along the run")
    return fig
