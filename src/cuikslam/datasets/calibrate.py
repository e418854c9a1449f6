"""Bounds that hold, honestly obtained: measure error bounds on a run with truth, check
them on another.

:func:`calibrate_mrclam` measures, on a part of a MRCLAM run (a robot, a time window),
the errors of each measurement type against the Vicon truth and returns the smallest
bounds under which a chosen share (by default all) of that part's measurements hold the
truth. :func:`count_outside` then imports *another* part with those bounds and counts
the measurements whose interval misses the truth
(:func:`cuikslam.results.measurement_check.check_log`): the honest figure of how well
the bounds carry over. :func:`write_bounds_file` and :func:`read_bounds_file` keep the
bounds in a small JSON file that ``cuikslam import mrclam --bounds FILE`` accepts::

    {"cuikslam_bounds": 1, "dataset": "mrclam",
     "bounds": {"range": 0.58, "bearing": 0.098, "velocity": 0.03, "turn_rate": 0.1, ...},
     "calibrated_on": {...}, "errors": {...}}

* **Range, bearing**: the error of each landmark sighting against the range and bearing
  from the robot's Vicon pose (interpolated at the image's time) to the landmark's
  Vicon position. The bearing bound is the ``quantile`` of the absolute errors (1: the
  maximum); for the range, the constant part (``range``) is kept and ``range_per_metre``
  is the quantile of what each sighting needs, ``(|error| - range) / reading``.
* **Motion**: the commands' bounds (``velocity``, ``turn_rate``, with the lag) are
  scaled together from the defaults until the share ``quantile`` of the part's moves
  hold the truth (bisection on the scale; every candidate is imported and checked).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Collection
from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from cuikslam._atomic import atomic_write_text
from cuikslam.datasets.mrclam import MrclamBounds, read_mrclam
from cuikslam.datasets.mrclam_files import MrclamTables, read_mrclam_tables
from cuikslam.errors import InputFileError
from cuikslam.interval.angles import wrap_angle
from cuikslam.results.measurement_check import Outside, check_log

if TYPE_CHECKING:
    from cuikslam.datasets.lost_in_the_woods_bounds import LitwBounds, LitwOutside

__all__ = [
    "Calibration",
    "calibrate_mrclam",
    "count_outside",
    "read_bounds_file",
    "write_bounds_file",
]

FORMAT_VERSION = 1


@dataclass
class Calibration:
    """Bounds measured on a part of a run, what they come from, and that part checked with
    them (MRCLAM's or Lost in the Woods')."""

    bounds: MrclamBounds | LitwBounds
    calibrated_on: dict[str, Any]
    errors: dict[str, dict[str, float]]
    outside: Outside | LitwOutside
    """The calibration part itself checked with the bounds (nonzero when quantile < 1)."""


def _sighting_errors(
    tables: MrclamTables, start: float, duration: float | None, truth_gap: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Range readings, range errors and bearing errors of the landmark sightings the
    importer keeps in the window (imported with zero bounds, so each interval is the
    reading), where Vicon has truth."""
    exact = replace(MrclamBounds(), range=0.0, range_per_metre=0.0, bearing=0.0)
    log, truth, _ = read_mrclam(
        tables, tables.robot, start=start, duration=duration, bounds=exact, truth_gap=truth_gap
    )
    pose = dict(zip(truth.pose_ids, truth.poses_xyt.tolist(), strict=True))
    mark = dict(zip(truth.landmark_ids, truth.landmarks_xy.tolist(), strict=True))
    readings, ranges, bearings = [], [], []
    for obs, lid in zip(log.observations, truth.assignment, strict=True):
        p = pose.get(obs.pose)
        if p is None or obs.landmark_class != "landmark":
            continue
        q = mark[lid]
        readings.append(obs.range[0])
        ranges.append(obs.range[0] - math.hypot(q[0] - p[0], q[1] - p[1]))
        direction = math.atan2(q[1] - p[1], q[0] - p[0]) - p[2]
        bearings.append(wrap_angle(obs.bearing[0] - direction))
    return np.array(readings), np.array(ranges), np.array(bearings)


