"""An interactive page of a solve's result: one self-contained HTML file (``cuikslam view``).

What a table cannot show, in a browser, with nothing fetched from the network (Bokeh with
its script inlined): the path, the pose boxes and their heading intervals, the landmarks,
every reported hypothesis (a selector), the envelope under them, the truth when given, a
slider that shows the boxes up to pose k, and what the survivors agree on. It draws what
the static figures draw (:mod:`cuikslam.results.figures`: every k-th box of a long run,
the last and the widest, a zoom on the widest stretch), so that a 10,000-pose result stays
fluid; the wheel and box zooms look closer.

Bokeh is optional (``pip install "cuikslam[view]"``) and imported only when a page is
built; without it :func:`build_page` raises :class:`BokehMissingError`, whose message
says what to install.
"""

from __future__ import annotations

import html
import os
from typing import TYPE_CHECKING, Any

from cuikslam._atomic import atomic_write_text
from cuikslam.outcome.solution import Solution, no_hypothesis
from cuikslam.results.figures.artists import ENVELOPE_COLOR, POSE_COLOR, TRUTH_COLOR
from cuikslam.results.figures.figure import WIDTH_PANEL_POSES, _classes, _solution_extent, _suptitle
from cuikslam.results.figures.geometry import MAX_POSE_BOXES, Extent
from cuikslam.results.figures.page_data import (
    Columns,
    correspondence_html,
    envelope_layers,
    hypothesis_html,
    hypothesis_layers,
    pose_order,
    stretch_of,
)

if TYPE_CHECKING:
    from cuikslam.simulate.truth import GroundTruth

__all__ = ["BOKEH_HINT", "BokehMissingError", "build_page", "require_bokeh", "write_page"]

BOKEH_HINT = 'needs Bokeh, which is not installed: pip install "cuikslam[view]"'
"""What to install for a page (the message of :class:`BokehMissingError`)."""

_MAP_WIDTH = 760
"""Pixels across the map's plotting area (its height follows the scene's aspect)."""
_ZOOM_WIDTH = 420
_MAX_FILLED_BOXES = 40
"""Beyond this many pose boxes, their fills are left out (as in the static figures)."""

# Drawn bottom to top, each with its legend entry (None: no entry) and glyph.
_STYLES: dict[str, tuple[str | None, str, dict[str, Any]]] = {
    "envelope_poses": ("pose envelope (any correspondence)", "quad", {"dash": "solid"}),
    "envelope_poses_unbounded": (None, "quad", {"dash": "dashed"}),
    "envelope_landmarks": ("sighted landmark envelope", "quad", {"dash": "dotted"}),
    "landmarks": ("landmark box (colour: its class)", "landmark", {"dash": "solid"}),
    "landmarks_unbounded": ("unbounded landmark (clipped)", "landmark", {"dash": "dashed"}),
    "path": ("path through the box centres", "line", {}),
    "pose_boxes": ("pose box", "pose", {"dash": "solid"}),
    "pose_boxes_unbounded": ("unbounded pose box (clipped)", "pose", {"dash": "dashed"}),
    "fans": ("heading interval", "fan", {}),
    "pose_labels": (None, "pose_text", {}),
    "truth_path": ("true path", "truth_line", {}),
    "truth_poses": ("true pose and heading", "truth_pose", {}),
    "truth_landmarks": ("true landmark", "truth_landmark", {}),
}

_UPDATE_JS = """
const i = select === null ? 0 : Number(select.value);
const kmax = slider === null ? Infinity : slider.value;
for (const [name, shown] of Object.entries(layers)) {
  const all = stores[name];
  const full = all[Math.min(i, all.length - 1)].data;
  const k = full.k;
  const data = {};
  for (const [column, values] of Object.entries(full)) {
    data[column] = k === undefined ? values : Array.from(values).filter((_, j) => k[j] <= kmax);
  }
  shown.data = data;
}
if (info !== null) { info.text = infos[i]; }
if (zoom !== null) {
  const e = zooms[i];
  zoom.x_range.start = e[0]; zoom.x_range.end = e[1];
  zoom.y_range.start = e[2]; zoom.y_range.end = e[3];
  zoom.title.text = zoom_titles[i];
}
if (slider !== null) {
  const id = pose_ids[Math.min(kmax, pose_ids.length) - 1];
  readout.text = "boxes up to pose " + id + " (" + kmax + " of " + pose_ids.length + ")";
}
"""


