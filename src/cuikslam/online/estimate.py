"""What an online session says about a pose once the pose is finished: its box."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cuikslam.outcome.solution import Hypothesis, TruthReport, bounds_to_json, check_truth
from cuikslam.simulate.truth import GroundTruth

__all__ = ["PoseEstimate", "check_estimates"]


@dataclass(frozen=True)
class PoseEstimate:
    """The box of one pose, as an online session gives it when the pose is finished.

    Examples
    --------
    >>> box = np.array([[1.0, 2.0], [0.5, 0.75], [-np.inf, np.inf]])
    >>> line = PoseEstimate(pose=3, box=box, latency_s=0.0015, hypotheses=1).to_json()
    >>> line
    {'pose': 3, 'x': [1.0, 2.0], 'y': [0.5, 0.75], 'theta': [None, None], 'latency_s': ...}
    >>> line["hypotheses"]
    1
    """

    pose: int
    box: np.ndarray
    """(3, 2): x, y, theta (radians, modulo 2π) by (lo, hi)."""
    latency_s: float
    """Seconds from the arrival of the record that finished the pose (or of the end of the
    input) to this box."""
    hypotheses: int
    """Correspondence hypotheses alive (1 with known correspondence); with several, the
    box is the hull of theirs."""

    def to_json(self) -> dict[str, Any]:
        """The JSON line of ``cuikslam follow``: an unbounded side is ``null``."""
        x, y, theta = bounds_to_json(self.box)
        return {
            "pose": int(self.pose),
            "x": x,
            "y": y,
            "theta": theta,
            "latency_s": float(self.latency_s),
            "hypotheses": int(self.hypotheses),
        }


def check_estimates(estimates: Sequence[PoseEstimate], truth: GroundTruth) -> TruthReport:
    """Check, exactly, that every box holds its true pose (headings modulo 2π); poses the
    truth lacks (a Vicon gap) are not checked.

    Examples
    --------
    >>> truth = GroundTruth(np.array([[1.5, 0.6, 6.3]]), [3], np.zeros((0, 2)), [], [], [])
    >>> box = np.array([[1.0, 2.0], [0.5, 0.75], [0.0, 0.1]])
    >>> check_estimates([PoseEstimate(3, box, 0.0, 1)], truth)
    TruthReport(misses=[], checked=3)
    """
    hypothesis = Hypothesis(
        assignment=[],
        pose_ids=[e.pose for e in estimates],
        poses=np.array([e.box for e in estimates]).reshape(-1, 3, 2),
        landmark_ids=[],
        landmark_classes=[],
        landmarks=np.zeros((0, 2, 2)),
    )
    return check_truth(hypothesis, truth.pose_ids, truth.exact_poses())