def _round_up(value: float) -> float:
    """``value`` rounded up to 3 significant digits (a bound never shrinks)."""
    if value <= 0:
        return 0.0
    if value < 1e-300:  # 3 significant digits would underflow
        return 1e-300
    step = 10.0 ** (math.floor(math.log10(value)) - 2)
    rounded = float(f"{math.ceil(value / step) * step:.3g}")
    while rounded < value:
        rounded = math.nextafter(rounded, math.inf)
    return rounded


def _stats(errors: np.ndarray) -> dict[str, float]:
    a = np.abs(errors)
    if a.size == 0:
        return {"count": 0}
    return {
        "count": int(a.size),
        "median": float(np.median(a)),
        "p99": float(np.quantile(a, 0.99)),
        "max": float(a.max()),
    }


def calibrate_mrclam(
    folder: str | os.PathLike[str] | MrclamTables,
    robot: int,
    *,
    start: float = 0.0,
    duration: float | None = None,
    quantile: float = 1.0,
    base: MrclamBounds | None = None,
    truth_gap: float = 0.25,
    keyframe_gap: float = 1.0,
) -> Calibration:
    """Measure bounds on robot ``robot``'s window ``start``, ``duration`` (see the module
    docstring).

    Parameters
    ----------
    quantile : float
        Share (0 < q <= 1) of the part's measurements of each type the bounds must hold;
        1 takes the maxima, so every measurement of the part holds.
    base : MrclamBounds, optional
        Bounds kept as they are (lag, move slack, prior) and the motion bounds' starting
        point (default :class:`MrclamBounds()`).

    Raises
    ------
    InputFileError
        If the files are malformed or the window holds no landmark sighting with truth.
    ValueError
        If ``quantile`` is not in (0, 1].
    """
    if not 0 < quantile <= 1:
        raise ValueError(f"the quantile must be in (0, 1], got {quantile}")
    tables = folder if isinstance(folder, MrclamTables) else read_mrclam_tables(folder, robot)
    base = base or MrclamBounds()
    readings, range_error, bearing_error = _sighting_errors(tables, start, duration, truth_gap)
    if range_error.size == 0:
        raise InputFileError(
            tables.folder,
            None,
            f"robot {robot}: no landmark sighting with Vicon truth in the window",
        )
    # Each sighting needs range_per_metre >= (|error| - range) / reading to hold its truth.
    per_metre = np.maximum(np.abs(range_error) - base.range, 0.0) / np.maximum(readings, 1e-9)
    bounds = replace(
        base,
        range_per_metre=_round_up(float(np.quantile(per_metre, quantile, method="higher"))),
        bearing=_round_up(float(np.quantile(np.abs(bearing_error), quantile, method="higher"))),
    )

    def moves_outside(scale: float) -> tuple[int, int]:
        trial = replace(bounds, velocity=base.velocity * scale, turn_rate=base.turn_rate * scale)
        log, truth, _ = read_mrclam(
            tables, robot, start=start, duration=duration, bounds=trial,
            truth_gap=truth_gap, keyframe_gap=keyframe_gap,
        )  # fmt: skip
        found = check_log(log, truth)
        return found.moves, found.moves_checked

    allowed = lambda checked: math.floor((1 - quantile) * checked + 1e-9)  # noqa: E731
    lo, hi = 0.0, 1.0
    while True:
        missed, checked = moves_outside(hi)
        if missed <= allowed(checked) or hi >= 64:
            break
        lo, hi = hi, 2 * hi
    for _ in range(8):  # the scale to within 1/256 of [lo, hi]
        mid = (lo + hi) / 2
        missed, checked = moves_outside(mid)
        if missed <= allowed(checked):
            hi = mid
        else:
            lo = mid
    bounds = replace(
        bounds,
        velocity=_round_up(base.velocity * hi),
        turn_rate=_round_up(base.turn_rate * hi),
    )
    log, truth, _ = read_mrclam(
        tables, robot, start=start, duration=duration, bounds=bounds,
        truth_gap=truth_gap, keyframe_gap=keyframe_gap,
    )  # fmt: skip
    return Calibration(
        bounds=bounds,
        calibrated_on={
            "folder": os.fspath(tables.folder),
            "robot": robot,
            "start": start,
            "duration": duration,
            "quantile": quantile,
        },
        errors={
            "range": _stats(range_error),
            "range_per_metre_needed": _stats(per_metre),
            "bearing": _stats(bearing_error),
            "motion_scale": {"of_default_velocity_and_turn_rate": hi},
        },
        outside=check_log(log, truth),
    )