class BokehMissingError(ImportError):
    """A page was asked for and Bokeh is not installed."""


def require_bokeh() -> Any:
    """The Bokeh modules a page needs (``embed``, ``layouts``, ``models``, ``plotting``,
    ``resources``); :class:`BokehMissingError`, saying what to install, without Bokeh."""
    try:
        from bokeh import embed, layouts, models, plotting, resources
    except ImportError:
        raise BokehMissingError(f"the page {BOKEH_HINT}") from None
    return embed, layouts, models, plotting, resources


def build_page(
    solution: Solution,
    truth: GroundTruth | None = None,
    *,
    title: str = "cuikslam view",
    max_pose_boxes: int | None = MAX_POSE_BOXES,
) -> str:
    """The HTML of an interactive page of ``solution``: self-contained, scripts inlined.

    Parameters
    ----------
    solution : Solution
        A solve's result (:func:`~cuikslam.solve`, or read back with
        :func:`~cuikslam.read_result_file`); it must have a hypothesis or an envelope.
    truth : GroundTruth, optional
        Drawn as black dots with heading ticks and crosses: the true poses of each
        hypothesis, and the true landmarks its landmarks stand for, paired through its
        association (as the static figures pair them).
    title : str
        The page's title (the browser tab's, and its heading).
    max_pose_boxes : int or None
        Pose boxes drawn at most per hypothesis (every k-th, the last and the widest:
        :func:`~cuikslam.results.figures.drawn_poses`); None draws every box. The path
        runs through every pose.

    Returns
    -------
    str
        The page. Write it with :func:`write_page`, or serve it.

    Raises
    ------
    BokehMissingError
        Without Bokeh (``pip install "cuikslam[view]"``).
    ValueError
        When the result has neither a hypothesis nor an envelope (a refuted log).
    """
    if not solution.hypotheses and solution.envelope is None:
        raise ValueError(f"no hypothesis to view ({no_hypothesis(solution)})")
    embed, layouts, models, plotting, resources = require_bokeh()
    from matplotlib.colors import to_hex

    from cuikslam.results.figures.artists import class_color_map

    colors = {
        c: to_hex(v) for c, v in class_color_map(_classes(solution.hypotheses, truth)).items()
    }
    extent = _solution_extent(solution.hypotheses, solution.envelope, truth)
    ids = pose_order(solution)
    order = {p: i for i, p in enumerate(ids)}

    stores: dict[str, list[Columns]] = {}
    for hypothesis in solution.hypotheses:
        layers = hypothesis_layers(hypothesis, truth, extent, order, colors, max_pose_boxes)
        for name, columns in layers.items():
            stores.setdefault(name, []).append(columns)
    if solution.envelope is not None:
        alone = not solution.hypotheses
        layers = envelope_layers(
            solution.envelope, truth, extent, order, max_pose_boxes, alone=alone
        )
        for name, columns in layers.items():
            stores.setdefault(name, [columns])

    width, height, ranges = _frame_ranges(models, extent, _MAP_WIDTH)
    figure = plotting.figure(
        frame_width=width, frame_height=height, x_range=ranges[0], y_range=ranges[1],
        tools="pan,wheel_zoom,box_zoom,reset,save", active_scroll="wheel_zoom",
        match_aspect=True, x_axis_label="x [m]", y_axis_label="y [m]",
    )  # fmt: skip
    figure.select_one(models.BoxZoomTool).match_aspect = True
    shown, sources, entries = _draw(models, figure, stores, many=_many_boxes(stores))
    items = [models.LegendItem(label=label, renderers=r) for label, r in entries]
    figure.add_layout(models.Legend(items=items, click_policy="hide"), "right")

    zoom = None
    long_run = solution.hypotheses and len(solution.hypotheses[0].pose_ids) > WIDTH_PANEL_POSES
    zooms, zoom_titles = [], []
    if long_run:
        zoom_stores: dict[str, list[Columns]] = {}
        for hypothesis in solution.hypotheses:
            stretch, part = stretch_of(hypothesis, truth)
            layers = hypothesis_layers(stretch, truth, part, order, colors, None, labels=False)
            for name, columns in layers.items():
                zoom_stores.setdefault(name, []).append(columns)
            zooms.append(_frame(part, _ZOOM_WIDTH)[2])
            zoom_titles.append(
                f"the widest stretch: poses {stretch.pose_ids[0]}–{stretch.pose_ids[-1]}, every box"
            )
        w, h, (x_range, y_range) = _frame_ranges(models, zooms[0], _ZOOM_WIDTH)
        zoom = plotting.figure(
            frame_width=w, frame_height=h, x_range=x_range, y_range=y_range,
            tools="pan,wheel_zoom,box_zoom,reset", active_scroll="wheel_zoom",
            title=zoom_titles[0], x_axis_label="x [m]", y_axis_label="y [m]",
        )  # fmt: skip
        zoom_shown, zoom_sources, _ = _draw(models, zoom, zoom_stores, many=False, prefix="zoom_")
        shown.update({f"zoom_{k}": v for k, v in zoom_shown.items()})
        sources.update({f"zoom_{k}": v for k, v in zoom_sources.items()})

    infos = [hypothesis_html(solution, r) for r in range(1, len(solution.hypotheses) + 1)]
    info = models.Div(text=infos[0], width=_MAP_WIDTH + 200, name="info") if infos else None
    select = None
    if len(solution.hypotheses) > 1:
        select = models.Select(
            title="Hypothesis (best-ranked first)",
            value="0",
            options=[(str(i), _option(solution, i)) for i in range(len(solution.hypotheses))],
            width=420,
            name="hypothesis",
        )
    slider = readout = None
    if len(ids) > 1:
        slider = models.Slider(
            start=1, end=len(ids), value=len(ids), step=1, width=420,
            title="boxes up to the k-th pose (in log order)", name="poses",
        )  # fmt: skip
        readout = models.Div(
            text=f"boxes up to pose {ids[-1]} ({len(ids)} of {len(ids)})", name="readout"
        )
    update = models.CustomJS(
        args={
            "select": select, "slider": slider, "readout": readout, "info": info,
            "layers": shown, "stores": sources, "infos": infos, "pose_ids": ids,
            "zoom": zoom, "zooms": zooms, "zoom_titles": zoom_titles,
        },
        code=_UPDATE_JS,
    )  # fmt: skip
    if select is not None:
        select.js_on_change("value", update)
    if slider is not None:
        slider.js_on_change("value", update)

    heading = html.escape(title)
    caption = html.escape(_suptitle(solution, len(solution.hypotheses))).replace("\n", "<br>")
    rows: list[Any] = [models.Div(text=f"<h2 style='margin:4px 0'>{heading}</h2>{caption}")]
    controls = [c for c in (select, slider, readout) if c is not None]
    if controls:
        rows.append(layouts.row(*controls))
    if info is not None:
        rows.append(info)
    rows.append(figure)
    if zoom is not None:
        rows.append(zoom)
    rows.append(models.Div(text=correspondence_html(solution), width=_MAP_WIDTH + 200))
    return embed.file_html(layouts.column(*rows), resources.INLINE, title)


