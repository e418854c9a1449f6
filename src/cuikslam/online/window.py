"""The stronger level online: the polytope-hull operator on a window of recent poses.

The ``lp`` level of a batch solve sweeps windows of ``WINDOW_POSES`` consecutive poses
along the whole log (:mod:`cuikslam.narrowing.sweeps`). Online, the window is the last
poses finished: their moves, the observations made from them (and from their sensors'
poses), and the landmarks those see. :func:`tighten_window` bounds each of their
variables over the linear relaxation of those factors (:func:`~cuikslam.narrowing.polytope.tighten`,
each bound certified by its safe bound, so that the window's boxes stay sound) and
returns the variables it narrowed, whose factors the caller then wakes.
"""

from __future__ import annotations

from collections.abc import Collection

import numpy as np

from cuikslam.budget import Budget
from cuikslam.graph.encoding import KIND, OBSERVATION, ODOMETRY, RELATIVE, ROTATION, XA, XB
from cuikslam.narrowing.polytope import tighten
from cuikslam.narrowing.sweeps import WINDOW_POSES
from cuikslam.online.growing import GrowingGraph

__all__ = ["WINDOW_POSES", "tighten_window", "window_rows"]


def window_rows(
    grown: GrowingGraph, pose_xs: np.ndarray, all_pose_xs: Collection[int]
) -> tuple[np.ndarray, np.ndarray]:
    """The factors of the window of poses at x variables ``pose_xs`` and the variables to
    bound. ``all_pose_xs`` holds the x variable of every pose of the graph: a move from a
    window pose to a variable that is no pose reaches a sensor's pose (an observation
    offset). The factors: moves between two window poses and to their sensors' poses,
    observations from them all; the variables: the positions and headings of those poses
    and the positions of the landmarks seen, x first, then y, then headings (consecutive
    LPs then have nearby optima).

    Examples
    --------
    >>> from cuikslam.graph.encoding import ODOMETRY, OBSERVATION
    >>> grown = GrowingGraph(rtol=1e-3)
    >>> _ = grown.add_variables(np.zeros(15), np.ones(15))
    >>> _ = grown.add_factors([[ODOMETRY, 0, 1, 2, 3, 4, 5, 6, 7],
    ...                        [OBSERVATION, 3, 4, 5, 8, 9, -1, 10, 11],
    ...                        [ODOMETRY, 3, 4, 5, 12, 13, 14, 6, 7]])
    >>> factors, targets = window_rows(grown, np.array([0, 3]), {0, 3, 12})
    >>> factors.tolist(), targets.tolist()
    ([0, 1], [0, 3, 8, 1, 4, 9, 2, 5])
    """
    pose_xs = np.unique(np.asarray(pose_xs, dtype=np.int64))
    rows = grown.factors_of(np.concatenate([pose_xs, pose_xs + 1, pose_xs + 2]))
    table = grown.factors[rows]
    kind, xb = table[:, KIND], table[:, XB]
    moves = np.isin(kind, (ODOMETRY, RELATIVE, ROTATION)) & np.isin(table[:, XA], pose_xs)
    to_sensor = moves & np.array([int(v) not in all_pose_xs for v in xb], dtype=np.bool_)
    observed = (kind == OBSERVATION) & np.isin(table[:, XA], pose_xs)
    keep = [rows[(moves & np.isin(xb, pose_xs)) | to_sensor | observed]]
    sensor_xs = np.unique(xb[to_sensor])
    if len(sensor_xs):
        seen_from = grown.factors_of(sensor_xs)
        sensor_table = grown.factors[seen_from]
        own = (sensor_table[:, KIND] == OBSERVATION) & np.isin(sensor_table[:, XA], sensor_xs)
        keep.append(seen_from[own])
    factors = np.unique(np.concatenate(keep))
    chosen = grown.factors[factors]
    places = np.concatenate([pose_xs, sensor_xs])
    landmarks = np.unique(chosen[chosen[:, KIND] == OBSERVATION, XB])
    targets = np.concatenate([places, landmarks, places + 1, landmarks + 1, places + 2])
    return factors, targets


def tighten_window(
    grown: GrowingGraph,
    pose_xs: np.ndarray,
    all_pose_xs: Collection[int],
    deadline: Budget | None = None,
) -> tuple[np.ndarray, bool]:
    """Narrow the window of poses at x variables ``pose_xs`` (see :func:`window_rows`) to
    the hull of the linear relaxation of its factors, in place, within ``deadline``;
    returns the variables that shrank, and False when that proves the boxes empty."""
    factors, targets = window_rows(grown, pose_xs, all_pose_xs)
    if len(factors) == 0:
        return targets[:0], True
    n = grown.n_variables
    lo, hi = grown.lo[:n], grown.hi[:n]
    before_lo, before_hi = lo[targets].copy(), hi[targets].copy()
    result = tighten(grown.factors[factors], lo, hi, targets, deadline=deadline)
    if result.is_empty:
        return targets[:0], False
    shrank = (lo[targets] != before_lo) | (hi[targets] != before_hi)
    return targets[shrank], True
