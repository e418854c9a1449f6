"""One figure of a log solved twice: with its landmark ids (known correspondence) and
without (every hypothesis that survives the correspondence search), as the seed paper
shows its experiment: the known-correspondence solve beside one panel per surviving
kinematic graph, each with its sightings, those the survivors assign differently in red,
over the search's envelope. ``cuikslam paper`` draws it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from cuikslam.results.figures.artists import _drawn_kinds, _legend_handles, class_color_map
from cuikslam.results.figures.figure import (
    _classes,
    _Panel,
    _panel_title,
    _solution_extent,
    _suptitle,
    _union_extent,
    _used_colors,
)
from cuikslam.results.figures.geometry import Extent
from cuikslam.results.solution import Hypothesis, Solution
from cuikslam.results.summary import ambiguous_observations

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["plot_known_and_unknown"]

AXES_INCHES = 3.2
"""The width of a panel's plot (its height follows the scene's aspect ratio)."""
_LINE_INCHES = 0.16
"""The height of a title line (``small`` text)."""
_PAD_INCHES = 0.08
"""Between the figure's edge and its suptitle or legend, and above the legend."""
_Y_LABELS_INCHES = 0.55
"""Room left of a plot for its y tick labels and y label."""
_X_LABELS_INCHES = 0.45
"""Room below a plot for its x tick labels and x label."""
_GAP_INCHES = 0.14
"""Between two panels of survivors (their y tick labels hidden: the limits are shared)."""
_TITLE_WIDTH = 42
"""Characters per line of a panel's title."""