def write_page(
    solution: Solution,
    path: str | os.PathLike[str],
    truth: GroundTruth | None = None,
    **options: Any,
) -> None:
    """Write :func:`build_page` of ``solution`` to ``path`` atomically (a reader sees the
    old file or the whole new page, never a part); ``options`` go to :func:`build_page`."""
    atomic_write_text(path, build_page(solution, truth, **options))


def _option(solution: Solution, i: int) -> str:
    h = solution.hypotheses[i]
    n = h.n_landmarks
    return f"#{i + 1} · {n} landmark{'s' if n != 1 else ''} · {h.status}"


def _frame(extent: Extent, width: int) -> tuple[int, int, Extent]:
    """A plotting area ``width`` pixels across at the extent's aspect (its height between
    a third and the whole of ``width``), and the extent widened to fill it at equal
    scales."""
    x0, x1, y0, y1 = extent
    height = int(min(max(width * (y1 - y0) / (x1 - x0), width / 3), width))
    per_pixel = max((x1 - x0) / width, (y1 - y0) / height)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    half_w, half_h = per_pixel * width / 2, per_pixel * height / 2
    return width, height, (cx - half_w, cx + half_w, cy - half_h, cy + half_h)


def _frame_ranges(models: Any, extent: Extent, width: int) -> tuple[int, int, tuple[Any, Any]]:
    w, h, (x0, x1, y0, y1) = _frame(extent, width)
    return w, h, (models.Range1d(x0, x1), models.Range1d(y0, y1))


