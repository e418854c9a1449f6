"""A log and a hypothesis as a GTSAM factor graph, to refine or compare with least squares.

:func:`factor_graph` turns every record a least-squares back end can take into a GTSAM
factor, each interval read as a Gaussian (:mod:`cuikslam.interop.gaussian`: centred on its
midpoint, the half-width as standard deviation by default):

========================  ====================================================
log record                GTSAM factor
========================  ====================================================
``prior``                 ``PriorFactorPose2``, diagonal noise
``landmark``              ``PriorFactorPoint2``, diagonal noise
``odometry``              ``BetweenFactorPose2``, a derived 3x3 covariance
``relative_pose``         ``BetweenFactorPose2``, a derived 3x3 covariance
``observation``           ``BearingRangeFactor2D`` (``BearingFactor2D`` or
                          ``RangeFactor2D`` for bearing-only or range-only)
========================  ====================================================

Odometry turns then drives; GTSAM has no such factor, so each step is a
``BetweenFactorPose2`` whose covariance is the first-order image of the turn and distance
errors, stiff sideways (where the model allows no motion to first order) only down to the
size of the second-order terms a ``BetweenFactorPose2`` cannot follow
(:func:`cuikslam.interop.gaussian.move_gaussian`). An observation from a
sensor mounted off the robot's centre is read from the centre, to first order
(:func:`cuikslam.interop.gaussian.reading_gaussian`). What GTSAM has no counterpart for is
left out: the sensor model's negative information, class priors, outlier declarations
(an observation the hypothesis takes as an outlier gets no factor).

Keys: pose ``p`` is ``X(p)`` = ``gtsam.symbol('x', p)``, the hypothesis' ``j``-th landmark
``L(j)`` = ``gtsam.symbol('l', j)`` (:func:`~cuikslam.interop.estimate.pose_key`,
:func:`~cuikslam.interop.estimate.landmark_key`); :func:`cuikslam.check_estimate` reads a
``gtsam.Values`` the same way. Needs ``pip install "cuikslam[interop]"``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cuikslam.interop.estimate import (
    Source,
    hypothesis_estimate,
    landmark_key,
    pose_key,
)
from cuikslam.interop.gaussian import (
    MIN_SIGMA,
    move_gaussian,
    prior_gaussian,
    reading_gaussian,
)
from cuikslam.log.records import (
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)
from cuikslam.outcome.solution import OUTLIER, Hypothesis

try:
    import gtsam
except ImportError as _missing:  # pragma: no cover - exercised without the extra
    raise ImportError(
        'cuikslam.interop.gtsam needs GTSAM: pip install "cuikslam[interop]" (or pip install gtsam)'
    ) from _missing

__all__ = [
    "factor_graph",
    "landmark_prior_factor",
    "move_factor",
    "observation_factor",
    "pose_prior_factor",
]


def pose_prior_factor(
    record: PosePrior, scale: float = 1.0, floor: float = MIN_SIGMA
) -> gtsam.PriorFactorPose2:
    """A pose prior as a ``PriorFactorPose2`` on ``X(record.pose)``.

    An exact prior gets ``floor`` standard deviations, not a hard constraint
    (``NonlinearEqualityPose2`` makes iSAM2 and ``gtsam.Marginals`` fail on some graphs
    with an indeterminate system): the optimum may leave it by about ``floor``² times the
    other factors' pull, which :func:`cuikslam.check_estimate` reports unless given a
    tolerance.
    """
    g = prior_gaussian(record, scale, floor)
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.sqrt(np.diag(g.covariance)))
    return gtsam.PriorFactorPose2(pose_key(record.pose), gtsam.Pose2(*g.mean), noise)


def landmark_prior_factor(
    record: LandmarkPrior, key: int, scale: float = 1.0, floor: float = MIN_SIGMA
) -> gtsam.PriorFactorPoint2:
    """A landmark prior as a ``PriorFactorPoint2`` on the landmark's ``key`` (an exact one
    with ``floor`` standard deviations, as :func:`pose_prior_factor`)."""
    g = prior_gaussian(record, scale, floor)
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.sqrt(np.diag(g.covariance)))
    return gtsam.PriorFactorPoint2(key, gtsam.Point2(*g.mean), noise)


def move_factor(
    record: Odometry | RelativePose, scale: float = 1.0, floor: float = MIN_SIGMA
) -> gtsam.BetweenFactorPose2:
    """An odometry step or relative pose as a ``BetweenFactorPose2`` from ``X(source)`` to
    ``X(target)`` (first order; see :func:`cuikslam.interop.gaussian.move_gaussian`)."""
    g = move_gaussian(record, scale, floor)
    noise = gtsam.noiseModel.Gaussian.Covariance(g.covariance)
    return gtsam.BetweenFactorPose2(
        pose_key(record.source), pose_key(record.target), gtsam.Pose2(*g.mean), noise
    )


def observation_factor(
    record: Observation, key: int, scale: float = 1.0, floor: float = MIN_SIGMA
) -> gtsam.NonlinearFactor:
    """An observation of the landmark at ``key`` from ``X(record.pose)``: a
    ``BearingRangeFactor2D``, or a ``BearingFactor2D`` / ``RangeFactor2D`` for a
    bearing-only / range-only reading."""
    reading = reading_gaussian(record, scale, floor)
    noise = gtsam.noiseModel.Gaussian.Covariance(reading.covariance)
    pose = pose_key(record.pose)
    if reading.kind == "bearing":
        return gtsam.BearingFactor2D(pose, key, gtsam.Rot2.fromAngle(reading.mean[0]), noise)
    if reading.kind == "range":
        return gtsam.RangeFactor2D(pose, key, float(reading.mean[0]), noise)
    bearing, distance = reading.mean
    return gtsam.BearingRangeFactor2D(
        pose, key, gtsam.Rot2.fromAngle(bearing), float(distance), noise
    )


def _check_fits(log: Log, hypothesis: Hypothesis) -> None:
    """Refuse a hypothesis that is not one of ``log``'s (``ValueError``, saying why)."""
    observations = len(log.observations)
    if len(hypothesis.assignment) != observations:
        raise ValueError(
            f"the hypothesis assigns {len(hypothesis.assignment)} observations, the log "
            f"{log.path} has {observations}: it is not a hypothesis of this log"
        )
    missing = sorted(set(log.pose_ids) - set(hypothesis.pose_ids))
    if missing:
        raise ValueError(f"the hypothesis has no box for pose(s) {missing[:5]} of {log.path}")
    named = {o.landmark for o in log.observations if o.landmark is not None}
    named |= {r.landmark for r in log.landmark_priors}
    unknown = sorted(named - set(hypothesis.landmark_ids))
    if unknown:
        raise ValueError(f"the hypothesis has no landmark {unknown[:5]} that {log.path} names")


