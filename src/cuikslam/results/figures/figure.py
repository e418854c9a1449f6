"""The figure layer of :mod:`cuikslam.results.figures`: a whole figure of a solve's
result (one panel, or small multiples), and writing it atomically; pyplot is loaded when a
figure is made, never at import."""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from cuikslam._atomic import atomic_open
from cuikslam.results.figures.artists import (
    FAN_RADIUS,
    _draw_truth,
    _finish_axes,
    _legend_handles,
    class_color_map,
)
from cuikslam.results.figures.axes import plot_hypothesis_on_axes, plot_widths_on_axes
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    _hypothesis_extent,
    _union_extent,
    drawn_poses,
    scene_extent,
    widest_stretch,
)
from cuikslam.results.solution import Hypothesis, Solution

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["WIDTH_PANEL_POSES", "plot_solution", "save_figure"]

WIDTH_PANEL_POSES = 60
"""A one-hypothesis figure of more poses than this gets a panel of widths over time."""
_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}


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
        text = (
            "no hypothesis survived: the log is proven inconsistent"
            if solution.refuted
            else "no hypothesis reported"
        )
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
            fig = plt.figure(figsize=figsize or (8.0, height + 3.2), layout="constrained")
            grid = fig.add_gridspec(2, 2, height_ratios=(height, 2.8), width_ratios=(3, 2))
            ax = fig.add_subplot(grid[0, :])
            aw, az = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
        else:
            fig = plt.figure(figsize=figsize or (8.0, height), layout="constrained")
            ax = fig.add_subplot()
        ax.set_anchor("N")
        if shown:
            title = _panel_title(1, shown[0], 80, _MAX_TITLE_OBSERVATIONS)
            plot_hypothesis_on_axes(ax, shown[0], truth, title=title, class_colors=colors)
        if long_run:
            plot_widths_on_axes(aw, shown[0], title="pose box widths along the run")
            _zoom(az, shown[0], truth, colors)
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


def _zoom(ax, hypothesis: Hypothesis, truth: GroundTruth | None, colors: dict) -> None:
    """The widest stretch of a long run, every box drawn, at its own scale."""
    from dataclasses import replace

    part = widest_stretch(hypothesis)
    stretch = replace(hypothesis, pose_ids=hypothesis.pose_ids[part], poses=hypothesis.poses[part])
    points = []
    if truth is not None:
        ids = set(stretch.pose_ids)
        points.append([p for i, p in zip(truth.pose_ids, truth.poses_xyt, strict=True) if i in ids])
    extent = scene_extent([stretch.poses], points)
    first, last = stretch.pose_ids[0], stretch.pose_ids[-1]
    plot_hypothesis_on_axes(
        ax, stretch, truth, title=f"the widest stretch: poses {first}–{last}", legend=False,
        extent=extent, class_colors=colors, max_pose_boxes=None, show_labels=False,
    )  # fmt: skip


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
