"""The figure layer of :mod:`cuikslam.results.figures`: a whole figure of a solve's
result (one panel, or small multiples), and writing it atomically; pyplot is loaded when a
figure is made, never at import."""

from __future__ import annotations

import math
import os
import textwrap
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cuikslam._atomic import atomic_open
from cuikslam.outcome.solution import Envelope, Hypothesis, Solution, no_hypothesis
from cuikslam.outcome.summary import ambiguous_observations
from cuikslam.results.figures.artists import (
    FAN_RADIUS,
    _draw_truth,
    _drawn_kinds,
    _finish_axes,
    _legend_handles,
    _place_legend,
    class_color_map,
)
from cuikslam.results.figures.axes import plot_hypothesis_on_axes, plot_widths_on_axes
from cuikslam.results.figures.envelope import plot_envelope_on_axes
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    Extent,
    _envelope_extent,
    _hypothesis_extent,
    _union_extent,
    drawn_poses,
    scene_extent,
    widest_stretch,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["DPI", "WIDTH_PANEL_POSES", "plot_solution", "save_figure"]

WIDTH_PANEL_POSES = 60
"""A one-hypothesis figure of more poses than this gets a panel of widths over time."""
_FORMATS = {".png": "png", ".pdf": "pdf", ".svg": "svg"}
DPI = 200
"""Pixels per inch of the PNG figures: above the 150 a printed figure needs at its size."""
PNG_COMPRESS_LEVEL = 1
"""zlib's level for PNG files: the seed's figure (1,680 pixels wide) encodes in 0.03 s
against 0.15 s at Pillow's default 6, for a file a seventh larger (164 kB, 144 kB)."""


def _assignment_text(
    assignment: Sequence[str], width: int, max_lines: int = 3, marked: Collection[int] = ()
) -> str:
    """``obs→L: 1 1 2 …`` with the landmark ids' common non-digit prefix moved to the head;
    the observations in ``marked`` in brackets (``[2]``)."""
    if not assignment:
        return "no observations"
    ids = [str(a) for a in assignment]
    prefix = _common_prefix(ids).rstrip("0123456789")
    if prefix and all(len(a) > len(prefix) for a in ids):
        head, tokens = f"obs→{prefix}:", [a[len(prefix) :] for a in ids]
    else:
        head, tokens = "obs→landmark:", ids
    tokens = [f"[{t}]" if i in marked else t for i, t in enumerate(tokens)]
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
    rank: int,
    hypothesis: Hypothesis,
    width: int,
    max_observations: int | None = None,
    marked: Collection[int] = (),
) -> str:
    """Rank, landmarks, status, level (and poses drawn, for long runs), then the
    assignment (``marked`` observations in brackets), or only its length beyond
    ``max_observations`` observations."""
    n = hypothesis.n_landmarks
    head = f"#{rank} · {n} landmark{'s' if n != 1 else ''} · {hypothesis.status}"
    if hypothesis.consistency:
        head += f" · {hypothesis.consistency}"
    poses = len(hypothesis.pose_ids)
    if poses > MAX_POSE_BOXES:
        head += f" · {poses:,} poses, {len(drawn_poses(hypothesis.poses))} boxes drawn"
    if max_observations is not None and len(hypothesis.assignment) > max_observations:
        return head + f"\n{len(hypothesis.assignment):,} observations (assignment in the result)"
    return head + "\n" + _assignment_text(hypothesis.assignment, width, marked=set(marked))


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
    text += "\nsearch INCOMPLETE: limits dropped hypotheses, the true one may be missing"
    if solution.envelope is not None:
        text += "\n(the grey envelope holds the truth whatever the correspondence)"
    return text


