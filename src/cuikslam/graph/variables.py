"""From log records to interval variables and factor rows: the one path every graph takes.

:class:`~cuikslam.graph.kinematic_graph.KinematicGraph` (one correspondence) and the
search's problem (:mod:`cuikslam.hypotheses.problem`, every correspondence) lay out their
variables with a :class:`Variables` table: a pose is 3 variables (x, y, theta), a
landmark 2, a measurement 1 per measured quantity, and a sensor mounted at an offset is a
pose of its own tied to the robot's by a relative pose. The domain of a measured length
(:func:`length_bounds`) and of a bearing (:func:`bearing_bounds`) are set here only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cuikslam.graph.encoding import OBSERVATION, ODOMETRY, RELATIVE, ROTATION
from cuikslam.interval._periodic import periodic_meet
from cuikslam.interval._rounding import PI_HI
from cuikslam.log.records import Bounds

__all__ = [
    "ANY",
    "ANY_ANGLE",
    "ANY_LENGTH",
    "Bounds",
    "Row",
    "Variables",
    "bearing_bounds",
    "length_bounds",
    "observation_row",
    "offset_key",
]

Row = tuple[int, ...]
"""A factor row: kind, then 8 variable indices (see :mod:`cuikslam.graph.encoding`)."""

ANY: Bounds = (-math.inf, math.inf)
"""The domain of a variable nothing constrains yet."""
ANY_ANGLE: Bounds = (-PI_HI, PI_HI)
"""The domain of an unmeasured bearing: every angle."""
ANY_LENGTH: Bounds = (0.0, math.inf)
"""The domain of an unmeasured range."""


def length_bounds(bounds: Bounds | None) -> Bounds:
    """The domain of a measured range or distance: never below 0 (a -0.0 or negative lower
    bound becomes 0.0); ``ANY_LENGTH`` when unmeasured.

    Examples
    --------
    >>> length_bounds((-0.5, 2.0)), length_bounds(None)
    ((0.0, 2.0), (0.0, inf))
    """
    if bounds is None:
        return ANY_LENGTH
    return (max(0.0, float(bounds[0])), float(bounds[1]))


def bearing_bounds(bounds: Bounds | None) -> Bounds:
    """The domain of a measured bearing; ``ANY_ANGLE`` when unmeasured."""
    return ANY_ANGLE if bounds is None else bounds


def observation_row(sensor_x: int, landmark_x: int, measurement: int) -> Row:
    """The row of an observation from the pose at ``sensor_x`` of the landmark at
    ``landmark_x``, bearing and range at ``measurement`` and ``measurement + 1``."""
    a, b, m = sensor_x, landmark_x, measurement
    return (OBSERVATION, a, a + 1, a + 2, b, b + 1, -1, m, m + 1)


@dataclass
class Variables:
    """Initial domains of variables, in one flat index space, as they are created."""

    lo: list[float] = field(default_factory=list)
    hi: list[float] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.lo)

    def new(self, *bounds: Bounds) -> int:
        """New variables with these domains; returns the index of the first."""
        first = len(self.lo)
        for lo, hi in bounds:
            self.lo.append(float(lo))
            self.hi.append(float(hi))
        return first

    def meet(self, var: int, bounds: Bounds) -> None:
        """Intersect the domain of ``var`` with ``bounds``."""
        self.lo[var] = max(self.lo[var], float(bounds[0]))
        self.hi[var] = min(self.hi[var], float(bounds[1]))

    def meet_angle(self, var: int, bounds: Bounds) -> None:
        """Headings meet modulo 2 pi: [0.1, 0.2] and [6.38, 6.48] are the same prior."""
        lo, hi = periodic_meet(self.lo[var], self.hi[var], float(bounds[0]), float(bounds[1]))
        self.lo[var], self.hi[var] = lo, hi

    def arrays(self, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Fresh float64 copies of the lower and upper bounds (from variable ``first`` on)."""
        return (
            np.array(self.lo[first:], dtype=np.float64),
            np.array(self.hi[first:], dtype=np.float64),
        )

    def pose(self) -> int:
        """A new pose (x, y, theta unconstrained); returns its x variable."""
        return self.new(ANY, ANY, ANY)

    def landmark(self) -> int:
        """A new landmark (x, y unconstrained); returns its x variable."""
        return self.new(ANY, ANY)

    def meet_pose(self, pose_x: int, x: Bounds, y: Bounds, theta: Bounds) -> None:
        """A box known to contain the pose at ``pose_x`` (the heading modulo 2 pi)."""
        self.meet(pose_x, x)
        self.meet(pose_x + 1, y)
        self.meet_angle(pose_x + 2, theta)

    def meet_point(self, x_var: int, x: Bounds, y: Bounds) -> None:
        """A box known to contain the point (a landmark) at ``x_var``."""
        self.meet(x_var, x)
        self.meet(x_var + 1, y)

    def odometry(self, a: int, b: int, turn: Bounds, distance: Bounds) -> Row:
        """Turn by ``turn``, then drive ``distance``, from the pose at ``a`` to the pose at
        ``b``: its measurement variables and its row."""
        m = self.new(turn, length_bounds(distance))
        return (ODOMETRY, a, a + 1, a + 2, b, b + 1, b + 2, m, m + 1)

    def relative_pose(self, a: int, b: int, dx: Bounds, dy: Bounds, dtheta: Bounds) -> list[Row]:
        """The pose at ``b`` at (dx, dy, dtheta) in the frame of the pose at ``a``: its
        measurement variables and its ``RELATIVE`` and ``ROTATION`` rows."""
        m = self.new(dx, dy, dtheta)
        return [
            (RELATIVE, a, a + 1, a + 2, b, b + 1, -1, m, m + 1),
            (ROTATION, a, a + 1, a + 2, b, b + 1, b + 2, m + 2, -1),
        ]

    def sensor_pose(self, a: int, offset: tuple[Bounds, ...]) -> tuple[int, list[Row]]:
        """A sensor mounted at ``offset`` (dx, dy, dtheta) on the pose at ``a``: its pose's x
        variable and the rows of the relative pose that ties it to the robot's."""
        o = self.new(*offset, ANY, ANY, ANY)
        s = o + 3
        return s, [
            (RELATIVE, a, a + 1, a + 2, s, s + 1, -1, o, o + 1),
            (ROTATION, a, a + 1, a + 2, s, s + 1, s + 2, o + 2, -1),
        ]

    def measurement(self, bearing: Bounds | None, range: Bounds | None) -> int:
        """The bearing and range variables of an observation; returns the bearing's."""
        return self.new(bearing_bounds(bearing), length_bounds(range))


def offset_key(offset: tuple[Bounds, ...]) -> tuple[Bounds, ...]:
    """An offset as a hashable key: observations from one pose with the same offset are
    one scan and share one sensor pose."""
    return tuple((float(lo), float(hi)) for lo, hi in offset)
