"""The seed paper's experiment: an octagonal loop in a 30 m square room with four landmarks.

The robot drives a regular octagon inscribed in the circle of radius 10 m centred at
(15, 15).  Pose ``k`` (1..9) sits on the circle at angle −90° + 45°·(k − 1), so pose 9
closes the loop on pose 1 = (15, 5).  Each pose's heading is the direction of the chord
it has just driven; pose 1's heading, −22.5°, is the direction of the chord from pose 8,
so every odometry step is a 45° turn followed by a 7.654 m drive.  The landmarks sit at
the wall midpoints.  :func:`paper_table1` gives the paper's own published boxes, to
compare box widths against.
"""

from __future__ import annotations

import csv
import math
from importlib import resources
from types import MappingProxyType

import numpy as np

from cuikslam.log.records import (
    Bounds,
    Log,
    Observation,
    Odometry,
    PosePrior,
    Record,
    SensorModel,
)
from cuikslam.simulate.truth import GroundTruth, noisy_interval, wrap_angle

__all__ = [
    "BEARING_BOUND",
    "CENTRE_XY",
    "DISTANCE_BOUND",
    "FIRST_HEADING",
    "LANDMARKS",
    "PAPER_SURVIVORS",
    "POSE_IDS",
    "RADIUS",
    "RANGE_BOUND",
    "ROOM_SIZE",
    "TIE_MARGIN",
    "TURN_BOUND",
    "paper_survivors",
    "paper_table1",
    "paper_truth",
    "simulate_paper",
]

ROOM_SIZE = 30.0
"""The room is the square [0, ROOM_SIZE]² (metres)."""
CENTRE_XY = (15.0, 15.0)
RADIUS = 10.0
POSE_IDS = tuple(range(1, 10))
"""The paper's pose numbering; pose 9 is back at pose 1's position."""
FIRST_HEADING = -math.pi / 8
"""Pose 1's heading (−22.5°), known exactly as the prior says."""
LANDMARKS = MappingProxyType(
    {
        "L1": ("door", (15.0, 0.0)),
        "L2": ("corridor", (30.0, 15.0)),
        "L3": ("door", (15.0, 30.0)),
        "L4": ("corridor", (0.0, 15.0)),
    }
)
"""Landmark id -> (class, (x, y)), at the wall midpoints."""
TIE_MARGIN = 0.5
"""A pose sees its nearest landmark and every landmark within this many metres as near."""
TURN_BOUND = math.radians(5.0)
DISTANCE_BOUND = 0.25
RANGE_BOUND = 0.025
BEARING_BOUND = math.radians(0.5)

PAPER_SURVIVORS = MappingProxyType(
    {"hypotheses": 5, "label_swapped_pairs": 2, "distinct_up_to_labels": 3}
)
"""What the seed paper reports under unknown correspondence: 5 surviving hypotheses, two
pairs of which differ only in landmark labels, so 3 distinct maps."""


def paper_truth() -> GroundTruth:
    """The true poses, landmarks and landmark sightings of the paper's experiment."""
    k = np.arange(len(POSE_IDS))
    angles = -np.pi / 2 + k * np.pi / 4
    poses_xyt = np.column_stack(
        (
            CENTRE_XY[0] + RADIUS * np.cos(angles),
            CENTRE_XY[1] + RADIUS * np.sin(angles),
            FIRST_HEADING + k * np.pi / 4,
        )
    )
    poses_xyt[-1, :2] = poses_xyt[0, :2]  # close the loop exactly, not up to cos rounding
    landmarks_xy = np.array([xy for _, xy in LANDMARKS.values()])
    assignment = [lid for xyt in poses_xyt for lid in _seen_from(xyt[:2], landmarks_xy)]
    return GroundTruth(
        poses_xyt=poses_xyt,
        pose_ids=list(POSE_IDS),
        landmarks_xy=landmarks_xy,
        landmark_ids=list(LANDMARKS),
        landmark_classes=[cls for cls, _ in LANDMARKS.values()],
        assignment=assignment,
    )


