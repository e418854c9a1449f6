"""A small log whose every interval is centred on its true value, for the interop tests.

Four poses (turn, then drive), two landmarks, an exact prior on the first pose, a landmark
prior, a relative pose, range-bearing readings, one bearing-only, one range-only and one
from a sensor mounted off the robot's centre. With every midpoint at the truth, a least-squares
back end that reads the log faithfully has its optimum (error 0) at the truth.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    Record,
    RelativePose,
)
from cuikslam.simulate.truth import GroundTruth

MOVES = [(0.3, 2.0), (0.5, 2.5), (-0.4, 1.5)]  # (turn, distance)
LANDMARKS = {"A": (7.0, 5.0), "B": (2.0, -3.0)}
TURN, DISTANCE, RANGE, BEARING = 0.05, 0.1, 0.05, 0.02  # half-widths
OFFSET = (0.3, -0.1, 0.2)  # a sensor ahead of the centre, turned left


def _around(value: float, half: float) -> tuple[float, float]:
    return (value - half, value + half)


def _poses() -> np.ndarray:
    poses = [np.array([0.0, 0.0, 0.0])]
    for turn, distance in MOVES:
        x, y, theta = poses[-1]
        theta += turn
        poses.append(
            np.array([x + distance * math.cos(theta), y + distance * math.sin(theta), theta])
        )
    return np.array(poses)


def _seen(
    xyt: np.ndarray, point: tuple[float, float], sensor=(0.0, 0.0, 0.0)
) -> tuple[float, float]:
    """(range, bearing) of ``point`` from the sensor at ``sensor`` in the frame of ``xyt``."""
    c, s = math.cos(xyt[2]), math.sin(xyt[2])
    sx = xyt[0] + c * sensor[0] - s * sensor[1]
    sy = xyt[1] + s * sensor[0] + c * sensor[1]
    dx, dy = point[0] - sx, point[1] - sy
    bearing = math.atan2(dy, dx) - xyt[2] - sensor[2]
    return math.hypot(dx, dy), math.remainder(bearing, 2 * math.pi)


def small_world(named: bool = True) -> tuple[Log, GroundTruth]:
    """The log (landmarks named when ``named``) and its truth."""
    poses = _poses()
    name = (lambda m: m) if named else (lambda m: None)
    records: list[Record] = [PosePrior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0))]
    records.append(LandmarkPrior("A", "door", _around(7.0, 0.5), _around(5.0, 0.5)))
    assignment = []
    for k, xyt in enumerate(poses):
        for m, point in LANDMARKS.items():
            r, b = _seen(xyt, point)
            reading = (_around(r, RANGE), _around(b, BEARING))
            offset = None
            if (k, m) == (1, "B"):
                reading = (None, reading[1])  # bearing-only
            elif (k, m) == (2, "A"):
                reading = (reading[0], None)  # range-only
            elif (k, m) == (3, "B"):
                r, b = _seen(xyt, point, OFFSET)
                reading = (_around(r, RANGE), _around(b, BEARING))
                offset = tuple(_around(v, 0.01) for v in OFFSET)
            records.append(Observation(k, "door", *reading, landmark=name(m), offset=offset))
            assignment.append(m)
        if k + 1 < len(poses):
            turn, distance = MOVES[k]
            records.append(Odometry(k, k + 1, _around(turn, TURN), _around(distance, DISTANCE)))
    # pose 3 seen from pose 1 (a loop closure by scan matching)
    c, s = math.cos(poses[1, 2]), math.sin(poses[1, 2])
    dx, dy = poses[3, :2] - poses[1, :2]
    records.append(
        RelativePose(
            1, 3, _around(c * dx + s * dy, 0.1), _around(-s * dx + c * dy, 0.1),
            _around(poses[3, 2] - poses[1, 2], 0.05),
        )
    )  # fmt: skip
    truth = GroundTruth(
        poses_xyt=poses,
        pose_ids=list(range(len(poses))),
        landmarks_xy=np.array(list(LANDMARKS.values())),
        landmark_ids=list(LANDMARKS),
        landmark_classes=["door", "door"],
        assignment=assignment,
    )
    return Log(records, path="<small world>"), truth