def plot_solution(
    solution: Solution,
    truth: GroundTruth | None = None,
    *,
    max_hypotheses: int = 12,
    figsize: tuple[float, float] | None = None,
    observation_poses: Sequence[int] | None = None,
) -> Figure:
    """A figure of a solve's surviving hypotheses and, with unknown correspondence, its
    envelope.

    One panel when a single hypothesis survived; otherwise small multiples (a grid, best
    rank first) of at most ``max_hypotheses`` panels sharing the same axes limits, each
    titled with its rank, number of landmarks, status and assignment (the landmark of
    each observation, in log order).  The figure title gives the number of hypotheses,
    whether the search was complete, and how many were left out.  The envelope
    (``solution.envelope``: each pose's box whatever the correspondence) is drawn in grey
    under every panel; with no hypothesis (a search stopped on its budget before finding
    one) it is drawn alone, with where each sighted landmark lies: the guaranteed answer.
    The legend sits outside the panels.

    Parameters
    ----------
    solution : Solution
        A solve's result.
    truth : GroundTruth, optional
        Drawn as points (see :func:`plot_hypothesis_on_axes`).
    max_hypotheses : int
        Panels at most.
    figsize : (float, float), optional
        The figure size in inches; default from the scene's aspect ratio.
    observation_poses : sequence of int, optional
        The pose id of each observation (log order): the panels draw the sightings, those
        the survivors assign differently in red (see :func:`plot_hypothesis_on_axes`).

    The figure is created with :mod:`matplotlib.pyplot` (so ``plt.show()`` can display
    it) but never shown here; pass it to :func:`save_figure`, which also closes it.
    """
    import matplotlib.pyplot as plt

    if max_hypotheses < 1:
        raise ValueError(f"max_hypotheses must be at least 1, got {max_hypotheses}")
    shown = solution.hypotheses[:max_hypotheses]
    colors = class_color_map(_classes(shown, truth))
    extent = _solution_extent(shown, solution.envelope, truth)
    aspect = (extent[3] - extent[2]) / (extent[1] - extent[0])
    panel = _Panel(solution, truth, extent, colors, observation_poses)

    # Figure sizes follow the scene's aspect ratio so that equal-aspect panels fill them.
    # Panels are anchored at the top: constrained layout measures titles from where the
    # axes would be before its aspect shrinks it, so a centred (lowered) axes lets titles
    # collide with the figure title.
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
        hypothesis = shown[0] if shown else None
        title = _panel_title(1, hypothesis, 80, _MAX_TITLE_OBSERVATIONS) if hypothesis else None
        drawn = panel.draw(ax, hypothesis, title)
        if long_run:
            plot_widths_on_axes(aw, shown[0], title="pose box widths along the run")
            _zoom(az, shown[0], truth, colors)
        _place_legend(ax, _legend_handles(_used_colors(colors, shown), _drawn_kinds(*drawn)))
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
    # keep titles off the row above, and the x labels off the legend below
    fig.get_layout_engine().set(hspace=0.05, wspace=0.04, h_pad=0.1)
    width = 44 if ncols <= 3 else 36
    marked = set(ambiguous_observations(solution))
    drawn = []
    for rank, (ax, hypothesis) in enumerate(zip(axes.flat, shown, strict=False), start=1):
        ax.set_anchor("N")
        drawn += panel.draw(ax, hypothesis, _panel_title(rank, hypothesis, width, None, marked))
    for ax in axes.flat[len(shown) :]:
        ax.set_visible(False)
    _figure_legend(fig, _legend_handles(_used_colors(colors, shown), _drawn_kinds(*drawn)))
    fig.suptitle(_suptitle(solution, len(shown)))
    return fig


def _classes(shown: Sequence[Hypothesis], truth: GroundTruth | None) -> set[str]:
    classes = {c for h in shown for c in h.landmark_classes}
    return classes | set(truth.landmark_classes) if truth is not None else classes


def _used_colors(colors: dict[str, Any], shown: Sequence[Hypothesis]) -> dict[str, Any]:
    """The colours of the landmark classes the panels draw boxes of (legend entries)."""
    used = {c for h in shown for c in h.landmark_classes}
    return {name: color for name, color in colors.items() if name in used}


