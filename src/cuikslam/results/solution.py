"""What a solve returns: the surviving hypotheses, each with its boxes, and statistics.

Boxes are NumPy arrays whose last axis is ``(lo, hi)``: ``poses`` has shape
``(n_poses, 3, 2)`` for (x, y, theta), ``landmarks`` has shape ``(n_landmarks, 2, 2)``.
Heading boxes are unwrapped: the true heading is congruent (mod 2 pi) to a value inside.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["NOT_REFUTED", "PROVEN", "Hypothesis", "Solution", "TruthReport", "check_truth"]

PROVEN = "proven consistent"
"""A point satisfying every constraint was found and verified in interval arithmetic."""
NOT_REFUTED = "not refuted"
"""Narrowing did not prove the hypothesis impossible (nor was a witness verified)."""


@dataclass
class Hypothesis:
    """One correspondence hypothesis (a kinematic graph) and its narrowed boxes."""

    assignment: list[str]
    """Landmark id of each observation, in log order."""
    pose_ids: list[int]
    poses: np.ndarray
    landmark_ids: list[str]
    landmark_classes: list[str]
    landmarks: np.ndarray
    status: str = NOT_REFUTED
    witness: dict[str, np.ndarray] | None = None
    """A verified solution point (``poses_xyt``, ``landmarks_xy``) when ``status`` is PROVEN."""
    consistency: str = ""
    """The consistency level these boxes reach (``hull``, ``lp``, ``lp-split``)."""

    @property
    def n_landmarks(self) -> int:
        return len(self.landmark_ids)

    @property
    def box_size(self) -> float:
        """Sum of all widths: a ranking key (smaller = more informative)."""
        widths = np.concatenate(
            [
                (self.poses[..., 1] - self.poses[..., 0]).ravel(),
                (self.landmarks[..., 1] - self.landmarks[..., 0]).ravel(),
            ]
        )
        return float(widths.sum())

    def pose(self, pose_id: int) -> np.ndarray:
        """The (3, 2) box of one pose."""
        return self.poses[self.pose_ids.index(pose_id)]

    def landmark(self, landmark_id: str) -> np.ndarray:
        """The (2, 2) box of one landmark."""
        return self.landmarks[self.landmark_ids.index(landmark_id)]


@dataclass
class Solution:
    """Every surviving hypothesis, best-ranked first, and how the solve went."""

    hypotheses: list[Hypothesis]
    complete: bool = True
    """False when a limit dropped hypotheses: then the true one may be missing."""
    statistics: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    log_path: str = ""
    consistency: str = ""
    messages: list[str] = field(default_factory=list)

    @property
    def best(self) -> Hypothesis:
        return self.hypotheses[0]

    @property
    def refuted(self) -> bool:
        """True when every hypothesis was proven impossible: the log is inconsistent."""
        return not self.hypotheses and self.complete


@dataclass
class TruthReport:
    """Which boxes miss the truth (an empty ``misses`` means all contain it)."""

    misses: list[str]
    checked: int

    @property
    def ok(self) -> bool:
        return not self.misses


def _angle_inside(box: np.ndarray, angle: float) -> bool:
    lo, hi = float(box[0]), float(box[1])
    if hi - lo >= 2 * math.pi:
        return True
    k = math.ceil((lo - angle) / (2 * math.pi))
    return lo <= angle + 2 * math.pi * k <= hi


def check_truth(
    hypothesis: Hypothesis,
    pose_ids: list[int],
    poses_xyt: np.ndarray,
    landmark_xy: dict[str, np.ndarray] | None = None,
) -> TruthReport:
    """Check that every box of ``hypothesis`` contains the true pose (and landmark) values.

    Headings are compared modulo 2 pi. ``landmark_xy`` maps the hypothesis' landmark ids
    to true positions (skip landmarks whose identity differs, e.g. in a wrong hypothesis).
    """
    misses: list[str] = []
    checked = 0
    for pose_id, truth in zip(pose_ids, poses_xyt, strict=True):
        if pose_id not in hypothesis.pose_ids:
            continue
        box = hypothesis.pose(pose_id)
        checked += _check_xy(f"pose {pose_id}", box, truth, misses) + 1
        if not _angle_inside(box[2], float(truth[2])):
            misses.append(
                f"pose {pose_id} theta={float(truth[2])!r} not in {box[2].tolist()} (mod 2pi)"
            )
    for landmark_id, xy in (landmark_xy or {}).items():
        if landmark_id not in hypothesis.landmark_ids:
            continue
        checked += _check_xy(
            f"landmark {landmark_id}", hypothesis.landmark(landmark_id), xy, misses
        )
    return TruthReport(misses, checked)


def _check_xy(label: str, box: np.ndarray, xy: Sequence[float], misses: list[str]) -> int:
    """Append a line to ``misses`` for each of x, y outside its box; return 2 (bounds checked)."""
    for j, name in enumerate(("x", "y")):
        if not box[j, 0] <= xy[j] <= box[j, 1]:
            misses.append(f"{label} {name}={float(xy[j])!r} not in {box[j].tolist()}")
    return 2