def factor_graph(
    log: Log,
    hypothesis: Hypothesis,
    *,
    initial: Source = "auto",
    scale: float = 1.0,
    floor: float = MIN_SIGMA,
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The factor graph of ``log`` under ``hypothesis``'s correspondence, and initial values.

    Parameters
    ----------
    log : Log
        The log that was solved.
    hypothesis : Hypothesis
        One of its hypotheses (e.g. ``solution.best``): which landmark each observation
        sees (its ``assignment``) and the initial values.
    initial : {"auto", "witness", "centres"}
        Initial values: the hypothesis' witness, its box centres, or (``auto``) the witness
        when it has one (see :func:`~cuikslam.interop.estimate.hypothesis_estimate`).
    scale, floor : float
        Standard deviation per interval half-width (1: the half-width), and its least
        value (for exact readings; see :mod:`cuikslam.interop.gaussian`).

    Returns
    -------
    graph : gtsam.NonlinearFactorGraph
        One factor per prior, move and observation (in log order), as in the module's table.
    values : gtsam.Values
        ``Pose2`` at ``X(p)`` for every pose, ``Point2`` at ``L(j)`` for every landmark a
        factor holds.

    Raises
    ------
    ValueError
        When the hypothesis is not one of the log's, or for a bearing-only or range-only
        reading with a sensor offset (no first-order reading from the centre).
    """
    _check_fits(log, hypothesis)
    point = hypothesis_estimate(hypothesis, initial)
    keys = {m: landmark_key(j) for j, m in enumerate(hypothesis.landmark_ids)}
    graph = gtsam.NonlinearFactorGraph()
    observed = iter(hypothesis.assignment)
    for record in log.records:
        factor: Any = None
        if isinstance(record, PosePrior):
            factor = pose_prior_factor(record, scale, floor)
        elif isinstance(record, Odometry | RelativePose):
            factor = move_factor(record, scale, floor)
        elif isinstance(record, LandmarkPrior):
            factor = landmark_prior_factor(record, keys[record.landmark], scale, floor)
        elif isinstance(record, Observation):
            landmark = next(observed)
            if landmark != OUTLIER:
                factor = observation_factor(record, keys[landmark], scale, floor)
        if factor is not None:
            graph.add(factor)
    values = gtsam.Values()
    used = set(graph.keyVector())  # a landmark only outliers saw has no factor, no value
    for pose_id, xyt in zip(point.pose_ids, point.poses_xyt, strict=True):
        values.insert(pose_key(pose_id), gtsam.Pose2(*map(float, xyt)))
    for landmark_id, xy in zip(point.landmark_ids, point.landmarks_xy, strict=True):
        if keys[landmark_id] in used:
            values.insert(keys[landmark_id], gtsam.Point2(*map(float, xy)))
    return graph, values
