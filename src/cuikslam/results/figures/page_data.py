"""What the interactive page (:mod:`.page`) draws, as columns of numbers and words, without
Bokeh: the same selection as the static figures (every k-th pose box on a long run, the
last and the widest: :func:`~.geometry.drawn_poses`; the truth paired through each
hypothesis' association: :func:`~.geometry._true_landmark_rows`), in the shape a Bokeh
``ColumnDataSource`` takes.

Every layer is a dict of equal-length columns. Columns named ``k`` hold each row's place
in the page's pose order (1 for the first pose, see :func:`pose_order`): the page's slider
keeps the rows with ``k`` at most its value. A layer has the same columns whatever it
holds (empty arrays when there is nothing), so that the page can switch hypotheses by
swapping data.
"""

from __future__ import annotations

import html
import math
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam.outcome.solution import Envelope, Hypothesis, Solution
from cuikslam.outcome.summary import ambiguous_observations, describe, summary_from_json
from cuikslam.results.figures.artists import FAN_RADIUS
from cuikslam.results.figures.axes import _LABEL_SPACING, _LONG_RUN_LABEL_SPACING
from cuikslam.results.figures.figure import _MAX_TITLE_OBSERVATIONS, _panel_title
from cuikslam.results.figures.geometry import (
    Extent,
    _clip_boxes,
    _fan_angles,
    _sighted_landmark_rows,
    _true_landmark_rows,
    _xy_boxes,
    drawn_poses,
    scene_extent,
    spread_labels,
    widest_stretch,
)

if TYPE_CHECKING:
    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "MAX_LISTED_OBSERVATIONS",
    "Columns",
    "correspondence_html",
    "envelope_layers",
    "hypothesis_html",
    "hypothesis_layers",
    "pose_order",
    "stretch_of",
]

Columns = dict[str, Any]
"""One layer: column name -> a NumPy array or a list, all of one length."""

MAX_LISTED_OBSERVATIONS = 300
"""The correspondence panel lists what each observation may follow up to this many
observations (the ambiguous ones always); beyond, it counts the certain ones."""


def pose_order(solution: Solution) -> list[int]:
    """The pose ids in the order the page's slider walks them: the best hypothesis' order
    (the order poses first appear in the log), then any other pose of the other hypotheses
    and of the envelope, in increasing id."""
    first = list(solution.hypotheses[0].pose_ids) if solution.hypotheses else []
    seen = set(first)
    others: set[int] = set()
    for hypothesis in solution.hypotheses[1:]:
        others.update(p for p in hypothesis.pose_ids if p not in seen)
    if solution.envelope is not None:
        others.update(p for p in solution.envelope.pose_ids if p not in seen)
    return first + sorted(others)


def _interval(lo: float, hi: float) -> str:
    return f"[{lo:.3f}, {hi:.3f}]"


def _box_layers(
    boxes: np.ndarray, extent: Extent, k: np.ndarray, names: Sequence[str]
) -> tuple[Columns, Columns]:
    """Rectangles of the x/y part of ``boxes``, clipped to ``extent``: the bounded ones,
    and those with an unbounded side (drawn dashed); ``k`` and ``names`` per box, and the
    bounds as words for the hover."""
    xy = _xy_boxes(boxes)
    clipped, unbounded = _clip_boxes(xy, extent)
    array = np.asarray(boxes, dtype=float)
    array = array.reshape(len(xy), -1, 2) if array.size else np.empty((0, 2, 2))
    words = [
        [f"{name}: x {_interval(*b[0])}, y {_interval(*b[1])}"]
        + ([f"θ {_interval(*b[2])}"] if len(b) > 2 else [])
        for name, b in zip(names, array, strict=True)
    ]
    layers = []
    for keep in (~unbounded, unbounded):
        rows = np.flatnonzero(keep)
        layers.append(
            {
                "left": clipped[rows, 0, 0],
                "right": clipped[rows, 0, 1],
                "bottom": clipped[rows, 1, 0],
                "top": clipped[rows, 1, 1],
                "k": np.asarray(k, dtype=float)[rows],
                "name": [", ".join(words[i]) for i in rows],
            }
        )
    return layers[0], layers[1]


def _k_of(pose_ids: Iterable[int], order: dict[int, int]) -> np.ndarray:
    """Each pose's place in the page's pose order (1-based; past the end when absent)."""
    return np.array([order.get(p, len(order)) + 1 for p in pose_ids], dtype=float)


