"""Result files: the JSON contract read by other tools, and a flat CSV.

The JSON layout, with every key it has, is documented in ``docs/result-format.md``
(``tests/test_result_doc.py`` keeps the page and :func:`solution_to_json` in step): the
solve's ``complete``, ``refuted``, ``consistency``, ``statistics``, ``timings`` and
``messages``; each hypothesis' assignment, pose and landmark boxes, status, level, rank
and witness; for unknown correspondence, what the survivors agree on
(``correspondence``).

Bounds are written with full precision (``repr`` of the floats), so reading a result
back gives the same boxes; an unbounded side is ``null``. Files are written atomically.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from typing import Any

import numpy as np

from cuikslam import __version__
from cuikslam._atomic import atomic_write_text
from cuikslam._json import dumps
from cuikslam.errors import InputFileError
from cuikslam.outcome.solution import Envelope, Hypothesis, Solution, bounds_to_json

__all__ = [
    "bounds_to_json",
    "read_result_file",
    "solution_to_json",
    "write_result_csv",
    "write_result_file",
]


def _hypothesis_to_json(h: Hypothesis, rank: int) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "assignment": list(h.assignment),
        "poses": {
            str(p): {"x": b[0], "y": b[1], "theta": b[2]}
            for p, b in zip(h.pose_ids, bounds_to_json(h.poses), strict=True)
        },
        "landmarks": {
            m: {"class": c, "x": b[0], "y": b[1]}
            for m, c, b in zip(
                h.landmark_ids, h.landmark_classes, bounds_to_json(h.landmarks), strict=True
            )
        },
        "status": h.status,
        "consistency": h.consistency,
        "rank": rank,
        "n_landmarks": h.n_landmarks,
    }
    if math.isfinite(h.fit):
        doc["fit"] = h.fit
    if h.witness is not None:
        doc["witness"] = {k: np.asarray(v).tolist() for k, v in h.witness.items()}
    return doc


def solution_to_json(solution: Solution) -> dict[str, Any]:
    """The result document of ``solution`` as plain JSON-ready Python objects."""
    return {
        "complete": solution.complete,
        "refuted": solution.refuted,
        "hypotheses": [_hypothesis_to_json(h, i + 1) for i, h in enumerate(solution.hypotheses)],
        "statistics": dict(solution.statistics),
        "timings": dict(solution.timings),
        "messages": list(solution.messages),
        "log": solution.log_path,
        "consistency": solution.consistency,
        "cuikslam_version": __version__,
        **(
            {}
            if solution.correspondence is None
            else {"correspondence": _correspondence_json(solution.correspondence)}
        ),
        **({} if solution.outliers is None else {"outliers": solution.outliers}),
        **({} if solution.envelope is None else {"envelope": _envelope_json(solution.envelope)}),
    }


def _envelope_json(envelope: Envelope) -> dict[str, Any]:
    """The envelope: pose id -> its (x, y, theta) box, and each observation's (x, y) box."""
    return {
        "poses": {
            str(p): {"x": b[0], "y": b[1], "theta": b[2]}
            for p, b in zip(envelope.pose_ids, bounds_to_json(envelope.poses), strict=True)
        },
        "observations": [{"x": b[0], "y": b[1]} for b in bounds_to_json(envelope.observations)],
    }


def _read_envelope(doc: Any) -> Envelope | None:
    """The envelope read back (null sides infinite again); None without one."""
    if doc is None:
        return None
    poses = doc["poses"]
    boxes = [
        [_read_bounds(poses[p][k], f"envelope pose {p} {k}") for k in ("x", "y", "theta")]
        for p in poses
    ]
    seen = [
        [_read_bounds(o[k], f"envelope observation {i} {k}") for k in ("x", "y")]
        for i, o in enumerate(doc["observations"])
    ]
    return Envelope(
        [int(p) for p in poses],
        np.array(boxes, dtype=np.float64).reshape(-1, 3, 2),
        np.array(seen, dtype=np.float64).reshape(-1, 2, 2),
    )


def _correspondence_json(correspondence: dict[str, Any]) -> dict[str, Any]:
    """The correspondence summary with its pose hull's unbounded sides as null."""
    hull = correspondence.get("pose_hull")
    if hull is None:
        return correspondence
    return {**correspondence, "pose_hull": bounds_to_json(np.asarray(hull, dtype=np.float64))}


def _read_correspondence(correspondence: Any) -> Any:
    """The correspondence summary read back, its pose hull's null sides infinite again."""
    if not isinstance(correspondence, dict) or correspondence.get("pose_hull") is None:
        return correspondence
    hull = [
        [list(_read_bounds(side, f"correspondence pose_hull, pose {i + 1}")) for side in box]
        for i, box in enumerate(correspondence["pose_hull"])
    ]
    return {**correspondence, "pose_hull": hull}


def write_result_file(solution: Solution, path: str | os.PathLike[str]) -> None:
    """Write the JSON result of ``solution`` to ``path`` (atomically)."""
    text = dumps(solution_to_json(solution), finite=_finite(solution))
    atomic_write_text(path, text + "\n")


def _finite(solution: Solution) -> bool:
    """No NaN or infinity among the floats the result document holds (bounds and the pose
    hull write infinities as null, so only a NaN counts there): witnesses, statistics,
    timings, the pose hull."""
    hull = (solution.correspondence or {}).get("pose_hull")
    if hull is not None and np.isnan(np.asarray(hull, dtype=float)).any():
        return False
    envelope = solution.envelope
    if envelope is not None and (
        np.isnan(envelope.poses).any() or np.isnan(envelope.observations).any()
    ):
        return False
    for value in (*solution.statistics.values(), *solution.timings.values()):
        if not (
            isinstance(value, int | str) or (isinstance(value, float) and math.isfinite(value))
        ):
            return False
    for h in solution.hypotheses:
        if np.isnan(h.poses).any() or np.isnan(h.landmarks).any():
            return False
        if h.witness is not None and not all(
            np.isfinite(np.asarray(v, dtype=float)).all() for v in h.witness.values()
        ):
            return False
    return True