def plot_known_and_unknown(
    known: Solution,
    unknown: Solution | None,
    truth: GroundTruth | None = None,
    *,
    observation_poses: Sequence[int] | None = None,
    max_hypotheses: int = 8,
) -> Figure:
    """The known-correspondence solve beside the survivors of the unknown-correspondence one.

    Panels share their axes limits: first ``known``'s best hypothesis, then each of
    ``unknown``'s reported hypotheses (at most ``max_hypotheses``, best rank first) over
    its envelope, or its envelope alone when it reports none (a search stopped on its
    budget). Up to three survivors the panels make one row; beyond, the survivors make two
    rows right of the known panel. Each survivor's title gives its rank, landmarks, status
    and assignment (the landmark of each observation, in log order; the observations the
    survivors assign differently in brackets, their sightings drawn in red). One legend
    sits below the panels.

    The layout is fixed in inches (no layout engine: drawing it is one pass, which keeps
    ``cuikslam paper``, which draws it while it solves, fast); save it with
    ``save_figure(fig, path, tight=False)``.

    Parameters
    ----------
    known : Solution
        A known-correspondence solve (one hypothesis).
    unknown : Solution or None
        The same log solved without landmark ids; None draws the known panel alone.
    truth : GroundTruth, optional
        Drawn in every panel, its landmarks paired with each hypothesis' by association.
    observation_poses : sequence of int, optional
        The pose of each observation (log order): draws the sightings.
    max_hypotheses : int
        Survivor panels at most.

    Returns
    -------
    matplotlib.figure.Figure
        Not shown; pass it to :func:`save_figure`.
    """
    import matplotlib.pyplot as plt

    if max_hypotheses < 1:
        raise ValueError(f"max_hypotheses must be at least 1, got {max_hypotheses}")
    survivors = [] if unknown is None else unknown.hypotheses[:max_hypotheses]
    panels = 0 if unknown is None else max(len(survivors), 1)
    rows = 1 if panels <= 3 else 2
    extents = [_solution_extent(known.hypotheses[:1], None, truth)]
    if unknown is not None:
        extents.append(_solution_extent(survivors, unknown.envelope, truth))
    extent = _union_extent(extents)
    colors = class_color_map(_classes(known.hypotheses[:1] + survivors, truth))
    marked = [] if unknown is None else ambiguous_observations(unknown)
    titles = [_known_title(known)] + [
        _survivor_title(k, len(unknown.hypotheses), h, marked) for k, h in enumerate(survivors)
    ]
    fig = plt.figure()
    cells = [(0, 0)] + [(k % rows, 1 + k // rows) for k in range(panels)]
    axes = [fig.add_axes((0, 0, 1, 1)) for _ in cells]  # placed below, once all is drawn

    drawn = _Panel(known, truth, extent, colors, observation_poses).draw(
        axes[0], known.best if known.hypotheses else None, titles[0]
    )
    if unknown is not None:
        panel = _Panel(unknown, truth, extent, colors, observation_poses)
        for k, ax in enumerate(axes[1:]):
            drawn += panel.draw(ax, *((survivors[k], titles[1 + k]) if survivors else (None, None)))
            if cells[1 + k][1] > 1:  # the first survivor column keeps its y tick labels
                ax.tick_params(labelleft=False)
                ax.set_ylabel("")
    shown = known.hypotheses[:1] + survivors
    handles = _legend_handles(_used_colors(colors, shown), _drawn_kinds(*drawn))
    legend = fig.legend(
        handles=handles, loc="lower center", ncols=_LEGEND_COLUMNS, fontsize="small",
        frameon=False,
    )  # fmt: skip
    legend_inches = legend.get_window_extent(fig.canvas.get_renderer()).height / fig.dpi
    layout = _Layout(extent, rows, math.ceil(panels / rows), titles, legend_inches)
    fig.set_size_inches(layout.size)
    for ax, (row, column) in zip(axes, cells, strict=True):
        ax.set_position(layout.position(row, column))
    legend.set_bbox_to_anchor((0.5, layout.inches_y(_PAD_INCHES)))
    if unknown is not None:
        fig.suptitle(
            "landmark ids known (left) and unknown: " + _suptitle(unknown, len(survivors)),
            y=1 - layout.inches_y(_PAD_INCHES), va="top",
        )  # fmt: skip
    return fig


_LEGEND_COLUMNS = 4


def _known_title(known: Solution) -> str:
    if not known.hypotheses:
        return "landmark ids known\nno hypothesis"
    return "landmark ids known\n" + _panel_title(1, known.best, _TITLE_WIDTH)


def _survivor_title(k: int, n: int, hypothesis: Hypothesis, marked: Sequence[int]) -> str:
    return f"without ids: survivor {k + 1} of {n}\n" + _panel_title(
        k + 1, hypothesis, _TITLE_WIDTH, None, marked
    )


class _Layout:
    """Where the panels go, in inches: a suptitle, rows of panels (each a title block, a
    plot of the scene's aspect ratio, its x labels), and a legend strip at the bottom."""

    def __init__(
        self,
        extent: Extent,
        rows: int,
        survivor_columns: int,
        titles: list[str],
        legend_inches: float,
    ) -> None:
        dx, dy = extent[1] - extent[0], extent[3] - extent[2]
        margin = 0.05 * max(dx, dy)  # as _finish_axes pads the limits
        self.rows = rows
        self.axes_h = AXES_INCHES * min(max((dy + margin) / (dx + margin), 0.4), 1.5)
        self.title_h = _LINE_INCHES * (max(t.count("\n") for t in titles) + 1) + 0.1
        self.row_h = self.title_h + self.axes_h + _X_LABELS_INCHES
        self.top = 0.4  # the suptitle
        self.bottom = legend_inches + 2 * _PAD_INCHES
        self.lefts = [_Y_LABELS_INCHES]
        for column in range(1, survivor_columns + 1):
            gap = _Y_LABELS_INCHES + 0.15 if column == 1 else _GAP_INCHES
            self.lefts.append(self.lefts[-1] + AXES_INCHES + gap)
        width = self.lefts[-1] + AXES_INCHES + 0.2
        self.size = (width, self.top + rows * self.row_h + self.bottom)

    def position(self, row: int, column: int) -> tuple[float, float, float, float]:
        """The plot of panel (``row``, ``column``) as figure fractions ``[left, bottom,
        width, height]``."""
        width, height = self.size
        top = self.top + row * self.row_h + self.title_h
        return (
            self.lefts[column] / width,
            1 - (top + self.axes_h) / height,
            AXES_INCHES / width,
            self.axes_h / height,
        )

    def inches_y(self, inches: float) -> float:
        """A height in inches as a fraction of the figure's."""
        return inches / self.size[1]
