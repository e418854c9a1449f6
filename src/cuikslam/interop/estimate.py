"""Point estimates: one (x, y, theta) per pose and (x, y) per landmark, and their GTSAM keys.

A hypothesis gives a point in two ways: its witness (a point proven to satisfy every
constraint, when its status is ``proven consistent``) or its box centres; a truth file
gives the truth. Exporters (TUM, g2o) and the GTSAM initial values read both the same way.

GTSAM keys follow GTSAM's own convention, computed here without importing it: pose ``p`` is
``X(p)`` = ``gtsam.symbol('x', p)``; the ``j``-th landmark of a hypothesis (its
``landmark_ids[j]``) is ``L(j)`` = ``gtsam.symbol('l', j)``.

Examples
--------
>>> pose_key(3) == (ord("x") << 56) + 3, landmark_key(0) == ord("l") << 56
(True, True)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from cuikslam.interval.midpoints import midpoint

if TYPE_CHECKING:
    from cuikslam.outcome.solution import Hypothesis
    from cuikslam.simulate.truth import GroundTruth

__all__ = [
    "PointEstimate",
    "Source",
    "hypothesis_estimate",
    "landmark_key",
    "pose_key",
    "truth_estimate",
]

_INDEX_BITS = 56  # gtsam.Symbol: an 8-bit character above a 56-bit index
Source = Literal["auto", "witness", "centres"]
"""Which point of a hypothesis: its witness, its box centres, or ``auto`` (the witness
where it has one, else the box centres)."""


def _symbol(character: str, index: int) -> int:
    if not 0 <= index < 1 << _INDEX_BITS:
        raise ValueError(f"a GTSAM key index must be in [0, 2**56), got {index}")
    return (ord(character) << _INDEX_BITS) | index


def pose_key(pose_id: int) -> int:
    """The GTSAM key of pose ``pose_id``: ``gtsam.symbol('x', pose_id)``."""
    return _symbol("x", int(pose_id))


def landmark_key(index: int) -> int:
    """The GTSAM key of a hypothesis' ``index``-th landmark: ``gtsam.symbol('l', index)``."""
    return _symbol("l", int(index))


@dataclass(frozen=True)
class PointEstimate:
    """One point per pose and per landmark, and where it comes from.

    Attributes
    ----------
    pose_ids : list of int
        Pose ids, row ``i`` of ``poses_xyt`` for ``pose_ids[i]``.
    poses_xyt : ndarray, shape (n, 3)
        ``x, y, theta`` of each pose.
    landmark_ids : list of str
        Landmark ids, row ``j`` of ``landmarks_xy`` for ``landmark_ids[j]``.
    landmarks_xy : ndarray, shape (m, 2)
        ``x, y`` of each landmark.
    source : str
        ``"witness"``, ``"box centres"``, ``"witness, box centres where it has no value"``
        or ``"truth"``: said in the header of an exported file.
    """

    pose_ids: list[int]
    poses_xyt: np.ndarray
    landmark_ids: list[str]
    landmarks_xy: np.ndarray
    source: str


def _centres(boxes: np.ndarray) -> np.ndarray:
    """Box centres; an unbounded side gives way to the bounded one, and 0 when both are."""
    lo, hi = boxes[..., 0], boxes[..., 1]
    centre = midpoint(lo, hi)
    centre = np.where(np.isfinite(lo) & ~np.isfinite(hi), lo, centre)
    centre = np.where(np.isfinite(hi) & ~np.isfinite(lo), hi, centre)
    return np.where(np.isfinite(centre), centre, 0.0)


def hypothesis_estimate(hypothesis: Hypothesis, source: Source = "auto") -> PointEstimate:
    """A point of ``hypothesis``: its witness, its box centres, or (``auto``) the witness
    when it has one.

    Parameters
    ----------
    hypothesis : Hypothesis
        A hypothesis of a solution.
    source : {"auto", "witness", "centres"}
        Which point; rows the witness leaves without a value (NaN) take the box centre.

    Raises
    ------
    ValueError
        ``source="witness"`` for a hypothesis without a witness.

    Examples
    --------
    >>> import cuikslam
    >>> h = cuikslam.Hypothesis(["L1"], [0], np.array([[[0.0, 2.0], [1.0, 1.0], [0.0, 0.5]]]),
    ...                         ["L1"], ["door"], np.array([[[4.0, 6.0], [-1.0, np.inf]]]))
    >>> point = hypothesis_estimate(h)
    >>> point.source, point.poses_xyt.tolist(), point.landmarks_xy.tolist()
    ('box centres', [[1.0, 1.0, 0.25]], [[5.0, -1.0]])
    """
    if source not in ("auto", "witness", "centres"):
        raise ValueError(f"source must be 'auto', 'witness' or 'centres', got {source!r}")
    poses, landmarks = _centres(hypothesis.poses), _centres(hypothesis.landmarks)
    witness = hypothesis.witness
    if source == "witness" and witness is None:
        raise ValueError(
            f"the hypothesis has no witness (status {hypothesis.status!r}); "
            "use its box centres instead"
        )
    if source == "centres" or witness is None:
        return PointEstimate(
            list(hypothesis.pose_ids), poses, list(hypothesis.landmark_ids), landmarks,
            "box centres",
        )  # fmt: skip
    seen_poses = np.asarray(witness["poses_xyt"], dtype=float).reshape(poses.shape)
    seen_landmarks = np.asarray(witness["landmarks_xy"], dtype=float).reshape(landmarks.shape)
    gaps = bool(np.isnan(seen_poses).any() or np.isnan(seen_landmarks).any())
    return PointEstimate(
        list(hypothesis.pose_ids),
        np.where(np.isnan(seen_poses), poses, seen_poses),
        list(hypothesis.landmark_ids),
        np.where(np.isnan(seen_landmarks), landmarks, seen_landmarks),
        "witness, box centres where it has no value" if gaps else "witness",
    )


def truth_estimate(truth: GroundTruth) -> PointEstimate:
    """The true poses and landmarks of a truth file, as a point estimate (nearest floats)."""
    return PointEstimate(
        list(truth.pose_ids),
        np.asarray(truth.poses_xyt, dtype=float).reshape(-1, 3),
        list(truth.landmark_ids),
        np.asarray(truth.landmarks_xy, dtype=float).reshape(-1, 2),
        "truth",
    )
