"""Log records read as Gaussians: what a least-squares back end (GTSAM, g2o) is given.

A bounded-error reading ``[lo, hi]`` becomes a Gaussian centred on its midpoint with a
standard deviation of ``scale`` half-widths (``scale=1``: the half-width itself; 1/3 reads
the interval as a 3-sigma bound; 1/sqrt(3) is the standard deviation of an error uniform
over the interval), and at least ``floor`` (an exact reading would otherwise be an
infinitely stiff factor).

Moves are expressed as GTSAM's ``BetweenFactorPose2`` and g2o's ``EDGE_SE2`` read them: the
mean relative pose of the target in the source frame, and a covariance in the tangent
space at that mean (the error of such a factor is ``Logmap(measured⁻¹ · between)``, whose
translation is in the frame of the measured target). The covariances are first order in
the errors. Nothing here imports GTSAM.

Examples
--------
>>> from cuikslam.log.records import Odometry
>>> move = move_gaussian(Odometry(1, 2, turn=(-0.1, 0.1), distance=(1.9, 2.1)))
>>> move.mean.tolist()  # (dx, dy, dtheta): no turn, 2 m ahead
[2.0, 0.0, 0.0]
>>> np.round(move.covariance, 4).tolist()  # distance along x; turn moves y by 2 m per rad
[[0.01, 0.0, 0.0], [0.0, 0.04, 0.02], [0.0, 0.02, 0.01]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuikslam.interval.midpoints import half_width
from cuikslam.interval.midpoints import midpoint as _midpoint
from cuikslam.log.records import (
    Bounds,
    LandmarkPrior,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)

__all__ = [
    "MIN_SIGMA",
    "Gaussian",
    "Reading",
    "midpoint",
    "move_gaussian",
    "prior_gaussian",
    "reading_gaussian",
    "sigma",
]

MIN_SIGMA = 1e-6
"""Default least standard deviation (metres or radians): that of an exact reading."""


def midpoint(bounds: Bounds) -> float:
    """The centre of ``bounds`` (:func:`cuikslam.interval.midpoints.midpoint`, for one
    interval of a log record).

    Examples
    --------
    >>> midpoint((1.0, 2.0)), midpoint((-1e308, 1e308))
    (1.5, 0.0)
    """
    return float(_midpoint(bounds[0], bounds[1]))


def sigma(bounds: Bounds, scale: float = 1.0, floor: float = MIN_SIGMA) -> float:
    """The standard deviation given to ``bounds``: ``scale`` half-widths, at least ``floor``.

    Examples
    --------
    >>> sigma((0.9, 1.1)), sigma((0.9, 1.1), scale=1 / 2), sigma((3.0, 3.0))
    (0.10000000000000003, 0.05000000000000002, 1e-06)
    """
    return max(scale * float(half_width(bounds[0], bounds[1])), floor)


@dataclass(frozen=True)
class Gaussian:
    """A mean and its covariance (for a move: in the tangent space at the mean)."""

    mean: np.ndarray
    covariance: np.ndarray

    @property
    def information(self) -> np.ndarray:
        """The inverse of the covariance (what g2o files hold)."""
        return np.linalg.inv(self.covariance)


def move_gaussian(
    record: Odometry | RelativePose, scale: float = 1.0, floor: float = MIN_SIGMA
) -> Gaussian:
    """The relative pose of ``record.target`` in the frame of ``record.source``.

    Parameters
    ----------
    record : Odometry or RelativePose
        A turn-then-drive odometry step or a relative pose.
    scale, floor : float
        Standard deviation per half-width, and its least value (see :func:`sigma`).

    Returns
    -------
    Gaussian
        Mean ``(dx, dy, dtheta)`` and a 3x3 covariance in the tangent space at the mean.

    Notes
    -----
    An odometry step turns by ``t`` then drives ``d``: the mean is
    ``(d cos t, d sin t, t)`` at the midpoints. An error ``(δd, δt)`` moves the target,
    in the frame of the mean target, by ``(δd, d δt, δt)`` to first order, so the
    covariance is ``J diag(σd², σt²) Jᵀ`` with ``J = [[1, 0], [0, d], [0, 1]]``. That is
    singular along ``n = (0, 1, -d) / √(1 + d²)``: to first order the model cannot move
    the target that way. To second order it does: the error of a ``BetweenFactorPose2``
    (``Logmap``) along ``n`` is ``δd δt / (2 √(1 + d²))``. So ``n`` gets the standard
    deviation ``σd σt / √(1 + d²)`` (twice that term at one-sigma errors; at least
    ``floor``): a stiff direction that a true move never strains, where ``floor`` alone
    would charge a move of one-sigma errors hundreds of units of error.

    A relative pose is independent errors on ``dx``, ``dy`` (source frame) and ``dtheta``;
    its translation covariance is turned into the frame of the mean target.
    """
    if isinstance(record, Odometry):
        t, d = midpoint(record.turn), midpoint(record.distance)
        mean = np.array([d * math.cos(t), d * math.sin(t), t])
        jac = np.array([[1.0, 0.0], [0.0, d], [0.0, 1.0]])
        sigmas = np.array([sigma(record.distance, scale, floor), sigma(record.turn, scale, floor)])
        sideways = np.array([0.0, 1.0, -d]) / math.hypot(1.0, d)
        side = max(sigmas[0] * sigmas[1] / math.hypot(1.0, d), floor)
        cov = jac @ np.diag(sigmas**2) @ jac.T + side**2 * np.outer(sideways, sideways)
        return Gaussian(mean, cov)
    dtheta = midpoint(record.dtheta)
    mean = np.array([midpoint(record.dx), midpoint(record.dy), dtheta])
    c, s = math.cos(dtheta), math.sin(dtheta)
    to_target = np.array([[c, s], [-s, c]])
    source = np.diag([sigma(record.dx, scale, floor) ** 2, sigma(record.dy, scale, floor) ** 2])
    cov = np.zeros((3, 3))
    turned = to_target @ source @ to_target.T
    cov[:2, :2] = (turned + turned.T) / 2  # symmetric to the last bit
    cov[2, 2] = sigma(record.dtheta, scale, floor) ** 2
    return Gaussian(mean, cov)


def prior_gaussian(
    record: PosePrior | LandmarkPrior, scale: float = 1.0, floor: float = MIN_SIGMA
) -> Gaussian:
    """A pose prior's ``(x, y, theta)`` or a landmark prior's ``(x, y)``, independent errors.

    Examples
    --------
    >>> from cuikslam.log.records import LandmarkPrior
    >>> g = prior_gaussian(LandmarkPrior("L1", "door", x=(9.0, 11.0), y=(0.0, 0.0)))
    >>> g.mean.tolist(), np.sqrt(np.diag(g.covariance)).tolist()
    ([10.0, 0.0], [1.0, 1e-06])
    """
    fields = [record.x, record.y] + ([record.theta] if isinstance(record, PosePrior) else [])
    mean = np.array([midpoint(b) for b in fields])
    return Gaussian(mean, np.diag([sigma(b, scale, floor) ** 2 for b in fields]))


@dataclass(frozen=True)
class Reading:
    """An observation as a back end takes it: what was measured, from the robot's centre.

    ``kind`` is ``"bearing-range"`` (``mean`` is ``(bearing, range)``, ``covariance``
    2x2), ``"bearing"`` or ``"range"`` (``mean`` and ``covariance`` of size 1).
    """

    kind: str
    mean: np.ndarray
    covariance: np.ndarray

    def point(self) -> Gaussian:
        """A bearing-range reading as the landmark's ``(x, y)`` in the robot's frame (first
        order: ``J cov Jᵀ`` with ``J`` the Jacobian of ``r (cos b, sin b)``)."""
        if self.kind != "bearing-range":
            raise ValueError(f"a {self.kind}-only reading does not place the landmark")
        b, r = self.mean
        c, s = math.cos(b), math.sin(b)
        jac = np.array([[-r * s, c], [r * c, s]])
        return Gaussian(np.array([r * c, r * s]), jac @ self.covariance @ jac.T)


def reading_gaussian(record: Observation, scale: float = 1.0, floor: float = MIN_SIGMA) -> Reading:
    """What ``record`` measured, as a Gaussian reading from the robot's centre.

    A sensor offset (a sensor mounted off the robot's centre) is folded in to first order:
    the landmark's position in the sensor frame is moved into the robot frame, with the
    offset's own errors, and read back as a bearing and a range from the robot's centre
    (a full 2x2 covariance). Only bearing-range readings can be moved so.

    Raises
    ------
    ValueError
        For a bearing-only or range-only reading with a sensor offset (it does not place
        the landmark, so the offset cannot be folded in).

    Examples
    --------
    >>> from cuikslam.log.records import Observation
    >>> r = reading_gaussian(Observation(1, "door", range=(4.9, 5.1), bearing=(-0.1, 0.1)))
    >>> r.kind, r.mean.tolist(), np.round(np.sqrt(np.diag(r.covariance)), 6).tolist()
    ('bearing-range', [0.0, 5.0], [0.1, 0.1])
    >>> reading_gaussian(Observation(1, "door", range=None, bearing=(0.1, 0.3))).kind
    'bearing'
    """
    if record.range is None or record.bearing is None:
        if record.offset is not None:
            where = f" (line {record.line})" if record.line else ""
            raise ValueError(
                f"observation{where}: a {'bearing' if record.range is None else 'range'}-only "
                "reading with a sensor offset has no Gaussian from the robot's centre"
            )
        bounds, kind = (
            (record.bearing, "bearing") if record.range is None else (record.range, "range")
        )
        assert bounds is not None
        return Reading(
            kind, np.array([midpoint(bounds)]), np.array([[sigma(bounds, scale, floor) ** 2]])
        )
    measured = np.array([midpoint(record.bearing), midpoint(record.range)])
    cov = np.diag(
        [sigma(record.bearing, scale, floor) ** 2, sigma(record.range, scale, floor) ** 2]
    )
    reading = Reading("bearing-range", measured, cov)
    if record.offset is None:
        return reading
    return _from_centre(reading.point(), record.offset, scale, floor)


def _from_centre(
    seen: Gaussian, offset: tuple[Bounds, Bounds, Bounds], scale: float, floor: float
) -> Reading:
    """The point ``seen`` in the sensor frame, read from the robot's centre (first order)."""
    ox, oy, ot = (midpoint(b) for b in offset)
    c, s = math.cos(ot), math.sin(ot)
    rot = np.array([[c, -s], [s, c]])
    sx, sy = seen.mean
    point = np.array([ox, oy]) + rot @ seen.mean
    d_theta = rot @ np.array([-sy, sx])  # the point's motion per radian of sensor heading
    offset_cov = np.diag([sigma(b, scale, floor) ** 2 for b in offset])
    jac_offset = np.column_stack([np.eye(2), d_theta])
    cov_xy = rot @ seen.covariance @ rot.T + jac_offset @ offset_cov @ jac_offset.T
    x, y = point
    r2 = x * x + y * y
    if not r2 > 0:
        raise ValueError("the landmark is read at the robot's centre: it has no bearing from it")
    r = math.sqrt(r2)
    to_polar = np.array([[-y / r2, x / r2], [x / r, y / r]])
    return Reading(
        "bearing-range",
        np.array([math.atan2(y, x), r]),
        to_polar @ cov_xy @ to_polar.T,
    )
