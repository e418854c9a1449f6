"""Importer for the UTIAS MRCLAM datasets (1–9): one robot's run as a log and its truth.

Five robots drive in a room with 15 barcoded cylinders; each robot's monocular camera
gives range and bearing to the barcodes it sees (landmarks and other robots), its
commands (forward and angular velocity, ~67 Hz) serve as odometry, and Vicon gives the
truth. :func:`read_mrclam` turns one robot's run (or a time window of it) into a
:class:`~cuikslam.log.records.Log` and a :class:`~cuikslam.simulate.truth.GroundTruth`.

Modelling choices:

* **Poses (keyframes).** One pose at the start of the window, one at every distinct
  measurement time (all detections of one image share it and form one scan), and more
  between them so that no two consecutive poses are more than ``keyframe_gap`` seconds
  apart. A longer gap means fewer poses (a smaller graph, faster) and wider steps; a
  shorter one more poses to evaluate against the truth.
* **Odometry.** The commands between two poses, each held until the next time stamp,
  become steps. The robot follows a command late (up to ``lag`` seconds), so during a
  step its forward and angular velocities lie in the hull of the commands in force in
  the last ``lag`` seconds, widened by ``± velocity`` and ``± turn_rate``. The
  ``motion`` function composes the steps soundly into one move from pose to pose (a
  relative pose: the robot turns while it drives), widened by ``move_xy`` and
  ``move_theta`` for the Vicon jitter.
* **Observations.** ``r ± (range + range_per_metre · r)`` for a reading r (lower end at
  least 0) and ``bearing ± bearing``
  from the robot centre, class ``"landmark"``, id ``L<subject>`` (e.g. ``L6``) unless
  ``unknown``. Barcodes that are in no table are dropped and counted. Sightings of other
  robots are dropped (``robots="drop"``, the default) or kept (``robots="class"``) as
  class ``"robot"``, each sighting its own landmark ``R<subject>@<row>`` (``row``: the
  sighting's data row in ``RobotN_Measurement.dat``, from 0; a robot moves, so two
  sightings are never one landmark); those ids are kept even with ``unknown``. A second
  detection of the same subject in one image is dropped and counted (a scan sees
  distinct landmarks).
* **Prior.** The first pose gets a box of ``± prior_xy``, ``± prior_theta`` around its
  Vicon pose (the window must start where Vicon has one).
* **Truth.** Vicon interpolated at each pose's time (headings unwrapped); a pose
  between Vicon samples more than ``truth_gap`` apart gets no truth (a Vicon gap). The
  landmark truth is ``Landmark_Groundtruth.dat``; a kept robot sighting's truth is that
  robot's Vicon position at the sighting's time (interpolated across any gap).
* **Time stamps.** Each record carries its UNIX time [s]: a move and an observation that
  of the pose they reach or are made from, the prior that of the first pose (``cuikslam
  follow --rate`` replays the run at its recorded pace).
* **Window.** From ``start`` seconds after the first command (no earlier than ``lag``
  after it, nor than the first Vicon sample) to the last measurement within ``duration``.

The default bounds were measured on Dataset 6 (all five robots, against the Vicon
truth); the range bound grows with the range, as the camera's error does. How many
measurements miss them is in ``docs/real-data.md``. **They do not hold for every
measurement**: MRCLAM has gross outliers (ranges off by up to ~3 m and bearings by up to
~3 rad on robots 3 and 5).
A log with a measurement outside its interval is not guaranteed; measure bounds for
your run (``cuikslam calibrate``) and expect a few outliers to need declaring.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from cuikslam import interval as ia
from cuikslam.datasets.mrclam_files import (
    ROBOT_SUBJECTS,
    MrclamTables,
    interpolate_poses,
    keyframe_times,
    lagged_command_hulls,
    read_mrclam_tables,
    velocity_steps,
)
from cuikslam.errors import InputFileError
from cuikslam.interval._arith import add, mul
from cuikslam.log.records import ClassPrior, LandmarkPrior, Log, Observation, PosePrior, Record
from cuikslam.messages import Message
from cuikslam.simulate.truth import GroundTruth

__all__ = ["MotionModel", "MrclamBounds", "MrclamImport", "read_mrclam"]


@dataclass(frozen=True)
class MrclamBounds:
    """Half-widths of the measured intervals (see the module docstring for their origin)."""

    range: float = 0.1
    """Range error bound [m], to which ``range_per_metre`` times the reading is added."""
    range_per_metre: float = 0.13
    """Range error bound per metre of the reading (the camera errs more far away)."""
    bearing: float = 0.1
    """Bearing error bound [rad]."""
    velocity: float = 0.03
    """Forward velocity error bound [m/s] around the lagged commands."""
    turn_rate: float = 0.1
    """Angular velocity error bound [rad/s] around the lagged commands."""
    lag: float = 1.0
    """Longest time [s] the robot takes to follow a command: its velocities at time t lie
    in the hull of the commands in force during ``[t - lag, t]``, widened by
    ``velocity`` and ``turn_rate``."""
    move_xy: float = 0.01
    """Slack added to each move's dx and dy [m]: the Vicon truth jitters by a few mm, so a
    robot at rest moves by that much in the truth."""
    move_theta: float = 0.02
    """Slack added to each move's heading change [rad] (Vicon jitter, command lag)."""
    prior_xy: float = 0.01
    """Half-width of the first pose's x and y box around its Vicon pose [m]."""
    prior_theta: float = 0.01
    """Half-width of the first pose's heading box [rad]."""

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0 <= value < float("inf")):
                raise ValueError(f"bound {name} must be a finite number >= 0, got {value!r}")