def _read_bounds(value: Any, where: str) -> tuple[float, float]:
    """``[lo, hi]`` of finite numbers (``null`` = unbounded side) with ``lo <= hi``."""
    if type(value) is list and len(value) == 2:  # the common case, decided at once
        lo, hi = value
        if type(lo) is float and type(hi) is float and -math.inf < lo <= hi < math.inf:
            return lo, hi
    shown = json.dumps(value)
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    if not (isinstance(value, list) and len(value) == 2):
        raise ValueError(f"{where} must be [lo, hi], got {shown}")
    for v in value:
        if v is not None and (isinstance(v, bool) or not isinstance(v, int | float)):
            raise ValueError(f"{where} must be [lo, hi] of two numbers (or null), got {shown}")
        if v is not None and not math.isfinite(v):
            raise ValueError(f"{where} holds {v}; bounds must be finite numbers or null")
    lo = -math.inf if value[0] is None else float(value[0])
    hi = math.inf if value[1] is None else float(value[1])
    if lo > hi:
        raise ValueError(f"{where} is the interval {shown} with lo > hi")
    return lo, hi


def _read_fit(value: Any, where: str) -> float:
    if value is None:
        return math.nan
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
        raise ValueError(f"{where} fit is {value!r}, not a number >= 0")
    return float(value)


def _hypothesis_from_json(doc: dict[str, Any], where: str) -> Hypothesis:
    poses = doc["poses"]
    pose_ids = [int(p) for p in poses]
    pose_boxes = np.array(
        [[_read_bounds(poses[p][k], f"{where} pose {p} {k}") for k in ("x", "y", "theta")]
         for p in poses],
        dtype=np.float64,
    ).reshape(len(pose_ids), 3, 2)  # fmt: skip
    marks = doc.get("landmarks", {})
    landmark_boxes = np.array(
        [[_read_bounds(marks[m][k], f"{where} landmark {m} {k}") for k in ("x", "y")]
         for m in marks],
        dtype=np.float64,
    ).reshape(len(marks), 2, 2)  # fmt: skip
    witness = doc.get("witness")
    return Hypothesis(
        assignment=[str(a) for a in doc.get("assignment", [])],
        pose_ids=pose_ids,
        poses=pose_boxes,
        landmark_ids=list(marks),
        landmark_classes=[str(marks[m].get("class", "")) for m in marks],
        landmarks=landmark_boxes,
        status=str(doc.get("status", "")),
        consistency=str(doc.get("consistency", "")),
        witness=None if witness is None else {k: np.asarray(v) for k, v in witness.items()},
        fit=_read_fit(doc.get("fit"), where),
    )


def read_result_file(path: str | os.PathLike[str]) -> Solution:
    """Read a result JSON written by :func:`write_result_file`.

    Raises InputFileError (one line naming the file) if it is unreadable or malformed.
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as handle:
            doc = json.load(handle)
    except OSError as err:
        raise InputFileError(name, None, f"cannot read result file: {err.strerror}") from None
    except json.JSONDecodeError as err:
        raise InputFileError(name, err.lineno, f"malformed JSON: {err.msg}") from None
    except UnicodeDecodeError as err:
        problem = f"the file is not UTF-8 text (bad byte at offset {err.start})"
        raise InputFileError(name, None, problem) from None
    except RecursionError:
        raise InputFileError(name, None, "malformed JSON: nested too deeply") from None
    if not isinstance(doc, dict):
        problem = 'not a cuikslam result file: expected a JSON object {"hypotheses": ...}'
        raise InputFileError(name, None, problem)
    try:
        hypotheses = [
            _hypothesis_from_json(h, f"hypothesis {i + 1}") for i, h in enumerate(doc["hypotheses"])
        ]
        return Solution(
            hypotheses=hypotheses,
            complete=bool(doc.get("complete", True)),
            statistics=dict(doc.get("statistics", {})),
            timings=dict(doc.get("timings", {})),
            log_path=str(doc.get("log", "")),
            consistency=str(doc.get("consistency", "")),
            messages=list(doc.get("messages", [])),
            correspondence=_read_correspondence(doc.get("correspondence")),
            outliers=doc.get("outliers"),
            envelope=_read_envelope(doc.get("envelope")),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as err:
        problem = f"missing key {err}" if isinstance(err, KeyError) else str(err)
        raise InputFileError(name, None, f"not a cuikslam result file: {problem}") from None


def write_result_csv(solution: Solution, path: str | os.PathLike[str]) -> None:
    """One row per box: hypothesis rank, kind (pose/landmark), id, then x, y, theta bounds."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        ["hypothesis", "kind", "id", "class", "x_lo", "x_hi", "y_lo", "y_hi", "theta_lo",
         "theta_hi"]
    )  # fmt: skip
    for rank, h in enumerate(solution.hypotheses, start=1):
        for p, b in zip(h.pose_ids, h.poses, strict=True):
            writer.writerow([rank, "pose", p, "", *map(repr, b.ravel().tolist())])
        for m, c, b in zip(h.landmark_ids, h.landmark_classes, h.landmarks, strict=True):
            writer.writerow([rank, "landmark", m, c, *map(repr, b.ravel().tolist()), "", ""])
    atomic_write_text(path, buffer.getvalue())