def _truth_layers(
    truth: GroundTruth | None,
    pose_ids: Sequence[int],
    dotted: Iterable[int],
    landmark_rows: Sequence[int],
    order: dict[int, int],
    tick: float,
) -> dict[str, Columns]:
    """The true poses of ``dotted`` (dots and heading ticks), the true path through every
    pose of ``pose_ids``, and the true landmarks of ``landmark_rows`` (crosses)."""
    if truth is None:
        poses, ids, rows = np.empty((0, 3)), [], []
    else:
        poses = np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3)
        ids, rows = list(truth.pose_ids), list(landmark_rows)
    wanted = set(pose_ids)
    keep = [i for i, p in enumerate(ids) if p in wanted]
    keep.sort(key=lambda i: order.get(ids[i], len(order)))
    marked = set(dotted)
    dots = [i for i in keep if ids[i] in marked]
    xyt = poses[dots]
    marks = np.empty((0, 2)) if truth is None else np.asarray(truth.landmarks_xy, dtype=float)
    marks = marks.reshape(-1, 2)[rows]
    return {
        "truth_poses": {
            "x": xyt[:, 0],
            "y": xyt[:, 1],
            "x1": xyt[:, 0] + tick * np.cos(xyt[:, 2]),
            "y1": xyt[:, 1] + tick * np.sin(xyt[:, 2]),
            "k": _k_of([ids[i] for i in dots], order),
            "name": [f"true pose {ids[i]}" for i in dots],
        },
        "truth_path": {
            "x": poses[keep, 0],
            "y": poses[keep, 1],
            "k": _k_of([ids[i] for i in keep], order),
        },
        "truth_landmarks": {
            "x": marks[:, 0],
            "y": marks[:, 1],
            "name": [] if truth is None else [f"true {truth.landmark_ids[j]}" for j in rows],
        },
    }


def hypothesis_layers(
    hypothesis: Hypothesis,
    truth: GroundTruth | None,
    extent: Extent,
    order: dict[int, int],
    class_colors: dict[str, str],
    max_pose_boxes: int | None,
    *,
    labels: bool = True,
) -> dict[str, Columns]:
    """The layers of one hypothesis, as its static panel draws them
    (:func:`~cuikslam.results.figures.plot_hypothesis_on_axes`).

    Parameters
    ----------
    hypothesis : Hypothesis
        Its pose and landmark boxes.
    truth : GroundTruth, optional
        The true poses it has, and the true landmarks its landmarks stand for (paired
        through its association).
    extent : (x_min, x_max, y_min, y_max)
        The clip box of unbounded sides, and the scale of the heading fans.
    order : dict[int, int]
        Pose id -> place in the page's pose order (0-based; :func:`pose_order`).
    class_colors : dict[str, str]
        Landmark class -> colour.
    max_pose_boxes : int or None
        Boxes drawn at most (:func:`~cuikslam.results.figures.drawn_poses`); None: all.
    labels : bool
        Pose labels (spread so that none overlap).

    Returns
    -------
    dict[str, Columns]
        ``pose_boxes``, ``pose_boxes_unbounded``, ``fans``, ``path``, ``pose_labels``,
        ``landmarks``, ``landmarks_unbounded``, ``truth_poses``, ``truth_path`` and
        ``truth_landmarks``.
    """
    scale = max(extent[1] - extent[0], extent[3] - extent[2])
    poses = np.asarray(hypothesis.poses, dtype=float).reshape(-1, 3, 2)
    drawn = drawn_poses(poses, max_pose_boxes)
    thinned = len(drawn) < len(poses)
    ids = list(hypothesis.pose_ids)
    k = _k_of(ids, order)
    names = [f"pose {p}" for p in ids]
    layers: dict[str, Columns] = {}
    layers["pose_boxes"], layers["pose_boxes_unbounded"] = _box_layers(
        poses[drawn], extent, k[drawn], [names[i] for i in drawn]
    )
    clipped, _ = _clip_boxes(poses[:, :2], extent)
    centres = clipped.mean(axis=2).reshape(-1, 2)
    fans = [(i, _fan_angles(poses[i, 2])) for i in drawn]
    fans = [(i, a) for i, a in fans if a is not None]
    layers["fans"] = {
        "x": centres[[i for i, _ in fans], 0],
        "y": centres[[i for i, _ in fans], 1],
        "start": np.radians([a[0] for _, a in fans]),
        "end": np.radians([a[1] for _, a in fans]),
        "radius": np.full(len(fans), FAN_RADIUS * scale),
        "k": k[[i for i, _ in fans]],
    }
    layers["path"] = {"x": centres[:, 0], "y": centres[:, 1], "k": k}
    groups = []
    if labels:
        spacing = (_LONG_RUN_LABEL_SPACING if thinned else _LABEL_SPACING) * scale
        groups = [[drawn[g] for g in group] for group in spread_labels(centres[drawn], spacing)]
    layers["pose_labels"] = {
        "x": centres[[g[0] for g in groups], 0],
        "y": centres[[g[0] for g in groups], 1],
        "text": [str(ids[g[0]]) for g in groups],
        "k": k[[g[0] for g in groups]],
    }
    marks = np.asarray(hypothesis.landmarks, dtype=float).reshape(-1, 2, 2)
    mark_ids = list(hypothesis.landmark_ids)
    bounded, unbounded = _box_layers(
        marks, extent, np.zeros(len(marks)), [f"landmark {m}" for m in mark_ids]
    )
    finite = np.isfinite(marks).all(axis=(1, 2))
    for layer, rows in ((bounded, np.flatnonzero(finite)), (unbounded, np.flatnonzero(~finite))):
        classes = [hypothesis.landmark_classes[j] for j in rows]
        layer["color"] = [class_colors.get(c, "#808080") for c in classes]
        layer["label"] = [mark_ids[j] for j in rows]
        layer["label_x"] = (layer["left"] + layer["right"]) / 2
        layer["name"] = [f"{n} ({c})" for n, c in zip(layer["name"], classes, strict=True)]
        del layer["k"]  # landmarks stay whatever the slider says
    layers["landmarks"], layers["landmarks_unbounded"] = bounded, unbounded
    rows = [] if truth is None else _true_landmark_rows(hypothesis, truth)
    dotted = [ids[i] for i in drawn] if thinned else ids
    layers.update(_truth_layers(truth, ids, dotted, rows, order, 0.8 * FAN_RADIUS * scale))
    return layers


