"""Importer for the UTIAS "Lost in the Woods" dataset (``dataset2.mat``).

A wheeled robot drives among 17 identical posts and measures them with a laser
rangefinder; Vicon gives the true robot poses and post positions. The importer turns the
whole recording, or a window of it, into a cuikslam :class:`~cuikslam.log.records.Log`
and its :class:`~cuikslam.simulate.truth.GroundTruth`. Nothing in the log comes from
Vicon except the prior box on the first pose that has a Vicon value; Vicon gaps only
leave poses without truth.

Modelling (each interval holds the truth whenever the stated bounds do):

* **Keyframes.** One pose every ``keyframe`` samples (10 Hz). The wheel odometry between
  two keyframes, speed ``v ± speed_bound`` and turn rate ``om ± turn_rate_bound`` per
  sample, is composed into one ``relative_pose`` by :func:`cuikslam.motion.compose_steps`
  (sound for a speed and turn rate that vary inside their bounds during a sample). The
  robot drives along its Vicon heading plus ``drive_angle`` (the tracker is mounted about
  0.08 rad askew: a measured constant of the dataset, with a margin).
* **Sensor offset.** The laser sits ``d`` (0.219 m) ahead of the robot centre. An
  observation made at sample j, between keyframes k and k + 1, carries the sensor's pose
  in the frame of keyframe k: the composed motion from k to j, then the mount
  (``offset_x``, ``offset_y``, ``offset_theta`` of the log format). Its range and
  bearing are the reading ± ``range_bound`` and ± ``bearing_bound``.
* **Bounds.** By default, the speed and turn-rate bounds are three standard deviations
  of the noise variances stored in the file (``v_var``, ``om_var``), and the range and
  bearing bounds lie just above the largest errors the dataset's documentation states
  (about 15.5 cm and 0.14 rad).
* **Prior.** The first sample with a Vicon value is a keyframe, and its pose gets a
  ±1 cm, ±0.01 rad box around it; when the window starts in a Vicon gap, the first pose
  gets a box 20 m around the posts. No sensor record is written: the laser misses posts.
* **Time stamps.** Each record carries the time [s] of its sample (``t``): a move and a
  prior that of the keyframe it reaches, an observation that of its reading, so that
  ``cuikslam follow --rate`` replays the run at its recorded pace.
"""

from __future__ import annotations

import math
import os
from dataclasses import replace
from typing import Literal

import numpy as np

from cuikslam.datasets._litw_file import load_dataset
from cuikslam.datasets.lost_in_the_woods_bounds import DRIVE_OFFSET, LitwBounds, nominal_move
from cuikslam.errors import InputFileError
from cuikslam.log.records import (
    Bounds,
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    PosePrior,
    Record,
    RelativePose,
)
from cuikslam.messages import Message
from cuikslam.motion import RelativeBounds, compose_relative, compose_steps
from cuikslam.simulate.truth import GroundTruth

__all__ = ["read_lost_in_the_woods"]

DRIVE_MARGIN = 0.03
"""Half-width [rad] of the drive-angle interval around ``DRIVE_OFFSET``."""
RANGE_BOUND = 0.16
"""Range error bound [m]: the documented largest error is about 15.5 cm."""
BEARING_BOUND = 0.15
"""Bearing error bound [rad]: the documented largest error is about 0.14 rad."""
ARENA_MARGIN = 20.0
"""Margin [m] around the posts of the box given to the first pose when it has no Vicon."""
PRIOR_BOUND = (0.01, 0.01)
"""Half-widths of the prior box on the first pose with truth: position [m], heading [rad]."""