MotionModel = Callable[[int, int, np.ndarray, np.ndarray, np.ndarray, MrclamBounds], list[Record]]
"""``motion(source, target, v, omega, times, bounds)``: the records of the move from pose
``source`` to pose ``target`` in n steps, step k between ``times[k]`` and ``times[k + 1]``
with its forward and angular velocity in the intervals ``v[k]`` and ``omega[k]`` ((n, 2)
arrays of lo, hi)."""


@dataclass
class MrclamImport:
    """What an import kept and dropped (every measurement is accounted for)."""

    robot: int
    start: float
    """Time of pose 0 [s] (UNIX time)."""
    end: float
    poses: int = 0
    poses_without_truth: int = 0
    commands: int = 0
    measurements: int = 0
    kept: int = 0
    dropped: dict[str, int] = field(default_factory=dict)

    def drop(self, why: str, count: int = 1) -> None:
        if count:
            self.dropped[why] = self.dropped.get(why, 0) + count

    def describe(self) -> str:
        """One paragraph for the user."""
        drops = ", ".join(f"{n} {why}" for why, n in sorted(self.dropped.items()))
        return (
            f"robot {self.robot}, {self.end - self.start:.1f} s: {self.poses} poses "
            f"({self.poses_without_truth} without Vicon truth), {self.commands} commands; "
            f"{self.kept} of {self.measurements} measurements kept"
            + (f" (dropped: {drops})" if drops else "")
        )


