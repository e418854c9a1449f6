"""The ground truth behind a simulated log, its JSON file, and how it is measured.

A simulator returns a :class:`GroundTruth` next to its :class:`~cuikslam.log.records.Log`
so that tests and benchmarks can check that every guaranteed box contains the truth.

Two truth-file layouts are read. The one :func:`write_truth_file` writes::

    {"poses": {"0": [x, y, theta]}, "landmarks": {"L0": {"class": .., "x": .., "y": ..}},
     "assignment": ["L0", ..]}

and the reproducers' layout, where a landmark is ``[x, y, class]`` and the assignment is
called ``obs_truth`` or ``observation_landmark``::

    {"poses": {"0": ["0.4864279400447726331435660540591925", ..]},
     "landmarks": {"L0": ["-3.5675477481952038161", "-4.42128592223", "c0"]},
     "obs_truth": ["L0", ..]}

Every coordinate may be a JSON number or a decimal string. A decimal string is taken
exactly; so is a JSON number, except one that is the shortest decimal of a double (as
:func:`write_truth_file` and every JSON writer print doubles), which means that double:
``-0.39269908169872414`` is the double nearest to -π/8, not the 17-digit decimal. The values
are kept exactly (:class:`fractions.Fraction`, see :meth:`GroundTruth.exact_poses`), next to
their nearest floats (``poses_xyt``, ``landmarks_xy``): a decimal truth of 60 digits may lie
just outside a box whose float bound equals its rounding, and only the exact value can tell.

A truth file given with a log must be that log's truth:
:func:`~cuikslam.simulate.truth_fit.check_truth_fits` refuses one that assigns another
number of observations, has poses the log does not have, or lacks a landmark the log names
(it may lack poses: Vicon gaps). It lives in :mod:`cuikslam.simulate.truth_fit`, and is
imported here too.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from decimal import Decimal
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from cuikslam._atomic import atomic_write_text
from cuikslam.errors import InputFileError
from cuikslam.interval.angles import wrap_angle
from cuikslam.log.records import Bounds
from cuikslam.simulate.truth_fit import (
    TruthMisfit,
    TruthMismatchError,
    check_truth_fits,
    truth_misfit,
)

__all__ = [
    "GroundTruth",
    "TruthMisfit",
    "TruthMismatchError",
    "check_truth_fits",
    "noisy_interval",
    "read_truth_file",
    "truth_misfit",
    "truth_to_json",
    "wrap_angle",
    "write_truth_file",
]


@dataclass(eq=False)
class GroundTruth:
    """The true poses and landmarks of a simulated run (compared by identity: it holds arrays).

    Attributes
    ----------
    poses_xyt : np.ndarray
        (n, 3) true ``x, y, theta`` of each pose, row ``i`` for ``pose_ids[i]``.
        Headings are the running sum of the true turns (not wrapped), so that
        ``theta_to = theta_from + turn`` holds without 2π jumps.
    pose_ids : list[int]
        The pose ids of the log, in time order.
    landmarks_xy : np.ndarray
        (m, 2) true landmark positions, row ``j`` for ``landmark_ids[j]``.
    landmark_ids : list[str]
        Landmark ids.
    landmark_classes : list[str]
        The class of each landmark.
    assignment : list[str]
        The true landmark id of each observation, in log order.
    poses_exact : list of (x, y, theta) Fractions, optional
        The exact true values behind ``poses_xyt`` (row ``i`` for ``pose_ids[i]``) when
        they are not floats (a truth file of decimal strings); ``None`` when
        ``poses_xyt`` is exact.
    landmarks_exact : list of (x, y) Fractions, optional
        The same for ``landmarks_xy``.
    """

    poses_xyt: np.ndarray
    pose_ids: list[int]
    landmarks_xy: np.ndarray
    landmark_ids: list[str]
    landmark_classes: list[str]
    assignment: list[str]
    poses_exact: list[tuple[Fraction, Fraction, Fraction]] | None = None
    landmarks_exact: list[tuple[Fraction, Fraction]] | None = None

    def pose_xyt(self, pose: int) -> np.ndarray:
        """The true ``(x, y, theta)`` of pose id ``pose``."""
        return self.poses_xyt[self.pose_ids.index(pose)]

    def landmark_xy(self, landmark: str) -> np.ndarray:
        """The true ``(x, y)`` of landmark id ``landmark``."""
        return self.landmarks_xy[self.landmark_ids.index(landmark)]

    def landmark_class(self, landmark: str) -> str:
        """The class of landmark id ``landmark``."""
        return self.landmark_classes[self.landmark_ids.index(landmark)]

    def exact_poses(self) -> list[tuple[Fraction, ...]]:
        """The exact true ``(x, y, theta)`` of every pose, in ``pose_ids`` order."""
        if self.poses_exact is not None:
            return [tuple(row) for row in self.poses_exact]
        return [tuple(Fraction(float(v)) for v in row) for row in self.poses_xyt]

    def exact_landmark(self, landmark: str) -> tuple[Fraction, Fraction]:
        """The exact true ``(x, y)`` of landmark id ``landmark``."""
        j = self.landmark_ids.index(landmark)
        if self.landmarks_exact is not None:
            x, y = self.landmarks_exact[j]
        else:
            x, y = (Fraction(float(v)) for v in self.landmarks_xy[j])
        return x, y


def noisy_interval(
    true_value: float, bound: float, rng: np.random.Generator, *, non_negative: bool = False
) -> Bounds:
    """Simulate one bounded-error measurement of ``true_value``.

    The sensor reads ``true_value + e`` with ``e`` uniform in ``[-bound, bound]``; the log
    stores ``[reading - bound, reading + bound]``, which contains ``true_value``.  The
    ``min``/``max`` only absorb floating-point rounding of ``reading ± bound``.  With
    ``non_negative`` (ranges, distances: the log format requires ``lo >= 0``) a negative
    ``lo`` is raised to 0, which still contains the non-negative truth.
    """
    reading = true_value + float(rng.uniform(-bound, bound))
    lo = min(reading - bound, true_value)
    return (max(lo, 0.0) if non_negative else lo, max(reading + bound, true_value))


def truth_to_json(truth: GroundTruth) -> dict[str, Any]:
    """The JSON document of ``truth`` (see :func:`write_truth_file`)."""
    return {
        "poses": {
            str(pose): [float(v) for v in xyt]
            for pose, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True)
        },
        "landmarks": {
            lid: {"class": cls, "x": float(xy[0]), "y": float(xy[1])}
            for lid, cls, xy in zip(
                truth.landmark_ids, truth.landmark_classes, truth.landmarks_xy, strict=True
            )
        },
        "assignment": list(truth.assignment),
    }


def write_truth_file(truth: GroundTruth, path: str | os.PathLike[str]) -> None:
    """Write ``truth`` as JSON: ``{"poses": {"0": [x, y, theta]}, "landmarks": {"L0":
    {"class": .., "x": .., "y": ..}}, "assignment": [..]}``."""
    atomic_write_text(path, json.dumps(truth_to_json(truth), indent=1, allow_nan=False) + "\n")


def read_truth_file(path: str | os.PathLike[str]) -> GroundTruth:
    """Read a truth file (either layout of the module docstring), keeping exact values.

    Raises
    ------
    InputFileError
        If the file cannot be read, is not JSON, or does not have a truth layout.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputFileError(path, None, f"cannot read truth file: {exc}") from exc
    try:
        doc = json.loads(text, parse_float=_json_number)
    except json.JSONDecodeError as exc:
        raise InputFileError(path, exc.lineno, f"not valid JSON: {exc.msg}") from exc
    except (ValueError, RecursionError) as exc:  # e.g. an integer of 5,000 digits
        raise InputFileError(path, None, f"not valid JSON: {exc}") from None
    try:
        return _truth_from_json(doc)
    except _TruthLayoutError as exc:
        raise InputFileError(path, None, str(exc)) from None


