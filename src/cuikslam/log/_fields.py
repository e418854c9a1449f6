"""Validation of one JSON record of the log format into a record dataclass.

Each check raises :class:`Problem` with a sentence for a human; the reader adds the
file and line. Cross-record checks (which poses are reached, landmark classes) live in
:mod:`cuikslam.log.reader`.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from cuikslam.log.records import (
    Bounds,
    ClassPrior,
    LandmarkPrior,
    Observation,
    Odometry,
    OutlierBound,
    PosePrior,
    Record,
    RelativePose,
    SensorModel,
)

__all__ = ["RECORD_TYPES", "Problem", "record_from_json"]


class Problem(Exception):
    """A record breaks the format; the message says how (no file or line yet)."""


@dataclass(frozen=True)
class _Schema:
    required: tuple[str, ...]
    optional: tuple[str, ...]
    build: Callable[[dict[str, Any], int], Record]

    @functools.cached_property
    def allowed(self) -> tuple[str, ...]:
        return (*self.required, *self.optional, "time")


def _show(value: Any) -> str:
    try:
        shown = json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        shown = repr(value)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _finite(value: int | float, name: str) -> float:
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise Problem(f'field "{name}" holds {_show(value)}, which is not a finite number')
    return number


def _interval(value: Any, name: str, *, non_negative: bool = False) -> Bounds:
    """``[lo, hi]`` with finite numbers, ``lo <= hi`` (and ``lo >= 0`` if asked)."""
    if type(value) is list and len(value) == 2:  # the common case, decided at once
        lo, hi = value
        if (
            type(lo) is float
            and type(hi) is float
            and -math.inf < lo <= hi < math.inf  # False for NaN
            and not (non_negative and lo < 0)
        ):
            return (lo, hi)
    if not (isinstance(value, list) and len(value) == 2 and all(map(_is_number, value))):
        raise Problem(
            f'field "{name}" must be an interval [lo, hi] of two numbers, got {_show(value)}'
        )
    lo, hi = (_finite(v, name) for v in value)
    if lo > hi:
        raise Problem(f'field "{name}" is the interval [{lo!r}, {hi!r}] with lo > hi')
    if non_negative and lo < 0:
        raise Problem(
            f'field "{name}" is the interval [{lo!r}, {hi!r}]; a {name} cannot be negative'
            " (need lo >= 0)"
        )
    return (lo, hi)


def _pose_id(value: Any, name: str) -> int:
    """A non-negative JSON integer (``1.0`` and ``true`` are refused)."""
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise Problem(f'field "{name}" must be a non-negative integer pose id, got {_show(value)}')
    return value


def _name(value: Any, name: str) -> str:
    """A non-empty string."""
    if not isinstance(value, str) or not value:
        raise Problem(f'field "{name}" must be a non-empty string, got {_show(value)}')
    return value


def _prior(f: dict[str, Any], line: int) -> PosePrior:
    return PosePrior(
        pose=_pose_id(f["pose"], "pose"),
        x=_interval(f["x"], "x"),
        y=_interval(f["y"], "y"),
        theta=_interval(f["theta"], "theta"),
        line=line,
    )


def _odometry(f: dict[str, Any], line: int) -> Odometry:
    source = _pose_id(f["from"], "from")
    target = _pose_id(f["to"], "to")
    if source == target:
        raise Problem(f"odometry from pose {source} to itself; from and to must differ")
    return Odometry(
        source=source,
        target=target,
        turn=_interval(f["turn"], "turn"),
        distance=_interval(f["distance"], "distance", non_negative=True),
        line=line,
    )


def _relative_pose(f: dict[str, Any], line: int) -> RelativePose:
    source = _pose_id(f["from"], "from")
    target = _pose_id(f["to"], "to")
    if source == target:
        raise Problem(f"relative pose from pose {source} to itself; from and to must differ")
    return RelativePose(
        source=source,
        target=target,
        dx=_interval(f["dx"], "dx"),
        dy=_interval(f["dy"], "dy"),
        dtheta=_interval(f["dtheta"], "dtheta"),
        line=line,
    )


_OFFSET_FIELDS = ("offset_x", "offset_y", "offset_theta")


def _observation(f: dict[str, Any], line: int) -> Observation:
    raw_range, raw_bearing, raw_landmark = (f.get(k) for k in ("range", "bearing", "landmark"))
    if raw_range is None and raw_bearing is None:
        raise Problem('observation has neither "range" nor "bearing"; give at least one')
    offset = None
    if any(f.get(k) is not None for k in _OFFSET_FIELDS):
        offset = tuple(
            (0.0, 0.0) if f.get(k) is None else _interval(f[k], k) for k in _OFFSET_FIELDS
        )
    return Observation(
        pose=_pose_id(f["pose"], "pose"),
        landmark_class=_name(f["class"], "class"),
        range=None if raw_range is None else _interval(raw_range, "range", non_negative=True),
        bearing=None if raw_bearing is None else _interval(raw_bearing, "bearing"),
        landmark=None if raw_landmark is None else _name(raw_landmark, "landmark"),
        line=line,
        offset=offset,
    )


def _landmark(f: dict[str, Any], line: int) -> LandmarkPrior:
    return LandmarkPrior(
        landmark=_name(f["id"], "id"),
        landmark_class=_name(f["class"], "class"),
        x=_interval(f["x"], "x"),
        y=_interval(f["y"], "y"),
        line=line,
    )


def _positive(value: Any, name: str) -> float:
    if not _is_number(value):
        raise Problem(f'field "{name}" must be a number, got {_show(value)}')
    number = _finite(value, name)
    if number <= 0:
        raise Problem(f'field "{name}" must be positive, got {_show(value)}')
    return number


def _class_prior(f: dict[str, Any], line: int) -> ClassPrior:
    at_most = f.get("at_most")
    if at_most is not None and (
        isinstance(at_most, bool) or not isinstance(at_most, int) or at_most < 0
    ):
        raise Problem(f'field "at_most" must be a whole number >= 0, got {_show(at_most)}')
    separation = f.get("min_separation")
    if sum(f.get(k) is not None for k in ("x", "y")) == 1:
        raise Problem('fields "x" and "y" come together: the region is the box x by y')
    prior = ClassPrior(
        landmark_class=_name(f["class"], "class"),
        at_most=at_most,
        min_separation=None if separation is None else _positive(separation, "min_separation"),
        x=None if f.get("x") is None else _interval(f["x"], "x"),
        y=None if f.get("y") is None else _interval(f["y"], "y"),
        line=line,
    )
    if prior.at_most is None and prior.min_separation is None and prior.x is None:
        raise Problem('a class record needs at least one of "at_most", "min_separation", "x"/"y"')
    return prior


def _sensor(f: dict[str, Any], line: int) -> SensorModel:
    margin = f.get("nearest_margin")
    return SensorModel(
        max_range=math.inf
        if f.get("max_range") is None
        else _positive(f["max_range"], "max_range"),
        fov=2 * math.pi if f.get("fov") is None else min(_positive(f["fov"], "fov"), 2 * math.pi),
        nearest_margin=None if margin is None else _positive(margin, "nearest_margin"),
        line=line,
    )


def _whole(value: Any, name: str, *, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise Problem(f'field "{name}" must be a whole number >= {least}, got {_show(value)}')
    return value


def _outliers(f: dict[str, Any], line: int) -> OutlierBound:
    window = f.get("window")
    return OutlierBound(
        at_most=_whole(f["at_most"], "at_most", least=0),
        window=None if window is None else _whole(window, "window", least=1),
        line=line,
    )


RECORD_TYPES: dict[str, _Schema] = {
    "prior": _Schema(("pose", "x", "y", "theta"), (), _prior),
    "odometry": _Schema(("from", "to", "turn", "distance"), (), _odometry),
    "relative_pose": _Schema(("from", "to", "dx", "dy", "dtheta"), (), _relative_pose),
    "observation": _Schema(
        ("pose", "class"), ("range", "bearing", "landmark", *_OFFSET_FIELDS), _observation
    ),
    "landmark": _Schema(("id", "class", "x", "y"), (), _landmark),
    "sensor": _Schema((), ("max_range", "fov", "nearest_margin"), _sensor),
    "class": _Schema(("class",), ("at_most", "min_separation", "x", "y"), _class_prior),
    "outliers": _Schema(("at_most",), ("window",), _outliers),
}

_TYPE_LIST = ", ".join(f'"{t}"' for t in RECORD_TYPES)


def _json_kind(value: Any) -> str:
    kinds = {list: "an array", str: "a string", bool: "a boolean", type(None): "null"}
    return kinds.get(type(value), "a number")


def record_from_json(value: Any, line: int) -> Record:
    """Check one decoded JSON value against the format and build its record."""
    if not isinstance(value, dict):
        raise Problem(
            f'record is {_json_kind(value)}, expected a JSON object like {{"type": "prior", ...}}'
        )
    if "type" not in value:
        raise Problem(f'record has no "type" field; expected one of {_TYPE_LIST}')
    kind = value["type"]
    if not isinstance(kind, str) or kind not in RECORD_TYPES:
        raise Problem(f"unknown record type {_show(kind)}; expected one of {_TYPE_LIST}")
    schema = RECORD_TYPES[kind]
    fields = {k: v for k, v in value.items() if k != "type"}
    for name in fields:
        if name not in schema.allowed:
            close = difflib.get_close_matches(name, schema.allowed, n=1)
            hint = f' (did you mean "{close[0]}"?)' if close else ""
            raise Problem(
                f'unknown field "{name}" in {kind} record{hint}; allowed fields: '
                + ", ".join(schema.allowed)
            )
    for name in schema.required:
        if name not in fields:
            raise Problem(
                f'{kind} record is missing field "{name}"; required fields: '
                + ", ".join(schema.required)
            )
    time = None
    if "time" in fields:
        if not _is_number(fields["time"]):
            raise Problem(f'field "time" must be a number, got {_show(fields["time"])}')
        time = _finite(fields["time"], "time")
    record = schema.build(fields, line)
    return record if time is None else dataclasses.replace(record, time=time)
