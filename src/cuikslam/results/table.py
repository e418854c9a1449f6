"""Tables of boxes in the seed paper's layout (description, x, y, theta), built with rich."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from rich.table import Table

from cuikslam.log.records import Bounds
from cuikslam.outcome.solution import Hypothesis, Solution

__all__ = [
    "comparison_table",
    "format_bounds",
    "hypothesis_rows",
    "hypothesis_table",
    "summary_table",
]

Row = tuple[str, Bounds, Bounds, Bounds | None]
"""(description, x, y, theta or None for a landmark)."""


def format_bounds(bounds: Bounds | np.ndarray | None, digits: int = 6) -> str:
    """``[lo, hi]`` with fixed decimals, as in the seed's tables; an em dash for None.

    >>> format_bounds((0.0, -0.0)), format_bounds((1.5, 2.0), digits=2)
    ('[0.000000, 0.000000]', '[1.50, 2.00]')
    """
    if bounds is None:
        return "—"
    lo, hi = float(bounds[0]) + 0.0, float(bounds[1]) + 0.0  # + 0.0: no "-0.000000"
    if lo > hi:
        return "∅"
    return f"[{lo:.{digits}f}, {hi:.{digits}f}]"


def hypothesis_rows(hypothesis: Hypothesis) -> list[Row]:
    """Rows "r <pose>" then "l <n>" (landmarks numbered 1.. in the hypothesis' order)."""
    rows: list[Row] = []
    for pose, box in zip(hypothesis.pose_ids, hypothesis.poses, strict=True):
        rows.append((f"r {pose}", tuple(box[0]), tuple(box[1]), tuple(box[2])))
    for landmark, box in zip(hypothesis.landmark_ids, hypothesis.landmarks, strict=True):
        rows.append((f"l {landmark}", tuple(box[0]), tuple(box[1]), None))
    return rows


def hypothesis_table(hypothesis: Hypothesis, title: str, digits: int = 6) -> Table:
    """One hypothesis as a table in the seed's layout (its Tables 1-6)."""
    table = Table(title=title, title_justify="left")
    for name in ("description", "x", "y", "θ"):
        table.add_column(name, justify="left" if name == "description" else "right")
    for desc, x, y, theta in hypothesis_rows(hypothesis):
        table.add_row(
            desc, format_bounds(x, digits), format_bounds(y, digits), format_bounds(theta, digits)
        )
    return table


def _width(bounds: Bounds | None) -> float:
    return math.nan if bounds is None else float(bounds[1]) - float(bounds[0])


def comparison_table(
    ours: Sequence[Row], reference: Sequence[Row], title: str, reference_name: str = "seed"
) -> Table:
    """Our rows beside a reference table's rows (matched by order) with width ratios ours / ref."""
    table = Table(title=title, title_justify="left")
    table.add_column("description")
    for name in ("x", "y", "θ"):
        table.add_column(f"{name} (cuikslam)", justify="right")
    for name in ("x", "y", "θ"):
        table.add_column(f"{name} ({reference_name})", justify="right")
    table.add_column(f"width ratio x / y / θ (cuikslam ÷ {reference_name})", justify="right")
    for ours_row, ref_row in zip(ours, reference, strict=False):
        ratios = []
        for k in (1, 2, 3):
            w_ours, w_ref = _width(ours_row[k]), _width(ref_row[k])
            if math.isnan(w_ours) or math.isnan(w_ref):
                ratios.append("—")
            elif w_ref <= 1e-5:
                ratios.append("exact" if w_ours <= 1e-5 else "∞")
            else:
                ratios.append(f"{w_ours / w_ref:.2f}")
        table.add_row(
            ours_row[0],
            *(format_bounds(b, 3) for b in ours_row[1:]),
            *(format_bounds(b, 3) for b in ref_row[1:]),
            " / ".join(ratios),
        )
    return table


def summary_table(
    solution: Solution, title: str = "Surviving hypotheses", limit: int | None = None
) -> Table:
    """One line per hypothesis: rank, landmarks, status, level, total box size,
    least-squares fit, assignment.

    With ``limit``, only the first ``limit`` hypotheses, and each assignment cut after
    ``limit`` observations."""
    table = Table(title=title, title_justify="left")
    columns = ("rank", "landmarks", "status", "level", "Σ widths", "fit")
    for name in (*columns, "assignment (observation → landmark)"):
        table.add_column(name)
    for rank, h in enumerate(solution.hypotheses[:limit], start=1):
        table.add_row(
            str(rank),
            str(h.n_landmarks),
            h.status,
            h.consistency or "—",
            f"{h.box_size:.2f}",
            f"{h.fit:.2f}" if math.isfinite(h.fit) else "—",
            _assignment_text(h.assignment, limit),
        )
    return table


def _assignment_text(assignment: Sequence[str], limit: int | None) -> str:
    """The assignment, cut after ``limit`` observations (when given) with a count of the rest."""
    if limit is None or len(assignment) <= limit:
        return " ".join(assignment)
    return " ".join(assignment[:limit]) + f" … ({len(assignment) - limit:,} more)"