class _TruthLayoutError(Exception):
    """A JSON document that is not a truth file; turned into ``InputFileError``."""


_ASSIGNMENT_KEYS = ("assignment", "obs_truth", "observation_landmark")
_DECIMAL = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_MAX_DIGITS = 2000
"""Longest decimal string accepted (bounds the work of an exact conversion)."""
_FLOAT_MAX = Fraction(np.finfo(float).max)


def _truth_from_json(doc: Any) -> GroundTruth:
    if not isinstance(doc, dict):
        raise _TruthLayoutError("a truth file must be a JSON object")
    keys = [key for key in _ASSIGNMENT_KEYS if key in doc]
    missing = [key for key in ("poses", "landmarks") if key not in doc]
    if not keys:
        missing.append("assignment")
    if missing:
        raise _TruthLayoutError(
            f"truth file lacks key(s) {', '.join(map(repr, missing))}"
            + (" (the assignment may also be called 'obs_truth')" if not keys else "")
        )
    if len(keys) > 1:
        raise _TruthLayoutError(f"truth file has both {keys[0]!r} and {keys[1]!r}")
    poses, landmarks, assignment = doc["poses"], doc["landmarks"], doc[keys[0]]
    if not isinstance(poses, dict):
        raise _TruthLayoutError('"poses" must be an object {"<pose id>": [x, y, theta]}')
    if not isinstance(landmarks, dict):
        raise _TruthLayoutError(
            '"landmarks" must be an object {"<id>": {"class", "x", "y"}} or {"<id>": [x, y, class]}'
        )
    if not isinstance(assignment, list):
        raise _TruthLayoutError(f'"{keys[0]}" must be a list of landmark ids')

    pose_ids: list[int] = []
    seen: set[int] = set()
    poses_exact: list[tuple[Fraction, Fraction, Fraction]] = []
    for key, xyt in poses.items():
        try:
            pose_ids.append(int(key))
        except ValueError:
            raise _TruthLayoutError(f"pose id {key!r} is not an integer") from None
        if pose_ids[-1] in seen:
            raise _TruthLayoutError(f"pose id {key!r} appears twice")
        seen.add(pose_ids[-1])
        if not (isinstance(xyt, list) and len(xyt) == 3):
            raise _TruthLayoutError(f"pose {key}: expected [x, y, theta], got {_show(xyt)}")
        x, y, theta = (_exact(v, f"pose {key}") for v in xyt)
        poses_exact.append((x, y, theta))

    landmark_classes: list[str] = []
    landmarks_exact: list[tuple[Fraction, Fraction]] = []
    for lid, entry in landmarks.items():
        if isinstance(entry, dict) and {"class", "x", "y"} <= entry.keys():
            cls, xy = entry["class"], (entry["x"], entry["y"])
        elif isinstance(entry, list) and len(entry) == 3:
            cls, xy = entry[2], (entry[0], entry[1])
        else:
            raise _TruthLayoutError(
                f'landmark {lid}: expected {{"class", "x", "y"}} or [x, y, class], '
                f"got {_show(entry)}"
            )
        if not isinstance(cls, str):
            raise _TruthLayoutError(f"landmark {lid}: class must be a string")
        landmark_classes.append(cls)
        x, y = (_exact(v, f"landmark {lid}") for v in xy)
        landmarks_exact.append((x, y))

    for k, lid in enumerate(assignment):
        if not isinstance(lid, str) or lid not in landmarks:
            raise _TruthLayoutError(f"{keys[0]}[{k}] = {_show(lid)} is not a landmark id")
    poses_xyt = np.array([[float(v) for v in row] for row in poses_exact], float)
    landmarks_xy = np.array([[float(v) for v in row] for row in landmarks_exact], float)
    return GroundTruth(
        poses_xyt=poses_xyt.reshape(len(poses_exact), 3),
        pose_ids=pose_ids,
        landmarks_xy=landmarks_xy.reshape(len(landmarks_exact), 2),
        landmark_ids=list(landmarks),
        landmark_classes=landmark_classes,
        assignment=list(assignment),
        poses_exact=poses_exact,
        landmarks_exact=landmarks_exact,
    )


