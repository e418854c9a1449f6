"""The kinematic graph: poses and landmarks as interval variables, measurements as factors.

Vocabulary follows GTSAM: you ``add`` priors, odometry (between) factors and
range-bearing factors to a graph; the graph encodes them as arrays for the compiled
narrowing operators (:mod:`cuikslam.narrowing`).

Variables live in one flat index space: 3 per pose (x, y, theta), 2 per landmark (x, y),
and 2 per factor (its measured angle and length, narrowed like everything else).
Initial domains: priors where given, the measured intervals for measurements, and
(-inf, inf) elsewhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cuikslam.graph.encoding import N_SLOTS, link_factor
from cuikslam.graph.variables import (
    ANY_ANGLE,
    ANY_LENGTH,
    Variables,
    observation_row,
    offset_key,
)
from cuikslam.log.records import (
    Bounds,
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    PosePrior,
    Record,
    RelativePose,
)

__all__ = ["ANY_ANGLE", "ANY_LENGTH", "KinematicGraph"]

_NO_LANDMARK = "observation has no landmark id; solve it with unknown correspondence"


@dataclass
class KinematicGraph:
    """Poses, landmarks and the factors between them, encoded as arrays.

    Build one with :meth:`from_log` or with the ``add_*`` methods. ``domains()`` gives the
    initial boxes; :func:`cuikslam.narrowing.propagate` narrows them. Variables are laid
    out by :class:`~cuikslam.graph.variables.Variables`.
    """

    pose_ids: list[int] = field(default_factory=list)
    landmark_ids: list[str] = field(default_factory=list)
    landmark_classes: list[str] = field(default_factory=list)
    _pose_var: dict[int, int] = field(default_factory=dict)
    _landmark_var: dict[str, int] = field(default_factory=dict)
    _vars: Variables = field(default_factory=Variables)
    _factors: list[tuple[int, ...]] = field(default_factory=list)
    _sensor_var: dict[tuple[int, tuple[Bounds, ...]], int] = field(default_factory=dict)
    factor_lines: list[int] = field(default_factory=list)
    """Log line of each factor (0 when built by hand), for messages."""
    regions: dict[str, tuple[Bounds, Bounds]] = field(default_factory=dict)
    """Class -> the box every landmark of the class lies in (a ``class`` record's ``x``,
    ``y``): applied to the class's landmarks, those declared before and after."""

    # ----------------------------------------------------------------- building
    def add_pose(self, pose: int) -> int:
        """Declare pose ``pose`` (no-op if known); returns the index of its x variable."""
        if pose not in self._pose_var:
            self._pose_var[pose] = self._vars.pose()
            self.pose_ids.append(pose)
        return self._pose_var[pose]

    def add_landmark(self, landmark: str, landmark_class: str = "") -> int:
        """Declare a landmark (no-op if known); returns the index of its x variable."""
        if landmark not in self._landmark_var:
            self._landmark_var[landmark] = self._vars.landmark()
            self.landmark_ids.append(landmark)
            self.landmark_classes.append(landmark_class)
            if landmark_class in self.regions:
                self._vars.meet_point(self._landmark_var[landmark], *self.regions[landmark_class])
        return self._landmark_var[landmark]

    def add_region(self, landmark_class: str, x: Bounds, y: Bounds) -> None:
        """Every landmark of ``landmark_class``, declared or to come, lies in ``x`` by ``y``."""
        self.regions[landmark_class] = (x, y)
        for landmark, cls in zip(self.landmark_ids, self.landmark_classes, strict=True):
            if cls == landmark_class:
                self._vars.meet_point(self._landmark_var[landmark], x, y)

    def add_pose_prior(self, pose: int, x: Bounds, y: Bounds, theta: Bounds) -> None:
        """A box known to contain the pose (headings meet modulo 2 pi)."""
        self._vars.meet_pose(self.add_pose(pose), x, y, theta)

    def add_landmark_prior(
        self, landmark: str, x: Bounds, y: Bounds, landmark_class: str = ""
    ) -> None:
        """A box known to contain the landmark."""
        self._vars.meet_point(self.add_landmark(landmark, landmark_class), x, y)

    def add_odometry(
        self, source: int, target: int, turn: Bounds, distance: Bounds, line: int = 0
    ) -> int:
        """Turn by ``turn``, then drive ``distance``, from ``source`` to ``target``."""
        a = self.add_pose(source)
        b = self.add_pose(target)
        self._factors.append(self._vars.odometry(a, b, turn, distance))
        self.factor_lines.append(line)
        return len(self._factors) - 1

    def add_relative_pose(
        self,
        source: int,
        target: int,
        dx: Bounds,
        dy: Bounds,
        dtheta: Bounds,
        line: int = 0,
    ) -> int:
        """Pose ``target`` at (``dx``, ``dy``, ``dtheta``) in the frame of pose ``source``.

        Two factors: ``RELATIVE`` (the translation) and ``ROTATION`` (the heading change);
        returns the index of the first.
        """
        a = self.add_pose(source)
        b = self.add_pose(target)
        self._factors.extend(self._vars.relative_pose(a, b, dx, dy, dtheta))
        self.factor_lines.extend((line, line))
        return len(self._factors) - 2

    def add_observation(
        self,
        pose: int,
        landmark: str,
        range: Bounds | None = None,
        bearing: Bounds | None = None,
        landmark_class: str = "",
        line: int = 0,
        offset: tuple[Bounds, Bounds, Bounds] | None = None,
    ) -> int:
        """``landmark`` seen from ``pose`` at ``range`` and ``bearing`` (either may be None).

        With ``offset``, the sensor's pose ``(dx, dy, dtheta)`` in the frame of the robot
        pose, the sensor's pose S becomes three variables: a relative pose from the robot
        pose to S (``RELATIVE`` and ``ROTATION`` factors), and the ``OBSERVATION`` from S.
        Observations from one pose with the same offset are one scan and share S.
        Returns the index of the ``OBSERVATION`` factor.
        """
        a = self.add_pose(pose)
        b = self.add_landmark(landmark, landmark_class)
        m = self._vars.measurement(bearing, range)
        if offset is not None:
            key = (pose, offset_key(offset))
            if key not in self._sensor_var:  # one scan, one sensor pose
                self._sensor_var[key], rows = self._vars.sensor_pose(a, key[1])
                self._factors.extend(rows)
                self.factor_lines.extend((line, line))
            a = self._sensor_var[key]
        self._factors.append(observation_row(a, b, m))
        self.factor_lines.append(line)
        return len(self._factors) - 1

    def add_record(self, record: Record, landmark: str | None = None) -> None:
        """Add one log record: a prior, a move, an observation, or a ``class`` record's
        region; the other records (``sensor``, ``outliers``, the rest of a ``class`` record)
        add nothing to a graph of one correspondence.

        ``landmark`` names the landmark an observation sees (by default its own id, which
        must then be present).

        Examples
        --------
        >>> from cuikslam.log.records import Observation, PosePrior
        >>> graph = KinematicGraph()
        >>> graph.add_record(PosePrior(0, (0, 0), (0, 0), (0, 0)))
        >>> graph.add_record(Observation(0, "door", (2, 3), (0, 0), landmark="L0"))
        >>> graph.pose_ids, graph.landmark_ids, graph.n_factors
        ([0], ['L0'], 1)
        """
        if isinstance(record, PosePrior):
            self.add_pose_prior(record.pose, record.x, record.y, record.theta)
        elif isinstance(record, Odometry):
            self.add_odometry(
                record.source, record.target, record.turn, record.distance, record.line
            )
        elif isinstance(record, RelativePose):
            self.add_relative_pose(
                record.source, record.target, record.dx, record.dy, record.dtheta, record.line
            )
        elif isinstance(record, LandmarkPrior):
            self.add_landmark_prior(record.landmark, record.x, record.y, record.landmark_class)
        elif isinstance(record, ClassPrior):
            if record.x is not None and record.y is not None:
                self.add_region(record.landmark_class, record.x, record.y)
        elif isinstance(record, Observation):
            landmark = record.landmark if landmark is None else landmark
            if landmark is None:
                raise ValueError(f"line {record.line}: {_NO_LANDMARK}")
            self.add_observation(
                record.pose,
                landmark,
                record.range,
                record.bearing,
                record.landmark_class,
                record.line,
                record.offset,
            )

    @classmethod
    def from_log(cls, log: Log, assignment: list[str] | None = None) -> KinematicGraph:
        """The graph of a log. ``assignment`` gives a landmark id per observation (log order);
        by default each observation's own ``landmark`` id, which must then be present."""
        graph = cls()
        observations = iter(assignment) if assignment is not None else None
        for record in log.records:
            landmark = None
            if isinstance(record, Observation):
                landmark = record.landmark if observations is None else next(observations)
                if landmark is None:
                    raise ValueError(f"{log.path}:{record.line}: {_NO_LANDMARK}")
            graph.add_record(record, landmark)
        return graph

    # ----------------------------------------------------------------- arrays
    @property
    def n_variables(self) -> int:
        return len(self._vars)

    @property
    def n_factors(self) -> int:
        return len(self._factors)

    def domains(self, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Fresh copies of the initial lower and upper bounds of the variables from index
        ``first`` on (every variable by default)."""
        return self._vars.arrays(first)

    def factor_table(self, first: int = 0) -> np.ndarray:
        """The factors from index ``first`` on (every factor by default) as an int64 array
        of shape (n, 9): kind, then 8 variable indices."""
        if len(self._factors) <= first:
            return np.zeros((0, 1 + N_SLOTS), dtype=np.int64)
        return np.array(self._factors[first:], dtype=np.int64)

    def adjacency(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Factors of each variable as linked lists ``(head, entry_factor, entry_next)``.

        See :mod:`cuikslam.graph.encoding`.
        """
        table = self.factor_table()
        head = np.full(self.n_variables, -1, dtype=np.int64)
        entry_factor = np.empty(N_SLOTS * len(table), dtype=np.int64)
        entry_next = np.empty(N_SLOTS * len(table), dtype=np.int64)
        n = 0
        for f in range(len(table)):
            n = link_factor(table[f], f, head, entry_factor, entry_next, n)
        return head, entry_factor[:n], entry_next[:n]

    def pose_index(self, pose: int) -> int:
        """Index of the x variable of ``pose`` (y and theta follow)."""
        return self._pose_var[pose]

    def landmark_index(self, landmark: str) -> int:
        """Index of the x variable of ``landmark`` (y follows)."""
        return self._landmark_var[landmark]

    def pose_boxes(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Pose boxes as an array of shape (n_poses, 3, 2): [pose, (x, y, theta), (lo, hi)]."""
        idx = np.array([self._pose_var[p] for p in self.pose_ids], dtype=np.int64)
        cols = idx[:, None] + np.arange(3)[None, :]
        return np.stack([lo[cols], hi[cols]], axis=-1)

    def landmark_boxes(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Landmark boxes as an array of shape (n_landmarks, 2, 2): [landmark, (x, y), (lo, hi)]."""
        idx = np.array([self._landmark_var[m] for m in self.landmark_ids], dtype=np.int64)
        if idx.size == 0:
            return np.zeros((0, 2, 2))
        cols = idx[:, None] + np.arange(2)[None, :]
        return np.stack([lo[cols], hi[cols]], axis=-1)
