"""Which measurements of a log miss their truth: the figure behind every bound's honesty.

:func:`check_log` compares each measured interval of a log with the value the ground
truth gives it: a range or bearing with the distance and direction from the true pose to
the true landmark, an odometry or relative-pose move with the true poses at its two ends.
Only measurements whose poses have a truth are checked (a truth may cover only some
poses). An observation made from a sensor offset (``offset_x`` ...) is checked from the
true pose moved by that offset when the offset is a point (a mount); one whose offset is an
interval (the motion since its keyframe, say) has no true sensor pose in the truth file
and is counted apart as unchecked. This is how ``cuikslam calibrate`` reports what falls
outside calibrated bounds, and how the outliers of a real log are found.

Compared in floating point (a calibration figure, not a proof); angles modulo 2π. A value
that misses its interval by no more than the rounding error of that comparison (a truth
exactly on a bound, say) is not counted outside: an observation is then counted unchecked,
a move inside. Counting it outside would make ``solve --truth`` take a sound log for one
that breaks its outliers declaration, and say "no guarantee applies" where it holds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from cuikslam.interval.angles import angle_excess
from cuikslam.log.records import Log, Observation, Odometry, RelativePose
from cuikslam.simulate.truth import GroundTruth

__all__ = ["Outside", "check_log", "outside_to_json"]


@dataclass
class Outside:
    """Measurements of a log whose interval misses the truth (only those with truth)."""

    ranges: int = 0
    bearings: int = 0
    observations_checked: int = 0
    observations_unchecked: int = 0
    """Observations with truth from an offset that is an interval (see the module docstring)."""
    unchecked_observations: list[int] = field(default_factory=list)
    """Their indices (log order)."""
    moves: int = 0
    moves_checked: int = 0
    outside_observations: list[int] = field(default_factory=list)
    """Indices (log order) of the observations with a range or bearing outside."""
    details: list[str] = field(default_factory=list)
    """One line per value outside its interval, in log order."""

    def describe(self) -> str:
        unchecked = (
            f" ({self.observations_unchecked} observations from an uncertain sensor offset "
            "not checked)"
            if self.observations_unchecked
            else ""
        )
        return (
            f"{self.ranges} ranges and {self.bearings} bearings of {self.observations_checked} "
            f"observations, {self.moves} of {self.moves_checked} moves outside their "
            f"intervals{unchecked}"
        )


_ROUNDING = 64 * 2.0**-52
"""Relative error allowed to a float evaluation of a measured value from the truth's floats."""


def _excess(value: float, box: tuple[float, float]) -> float:
    return max(box[0] - value, value - box[1], 0.0)


def _beyond(excess: float, error: float) -> bool:
    """True when ``excess`` is larger than what rounding (``error``) can explain."""
    return excess > error


def _where(kind: str, index: int, record: Any) -> str:
    line = getattr(record, "line", 0)
    return f"{kind} {index}" + (f" (line {line})" if line else "")