def read_lost_in_the_woods(
    path: str | os.PathLike[str],
    *,
    start: int = 0,
    steps: int | None = None,
    keyframe: int = 10,
    unknown: bool = True,
    speed_bound: float | None = None,
    turn_rate_bound: float | None = None,
    range_bound: float | None = None,
    bearing_bound: float | None = None,
    drive_angle: Bounds = (DRIVE_OFFSET - DRIVE_MARGIN, DRIVE_OFFSET + DRIVE_MARGIN),
    every_observation: bool = True,
    bounds: LitwBounds | None = None,
    posts_at_most: int | Literal["file"] | None = None,
    post_separation: float | None = None,
    map_bound: float | None = None,
) -> tuple[Log, GroundTruth]:
    """Import samples ``start .. start + steps`` of ``dataset2.mat`` (default: to the end).

    Parameters
    ----------
    keyframe : int
        Samples per pose (the first sample with a Vicon pose is a keyframe too). Fewer
        poses solve faster; each keyframe's motion interval widens (see
        :mod:`cuikslam.motion`).
    unknown : bool
        Drop the landmark ids (``P0..P16``): unknown correspondence.
    speed_bound, turn_rate_bound : float, optional
        Per-sample odometry error bounds [m/s, rad/s]; default three standard deviations
        of the file's ``v_var`` and ``om_var``. Not with ``bounds``.
    range_bound, bearing_bound : float, optional
        Observation error bounds [m, rad]; default those of ``bounds``, else
        ``RANGE_BOUND`` and ``BEARING_BOUND``.
    drive_angle : (float, float)
        Angle from the heading to the direction the wheels drive [rad].
    every_observation : bool
        Keep the observations made between keyframes (from an offset sensor pose); with
        False only those made at a keyframe sample are kept.
    bounds : LitwBounds, optional
        Bounds calibrated on a part of the run
        (:func:`~.lost_in_the_woods_bounds.calibrate_lost_in_the_woods`): each stretch of
        odometry is its readings composed at face value, widened by the calibrated motion
        model, instead of the per-sample bounds composed soundly.
    posts_at_most, post_separation : optional
        A ``class`` record for the posts: at most this many (``"file"``: as many as the
        file's map has, 17), and two at least this far apart [m]; priors a user of the
        arena knows, which the correspondence search uses to refute hypotheses.
    map_bound : float, optional
        Write the file's surveyed map (the posts' Vicon positions, ``l``) as landmark
        records, each post's position ± ``map_bound`` [m], and no post beyond the map's
        (unless ``posts_at_most`` says otherwise): localization against a known map. With
        ``unknown`` the search then matches each reading to a surveyed post.

    Returns
    -------
    (Log, GroundTruth)
        The truth lists the poses whose sample has a valid Vicon pose.

    Raises
    ------
    InputFileError
        If the file cannot be read, lacks a variable, or the window is empty, leaves the
        recording, or has no valid Vicon pose (the prior needs one).
    """
    if bounds is not None and (speed_bound is not None or turn_rate_bound is not None):
        raise ValueError("per-sample odometry bounds and calibrated bounds exclude each other")
    if bounds is not None and keyframe > bounds.max_samples:
        raise InputFileError(
            path, None, Message(
                "keyframe_beyond_calibration",
                f"keyframes of {keyframe} samples, but the bounds were calibrated on "
                f"stretches of at most {bounds.max_samples} (calibrate with keyframe={keyframe})",
                keyframe=keyframe, max_samples=bounds.max_samples,
            ),
        )  # fmt: skip
    if range_bound is None:
        range_bound = RANGE_BOUND if bounds is None else bounds.range
    if bearing_bound is None:
        bearing_bound = BEARING_BOUND if bounds is None else bounds.bearing
    data = load_dataset(path)
    t = data["t"].ravel().astype(float)
    n_samples = t.size
    end = n_samples - 1 if steps is None else start + steps
    if keyframe < 1 or end <= start:
        raise InputFileError(path, None, f"need keyframe >= 1 and steps >= 1 ({steps=})")
    if start < 0 or end >= n_samples:
        raise InputFileError(
            path, None, f"window {start}..{end} leaves the recording (0..{n_samples - 1})"
        )
    valid = data["true_valid"].ravel() != 0
    first_truth = start + int(np.argmax(valid[start : end + 1]))
    if not valid[first_truth]:
        raise InputFileError(
            path, None, f"no valid Vicon pose in samples {start}..{end}: nothing to anchor"
        )
    v, om = data["v"].ravel().astype(float), data["om"].ravel().astype(float)
    if speed_bound is None:
        speed_bound = 3.0 * math.sqrt(float(np.asarray(data["v_var"]).ravel()[0]))
    if turn_rate_bound is None:
        turn_rate_bound = 3.0 * math.sqrt(float(np.asarray(data["om_var"]).ravel()[0]))
    ranges, bearings = np.asarray(data["r"], float), np.asarray(data["b"], float)
    d = float(np.asarray(data["d"]).ravel()[0])
    x, y = data["x_true"].ravel(), data["y_true"].ravel()
    theta = np.unwrap(data["th_true"].ravel())
    posts = np.asarray(data["l"], float)
    v_box = np.stack([v - speed_bound, v + speed_bound], axis=-1)
    om_box = np.stack([om - turn_rate_bound, om + turn_rate_bound], axis=-1)
    mount = ((d, d), (0.0, 0.0), (0.0, 0.0))

    def motion(a: int, j: int) -> RelativeBounds:
        """The robot's motion from sample ``a`` to sample ``j``."""
        if bounds is None:
            return compose_steps(v_box[a:j], om_box[a:j], t[a : j + 1], drive_angle)
        if j == a:
            return ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
        centre, travelled, turned = nominal_move(v[a:j], om[a:j], t[a : j + 1])
        half = bounds.motion(travelled, turned)
        return tuple(_widen(c, h) for c, h in zip(centre, half, strict=True))

    keys = sorted({*range(start, end, keyframe), first_truth, end})
    records: list[Record] = []
    if posts_at_most == "file" or (map_bound is not None and posts_at_most is None):
        posts_at_most = len(posts)  # a surveyed map: no post beyond it
    if posts_at_most is not None or post_separation is not None:
        records.append(ClassPrior("post", at_most=posts_at_most, min_separation=post_separation))
    if map_bound is not None:
        records.extend(
            LandmarkPrior(f"P{j}", "post", _widen(px, map_bound), _widen(py, map_bound))
            for j, (px, py) in enumerate(posts.tolist())
        )
    if first_truth > start:
        # before the first Vicon pose the robot is only known to be near the posts
        lo, hi = posts.min(axis=0) - ARENA_MARGIN, posts.max(axis=0) + ARENA_MARGIN
        records.append(
            PosePrior(0, (lo[0], hi[0]), (lo[1], hi[1]), (-4.0, 4.0), time=float(t[start]))
        )
    assignment: list[str] = []
    truth_ids: list[int] = []
    truth_poses: list[list[float]] = []
    for i, k in enumerate(keys):
        if i > 0:
            a = keys[i - 1]
            records.append(RelativePose(i - 1, i, *motion(a, k), time=float(t[k])))
        if k == first_truth:
            records.append(replace(_prior(i, k, x, y, theta), time=float(t[k])))
        if valid[k]:
            truth_ids.append(i)
            truth_poses.append([float(x[k]), float(y[k]), float(theta[k])])
        last = keys[i + 1] if i + 1 < len(keys) else end + 1
        for j in range(k, last if every_observation else k + 1):
            seen = np.flatnonzero(ranges[j] > 0)
            if seen.size == 0:
                continue
            offset = compose_relative([motion(k, j), mount])
            for p in seen:
                r, b = float(ranges[j, p]), float(bearings[j, p])
                records.append(
                    Observation(
                        i,
                        "post",
                        (max(r - range_bound, 0.0), r + range_bound),
                        (b - bearing_bound, b + bearing_bound),
                        None if unknown else f"P{p}",
                        offset=offset,
                        time=float(t[j]),
                    )
                )
                assignment.append(f"P{p}")
    truth = GroundTruth(
        poses_xyt=np.asarray(truth_poses, float).reshape(-1, 3),
        pose_ids=truth_ids,
        landmarks_xy=posts.copy(),
        landmark_ids=[f"P{j}" for j in range(len(posts))],
        landmark_classes=["post"] * len(posts),
        assignment=assignment,
    )
    return Log(records=records, path=os.fspath(path)), truth


def _prior(pose: int, k: int, x: np.ndarray, y: np.ndarray, theta: np.ndarray) -> PosePrior:
    """A small box around the Vicon pose of sample ``k`` (the one anchor of the log)."""
    e, et = PRIOR_BOUND
    return PosePrior(
        pose,
        (float(x[k]) - e, float(x[k]) + e),
        (float(y[k]) - e, float(y[k]) + e),
        (float(theta[k]) - et, float(theta[k]) + et),
    )


def _widen(centre: float, half: float) -> Bounds:
    """``centre ± half``, rounded outward."""
    return (math.nextafter(centre - half, -math.inf), math.nextafter(centre + half, math.inf))
