"""One figure of a log solved twice: with its landmark ids (known correspondence) and
without (every hypothesis that survives the correspondence search), as the seed paper
shows its experiment: the known-correspondence solve beside one panel per surviving
kinematic graph, each with its sightings, those the survivors assign differently in red,
over the search's envelope. ``cuikslam paper`` draws it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from cuikslam.outcome.solution import Hypothesis, Solution
from cuikslam.outcome.summary import ambiguous_observations
from cuikslam.results.figures.artists import _drawn_kinds, _legend_handles, class_color_map
from cuikslam.results.figures.figure import (
    DPI,
    ENVELOPE_TITLE,
    _classes,
    _Panel,
    _panel_title,
    _solution_extent,
    _suptitle,
    _used_colors,
)
from cuikslam.results.figures.geometry import Extent

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from cuikslam.simulate.truth import GroundTruth

__all__ = ["KnownUnknownFigure", "plot_known_and_unknown"]

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
    dpi: float = DPI,
) -> Figure:
    """The known-correspondence solve beside the survivors of the unknown-correspondence one.

    Panels share their axes limits (those of the survivors and the truth): first
    ``known``'s best hypothesis, then each of ``unknown``'s reported hypotheses (at most
    ``max_hypotheses``, best rank first) over its envelope, or its envelope alone when it
    reports none (a search stopped on its budget). Up to three survivors the panels make
    one row; beyond, the survivors make two rows right of the known panel. Each survivor's
    title gives its rank, landmarks, status and assignment (the landmark of each
    observation, in log order; the observations the survivors assign differently in
    brackets, their sightings drawn in red). One legend sits below the panels.

    The layout is fixed in inches (no layout engine: drawing it is one pass); save it with
    ``save_figure(fig, path, tight=False)``. :class:`KnownUnknownFigure` builds the same
    figure in two steps, the survivors first.

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
    dpi : float
        The figure's resolution: the layout measures the legend at it; save at the same.

    Returns
    -------
    matplotlib.figure.Figure
        Not shown; pass it to :func:`save_figure`.
    """
    builder = KnownUnknownFigure(
        unknown, truth, observation_poses=observation_poses, max_hypotheses=max_hypotheses,
        known=known, dpi=dpi,
    )  # fmt: skip
    builder.add_known(known)
    return builder.figure


class KnownUnknownFigure:
    """:func:`plot_known_and_unknown` in two steps: the survivors' panels, the legend and
    the layout first, then :meth:`add_known` draws the known-correspondence panel into the
    room left for it. A caller that gets the unknown-correspondence result first (as
    ``cuikslam paper``'s drawing process does) can render the figure before the known
    part is solved, then draw only the known panel onto that canvas.

    Parameters
    ----------
    unknown : Solution or None
        The log solved without landmark ids (None: the known panel alone; then ``known``
        is needed).
    truth : GroundTruth, optional
        Drawn in every panel.
    observation_poses : sequence of int, optional
        The pose of each observation (log order): draws the sightings.
    max_hypotheses : int
        Survivor panels at most.
    known : Solution, optional
        The known-correspondence result, when at hand already: room is then made for its
        title, its landmark classes get their colours, and (without ``unknown``) its
        boxes set the limits.
    dpi : float
        The figure's resolution: the layout measures the legend at it; save at the same.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
        The figure; its known panel is empty and hidden until :meth:`add_known`.
    known_axes : matplotlib.axes.Axes
        The known panel's axes.
    """

    def __init__(
        self,
        unknown: Solution | None,
        truth: GroundTruth | None = None,
        *,
        observation_poses: Sequence[int] | None = None,
        max_hypotheses: int = 8,
        known: Solution | None = None,
        dpi: float = DPI,
    ) -> None:
        import matplotlib.pyplot as plt

        if max_hypotheses < 1:
            raise ValueError(f"max_hypotheses must be at least 1, got {max_hypotheses}")
        if unknown is None and known is None:
            raise ValueError("give the unknown-correspondence result, or the known one")
        self.unknown, self.truth, self.observation_poses = unknown, truth, observation_poses
        self.survivors = [] if unknown is None else unknown.hypotheses[:max_hypotheses]
        panels = 0 if unknown is None else max(len(self.survivors), 1)
        self.rows = 1 if panels <= 3 else 2
        self.columns = math.ceil(panels / self.rows)
        ahead = [] if known is None else known.hypotheses[:1]
        self.extent = (
            _solution_extent(ahead, None, truth)
            if unknown is None
            else _solution_extent(self.survivors, unknown.envelope, truth)
        )
        self.colors = class_color_map(_classes(ahead + self.survivors, truth))
        marked = [] if unknown is None else ambiguous_observations(unknown)
        self.titles = [_known_title(known)] if known is not None else []
        self.titles += [
            _survivor_title(k, len(unknown.hypotheses), h, marked)
            for k, h in enumerate(self.survivors)
        ]

        self.figure = fig = plt.figure(dpi=dpi)
        self.cells = [(0, 0)] + [(k % self.rows, 1 + k // self.rows) for k in range(panels)]
        self.known_axes = fig.add_axes((0, 0, 1, 1))  # placed once all is drawn
        self.known_axes.set_visible(False)
        self.drawn: list[dict] = []
        if unknown is not None:
            panel = _Panel(unknown, truth, self.extent, self.colors, observation_poses)
            for k, (_, column) in enumerate(self.cells[1:]):
                ax = fig.add_axes((0, 0, 1, 1))
                ax.set_anchor("N")
                hypothesis = self.survivors[k] if self.survivors else None
                title = self.titles[-len(self.survivors) + k] if self.survivors else None
                self.drawn += panel.draw(ax, hypothesis, title)
                if column > 1:  # the first survivor column keeps its y tick labels
                    ax.tick_params(labelleft=False)
                    ax.set_ylabel("")
            self.suptitle = fig.suptitle(
                "landmark ids known (left) and unknown: " + _suptitle(unknown, len(self.survivors)),
                va="top",
            )
            if not self.survivors:  # its envelope panel's title needs room too
                self.titles.append(ENVELOPE_TITLE)
        self.legend = None
        self._arrange(ahead)

    def add_known(self, known: Solution) -> bool:
        """Draw the known-correspondence panel into its room, and show it.

        Returns
        -------
        bool
            True when the figure's layout and legend are as they were (a canvas drawn
            before holds the rest of the figure: drawing :attr:`known_axes` onto it
            completes it); False when the known panel changed them (a longer title, a
            legend entry of its own): draw the whole figure again.
        """
        ax = self.known_axes
        ax.set_visible(True)
        ax.set_anchor("N")
        title = _known_title(known)
        lines = max(t.count("\n") for t in self.titles) if self.titles else -1
        self.drawn += _Panel(
            known, self.truth, self.extent, self.colors, self.observation_poses
        ).draw(ax, known.best if known.hypotheses else None, title)
        if title not in self.titles:
            self.titles.insert(0, title)
        entries = len(self._handles(known.hypotheses[:1]))
        if entries == len(self.legend.legend_handles) and title.count("\n") <= lines:
            return True  # the legend and the layout stand: nothing else moves
        self._arrange(known.hypotheses[:1])
        return False

    def _handles(self, known_hypotheses: list[Hypothesis]) -> list:
        shown = known_hypotheses + self.survivors
        return _legend_handles(_used_colors(self.colors, shown), _drawn_kinds(*self.drawn))

    def _arrange(self, known_hypotheses: list[Hypothesis]) -> None:
        """(Re)make the legend, then size the figure and place every panel and text."""
        fig = self.figure
        if self.legend is not None:
            self.legend.remove()
        handles = self._handles(known_hypotheses)
        self.legend = fig.legend(
            handles=handles, loc="lower center", ncols=_LEGEND_COLUMNS, fontsize="small",
            frameon=False,
        )  # fmt: skip
        legend_inches = self.legend.get_window_extent(fig.canvas.get_renderer()).height / fig.dpi
        titles = self.titles or [_known_title(None)]
        layout = _Layout(self.extent, self.rows, self.columns, titles, legend_inches)
        fig.set_size_inches(layout.size)
        for ax, (row, column) in zip(fig.axes, self.cells, strict=True):
            ax.set_position(layout.position(row, column))
        self.legend.set_bbox_to_anchor((0.5, layout.inches_y(_PAD_INCHES)))
        if self.unknown is not None:
            self.suptitle.set_y(1 - layout.inches_y(_PAD_INCHES))


_LEGEND_COLUMNS = 4


def _known_title(known: Solution | None) -> str:
    if known is None or not known.hypotheses:
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