def read_mrclam(
    folder: str | os.PathLike[str] | MrclamTables,
    robot: int,
    *,
    start: float = 0.0,
    duration: float | None = None,
    keyframe_gap: float = 1.0,
    robots: str = "drop",
    unknown: bool = False,
    bounds: MrclamBounds | None = None,
    truth_gap: float = 0.25,
    motion: MotionModel | None = None,
    map_bound: float | None = None,
) -> tuple[Log, GroundTruth, MrclamImport]:
    """Import robot ``robot`` of the MRCLAM dataset in ``folder`` (see the module docstring).

    Parameters
    ----------
    folder : path or MrclamTables
        The dataset folder (``Barcodes.dat``, ``RobotN_*.dat``, ...), or its tables
        already read by :func:`~cuikslam.datasets.mrclam_files.read_mrclam_tables`.
    robot : int
        1 to 5.
    start, duration : float
        The window, in seconds from the robot's first command (default: the whole run).
        The window starts no earlier than the first Vicon sample.
    keyframe_gap : float
        Longest time between consecutive poses [s].
    robots : {"drop", "class"}
        What to do with sightings of other robots.
    unknown : bool
        Leave the landmark ids out (unknown correspondence).
    bounds : MrclamBounds, optional
        Error bounds; default :class:`MrclamBounds()`.
    truth_gap : float
        Longest Vicon gap [s] across which a pose's truth is interpolated.
    motion : MotionModel, optional
        Turns the commands between two poses into records; default
        :func:`cuikslam.datasets.mrclam_motion.relative_pose_motion`.
    map_bound : float, optional
        Write the surveyed map (``Landmark_Groundtruth.dat``) as landmark records, each
        landmark's position ± ``map_bound`` [m], and a class record: no landmark beyond
        the map's (localization against a known map). With ``unknown`` the search then
        matches each sighting to a surveyed landmark.

    Returns
    -------
    (Log, GroundTruth, MrclamImport)

    Raises
    ------
    InputFileError
        If a file is missing or malformed, or the window is empty or starts where
        Vicon has no pose.
    """
    if robots not in ("drop", "class"):
        raise ValueError(f"robots must be 'drop' or 'class', got {robots!r}")
    bounds = bounds or MrclamBounds()
    if motion is None:
        from cuikslam.datasets.mrclam_motion import relative_pose_motion as motion
    if isinstance(folder, MrclamTables):
        tables = folder
        if tables.robot != robot:
            raise ValueError(f"the tables are robot {tables.robot}'s, not robot {robot}'s")
    else:
        tables = read_mrclam_tables(folder, robot)
    t0, t1 = _window(tables, start, duration, bounds)
    report = MrclamImport(robot=robot, start=t0, end=t1)

    meas = tables.measurements
    report.measurements = len(meas)
    inside = (meas[:, 0] > t0) & (meas[:, 0] <= t1)
    report.drop("outside the window", int((~inside).sum()))
    times = keyframe_times(meas[inside, 0], t0, t1, keyframe_gap)
    own_truth, has_truth = interpolate_poses(tables.groundtruth[robot], times, truth_gap)
    if not has_truth[0]:
        raise InputFileError(
            tables.folder,
            None,
            Message(
                "no_truth_at_start",
                f"no Vicon pose of robot {robot} at the window start: move start",
                robot=robot,
            ),
        )

    x, y, th = own_truth[0]
    records: list[Record] = [
        PosePrior(
            0,
            _around(x, bounds.prior_xy),
            _around(y, bounds.prior_xy),
            _around(th, bounds.prior_theta),
            time=float(times[0]),
        )
    ]
    if map_bound is not None:  # every landmark is surveyed: none beyond the map
        records.append(ClassPrior("landmark", at_most=len(tables.landmarks)))
        records.extend(
            LandmarkPrior(f"L{s}", "landmark", _around(xy[0], map_bound), _around(xy[1], map_bound))
            for s, xy in tables.landmarks.items()
        )
    pose_of_time = {float(t): i for i, t in enumerate(times)}
    obs_by_pose = _observations(
        tables, np.flatnonzero(inside), pose_of_time, bounds, robots, unknown, report
    )
    assignment: list[str] = []
    landmark_truth: dict[str, tuple[float, float, str]] = {
        f"L{s}": (*xy, "landmark") for s, xy in tables.landmarks.items()
    }
    hulls = lagged_command_hulls(tables.odometry, bounds.lag)
    v_slack = np.array([-bounds.velocity, bounds.velocity])
    w_slack = np.array([-bounds.turn_rate, bounds.turn_rate])
    for i in range(len(times)):
        if i > 0:
            rows, step_times = velocity_steps(tables.odometry, float(times[i - 1]), float(times[i]))
            report.commands += len(rows)
            v_box = ia.add(hulls[rows, 0:2], v_slack)
            w_box = ia.add(hulls[rows, 2:4], w_slack)
            moves = motion(i - 1, i, v_box, w_box, step_times, bounds)
            records.extend(replace(move, time=float(times[i])) for move in moves)
        for obs, true_id, xy in obs_by_pose.get(i, []):
            records.append(replace(obs, time=float(times[i])))
            assignment.append(true_id)
            if xy is not None:
                landmark_truth[true_id] = (*xy, "robot")
    report.end = float(times[-1])
    report.poses = len(times)
    report.poses_without_truth = int((~has_truth).sum())
    report.kept = len(assignment)
    truth = GroundTruth(
        poses_xyt=own_truth[has_truth],
        pose_ids=[i for i in range(len(times)) if has_truth[i]],
        landmarks_xy=np.array([v[:2] for v in landmark_truth.values()], float).reshape(-1, 2),
        landmark_ids=list(landmark_truth),
        landmark_classes=[v[2] for v in landmark_truth.values()],
        assignment=assignment,
    )
    return Log(records=records, path=os.fspath(tables.folder)), truth, report


