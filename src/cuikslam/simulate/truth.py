"""The ground truth behind a simulated log, its JSON file, and how it is measured.

A simulator returns a :class:`GroundTruth` next to its :class:`~cuikslam.log.records.Log`
so that tests and benchmarks can check that every guaranteed box contains the truth.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cuikslam._atomic import atomic_write_text
from cuikslam.log.errors import LogFormatError
from cuikslam.log.records import Bounds

__all__ = [
    "GroundTruth",
    "noisy_interval",
    "read_truth_file",
    "truth_to_json",
    "wrap_angle",
    "write_truth_file",
]


@dataclass(eq=False)
class GroundTruth:
    """The true poses and landmarks of a simulated run (compared by identity: it holds arrays).

    Attributes
    ----------
    poses_xyt : np.ndarray
        (n, 3) true ``x, y, theta`` of each pose, row ``i`` for ``pose_ids[i]``.
        Headings are the running sum of the true turns (not wrapped), so that
        ``theta_to = theta_from + turn`` holds without 2π jumps.
    pose_ids : list[int]
        The pose ids of the log, in time order.
    landmarks_xy : np.ndarray
        (m, 2) true landmark positions, row ``j`` for ``landmark_ids[j]``.
    landmark_ids : list[str]
        Landmark ids.
    landmark_classes : list[str]
        The class of each landmark.
    assignment : list[str]
        The true landmark id of each observation, in log order.
    """

    poses_xyt: np.ndarray
    pose_ids: list[int]
    landmarks_xy: np.ndarray
    landmark_ids: list[str]
    landmark_classes: list[str]
    assignment: list[str]

    def pose_xyt(self, pose: int) -> np.ndarray:
        """The true ``(x, y, theta)`` of pose id ``pose``."""
        return self.poses_xyt[self.pose_ids.index(pose)]

    def landmark_xy(self, landmark: str) -> np.ndarray:
        """The true ``(x, y)`` of landmark id ``landmark``."""
        return self.landmarks_xy[self.landmark_ids.index(landmark)]

    def landmark_class(self, landmark: str) -> str:
        """The class of landmark id ``landmark``."""
        return self.landmark_classes[self.landmark_ids.index(landmark)]


def wrap_angle(angle: float) -> float:
    """``angle`` wrapped to (−π, π]."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def noisy_interval(
    true_value: float, bound: float, rng: np.random.Generator, *, non_negative: bool = False
) -> Bounds:
    """Simulate one bounded-error measurement of ``true_value``.

    The sensor reads ``true_value + e`` with ``e`` uniform in ``[-bound, bound]``; the log
    stores ``[reading - bound, reading + bound]``, which contains ``true_value``.  The
    ``min``/``max`` only absorb floating-point rounding of ``reading ± bound``.  With
    ``non_negative`` (ranges, distances: the log format requires ``lo >= 0``) a negative
    ``lo`` is raised to 0, which still contains the non-negative truth.
    """
    reading = true_value + float(rng.uniform(-bound, bound))
    lo = min(reading - bound, true_value)
    return (max(lo, 0.0) if non_negative else lo, max(reading + bound, true_value))


def truth_to_json(truth: GroundTruth) -> dict[str, Any]:
    """The JSON document of ``truth`` (see :func:`write_truth_file`)."""
    return {
        "poses": {
            str(pose): [float(v) for v in xyt]
            for pose, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True)
        },
        "landmarks": {
            lid: {"class": cls, "x": float(xy[0]), "y": float(xy[1])}
            for lid, cls, xy in zip(
                truth.landmark_ids, truth.landmark_classes, truth.landmarks_xy, strict=True
            )
        },
        "assignment": list(truth.assignment),
    }


def write_truth_file(truth: GroundTruth, path: str | os.PathLike[str]) -> None:
    """Write ``truth`` as JSON: ``{"poses": {"0": [x, y, theta]}, "landmarks": {"L0":
    {"class": .., "x": .., "y": ..}}, "assignment": [..]}``."""
    atomic_write_text(path, json.dumps(truth_to_json(truth), indent=1, allow_nan=False) + "\n")


def read_truth_file(path: str | os.PathLike[str]) -> GroundTruth:
    """Read a truth file written by :func:`write_truth_file`.

    Raises
    ------
    LogFormatError
        If the file cannot be read, is not JSON, or does not have the truth layout.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise LogFormatError(path, None, f"cannot read truth file: {exc}") from exc
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise LogFormatError(path, exc.lineno, f"not valid JSON: {exc.msg}") from exc
    try:
        return _truth_from_json(doc)
    except _TruthLayoutError as exc:
        raise LogFormatError(path, None, str(exc)) from None


class _TruthLayoutError(Exception):
    """A JSON document that is not a truth file; turned into ``LogFormatError``."""


def _truth_from_json(doc: Any) -> GroundTruth:
    if not isinstance(doc, dict):
        raise _TruthLayoutError("a truth file must be a JSON object")
    missing = [key for key in ("poses", "landmarks", "assignment") if key not in doc]
    if missing:
        raise _TruthLayoutError(f"truth file lacks key(s) {', '.join(map(repr, missing))}")
    poses, landmarks, assignment = doc["poses"], doc["landmarks"], doc["assignment"]
    if not isinstance(poses, dict):
        raise _TruthLayoutError('"poses" must be an object {"<pose id>": [x, y, theta]}')
    if not isinstance(landmarks, dict):
        raise _TruthLayoutError('"landmarks" must be an object {"<id>": {"class", "x", "y"}}')
    if not isinstance(assignment, list):
        raise _TruthLayoutError('"assignment" must be a list of landmark ids')

    pose_ids: list[int] = []
    poses_xyt = np.empty((len(poses), 3))
    for i, (key, xyt) in enumerate(poses.items()):
        try:
            pose_ids.append(int(key))
        except ValueError:
            raise _TruthLayoutError(f"pose id {key!r} is not an integer") from None
        if pose_ids[-1] in pose_ids[:-1]:
            raise _TruthLayoutError(f"pose id {key!r} appears twice")
        if not (isinstance(xyt, list) and len(xyt) == 3):
            raise _TruthLayoutError(f"pose {key}: expected [x, y, theta], got {xyt!r}")
        poses_xyt[i] = [_finite(v, f"pose {key}") for v in xyt]

    landmark_classes: list[str] = []
    landmarks_xy = np.empty((len(landmarks), 2))
    for j, (lid, entry) in enumerate(landmarks.items()):
        if not (isinstance(entry, dict) and {"class", "x", "y"} <= entry.keys()):
            raise _TruthLayoutError(f'landmark {lid}: expected {{"class", "x", "y"}}')
        if not isinstance(entry["class"], str):
            raise _TruthLayoutError(f"landmark {lid}: class must be a string")
        landmark_classes.append(entry["class"])
        landmarks_xy[j] = [_finite(entry[k], f"landmark {lid}") for k in ("x", "y")]

    for k, lid in enumerate(assignment):
        if not isinstance(lid, str) or lid not in landmarks:
            raise _TruthLayoutError(f"assignment[{k}] = {lid!r} is not a landmark id")
    return GroundTruth(
        poses_xyt=poses_xyt,
        pose_ids=pose_ids,
        landmarks_xy=landmarks_xy,
        landmark_ids=list(landmarks),
        landmark_classes=landmark_classes,
        assignment=list(assignment),
    )


def _finite(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise _TruthLayoutError(f"{where}: {value!r} is not a finite number")
    return float(value)