def count_outside(
    folder: str | os.PathLike[str] | MrclamTables,
    robot: int,
    bounds: MrclamBounds,
    *,
    start: float = 0.0,
    duration: float | None = None,
    truth_gap: float = 0.25,
    keyframe_gap: float = 1.0,
) -> Outside:
    """Import a part with ``bounds`` and count the measurements that miss the truth."""
    log, truth, _ = read_mrclam(
        folder, robot, start=start, duration=duration, bounds=bounds,
        truth_gap=truth_gap, keyframe_gap=keyframe_gap,
    )  # fmt: skip
    return check_log(log, truth)


def write_bounds_file(
    calibration: Calibration, path: str | os.PathLike[str], dataset: str = "mrclam"
) -> None:
    """Write the bounds file (see the module docstring), atomically. ``calibration.bounds``
    may be any dataclass of named bounds (the importer of ``dataset`` reads them)."""
    doc = {
        "cuikslam_bounds": FORMAT_VERSION,
        "dataset": dataset,
        "bounds": asdict(calibration.bounds),
        "calibrated_on": calibration.calibrated_on,
        "errors": calibration.errors,
    }
    atomic_write_text(path, json.dumps(doc, indent=1, allow_nan=False) + "\n")


def read_bounds_file(
    path: str | os.PathLike[str], dataset: str = "mrclam", names: Collection[str] | None = None
) -> dict[str, float]:
    """The bounds of a bounds file, checked (names and values) for ``dataset``.

    ``names`` are the bounds ``dataset``'s importer knows (default: the fields of
    :class:`~cuikslam.datasets.mrclam.MrclamBounds` for ``"mrclam"``).

    Raises
    ------
    InputFileError
        Naming the file: unreadable, not JSON, another dataset's, an unknown bound name,
        or a value that is not a finite number >= 0.
    """
    try:
        with open(path, encoding="utf-8") as handle:
            doc = json.load(handle)
    except OSError as err:
        raise InputFileError(path, None, f"cannot read the bounds file: {err.strerror}") from None
    except json.JSONDecodeError as err:
        raise InputFileError(path, err.lineno, f"malformed JSON: {err.msg}") from None
    except UnicodeDecodeError:
        raise InputFileError(path, None, "the bounds file is not UTF-8 text") from None
    if not (isinstance(doc, dict) and doc.get("cuikslam_bounds") == FORMAT_VERSION):
        raise InputFileError(
            path,
            None,
            'not a cuikslam bounds file (no "cuikslam_bounds": 1; see cuikslam calibrate)',
        )
    if doc.get("dataset") != dataset:
        raise InputFileError(
            path, None, f"bounds of dataset {doc.get('dataset')!r}, not of {dataset!r}"
        )
    bounds = doc.get("bounds")
    if not isinstance(bounds, dict):
        raise InputFileError(path, None, '"bounds" must be an object {"range": ..., ...}')
    known = set(MrclamBounds.__dataclass_fields__ if names is None else names)
    for name, value in bounds.items():
        if name not in known:
            raise InputFileError(
                path, None, f"unknown bound {name!r}; known: {', '.join(sorted(known))}"
            )
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise InputFileError(path, None, f"bound {name!r} must be a number, got {value!r}")
        if not (math.isfinite(value) and value >= 0):
            raise InputFileError(path, None, f"bound {name!r} must be finite and >= 0")
    return {k: float(v) for k, v in bounds.items()}