def _json_number(text: str) -> float | Decimal:
    """A JSON number: the double it is the shortest decimal of, else the exact decimal."""
    exact = Decimal(text)
    if len(text) <= 40 and exact.is_finite():
        double = float(text)
        if math.isfinite(double) and Decimal(repr(double)) == exact:
            return double
    return exact


def _show(value: Any) -> str:
    """A short rendering of a JSON value for a message (Decimals as plain numbers)."""
    text = str(value) if isinstance(value, Decimal) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _exact(value: Any, where: str) -> Fraction:
    """A JSON number or decimal string as an exact Fraction (finite, within float range)."""
    if isinstance(value, str):
        text = value.strip()
        if len(text) > _MAX_DIGITS or not _DECIMAL.fullmatch(text):
            raise _TruthLayoutError(f"{where}: {_show(value)} is not a finite number")
        value = Decimal(text)
    if isinstance(value, bool) or not isinstance(value, int | float | Decimal):
        raise _TruthLayoutError(f"{where}: {_show(value)} is not a finite number")
    if isinstance(value, float) and not math.isfinite(value):
        raise _TruthLayoutError(f"{where}: {_show(value)} is not a finite number")
    if isinstance(value, Decimal):
        if not value.is_finite():
            raise _TruthLayoutError(f"{where}: {_show(value)} is not a finite number")
        if len(value.as_tuple().digits) > _MAX_DIGITS:
            raise _TruthLayoutError(f"{where}: {_show(value)} has too many digits")
        if not value.is_zero() and not -_MAX_DIGITS <= value.adjusted() <= 400:
            raise _TruthLayoutError(f"{where}: {_show(value)} is beyond the float range")
    exact = Fraction(value)
    if abs(exact) > _FLOAT_MAX:
        raise _TruthLayoutError(f"{where}: {_show(value)} is beyond the float range")
    return exact