def envelope_layers(
    envelope: Envelope,
    truth: GroundTruth | None,
    extent: Extent,
    order: dict[int, int],
    max_pose_boxes: int | None,
    *,
    alone: bool,
) -> dict[str, Columns]:
    """The envelope's layers, as :func:`~cuikslam.results.figures.plot_envelope_on_axes`
    draws them: its pose boxes (every k-th on a long run); ``alone`` (a result with no
    hypothesis) also where each sighted landmark lies (each distinct bounded observation
    box once) and the truth.

    Returns
    -------
    dict[str, Columns]
        ``envelope_poses``, ``envelope_poses_unbounded``, ``envelope_landmarks``, and
        with ``alone`` the truth layers of :func:`hypothesis_layers`.
    """
    poses = np.asarray(envelope.poses, dtype=float).reshape(-1, 3, 2)
    drawn = drawn_poses(poses, max_pose_boxes)
    k = _k_of(envelope.pose_ids, order)
    names = [f"envelope, pose {envelope.pose_ids[i]}" for i in drawn]
    layers: dict[str, Columns] = {}
    layers["envelope_poses"], layers["envelope_poses_unbounded"] = _box_layers(
        poses[drawn], extent, k[drawn], names
    )
    seen = np.empty((0, 2, 2))
    if alone:
        boxes = _xy_boxes(envelope.observations)
        seen = np.unique(boxes[np.isfinite(boxes).all(axis=(1, 2))], axis=0)
        seen = seen[drawn_poses(seen, max_pose_boxes)]
    marks, _ = _box_layers(seen, extent, np.zeros(len(seen)), ["a sighted landmark"] * len(seen))
    del marks["k"]
    layers["envelope_landmarks"] = marks
    if alone:
        scale = max(extent[1] - extent[0], extent[3] - extent[2])
        rows = [] if truth is None else _sighted_landmark_rows(truth)
        dotted = [envelope.pose_ids[i] for i in drawn]
        tick = 0.8 * FAN_RADIUS * scale
        layers.update(_truth_layers(truth, envelope.pose_ids, dotted, rows, order, tick))
    return layers