def _solution_extent(
    shown: Sequence[Hypothesis], envelope: Envelope | None, truth: GroundTruth | None
) -> Extent:
    """The extent shared by a figure's panels: every hypothesis shown and the truth drawn;
    with none, the envelope's boxes. (Panels of hypotheses frame them: an envelope box
    wider than the frame, as after a search cut short, runs past its edges.)"""
    if shown:
        return _union_extent(_hypothesis_extent(h, truth) for h in shown)
    if envelope is not None:
        return _envelope_extent(envelope, truth)
    return scene_extent([], [] if truth is None else [truth.poses_xyt, truth.landmarks_xy])


@dataclass
class _Panel:
    """What every panel of a result's figure shares: its envelope, truth, extent, colours."""

    solution: Solution
    truth: GroundTruth | None
    extent: Extent
    colors: dict[str, Any]
    observation_poses: Sequence[int] | None = None

    def draw(self, ax: Axes, hypothesis: Hypothesis | None, title: str | None) -> list[dict]:
        """The envelope (if any), then ``hypothesis``; with neither, why there is nothing.

        Returns the artists of each layer drawn (:func:`plot_hypothesis_on_axes`)."""
        envelope = self.solution.envelope
        drawn = []
        if envelope is not None:
            alone = hypothesis is None
            drawn.append(
                plot_envelope_on_axes(
                    ax, envelope, self.truth if alone else None, landmarks=alone,
                    extent=self.extent, title=ENVELOPE_TITLE if alone else None,
                )
            )  # fmt: skip
        if hypothesis is not None:
            drawn.append(
                plot_hypothesis_on_axes(
                    ax, hypothesis, self.truth, title=title, legend=False, extent=self.extent,
                    class_colors=self.colors, observation_poses=self.observation_poses,
                    highlight=ambiguous_observations(self.solution),
                )
            )  # fmt: skip
        elif envelope is None:
            if self.truth is not None:
                tick = 0.8 * FAN_RADIUS * (self.extent[1] - self.extent[0])
                drawn.append(_draw_truth(ax, self.truth, tick, None, None))
            _finish_axes(ax, self.extent, None)
            ax.text(
                0.5, 0.5, f"nothing to draw: {no_hypothesis(self.solution)}",
                transform=ax.transAxes, ha="center", va="center", wrap=True, color="0.4",
            )  # fmt: skip
        return drawn


ENVELOPE_TITLE = "the envelope: each pose, and each sighted landmark,\nwhatever the correspondence"
"""The title of a panel that draws the envelope alone (a result with no hypothesis)."""


def _figure_legend(fig: Figure, handles: list) -> Any:
    """A figure legend below the panels, never over them."""
    return fig.legend(
        handles=handles,
        loc="outside lower center",
        ncols=min(len(handles), 4),
        fontsize="small",
        frameon=False,
    )


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


def save_figure(
    fig: Figure, path: str | os.PathLike[str], dpi: int = DPI, *, tight: bool = True
) -> None:
    """Write ``fig`` to ``path`` atomically (png, pdf or svg, from the suffix), then close it.

    The image is rendered into a temporary file in the target's folder and renamed over
    the target only when complete, so readers never see a partial image.  A PNG records
    its ``dpi``, so that it is shown at the figure's size.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : str or os.PathLike
        The file; its suffix (``.png``, ``.pdf``, ``.svg``) chooses the format.
    dpi : int
        Pixels per inch of a PNG (:data:`DPI`: fit for print at the figure's size).
    tight : bool
        Save the figure's tight bounding box (so that legends outside the axes are kept
        whole), at the cost of drawing it twice; False saves the figure as laid out (for
        a figure whose layout keeps everything inside, as :func:`plot_known_and_unknown`).

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
    crop = {"bbox_inches": "tight", "pad_inches": 0.1} if tight else {}
    png = {"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}} if suffix == ".png" else {}
    with atomic_open(path, "wb") as stream:
        fig.savefig(stream, format=_FORMATS[suffix], dpi=dpi, **crop, **png)
    import matplotlib.pyplot as plt

    plt.close(fig)
