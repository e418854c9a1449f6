"""A short account of a long result: what a person reads instead of 10,000 table rows.

For each hypothesis: how many poses and landmarks, the median and the widest box of
each coordinate, how many headings are unbounded, and the few worst poses (widest
position boxes) with their bounds. Full tables go to the result files (or, on request,
to the terminal); :func:`overview_lines` only summarises.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuikslam.outcome.solution import Envelope, Hypothesis

__all__ = ["BoxStatistics", "box_statistics", "envelope_lines", "overview_lines", "worst_poses"]

FULL_TURN = 2.0 * math.pi
"""A heading box this wide holds every heading."""


@dataclass(frozen=True)
class BoxStatistics:
    """Median and widest width of each coordinate over a set of boxes.

    Attributes
    ----------
    names : tuple of str
        Coordinate names (``x, y, θ`` for poses, ``x, y`` for landmarks).
    median : np.ndarray
        Median width of each coordinate.
    widest : np.ndarray
        Largest width of each coordinate.
    widest_at : list of str
        The id of a box of largest width, per coordinate.
    """

    names: tuple[str, ...]
    median: np.ndarray
    widest: np.ndarray
    widest_at: list[str]


def _widths(boxes: np.ndarray) -> np.ndarray:
    """Widths ``hi - lo`` (inf for unbounded sides, 0 for empty boxes)."""
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf; 1e308 - -1e308 is inf
        widths = boxes[..., 1] - boxes[..., 0]
    return np.where(np.isnan(widths), np.inf, np.maximum(widths, 0.0))


def box_statistics(boxes: np.ndarray, ids: list, names: tuple[str, ...]) -> BoxStatistics:
    """Median and widest widths of ``boxes`` (shape ``(n, len(names), 2)``), ``n >= 1``."""
    widths = _widths(boxes)
    widest_index = np.argmax(widths, axis=0)
    return BoxStatistics(
        names=names,
        median=np.median(widths, axis=0),
        widest=widths[widest_index, np.arange(widths.shape[1])],
        widest_at=[str(ids[i]) for i in widest_index],
    )


def worst_poses(hypothesis: Hypothesis, count: int = 5) -> list[int]:
    """Indices (into ``hypothesis.pose_ids``) of the ``count`` poses whose position boxes
    are widest (largest of the x and y widths; ties by heading width), widest first."""
    if not len(hypothesis.pose_ids):
        return []
    widths = _widths(hypothesis.poses)
    position = np.maximum(widths[:, 0], widths[:, 1])
    order = np.lexsort((-widths[:, 2], -position))  # last key is the primary one
    return [int(i) for i in order[:count]]


def _metres(value: float) -> str:
    return "unbounded" if math.isinf(value) else f"{value:.3g} m"


def _radians(value: float) -> str:
    if value >= FULL_TURN:
        return "any (≥ 2π)"
    return f"{value:.3g} rad ({math.degrees(value):.3g}°)"


def _describe(stats: BoxStatistics, unit: tuple) -> tuple[str, str]:
    median = ", ".join(
        f"{n} {u(v)}" for n, u, v in zip(stats.names, unit, stats.median, strict=True)
    )
    widest = ", ".join(
        f"{n} {u(v)} ({at})"
        for n, u, v, at in zip(stats.names, unit, stats.widest, stats.widest_at, strict=True)
    )
    return median, widest


def overview_lines(hypothesis: Hypothesis, title: str, worst: int = 5) -> list[str]:
    """A few lines that summarise one hypothesis' boxes (see the module docstring).

    Parameters
    ----------
    hypothesis : Hypothesis
        The hypothesis to describe.
    title : str
        The first line (e.g. ``"Hypothesis 1 of 1: 4 landmarks, not refuted"``).
    worst : int
        How many of the widest pose boxes to list with their bounds.
    """
    n_poses, n_landmarks = len(hypothesis.pose_ids), hypothesis.n_landmarks
    lines = [
        title,
        f"  {n_poses:,} poses, {n_landmarks:,} landmarks"
        + (f", level {hypothesis.consistency}" if hypothesis.consistency else ""),
    ]
    if n_poses:
        labels = [f"r {p}" for p in hypothesis.pose_ids]
        stats = box_statistics(hypothesis.poses, labels, ("x", "y", "θ"))
        median, widest = _describe(stats, (_metres, _metres, _radians))
        lines.append(f"  pose box widths, median: {median}")
        lines.append(f"  pose box widths, widest: {widest}")
        headings = _widths(hypothesis.poses)[:, 2]
        free = int(np.count_nonzero(headings >= FULL_TURN))
        if free:
            lines.append(f"  {free:,} of {n_poses:,} headings are unknown (boxes ≥ 2π wide)")
    if n_landmarks:
        labels = [f"l {m}" for m in hypothesis.landmark_ids]
        stats = box_statistics(hypothesis.landmarks, labels, ("x", "y"))
        median, widest = _describe(stats, (_metres, _metres))
        lines.append(f"  landmark box widths, median: {median}")
        lines.append(f"  landmark box widths, widest: {widest}")
    rows = worst_poses(hypothesis, worst)
    if rows:
        lines.append(f"  the {len(rows)} widest pose boxes (x, y, θ):")
        for i in rows:
            box = hypothesis.poses[i]
            bounds = "  ".join(f"[{lo:.3f}, {hi:.3f}]" for lo, hi in box.tolist())
            lines.append(f"    r {hypothesis.pose_ids[i]}: {bounds}")
    return lines


def envelope_lines(envelope: Envelope, complete: bool) -> list[str]:
    """A few lines on the envelope: the boxes that hold the truth whatever the
    correspondence (and, after an incomplete search, whatever it did not explore).

    Parameters
    ----------
    envelope : Envelope
        The result's envelope.
    complete : bool
        Whether the search was complete (the envelope is then the survivors' hull).
    """
    where = "the survivors" if complete else "the survivors and every unexplored subtree"
    lines = [f"Envelope (holds the truth whatever the correspondence; over {where}):"]
    if len(envelope.pose_ids):
        labels = [f"r {p}" for p in envelope.pose_ids]
        stats = box_statistics(envelope.poses, labels, ("x", "y", "θ"))
        median, widest = _describe(stats, (_metres, _metres, _radians))
        lines.append(f"  {len(envelope.pose_ids):,} poses; box widths, median: {median}")
        lines.append(f"  widest: {widest}")
    if len(envelope.observations):
        labels = [f"o {i}" for i in range(len(envelope.observations))]
        stats = box_statistics(envelope.observations, labels, ("x", "y"))
        median, widest = _describe(stats, (_metres, _metres))
        lines.append(
            f"  the landmark of each of {len(envelope.observations):,} observations; "
            f"box widths, median: {median}"
        )
    return lines
