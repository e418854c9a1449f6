"""The records of a cuikslam log: what the robot measured, in time order.

One dataclass per record type of the JSON Lines log format (``docs/log-format.md``).
Every measured quantity is a closed interval ``(lo, hi)`` that contains the true value.
Angles are in radians; headings counter-clockwise from +x, bearings counter-clockwise
from the robot's heading. Every record may carry ``time``, the log's optional time stamp
in seconds (None when absent): solving ignores it, ``cuikslam follow --rate`` replays the
records at these times, and it takes no part in comparing records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "RESERVED_LANDMARK_ID",
    "Bounds",
    "ClassPrior",
    "LandmarkPrior",
    "Log",
    "Observation",
    "Odometry",
    "OutlierBound",
    "PosePrior",
    "Record",
    "RelativePose",
    "SensorModel",
]

Bounds = tuple[float, float]
"""A closed interval ``(lo, hi)`` with ``lo <= hi``."""

RESERVED_LANDMARK_ID = "outlier"
"""No landmark may have this id: in a hypothesis' assignment it marks an observation taken
as an outlier (one that explains nothing), and the witness search, the fit and the labelled
logs leave such observations out."""


@dataclass(frozen=True)
class PosePrior:
    """A box known to contain pose ``pose`` (x, y, theta)."""

    pose: int
    x: Bounds
    y: Bounds
    theta: Bounds
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Odometry:
    """Turn in place by ``turn``, then drive straight ``distance``: pose ``source`` to ``target``.

    theta_target = theta_source + turn;
    (x, y)_target = (x, y)_source + distance * (cos theta_target, sin theta_target).
    """

    source: int
    target: int
    turn: Bounds
    distance: Bounds
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class RelativePose:
    """The pose ``target`` in the frame of pose ``source``: a move that turns while it drives.

    (x, y)_target = (x, y)_source + R(theta_source) (dx, dy) and
    theta_target = theta_source + dtheta, where R(t) rotates by t: ``dx`` is the
    displacement along the source heading, ``dy`` to its left.
    """

    source: int
    target: int
    dx: Bounds
    dy: Bounds
    dtheta: Bounds
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Observation:
    """A landmark of kind ``landmark_class`` seen from pose ``pose``.

    ``range`` or ``bearing`` may be ``None`` (bearing-only / range-only sensors).
    ``landmark`` names the landmark when the correspondence is known, else ``None``.
    Observations made from the same pose form one scan: they see distinct landmarks.
    ``offset``, when given, is the sensor's pose ``(dx, dy, dtheta)`` in the frame of the
    robot pose (a laser mounted ahead of the centre, or the robot's motion since the
    keyframe); range and bearing are then measured from that sensor pose.
    """

    pose: int
    landmark_class: str
    range: Bounds | None
    bearing: Bounds | None
    landmark: str | None = None
    line: int = 0
    offset: tuple[Bounds, Bounds, Bounds] | None = None
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class LandmarkPrior:
    """A box known to contain landmark ``landmark`` (a partially known map)."""

    landmark: str
    landmark_class: str
    x: Bounds
    y: Bounds
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class ClassPrior:
    """What the user knows of all the landmarks of class ``landmark_class`` (a map's rules).

    At most ``at_most`` distinct landmarks of the class exist; any two distinct ones are at
    least ``min_separation`` apart; every one lies inside the box ``x`` by ``y`` (a room's
    walls). Each is optional (None). They hold whatever the correspondence, so the search
    refutes a hypothesis that breaks one: a prior a user really has makes wrong "new
    landmark" explanations impossible.
    """

    landmark_class: str
    at_most: int | None = None
    min_separation: float | None = None
    x: Bounds | None = None
    y: Bounds | None = None
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class SensorModel:
    """What the robot's sensor is sure to see: the source of negative information.

    The robot observes every landmark within ``max_range`` and inside the field of view
    ``fov`` (centred on its heading) and, when ``nearest_margin`` is set, only those within
    ``nearest_margin`` of the nearest landmark's distance. A hypothesis that puts a
    landmark where the robot was sure to see it, at a pose that did not observe it, is
    impossible. Without a sensor record no such conclusion is drawn.
    """

    max_range: float = math.inf
    fov: float = 2 * math.pi
    nearest_margin: float | None = None
    line: int = 0
    time: float | None = field(default=None, compare=False)


@dataclass(frozen=True)
class OutlierBound:
    """At most ``at_most`` observations are outliers: their interval misses the truth.

    Without ``window`` the bound holds for the whole log. With ``window`` = W, the poses
    are taken in the order the log first mentions them and cut into consecutive blocks of
    W poses (the first W, the next W, ...); the observations made from the poses of each
    block hold at most ``at_most`` outliers. Every other record must still hold its truth.
    """

    at_most: int
    window: int | None = None
    line: int = 0
    time: float | None = field(default=None, compare=False)


Record = (
    PosePrior
    | Odometry
    | RelativePose
    | Observation
    | LandmarkPrior
    | ClassPrior
    | SensorModel
    | OutlierBound
)


@dataclass
class Log:
    """A whole log: its records in file order, plus where it came from (for messages)."""

    records: list[Record] = field(default_factory=list)
    path: str = "<memory>"

    @property
    def priors(self) -> list[PosePrior]:
        return [r for r in self.records if isinstance(r, PosePrior)]

    @property
    def odometry(self) -> list[Odometry]:
        return [r for r in self.records if isinstance(r, Odometry)]

    @property
    def relative_poses(self) -> list[RelativePose]:
        return [r for r in self.records if isinstance(r, RelativePose)]

    @property
    def observations(self) -> list[Observation]:
        return [r for r in self.records if isinstance(r, Observation)]

    @property
    def landmark_priors(self) -> list[LandmarkPrior]:
        return [r for r in self.records if isinstance(r, LandmarkPrior)]

    @property
    def class_priors(self) -> dict[str, ClassPrior]:
        """The class priors, by class (the reader allows one per class)."""
        return {r.landmark_class: r for r in self.records if isinstance(r, ClassPrior)}

    @property
    def sensor(self) -> SensorModel | None:
        """The sensor model, if the log declares one."""
        found = [r for r in self.records if isinstance(r, SensorModel)]
        return found[0] if found else None

    @property
    def outlier_bounds(self) -> list[OutlierBound]:
        """The outlier declarations (at most one for the whole log, one per window)."""
        return [r for r in self.records if isinstance(r, OutlierBound)]

    @property
    def pose_ids(self) -> list[int]:
        """Every pose the log mentions, sorted."""
        return sorted(self.pose_order())

    def pose_order(self) -> dict[int, int]:
        """Each pose the log mentions and its rank in the order the log first mentions it
        (the blocks of poses of an ``outliers`` window follow it)."""
        order: dict[int, int] = {}
        for r in self.records:
            if isinstance(r, PosePrior | Observation):
                order.setdefault(r.pose, len(order))
            elif isinstance(r, Odometry | RelativePose):
                order.setdefault(r.source, len(order))
                order.setdefault(r.target, len(order))
        return order

    @property
    def has_unknown_correspondence(self) -> bool:
        """True when some observation does not name its landmark."""
        return any(o.landmark is None for o in self.observations)