def _around(value: float, bound: float) -> tuple[float, float]:
    """``[value - bound, value + bound]`` rounded outward."""
    return add(value, value, -bound, bound)


def _window(
    tables: MrclamTables, start: float, duration: float | None, bounds: MrclamBounds
) -> tuple[float, float]:
    """The window [t0, t1] in UNIX time: inside the commands (from ``lag`` after the
    first), from the first Vicon sample."""
    commands = tables.odometry[:, 0]
    vicon = tables.groundtruth[tables.robot][:, 0]
    if not (start >= 0 and (duration is None or duration > 0)):
        raise InputFileError(
            tables.folder, None, f"window start {start} s, duration {duration} s: need start "
            ">= 0 and duration > 0"
        )  # fmt: skip
    # Before the first command plus the lag, the robot may follow unrecorded commands.
    t0 = max(commands[0] + max(start, bounds.lag), vicon[0])
    t1 = commands[-1] if duration is None else min(commands[0] + start + duration, commands[-1])
    if not t1 > t0:
        raise InputFileError(
            tables.folder,
            None,
            f"the window from {start} s"
            + (f" for {duration} s" if duration is not None else " to the end")
            + f" holds no command of robot {tables.robot} "
            f"with Vicon (commands last {commands[-1] - commands[0]:.1f} s)",
        )
    return float(t0), float(t1)


def _observations(
    tables: MrclamTables,
    rows: np.ndarray,
    pose_of_time: dict[float, int],
    bounds: MrclamBounds,
    robots: str,
    unknown: bool,
    report: MrclamImport,
) -> dict[int, list[tuple[Observation, str, tuple[float, float] | None]]]:
    """Each pose's observations with their true landmark id (and, for a robot sighting,
    that robot's position, the landmark truth)."""
    out: dict[int, list[tuple[Observation, str, tuple[float, float] | None]]] = {}
    seen: set[tuple[int, int]] = set()
    for index in rows.tolist():
        t, code, rng, bearing = tables.measurements[index]
        subject = tables.subject_of_barcode.get(int(code))
        if subject is None or (subject not in tables.landmarks and subject not in ROBOT_SUBJECTS):
            report.drop("barcodes in no table")
            continue
        is_robot = subject in ROBOT_SUBJECTS
        if is_robot and robots == "drop":
            report.drop("sightings of other robots")
            continue
        pose = pose_of_time[float(t)]
        if (pose, subject) in seen:
            report.drop("second detections of a subject in one image")
            continue
        seen.add((pose, subject))
        _, scaled = mul(float(rng), float(rng), bounds.range_per_metre, bounds.range_per_metre)
        _, half = add(bounds.range, bounds.range, scaled, scaled)
        lo, hi = _around(float(rng), half)
        range_box = (max(lo, 0.0), hi)
        bearing_box = _around(float(bearing), bounds.bearing)
        xy = None
        if is_robot:
            true_id = f"R{subject}@{index}"
            other = tables.vicon(subject)
            if other is None:
                report.drop("sightings of robots without a Vicon file")
                continue
            pos, _ = interpolate_poses(other, np.array([t]), float("inf"))
            xy = (float(pos[0, 0]), float(pos[0, 1]))
            obs = Observation(pose, "robot", range_box, bearing_box, true_id)
        else:
            true_id = f"L{subject}"
            obs = Observation(
                pose, "landmark", range_box, bearing_box, None if unknown else true_id
            )
        out.setdefault(pose, []).append((obs, true_id, xy))
    return out