def simulate_paper(seed: int = 0, unknown: bool = False) -> tuple[Log, GroundTruth]:
    """Simulate the paper's experiment as a log with bounded errors.

    Records come in time order: pose 1's exact prior, then at each pose its observations
    followed by the odometry to the next pose.  Errors are uniform inside the bounds, drawn
    from ``numpy.random.default_rng(seed)`` in record order.

    Parameters
    ----------
    seed : int
        Seed of the measurement errors.
    unknown : bool
        If true, observations carry their landmark class only, not the landmark id.
        The measurements are the same as with ``unknown=False``.
    """
    rng = np.random.default_rng(seed)
    truth = paper_truth()
    x1, y1, t1 = (float(v) for v in truth.poses_xyt[0])
    records: list[Record] = [
        SensorModel(nearest_margin=TIE_MARGIN),
        PosePrior(POSE_IDS[0], (x1, x1), (y1, y1), (t1, t1)),
    ]
    for i, pose in enumerate(POSE_IDS):
        xyt = truth.poses_xyt[i]
        for lid in _seen_from(xyt[:2], truth.landmarks_xy):
            dx, dy = truth.landmark_xy(lid) - xyt[:2]
            records.append(
                Observation(
                    pose=pose,
                    landmark_class=truth.landmark_class(lid),
                    range=noisy_interval(math.hypot(dx, dy), RANGE_BOUND, rng, non_negative=True),
                    bearing=noisy_interval(
                        wrap_angle(math.atan2(dy, dx) - xyt[2]), BEARING_BOUND, rng
                    ),
                    landmark=None if unknown else lid,
                )
            )
        if i + 1 < len(POSE_IDS):
            dx, dy, turn = truth.poses_xyt[i + 1] - xyt
            records.append(
                Odometry(
                    source=pose,
                    target=POSE_IDS[i + 1],
                    turn=noisy_interval(float(turn), TURN_BOUND, rng),
                    distance=noisy_interval(
                        math.hypot(dx, dy), DISTANCE_BOUND, rng, non_negative=True
                    ),
                )
            )
    return Log(records=records, path=f"<paper seed={seed}>"), truth


def paper_table1() -> list[tuple[str, Bounds, Bounds, Bounds | None]]:
    """The seed paper's Table 1: its boxes for poses ``"r 1"``..``"r 9"`` and landmarks
    ``"l 1"``..``"l 4"`` as ``(description, x, y, theta)``, ``theta`` None for landmarks.

    The numbers are as published; the paper's θ uses another convention (r 1 is 112.5°,
    our −22.5°), so compare widths, not positions.
    """
    source = resources.files("cuikslam") / "data" / "paper_table1.csv"
    with source.open("r", encoding="utf-8", newline="") as stream:
        rows = list(csv.DictReader(stream))
    return [
        (
            row["description"],
            (float(row["x_lo"]), float(row["x_hi"])),
            (float(row["y_lo"]), float(row["y_hi"])),
            (float(row["theta_lo"]), float(row["theta_hi"])) if row["theta_lo"] else None,
        )
        for row in rows
    ]


def paper_survivors() -> dict[str, int]:
    """The seed paper's surviving hypotheses under unknown correspondence (a copy of
    :data:`PAPER_SURVIVORS`)."""
    return dict(PAPER_SURVIVORS)


def _seen_from(position_xy: np.ndarray, landmarks_xy: np.ndarray) -> list[str]:
    """The landmarks seen from ``position_xy``: the nearest and all within TIE_MARGIN of it."""
    distances = np.hypot(*(landmarks_xy - position_xy).T)
    near = distances <= distances.min() + TIE_MARGIN
    return [lid for lid, seen in zip(LANDMARKS, near, strict=True) if seen]
