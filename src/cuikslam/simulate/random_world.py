"""Random worlds: landmarks of a few classes in a rectangle, a wandering robot, a bounded sensor.

Landmark classes are assigned round-robin so that every class has several members,
which makes the correspondence ambiguous when observations carry their class only.
With ``loop=True`` the robot heads back to its start in the second half of the run,
so that it re-observes the first landmarks (a loop closure).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from cuikslam.log.records import Log, Observation, Odometry, PosePrior, Record, SensorModel
from cuikslam.simulate.truth import GroundTruth, noisy_interval, wrap_angle

__all__ = ["WANDER_TURN", "WorldSpec", "simulate_random_world", "simulate_world"]

WANDER_TURN = math.pi / 4
"""Largest turn, either way, of the robot when it wanders freely."""
_HOMING_JITTER = 0.2
"""Largest deviation (rad) from the straight heading home."""


@dataclass(frozen=True)
class WorldSpec:
    """Parameters of a random world; see :func:`simulate_random_world`."""

    n_poses: int = 50
    n_landmarks: int = 10
    classes: tuple[str, ...] = ("door", "corridor", "post")
    size: tuple[float, float] = (40.0, 30.0)
    max_range: float = 8.0
    fov: float = 2 * math.pi
    odometry_bounds: tuple[float, float] = (0.05, 0.1)
    """Half-widths ``(turn [rad], distance [m])`` of the odometry errors."""
    observation_bounds: tuple[float, float] = (0.05, 0.02)
    """Half-widths ``(range [m], bearing [rad])`` of the observation errors."""
    step_length: tuple[float, float] = (0.5, 2.0)
    unknown: bool = False
    loop: bool = True
    range_only_fraction: float = 0.0
    bearing_only_fraction: float = 0.0

    def __post_init__(self) -> None:
        problems = [
            (self.n_poses < 1, "n_poses must be at least 1"),
            (self.n_landmarks < 1, "n_landmarks must be at least 1"),
            (not self.classes, "classes must not be empty"),
            (min(self.size) <= 0, "size must be positive"),
            (self.max_range <= 0, "max_range must be positive"),
            (not 0 < self.fov <= 2 * math.pi, "fov must be in (0, 2π]"),
            (min(*self.odometry_bounds, *self.observation_bounds) < 0, "bounds must be >= 0"),
            (not 0 < self.step_length[0] <= self.step_length[1], "need 0 < step min <= max"),
            (
                not (0 <= self.range_only_fraction and 0 <= self.bearing_only_fraction)
                or self.range_only_fraction + self.bearing_only_fraction > 1,
                "range/bearing-only fractions must be >= 0 and sum to at most 1",
            ),
        ]
        for failed, problem in problems:
            if failed:
                raise ValueError(f"WorldSpec: {problem}")

    @property
    def wall_margin(self) -> float:
        """The robot steers back toward the centre rather than come this close to a wall."""
        return min(self.step_length[1], 0.25 * min(self.size))


def simulate_random_world(
    seed: int = 0,
    n_poses: int = 50,
    n_landmarks: int = 10,
    classes: tuple[str, ...] = ("door", "corridor", "post"),
    size: tuple[float, float] = (40.0, 30.0),
    max_range: float = 8.0,
    fov: float = 2 * math.pi,
    odometry_bounds: tuple[float, float] = (0.05, 0.1),
    observation_bounds: tuple[float, float] = (0.05, 0.02),
    step_length: tuple[float, float] = (0.5, 2.0),
    unknown: bool = False,
    loop: bool = True,
    range_only_fraction: float = 0.0,
    bearing_only_fraction: float = 0.0,
) -> tuple[Log, GroundTruth]:
    """Simulate a random world and the log of a robot driving through it.

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``; everything random derives from it.
    n_poses, n_landmarks : int
        Pose ids are ``0..n_poses-1``, landmark ids ``"L0".."L{n_landmarks-1}"``.
    classes : tuple of str
        Landmark classes, assigned round-robin.
    size : (float, float)
        The world is the rectangle ``[0, size[0]] x [0, size[1]]`` (metres).
    max_range, fov : float
        The sensor sees every landmark within ``max_range`` and within ``fov / 2`` of the
        heading, either side (``fov = 2π`` sees all around).
    odometry_bounds : (float, float)
        Error half-widths of ``(turn, distance)``.
    observation_bounds : (float, float)
        Error half-widths of ``(range, bearing)``.
    step_length : (float, float)
        Shortest and longest drive between two poses (the robot may drive less to avoid
        a wall).
    unknown : bool
        Observations carry their class only, not the landmark id.
    loop : bool
        Head back to the start in the second half of the run.
    range_only_fraction, bearing_only_fraction : float
        Fractions of the observations that drop their bearing, respectively their range.

    Returns
    -------
    (Log, GroundTruth)
        The log (pose 0 has an exact prior at its true pose; at least one observation)
        and the truth behind it.
    """
    spec = WorldSpec(
        n_poses=n_poses,
        n_landmarks=n_landmarks,
        classes=tuple(classes),
        size=size,
        max_range=max_range,
        fov=fov,
        odometry_bounds=odometry_bounds,
        observation_bounds=observation_bounds,
        step_length=step_length,
        unknown=unknown,
        loop=loop,
        range_only_fraction=range_only_fraction,
        bearing_only_fraction=bearing_only_fraction,
    )
    return simulate_world(spec, seed)


def simulate_world(spec: WorldSpec, seed: int = 0) -> tuple[Log, GroundTruth]:
    """:func:`simulate_random_world` with its parameters given as a :class:`WorldSpec`."""
    rng = np.random.default_rng(seed)
    size_xy = np.asarray(spec.size, dtype=float)
    landmarks_xy = rng.uniform((0.0, 0.0), size_xy, size=(spec.n_landmarks, 2))
    poses_xyt, turns, distances = _drive(spec, rng)
    sightings = _sightings(spec, poses_xyt, landmarks_xy)
    if not any(sightings):
        landmarks_xy[0] = _point_in_view(spec, poses_xyt[0], rng)
        sightings = _sightings(spec, poses_xyt, landmarks_xy)

    landmark_ids = [f"L{j}" for j in range(spec.n_landmarks)]
    landmark_classes = [spec.classes[j % len(spec.classes)] for j in range(spec.n_landmarks)]
    turn_bound, distance_bound = spec.odometry_bounds
    range_bound, bearing_bound = spec.observation_bounds
    x0, y0, t0 = (float(v) for v in poses_xyt[0])
    records: list[Record] = [
        SensorModel(max_range=spec.max_range, fov=min(spec.fov, 2 * math.pi)),
        PosePrior(0, (x0, x0), (y0, y0), (t0, t0)),
    ]
    assignment: list[str] = []
    for i in range(spec.n_poses):
        for j, true_range, true_bearing in sightings[i]:
            assignment.append(landmark_ids[j])
            records.append(
                Observation(
                    pose=i,
                    landmark_class=landmark_classes[j],
                    range=noisy_interval(true_range, range_bound, rng, non_negative=True),
                    bearing=noisy_interval(true_bearing, bearing_bound, rng),
                    landmark=None if spec.unknown else landmark_ids[j],
                )
            )
        if i + 1 < spec.n_poses:
            records.append(
                Odometry(
                    source=i,
                    target=i + 1,
                    turn=noisy_interval(turns[i], turn_bound, rng),
                    distance=noisy_interval(distances[i], distance_bound, rng, non_negative=True),
                )
            )
    records = _drop_range_or_bearing(spec, records, rng)
    truth = GroundTruth(
        poses_xyt=poses_xyt,
        pose_ids=list(range(spec.n_poses)),
        landmarks_xy=landmarks_xy,
        landmark_ids=landmark_ids,
        landmark_classes=landmark_classes,
        assignment=assignment,
    )
    return Log(records=records, path=f"<random world seed={seed}>"), truth


def _drive(
    spec: WorldSpec, rng: np.random.Generator
) -> tuple[np.ndarray, list[float], list[float]]:
    """A random turn-then-drive path inside the rectangle, away from the walls.

    Returns the (n, 3) true poses and the true turn and distance of each step.
    """
    margin = spec.wall_margin
    low_xy = np.full(2, margin)
    high_xy = np.asarray(spec.size, dtype=float) - margin
    centre_xy = (low_xy + high_xy) / 2
    # Any point within this distance of the centre is away from the walls.
    centre_reach = float(np.min(centre_xy - low_xy))
    step_min, step_max = spec.step_length

    poses_xyt = np.empty((spec.n_poses, 3))
    poses_xyt[0] = (*rng.uniform(low_xy, high_xy), rng.uniform(-np.pi, np.pi))
    start_xy = poses_xyt[0, :2]
    turns: list[float] = []
    distances: list[float] = []
    for i in range(1, spec.n_poses):
        xy, theta = poses_xyt[i - 1, :2], poses_xyt[i - 1, 2]
        steps_left = spec.n_poses - i
        home_xy = start_xy - xy
        if spec.loop and i >= spec.n_poses // 2 and np.any(home_xy):
            heading_home = math.atan2(home_xy[1], home_xy[0])
            jitter = rng.uniform(-_HOMING_JITTER, _HOMING_JITTER)
            turn = wrap_angle(heading_home - theta + jitter)
            distance = float(np.clip(np.hypot(*home_xy) / steps_left, step_min, step_max))
        else:
            turn = float(rng.uniform(-WANDER_TURN, WANDER_TURN))
            distance = float(rng.uniform(step_min, step_max))
        heading = theta + turn
        next_xy = xy + distance * np.array([math.cos(heading), math.sin(heading)])
        if np.any(next_xy < low_xy) or np.any(next_xy > high_xy):
            to_centre_xy = centre_xy - xy
            turn = wrap_angle(math.atan2(to_centre_xy[1], to_centre_xy[0]) - theta)
            distance = min(distance, float(np.hypot(*to_centre_xy)) + centre_reach)
            heading = theta + turn
            next_xy = xy + distance * np.array([math.cos(heading), math.sin(heading)])
        poses_xyt[i] = (*next_xy, heading)
        turns.append(turn)
        distances.append(distance)
    return poses_xyt, turns, distances


def _sightings(
    spec: WorldSpec, poses_xyt: np.ndarray, landmarks_xy: np.ndarray
) -> list[list[tuple[int, float, float]]]:
    """Per pose, the ``(landmark index, range, bearing)`` of every landmark in view."""
    sightings = []
    for x, y, theta in poses_xyt:
        seen = []
        for j, (lx, ly) in enumerate(landmarks_xy):
            true_range = math.hypot(lx - x, ly - y)
            true_bearing = wrap_angle(math.atan2(ly - y, lx - x) - theta)
            in_view = spec.fov >= 2 * math.pi or abs(true_bearing) <= spec.fov / 2
            if 0 < true_range <= spec.max_range and in_view:
                seen.append((j, true_range, true_bearing))
        sightings.append(seen)
    return sightings


def _point_in_view(spec: WorldSpec, pose_xyt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A random point in the sensor's view from ``pose_xyt``, inside the rectangle.

    The pose keeps ``wall_margin`` from the walls, so a point closer than that is inside.
    """
    reach = min(spec.wall_margin, spec.max_range)
    distance = rng.uniform(0.5, 1.0) * reach
    # 0.9: keep clear of the edge of the field of view, where rounding could hide it.
    direction = pose_xyt[2] + 0.9 * rng.uniform(-spec.fov / 2, spec.fov / 2)
    return pose_xyt[:2] + distance * np.array([math.cos(direction), math.sin(direction)])


def _drop_range_or_bearing(
    spec: WorldSpec, records: list[Record], rng: np.random.Generator
) -> list[Record]:
    """Make the requested fractions of the observations range-only and bearing-only."""
    where = [k for k, r in enumerate(records) if isinstance(r, Observation)]
    order = rng.permutation(len(where))
    n_range_only = round(spec.range_only_fraction * len(where))
    n_bearing_only = min(round(spec.bearing_only_fraction * len(where)), len(where) - n_range_only)
    records = list(records)
    for rank, o in enumerate(order[: n_range_only + n_bearing_only]):
        k = where[o]
        drop = "bearing" if rank < n_range_only else "range"
        records[k] = dataclasses.replace(records[k], **{drop: None})
    return records
