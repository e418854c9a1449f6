"""Writing a :class:`~cuikslam.log.records.Log` back to the JSON Lines log format.

Floats are written with :func:`repr` precision, so reading the file back gives
identical values; the file is replaced atomically so a crash never leaves half a log.
"""

from __future__ import annotations

import json
import math
import operator
import os
from typing import Any

from cuikslam._atomic import atomic_open
from cuikslam.log.reader import parse_log_lines
from cuikslam.log.records import (
    Bounds,
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    OutlierBound,
    PosePrior,
    Record,
    RelativePose,
    SensorModel,
)

__all__ = ["log_to_lines", "write_log_file"]


def log_to_lines(log: Log) -> list[str]:
    """One JSON line per record, in order, without newline characters."""
    return [_record_to_line(record) for record in log.records]


def write_log_file(log: Log, path: str | os.PathLike[str], *, validate: bool = True) -> None:
    """Write ``log`` to ``path`` atomically, one record per line.

    With ``validate`` (the default) the written lines are read back with
    :func:`~cuikslam.log.reader.parse_log_lines` before the file is committed, so a log
    that :func:`~cuikslam.log.reader.read_log_file` would refuse is never written.

    Raises
    ------
    InputFileError
        If ``validate`` and the log breaks the format (``path`` keeps its old content).
    ValueError, TypeError
        If a record holds a non-finite number or a value of the wrong type.
    """
    lines: list[str] = []
    with atomic_open(path, "w", encoding="utf-8", newline="\n") as file:
        for record in log.records:
            line = _record_to_line(record)
            file.write(line + "\n")
            lines.append(line)
        if validate:
            parse_log_lines(lines, path=os.fspath(path))


def _bounds(value: Bounds) -> list[float]:
    lo, hi = value
    return [float(lo), float(hi)]


def _record_to_json(record: Record) -> dict[str, Any]:
    match record:
        case PosePrior():
            return {
                "type": "prior",
                "pose": operator.index(record.pose),
                "x": _bounds(record.x),
                "y": _bounds(record.y),
                "theta": _bounds(record.theta),
            }
        case Odometry():
            return {
                "type": "odometry",
                "from": operator.index(record.source),
                "to": operator.index(record.target),
                "turn": _bounds(record.turn),
                "distance": _bounds(record.distance),
            }
        case RelativePose():
            return {
                "type": "relative_pose",
                "from": operator.index(record.source),
                "to": operator.index(record.target),
                "dx": _bounds(record.dx),
                "dy": _bounds(record.dy),
                "dtheta": _bounds(record.dtheta),
            }
        case Observation():
            fields: dict[str, Any] = {
                "type": "observation",
                "pose": operator.index(record.pose),
                "class": str(record.landmark_class),
            }
            if record.range is not None:
                fields["range"] = _bounds(record.range)
            if record.bearing is not None:
                fields["bearing"] = _bounds(record.bearing)
            if record.landmark is not None:
                fields["landmark"] = str(record.landmark)
            if record.offset is not None:
                for name, bounds in zip(
                    ("offset_x", "offset_y", "offset_theta"), record.offset, strict=True
                ):
                    fields[name] = _bounds(bounds)
            return fields
        case LandmarkPrior():
            return {
                "type": "landmark",
                "id": str(record.landmark),
                "class": str(record.landmark_class),
                "x": _bounds(record.x),
                "y": _bounds(record.y),
            }
        case ClassPrior():
            fields = {"type": "class", "class": str(record.landmark_class)}
            if record.at_most is not None:
                fields["at_most"] = operator.index(record.at_most)
            if record.min_separation is not None:
                fields["min_separation"] = float(record.min_separation)
            if record.x is not None and record.y is not None:
                fields["x"], fields["y"] = _bounds(record.x), _bounds(record.y)
            return fields
        case SensorModel():
            fields = {"type": "sensor"}
            if math.isfinite(record.max_range):
                fields["max_range"] = float(record.max_range)
            if record.fov < 2 * math.pi:
                fields["fov"] = float(record.fov)
            if record.nearest_margin is not None:
                fields["nearest_margin"] = float(record.nearest_margin)
            return fields
        case OutlierBound():
            fields = {"type": "outliers", "at_most": operator.index(record.at_most)}
            if record.window is not None:
                fields["window"] = operator.index(record.window)
            return fields
    raise TypeError(f"not a log record: {record!r}")


def _record_to_line(record: Record) -> str:
    fields = _record_to_json(record)
    if record.time is not None:
        fields["time"] = float(record.time)
    return json.dumps(fields, allow_nan=False)