def _many_boxes(stores: dict[str, list[Columns]]) -> bool:
    """Whether the pose boxes are many enough that their fills would hide one another."""
    return any(len(c["left"]) > _MAX_FILLED_BOXES for c in stores.get("pose_boxes", []))


def _draw(
    models: Any, figure: Any, stores: dict[str, list[Columns]], *, many: bool, prefix: str = ""
) -> tuple[dict[str, Any], dict[str, list[Any]], list[tuple[str, list[Any]]]]:
    """A renderer per layer that some store fills, in the order of :data:`_STYLES`.

    Returns the shown source of each layer (holding the first store's data), the stored
    sources (one per store: a hypothesis, or the envelope), and the legend entries
    (label, renderers)."""
    shown: dict[str, Any] = {}
    sources: dict[str, list[Any]] = {}
    entries: list[tuple[str, list[Any]]] = []
    hover = []
    for name, (label, kind, style) in _STYLES.items():
        columns = stores.get(name, [])
        if not any(len(next(iter(c.values()))) for c in columns):
            continue
        sources[name] = [models.ColumnDataSource(dict(c)) for c in columns]
        source = models.ColumnDataSource(dict(columns[0]), name=f"shown:{prefix}{name}")
        shown[name] = source
        renderers = _glyph(figure, kind, source, style, many)
        if kind in ("quad", "landmark", "pose", "truth_pose", "truth_landmark"):
            hover.append(renderers[0])
        if label is not None:
            entries.append((label, renderers))
    if hover:
        figure.add_tools(models.HoverTool(renderers=hover, tooltips="@name"))
    return shown, sources, entries


def _glyph(figure: Any, kind: str, source: Any, style: dict[str, Any], many: bool) -> list[Any]:
    """The renderers of one layer."""
    from matplotlib.colors import to_hex

    pose, envelope, truth = to_hex(POSE_COLOR), to_hex(ENVELOPE_COLOR), to_hex(TRUTH_COLOR)
    box = {"left": "left", "right": "right", "bottom": "bottom", "top": "top", "source": source}
    dash = style.get("dash", "solid")
    if kind == "quad":
        return [figure.quad(**box, fill_alpha=0, line_color=envelope, line_width=1.0,
                            line_dash=dash)]  # fmt: skip
    if kind == "landmark":
        quad = figure.quad(**box, fill_color="color", fill_alpha=0.45, line_color="color",
                           line_width=1.2, line_dash=dash)  # fmt: skip
        text = figure.text(x="label_x", y="top", text="label", source=source,
                           text_color="color", text_font_style="bold", text_font_size="11px",
                           text_align="center", text_baseline="bottom", y_offset=-2)  # fmt: skip
        return [quad, text]
    if kind == "pose":
        return [figure.quad(**box, fill_color=pose, fill_alpha=0.0 if many else 0.06,
                            line_color=pose, line_width=0.6 if many else 1.0,
                            line_dash=dash)]  # fmt: skip
    if kind == "fan":
        return [figure.wedge(x="x", y="y", radius="radius", start_angle="start", end_angle="end",
                             source=source, fill_color=pose, fill_alpha=0.3, line_color=pose,
                             line_width=0.6)]  # fmt: skip
    if kind == "line":  # through every pose: thin and light when the boxes are thinned
        return [figure.line(x="x", y="y", source=source, line_color=pose,
                            line_width=0.5 if many else 0.8,
                            line_alpha=0.35 if many else 0.6)]  # fmt: skip
    if kind == "pose_text":
        return [figure.text(x="x", y="y", text="text", source=source, text_color=pose,
                            text_font_size="10px", x_offset=4, y_offset=4)]  # fmt: skip
    if kind == "truth_line":
        return [figure.line(x="x", y="y", source=source, line_color=truth,
                            line_width=0.6, line_alpha=0.6)]  # fmt: skip
    if kind == "truth_pose":
        dots = figure.scatter(x="x", y="y", source=source, size=4, color=truth)
        ticks = figure.segment(x0="x", y0="y", x1="x1", y1="y1", source=source,
                               line_color=truth, line_width=1.0)  # fmt: skip
        return [dots, ticks]
    if kind == "truth_landmark":
        return [figure.scatter(x="x", y="y", source=source, marker="x", size=10,
                               line_width=2, color=truth)]  # fmt: skip
    raise ValueError(f"unknown layer kind {kind!r}")