def stretch_of(hypothesis: Hypothesis, truth: GroundTruth | None) -> tuple[Hypothesis, Extent]:
    """The widest stretch of a long run (:func:`~.geometry.widest_stretch`), every box of
    it, and its extent (the zoom of the static figure of a long run)."""
    from dataclasses import replace

    part = widest_stretch(hypothesis)
    stretch = replace(
        hypothesis,
        pose_ids=list(hypothesis.pose_ids[part]),
        poses=np.asarray(hypothesis.poses)[part],
        landmark_ids=[],
        landmark_classes=[],
        landmarks=np.empty((0, 2, 2)),
    )
    points = []
    if truth is not None:
        ids = set(stretch.pose_ids)
        points.append([p for i, p in zip(truth.pose_ids, truth.poses_xyt, strict=True) if i in ids])
    return stretch, scene_extent([stretch.poses], points)


def hypothesis_html(solution: Solution, rank: int) -> str:
    """The head of hypothesis ``rank`` (1-based) as the static panels title it (rank,
    landmarks, status, level, its assignment with the ambiguous observations in
    brackets), as HTML."""
    hypothesis = solution.hypotheses[rank - 1]
    marked = ambiguous_observations(solution)
    text = _panel_title(rank, hypothesis, 110, 10 * _MAX_TITLE_OBSERVATIONS, marked)
    head, _, rest = text.partition("\n")
    fit = f" · fit {hypothesis.fit:.4g}" if math.isfinite(hypothesis.fit) else ""
    return (
        f"<b>Hypothesis {html.escape(head)}{fit}</b>"
        f"<pre style='margin:2px 0'>{html.escape(rest)}</pre>"
    )


def correspondence_html(solution: Solution) -> str:
    """What the survivors agree on, as HTML: the summary's sentence
    (:func:`~cuikslam.outcome.summary.describe`), what each observation may follow
    (the observation that saw the same landmark last, ``#j``; a named landmark; or
    ``new``), which associations are certain, the independent groups of ambiguous ones,
    and the solve's messages."""
    doc = solution.correspondence
    parts: list[str] = []
    sentence = ""
    if doc is None:
        n = len(solution.hypotheses[0].assignment) if solution.hypotheses else 0
        parts.append(
            f"<b>Known correspondence</b>: each of the {n:,} observations names its landmark."
        )
    else:
        summary = summary_from_json(doc)
        survivors = int(doc.get("survivors", len(solution.hypotheses)))
        complete = bool(doc.get("complete", solution.complete))
        sentence = describe(summary, survivors, complete, doc.get("summarised"))
        parts.append(f"<b>Correspondence</b>: {html.escape(sentence)}.")
        parts.append(_follows_html(summary.follows, summary.certain))
        for g, factor in enumerate(summary.factors, start=1):
            observations = ", ".join(f"#{i}" for i in factor.observations)
            choices = " | ".join("(" + ", ".join(c) + ")" for c in factor.choices)
            parts.append(
                f"Group {g} (observations {html.escape(observations)}): "
                f"{len(factor.choices)} choices {html.escape(choices)}"
            )
    messages = [m for m in solution.messages if m != sentence]  # not the sentence again
    if messages:
        items = "".join(f"<li>{html.escape(m)}</li>" for m in messages)
        parts.append(f"<b>Messages of the solve</b><ul style='margin:2px 0'>{items}</ul>")
    return "<br>".join(parts)


def _follows_html(follows: Sequence[Sequence[str]], certain: Sequence[bool]) -> str:
    """Observation ``#i`` -> what it may follow, certain ones plain, ambiguous ones bold
    (all of them up to :data:`MAX_LISTED_OBSERVATIONS` observations, else the ambiguous
    ones and a count)."""
    n = len(follows)
    listed = range(n) if n <= MAX_LISTED_OBSERVATIONS else [i for i in range(n) if not certain[i]]
    rows = []
    for i in listed:
        what = html.escape(" or ".join(follows[i]))
        rows.append(f"#{i} → {what}" if certain[i] else f"<b>#{i} → {what}</b>")
    head = (
        "What each observation follows (#j: the observation that saw the same landmark "
        "last; new: a landmark's first sighting); <b>bold</b>: ambiguous"
    )
    more = "" if len(rows) == n else f" ({n - len(rows):,} certain observations not listed)"
    return f"{head}{more}:<div style='columns:14em'>" + "<br>".join(rows) + "</div>"
