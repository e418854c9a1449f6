"""g2o graph files: a log under one correspondence, with a point estimate as its vertices.

The types are g2o's ``slam2d`` group, which g2o, its viewer and GTSAM-based readers know:

===========================  =========================================================
line                         what it holds
===========================  =========================================================
``VERTEX_SE2 i x y θ``       a pose (the estimate's value)
``VERTEX_XY i x y``          a landmark
``EDGE_SE2 i j dx dy dθ I``  an odometry step or relative pose (``I``: the upper
                             triangle of the 3x3 information matrix, row by row)
``EDGE_SE2_XY i j x y I``    a bearing-range reading, as the landmark's position in the
                             pose's frame (2x2 information)
``EDGE_BEARING_SE2_XY``      a bearing-only reading: ``i j bearing information``
``EDGE_PRIOR_SE2 i x y θ I``  a pose prior
``EDGE_PRIOR_XY i x y I``    a landmark prior
===========================  =========================================================

Means and covariances are those of :mod:`cuikslam.interop.gaussian` (midpoints, half-widths
as standard deviations by default; information = inverse covariance). Pose ``p`` keeps its
id as vertex id; the ``j``-th landmark is vertex ``max pose id + 1 + j`` (the header says
which). A range-only reading has no ``slam2d`` edge and is left out, as is what g2o has no
counterpart for (sensor model, class priors, outlier declarations, observations taken as
outliers). ``#`` comments at the end of the file say where the vertices come from, which
vertex each landmark is, and what was left out: g2o skips comments and lines it does not
know, and GTSAM's ``readG2o`` stops reading edges at the first comment, so none comes
before the last edge.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from cuikslam._atomic import atomic_write_text
from cuikslam.errors import InputFileError
from cuikslam.interop.estimate import PointEstimate
from cuikslam.interop.gaussian import (
    MIN_SIGMA,
    move_gaussian,
    prior_gaussian,
    reading_gaussian,
)
from cuikslam.log.records import (
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    OutlierBound,
    PosePrior,
    RelativePose,
    SensorModel,
)
from cuikslam.outcome.solution import OUTLIER

__all__ = ["G2oGraph", "g2o_lines", "read_g2o_file", "write_g2o_file"]

_SIZES = {  # tag: (vertices, measurement size, information size)
    "VERTEX_SE2": (1, 3, 0),
    "VERTEX_XY": (1, 2, 0),
    "EDGE_SE2": (2, 3, 6),
    "EDGE_SE2_XY": (2, 2, 3),
    "EDGE_BEARING_SE2_XY": (2, 1, 1),
    "EDGE_PRIOR_SE2": (1, 3, 6),
    "EDGE_PRIOR_XY": (1, 2, 3),
}


def _numbers(values: np.ndarray) -> str:
    return " ".join(repr(float(v)) for v in values)


def _upper(information: np.ndarray) -> np.ndarray:
    """The upper triangle of a symmetric matrix, row by row (g2o's order)."""
    return information[np.triu_indices(information.shape[0])]


def g2o_lines(
    log: Log,
    point: PointEstimate,
    assignment: Sequence[str],
    *,
    scale: float = 1.0,
    floor: float = MIN_SIGMA,
    comments: Sequence[str] = (),
) -> list[str]:
    """The lines of the g2o file of ``log`` under ``assignment``, vertices at ``point``.

    Parameters
    ----------
    log : Log
        The log.
    point : PointEstimate
        A value for every pose of the log and every landmark ``assignment`` names.
    assignment : sequence of str
        The landmark id of each observation, in log order (a hypothesis' or a truth's);
        ``"outlier"`` leaves an observation out.
    scale, floor : float
        Standard deviation per half-width and its least value
        (:mod:`cuikslam.interop.gaussian`).
    comments : sequence of str
        More ``#`` lines for the notes at the end.

    Raises
    ------
    ValueError
        When ``assignment`` or ``point`` does not fit the log.
    """
    observations = log.observations
    if len(assignment) != len(observations):
        raise ValueError(
            f"{len(assignment)} observations assigned, the log {log.path} has {len(observations)}"
        )
    missing = sorted(set(log.pose_ids) - set(point.pose_ids))
    if missing:
        raise ValueError(f"no value for pose(s) {missing[:5]} of the log {log.path}")
    first = max(point.pose_ids, default=-1) + 1
    vertex = {m: first + j for j, m in enumerate(point.landmark_ids)}
    wanted = {m for m in assignment if m != OUTLIER} | {r.landmark for r in log.landmark_priors}
    if not wanted <= vertex.keys():
        raise ValueError(f"no value for landmark(s) {sorted(wanted - vertex.keys())[:5]}")
    notes = [
        f"cuikslam graph: vertices from the {point.source}",
        f"landmarks are vertices {first}..{first + len(vertex) - 1}: "
        + ", ".join(f"{m}={v}" for m, v in vertex.items()),
        *comments,
    ]
    lines = []
    for pose_id, xyt in sorted(zip(point.pose_ids, point.poses_xyt.tolist(), strict=True)):
        lines.append(f"VERTEX_SE2 {pose_id} {_numbers(np.asarray(xyt))}")
    for m, xy in zip(point.landmark_ids, point.landmarks_xy, strict=True):
        lines.append(f"VERTEX_XY {vertex[m]} {_numbers(xy)}")
    left_out: list[str] = []
    seen = iter(assignment)
    for r in log.records:
        if isinstance(r, PosePrior):
            g = prior_gaussian(r, scale, floor)
            lines.append(
                f"EDGE_PRIOR_SE2 {r.pose} {_numbers(g.mean)} {_numbers(_upper(g.information))}"
            )
        elif isinstance(r, LandmarkPrior):
            g = prior_gaussian(r, scale, floor)
            lines.append(
                f"EDGE_PRIOR_XY {vertex[r.landmark]} {_numbers(g.mean)} "
                f"{_numbers(_upper(g.information))}"
            )
        elif isinstance(r, Odometry | RelativePose):
            g = move_gaussian(r, scale, floor)
            lines.append(
                f"EDGE_SE2 {r.source} {r.target} {_numbers(g.mean)} "
                f"{_numbers(_upper(g.information))}"
            )
        elif isinstance(r, Observation):
            landmark = next(seen)
            if landmark == OUTLIER:
                left_out.append(f"observation at pose {r.pose} taken as an outlier")
                continue
            reading = reading_gaussian(r, scale, floor)
            ids = f"{r.pose} {vertex[landmark]}"
            if reading.kind == "bearing-range":
                g = reading.point()
                lines.append(
                    f"EDGE_SE2_XY {ids} {_numbers(g.mean)} {_numbers(_upper(g.information))}"
                )
            elif reading.kind == "bearing":
                information = 1.0 / reading.covariance[0, 0]
                lines.append(
                    f"EDGE_BEARING_SE2_XY {ids} {float(reading.mean[0])!r} {float(information)!r}"
                )
            else:
                left_out.append(f"range-only observation at pose {r.pose} of {landmark}")
        elif isinstance(r, SensorModel | ClassPrior | OutlierBound):
            left_out.append(f"{type(r).__name__} record (no g2o counterpart)")
    notes += [f"left out: {what}" for what in left_out]
    return lines + [f"# {note}" for note in notes]


def write_g2o_file(
    log: Log,
    point: PointEstimate,
    assignment: Sequence[str],
    path: str | os.PathLike[str],
    *,
    scale: float = 1.0,
    floor: float = MIN_SIGMA,
    comments: Sequence[str] = (),
) -> None:
    """Write the g2o file of :func:`g2o_lines` to ``path`` (atomically)."""
    lines = g2o_lines(log, point, assignment, scale=scale, floor=floor, comments=comments)
    atomic_write_text(path, "\n".join(lines) + "\n")


@dataclass
class G2oGraph:
    """What a g2o file of the ``slam2d`` types holds (other lines are skipped)."""

    vertices: dict[int, np.ndarray] = field(default_factory=dict)
    """Vertex id -> its value, ``(x, y, θ)`` or ``(x, y)``."""
    edges: list[tuple[str, tuple[int, ...], np.ndarray, np.ndarray]] = field(default_factory=list)
    """``(tag, vertex ids, measurement, information matrix)``, in file order."""


def _symmetric(upper: list[float], n: int) -> np.ndarray:
    matrix = np.zeros((n, n))
    matrix[np.triu_indices(n)] = upper
    return matrix + np.triu(matrix, 1).T


def read_g2o_file(path: str | os.PathLike[str]) -> G2oGraph:
    """Read the ``slam2d`` lines of a g2o file (those :func:`write_g2o_file` writes).

    Raises
    ------
    InputFileError
        Naming the file and line when it cannot be read or a known line is malformed.
    """
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError) as err:
        raise InputFileError(path, None, f"cannot read g2o file: {err}") from None
    graph = G2oGraph()
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields or fields[0] not in _SIZES:
            continue
        tag = fields[0]
        n_ids, n_measured, n_info = _SIZES[tag]
        expected = 1 + n_ids + n_measured + n_info
        try:
            ids = tuple(int(f) for f in fields[1 : 1 + n_ids])
            numbers = [float(f) for f in fields[1 + n_ids :]]
        except ValueError:
            ids, numbers = (), []
        if len(fields) != expected or len(ids) != n_ids or not all(map(math.isfinite, numbers)):
            raise InputFileError(
                path,
                number,
                f"{tag} needs {n_ids} vertex id(s) and {expected - 1 - n_ids} finite numbers",
            )
        measured = np.array(numbers[:n_measured])
        if tag.startswith("VERTEX"):
            graph.vertices[ids[0]] = measured
            continue
        size = {6: 3, 3: 2, 1: 1}[n_info]
        graph.edges.append((tag, ids, measured, _symmetric(numbers[n_measured:], size)))
    return graph