def check_log(log: Log, truth: GroundTruth) -> Outside:
    """Count (and describe) the measurements of ``log`` whose interval misses ``truth``.

    ``truth.assignment`` gives the true landmark of each observation, in log order.
    """
    pose = dict(zip(truth.pose_ids, truth.poses_xyt.tolist(), strict=True))
    mark = dict(zip(truth.landmark_ids, truth.landmarks_xy.tolist(), strict=True))
    out = Outside()
    observations = iter(truth.assignment)
    index = moves = 0
    for record in log.records:
        if isinstance(record, Observation):
            lid = next(observations, None)
            p = pose.get(record.pose)
            if p is not None and record.offset is not None:
                p = _sensor_pose(p, record.offset)
                if p is None:
                    out.observations_unchecked += 1
                    out.unchecked_observations.append(index)
            if p is not None and lid is not None:
                out.observations_checked += 1
                q = mark[lid]
                bad = borderline = False
                scale = 1.0 + abs(q[0]) + abs(q[1]) + abs(p[0]) + abs(p[1])
                rng = math.hypot(q[0] - p[0], q[1] - p[1])
                if record.range is not None:
                    e = _excess(rng, record.range)
                    borderline |= 0 < e <= _ROUNDING * scale
                    if _beyond(e, _ROUNDING * scale):
                        out.ranges += 1
                        bad = True
                        out.details.append(
                            f"{_where('observation', index, record)}: range {rng:.4g} misses "
                            f"[{record.range[0]:.4g}, {record.range[1]:.4g}] by {e:.3g}"
                        )
                if record.bearing is not None:
                    bearing = math.atan2(q[1] - p[1], q[0] - p[0]) - p[2]
                    e = angle_excess(bearing, *record.bearing)
                    error = _ROUNDING * (scale / max(rng, 1e-300) + 1.0 + abs(p[2]))
                    borderline |= 0 < e <= error
                    if _beyond(e, error):
                        out.bearings += 1
                        bad = True
                        out.details.append(
                            f"{_where('observation', index, record)}: bearing misses "
                            f"[{record.bearing[0]:.4g}, {record.bearing[1]:.4g}] by {e:.3g} rad"
                        )
                if bad:
                    out.outside_observations.append(index)
                elif borderline:  # on a bound, as far as floats can tell
                    out.observations_checked -= 1
                    out.observations_unchecked += 1
                    out.unchecked_observations.append(index)
            index += 1
        elif isinstance(record, RelativePose | Odometry):
            a, b = pose.get(record.source), pose.get(record.target)
            if a is not None and b is not None:
                out.moves_checked += 1
                missed = _move_misses(record, a, b)
                if missed:
                    out.moves += 1
                    out.details.append(
                        f"{_where('move', moves, record)} {record.source}->{record.target}: "
                        + ", ".join(missed)
                    )
            moves += 1
    return out


def _sensor_pose(pose: list[float], offset: tuple) -> list[float] | None:
    """The true pose moved by a point ``offset`` (dx, dy, dtheta in its frame); None when
    the offset is an interval."""
    if any(hi - lo > 1e-9 for lo, hi in offset):
        return None
    dx, dy, dt = (0.5 * lo + 0.5 * hi for lo, hi in offset)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return [pose[0] + c * dx - s * dy, pose[1] + s * dx + c * dy, pose[2] + dt]


def _move_misses(record: RelativePose | Odometry, a: list[float], b: list[float]) -> list[str]:
    """The components of a move that miss the true poses ``a`` -> ``b``."""
    scale = 1.0 + abs(a[0]) + abs(a[1]) + abs(b[0]) + abs(b[1])
    turned = _ROUNDING * (1.0 + abs(a[2]) + abs(b[2]))
    if isinstance(record, Odometry):
        dist = math.hypot(b[0] - a[0], b[1] - a[1])
        values = [
            ("turn", angle_excess(b[2] - a[2], *record.turn), turned),
            ("distance", _excess(dist, record.distance), _ROUNDING * scale),
        ]
    else:
        c, s = math.cos(a[2]), math.sin(a[2])
        dx, dy = b[0] - a[0], b[1] - a[1]
        values = [
            ("dx", _excess(c * dx + s * dy, record.dx), _ROUNDING * scale),
            ("dy", _excess(-s * dx + c * dy, record.dy), _ROUNDING * scale),
            ("dtheta", angle_excess(b[2] - a[2], *record.dtheta), turned),
        ]
    return [f"{name} by {e:.3g}" for name, e, error in values if _beyond(e, error)]


def outside_to_json(found: Outside) -> dict[str, Any]:
    """The counts and details as JSON-ready objects."""
    return {
        "observations_checked": found.observations_checked,
        "observations_unchecked": found.observations_unchecked,
        "ranges_outside": found.ranges,
        "bearings_outside": found.bearings,
        "moves_checked": found.moves_checked,
        "moves_outside": found.moves,
        "outside_observations": found.outside_observations,
        "details": found.details,
    }
